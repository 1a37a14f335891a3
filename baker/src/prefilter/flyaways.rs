//! The flyaway volume of coarse levels (paper §5.3.5): level-0 voxels merged 2^ℓ at a
//! time in x, y and z.
//!
//! A coarse voxel's coverage is what it hides seen straight down: the mean over the
//! level-0 columns it covers *that exist* (at the tile's x–y edges a coarse voxel
//! covers fewer than 4^ℓ) of each column's opacity through its 2^ℓ layers,
//! α = 1 − mean_columns Π_layers (1 − α₀). The mean coverage of the positions
//! (Σ α₀ / (n_x n_y n_z), the first reading) makes a thin fibre crossing a
//! coarse voxel nearly transparent — one filled voxel of 8 gives α = 1/8 where it hides
//! 1/4 of the view — and measured 9.7% against 1.4% without flyaways on a far view of
//! twill (baker/PREFILTER_MEASUREMENTS.md); [`Coverage::Volume`] keeps it.
//!
//! **Free space.** A ray stops at the surface, and a coarse voxel often reaches below it
//! (at satin's level 1 half of them, a mean 27% of their depth; at level 3 all, 55%):
//! only the part above is ever crossed. Its fibres all lie in that part, so α is the
//! coverage of the free depth: α' = 1 − (1 − α)^(1/f), f the mean free fraction of its
//! columns. Without it the coarse flyaways' opacity fell with the level (satin at 70°:
//! 0.44 at level 0, 0.33 at level 3, 0.23 at level 5); with it every level is within
//! 0.43 ± 0.02. With spread records a node also stores the depth range its level-0
//! layers occupy; renderers cross only that range, and f counts only its free part (a
//! grazing ray to a yarn's crest passes above fibres that lie low in the voxel).
//!
//! **What a level-0 ray meets.** A level-0 voxel counts by what a ray down its column
//! meets of it: its part above the surface (opacity 1 − (1 − α₀)^free; a voxel wholly
//! below the surface is never seen and counts for nothing), and each voxel's share of
//! the axis tensor and of the cluster vote is that opacity times the transmittance of the
//! voxels over it in the same cell, w = α₀ Π_above (1 − α₀) — seen from above, a fibre
//! under another is hidden. Measured on felt (16 px far views, flyaways alone, chain
//! mean over truth's, 0° / 45° / 70°): 1.108 / 1.079 / 1.465 with every voxel counted
//! whole, 1.056 / 1.019 / 1.361 with both (baker/PREFILTER_MEASUREMENTS.md, "What a
//! level-0 ray meets").
//!
//! Its axis is the principal axis of that weighted axis tensor T = Σ w t tᵀ / Σ w (axes,
//! never averaged as vectors), and the node stores the spread of T about it
//! (`FLYAWAY_SPREAD`, format 1.5): renderers shade it as four axes on a cone with T's
//! second moment (`brdf::axis_spread`), which brings a node's response to within a few
//! percent of the mean of the level-0 nodes it merges at 45° (one merged axis: 0.5–0.9
//! of it; a lit fibre among unlit ones is all or nothing). Where the fibres split in two
//! groups of axes (warp and weft, whose tensor is also that of fibres along the
//! diagonals), the node's axis and record are the larger group's and the other is its
//! `FLYAWAY_GROUP` record (format 1.8, [`split_axes`]). Its BRDF is that of the
//! flyaway cluster with the most of that weight inside it. Without spread records
//! (`PrefilterOptions::flyaway_spread` off) each lobe is widened by the spread instead:
//! β'² = β² + 2σ², σ² = 1 − eᵀ T e (the moment rule of the surface lobes,
//! `lobe_fit::moments`), σ² quantized to [`SPREAD_BINS`] steps so that a level's table
//! stays small (one entry per cluster and step in use). Renderers composite coarse voxels
//! with the path-length opacity 1 − (1 − α)^(ℓ/s) (`cpu::flyaways`).

use std::collections::BTreeMap;

use glam::{Mat3, Vec3};

use fabric_runtime::brdf::{BETA_MAX, ClothLobe, ClothParams};
use fabric_runtime::brdf::axis_spread::spread_basis;
use fabric_runtime::hybrid::packing::{octahedral_decode, octahedral_encode};
use fabric_runtime::hybrid::{BrdfTable, FlyawayInput, Flyaways, HybridModel, ModelError, PackedAxisGroup, PackedAxisSpread, level_dims};

use crate::geometry::tangents::principal_axis;

/// Steps of the axis spread σ² ∈ [0, 2/3] in the coarse tables.
pub const SPREAD_BINS: u32 = 8;
const SPREAD_MAX: f32 = 2.0 / 3.0;

