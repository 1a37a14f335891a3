//! The procedural fabric generator (docs/DESIGN.md §3): fibers → plies → yarns →
//! weave (or a matted felt layer), voxelized to density, albedo and orientation.
//!
//! World units are millimetres. The volume spans [0, X·h] × [0, Y·h] × [0, Z·h] for a
//! voxel edge h (by default: footroom + fabric body + headroom = Z·h). Yarn spacings
//! are adjusted so that a whole number of pattern and colour repeats fills the tile, and
//! twists and migration cycles so that every fiber closes on itself across the tile:
//! the volume tiles seamlessly in x and y. Every random choice is keyed by (seed,
//! item), so a seed gives bit-identical volumes for any number of threads.
//!
//! Stages: [`weave`] (pattern, centrelines) and [`yarn`] (fibers in plies, Zhao et al.
//! 2016) or [`felt`] make fiber polylines; [`voxelize`] turns them into voxels;
//! [`preview`] draws top views.

pub mod felt;
pub mod params;
pub mod presets;
pub mod preview;
pub mod random;
pub mod voxelize;
pub mod weave;
pub mod yarn;

use std::time::Instant;

use glam::Vec3;
use indicatif::ProgressBar;
use rayon::prelude::*;
use serde::Serialize;

pub use params::{FabricParams, FeltParams, FiberParams, FlyawayParams, GeneratorParams, MaterialSpec, PatternKind, WovenParams, YarnParams};
pub use presets::Preset;

use crate::volume::{Aabb, FabricVolume, MaterialParams, VolumeError};
use random::{Rng, stream};
use voxelize::{FiberStyle, Segment};
use weave::{Axis, Weave, YarnPath};
use yarn::{FiberSeed, HairSeed, YarnModel};

/// Why a fabric could not be generated.
#[derive(Debug, thiserror::Error)]
pub enum GenerateError {
    /// A parameter is out of range or malformed.
    #[error("generator parameter {key} = {value}: {rule}")]
    Param { key: String, value: String, rule: String },
    /// The requested size is not a valid volume size.
    #[error("size: {0}")]
    Size(VolumeError),
    /// The parameters and size together make no sense (e.g. fibers far below a voxel).
    #[error("{0}")]
    Layout(String),
}

/// Most segments one generation may create (bounds memory: 28 bytes each).
pub const MAX_SEGMENTS: usize = 200_000_000;

/// What was generated, for reports and `material.toml`'s provenance.
#[derive(Clone, Debug, Serialize)]
pub struct GenerationStats {
    /// Voxel edge (mm).
    pub voxel_size: f32,
    /// Volume size (mm).
    pub extent: [f32; 3],
    /// Fiber diameter in voxels.
    pub fiber_diameter_voxels: f32,
    /// Warp and weft yarns per tile (0 for felt).
    pub warps: u32,
    pub wefts: u32,
    /// Fibers (including hair flyaways) and polyline segments.
    pub fibers: usize,
    pub hairs: usize,
    pub segments: usize,
    /// Seconds spent building fiber curves and voxelizing.
    pub curves_seconds: f64,
    pub voxelize_seconds: f64,
}

/// A generated fabric and how it was made.
pub struct Generated {
    pub volume: FabricVolume,
    pub stats: GenerationStats,
}

/// Generates a fabric volume of `dims` cells.
pub fn generate(params: &GeneratorParams, dims: [usize; 3], seed: u64) -> Result<FabricVolume, GenerateError> {
    generate_with_progress(params, dims, seed, &ProgressBar::hidden()).map(|g| g.volume)
}

/// A fiber to trace: where its polyline comes from. `key` names it stably (yarn, ply,
/// kind, index), so its random choices (colour variation, loops) do not move when
/// other fibers are added or removed, e.g. when flyaways are switched off.
enum Spec {
    Fiber { key: u64, yarn: u32, ply: u32, seed: FiberSeed },
    Hair { key: u64, yarn: u32, ply: u32, seed: HairSeed },
    Felt { key: u64 },
}

/// Stable key of fiber `index` of `kind` (0 body, 1 hair, 2 loop) in ply `ply` of yarn `yarn`.
fn fiber_key(yarn: u32, ply: u32, kind: u64, index: usize) -> u64 {
    ((yarn as u64) << 40) | ((ply as u64) << 32) | (kind << 28) | index as u64
}

