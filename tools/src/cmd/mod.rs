//! One module per `fabric` subcommand.

pub mod devices;
pub mod generate;
pub mod inspect;
pub mod render;
pub mod view;