/// How a coarse voxel's α is computed from its level-0 voxels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Coverage {
    /// The mean opacity of its columns seen from above, over the part of the voxel its
    /// fibres occupy above the surface (the default).
    #[default]
    Projected,
    /// The mean coverage of its voxel positions (over the whole voxel, below the surface
    /// included).
    Volume,
}

/// What a coarse voxel accumulates.
#[derive(Clone)]
struct Cell {
    alpha: f32,
    /// Σ of the voxels' α times the transmittance over them inside the cell.
    seen: f32,
    /// Per level-0 column (i, j): the transmittance through its voxels in this cell.
    columns: BTreeMap<(u32, u32), f32>,
    tensor: Mat3,
    /// Coverage per level-0 cluster.
    by_param: Vec<(u32, f32)>,
    /// The level-0 layers its voxels occupy, [first, last].
    layers: (u32, u32),
    /// Each voxel's unit axis and weight (its share of `tensor`), for the two groups.
    axes: Vec<(Vec3, f32)>,
}

// Not derived: glam's Mat3::default() is the identity, which would add 1/Σα to every
// eigenvalue of the axis tensor.
impl Default for Cell {
    fn default() -> Cell {
        Cell { alpha: 0.0, seen: 0.0, columns: BTreeMap::new(), tensor: Mat3::ZERO, by_param: Vec::new(), layers: (u32::MAX, 0), axes: Vec::new() }
    }
}

impl Cell {
    /// Adds a level-0 voxel; a column's voxels must come top down (lists go down).
    fn add(&mut self, alpha: f32, t: Vec3, param: u32, column: (u32, u32), layer: u32) {
        self.alpha += alpha;
        self.layers = (self.layers.0.min(layer), self.layers.1.max(layer));
        let transmittance = self.columns.entry(column).or_insert(1.0);
        // What of it is seen from above through the cell's voxels over it.
        let seen = alpha * *transmittance;
        *transmittance *= 1.0 - alpha.clamp(0.0, 1.0);
        self.seen += seen;
        let t = t.normalize_or_zero();
        self.tensor += Mat3::from_cols(t * t.x, t * t.y, t * t.z) * seen;
        if seen > 0.0 && t != Vec3::ZERO {
            self.axes.push((t, seen));
        }
        match self.by_param.iter_mut().find(|s| s.0 == param) {
            Some(slot) => slot.1 += seen,
            None => self.by_param.push((param, seen)),
        }
    }
}

/// The table entry of cluster `param` widened by spread bin `bin`.
fn widened(base: &ClothParams, bin: u32) -> ClothParams {
    let spread = SPREAD_MAX * bin as f32 / (SPREAD_BINS - 1) as f32;
    let mut p = *base;
    for lobe in p.lobes[..p.lobe_count as usize].iter_mut() {
        *lobe = ClothLobe { beta: (lobe.beta * lobe.beta + 2.0 * spread).sqrt().min(BETA_MAX), ..*lobe };
    }
    p
}

