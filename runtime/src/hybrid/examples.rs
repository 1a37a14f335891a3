//! Hand-built hybrid models with known answers, for tests of every renderer (CPU here,
//! GPU in the Vulkan renderer) and of the file format: no baker needed.

use glam::{Vec2, Vec3};

use super::error::ModelError;
use super::flyaway::{FlyawayInput, Flyaways};
use super::lobe::{BrdfTable, ClusteredTexel};
use super::model::{BakeMetadata, HeightField, HybridModel, Level, Surface, Tile, level_dims, max_levels};
use crate::brdf::{BrdfReading, ClothLobe, ClothParams};
use crate::scene::Aabb;

/// A silk-like BRDF: weak diffuse, a narrow and a wide lobe.
pub fn silk_params() -> ClothParams {
    ClothParams::new(
        Vec3::new(0.06, 0.04, 0.03),
        1.46,
        1.0,
        &[ClothLobe { k: Vec3::new(0.9, 0.8, 0.7), beta: 0.12, gamma: 0.8 }, ClothLobe { k: Vec3::new(0.3, 0.25, 0.2), beta: 0.35, gamma: ClothLobe::GAMMA_OFF }],
    )
}

/// Metadata of a hand-built model over `tile`.
pub fn example_meta(tile: &Tile, levels: usize, dims: [u32; 3]) -> BakeMetadata {
    let min = Vec3::new(tile.origin.x, tile.origin.y, tile.top_z - tile.height_scale);
    let max = Vec3::new(tile.origin.x + tile.size.x, tile.origin.y + tile.size.y, tile.top_z);
    BakeMetadata {
        reading: BrdfReading::Bounded,
        fitted_with_shadowing: false,
        volumetric: false,
        coarse_visibility: false,
        diffuse: crate::brdf::DiffuseLaw::Lambert,
        fiber_lobes: crate::brdf::FiberLobes::Facing,
        flyaway_shadow: false,
        fit_error: vec![-1.0; levels],
        source_bbox: Aabb::new(min, max),
        source_dims: dims,
        seed: 0,
        note: "hand-built example".into(),
    }
}

/// A `w`×`h` model with `levels` levels on `tile`, whose depth below the top plane at
/// texel centre (x, y) (world units) is `depth(x, y)`, and whose every texel at every
/// level has BRDF `params` in frame (`n`, `t`) (level 0 clustered with one cluster,
/// coarse levels per texel). No flyaways.
#[allow(clippy::too_many_arguments)] // a test fixture: every argument is one property of the model
pub fn uniform_model(w: u32, h: u32, levels: usize, tile: Tile, depth: impl Fn(f32, f32) -> f32, params: &ClothParams, n: Vec3, t: Vec3) -> Result<HybridModel, ModelError> {
    let texel = tile.size / Vec2::new(w as f32, h as f32);
    let mut depths = Vec::with_capacity(w as usize * h as usize);
    for j in 0..h {
        for i in 0..w {
            let c = tile.origin + (Vec2::new(i as f32, j as f32) + 0.5) * texel;
            depths.push(depth(c.x, c.y));
        }
    }
    let height = HeightField::from_depths(w, h, &depths, tile.height_scale)?;
    let levels = levels.clamp(1, max_levels(w, h));
    let mut out = Vec::with_capacity(levels);
    for level in 0..levels {
        let (lw, lh) = level_dims(w, h, level);
        let count = lw as usize * lh as usize;
        let surface = if level == 0 {
            let mut table = BrdfTable::new();
            table.push(params);
            Surface::Clustered { texels: vec![ClusteredTexel::new(n, t, 0); count], table }
        } else {
            let mut table = BrdfTable::new();
            let lobes: Vec<(ClothLobe, Vec3, Vec3)> = params.lobes().iter().map(|l| (*l, n, t)).collect();
            for _ in 0..count {
                table.push_framed(params.kd, params.eta, params.a, &lobes);
            }
            Surface::PerTexel(table)
        };
        out.push(Level { width: lw, height: lh, surface, flyaways: None, transmission: None, transmission_visibility: None, view_tilt: None, gradient: None, curvature: None });
    }
    let dims = [w, h, (tile.height_scale / tile.voxel_depth).round().max(1.0) as u32];
    let meta = example_meta(&tile, levels, dims);
    let model = HybridModel { tile, height, levels: out, meta };
    model.validate()?;
    Ok(model)
}

