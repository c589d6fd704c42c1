//! The CLI's subcommands.

pub mod render;
