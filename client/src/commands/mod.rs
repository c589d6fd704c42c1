//! The CLI's subcommands.

pub mod bench;
pub mod inspect;
pub mod render;
