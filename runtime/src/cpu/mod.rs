//! The CPU renderer of hybrid models: the specification of the shading, the twin of the
//! GPU renderer, and the baker's validation renderer (DESIGN.md §7).
//!
//! Its decomposition is the one the GLSL has: [`heightfield`] (heightfield.glsl: the
//! POM march with a min-depth quadtree and exact refinement), [`flyaways`]
//! (flyaways.glsl: the linked-list march with alpha compositing), [`shading`]
//! (shading.glsl: lobes under lights, fiber frames, shadows), [`crate::brdf`]
//! (brdf.glsl), and [`render`] (the per-pixel program and the image loop).
//!
//! Geometry (DESIGN.md §8, runtime/HYBRID_FORMAT.md §5): by default the tile sits on
//! the source volume's top plane covering exactly its x–y box, depths going down into
//! it; rays enter through the top plane only (the GPU draws the top face). With
//! `periodic` the tile repeats forever in x and y, matching `fabric reference
//! --periodic`.
//!
//! ```no_run
//! # use fabric_runtime::{cpu, hybrid, scene::{Camera, Light}};
//! # fn f(model: &hybrid::HybridModel, camera: &Camera, lights: &[Light]) -> Result<(), cpu::CpuRenderError> {
//! let image = cpu::render(model, camera, lights, &cpu::CpuRenderOptions { periodic: true, ..Default::default() })?;
//! # Ok(()) }
//! ```

pub mod edits;
pub mod env_shading;
pub mod flyaways;
pub mod heightfield;
pub mod level;
pub mod probe;
pub mod render;
pub mod shading;

use glam::Vec3;

pub use edits::{Edit, EditMask, Edits};
pub use env_shading::texel_env_response;
pub use render::{LevelMix, PixelTrace, Scene, render, render_with_progress, render_with_stats, validate_render, validate_view};

use crate::hybrid::ModelError;
use crate::scene::{CameraError, Light, LightError};

/// Which level of the mip chain shades a pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LevelChoice {
    /// From the pixel's footprint where its ray meets the height field (the top plane
    /// if it misses), filtered anisotropically as a GPU filters a texture: N =
    /// ⌈major/minor⌉ ≤ 8 lookups along the footprint's major axis, λ = log2(major/N) +
    /// bias in level-0 texels, levels ⌊λ⌋ and ⌊λ⌋ + 1 blended by λ − ⌊λ⌋ (Vulkan's
    /// linear-mip rule), clamped to the chain. λ ≤ 0 shades level 0 alone.
    Auto { bias: f32 },
    /// Isotropic, one level: ⌊log2 major + bias + ½⌋ (Vulkan's nearest-mip rule). No
    /// blending: seams where the level changes.
    Nearest { bias: f32 },
    /// This level everywhere.
    Fixed(u32),
}

/// Height-field shadowing of the lights.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShadowMode {
    /// As the model was fitted (its metadata says whether the fit assumed shadowing).
    FromModel,
    On,
    Off,
}

/// How coarse levels (≥ 1) are filtered (level.rs, `box_grid`; runtime/HYBRID_FORMAT.md §6).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CoarseFilter {
    /// A grid of `level::SURFACE_GRID` lookups per axis a level or two finer, spread to keep
    /// the pixel's variance (`level::box_grid`), and the flyaways marched along a grid of
    /// `level::FILTER_GRID` parallel rays per axis over the footprint, each to its own
    /// surface (min(N, 2)·FILTER_GRID along a grazing footprint's major axis, at their own
    /// level; `level::fly_box_grid`): closer
    /// to the pixel's box (baker/PREFILTER_MEASUREMENTS.md, "The box filter"), at a
    /// multiple of the far views' frame time (runtime/GPU_MEASUREMENTS.md).
    Box,
    /// One bilinear lookup per anisotropic tap, as wide as the pixel, and one flyaway
    /// ray at the footprint's level: cheaper far away.
    Bilinear,
    /// The surface as `Box`, the flyaways along a grid of `level::FLY_FINE_GRID` rays
    /// per axis through voxels as many times finer: sparse, bright fibres need a finer
    /// box than the dense surface (far views 12% lower summed over the presets, felt at
    /// 70° 17.6 → 12.0%), at 2–3× a wholly distant frame's time on the CPU
    /// (baker/PREFILTER_MEASUREMENTS.md, "A finer box for the flyaways").
    Fine,
    /// The flyaways' light as `Box` shades it, their coverage from `Fine`'s grid marched
    /// unshaded: each box ray's colour (its radiance per unit of opacity) spread over
    /// the opacity of the fine rays in its cell (baker/PREFILTER_MEASUREMENTS.md, "The
    /// flyaways' coverage from a finer grid"). The default: far views 17% lower summed
    /// over the presets than `Box`, for unshaded marches whose cost does not grow with
    /// the lighting (lavapipe: 2.1–2.3× the box's far frame under one light, 1.14–1.16×
    /// under the sky; baker/PREFILTER_MEASUREMENTS.md, "The split filter as the default").
    Split,
    /// As `Split`, with the finer grid's rays shaded too: where the shading rays march a
    /// coarse level, the flyaways' coverage and the lights' light come from `Fine`'s
    /// grid, an environment's smooth SG part from the box grid's rays spread over that
    /// coverage as `Split` spreads it, and the surface's lookups are still where the box
    /// grid's rays land (`Fine` takes them from its own finer rays, which at grazing
    /// views read the surface too bright). The default: every far view of the 128²
    /// presets within 5%, where `Split` left three above, at 1.4–1.9× `Split`'s far frame
    /// under one light and about the same under the sky (baker/PREFILTER_MEASUREMENTS.md,
    /// "The finer grid shaded").
    #[default]
    SplitShaded,
}

