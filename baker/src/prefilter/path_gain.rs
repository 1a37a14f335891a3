//! The coarse flyaways' path gain (format 1.9; runtime/HYBRID_FORMAT.md §7.3): per
//! coarse level, the gain g(θ) on the opacity exponent, 1 − (1 − α)^(g·ℓ/s), at the
//! polar angles θ = 0°, 10°, … 80° of [`PathGain`].
//!
//! Why: a coarse voxel's α is what its fibres hide seen from above (§7), and Beer's law
//! carries it to slanted rays as if the fibres were a random medium. They are not —
//! mostly flat-lying, clumped, reaching below the surface where rays stop — so at a
//! slant the coarse levels let 5–20% too much light through (and, from above, a few
//! percent too little), and a distant pixel shows the surface behind them too brightly
//! (baker/PREFILTER_MEASUREMENTS.md, "The coarse flyaways' opacity by angle").
//!
//! The fit: for each node angle θ_k, [`GAIN_AZIMUTHS`] azimuths, rays leave the top
//! plane at jittered points of a [`GAIN_RAYS`]² grid over the tile toward −ω, meet the
//! height field (the same for every level), and march each level's flyaways between:
//! T_r^ℓ, ray r's transmittance at level ℓ with no gain. Since the gain multiplies
//! every node's exponent on the ray, the ray's transmittance with gain g is (T_r^ℓ)^g,
//! so g_ℓ(θ_k) solves mean_r (T_r^ℓ)^g = mean_r T_r^0 — a monotone equation in one
//! unknown, solved by bisection within [`PATH_GAIN_RANGE`]. A level whose flyaways no
//! ray meets keeps g = 1.

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use fabric_runtime::cpu::flyaways::{FlyawayGrid, visit_flyaways};
use fabric_runtime::cpu::heightfield::{HeightTracer, HfTrace};
use fabric_runtime::hybrid::flyaway::{PATH_GAIN_RANGE, PATH_GAIN_STEP_DEGREES};
use fabric_runtime::hybrid::{HybridModel, PATH_GAIN_NODES, PathGain};
use fabric_runtime::scene::{Ray, direction_from_angles};

use crate::reference::rng::Rng;
use crate::reference::tracking::{GridRay, TracedMedium};

/// Azimuths per node angle (offset by half a step from the tile's axes, so that no ray
/// runs along a column line).
pub const GAIN_AZIMUTHS: usize = 8;
/// Rays per tile axis and direction (a jittered grid; fewer on a smaller tile: one per
/// level-0 texel).
pub const GAIN_RAYS: u32 = 128;
/// Height-field steps per ray.
const STEPS: u32 = 4096;
/// Column budget of a march (far more than a ray crosses at 80°).
const COLUMNS: u32 = 1 << 16;

/// What the fit found for one coarse level: the gains and, per node angle, the mean
/// transmittance of level 0 and of the level before the gain.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelGain {
    pub gain: PathGain,
    pub level0_transmittance: [f64; PATH_GAIN_NODES],
    pub level_transmittance: [f64; PATH_GAIN_NODES],
}

/// The fit's rays at node angle `k`: every azimuth's jittered grid over the tile, each
/// from the top plane to where it meets the height field, calling `each(ray, t_end)` in
/// parallel per row; the results in a fixed order (the same on any number of threads).
fn trace_rays<T: Send>(model: &HybridModel, periodic: bool, seed: u64, k: usize, each: &(dyn Fn(&Ray, f32, &mut Rng) -> T + Sync)) -> Vec<T> {
    let tracer = HeightTracer::new(model, periodic);
    let (w0, h0) = (model.width(), model.height_px());
    let (rx, ry) = (w0.min(GAIN_RAYS), h0.min(GAIN_RAYS));
    let size = model.tile.size;
    let (origin, top) = (model.tile.origin, model.tile.top_z);
    let polar = k as f32 * PATH_GAIN_STEP_DEGREES;
    let mut all = Vec::with_capacity((GAIN_AZIMUTHS as u32 * rx * ry) as usize);
    for a in 0..GAIN_AZIMUTHS {
        let azimuth = (a as f32 + 0.5) * 360.0 / GAIN_AZIMUTHS as f32;
        let wo: Vec3 = direction_from_angles(polar, azimuth);
        let stream = (k * GAIN_AZIMUTHS + a) as u64;
        let rows: Vec<Vec<T>> = (0..ry)
            .into_par_iter()
            .map(|j| {
                let mut out = Vec::with_capacity(rx as usize);
                for i in 0..rx {
                    let mut rng = Rng::new(seed, stream, (j * rx + i) as u64);
                    let (u, v) = rng.next_2d();
                    let start = origin + Vec2::new((i as f32 + u) / rx as f32, (j as f32 + v) / ry as f32) * size;
                    let ray = Ray::new(start.extend(top), -wo);
                    let mut steps = 0;
                    if let HfTrace::Hit(t_end) = tracer.trace(&ray, 0.0, f32::MAX, 0.0, STEPS, &mut steps) {
                        out.push(each(&ray, t_end, &mut rng));
                    }
                }
                out
            })
            .collect();
        all.extend(rows.into_iter().flatten());
    }
    all
}

