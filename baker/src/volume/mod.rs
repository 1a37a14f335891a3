//! Fabric volumes: the in-memory grid, Mitsuba `.vol` I/O and validation.

pub mod grid;

pub use grid::{Aabb, FabricVolume, MaterialParams, Voxel, MAX_DENSITY};
