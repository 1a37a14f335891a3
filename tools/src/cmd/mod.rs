//! One module per `fabric` subcommand.

pub mod devices;
#[allow(dead_code)] // the lead wires it into `fabric inspect`
pub mod inspect_model;
pub mod render;
#[allow(dead_code)] // the lead wires it into `fabric render --backend cpu`
pub mod render_cpu;
