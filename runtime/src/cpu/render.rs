//! The per-pixel program (the CPU twin of the GPU renderer's fragment shader) and the
//! image loop around it (rayon over rows).
//!
//! For a pixel: the camera ray enters the tile's top plane (outside the tile, or from
//! below: background); the height field is marched from the entry to the first surface
//! hit (every level shares it); the level comes from the pixel's footprint at that hit
//! (two adjacent levels, blended), or is fixed; per level, the flyaway lists are
//! marched over the same stretch and composited front to back, and what they let
//! through sees the surface, shaded with its texel's lobes.


// `!(x > 0.0)` is the NaN-aware test (NaN fails it), as the GLSL writes it.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::flyaways::{FlyawayGrid, march_flyaways, visit_flyaways};
use super::heightfield::{HeightTracer, HfTrace};
use super::env_shading::{EnvBudget, texel_env_response, transmission_env_response};
use crate::brdf::visible_normal::{tilt_frames, view_visibility};
use super::shading::{in_fiber_frame, shade, shade_blend, volume_factor};
use super::edits::Edit;
use super::{CpuRenderError, CpuRenderOptions, LevelChoice, RenderStats, ShadowMode};
// The level rules live in level.rs; re-exported here, where they were first written.
pub use super::level::*;
use crate::brdf::{BrdfReading, DiffuseLaw};
use crate::hybrid::{HybridModel, TexelBrdf};
use crate::image::Image;
use crate::scene::{Camera, Light, LightSample, Ray};

/// The camera of [`Scene::for_rays`]: valid, never used to make rays.
static NO_CAMERA: Camera = Camera {
    origin: Vec3::new(0.0, 0.0, 1.0),
    target: Vec3::ZERO,
    up: Vec3::Y,
    projection: crate::scene::Projection::Orthographic { extent: 1.0 },
    width: 1,
    height: 1,
};

/// Everything prepared once per image.
pub struct Scene<'a> {
    pub model: &'a HybridModel,
    pub camera: &'a Camera,
    pub lights: &'a [Light],
    pub options: CpuRenderOptions,
    pub tracer: HeightTracer,
    pub shadows: bool,
    reading: BrdfReading,
    /// The surface texels' diffuse law (the model's; flyaways are Lambert's).
    diffuse: DiffuseLaw,
    /// Whether `options.edits` changes anything.
    edited: bool,
    pub(crate) grids: Vec<FlyawayGrid>,
}


/// What the flyaways let through in front of each lookup of a surface grid (`offsets`
/// from the pixel's hit): the transmittance `fly_t` of the flyaway ray whose cell holds
/// it ([`fly_cell`]; rays in [`tap_offset`] order over `fly_axes`, `fly_taps`), scaled so
/// that their mean is the pixel's `mean_t` (the rays and the lookups spread differently,
/// and unscaled the cells shift the mean: felt's 32 px view at 45° went from 6.1 to
/// 17.4%). All `mean_t` where no lookup sees through. Twin: `lookup_transmittances` in
/// shaders/common/trace.glsl.
pub fn lookup_transmittances(offsets: &[Vec2], fly_t: &[f32], fly_axes: (Vec2, Vec2), fly_taps: (u32, u32), mean_t: f32) -> Vec<f32> {
    let t: Vec<f32> = offsets.iter().map(|&o| fly_t.get(fly_cell(o, fly_axes.0, fly_taps.0, fly_axes.1, fly_taps.1) as usize).copied().unwrap_or(mean_t)).collect();
    let mean = t.iter().sum::<f32>() / t.len().max(1) as f32;
    if mean > 0.0 { t.iter().map(|x| x * mean_t / mean).collect() } else { vec![mean_t; t.len()] }
}

/// The split filter's flyaway radiance: each shading ray's colour (its radiance
/// `box_rays[k].0` per unit of its opacity 1 − `box_rays[k].1`) times the mean opacity
/// of the coverage rays in its cell (`cell_opacity[k]`: their summed opacity and count;
/// the ray's own where none fell in it), averaged over the cells. Where a shading ray met
/// nothing its cell's coverage rays met, the pixel's mean colour. Twin:
/// `spread_colours` in shaders/common/trace.glsl.
pub fn spread_colours(box_rays: &[(Vec3, f32)], cell_opacity: &[(f32, u32)]) -> Vec3 {
    let (radiance, opacity) = box_rays.iter().fold((Vec3::ZERO, 0.0f32), |(r, o), (f, t)| (r + *f, o + (1.0 - t)));
    let mean_colour = if opacity > 1e-4 { radiance / opacity } else { Vec3::ZERO };
    let share = 1.0 / box_rays.len().max(1) as f32;
    box_rays
        .iter()
        .zip(cell_opacity)
        .map(|((f, t), &(o_sum, n))| {
            let o = 1.0 - t;
            let cover_o = if n > 0 { o_sum / n as f32 } else { o };
            let colour = if o > 1e-4 { *f / o } else { mean_colour };
            colour * cover_o * share
        })
        .sum()
}

/// The light a flyaway march shades its nodes with: `SplitShaded` shades the lights
/// along its finer grid and the environment's SG part along the box grid. Twin:
/// FLY_LIGHT_* in shaders/common/shading.glsl.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum FlyLight {
    All,
    /// The lights (with an environment's extracted sources), not its SG part.
    Lights,
    /// The environment's SG part alone.
    Env,
}

/// One level's flyaways along a ray.
struct FlyShade {
    radiance: Vec3,
    transmittance: f32,
    limited: bool,
    shadow_limited: u32,
}

/// Where a pixel's flyaway rays met the surface, in grid order ([`tap_offset`] over
/// `axes`, `taps`; None where a ray missed), for level 0's lookups to share.
struct FlyHits<'h> {
    hits: &'h [Option<Vec3>],
    axes: (Vec2, Vec2),
    taps: (u32, u32),
}

/// What one camera ray found.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PixelTrace {
    pub radiance: Vec3,
    /// The level used, the finer of a blend's two (None: the ray missed the tile).
    pub level: Option<usize>,
    /// Ray parameter of the surface hit.
    pub surface_t: Option<f32>,
    /// Opacity of the flyaways in front of the surface (0 = none crossed).
    pub flyaway_opacity: f32,
    pub step_limited: bool,
    pub shadow_step_limited: u32,
    /// Height-field traversal steps of the camera ray.
    pub steps: u32,
}

impl<'a> Scene<'a> {
    /// Validates everything and builds the accelerators.
    pub fn new(model: &'a HybridModel, camera: &'a Camera, lights: &'a [Light], options: CpuRenderOptions) -> Result<Scene<'a>, CpuRenderError> {
        let shadows = validate_render(model, camera, lights, &options)?;
        let grids = (0..model.levels.len()).map(|l| FlyawayGrid::new(model, l, options.periodic)).collect();
        Ok(Scene { model, camera, lights, tracer: HeightTracer::new(model, options.periodic), shadows, reading: model.meta.reading, diffuse: model.meta.diffuse, grids, edited: !options.edits.is_identity(), options })
    }

    /// A scene for rays given by the caller rather than by a camera (the baker's probe,
    /// [`super::probe`]): `trace_ray` and `probe_ray` work, pixel methods do not apply.
    pub fn for_rays(model: &'a HybridModel, lights: &'a [Light], options: CpuRenderOptions) -> Result<Scene<'a>, CpuRenderError> {
        Scene::new(model, &NO_CAMERA, lights, options)
    }

    /// Where a ray enters the top plane (t), or None: from below, parallel, or (on a
    /// clamped tile) outside the tile.
    pub fn enter_top(&self, ray: &Ray) -> Option<f32> {
        let tile = &self.model.tile;
        if !(ray.d.z < 0.0) || ray.o.z < tile.top_z {
            return None;
        }
        let t = (tile.top_z - ray.o.z) / ray.d.z;
        if !self.options.periodic {
            let p = ray.at(t).truncate() - tile.origin;
            if p.x < 0.0 || p.y < 0.0 || p.x > tile.size.x || p.y > tile.size.y {
                return None;
            }
        }
        Some(t)
    }

    /// The level for pixel (px, py) (continuous, pixel centre at +0.5), from its
    /// footprint on the top plane: the level shading most of the pixel (the lower of a
    /// blend's two when they weigh the same).
    pub fn pixel_level(&self, px: f32, py: f32) -> usize {
        let mix = self.level_mix(px, py, self.model.tile.top_z);
        if mix.weight > 0.5 { mix.hi } else { mix.lo }
    }

