//! One module per `fabric` subcommand.

pub mod devices;
pub mod diff;
pub mod generate;
pub mod inspect;
#[allow(dead_code)] // the lead wires it into `fabric inspect`
pub mod inspect_model;
pub mod reference;
pub mod render;
#[allow(dead_code)] // the lead wires it into `fabric render --backend cpu`
pub mod render_cpu;
pub mod view;
