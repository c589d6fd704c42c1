//! The CLI's subcommands.

pub mod bench;
pub mod effects;
pub mod inspect;
pub mod lights;
pub mod render;