    /// The levels that shade pixel (px, py) when its ray meets the surface at height `z`.
    /// With s × s samples per pixel each sample filters its own sub-pixel, 1/s of the
    /// pixel's footprint across: the samples then add up to the pixel's box, and more of
    /// them converge on the supersampled truth. (Each sample filtering the whole pixel,
    /// as until 2026-12, blurred the box over the sample grid: satin's 16 px far view at
    /// 45° was 14.1% off with 8 × 8 samples against 9.7% with one.)
    pub fn level_mix(&self, px: f32, py: f32, z: f32) -> LevelMix {
        if let LevelChoice::Fixed(l) = self.options.level {
            return LevelMix::single(l as usize);
        }
        let k = 1.0 / self.options.supersampling.max(1) as f32;
        self.level_mix_axes(self.footprint_axes_at(px, py, z).map(|(a, b)| (a * k, b * k)))
    }

    /// The levels for a footprint with axes (a, b) — world x–y steps to where the next
    /// pixel right and down meet the surface's plane — or None where one of them misses
    /// it (the coarsest level). A mesh renderer gives screen-space derivatives here.
    pub fn level_mix_axes(&self, axes: Option<(Vec2, Vec2)>) -> LevelMix {
        let last = self.model.levels.len() - 1;
        let (bias, nearest) = match self.options.level {
            LevelChoice::Fixed(l) => return LevelMix::single(l as usize),
            LevelChoice::Auto { bias } => (bias, false),
            LevelChoice::Nearest { bias } => (bias, true),
        };
        let Some((a, b)) = axes else {
            return LevelMix::single(last);
        };
        let inv_texel = self.model.inv_texel_size();
        let (la, lb) = ((a * inv_texel).length(), (b * inv_texel).length());
        let (major, minor, axis, minor_axis) = if la >= lb { (la, lb, a, b) } else { (lb, la, b, a) };
        if !(major > 0.0) {
            return LevelMix::single(0);
        }
        if !major.is_finite() {
            return LevelMix::single(last);
        }
        if nearest {
            // Isotropic, as Vulkan's nearest-mip rule: the longer axis.
            let lambda = major.log2() + bias;
            return LevelMix::single(((lambda + 0.5).floor().max(0.0) as usize).min(last));
        }
        // Anisotropic (Vulkan's rule, EXT_texture_filter_anisotropic): N = ⌈major/minor⌉
        // lookups along the major axis at the level of major/N.
        // 1e-3: a round footprint measured as 8.00001 × 8 is one lookup, not two.
        let n = ((major / minor.max(1e-6) - 1e-3).ceil() as u32).clamp(1, MAX_ANISOTROPY);
        let lambda = (major / n as f32).log2() + FILTER_OFFSET + bias;
        let g = self.options.coarse_filter.grid();
        let fly_grid = fly_box_grid(major, n, bias, self.options.coarse_filter.fly_grid());
        let fly = linear_levels(fly_grid.lambda, last);
        let shadow = linear_levels(shadow_lambda(major, minor, bias), last);
        let (fly_axes, fly_taps) = if fly_grid.spread > 0.0 { ((axis * fly_grid.spread, minor_axis * fly_grid.spread), (fly_grid.taps_major, fly_grid.taps_minor)) } else { ((Vec2::ZERO, Vec2::ZERO), (1, 1)) };
        // `Split`: the coverage from the fine grid, where both grids spread and the shading
        // rays march a coarse level: at level 0 the finer grid's voxels are theirs, and its
        // 16 rays only supersample them (the demo's sphere, 1–3 texels per pixel, cost 3×
        // the box's frame on lavapipe with them; baker/PREFILTER_MEASUREMENTS.md, "The
        // split filter as the default").
        let cover = (self.options.coarse_filter.cover_grid() != self.options.coarse_filter.fly_grid() && fly_grid.spread > 0.0 && fly_grid.lambda > 0.0)
            .then(|| fly_box_grid(major, n, bias, self.options.coarse_filter.cover_grid()))
            .filter(|c| c.spread > 0.0)
            .map(|c| FlyCover { fly: linear_levels(c.lambda, last), axes: (axis * c.spread, minor_axis * c.spread), taps: (c.taps_major, c.taps_minor) });
        let Some(grid) = box_grid(major, minor, n, lambda, bias, g) else {
            // With a grid, level 0 alone up to [`LEVEL0_REACH`] texels (λ ≤ 1 here);
            // without one, Vulkan's linear-mip blend.
            let (lo, hi, weight) = if g > 1 { (0, 0, 0.0) } else { linear_levels(lambda, last) };
            let blend = if g > 1 { lambda.clamp(0.0, 1.0) } else { weight };
            // Level 0 is read through a grid of its nearest texels ([`level0_grid_taps`],
            // evenly over the footprint) once the footprint is a good part of a texel: one
            // texel at the hit point-samples a box that a texel's border may cross, which
            // aliases (sharp texel-to-texel contrast at ½–2 texels per pixel). The grid spreads
            // with the footprint's minor axis, from nothing at [`FINE_GRID_FROM`] texels
            // to the whole footprint at [`FINE_GRID_FULL`] (along the major axis as wide
            // in texels as along the minor), and past λ = 0 (where level 1 was once
            // blended in) at least from nothing at λ = 0 to the whole footprint at λ = ½
            // (baker/PREFILTER_MEASUREMENTS.md, "Level 0 through a grid where it is
            // blended", "Level 0 through a grid from a quarter texel across"). Close-ups,
            // at most a quarter texel per pixel, read the hit's texel alone, as before.
            let beyond = fine_grid_spread(minor);
            let (fine_axes, fine_taps) = if lo == 0 && (blend > 0.0 || beyond > 0.0) && g > 1 {
                // Along the major axis, a grazing view's offsets in the plane land on texels
                // the pixel's rays do not meet (parallax): there the minor axis's width in
                // texels, at most (measured at 70°: the full major spread made satin's
                // far view 24% too bright).
                let blended = (2.0 * blend).min(1.0);
                let spread_minor = blended.max(beyond);
                let spread_major = blended.max(beyond * minor / major);
                ((axis * spread_major, minor_axis * spread_minor), level0_grid_taps(minor, n, g))
            } else {
                ((Vec2::ZERO, Vec2::ZERO), (1, 1))
            };
            return LevelMix { lo, hi, weight, axis, taps: n, minor_axis: Vec2::ZERO, taps_minor: 1, fly, shadow, fly_axes, fly_taps, fine_axes, fine_taps, cover };
        };
        let (axis_b, minor_b) = (axis * (grid.span_major / major), minor_axis * (grid.span_minor / minor.max(1e-6)));
        // Level 0's grid blended with level 1's box grid up to where a FILTER_GRID grid's
        // level reaches 1 ([`level0_reach_weight`]): the reach is a footprint's size, not
        // the surface grid's (with a 3 × 3 grid measured in its own lookups, level 0 read
        // 16 lookups over satin's 11 × 8-texel footprints at 45°: 5.4 → 8.1% for the
        // surface alone).
        let reach = level0_reach_weight((major / grid_taps(n, FILTER_GRID) as f32).log2() + FILTER_OFFSET + bias);
        // A model without a chain reads level 0 through its grid at every distance.
        if last == 0 {
            return LevelMix { lo: 0, hi: 0, weight: 0.0, axis: Vec2::ZERO, taps: 1, minor_axis: Vec2::ZERO, taps_minor: 1, fly, shadow, fly_axes, fly_taps, fine_axes: (axis, minor_axis), fine_taps: level0_grid_taps(minor, n, g), cover };
        }
        if reach < 1.0 {
            return LevelMix { lo: 0, hi: 1, weight: reach, axis: axis_b, taps: grid.taps_major, minor_axis: minor_b, taps_minor: grid.taps_minor, fly, shadow, fly_axes, fly_taps, fine_axes: (axis, minor_axis), fine_taps: level0_grid_taps(minor, n, g), cover };
        }
        let (lo, hi, weight) = linear_levels(grid.lambda, last);
        LevelMix { lo, hi, weight, axis: axis_b, taps: grid.taps_major, minor_axis: minor_b, taps_minor: grid.taps_minor, fly, shadow, fly_axes, fly_taps, fine_axes: (Vec2::ZERO, Vec2::ZERO), fine_taps: (1, 1), cover }
    }

