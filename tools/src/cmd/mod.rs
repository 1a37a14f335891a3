//! One module per `fabric` subcommand.

pub mod devices;
pub mod diff;
pub mod reference;
pub mod render;