/// Gives `level` of `model` flyaway voxels: `voxels` lists (i, j, voxel) at that level,
/// all using BRDF `params` (one table entry).
pub fn add_flyaways(model: &mut HybridModel, level: usize, voxels: &[(u32, u32, FlyawayInput)], params: &ClothParams) -> Result<(), ModelError> {
    let mut table = BrdfTable::new();
    table.push(params);
    let l = &mut model.levels[level];
    let f = Flyaways::from_columns(l.width, l.height, table, |i, j| voxels.iter().filter(|(vi, vj, _)| (*vi, *vj) == (i, j)).map(|(_, _, v)| FlyawayInput { param: 0, ..*v }).collect())?;
    l.flyaways = Some(f);
    model.validate()
}

/// A deterministic model that exercises every part of the format: a 12×10 tile (not a
/// power of two), 4 levels, a clustered level 0 with 3 clusters and varying frames,
/// per-texel coarse levels with 1–8 lobes, flyaways on levels 0 and 1, metadata.
pub fn sample_model() -> HybridModel {
    let (w, h) = (12u32, 10u32);
    let tile = Tile { origin: Vec2::new(-0.6, -0.5), size: Vec2::new(1.2, 1.0), top_z: 0.25, height_scale: 0.2, voxel_depth: 0.0125 };
    let depth = |x: f32, y: f32| 0.05 + 0.04 * (6.0 * x).sin() * (5.0 * y).cos();
    let texel = tile.size / Vec2::new(w as f32, h as f32);
    let depths: Vec<f32> = (0..h).flat_map(|j| (0..w).map(move |i| (i, j))).map(|(i, j)| depth(tile.origin.x + (i as f32 + 0.5) * texel.x, tile.origin.y + (j as f32 + 0.5) * texel.y)).collect();
    let height = HeightField { width: w, height: h, codes: HeightField::from_depths(w, h, &depths, tile.height_scale).map(|hf| hf.codes).unwrap_or_default() };
    let frame = |i: u32, j: u32| {
        let n = Vec3::new(0.2 * (i as f32 * 0.7).sin(), 0.2 * (j as f32 * 0.9).cos(), 1.0).normalize();
        let t = Vec3::new((i as f32 * 0.3).cos(), (j as f32 * 0.3).sin(), 0.0);
        (n, t)
    };
    let lobe = |s: f32| ClothLobe { k: Vec3::new(0.5 + 0.1 * s, 0.4, 0.3), beta: 0.05 + 0.02 * s, gamma: if (s as u32).is_multiple_of(3) { 0.0 } else { 0.3 + 0.1 * s } };
    let mut levels = Vec::new();
    for level in 0..4 {
        let (lw, lh) = level_dims(w, h, level);
        let surface = if level == 0 {
            let mut table = BrdfTable::new();
            for c in 0..3 {
                table.push(&ClothParams::new(Vec3::splat(0.05 * c as f32), 1.3 + 0.1 * c as f32, c as f32, &[lobe(c as f32), lobe(c as f32 + 1.0)]));
            }
            let texels = (0..lh).flat_map(|j| (0..lw).map(move |i| (i, j))).map(|(i, j)| {
                let (n, t) = frame(i, j);
                ClusteredTexel::new(n, t, ((i + 2 * j) % 3) as u16)
            });
            Surface::Clustered { texels: texels.collect(), table }
        } else {
            let mut table = BrdfTable::new();
            for j in 0..lh {
                for i in 0..lw {
                    let count = 1 + ((i + j + level as u32) % 8) as usize;
                    let lobes: Vec<(ClothLobe, Vec3, Vec3)> = (0..count).map(|k| (lobe(k as f32), frame(i + k as u32, j).0, frame(i, j + k as u32).1)).collect();
                    table.push_framed(Vec3::new(0.1, 0.05, 0.02 * level as f32), 1.5, 0.5 * level as f32, &lobes);
                }
            }
            Surface::PerTexel(table)
        };
        levels.push(Level { width: lw, height: lh, surface, flyaways: None, transmission: None, transmission_visibility: None, view_tilt: None, gradient: None, curvature: None });
    }
    let meta = BakeMetadata { seed: 0x5eed, note: "sample_model: every section kind".into(), fit_error: vec![0.031, 0.045, -1.0, 0.12], ..example_meta(&tile, 4, [w, h, 16]) };
    let mut model = HybridModel { tile, height, levels, meta };
    let fly = silk_params();
    let mut voxels0: Vec<(u32, u32, FlyawayInput)> = (0..9u32).map(|k| ((k * 5) % w, (k * 3) % h, FlyawayInput { depth: (k % 4) as u16, alpha: 1.0, tangent: Vec3::new(1.0, k as f32 * 0.1, 0.3), param: 0 })).collect();
    voxels0.push((0, 0, FlyawayInput { depth: 6, alpha: 1.0, tangent: Vec3::Z, param: 0 }));
    let voxels1: Vec<(u32, u32, FlyawayInput)> = vec![(1, 1, FlyawayInput { depth: 0, alpha: 0.375, tangent: Vec3::Y, param: 0 }), (1, 1, FlyawayInput { depth: 2, alpha: 0.125, tangent: Vec3::X, param: 0 })];
    // The builders cannot fail on these inputs; a failure shows up in validate() below.
    let _ = add_flyaways(&mut model, 0, &voxels0, &fly);
    let _ = add_flyaways(&mut model, 1, &voxels1, &fly);
    model
}