    /// The steps, in world x–y on the plane at height `z`, to where the rays through the
    /// next pixel right and down meet it; None if one of them misses the plane.
    pub fn footprint_axes_at(&self, px: f32, py: f32, z: f32) -> Option<(Vec2, Vec2)> {
        let on_plane = |x: f32, y: f32| -> Option<Vec2> {
            let r = self.camera.ray(x, y);
            if !(r.d.z < 0.0) || r.o.z < z {
                return None;
            }
            Some(r.at((z - r.o.z) / r.d.z).truncate())
        };
        let (c, a, b) = (on_plane(px, py)?, on_plane(px + 1.0, py)?, on_plane(px, py + 1.0)?);
        Some((a - c, b - c))
    }

    /// The pixel's footprint on the top plane in level-0 texels (see
    /// [`Scene::footprint_texels_at`]).
    pub fn footprint_texels(&self, px: f32, py: f32) -> f32 {
        self.footprint_texels_at(px, py, self.model.tile.top_z)
    }

    /// The pixel's footprint on the plane at height `z` in level-0 texels: the longer of
    /// the steps to the next pixel right and down (∞ if one of them misses the plane).
    pub fn footprint_texels_at(&self, px: f32, py: f32, z: f32) -> f32 {
        let inv_texel = self.model.inv_texel_size();
        match self.footprint_axes_at(px, py, z) {
            Some((a, b)) => (a * inv_texel).length().max((b * inv_texel).length()),
            None => f32::INFINITY,
        }
    }

    /// The level-ℓ texel under world point `p` (wrapped or clamped into the tile).
    pub fn texel_at(&self, p: Vec3, level: usize) -> (u32, u32) {
        let m = self.model;
        // A product with 1/texel, as the GPU twin: HybridModel::inv_texel_size.
        let u = (p.truncate() - m.tile.origin) * m.inv_texel_size();
        let (w, h) = (m.width() as i32, m.height_px() as i32);
        let (i, j) = (u.x.floor() as i32, u.y.floor() as i32);
        let (i, j) = if self.options.periodic { (i.rem_euclid(w), j.rem_euclid(h)) } else { (i.clamp(0, w - 1), j.clamp(0, h - 1)) };
        ((i >> level) as u32, (j >> level) as u32)
    }

    /// The four level-ℓ texels around world point `p` with their bilinear weights
    /// (texel centres at +½; wrapped on a periodic tile, clamped at a clamped tile's
    /// edges): coarse levels are filtered like a texture's mip levels, so that a pixel
    /// between four coarse texels sees their blend rather than one of them. Level 0 is
    /// shaded by its nearest texel (the model's own data).
    pub fn bilinear_texels(&self, p: Vec3, level: usize) -> [(TexelBrdf, f32); 4] {
        let l = &self.model.levels[level];
        self.bilinear_corners(p, level).map(|((i, j), w)| (l.texel_brdf(i, j), w))
    }

    /// [`Scene::bilinear_texels`] as seen from `wo`: where the level has view tilts
    /// (`brdf::visible_normal`), each texel's frames turned toward the viewer; with its
    /// bilinear weight and its visibility v(ω_o) (1 without a tilt).
    pub fn bilinear_texels_seen(&self, p: Vec3, level: usize, wo: Vec3) -> [(TexelBrdf, f32, f32); 4] {
        self.bilinear_corners(p, level).map(|((i, j), w)| {
            let (b, v) = self.texel_seen(level, i, j, wo);
            (b, w, v)
        })
    }

    /// Texel (i, j) of `level` as seen from `wo`: its frames turned by the level's view
    /// tilt, with the tilt's visibility (1 without a tilt).
    fn texel_seen(&self, level: usize, i: u32, j: u32, wo: Vec3) -> (TexelBrdf, f32) {
        let l = &self.model.levels[level];
        let mut b = l.texel_brdf(i, j);
        match l.view_tilt_at(i, j) {
            Some(tilt) => {
                let n = (b.params.lobe_count as usize).clamp(1, crate::brdf::MAX_LOBES);
                tilt_frames(&mut b.frames[..n], &tilt, wo);
                (b, view_visibility(&tilt, wo))
            }
            None => (b, 1.0),
        }
    }

    /// The texels and weights of [`Scene::bilinear_texels`].
    fn bilinear_corners(&self, p: Vec3, level: usize) -> [((u32, u32), f32); 4] {
        let m = self.model;
        let l = &m.levels[level];
        let (w, h) = (l.width as i32, l.height as i32);
        let mut x = (p.truncate() - m.tile.origin) * m.inv_texel_size();
        // On a periodic tile whose size 2^level does not divide, the level's grid repeats
        // every (its size · 2^level) level-0 texels, longer than the tile: lookups in later
        // repeats would drift by a texel per repeat. The point is brought into the first
        // repeat then; where 2^level divides the size the grids agree and nothing changes.
        let span = 1i32 << level;
        if self.options.periodic {
            let n0 = [m.width() as i32, m.height_px() as i32];
            for a in 0..2 {
                if n0[a] % span != 0 {
                    x[a] -= n0[a] as f32 * (x[a] / n0[a] as f32).floor();
                }
            }
        }
        // 2^-level is exact: the GPU twin's ldexp.
        let u = x * (1.0 / span as f32) - Vec2::splat(0.5);
        let (i0, j0) = (u.x.floor(), u.y.floor());
        let (fx, fy) = (u.x - i0, u.y - j0);
        let index = |i: i32, n: i32| if self.options.periodic { i.rem_euclid(n) } else { i.clamp(0, n - 1) };
        let (i0, j0) = (i0 as i32, j0 as i32);
        let texel = |di: i32, dj: i32, weight: f32| ((index(i0 + di, w) as u32, index(j0 + dj, h) as u32), weight);
        [texel(0, 0, (1.0 - fx) * (1.0 - fy)), texel(1, 0, fx * (1.0 - fy)), texel(0, 1, (1.0 - fx) * fy), texel(1, 1, fx * fy)]
    }

    /// The edit at world point `p` (its position in the tile looks up the mask).
    pub fn edit_at(&self, p: Vec3) -> Edit {
        let t = &self.model.tile;
        self.options.edits.at((p.truncate() - t.origin) / t.size)
    }

    /// Visibility of a light from `p` (height-field shadow ray), counting step-limited
    /// shadow rays.
    pub fn visibility(&self, p: Vec3, s: &LightSample, limited: &mut u32) -> f32 {
        if !self.shadows {
            return 1.0;
        }
        let (blocked, hit_limit) = self.tracer.occluded(p, s.wi, s.distance, self.options.max_steps);
        *limited += hit_limit as u32;
        if blocked { 0.0 } else { 1.0 }
    }

    /// What the flyaways of `level` let through from the surface point `p` toward a light
    /// in direction `wi` at `distance`: the path from `p` to the top plane (or to the
    /// light, if nearer), marched down from its upper end as a camera ray is (the coarser
    /// level of [`Scene::grazing_level`] past its column budget); with whether the march
    /// ran out of columns. A surface hit reads its footprint's levels
    /// ([`Scene::flyaway_shadow_mixed`]). 1 unless the model's flyaways shadow the surface
    /// (`BakeMetadata::flyaway_shadow`, format 1.13) and flyaways are rendered, or for a
    /// light below the sheet. The height field's shadow rays are another matter: the
    /// bake fits without them by default, and the flyaways' shadow holds either way.
    /// Only the surface is shadowed so: a flyaway's own lights see the height field
    /// alone, since the flyaways shadowing each other too darkened felt to 0.80–0.97 of
    /// the truth's mean (baker/FIT_MEASUREMENTS.md, "The flyaways' shadow on the
    /// surface"). Twin: `flyaway_shadow` in shaders/common/trace.glsl.
    pub fn flyaway_shadow(&self, level: usize, p: Vec3, wi: Vec3, distance: f32) -> (f32, bool) {
        if !self.options.flyaways || !self.model.meta.flyaway_shadow || !(wi.z > 0.0) {
            return (1.0, false);
        }
        let s = ((self.model.tile.top_z - p.z) / wi.z).min(distance);
        if !(s > 0.0 && s.is_finite()) {
            return (1.0, false);
        }
        let ray = Ray::new(p + wi * s, -wi);
        self.level_transmittance(self.grazing_level(&ray, 0.0, s, level), &ray, 0.0, s)
    }

    /// What the flyaways of `level` let through along `ray` over [t_start, t_end],
    /// unshaded, and whether the march ran out of columns ((1, false) where the level has
    /// none).
    fn level_transmittance(&self, level: usize, ray: &Ray, t_start: f32, t_end: f32) -> (f32, bool) {
        match self.model.levels[level].flyaways.as_ref().filter(|f| !f.nodes.is_empty()) {
            Some(f) => {
                let m = visit_flyaways(f, &self.grids[level], ray, t_start, t_end, self.options.max_flyaway_columns, |_, _, _, _| {});
                (m.transmittance, m.limited)
            }
            None => (1.0, false),
        }
    }

