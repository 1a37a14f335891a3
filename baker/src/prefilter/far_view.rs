//! How well the mip chain stands in for supersampling (issue "Multi-scale", accuracy):
//! the tile seen from afar at one sample per pixel with automatic levels, against the
//! ground truth of the chain — level 0 with at least 4×4 samples per level-0 texel
//! (16×16 per pixel of an image f times larger, box-downsampled; ≥ 256 per pixel) —
//! and level 0 at one sample per pixel (the aliasing the chain removes). 64 samples per
//! pixel are not a ground truth once a pixel covers 8×8 texels that differ as much as a
//! fabric's do: their own error is then ~20%. The truth's own error is estimated
//! against a second truth on an 11×11 grid and reported.
//!
//! Views are orthographic and periodic (every pixel sees fabric), the whole tile's
//! width spanning `pixels` pixels, at polar angle θ and azimuth 30° (off the yarn
//! axes), under one directional light at polar 40°, azimuth 210°. The distance sweep
//! moves a perspective camera (40° field of view) from where a level-0 texel covers
//! ½ pixel to where it covers 1/64 pixel.

use glam::Vec3;
use serde::Serialize;

use fabric_runtime::cpu::{CoarseFilter, CpuRenderError, CpuRenderOptions, LevelChoice, render};
use fabric_runtime::hybrid::HybridModel;
use fabric_runtime::image::Image;
use fabric_runtime::metrics::relative_rmse;
use fabric_runtime::scene::{Camera, Light, Projection, direction_from_angles};

/// Samples per pixel axis of the ground truth, per pixel of the enlarged image.
pub const TRUTH_SUPERSAMPLING: u32 = 16;
/// Samples per level-0 texel axis the truth takes at least.
pub const TRUTH_SAMPLES_PER_TEXEL: f32 = 4.0;
/// Azimuth of the views (degrees).
pub const VIEW_AZIMUTH: f32 = 30.0;

/// One far view's figures.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FarViewError {
    pub polar_deg: f32,
    pub pixels: u32,
    /// Level-0 texels per pixel along the tile's width.
    pub texels_per_pixel: f32,
    /// Relative RMSE of the chain (auto levels, 1 spp) against the truth.
    pub chain: f64,
    /// Relative RMSE of level 0 at 1 spp against the truth.
    pub level0: f64,
    /// The same with nearest-level choice (no blending).
    pub chain_nearest: f64,
    /// The truth's own error (against a second truth on another sample grid).
    pub truth_noise: f64,
}

/// The light of the far views.
pub fn far_light() -> Light {
    Light::directional(direction_from_angles(40.0, 210.0), Vec3::ONE)
}

fn options(level: LevelChoice, supersampling: u32) -> CpuRenderOptions {
    CpuRenderOptions { level, periodic: true, supersampling, ..Default::default() }
}

/// The figures of one camera whose pixels cover about `texels_per_pixel` level-0 texels.
struct Comparison {
    chain: f64,
    level0: f64,
    chain_nearest: f64,
    truth_noise: f64,
}

fn enlarged(camera: &Camera, f: u32) -> Camera {
    Camera { width: camera.width * f, height: camera.height * f, ..*camera }
}

fn compare(model: &HybridModel, camera: &Camera, light: &[Light], texels_per_pixel: f32, filter: CoarseFilter) -> Result<Comparison, CpuRenderError> {
    let f = ((texels_per_pixel * TRUTH_SAMPLES_PER_TEXEL / TRUTH_SUPERSAMPLING as f32).ceil() as u32).clamp(1, 64);
    let big = enlarged(camera, f);
    let truth = render(model, &big, light, &options(LevelChoice::Fixed(0), TRUTH_SUPERSAMPLING))?.box_downsample(f);
    let other = render(model, &big, light, &options(LevelChoice::Fixed(0), 11))?.box_downsample(f);
    // The chain with the coarse filter under test; level 0 and the truth have no coarse level.
    let chain = render(model, camera, light, &CpuRenderOptions { coarse_filter: filter, ..options(LevelChoice::Auto { bias: 0.0 }, 1) })?;
    let nearest = render(model, camera, light, &CpuRenderOptions { coarse_filter: filter, ..options(LevelChoice::Nearest { bias: 0.0 }, 1) })?;
    let level0 = render(model, camera, light, &options(LevelChoice::Fixed(0), 1))?;
    let e = |a: &Image| relative_rmse(a, &truth).unwrap_or(f64::INFINITY);
    Ok(Comparison { chain: e(&chain), level0: e(&level0), chain_nearest: e(&nearest), truth_noise: e(&other) })
}

/// The orthographic far view at polar `polar_deg` with the tile's width over `pixels`.
pub fn far_camera(model: &HybridModel, polar_deg: f32, pixels: u32) -> Camera {
    far_camera_at(model, polar_deg, VIEW_AZIMUTH, pixels)
}

