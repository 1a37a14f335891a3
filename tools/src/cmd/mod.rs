//! One module per `fabric` subcommand.

pub mod devices;
pub mod diff;
pub mod reference;
mod volume_input;
pub mod render;