    /// [`Scene::flyaway_shadow`] blended over the levels `(lo, hi, weight of hi)` of a
    /// pixel's footprint (`LevelMix::shadow`): a footprint of many texels reads one
    /// shadow for all of them, a coarse level's, where level 0's from the hit alone
    /// would stand for every texel of it (felt 64², far views at 4 texels per pixel:
    /// 20–25% off the supersampled level 0 with level 0's shadow, 9.5–14% with the
    /// footprint's level; [`shadow_lambda`]). Returns the marches that ran out of columns
    /// with it. Twin: `flyaway_shadow_mixed` in shaders/common/trace.glsl.
    pub fn flyaway_shadow_mixed(&self, (lo, hi, w): (usize, usize, f32), p: Vec3, wi: Vec3, distance: f32) -> (f32, u32) {
        let (t, limited) = self.flyaway_shadow(lo, p, wi, distance);
        if w > 0.0 && hi != lo {
            let (th, lh) = self.flyaway_shadow(hi, p, wi, distance);
            return (t * (1.0 - w) + th * w, limited as u32 + lh as u32);
        }
        (t, limited as u32)
    }

    /// [`Scene::flyaway_sky`] blended over the flyaway levels `(lo, hi, weight of hi)`.
    /// Twin: `flyaway_sky_mixed` in shaders/common/trace.glsl.
    pub fn flyaway_sky_mixed(&self, (lo, hi, w): (usize, usize, f32), p: Vec3) -> f32 {
        let t = self.flyaway_sky(lo, p);
        if w > 0.0 && hi != lo {
            return t * (1.0 - w) + self.flyaway_sky(hi, p) * w;
        }
        t
    }

    /// What the flyaways of `level` let through of the environment at surface point `p`:
    /// their transmittance straight up, one column (1 where [`Scene::flyaway_shadow`] is).
    /// An approximation: the map's light comes from the whole sky, through longer paths
    /// the lower it comes, and the column above `p` stands for all of them
    /// (env_shading.rs states the approximations). Twin: `flyaway_sky` in
    /// shaders/common/trace.glsl.
    pub fn flyaway_sky(&self, level: usize, p: Vec3) -> f32 {
        let s = self.model.tile.top_z - p.z;
        if !self.options.flyaways || !self.model.meta.flyaway_shadow || !(s > 0.0 && s.is_finite()) {
            return 1.0;
        }
        self.level_transmittance(level, &Ray::new(Vec3::new(p.x, p.y, self.model.tile.top_z), Vec3::NEG_Z), 0.0, s).0
    }

    /// Traces one ray at `level`.
    pub fn trace_ray(&self, ray: &Ray, level: usize) -> PixelTrace {
        self.trace_mixed(ray, &|_| LevelMix::single(level))
    }

    /// Traces one ray, shading with the levels `choose(z)` gives for the height z where
    /// it meets the surface (the top plane if it misses): the height field is marched
    /// once, the flyaways and the surface are shaded per level and blended.
    pub fn trace_mixed(&self, ray: &Ray, choose: &dyn Fn(f32) -> LevelMix) -> PixelTrace {
        let background = match &self.options.env {
            // Level 0 of the chain, bilinear: what the GPU reads too (no copy of the full map).
            Some(e) if e.background => e.prefiltered.blurred(ray.d, 0.0),
            _ => self.options.background,
        };
        let mut out = PixelTrace { radiance: background, ..Default::default() };
        let Some(t_top) = self.enter_top(ray) else {
            return out;
        };
        let mut steps = 0;
        // With coarse relief, the march stops descending at the level of the footprint on
        // the top plane.
        let floor = if self.options.coarse_relief { choose(self.model.tile.top_z).lo } else { 0 };
        let hit = self.tracer.trace_to(ray, t_top, f32::MAX, 0.0, self.options.max_steps, &mut steps, floor);
        out.step_limited = hit == HfTrace::StepLimit;
        out.steps = steps;
        if let HfTrace::Hit(t) = hit {
            out.surface_t = Some(t);
        }
        let z = out.surface_t.map_or(self.model.tile.top_z, |t| ray.at(t).z);
        let mix = choose(z);
        out.level = Some(mix.lo);
        let t_end = out.surface_t.unwrap_or(t_top + self.model.tile.height_scale / -ray.d.z);
        // The flyaways in front, blended over their levels, then what they let through.
        // Over a box grid (`fly_taps` parallel rays spread over `fly_axes`), each ray
        // blending its two levels and stopping where it meets the surface itself; one ray
        // where there is no grid.
        let ((ga, gb), (fa, fb)) = ((mix.fly_taps.0.max(1), mix.fly_taps.1.max(1)), mix.fly_axes);
        let share = 1.0 / (ga * gb) as f32;
        let mut fly = FlyShade { radiance: Vec3::ZERO, transmittance: 0.0, limited: false, shadow_limited: 0 };
        // Each grid ray's transmittance (what it lets through of the surface where it
        // lands), in grid order.
        let mut fly_rays: Vec<f32> = Vec::new();
        // ... and where each met the surface (None: it missed or ran out of steps).
        let mut fly_hits: Vec<Option<Vec3>> = Vec::new();
        // ... and with `Split`, each one's radiance and transmittance (its colour).
        let mut box_rays: Vec<(Vec3, f32)> = Vec::new();
        let covered = mix.cover.is_some() && ga * gb > 1 && self.options.flyaways && self.model.has_flyaways();
        // `SplitShaded`: the cover grid's rays bring the lights' light; the box rays land
        // and bring the environment's SG part, smooth enough for their coarser grid (with
        // no environment they only land).
        let shaded_cover = covered && self.options.coarse_filter.cover_shaded();
        let box_light = if shaded_cover { FlyLight::Env } else { FlyLight::All };
        for k in 0..ga * gb {
            let (r, t_end) = if ga * gb == 1 {
                (*ray, t_end)
            } else {
                let r = Ray::new(ray.o + tap_offset(fa, ga, fb, gb, k).extend(0.0), ray.d);
                let (t_end, landed) = self.own_surface_end(&r, t_top, t_end, floor, &mut out);
                fly_hits.push(landed.then(|| r.at(t_end)));
                (r, t_end)
            };
            if shaded_cover && self.options.env.is_none() {
                continue;
            }
            let f = self.march_blended_flyaways(&r, t_top, t_end, mix.fly, box_light);
            if ga * gb > 1 {
                fly_rays.push(f.transmittance);
                if mix.cover.is_some() {
                    box_rays.push((f.radiance, f.transmittance));
                }
            }
            fly.radiance += f.radiance * share;
            fly.transmittance += f.transmittance * share;
            fly.limited |= f.limited;
            fly.shadow_limited += f.shadow_limited;
        }
        // `Split`: the coverage from the finer grid's unshaded rays, each box ray's
        // colour spread over the opacity of the fine rays in its cell; `SplitShaded`: the
        // coverage and the lights' light from the finer grid's rays, the environment's
        // spread so.
        // (The box rays' hits stay level 0's to borrow: the surface is the box filter's.)
        let hits_grid = ((fa, fb), (ga, gb));
        let ((fa, fb), (ga, gb)) = match mix.cover {
            Some(c) if covered => {
                let (cl, ch, cw) = c.fly;
                let (ca, cb) = (c.taps.0.max(1), c.taps.1.max(1));
                let mut cell_opacity = vec![(0.0f32, 0u32); (ga * gb) as usize];
                let mut cover_radiance = Vec3::ZERO;
                let mut rays = Vec::with_capacity((ca * cb) as usize);
                for k in 0..ca * cb {
                    let offset = tap_offset(c.axes.0, ca, c.axes.1, cb, k);
                    let r = Ray::new(ray.o + offset.extend(0.0), ray.d);
                    let (t_end, _) = self.own_surface_end(&r, t_top, t_end, floor, &mut out);
                    let (t, limited) = if shaded_cover {
                        let f = self.march_blended_flyaways(&r, t_top, t_end, c.fly, FlyLight::Lights);
                        cover_radiance += f.radiance;
                        fly.shadow_limited += f.shadow_limited;
                        (f.transmittance, f.limited)
                    } else {
                        self.level_coverage(&r, t_top, t_end, cl, ch, cw)
                    };
                    fly.limited |= limited;
                    rays.push(t);
                    let cell = &mut cell_opacity[fly_cell(offset, fa, ga, fb, gb) as usize];
                    *cell = (cell.0 + 1.0 - t, cell.1 + 1);
                }
                let spread = if box_rays.is_empty() { Vec3::ZERO } else { spread_colours(&box_rays, &cell_opacity) };
                fly.radiance = if shaded_cover { cover_radiance / (ca * cb) as f32 + spread } else { spread };
                fly.transmittance = rays.iter().sum::<f32>() / rays.len() as f32;
                fly_rays = rays;
                (c.axes, (ca, cb))
            }
            _ => ((fa, fb), (ga, gb)),
        };
        out.flyaway_opacity = 1.0 - fly.transmittance;
        out.step_limited |= fly.limited;
        out.shadow_step_limited = fly.shadow_limited;
        let mut behind = background;
        let mut behind_weighted = false;
        if let Some(t) = out.surface_t {
            behind = Vec3::ZERO;
            if fly.transmittance > 0.0 {
                // The box grid's lookup points, once for both levels of a blend.
                let coarse = mix.lo > 0 || (mix.weight > 0.0 && mix.hi > 0);
                let (n, m) = (mix.taps, mix.taps_minor);
                let points: Vec<Vec3> = if coarse && n * m > 1 { (0..n * m).map(|k| self.tap_surface_point(ray, tap_offset(mix.axis, n, mix.minor_axis, m, k), ray.at(t), floor)).collect() } else { Vec::new() };
                let (f0, f1) = mix.fine_taps;
                // Level 0's grid, each lookup (past half a texel across) where its own parallel
                // ray meets the height field, as the coarse grid's: at ½–2 texels per pixel the one ray's hit jumps
                // between crest and valley, which the offsets beside it kept (satin's
                // surface at the sweep's first three steps 8.1 / 9.3 / 11.0% → 5.6 / 6.1 /
                // 6.8%; twill had gained 0–0.4 points; baker/PREFILTER_MEASUREMENTS.md,
                // "Level 0's lookups where their rays land").
                // A close-up's grid, under half a texel across, reads beside the hit
                // ([`FINE_TRACE_FROM`]).
                let traced = fine_grid_traced(mix.fine_axes, self.model.inv_texel_size());
                let fly_grid = FlyHits { hits: &fly_hits, axes: hits_grid.0, taps: hits_grid.1 };
                let fine_point = |k: u32| self.fine_lookup_point(ray, ray.at(t), tap_offset(mix.fine_axes.0, f0, mix.fine_axes.1, f1, k), traced, &fly_grid, floor);
                let fine: Vec<Vec3> = if mix.lo == 0 && f0 * f1 > 1 { (0..f0 * f1).map(fine_point).collect() } else { Vec::new() };
                // Each lookup seen through the flyaway ray whose cell holds it: where the
                // flyaways leave a gap, the surface under it shows. The mean of the rays'
                // transmittance times the mean of the lookups lost where gaps and bright
                // surface go together (baker/PREFILTER_MEASUREMENTS.md, "The surface
                // through the flyaways' gaps").
                let per_lookup = !fly_rays.is_empty();
                let through = |offsets: Vec<Vec2>| if per_lookup && !offsets.is_empty() { lookup_transmittances(&offsets, &fly_rays, (fa, fb), (ga, gb), fly.transmittance) } else { Vec::new() };
                let coarse_t = through(if points.is_empty() { Vec::new() } else { (0..n * m).map(|k| tap_offset(mix.axis, n, mix.minor_axis, m, k)).collect() });
                let fine_t = through(if fine.is_empty() { Vec::new() } else { (0..f0 * f1).map(|k| tap_offset(mix.fine_axes.0, f0, mix.fine_axes.1, f1, k)).collect() });
                let lo_t = if mix.lo == 0 { &fine_t } else { &coarse_t };
                let shade = |level: usize, points: &[Vec3], lookup_t: &[f32]| if per_lookup { self.shade_surface_t(ray, t, level, &mix, points, lookup_t, fly.transmittance) } else { self.shade_surface(ray, t, level, &mix, points, None) };
                let (mut surface, mut limited) = shade(mix.lo, if mix.lo == 0 { &fine } else { &points }, lo_t);
                if mix.weight > 0.0 && mix.hi != mix.lo {
                    let (hi, l) = shade(mix.hi, &points, &coarse_t);
                    surface = surface * (1.0 - mix.weight) + hi * mix.weight;
                    limited += l;
                }
                behind = surface;
                behind_weighted = per_lookup;
                out.shadow_step_limited += limited;
            }
        }
        out.radiance = fly.radiance + if behind_weighted { behind } else { fly.transmittance * behind };
        out
    }