/// [`generate`], reporting voxelization progress (bands of rows) on `progress`.
pub fn generate_with_progress(params: &GeneratorParams, dims: [usize; 3], seed: u64, progress: &ProgressBar) -> Result<Generated, GenerateError> {
    params.validate()?;
    let dims = crate::volume::vol::check_dims(dims.map(|d| d as i64), std::path::Path::new("(generated volume)")).map_err(GenerateError::Size)?;
    let h = match params.voxel_size {
        Some(h) => h,
        None => (params.footroom + body_thickness(params) + params.headroom) / dims[2] as f32,
    };
    let extent = [dims[0] as f32 * h, dims[1] as f32 * h, dims[2] as f32 * h];
    let fiber_radius = 0.5 * params.fiber.diameter;
    let fiber_diameter_voxels = params.fiber.diameter / h;
    if fiber_diameter_voxels < 0.25 {
        return Err(GenerateError::Layout(format!(
            "fibers of {} mm are {fiber_diameter_voxels:.3} voxels of {h} mm wide; at least 0.25 voxel is needed (raise the z resolution, fiber.diameter or voxel_size)",
            params.fiber.diameter
        )));
    }
    // Segments of about max(r, 0.75) voxels, at most 4 (chord error ≤ 4²/(8·R_curv) stays
    // below 0.1 voxel for the ≥ 20-voxel curvature radii of twisted fibers and loops).
    let step_mm = h * (0.5 * fiber_diameter_voxels).clamp(0.75, 4.0);
    let z_top = extent[2] - params.headroom;

    let t0 = Instant::now();
    let (lines, styles, warps, wefts, hairs) = match &params.fabric {
        FabricParams::Woven(w) => woven_fibers(params, w, extent, z_top, fiber_radius, h, step_mm, seed)?,
        FabricParams::Felt(f) => felt_fibers(params, f, extent, z_top, fiber_radius, h, step_mm, seed)?,
    };
    let segments: Vec<Segment> = lines
        .iter()
        .enumerate()
        .flat_map(|(id, pts)| pts.windows(2).map(move |w| Segment { a: w[0] / h, b: w[1] / h, fiber: id as u32 }))
        .collect();
    let curves_seconds = t0.elapsed().as_secs_f64();
    drop(lines);

    let t1 = Instant::now();
    let bbox = Aabb::new(Vec3::ZERO, Vec3::from(extent));
    let material = MaterialParams { density_scale: params.material.fiber_optical_depth / params.fiber.diameter, roughness: params.material.roughness };
    let mut volume = FabricVolume::try_new(dims, bbox, material).map_err(GenerateError::Layout)?;
    voxelize::voxelize(&mut volume, &segments, &styles, progress);
    let stats = GenerationStats {
        voxel_size: h,
        extent,
        fiber_diameter_voxels,
        warps,
        wefts,
        fibers: styles.len(),
        hairs,
        segments: segments.len(),
        curves_seconds,
        voxelize_seconds: t1.elapsed().as_secs_f64(),
    };
    Ok(Generated { volume, stats })
}

/// Nominal thickness of the fabric body (mm): two crossing yarn layers, or the felt.
pub fn body_thickness(params: &GeneratorParams) -> f32 {
    match &params.fabric {
        FabricParams::Woven(w) => {
            let (warp_t, weft_t) = (w.flattening * w.cover * w.warp_spacing, w.flattening * w.cover * w.weft_spacing);
            let [a_warp, a_weft] = crimp_amplitudes(w, warp_t, weft_t);
            2.0 * (a_warp + 0.5 * warp_t).max(a_weft + 0.5 * weft_t)
        }
        FabricParams::Felt(f) => f.thickness,
    }
}

/// Crimp amplitudes of warp and weft: crossing centres are crimp·(t_warp + t_weft)/2
/// apart, the warp taking `crimp_balance` of that distance.
fn crimp_amplitudes(w: &WovenParams, warp_t: f32, weft_t: f32) -> [f32; 2] {
    let separation = w.crimp * 0.5 * (warp_t + weft_t);
    [separation * w.crimp_balance, separation * (1.0 - w.crimp_balance)]
}