/// The mask (`true` = removed, volume order, x fastest) that leaves a volume of `dims`
/// voxels with only the voxels `model`'s level-0 flyaway lists hold (one level-0 texel
/// per voxel column; node depth k is voxel layer dims[2] − 1 − k): the medium
/// [`fit_level0_gain`] takes.
pub fn all_but_level0_flyaways(model: &HybridModel, dims: [usize; 3]) -> Vec<bool> {
    let [nx, ny, nz] = dims;
    let mut removed = vec![true; nx * ny * nz];
    if let Some(f) = model.levels[0].flyaways.as_ref() {
        for index in 0..f.heads.len().min(nx * ny) {
            let (i, j) = (index % nx, index / nx);
            for node in f.list(index).filter(|n| (n.depth as usize) < nz) {
                removed[((nz - 1 - node.depth as usize) * ny + j) * nx + i] = false;
            }
        }
    }
    removed
}

/// Level 0's path gain against the volume it was baked from: g(θ_k) such that the mean
/// transmittance of the model's level-0 flyaway voxels matches the reference medium's
/// through the same voxels alone (`flyaways_only`: the medium with every other voxel
/// removed; ratio tracking, SGGX projected areas) along the same segments, top plane to
/// the model's surface. Level 0's α = ρ/ρ_solid crossed by Beer's law is isotropic; the
/// medium's fibres, mostly flat-lying, block less at a slant (their projected area
/// falls as a ray turns along them). Returns None where level 0 has no flyaways.
pub fn fit_level0_gain(model: &HybridModel, flyaways_only: &TracedMedium<'_>, seed: u64) -> Option<LevelGain> {
    let mut bare = model.clone();
    let f = bare.levels[0].flyaways.as_mut().filter(|f| !f.nodes.is_empty())?;
    f.path_gain = None;
    let f = bare.levels[0].flyaways.as_ref().unwrap();
    let grid = FlyawayGrid::new(&bare, 0, true);
    let mut gain = PathGain::ONE;
    let mut level0_transmittance = [1.0; PATH_GAIN_NODES];
    let mut level_transmittance = [1.0; PATH_GAIN_NODES];
    for k in 0..PATH_GAIN_NODES {
        let pairs: Vec<(f32, f32)> = trace_rays(&bare, true, seed, k, &|ray, t_end, rng| {
            let model_t = visit_flyaways(f, &grid, ray, 0.0, t_end, COLUMNS, |_, _, _, _| {}).transmittance;
            let g = GridRay::new(&flyaways_only.medium, ray.o, ray.d);
            (model_t, flyaways_only.transmittance(&g, 0.0, t_end, rng).0)
        });
        let model_t: Vec<f32> = pairs.iter().map(|p| p.0).collect();
        let target = mean(pairs.iter().map(|p| p.1 as f64));
        level0_transmittance[k] = target;
        level_transmittance[k] = mean(model_t.iter().map(|&t| t as f64));
        gain.0[k] = solve_gain(&model_t, target);
    }
    Some(LevelGain { gain, level0_transmittance, level_transmittance })
}