    /// Where a flyaway ray of a box grid, parallel to the pixel's ray (which meets the
    /// surface at `t_end`), meets the surface itself: spread along a grazing footprint,
    /// the pixel's hit lies at another place's depth (baker/PREFILTER_MEASUREMENTS.md,
    /// "Each flyaway ray to its own surface"). The bottom of the flyaway layer where it
    /// misses a clamped tile; the pixel's `t_end` where its step budget runs out. Steps
    /// count as the pixel's. True with it where the ray met the surface (level 0's grid
    /// reads its lookups from such hits).
    fn own_surface_end(&self, ray: &Ray, t_top: f32, t_end: f32, floor: usize, out: &mut PixelTrace) -> (f32, bool) {
        let mut steps = 0;
        let hit = self.tracer.trace_to(ray, t_top, f32::MAX, 0.0, self.options.max_steps, &mut steps, floor);
        out.steps += steps;
        match hit {
            HfTrace::Hit(t) => (t, true),
            HfTrace::Miss => (t_top + self.model.tile.height_scale / -ray.d.z, false),
            HfTrace::StepLimit => {
                out.step_limited = true;
                (t_end, false)
            }
        }
    }

    /// The transmittance of the flyaways of levels `lo` and `hi` (weight `w` of `hi`)
    /// over [t_top, t_end], unshaded; and whether a march ran out of columns.
    fn level_coverage(&self, ray: &Ray, t_top: f32, t_end: f32, lo: usize, hi: usize, w: f32) -> (f32, bool) {
        if !self.options.flyaways {
            return (1.0, false);
        }
        let one = |level: usize| self.level_transmittance(self.grazing_level(ray, t_top, t_end, level), ray, t_top, t_end);
        let (t, limited) = one(lo);
        if w > 0.0 && hi != lo {
            let (th, lh) = one(hi);
            return (t * (1.0 - w) + th * w, limited | lh);
        }
        (t, limited)
    }

    /// The level a flyaway march of `level` over [t_top, t_end] reads: coarser where its
    /// columns would number more than `GRAZING_COLUMNS` (a ray near a periodic sheet's
    /// horizon; level.rs, [`grazing_level`]). Twin: march_level_flyaways in
    /// shaders/common/trace.glsl.
    fn grazing_level(&self, ray: &Ray, t_top: f32, t_end: f32, level: usize) -> usize {
        let inv = self.model.inv_texel_size();
        let columns = (ray.d.x.abs() * inv.x + ray.d.y.abs() * inv.y) * (t_end - t_top);
        grazing_level(level, columns, self.model.levels.len() - 1)
    }

    /// The flyaways over [t_top, t_end] blended over the levels `(lo, hi, weight of hi)`,
    /// shaded with `light`.
    fn march_blended_flyaways(&self, ray: &Ray, t_top: f32, t_end: f32, (lo, hi, w): (usize, usize, f32), light: FlyLight) -> FlyShade {
        let mut f = self.march_level_flyaways(ray, t_top, t_end, lo, light);
        if w > 0.0 && hi != lo {
            let h = self.march_level_flyaways(ray, t_top, t_end, hi, light);
            f.radiance = f.radiance * (1.0 - w) + h.radiance * w;
            f.transmittance = f.transmittance * (1.0 - w) + h.transmittance * w;
            f.limited |= h.limited;
            f.shadow_limited += h.shadow_limited;
        }
        f
    }

