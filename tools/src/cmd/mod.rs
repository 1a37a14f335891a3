//! One module per `fabric` subcommand.

pub mod devices;
pub mod geometry;
pub mod render;
pub mod view;
