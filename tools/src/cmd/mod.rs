//! One module per `fabric` subcommand.

pub mod bake;
pub mod bench;
pub mod demo;
pub mod devices;
pub mod diff;
pub mod generate;
pub mod geometry;
pub mod inspect;
pub mod inspect_model;
pub mod prefilter;
pub mod reference;
pub mod render;
pub mod render_cpu;
pub mod render_gpu;
pub mod stress;
pub mod view;