impl CoarseFilter {
    /// Every filter by its command-line name, the default first.
    pub const NAMES: [(&'static str, CoarseFilter); 5] = [("split-shaded", CoarseFilter::SplitShaded), ("split", CoarseFilter::Split), ("box", CoarseFilter::Box), ("fine", CoarseFilter::Fine), ("bilinear", CoarseFilter::Bilinear)];

    /// The filter of a command-line name (`--coarse-filter`).
    pub fn from_name(name: &str) -> Option<CoarseFilter> {
        Self::NAMES.iter().find(|(n, _)| *n == name).map(|(_, f)| *f)
    }

    /// Lookups per axis of the surface's grid (1: none).
    pub fn grid(self) -> u32 {
        match self {
            CoarseFilter::Box | CoarseFilter::Fine | CoarseFilter::Split | CoarseFilter::SplitShaded => level::SURFACE_GRID,
            CoarseFilter::Bilinear => 1,
        }
    }

    /// Rays per axis of the grid that gives the flyaways' coverage (`Split`,
    /// `SplitShaded`: the fine grid; else the shading grid's own,
    /// [`CoarseFilter::fly_grid`]).
    pub fn cover_grid(self) -> u32 {
        match self {
            CoarseFilter::Split | CoarseFilter::SplitShaded => level::FLY_FINE_GRID,
            f => f.fly_grid(),
        }
    }

    /// Whether the coverage grid's rays are shaded with the lights, the shading grid's
    /// with an environment's SG part alone (`SplitShaded`).
    pub fn cover_shaded(self) -> bool {
        self == CoarseFilter::SplitShaded
    }

    /// Rays per axis of the flyaways' grid (1: none; `level::fly_box_grid`).
    pub fn fly_grid(self) -> u32 {
        match self {
            CoarseFilter::Box | CoarseFilter::Split | CoarseFilter::SplitShaded => level::FILTER_GRID,
            CoarseFilter::Fine => level::FLY_FINE_GRID,
            CoarseFilter::Bilinear => 1,
        }
    }
}

/// How to render.
#[derive(Clone, Debug, PartialEq)]
pub struct CpuRenderOptions {
    pub level: LevelChoice,
    /// Repeat the tile forever in x and y.
    pub periodic: bool,
    pub shadows: ShadowMode,
    /// Budget of height-field traversal steps per ray (camera and shadow rays).
    pub max_steps: u32,
    /// Budget of flyaway columns per camera ray.
    pub max_flyaway_columns: u32,
    /// s×s camera rays per pixel on a regular grid (1..=16); at automatic levels each
    /// filters its own sub-pixel (`Scene::level_mix`).
    pub supersampling: u32,
    /// Radiance where rays miss the tile.
    pub background: Vec3,
    /// March the flyaways (off: the surface alone, as if the model had none).
    pub flyaways: bool,
    /// March the height field only down to the quadtree level of the pixel's surface
    /// level at the top plane: a node the ray reaches there is a hit on its flat top. Far
    /// away this takes fewer steps and flattens relief finer than the pixel; off (the
    /// default), the march is exact at every distance.
    pub coarse_relief: bool,
    /// How coarse levels are filtered ([`CoarseFilter`]; `Split` by default: a box grid
    /// of lookups, the flyaways' coverage from a finer grid of unshaded rays).
    pub coarse_filter: CoarseFilter,
    /// Appearance edits (identity by default).
    pub edits: Edits,
    /// Environment lighting (env_shading.rs): the prefiltered map's SG lookups plus its
    /// extracted sources as extra directional lights; where rays miss the tile they see
    /// the map instead of `background` (unless `EnvLight::background` is off).
    pub env: Option<EnvLight>,
}

/// A shared prefiltered environment (compared by identity: two options are equal when
/// they light with the same prefiltered map), and whether rays that miss see it.
#[derive(Clone, Debug)]
pub struct EnvLight {
    pub prefiltered: std::sync::Arc<crate::scene::PrefilteredEnv>,
    pub background: bool,
}

impl EnvLight {
    pub fn new(prefiltered: crate::scene::PrefilteredEnv) -> EnvLight {
        EnvLight { prefiltered: std::sync::Arc::new(prefiltered), background: true }
    }
}

impl PartialEq for EnvLight {
    fn eq(&self, other: &Self) -> bool {
        std::sync::Arc::ptr_eq(&self.prefiltered, &other.prefiltered) && self.background == other.background
    }
}

impl CpuRenderOptions {
    /// The lights a render shades: the caller's, then the environment's sources.
    pub fn lights_with_env(&self, lights: &[Light]) -> Vec<Light> {
        let mut all = lights.to_vec();
        if let Some(env) = &self.env {
            all.extend_from_slice(&env.prefiltered.lights);
        }
        all
    }
}

impl Default for CpuRenderOptions {
    fn default() -> Self {
        CpuRenderOptions {
            level: LevelChoice::Auto { bias: 0.0 },
            periodic: false,
            shadows: ShadowMode::FromModel,
            max_steps: 4096,
            max_flyaway_columns: 16384,
            supersampling: 1,
            background: Vec3::ZERO,
            flyaways: true,
            coarse_relief: false,
            coarse_filter: CoarseFilter::SplitShaded,
            edits: Edits::default(),
            env: None,
        }
    }
}

/// What a render did, for the command line and the benchmarks.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RenderStats {
    pub pixels: u64,
    /// Pixels whose camera ray entered the tile.
    pub tile_pixels: u64,
    /// Pixels whose camera ray hit the height field.
    pub surface_pixels: u64,
    /// Pixels where flyaways covered part of the view.
    pub flyaway_pixels: u64,
    /// Pixels per level.
    pub level_pixels: Vec<u64>,
    /// Pixels whose camera march ran out of steps (shown as background past that point).
    pub step_limited_pixels: u64,
    /// Shadow rays that ran out of steps (counted as blocked).
    pub step_limited_shadow_rays: u64,
    /// Height-field traversal steps of all camera rays.
    pub camera_steps: u64,
    /// Pixels whose loops the Vulkan driver cut short, so drawn wrong (GPU only:
    /// lavapipe runs at most 65535 loop iterations per shader invocation;
    /// runtime/GPU_MEASUREMENTS.md, "lavapipe's loop budget"). Always 0 on the CPU.
    pub loop_cut_pixels: u64,
}

impl RenderStats {
    fn add(&mut self, t: &PixelTrace) {
        self.pixels += 1;
        if let Some(level) = t.level {
            self.tile_pixels += 1;
            self.level_pixels[level] += 1;
        }
        self.surface_pixels += t.surface_t.is_some() as u64;
        self.flyaway_pixels += (t.flyaway_opacity > 0.0) as u64;
        self.step_limited_pixels += t.step_limited as u64;
        self.step_limited_shadow_rays += t.shadow_step_limited as u64;
        self.camera_steps += t.steps as u64;
    }

    fn merge(&mut self, o: &RenderStats) {
        self.pixels += o.pixels;
        self.tile_pixels += o.tile_pixels;
        self.surface_pixels += o.surface_pixels;
        self.flyaway_pixels += o.flyaway_pixels;
        for (a, b) in self.level_pixels.iter_mut().zip(&o.level_pixels) {
            *a += b;
        }
        self.step_limited_pixels += o.step_limited_pixels;
        self.step_limited_shadow_rays += o.step_limited_shadow_rays;
        self.camera_steps += o.camera_steps;
    }
}

/// Why a render cannot run.
#[derive(Debug, thiserror::Error)]
pub enum CpuRenderError {
    #[error("invalid model: {0}")]
    Model(#[from] ModelError),
    #[error("invalid camera: {0}")]
    Camera(#[from] CameraError),
    #[error("invalid light: {0}")]
    Light(#[from] LightError),
    #[error("level {level} does not exist: the model has levels 0..{count}")]
    Level { level: u32, count: usize },
    #[error("invalid options: {0}")]
    Options(String),
    #[error("pixel ({x}, {y}) came out as {value}: a bug in the renderer, please report it")]
    NonFinite { x: u32, y: u32, value: Vec3 },
}