/// [`far_camera`] at azimuth `azimuth_deg` (0: pixel rows along the tile's axes).
pub fn far_camera_at(model: &HybridModel, polar_deg: f32, azimuth_deg: f32, pixels: u32) -> Camera {
    let b = model.bounds();
    let centre = Vec3::new(0.5 * (b.min.x + b.max.x), 0.5 * (b.min.y + b.max.y), model.tile.top_z);
    let extent = model.tile.size.x;
    Camera::orbit_orthographic(polar_deg, azimuth_deg, centre, 4.0 * extent.max(model.tile.size.y), extent, pixels, pixels)
}

/// Errors of the far view at `polar_deg`, the tile's width over `pixels` pixels.
pub fn far_view(model: &HybridModel, polar_deg: f32, pixels: u32) -> Result<FarViewError, CpuRenderError> {
    far_view_at(model, polar_deg, VIEW_AZIMUTH, pixels)
}

/// [`far_view`] at azimuth `azimuth_deg`.
pub fn far_view_at(model: &HybridModel, polar_deg: f32, azimuth_deg: f32, pixels: u32) -> Result<FarViewError, CpuRenderError> {
    far_view_filtered(model, polar_deg, azimuth_deg, pixels, CoarseFilter::default())
}

/// [`far_view_at`] with the chain rendered through `filter` (`--coarse-filter`).
pub fn far_view_filtered(model: &HybridModel, polar_deg: f32, azimuth_deg: f32, pixels: u32, filter: CoarseFilter) -> Result<FarViewError, CpuRenderError> {
    let camera = far_camera_at(model, polar_deg, azimuth_deg, pixels);
    let texels_per_pixel = model.width() as f32 / pixels as f32;
    // A grazing view stretches the footprint by 1/cos θ along the view.
    let stretch = 1.0 / polar_deg.to_radians().cos().max(0.1);
    let c = compare(model, &camera, &[far_light()], texels_per_pixel * stretch, filter)?;
    Ok(FarViewError { polar_deg, pixels, texels_per_pixel, chain: c.chain, level0: c.level0, chain_nearest: c.chain_nearest, truth_noise: c.truth_noise })
}

/// One step of the distance sweep.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SweepStep {
    pub distance: f32,
    /// Level-0 texels per pixel at the image centre.
    pub texels_per_pixel: f32,
    pub chain: f64,
    pub level0: f64,
    pub chain_nearest: f64,
    pub truth_noise: f64,
}

/// The distance sweep: `steps` perspective views of `pixels`² at polar 45°, from where
/// a pixel covers ½ texel to 32 texels at the image centre (geometric steps).
pub fn distance_sweep(model: &HybridModel, pixels: u32, steps: usize) -> Result<Vec<SweepStep>, CpuRenderError> {
    distance_sweep_filtered(model, pixels, steps, CoarseFilter::default())
}

/// [`distance_sweep`] with the chain rendered through `filter` (`--coarse-filter`).
pub fn distance_sweep_filtered(model: &HybridModel, pixels: u32, steps: usize, filter: CoarseFilter) -> Result<Vec<SweepStep>, CpuRenderError> {
    let (near, far) = (0.5f32, 32.0f32);
    (0..steps).map(|s| sweep_step_filtered(model, pixels, near * (far / near).powf(s as f32 / (steps.max(2) - 1) as f32), filter)).collect()
}

/// One step of [`distance_sweep`]: the tile at 45° from where a pixel at the view's
/// centre spans `texels` level-0 texels.
pub fn sweep_step(model: &HybridModel, pixels: u32, texels: f32) -> Result<SweepStep, CpuRenderError> {
    sweep_step_filtered(model, pixels, texels, CoarseFilter::default())
}

/// [`sweep_step`] with the chain rendered through `filter`.
pub fn sweep_step_filtered(model: &HybridModel, pixels: u32, texels: f32, filter: CoarseFilter) -> Result<SweepStep, CpuRenderError> {
    let b = model.bounds();
    let centre = Vec3::new(0.5 * (b.min.x + b.max.x), 0.5 * (b.min.y + b.max.y), model.tile.top_z);
    let fov = 40f32;
    let texel = model.texel_size().x;
    // At distance d a pixel spans 2 d tan(fov/2) / pixels at the centre (perpendicular).
    let pixel_at = |d: f32| 2.0 * d * (0.5 * fov).to_radians().tan() / pixels as f32;
    let dir = direction_from_angles(45.0, VIEW_AZIMUTH);
    let d = texels * texel / pixel_at(1.0);
    let camera = Camera { origin: centre + d * dir, target: centre, up: Vec3::Z, projection: Projection::Perspective { fov_x_deg: fov }, width: pixels, height: pixels };
    // The far corners of the view see up to ~1.6 times the centre's footprint.
    let c = compare(model, &camera, &[far_light()], 1.6 * texels * std::f32::consts::SQRT_2, filter)?;
    Ok(SweepStep { distance: d, texels_per_pixel: texels, chain: c.chain, level0: c.level0, chain_nearest: c.chain_nearest, truth_noise: c.truth_noise })
}
