//! The CLI's subcommands.

pub mod frames;
pub mod inspect;
pub mod render;