/// The flyaway lists of level `level` ≥ 1, merged from level 0's, with spread records
/// where `spread` (else widened lobes), and each node's fibres in two groups of axes
/// where `groups` too (format 1.8); `None` when level 0 has none.
pub fn flyaway_level(model: &HybridModel, level: usize, coverage: Coverage, spread: bool, groups: bool) -> Result<Option<Flyaways>, ModelError> {
    let Some(f0) = model.levels[0].flyaways.as_ref().filter(|f| !f.nodes.is_empty()) else {
        return Ok(None);
    };
    let (w0, h0) = (model.width(), model.height_px());
    let depth0 = (model.tile.height_scale / model.tile.voxel_depth).ceil().min(65536.0) as u32;
    let mut cells: BTreeMap<(u32, u32, u32), Cell> = BTreeMap::new();
    let s0 = model.voxel_depth(0);
    for j in 0..h0 {
        for i in 0..w0 {
            let surface = model.depth(i, j);
            for node in f0.list((j * w0 + i) as usize) {
                // What a level-0 ray down this column meets of the voxel: the part above
                // the surface (rays stop there), opacity 1 − (1 − α₀)^free; a voxel wholly
                // below it is never seen.
                let alpha = match coverage {
                    Coverage::Volume => node.alpha(),
                    Coverage::Projected => {
                        let free = ((surface - node.depth as f32 * s0) / s0).clamp(0.0, 1.0);
                        if free <= 0.0 {
                            continue;
                        }
                        1.0 - (1.0 - node.alpha().clamp(0.0, 1.0)).powf(free)
                    }
                };
                let key = (j >> level, i >> level, (node.depth as u32) >> level);
                cells.entry(key).or_default().add(alpha, node.tangent(), node.param, (i, j), node.depth as u32);
            }
        }
    }
    let (lw, lh) = level_dims(w0, h0, level);
    let extent = |c: u32, n: u32| super::extent(c, level, n).max(1);
    let base: Vec<ClothParams> = (0..f0.table.headers.len()).map(|k| f0.table.brdf_in_frame(k, fabric_runtime::brdf::cloth_frame(Vec3::Z, Vec3::X)).params).collect();
    let mut table = BrdfTable::new();
    let mut entries: BTreeMap<(u32, u32), u32> = BTreeMap::new();
    let mut columns: BTreeMap<(u32, u32), Vec<FlyawayInput>> = BTreeMap::new();
    let mut spreads: BTreeMap<(u32, u32, u16), (PackedAxisSpread, PackedAxisGroup)> = BTreeMap::new();
    for (&(j, i, k), cell) in &cells {
        let alpha = match coverage {
            Coverage::Volume => cell.alpha / (extent(i, w0) * extent(j, h0) * extent(k, depth0)) as f32,
            Coverage::Projected => cell.columns.values().map(|t| 1.0 - t).sum::<f32>() / (extent(i, w0) * extent(j, h0)) as f32,
        };
        // The layers the fibres occupy, as fractions of the coarse voxel's depth.
        let span = (1u32 << level) as f32;
        // (Coverage::Volume keeps its meaning, the positions' mean: the whole voxel, as is.)
        let projected = coverage == Coverage::Projected;
        let slab = if spread && projected { ((cell.layers.0 as f32 - (k << level) as f32) / span, (cell.layers.1 as f32 + 1.0 - (k << level) as f32) / span) } else { (0.0, 1.0) };
        let slab = (((slab.0 * 255.0).floor() / 255.0).max(0.0), ((slab.1 * 255.0).ceil() / 255.0).min(1.0));
        let alpha = if projected { free_space_alpha(alpha, free_fraction(model, level, i, j, k, slab)) } else { alpha }.clamp(2.0 / 65535.0, 1.0);
        let mut tensor = cell.tensor * (1.0 / cell.seen.max(1e-30));
        // Two groups where the fibres split (warp and weft): the node's axis and record
        // are the larger group's, the other is its second group.
        let mut group = PackedAxisGroup::NONE;
        if spread && groups {
            if let Some(split) = split_axes(&cell.axes) {
                tensor = split.first;
                group = split.second;
            }
        }
        let axis = principal_axis(tensor).unwrap_or(Vec3::X);
        // With spread records the cone carries the spread: no widening.
        let sigma2 = if spread { 0.0 } else { (1.0 - axis.dot(tensor * axis)).clamp(0.0, SPREAD_MAX) };
        let bin = ((sigma2 / SPREAD_MAX) * (SPREAD_BINS - 1) as f32).round() as u32;
        let param = cell.by_param.iter().fold((0u32, -1.0f32), |b, s| if s.1 > b.1 { *s } else { b }).0;
        let param = (param as usize).min(base.len() - 1) as u32;
        let entry = *entries.entry((param, bin)).or_insert_with(|| table.push(&widened(&base[param as usize], bin)));
        let depth = u16::try_from(k).map_err(|_| ModelError::FlyawayNode { level, node: 0, why: format!("depth index {k} does not fit 16 bits") })?;
        if spread {
            spreads.insert((i, j, depth), (axis_spread(tensor, axis).with_slab(slab.0, slab.1), group));
        }
        columns.entry((i, j)).or_default().push(FlyawayInput { depth, alpha, tangent: axis, param: entry });
    }
    let mut f = Flyaways::from_columns(lw, lh, table, |i, j| columns.remove(&(i, j)).unwrap_or_default())?;
    if spread {
        let mut records = vec![PackedAxisSpread::default(); f.nodes.len()];
        let mut second = vec![PackedAxisGroup::NONE; f.nodes.len()];
        for j in 0..lh {
            for i in 0..lw {
                for (index, node) in f.list((j * lw + i) as usize).with_index() {
                    (records[index], second[index]) = spreads[&(i, j, node.depth)];
                }
            }
        }
        f.spreads = Some(records);
        if groups {
            f.groups = Some(second);
        }
    }
    Ok(Some(f))
}

