//! Fabric volumes: the in-memory grid, Mitsuba `.vol` I/O, `material.toml` and
//! validation (docs/DESIGN.md §3).

pub mod error;
pub mod fabric_dir;
pub mod grid;
pub mod material;
pub mod stats;
pub mod vol;

pub use error::VolumeError;
pub use fabric_dir::{ALBEDO_FILE, DENSITY_FILE, MATERIAL_FILE, ORIENTATION_FILE, SaveEncoding, SaveOptions, load_fabric, load_fabric_with_progress, material_defaults_note, save_fabric, save_fabric_with};
pub use grid::{Aabb, FabricVolume, MAX_DENSITY, MaterialParams, Voxel};
pub use material::{MaterialFile, MaterialOverrides};
pub use vol::{Encoding, VolGrid, VolHeader, VolReader, VolWriter, read_vol, write_vol};