/// A woven-looking synthetic model of `n`×`n` texels for benchmarks: yarn-scale bumps,
/// warp/weft tangents with fiber-level normal noise, 8 clusters at level 0, two framed
/// lobes per texel at coarse levels, and sparse flyaways (≈ 2% of columns) downsampled
/// to every level with alpha = the fraction of filled children. Deterministic in `seed`.
pub fn synthetic_model(n: u32, seed: u64) -> HybridModel {
    use crate::brdf::twin::SplitMix64;
    let tile = Tile { origin: Vec2::ZERO, size: Vec2::ONE, top_z: 0.1, height_scale: 0.1, voxel_depth: 0.1 / 64.0 };
    let yarns = 8.0;
    let depth = |x: f32, y: f32| 0.05 + 0.02 * (std::f32::consts::TAU * yarns * x).sin() * (std::f32::consts::TAU * yarns * y).sin();
    let warp = |x: f32, y: f32| ((yarns * x).floor() + (yarns * y).floor()) as i32 % 2 == 0;
    let texel = 1.0 / n as f32;
    let centre = |i: u32, j: u32| ((i as f32 + 0.5) * texel, (j as f32 + 0.5) * texel);
    let depths: Vec<f32> = (0..n).flat_map(|j| (0..n).map(move |i| (i, j))).map(|(i, j)| { let (x, y) = centre(i, j); depth(x, y) }).collect();
    let height = HeightField { width: n, height: n, codes: HeightField::from_depths(n, n, &depths, tile.height_scale).map(|h| h.codes).unwrap_or_default() };
    let mut rng = SplitMix64(seed);
    let frame = |rng: &mut SplitMix64, x: f32, y: f32| {
        let e = 1e-3;
        let gx = (depth(x + e, y) - depth(x - e, y)) / (2.0 * e);
        let gy = (depth(x, y + e) - depth(x, y - e)) / (2.0 * e);
        // Depth grows downward: the surface normal leans toward increasing depth.
        let n = (Vec3::new(gx, gy, 1.0) + 0.15 * Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), 0.0)).normalize();
        (n, if warp(x, y) { Vec3::X } else { Vec3::Y })
    };
    let lobe = |s: f32| ClothLobe { k: Vec3::new(0.6, 0.5, 0.4) * (0.5 + s), beta: 0.05 + 0.1 * s, gamma: 0.4 + s };
    let mut levels = Vec::new();
    let count = max_levels(n, n);
    for level in 0..count {
        let (lw, lh) = level_dims(n, n, level);
        let surface = if level == 0 {
            let mut table = BrdfTable::new();
            for c in 0..8 {
                let s = c as f32 / 8.0;
                table.push(&ClothParams::new(Vec3::new(0.1, 0.05, 0.03) * (1.0 + s), 1.46, 1.0 + s, &[lobe(s), lobe(1.0 - s)]));
            }
            let mut texels = Vec::with_capacity((lw * lh) as usize);
            for j in 0..lh {
                for i in 0..lw {
                    let (x, y) = centre(i, j);
                    let (nn, t) = frame(&mut rng, x, y);
                    let cluster = ((rng.next_u64() % 4) as u16) + if warp(x, y) { 0 } else { 4 };
                    texels.push(ClusteredTexel::new(nn, t, cluster));
                }
            }
            Surface::Clustered { texels, table }
        } else {
            let mut table = BrdfTable::new();
            let size = texel * (1u32 << level) as f32;
            for j in 0..lh {
                for i in 0..lw {
                    let (x, y) = ((i as f32 + 0.5) * size, (j as f32 + 0.5) * size);
                    let (nn, _) = frame(&mut rng, x, y);
                    table.push_framed(Vec3::new(0.12, 0.06, 0.04), 1.46, 1.5, &[(lobe(0.3), nn, Vec3::X), (lobe(0.6), nn, Vec3::Y)]);
                }
            }
            Surface::PerTexel(table)
        };
        levels.push(Level { width: lw, height: lh, surface, flyaways: None, transmission: None, transmission_visibility: None, view_tilt: None, gradient: None, curvature: None });
    }
    // Level-0 flyaway voxels, then their downsampling.
    let mut voxels: Vec<(u32, u32, u16, Vec3)> = Vec::new();
    for j in 0..n {
        for i in 0..n {
            if rng.next_u64().is_multiple_of(50) {
                for _ in 0..1 + rng.next_u64() % 3 {
                    let (x, y) = centre(i, j);
                    let limit = ((depth(x, y) / tile.voxel_depth) as u64).max(2);
                    voxels.push((i, j, (rng.next_u64() % limit) as u16, rng.unit_vector()));
                }
            }
        }
    }
    voxels.sort_by_key(|v| (v.1, v.0, v.2));
    voxels.dedup_by_key(|v| (v.0, v.1, v.2));
    let fly = silk_params();
    for (level, l) in levels.iter_mut().enumerate() {
        let mut cells: std::collections::BTreeMap<(u32, u32, u16), (u32, Vec3)> = std::collections::BTreeMap::new();
        for &(i, j, k, t) in &voxels {
            let e = cells.entry((i >> level, j >> level, k >> level)).or_insert((0, t));
            e.0 += 1;
        }
        let children = 8f32.powi(level as i32);
        let mut table = BrdfTable::new();
        table.push(&fly);
        let f = Flyaways::from_columns(l.width, l.height, table, |i, j| {
            cells.range((i, j, 0)..=(i, j, u16::MAX)).map(|(&(_, _, k), &(c, t))| FlyawayInput { depth: k, alpha: (c as f32 / children).min(1.0), tangent: t, param: 0 }).collect()
        });
        l.flyaways = f.ok();
    }
    let meta = BakeMetadata { note: format!("synthetic_model({n}, {seed})"), seed, ..example_meta(&tile, count, [n, n, 64]) };
    HybridModel { tile, height, levels, meta }
}