/// The part of coarse voxel (i, j, k) of `level` a ray can cross through its fibres: the
/// mean over the level-0 columns of its footprint of the fraction of its depth that lies
/// in the occupied range `slab` (fractions of [k s_ℓ, (k+1) s_ℓ]) and above the surface
/// (a ray stops there).
fn free_fraction(model: &HybridModel, level: usize, i: u32, j: u32, k: u32, slab: (f32, f32)) -> f32 {
    let s = model.voxel_depth(level);
    let top = (k as f32 + slab.0) * s;
    let (w0, h0) = (model.width(), model.height_px());
    let (mut sum, mut n) = (0.0f32, 0u32);
    for jj in (j << level)..((j + 1) << level).min(h0) {
        for ii in (i << level)..((i + 1) << level).min(w0) {
            sum += ((model.depth(ii, jj) - top) / s).clamp(0.0, slab.1 - slab.0);
            n += 1;
        }
    }
    if n == 0 { 1.0 } else { sum / n as f32 }
}

/// The coverage of a voxel whose free part (fraction `free` of its depth) holds all of
/// its fibers: the density that gives coverage `alpha` over the free depth,
/// 1 − (1 − α)^(1/f) (α = 1 stays opaque; below 1 it stays below 1, so that a short
/// path through the voxel stays partly transparent).
fn free_space_alpha(alpha: f32, free: f32) -> f32 {
    if alpha >= 1.0 || !(free > 0.0) {
        return alpha;
    }
    let f = free.max(1e-3);
    (1.0 - (1.0 - alpha).powf(1.0 / f)).min(65534.0 / 65535.0)
}

/// A cell's fibres in two groups of axes.
struct AxisSplit {
    /// The larger group's axis tensor (trace 1).
    first: Mat3,
    /// The other group: its principal axis, its share of the weight, its spread.
    second: PackedAxisGroup,
}

/// Rounds of the two-group k-means.
const SPLIT_ROUNDS: usize = 8;

/// The fibres `axes` (unit, weighted) in two groups by k-means on axes (similarity
/// |a · c|, centres the principal axes of their groups), started from the principal axis
/// of all and the fibre that weighs most away from it (w·sin² of its angle). `None`
/// where they do not split: fewer than two, that fibre within about a degree of the
/// axis, or a group left empty or below one part in 255 of the weight (what the
/// record's share can hold). Nearly every voxel of more than one fibre direction splits:
/// the cone of one group is the special case of a second group of no weight. Measured on the presets'
/// 70° far views, fixed levels 1–3 with the flyaways alone, against the one cone of all
/// the fibres: satin's level 2 54.6% → 33.8%, felt's level 3 53.8% → 36.2%
/// (baker/PREFILTER_MEASUREMENTS.md, "What the coarse flyaways get wrong").
fn split_axes(axes: &[(Vec3, f32)]) -> Option<AxisSplit> {
    let outer = |a: Vec3| Mat3::from_cols(a * a.x, a * a.y, a * a.z);
    let all = axes.iter().fold(Mat3::ZERO, |m, (a, w)| m + outer(*a) * *w);
    let mut centres = [principal_axis(all)?, Vec3::ZERO];
    // The second seed: the fibre that weighs most away from the first axis, w·sin², so
    // that a stray fibre of little weight does not seed a group of its own.
    let (far, _) = axes.iter().map(|(a, w)| (*a, *w * (1.0 - a.dot(centres[0]).powi(2)))).fold((Vec3::ZERO, -1.0f32), |b, x| if x.1 > b.1 { x } else { b });
    if !(far.dot(centres[0]).abs() < 0.9998) {
        return None;
    }
    centres[1] = far;
    let mut tensors = [Mat3::ZERO; 2];
    let mut weights = [0.0f32; 2];
    for _ in 0..SPLIT_ROUNDS {
        tensors = [Mat3::ZERO; 2];
        weights = [0.0; 2];
        for (a, w) in axes {
            let g = usize::from(a.dot(centres[1]).abs() > a.dot(centres[0]).abs());
            tensors[g] += outer(*a) * *w;
            weights[g] += *w;
        }
        if !(weights[0] > 0.0 && weights[1] > 0.0) {
            return None;
        }
        centres = [principal_axis(tensors[0])?, principal_axis(tensors[1])?];
    }
    let (big, small) = if weights[0] >= weights[1] { (0, 1) } else { (1, 0) };
    let share = weights[small] / (weights[0] + weights[1]);
    if !(share * 255.0 >= 0.5) {
        return None;
    }
    let second = tensors[small] * (1.0 / weights[small]);
    let b = centres[small];
    let spread = (1.0 - b.dot(second * b)).clamp(0.0, 1.0);
    Some(AxisSplit { first: tensors[big] * (1.0 / weights[big]), second: PackedAxisGroup::new(b, share, spread) })
}