    /// The flyaways of `level` (or the coarser level of [`Scene::grazing_level`]) over
    /// [t_top, t_end], composited front to back.
    fn march_level_flyaways(&self, ray: &Ray, t_top: f32, t_end: f32, level: usize, light: FlyLight) -> FlyShade {
        let level = self.grazing_level(ray, t_top, t_end, level);
        let lights = if light == FlyLight::Env { &[][..] } else { self.lights };
        let env = light != FlyLight::Lights;
        let wo = -ray.d;
        let mut out = FlyShade { radiance: Vec3::ZERO, transmittance: 1.0, limited: false, shadow_limited: 0 };
        if !self.options.flyaways {
            return out;
        }
        if let Some(f) = self.model.levels[level].flyaways.as_ref().filter(|f| !f.nodes.is_empty()) {
            let mut shadow_limited = 0u32;
            let march = march_flyaways(f, &self.grids[level], ray, t_top, t_end, self.options.max_flyaway_columns, |index, node, t_in| {
                let p = ray.at(t_in);
                let brdf = f.table.brdf_in_frame(node.param as usize, crate::brdf::cloth_frame(Vec3::Z, Vec3::X));
                let fiber = |axis: Vec3| {
                    let b = in_fiber_frame(brdf, axis, wo, self.model.meta.fiber_lobes);
                    if self.edited { self.edit_at(p).apply(b, false) } else { b }
                };
                let axes = f.node_axes(index);
                if axes.weights[0] >= 1.0 {
                    let b = fiber(axes.axes[0]);
                    let from_env = if env { self.env_response(&b, wo, false, DiffuseLaw::Lambert, EnvBudget::FLYAWAY) } else { Vec3::ZERO };
                    return shade(&b, p, wo, lights, self.reading, DiffuseLaw::Lambert, |p, s| self.visibility(p, s, &mut shadow_limited)) + from_env;
                }
                // A coarse node's spread axes, one or two groups (brdf::axis_spread): their
                // mean response, each light's visibility once. A fixed array: this runs per
                // node crossed.
                let mut texels = [(fiber(axes.axes[0]), 0.0f32); crate::brdf::axis_spread::MAX_SPREAD_AXES];
                let mut n = 0;
                for k in (0..crate::brdf::axis_spread::MAX_SPREAD_AXES).filter(|&k| axes.weights[k] > 0.0) {
                    texels[n] = (fiber(axes.axes[k]), axes.weights[k]);
                    n += 1;
                }
                let texels = &texels[..n];
                let from_env = if env { texels.iter().map(|(b, w)| *w * self.env_response(b, wo, false, DiffuseLaw::Lambert, EnvBudget::FLYAWAY)).sum::<Vec3>() } else { Vec3::ZERO };
                shade_blend(texels, p, wo, lights, self.reading, DiffuseLaw::Lambert, |p, s| self.visibility(p, s, &mut shadow_limited)) + from_env
            });
            out = FlyShade { radiance: march.radiance, transmittance: march.transmittance, limited: march.limited, shadow_limited };
        }
        out
    }

    /// Where level 0's grid reads its lookup at `offset` (world x–y) beside the pixel's hit
    /// `hit`. Under half a texel across (`traced` false): beside the hit. Traced: where the
    /// flyaway ray whose cell holds the lookup met the surface, moved by the lookup's
    /// offset from that ray in the hit's horizontal plane — the flyaways' grid traced it
    /// already, and on a round footprint the two grids' offsets coincide
    /// (baker/PREFILTER_MEASUREMENTS.md, "Level 0's lookups from the flyaway rays' hits");
    /// its own trace where that ray did not land or there is no flyaway grid. Twin: the
    /// fine grid's loop in shaders/common/trace.glsl.
    fn fine_lookup_point(&self, ray: &Ray, hit: Vec3, offset: Vec2, traced: bool, fly: &FlyHits, floor: usize) -> Vec3 {
        if !traced {
            return hit + offset.extend(0.0);
        }
        if fly.hits.len() > 1 {
            let (ga, gb) = fly.taps;
            let c = fly_cell(offset, fly.axes.0, ga, fly.axes.1, gb);
            if let Some(h) = fly.hits.get(c as usize).copied().flatten() {
                return h + (offset - tap_offset(fly.axes.0, ga, fly.axes.1, gb, c)).extend(0.0);
            }
        }
        self.tap_surface_point(ray, offset, hit, floor)
    }

    /// Where the lookup at `offset` (world x–y) of a box grid reads the surface: where a
    /// ray parallel to the pixel's, started `offset` beside it, meets the height field —
    /// a grazing footprint's texels as the pixel's rays meet them, hidden ones left out
    /// and faces turned to the viewer seen more (baker/PREFILTER_MEASUREMENTS.md, "Box
    /// lookups where their rays land"). The point `offset` beside the pixel's hit `p`
    /// where that ray misses or runs out of steps. Twin: `tap_surface_point` in
    /// shaders/common/trace.glsl.
    fn tap_surface_point(&self, ray: &Ray, offset: Vec2, p: Vec3, floor: usize) -> Vec3 {
        let beside = p + offset.extend(0.0);
        let r = Ray::new(ray.o + offset.extend(0.0), ray.d);
        let Some(t_top) = self.enter_top(&r) else {
            return beside;
        };
        let mut steps = 0;
        match self.tracer.trace_to(&r, t_top, f32::MAX, 0.0, self.options.max_steps, &mut steps, floor) {
            HfTrace::Hit(t) => r.at(t),
            _ => beside,
        }
    }

    /// [`Scene::shade_surface`] seen through the flyaways: `lookup_t` what they let
    /// through in front of each lookup of `points` ([`lookup_transmittances`]; empty:
    /// `mean_t` in front of all).
    fn shade_surface_t(&self, ray: &Ray, t: f32, level: usize, mix: &LevelMix, points: &[Vec3], lookup_t: &[f32], mean_t: f32) -> (Vec3, u32) {
        if lookup_t.is_empty() || lookup_t.len() != points.len() {
            let (r, l) = self.shade_surface(ray, t, level, mix, points, None);
            return (mean_t * r, l);
        }
        self.shade_surface(ray, t, level, mix, points, Some(lookup_t))
    }

    /// The surface hit at ray parameter `t`, shaded with `level` (filtered as `mix`
    /// says at coarse levels; `points`: a box grid's lookups where their own rays meet
    /// the height field, [`Scene::tap_surface_point`]; at level 0, its grid's lookups,
    /// empty for the hit's texel alone; `lookup_t`: each lookup's weight scaled by it);
    /// returns the radiance and the step-limited shadow rays.
    fn shade_surface(&self, ray: &Ray, t: f32, level: usize, mix: &LevelMix, points: &[Vec3], lookup_t: Option<&[f32]>) -> (Vec3, u32) {
        let tw = |k: usize| lookup_t.map_or(1.0, |v| v[k]);
        let wo = -ray.d;
        let l = &self.model.levels[level];
        let mut shadow_limited = 0u32;
        let p = ray.at(t);
        let volumetric = self.model.meta.volumetric;
        // Coarse levels of a prefiltered model carry the light's visibility.
        let shadowed = level == 0 || !self.model.meta.coarse_visibility;
        // The height field's shadow, then the flyaways' between the hit and the light
        // (format 1.13) at the footprint's levels, at every surface level: a coarse
        // level's visibility (`coarse_visibility`) is the height field's alone.
        let visible = |p: Vec3, s: &LightSample| {
            let v = if shadowed { self.visibility(p, s, &mut shadow_limited) } else { 1.0 };
            let v = if v > 0.0 {
                let (fly, limited) = self.flyaway_shadow_mixed(mix.shadow, p, s.wi, s.distance);
                shadow_limited += limited;
                v * fly
            } else {
                v
            };
            if volumetric { v * volume_factor(s.wi, wo) } else { v }
        };
        let sky = if self.options.env.is_some() { self.flyaway_sky_mixed(mix.shadow, p) } else { 1.0 };
        // The edit at the hit (the same for all its texels).
        let edit = self.edited.then(|| self.edit_at(p));
        let edited = |b: TexelBrdf| edit.map_or(b, |e| e.apply(b, true));
        if level == 0 && points.is_empty() {
            let (i, j) = self.texel_at(p, 0);
            let b = edited(l.texel_brdf(i, j));
            let radiance = shade(&b, p, wo, self.lights, self.reading, self.diffuse, visible) + sky * self.env_response(&b, wo, volumetric, self.diffuse, EnvBudget::SURFACE) + self.env_through(&b, wo);
            return (radiance, shadow_limited);
        }
        // The texels read and their weights, in the GPU twin's order (surface_corner).
        let corners: Vec<((u32, u32), f32)> = if level == 0 {
            // Level 0 through its grid: the nearest texel at each lookup.
            let share = 1.0 / points.len() as f32;
            points.iter().enumerate().map(|(k, &q)| (self.texel_at(q, 0), share * tw(k))).collect()
        } else if mix.taps <= 1 && mix.taps_minor <= 1 {
            self.bilinear_corners(p, level).to_vec()
        } else {
            let (n, m) = (mix.taps, mix.taps_minor);
            let share = 1.0 / (n * m) as f32;
            points[..(n * m) as usize].iter().enumerate().flat_map(|(k, &q)| { let s = share * tw(k); self.bilinear_corners(q, level).map(move |(ij, w)| (ij, w * s)) }).collect()
        };
        // Coarse texels turn their frames by the view tilt. Each lookup where its own ray
        // lands already weights the footprint as a distant view sees it: the tilts'
        // visibility v would count that twice (measured: twill 45°, 6.0% without v, 7.8%
        // with), so only their frames turn.
        let texel = |i: u32, j: u32| edited(if level == 0 { l.texel_brdf(i, j) } else { self.texel_seen(level, i, j, wo).0 });
        // Each distinct texel shaded once, weighted by the sum of its lookups' weights
        // (the same sum by linearity, to rounding): a grid's lookups share texels (a 2×2
        // grid one texel apart reads 9 distinct texels of its 16 corners; level 0's grid
        // over a footprint of half a texel mostly one or two), and a texel's shading —
        // under an environment map its SG mixtures above all — costs far more than
        // finding its repeats. A far frame under the sky draws 1.5–1.9× faster, a frame
        // at half a texel per pixel 1.5× (runtime/ENV_MEASUREMENTS.md, "Speed";
        // baker/PREFILTER_MEASUREMENTS.md, "Level 0 through a grid from a quarter texel
        // across"). The GPU twin does the same on level 0's grid (level0_distinct in
        // shaders/common/shading.glsl) and shades a coarse grid's every corner in order:
        // there distinct texels are 9 of 16, and with the search for them the frame was
        // 7–14% slower on lavapipe (a SIMD group loops over its lanes' most).
        let texels: Vec<(TexelBrdf, f32)> = distinct_corners(&corners).into_iter().map(|((i, j), w)| (texel(i, j), w)).collect();
        let mut radiance = shade_blend(&texels, p, wo, self.lights, self.reading, self.diffuse, visible);
        if self.options.env.is_some() {
            radiance += texels.iter().map(|(b, w)| *w * (sky * self.env_response(b, wo, volumetric, self.diffuse, EnvBudget::SURFACE) + self.env_through(b, wo))).sum::<Vec3>();
        }
        (radiance, shadow_limited)
    }