/// Gives every level of `model` a transmission term (a BSDF, format 1.3): `t` scaled
/// per texel by 0.5–1.5 in a checker of `cells` × `cells` over the tile, so that the
/// texels differ and a renderer that reads the wrong one shows it. Where `t.grad` or
/// `t.curv` is not zero, each level also gets a transmission visibility (format 1.16):
/// `t.grad`, `t.curv` on one colour of the checker, the gradient's x terms and the
/// curvature negated on the other.
pub fn add_transmission(model: &mut HybridModel, t: &crate::brdf::ClothTransmission, cells: u32) {
    use crate::hybrid::{PackedTransmission, PackedTransmissionVisibility};
    for l in model.levels.iter_mut() {
        let (w, h) = (l.width, l.height);
        let records = (0..h)
            .flat_map(|j| (0..w).map(move |i| (i, j)))
            .map(|(i, j)| {
                let odd = ((i * cells / w) + (j * cells / h)) % 2 == 1;
                let s = if odd { 1.5 } else { 0.5 };
                PackedTransmission::new(&crate::brdf::ClothTransmission { kd: t.kd * s, lobe: ClothLobe { k: t.lobe.k * s, ..t.lobe }, tau: t.tau, gap: crate::brdf::ClothOpenness { o: t.gap.o * s / 1.5, ..t.gap }, grad: [0.0; 4], curv: [0.0; 6] })
            })
            .collect();
        l.transmission = Some(records);
        if t.grad != [0.0; 4] || t.curv != [0.0; 6] {
            let [ux, uy, lx, ly] = t.grad;
            l.transmission_visibility = Some(checker(l, cells, PackedTransmissionVisibility::new(t.grad, t.curv), PackedTransmissionVisibility::new([-ux, uy, -lx, ly], t.curv.map(|q| -q))));
        }
    }
}

