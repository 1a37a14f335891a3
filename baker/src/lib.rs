//! The baker: fabric volumes, the reference path tracer, and the conversion of a
//! volume into a hybrid model (docs/DESIGN.md).

// `!(x > 0.0)` is how this crate rejects NaN together with non-positive values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod bake;
pub mod evaluate;
pub mod fit;
pub mod generate;
pub mod geometry;
pub mod memory;
pub mod prefilter;
pub mod progress;
pub mod reference;
pub mod volume;
