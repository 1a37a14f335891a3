//! The reference renderer: an unbiased volumetric path tracer of the input fabric
//! (docs/DESIGN.md §4). See `medium` for the conventions it shares with Mitsuba 3.

pub mod integrator;
pub mod majorant;
pub mod measure;
pub mod medium;
pub mod render;
pub mod rng;
pub mod sggx;
pub mod tracking;
#[cfg(test)]
mod validation;
#[cfg(test)]
mod validation_env;

pub use integrator::{Lighting, PathSettings, PathStats};
pub use measure::MeasureScene;
pub use medium::{EmptyOrientation, Lookup, MediumOptions};
pub use render::{RenderSettings, RenderStats, render};
pub use tracking::TracedMedium;

use glam::Vec3;

/// Why a reference render or measurement cannot run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReferenceError {
    #[error("unusable volume: {0}")]
    BadVolume(String),
    #[error("voxel mask has {got} entries, the volume has {expected} voxels")]
    MaskLength { expected: usize, got: usize },
    #[error("height map has {got} texels, the volume has {expected} columns (xres·yres)")]
    HeightMapLength { expected: usize, got: usize },
    #[error("height map texel ({x}, {y}) is {value}, which is not finite")]
    BadHeight { x: usize, y: usize, value: f32 },
    #[error("{what} direction {value} is zero or not finite")]
    BadDirection { what: &'static str, value: Vec3 },
    #[error("{what} direction {value} is within 0.06° of the sheet's plane (|z| < 1e-3); no ray can reach the surface from there")]
    GrazingDirection { what: &'static str, value: Vec3 },
    #[error("texel ({x}, {y}) is outside the {w}x{h} volume")]
    BadTexel { x: usize, y: usize, w: usize, h: usize },
    #[error("samples per pixel must be at least 1")]
    ZeroSamples,
    #[error("max depth must be at least 1 (2 = single scattering)")]
    ZeroDepth,
    #[error(transparent)]
    Camera(#[from] fabric_runtime::scene::CameraError),
    #[error(transparent)]
    Light(#[from] fabric_runtime::scene::LightError),
}
