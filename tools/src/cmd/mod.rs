//! One module per `fabric` subcommand.

pub mod devices;
pub mod render;
