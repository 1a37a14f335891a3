//! The reference renderer: an unbiased volumetric path tracer of the input fabric
//! (../shared/DESIGN.md §4). See `medium` for the conventions it shares with Mitsuba 3.

pub mod rng;
pub mod sggx;