    /// The environment's SG part at a hit (zero without a map). Unshadowed by the
    /// height field (env_shading.rs states the approximation).
    fn env_response(&self, b: &TexelBrdf, wo: Vec3, volumetric: bool, diffuse: DiffuseLaw, budget: EnvBudget) -> Vec3 {
        match &self.options.env {
            Some(env) => texel_env_response(b, wo, self.reading, volumetric, diffuse, budget, &env.prefiltered),
            None => Vec3::ZERO,
        }
    }

    /// The map below the sheet through a surface texel's transmission term (zero without
    /// a map, a term, or light below: `PrefilteredEnv::lights_below`, the GPU twin's
    /// TRANSMISSION rule). Unshadowed, as lights behind the sheet are (shading.rs).
    fn env_through(&self, b: &TexelBrdf, wo: Vec3) -> Vec3 {
        match &self.options.env {
            Some(env) if !b.transmission.is_zero() && env.prefiltered.lights_below() => transmission_env_response(&b.transmission, &b.frames[0], wo, EnvBudget::SURFACE, &env.prefiltered),
            _ => Vec3::ZERO,
        }
    }

    /// One pixel: s×s samples on a regular grid, the levels from the pixel's footprint
    /// at each sample's surface hit.
    pub fn trace_pixel(&self, x: u32, y: u32) -> PixelTrace {
        let (cx, cy) = (x as f32 + 0.5, y as f32 + 0.5);
        let choose = |z: f32| self.level_mix(cx, cy, z);
        let s = self.options.supersampling;
        if s == 1 {
            return self.trace_mixed(&self.camera.ray(cx, cy), &choose);
        }
        let mut acc = PixelTrace::default();
        let inv = 1.0 / s as f32;
        for a in 0..s {
            for b in 0..s {
                let t = self.trace_mixed(&self.camera.ray(x as f32 + (b as f32 + 0.5) * inv, y as f32 + (a as f32 + 0.5) * inv), &choose);
                acc.radiance += t.radiance;
                acc.level = acc.level.or(t.level);
                acc.surface_t = acc.surface_t.or(t.surface_t);
                acc.flyaway_opacity += t.flyaway_opacity;
                acc.step_limited |= t.step_limited;
                acc.shadow_step_limited += t.shadow_step_limited;
                acc.steps += t.steps;
            }
        }
        let n = (s * s) as f32;
        acc.radiance /= n;
        acc.flyaway_opacity /= n;
        acc
    }
}

/// Checks a render's inputs (the same for the CPU and the GPU renderer) and says
/// whether the lights are shadowed (the options, or the model's fit).
pub fn validate_render(model: &HybridModel, camera: &Camera, lights: &[Light], options: &CpuRenderOptions) -> Result<bool, CpuRenderError> {
    model.validate()?;
    validate_view(model, camera, lights, options)
}

/// [`validate_render`] for a model already validated (the GPU pass validates it once, at
/// upload): the camera, lights and options only, O(lights) — cheap enough per frame.
pub fn validate_view(model: &HybridModel, camera: &Camera, lights: &[Light], options: &CpuRenderOptions) -> Result<bool, CpuRenderError> {
    camera.validate()?;
    for light in lights {
        light.validate()?;
    }
    match options.level {
        LevelChoice::Fixed(level) if level as usize >= model.levels.len() => return Err(CpuRenderError::Level { level, count: model.levels.len() }),
        LevelChoice::Auto { bias } | LevelChoice::Nearest { bias } if !bias.is_finite() => return Err(CpuRenderError::Options(format!("level bias {bias} is not finite"))),
        _ => {}
    }
    if options.supersampling == 0 || options.supersampling > 16 {
        return Err(CpuRenderError::Options(format!("supersampling {} must be in 1..=16", options.supersampling)));
    }
    if options.max_steps == 0 || options.max_flyaway_columns == 0 {
        return Err(CpuRenderError::Options("max_steps and max_flyaway_columns must be positive".into()));
    }
    if !options.background.is_finite() {
        return Err(CpuRenderError::Options(format!("background {} is not finite", options.background)));
    }
    options.edits.validate().map_err(CpuRenderError::Options)?;
    Ok(match options.shadows {
        ShadowMode::FromModel => model.meta.fitted_with_shadowing,
        ShadowMode::On => true,
        ShadowMode::Off => false,
    })
}

/// Renders `model` seen by `camera` under `lights` (and `options.env`, whose sources
/// join the lights): the CPU reference of the GPU renderer. Deterministic (no randomness; any thread count gives the same bits).
pub fn render(model: &HybridModel, camera: &Camera, lights: &[Light], options: &CpuRenderOptions) -> Result<Image, CpuRenderError> {
    render_with_stats(model, camera, lights, options).map(|(image, _)| image)
}

/// [`render`], with statistics (levels used, hits, step-limited rays).
pub fn render_with_stats(model: &HybridModel, camera: &Camera, lights: &[Light], options: &CpuRenderOptions) -> Result<(Image, RenderStats), CpuRenderError> {
    render_with_progress(model, camera, lights, options, &|| {})
}

/// [`render_with_stats`], calling `row_done` (from any thread) as each image row
/// finishes, for a progress bar.
pub fn render_with_progress(model: &HybridModel, camera: &Camera, lights: &[Light], options: &CpuRenderOptions, row_done: &(dyn Fn() + Sync)) -> Result<(Image, RenderStats), CpuRenderError> {
    let lights = options.lights_with_env(lights);
    let scene = Scene::new(model, camera, &lights, options.clone())?;
    let (w, h) = (camera.width, camera.height);
    let levels = model.levels.len();
    let rows: Vec<(Vec<Vec3>, RenderStats)> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut stats = RenderStats { level_pixels: vec![0; levels], ..Default::default() };
            let row = (0..w)
                .map(|x| {
                    let t = scene.trace_pixel(x, y);
                    stats.add(&t);
                    t.radiance
                })
                .collect();
            row_done();
            (row, stats)
        })
        .collect();
    let mut stats = RenderStats { level_pixels: vec![0; levels], ..Default::default() };
    let mut pixels = Vec::with_capacity((w * h) as usize);
    for (row, s) in rows {
        pixels.extend(row);
        stats.merge(&s);
    }
    let image = Image { width: w, height: h, pixels };
    if let Some((x, y, v)) = image.first_non_finite() {
        return Err(CpuRenderError::NonFinite { x, y, value: v });
    }
    Ok((image, stats))
}



