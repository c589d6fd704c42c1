//! The CLI's subcommands.

pub mod inspect;
pub mod render;