/// The path gains of levels 1..`model.levels.len()` (index 0 of the result is level 1);
/// `None` for a level without flyaways. The coarse levels' own gains, if any, are
/// ignored; level 0's (fitted against the volume, [`fit_level0_gain`]) is kept: it is
/// part of the transmittance they match.
pub fn fit_path_gains(model: &HybridModel, periodic: bool, seed: u64) -> Vec<Option<LevelGain>> {
    let levels = model.levels.len();
    let with_flyaways: Vec<bool> = model.levels.iter().map(|l| l.flyaways.as_ref().is_some_and(|f| !f.nodes.is_empty())).collect();
    if levels < 2 || !with_flyaways[0] && !with_flyaways[1..].iter().any(|&f| f) {
        return vec![None; levels.saturating_sub(1)];
    }
    // Each coarse level's marches without its gain (a model re-prefiltered may carry old ones).
    let mut bare = model.clone();
    for f in bare.levels.iter_mut().skip(1).filter_map(|l| l.flyaways.as_mut()) {
        f.path_gain = None;
    }
    let grids: Vec<FlyawayGrid> = (0..levels).map(|l| FlyawayGrid::new(&bare, l, periodic)).collect();
    // transmittances[k][level]: every ray's, over all azimuths.
    let transmittances: Vec<Vec<Vec<f32>>> = (0..PATH_GAIN_NODES)
        .map(|k| {
            let rays: Vec<Vec<f32>> = trace_rays(&bare, periodic, seed, k, &|ray, t_end, _| {
                (0..levels).map(|level| if with_flyaways[level] { visit_flyaways(bare.levels[level].flyaways.as_ref().unwrap(), &grids[level], ray, 0.0, t_end, COLUMNS, |_, _, _, _| {}).transmittance } else { 1.0 }).collect()
            });
            (0..levels).map(|level| rays.iter().map(|r| r[level]).collect()).collect()
        })
        .collect();
    (1..levels)
        .map(|level| {
            if !with_flyaways[level] {
                return None;
            }
            let mut gain = PathGain::ONE;
            let mut level0_transmittance = [1.0; PATH_GAIN_NODES];
            let mut level_transmittance = [1.0; PATH_GAIN_NODES];
            for k in 0..PATH_GAIN_NODES {
                let t0 = &transmittances[k][0];
                let tl = &transmittances[k][level];
                let target = mean(t0.iter().map(|&t| t as f64));
                level0_transmittance[k] = target;
                level_transmittance[k] = mean(tl.iter().map(|&t| t as f64));
                gain.0[k] = solve_gain(tl, target);
            }
            Some(LevelGain { gain, level0_transmittance, level_transmittance })
        })
        .collect()
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 { 1.0 } else { sum / n as f64 }
}

/// The g in [`PATH_GAIN_RANGE`] with mean (t_r)^g = `target` (its nearest end where
/// none does); 1 where the rays cross nothing or already match.
pub fn solve_gain(transmittances: &[f32], target: f64) -> f32 {
    let at = |g: f64| mean(transmittances.iter().map(|&t| if t <= 0.0 { 0.0 } else { (t as f64).powf(g) }));
    let now = at(1.0);
    if transmittances.is_empty() || now >= 1.0 - 1e-9 || (now - target).abs() <= 1e-6 {
        return 1.0;
    }
    let (mut lo, mut hi) = (PATH_GAIN_RANGE[0] as f64, PATH_GAIN_RANGE[1] as f64);
    if at(lo) <= target {
        return lo as f32;
    }
    if at(hi) >= target {
        return hi as f32;
    }
    // at() falls as g grows.
    for _ in 0..50 {
        let mid = 0.5 * (lo + hi);
        if at(mid) > target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (0.5 * (lo + hi)) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_gain_solves_for_the_mean_transmittance() {
        let t = [0.2f32, 0.5, 0.9, 1.0, 0.0];
        for g in [0.5f64, 0.8, 1.0, 1.3, 2.5] {
            let target = t.iter().map(|&x| if x <= 0.0 { 0.0 } else { (x as f64).powf(g) }).sum::<f64>() / t.len() as f64;
            let got = solve_gain(&t, target);
            assert!((got as f64 - g).abs() < 1e-4, "g {g}: solved {got}");
        }
        // Out of reach: the range's ends; nothing crossed: 1.
        assert_eq!(solve_gain(&t, 0.99), PATH_GAIN_RANGE[0]);
        assert_eq!(solve_gain(&t, 0.01), PATH_GAIN_RANGE[1]);
        assert_eq!(solve_gain(&[1.0, 1.0], 0.5), 1.0);
        assert_eq!(solve_gain(&[], 0.5), 1.0);
    }
}