/// Gives every coarse level of `model` view tilts (format 1.4) that differ per texel:
/// B = `strength` · (I + a small skew) and c = `strength` · (±1, ±½) in a checker of
/// `cells` × `cells`, so that a renderer that ignores or misreads them shows it.
pub fn add_view_tilts(model: &mut HybridModel, strength: f32, cells: u32) {
    use crate::brdf::visible_normal::ViewTilt;
    use crate::hybrid::PackedViewTilt;
    for l in model.levels.iter_mut().skip(1) {
        let (w, h) = (l.width, l.height);
        let records = (0..h)
            .flat_map(|j| (0..w).map(move |i| (i, j)))
            .map(|(i, j)| {
                let odd = ((i * cells / w) + (j * cells / h)) % 2 == 1;
                let s = if odd { 1.0 } else { -1.0 };
                PackedViewTilt::new(&ViewTilt { b: [strength, 0.1 * strength * s, -0.05 * strength, 0.8 * strength], c: [strength * s, 0.5 * strength * s] })
            })
            .collect();
        l.view_tilt = Some(records);
    }
}

/// Gives every level of `model` visibility gradients (format 1.12) that differ per
/// texel: g = ±(0.4, −0.3, 0.25, 0.5) and (−0.2, 0.6, −0.5, 0.1) in a checker of
/// `cells` × `cells`, so that a renderer that ignores or misreads them shows it.
pub fn add_gradients(model: &mut HybridModel, cells: u32) {
    use crate::hybrid::PackedGradient;
    for l in model.levels.iter_mut() {
        l.gradient = Some(checker(l, cells, PackedGradient::new([0.4, -0.3, 0.25, 0.5]), PackedGradient::new([-0.2, 0.6, -0.5, 0.1])));
    }
}

