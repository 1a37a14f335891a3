//! The baker: fabric volumes, the reference path tracer, and the conversion of a
//! volume into a hybrid model (../shared/DESIGN.md).

pub mod generate;
pub mod reference;
pub mod volume;