/// The spread record of a voxel of axis tensor `tensor` (trace 1) and merged axis
/// `axis`: the eigen-axes of the tensor in the plane ⊥ the axis *as stored* (the
/// renderer rebuilds the others from the decoded tangent), in closed form for 2×2.
fn axis_spread(tensor: Mat3, axis: Vec3) -> PackedAxisSpread {
    let e1 = octahedral_decode(octahedral_encode(axis));
    let (r, q) = spread_basis(e1);
    let (a, b, c) = (r.dot(tensor * r), r.dot(tensor * q), q.dot(tensor * q));
    let mid = 0.5 * (a + c);
    let half = (0.25 * (a - c) * (a - c) + b * b).sqrt();
    let roll = 0.5 * (2.0 * b).atan2(a - c);
    PackedAxisSpread::new(roll, (mid + half).max(0.0), (mid - half).max(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tensor_of(axes: &[(Vec3, f32)]) -> Mat3 {
        let total: f32 = axes.iter().map(|a| a.1).sum();
        axes.iter().fold(Mat3::ZERO, |m, (t, w)| {
            let t = t.normalize();
            m + Mat3::from_cols(t * t.x, t * t.y, t * t.z) * (*w / total)
        })
    }

    #[test]
    fn two_groups_split_warp_from_weft_and_ignore_a_stray_fibre() {
        // Warp and weft half and half, and one near-vertical stray of little weight: the
        // stray must not seed a group of its own (it would leave warp and weft together).
        let stray = Vec3::new(0.05, 0.02, 1.0).normalize();
        let axes = [(Vec3::X, 1.0), (Vec3::Y, 1.0), (Vec3::X, 1.0), (Vec3::Y, 1.0), (stray, 0.001)];
        for order in [axes.to_vec(), axes.iter().rev().copied().collect()] {
            let split = split_axes(&order).expect("warp and weft split");
            let first = principal_axis(split.first).unwrap();
            let second = split.second.axis();
            let (x, y) = if first.x.abs() > 0.9 { (first, second) } else { (second, first) };
            assert!(x.x.abs() > 0.999 && y.y.abs() > 0.99, "{first} {second}");
            assert!((split.second.share() - 0.5).abs() < 0.01, "{:?}", split.second);
        }
        // One direction (either sign) does not split; nor does an empty or single cell.
        assert!(split_axes(&[(Vec3::X, 1.0), (-Vec3::X, 2.0)]).is_none());
        assert!(split_axes(&[(Vec3::Y, 1.0)]).is_none());
        assert!(split_axes(&[]).is_none());
        // A second group too small for the record's share (below 1/510) is none.
        assert!(split_axes(&[(Vec3::X, 1.0), (Vec3::Y, 1e-4)]).is_none());
    }

    #[test]
    fn a_cell_starts_empty() {
        // glam's Mat3::default() is the identity: a cell's tensor must start at zero.
        let mut c = Cell::default();
        c.add(0.5, Vec3::X, 0, (0, 0), 0);
        assert_eq!(c.tensor * (1.0 / c.seen), Mat3::from_cols(Vec3::X, Vec3::ZERO, Vec3::ZERO));
    }

    #[test]
    fn one_fibre_has_no_spread_and_two_keep_their_plane() {
        let t = Vec3::new(0.11, 0.99, -0.01).normalize();
        let s = axis_spread(tensor_of(&[(t, 1.0)]), t);
        assert!(s.lambda[0] <= 1 && s.lambda[1] <= 1, "{s:?}");
        // Two fibres 30° apart in the plane of t and x̂: one axis between them, spread
        // sin²15° along the plane's other direction.
        let (a, b) = (Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.5, 3f32.sqrt() / 2.0, 0.0));
        let tensor = tensor_of(&[(a, 1.0), (b, 1.0)]);
        let axis = principal_axis(tensor).unwrap();
        let s = axis_spread(tensor, axis);
        let (l2, l3) = s.lambdas();
        assert!((l2 - 15f32.to_radians().sin().powi(2)).abs() < 2.0 / 255.0 && l3 < 1.0 / 255.0, "{l2} {l3}");
        let node = fabric_runtime::hybrid::FlyawayNode { tangent: octahedral_encode(axis), ..Default::default() };
        let axes = s.axes(&node);
        // The cone's two heavy axes are the fibres.
        for t in [a, b] {
            assert!(axes.axes[..2].iter().any(|x| x.dot(t).abs() > 0.999), "{t} not in {:?}", axes.axes);
        }
    }
}