/// One record per texel of `l` (x fastest): `odd` and `even` in a checker of `cells` ×
/// `cells`.
fn checker<T: Copy>(l: &Level, cells: u32, odd: T, even: T) -> Vec<T> {
    let (w, h) = (l.width, l.height);
    (0..h).flat_map(|j| (0..w).map(move |i| if ((i * cells / w) + (j * cells / h)) % 2 == 1 { odd } else { even })).collect()
}

/// Gives every level of `model` visibility curvatures (format 1.15) that differ per
/// texel: q = (0.3, −0.2, 0.25, −0.4, 0.35, 0.1) and (−0.25, 0.4, −0.1, 0.3, −0.3, −0.2)
/// in a checker of `cells` × `cells`, so that a renderer that ignores or misreads them
/// shows it.
pub fn add_curvatures(model: &mut HybridModel, cells: u32) {
    use crate::hybrid::PackedCurvature;
    for l in model.levels.iter_mut() {
        l.curvature = Some(checker(l, cells, PackedCurvature::new([0.3, -0.2, 0.25, -0.4, 0.35, 0.1]), PackedCurvature::new([-0.25, 0.4, -0.1, 0.3, -0.3, -0.2])));
    }
}

/// Gives the flyaway nodes of every coarse level of `model` spread records (format 1.5)
/// that differ per node: roll 0.7·k rad, λ₂ = `strength`·(0.2 + 0.1·(k mod 3)), λ₃ =
/// `strength`·0.1, occupied depths [0.1·(k mod 3), 1 − 0.2·(k mod 2)] for node k, so that
/// a renderer that ignores or misreads them shows it.
pub fn add_axis_spreads(model: &mut HybridModel, strength: f32) {
    use crate::hybrid::PackedAxisSpread;
    for l in model.levels.iter_mut().skip(1) {
        if let Some(f) = l.flyaways.as_mut() {
            f.spreads = Some((0..f.nodes.len()).map(|k| PackedAxisSpread::new(0.7 * k as f32, strength * (0.2 + 0.1 * (k % 3) as f32), strength * 0.1).with_slab(0.1 * (k % 3) as f32, 1.0 - 0.2 * (k % 2) as f32)).collect());
        }
    }
}

/// Gives the flyaway nodes of every coarse level of `model` that has spread records a
/// second group of axes (format 1.8) that differs per node: axis turning with k, share
/// 0.2·(k mod 4) (none where k is a multiple of 4), spread 0.15·(k mod 3) for node k.
pub fn add_axis_groups(model: &mut HybridModel) {
    use crate::hybrid::PackedAxisGroup;
    for l in model.levels.iter_mut().skip(1) {
        if let Some(f) = l.flyaways.as_mut().filter(|f| f.spreads.is_some()) {
            f.groups = Some((0..f.nodes.len()).map(|k| PackedAxisGroup::new(Vec3::new((1.3 * k as f32).cos(), (0.9 * k as f32).sin(), 0.4 - 0.1 * (k % 5) as f32), 0.2 * (k % 4) as f32, 0.15 * (k % 3) as f32)).collect());
        }
    }
}

/// Gives every coarse flyaway level of `model` a path gain (format 1.9) that rises with
/// the polar angle and differs per level: g(θ_k) = 0.5 + 0.2·k + 0.1·ℓ at node k of
/// level ℓ, so that a renderer that ignores or misreads it shows it.
pub fn add_path_gains(model: &mut HybridModel) {
    use crate::hybrid::{PATH_GAIN_NODES, PathGain};
    for (level, l) in model.levels.iter_mut().enumerate().skip(1) {
        if let Some(f) = l.flyaways.as_mut() {
            f.path_gain = Some(PathGain(std::array::from_fn::<f32, PATH_GAIN_NODES, _>(|k| 0.5 + 0.2 * k as f32 + 0.1 * level as f32)));
        }
    }
}