/// The distinct texels among `corners`, in order of first appearance, each with the sum
/// of its corners' weights taken in order.
fn distinct_corners(corners: &[((u32, u32), f32)]) -> Vec<((u32, u32), f32)> {
    let mut out: Vec<((u32, u32), f32)> = Vec::with_capacity(corners.len());
    for (c, &(ij, w)) in corners.iter().enumerate() {
        if corners[..c].iter().any(|(e, _)| *e == ij) {
            continue;
        }
        let total = corners[c + 1..].iter().filter(|(e, _)| *e == ij).fold(w, |sum, (_, wd)| sum + wd);
        out.push((ij, total));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::{FlyHits, Scene, distinct_corners, spread_colours, tap_offset};
    use crate::cpu::CpuRenderOptions;
    use crate::hybrid::{Tile, examples};
    use crate::scene::{Camera, Light};
    use glam::{Vec2, Vec3};

    /// Level 0's traced lookups borrow the flyaway rays' hits: on a flat height field a
    /// borrowed hit is the lookup's own trace; where a flyaway ray missed, or there is
    /// no flyaway grid, the lookup traces its own ray; under half a texel it sits beside
    /// the hit.
    #[test]
    fn level_0_lookups_borrow_the_flyaway_rays_hits() {
        let tile = Tile { origin: Vec2::new(-0.5, -0.5), size: Vec2::ONE, top_z: 0.3, height_scale: 0.3, voxel_depth: 0.01 };
        let params = examples::silk_params();
        let (n, t) = (Vec3::Z, Vec3::X);
        let flat = examples::uniform_model(32, 32, 1, tile, |_, _| 0.1, &params, n, t).unwrap();
        // A relief along x (a crest every 8 texels): a borrowed hit keeps its own ray's depth.
        let bumpy = examples::uniform_model(32, 32, 1, tile, |x, _| 0.1 + 0.08 * (x * 25.0).sin(), &params, n, t).unwrap();
        let camera = Camera::orbit_orthographic(50.0, 30.0, Vec3::new(0.0, 0.0, 0.2), 3.0, 1.0, 16, 16);
        let lights = [Light::directional(Vec3::new(0.3, 0.2, 1.0), Vec3::ONE)];
        let ray = camera.ray(8.5, 8.5);
        // Two flyaway rays along x, two across, over 3 texels; level 0's grid 4 × 2 on the same box.
        let (fa, fb) = (Vec2::new(3.0 / 32.0, 0.0), Vec2::new(0.0, 3.0 / 32.0));
        let offsets: Vec<Vec2> = (0..8).map(|k| tap_offset(fa, 4, fb, 2, k)).collect();
        for (name, model) in [("flat", &flat), ("bumpy", &bumpy)] {
            let scene = Scene::new(model, &camera, &lights, CpuRenderOptions::default()).unwrap();
            let hit = scene.tap_surface_point(&ray, Vec2::ZERO, Vec3::ZERO, 0);
            assert!((hit.z - 0.2).abs() < 0.1 && hit.x.abs() < 0.5, "{name}: pixel's hit {hit}");
            let own: Vec<Vec3> = offsets.iter().map(|&o| scene.tap_surface_point(&ray, o, hit, 0)).collect();
            let fly: Vec<Option<Vec3>> = (0..4).map(|k| Some(scene.tap_surface_point(&ray, tap_offset(fa, 2, fb, 2, k), hit, 0))).collect();
            let grid = FlyHits { hits: &fly, axes: (fa, fb), taps: (2, 2) };
            let borrowed: Vec<Vec3> = offsets.iter().map(|&o| scene.fine_lookup_point(&ray, hit, o, true, &grid, 0)).collect();
            for (k, (&o, (b, w))) in offsets.iter().zip(borrowed.iter().zip(&own)).enumerate() {
                // Each borrowed point is a flyaway hit moved by less than the cell, at that hit's depth.
                let c = super::fly_cell(o, fa, 2, fb, 2) as usize;
                let from = fly[c].unwrap();
                assert_eq!(b.z, from.z, "{name}, lookup {k}");
                assert!(((*b - from).truncate() - (o - tap_offset(fa, 2, fb, 2, c as u32))).length() < 1e-6, "{name}, lookup {k}");
                if name == "flat" {
                    assert!((*b - *w).length() < 1e-4, "flat, lookup {k}: borrowed {b} against its own trace {w}");
                }
            }
            if name == "bumpy" {
                let apart = borrowed.iter().zip(&own).filter(|(b, w)| (**b - **w).length() > 1e-3).count();
                assert!(apart > 0, "the relief should make borrowed hits differ from own traces");
            }
            // A flyaway ray that missed: its lookups trace their own rays, the others still borrow.
            let mut missed = fly.clone();
            missed[1] = None;
            let grid = FlyHits { hits: &missed, axes: (fa, fb), taps: (2, 2) };
            for (k, &o) in offsets.iter().enumerate() {
                let c = super::fly_cell(o, fa, 2, fb, 2) as usize;
                let got = scene.fine_lookup_point(&ray, hit, o, true, &grid, 0);
                let want = if c == 1 { own[k] } else { borrowed[k] };
                assert_eq!(got, want, "{name}, lookup {k} in cell {c}");
            }
            assert!(offsets.iter().any(|&o| super::fly_cell(o, fa, 2, fb, 2) == 1));
            // No flyaway grid: every lookup its own trace. Not traced: beside the hit.
            let none = FlyHits { hits: &[], axes: (fa, fb), taps: (1, 1) };
            for (k, &o) in offsets.iter().enumerate() {
                assert_eq!(scene.fine_lookup_point(&ray, hit, o, true, &none, 0), own[k], "{name}, lookup {k}");
                assert_eq!(scene.fine_lookup_point(&ray, hit, o, false, &grid, 0), hit + o.extend(0.0), "{name}, lookup {k}");
            }
        }
    }

    #[test]
    fn distinct_corners_keep_first_appearance_and_sum_weights_in_order() {
        // Two bilinear lookups one texel apart share two texels.
        let corners = [((3, 4), 0.1), ((4, 4), 0.2), ((3, 5), 0.3), ((4, 5), 0.4), ((4, 4), 0.5), ((5, 4), 0.6), ((4, 5), 0.7), ((5, 5), 0.8)];
        let d = distinct_corners(&corners);
        assert_eq!(d.iter().map(|(ij, _)| *ij).collect::<Vec<_>>(), vec![(3, 4), (4, 4), (3, 5), (4, 5), (5, 4), (5, 5)]);
        assert_eq!(d[1].1, 0.2f32 + 0.5);
        assert_eq!(d[3].1, 0.4f32 + 0.7);
        // Any f weighted by the corners equals f weighted by the distinct texels.
        let f = |(i, j): (u32, u32)| (i * 7 + j * 3) as f32;
        let all: f32 = corners.iter().map(|&(ij, w)| w * f(ij)).sum();
        let once: f32 = d.iter().map(|&(ij, w)| w * f(ij)).sum();
        assert!((all - once).abs() <= 1e-5 * all.abs(), "{all} vs {once}");
        assert!(distinct_corners(&[]).is_empty());
    }

    #[test]
    fn spread_colours_keep_each_cells_colour_and_take_its_coverage() {
        // Two cells: a red shading ray of opacity 0.5 whose cell's coverage rays are
        // opaque at 0.2 on average, and one that met nothing where its coverage rays met
        // fibres (opacity 0.4): that cell takes the pixel's mean colour, red.
        let red = Vec3::new(1.0, 0.0, 0.0);
        let rays = [(0.5 * red, 0.5), (Vec3::ZERO, 1.0)];
        let cells = [(0.4, 2u32), (1.2, 3u32)];
        let r = spread_colours(&rays, &cells);
        assert!((r - red * 0.5 * (0.2 + 0.4)).length() < 1e-6, "{r}");
        // A cell without coverage rays keeps its shading ray's own opacity: the box filter's.
        let r = spread_colours(&rays, &[(0.0, 0), (0.0, 0)]);
        assert!((r - 0.25 * red).length() < 1e-6, "{r}");
        // Nothing met anywhere: no light, no NaN.
        assert_eq!(spread_colours(&[(Vec3::ZERO, 1.0); 4], &[(0.0, 4); 4]), Vec3::ZERO);
    }
}