/// A fiber's albedo: its yarn's colour times exp(variation · N(0, 1)) (Rng keyed by fiber).
fn vary(color: [f32; 3], variation: f32, seed: u64, key: u64) -> Vec3 {
    let mut rng = Rng::new(seed, stream::FIBER, key);
    (Vec3::from(color) * (variation * rng.normal()).exp()).clamp(Vec3::ZERO, Vec3::ONE)
}

type Fibers = (Vec<Vec<Vec3>>, Vec<FiberStyle>, u32, u32, usize);

fn check_segments(estimate: f64) -> Result<(), GenerateError> {
    if estimate > MAX_SEGMENTS as f64 {
        return Err(GenerateError::Layout(format!(
            "the fabric would need about {estimate:.3e} fiber segments (limit {MAX_SEGMENTS}); use thicker fibers, fewer fibers per ply or a smaller volume"
        )));
    }
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn woven_fibers(params: &GeneratorParams, w: &WovenParams, extent: [f32; 3], z_top: f32, fiber_radius: f32, h: f32, step: f32, seed: u64) -> Result<Fibers, GenerateError> {
    let weave = Weave::from_params(w);
    let period = weave.period();
    let n_warp = weave::yarn_count(extent[0], w.warp_spacing, period, w.warp_colors.len());
    let n_weft = weave::yarn_count(extent[1], w.weft_spacing, period, w.weft_colors.len());
    let (sx, sy) = (extent[0] / n_warp as f32, extent[1] / n_weft as f32);
    let (warp_w, weft_w) = (w.cover * sx, w.cover * sy);
    let (warp_t, weft_t) = (w.flattening * warp_w, w.flattening * weft_w);
    let [a_warp, a_weft] = crimp_amplitudes(w, warp_t, weft_t);
    let z_mid = z_top - (a_warp + 0.5 * warp_t).max(a_weft + 0.5 * weft_t);
    let warp_model = YarnModel::new(&w.yarn, warp_w, warp_t, extent[1], fiber_radius);
    let weft_model = YarnModel::new(&w.yarn, weft_w, weft_t, extent[0], fiber_radius);

    let mut paths: Vec<(YarnPath, &YarnModel, [f32; 3])> = Vec::with_capacity((n_warp + n_weft) as usize);
    for i in 0..n_warp {
        let sides = (0..n_weft).map(|j| if weave.warp_over(i, j) { 1.0 } else { -1.0 }).collect();
        let path = YarnPath { axis: Axis::Y, offset: (i as f32 + 0.5) * sx, z_mid, amplitude: a_warp, crossing_spacing: sy, sides, length: extent[1] };
        paths.push((path, &warp_model, w.warp_colors[i as usize % w.warp_colors.len()]));
    }
    for j in 0..n_weft {
        let sides = (0..n_warp).map(|i| if weave.warp_over(i, j) { -1.0 } else { 1.0 }).collect();
        let path = YarnPath { axis: Axis::X, offset: (j as f32 + 0.5) * sy, z_mid, amplitude: a_weft, crossing_spacing: sx, sides, length: extent[0] };
        paths.push((path, &weft_model, w.weft_colors[j as usize % w.weft_colors.len()]));
    }

    let per_yarn = (w.yarn.plies * warp_model.fibers_per_ply.max(weft_model.fibers_per_ply)) as f64;
    let longest = extent[0].max(extent[1]) as f64 * 3.0; // twist and migration lengthen fibers
    check_segments(paths.len() as f64 * per_yarn * longest / step as f64)?;

    let mut specs = Vec::new();
    let mut hairs = 0;
    for (y, (path, model, _)) in paths.iter().enumerate() {
        let y = y as u32;
        for ply in 0..model.plies {
            let mut rng = Rng::new(seed, stream::YARN, fiber_key(y, ply, 0, 0));
            for (k, s) in model.sample_fibers(&mut rng).into_iter().enumerate() {
                specs.push(Spec::Fiber { key: fiber_key(y, ply, 0, k), yarn: y, ply, seed: s });
            }
            let mut rng = Rng::new(seed, stream::HAIR, fiber_key(y, ply, 1, 0));
            for (k, s) in model.sample_hairs(path.length, &mut rng).into_iter().enumerate() {
                specs.push(Spec::Hair { key: fiber_key(y, ply, 1, k), yarn: y, ply, seed: s });
                hairs += 1;
            }
        }
    }
    let traced: Vec<(Vec<Vec3>, FiberStyle)> = specs
        .par_iter()
        .map(|spec| {
            let (line, yarn, key) = match spec {
                Spec::Fiber { key, yarn, ply, seed: s } => {
                    let (path, model, _) = &paths[*yarn as usize];
                    (yarn::fiber_polyline(model, path, *ply, s, (seed, *key), step), *yarn, *key)
                }
                Spec::Hair { key, yarn, ply, seed: s } => {
                    let (path, model, _) = &paths[*yarn as usize];
                    (yarn::hair_polyline(model, path, *ply, s, step), *yarn, *key)
                }
                Spec::Felt { .. } => unreachable!("felt fibers in a woven fabric"),
            };
            let albedo = vary(paths[yarn as usize].2, params.fiber.albedo_variation, seed, key);
            (line, FiberStyle { radius: fiber_radius / h, albedo })
        })
        .collect();
    let (lines, styles) = traced.into_iter().unzip();
    Ok((lines, styles, n_warp, n_weft, hairs))
}

#[allow(clippy::too_many_arguments)]
fn felt_fibers(params: &GeneratorParams, f: &FeltParams, extent: [f32; 3], z_top: f32, fiber_radius: f32, h: f32, step: f32, seed: u64) -> Result<Fibers, GenerateError> {
    let layout = felt::FeltLayout { size: [extent[0], extent[1]], z_bottom: z_top - f.thickness, z_top, fiber_radius };
    let [n_body, n_hair, n_loop] = felt::counts(f, &layout);
    let length = n_body as f64 * 1.5 * f.fiber_length as f64 + n_hair as f64 * 1.5 * f.hair_length as f64 + n_loop as f64 * 1.5 * (f.loop_span + 2.0 * f.loop_height) as f64;
    check_segments(length / step as f64)?;
    let specs: Vec<Spec> = (0..n_body)
        .map(|i| Spec::Felt { key: fiber_key(0, 0, 0, i) })
        .chain((0..n_hair).map(|i| Spec::Felt { key: fiber_key(0, 0, 1, i) }))
        .chain((0..n_loop).map(|i| Spec::Felt { key: fiber_key(0, 0, 2, i) }))
        .collect();
    let traced: Vec<(Vec<Vec3>, FiberStyle)> = specs
        .par_iter()
        .map(|spec| {
            let Spec::Felt { key } = *spec else { unreachable!("woven fibers in a felt") };
            let index = key & 0x0fff_ffff;
            let fiber = match key >> 28 {
                0 => felt::body_fiber(f, &layout, seed, index, step),
                1 => felt::hair(f, &layout, seed, index, step),
                _ => felt::fiber_loop(f, &layout, seed, index, step),
            };
            let albedo = vary(f.colors[fiber.color], params.fiber.albedo_variation, seed, key);
            (fiber.points, FiberStyle { radius: fiber_radius / h, albedo })
        })
        .collect();
    let (lines, styles) = traced.into_iter().unzip();
    Ok((lines, styles, 0, 0, n_hair + n_loop))
}

/// The `[generator]` table `fabric gen` stores in `material.toml`: enough to
/// regenerate the same volume.
pub fn provenance(preset: Option<Preset>, params: &GeneratorParams, dims: [usize; 3], seed: u64, stats: &GenerationStats) -> toml::Table {
    let mut t = toml::Table::new();
    if let Some(p) = preset {
        t.insert("preset".into(), p.name().into());
    }
    // TOML integers are i64: larger seeds are kept as text.
    t.insert("seed".into(), i64::try_from(seed).map_or_else(|_| toml::Value::String(seed.to_string()), toml::Value::Integer));
    t.insert("size".into(), toml::Value::Array(dims.iter().map(|&d| toml::Value::Integer(d as i64)).collect()));
    t.insert("voxel_size".into(), toml::Value::Float(stats.voxel_size as f64));
    t.insert("fiber_diameter_voxels".into(), toml::Value::Float(stats.fiber_diameter_voxels as f64));
    t.insert("params".into(), toml::Value::Table(params.to_table()));
    t.iter_mut().for_each(|(_, v)| params::shorten_floats(v));
    t
}
