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
//! twill (baker/PREFILTER_MEASUREMENTS.md); [`Coverage::Volume`] keeps it. Its axis is the principal axis of the α-weighted Σ t tᵀ
//! (axes, never averaged as vectors). Its BRDF is the BRDF of the flyaway cluster with
//! the most coverage inside it, with each lobe widened by the spread of the merged axes:
//! β'² = β² + 2σ², σ² = 1 − eᵀ T e the α-weighted mean squared sine between the axes and
//! the principal one (the same moment rule as the surface lobes, `lobe_fit::moments`);
//! σ² is quantized to [`SPREAD_BINS`] steps so that a level's table stays small (one
//! entry per cluster and step in use). Renderers composite coarse voxels with the
//! path-length opacity 1 − (1 − α)^(ℓ/s) (`cpu::flyaways`).

use std::collections::BTreeMap;

use glam::{Mat3, Vec3};

use fabric_runtime::brdf::{BETA_MAX, ClothLobe, ClothParams};
use fabric_runtime::hybrid::{BrdfTable, FlyawayInput, Flyaways, HybridModel, ModelError, level_dims};

use crate::geometry::tangents::principal_axis;

/// Steps of the axis spread σ² ∈ [0, 2/3] in the coarse tables.
pub const SPREAD_BINS: u32 = 8;
const SPREAD_MAX: f32 = 2.0 / 3.0;

/// How a coarse voxel's α is computed from its level-0 voxels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Coverage {
    /// The mean opacity of its columns seen from above (the default).
    #[default]
    Projected,
    /// The mean coverage of its voxel positions.
    Volume,
}

/// What a coarse voxel accumulates.
#[derive(Clone, Default)]
struct Cell {
    alpha: f32,
    /// Per level-0 column (i, j): the transmittance through its voxels in this cell.
    columns: BTreeMap<(u32, u32), f32>,
    tensor: Mat3,
    /// Coverage per level-0 cluster.
    by_param: Vec<(u32, f32)>,
}

impl Cell {
    fn add(&mut self, alpha: f32, t: Vec3, param: u32, column: (u32, u32)) {
        self.alpha += alpha;
        *self.columns.entry(column).or_insert(1.0) *= 1.0 - alpha.clamp(0.0, 1.0);
        let t = t.normalize_or_zero();
        self.tensor += Mat3::from_cols(t * t.x, t * t.y, t * t.z) * alpha;
        match self.by_param.iter_mut().find(|s| s.0 == param) {
            Some(slot) => slot.1 += alpha,
            None => self.by_param.push((param, alpha)),
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

/// The flyaway lists of level `level` ≥ 1, merged from level 0's; `None` when level 0
/// has none.
pub fn flyaway_level(model: &HybridModel, level: usize, coverage: Coverage) -> Result<Option<Flyaways>, ModelError> {
    let Some(f0) = model.levels[0].flyaways.as_ref().filter(|f| !f.nodes.is_empty()) else {
        return Ok(None);
    };
    let (w0, h0) = (model.width(), model.height_px());
    let depth0 = (model.tile.height_scale / model.tile.voxel_depth).ceil().min(65536.0) as u32;
    let mut cells: BTreeMap<(u32, u32, u32), Cell> = BTreeMap::new();
    for j in 0..h0 {
        for i in 0..w0 {
            for node in f0.list((j * w0 + i) as usize) {
                let key = (j >> level, i >> level, (node.depth as u32) >> level);
                cells.entry(key).or_default().add(node.alpha(), node.tangent(), node.param, (i, j));
            }
        }
    }
    let (lw, lh) = level_dims(w0, h0, level);
    let extent = |c: u32, n: u32| super::extent(c, level, n).max(1);
    let base: Vec<ClothParams> = (0..f0.table.headers.len()).map(|k| f0.table.brdf_in_frame(k, fabric_runtime::brdf::cloth_frame(Vec3::Z, Vec3::X)).params).collect();
    let mut table = BrdfTable::new();
    let mut entries: BTreeMap<(u32, u32), u32> = BTreeMap::new();
    let mut columns: BTreeMap<(u32, u32), Vec<FlyawayInput>> = BTreeMap::new();
    for (&(j, i, k), cell) in &cells {
        let alpha = match coverage {
            Coverage::Volume => cell.alpha / (extent(i, w0) * extent(j, h0) * extent(k, depth0)) as f32,
            Coverage::Projected => cell.columns.values().map(|t| 1.0 - t).sum::<f32>() / (extent(i, w0) * extent(j, h0)) as f32,
        };
        let alpha = alpha.clamp(2.0 / 65535.0, 1.0);
        let tensor = cell.tensor * (1.0 / cell.alpha.max(1e-30));
        let axis = principal_axis(tensor).unwrap_or(Vec3::X);
        let spread = (1.0 - axis.dot(tensor * axis)).clamp(0.0, SPREAD_MAX);
        let bin = ((spread / SPREAD_MAX) * (SPREAD_BINS - 1) as f32).round() as u32;
        let param = cell.by_param.iter().fold((0u32, -1.0f32), |b, s| if s.1 > b.1 { *s } else { b }).0;
        let param = (param as usize).min(base.len() - 1) as u32;
        let entry = *entries.entry((param, bin)).or_insert_with(|| table.push(&widened(&base[param as usize], bin)));
        let depth = u16::try_from(k).map_err(|_| ModelError::FlyawayNode { level, node: 0, why: format!("depth index {k} does not fit 16 bits") })?;
        columns.entry((i, j)).or_default().push(FlyawayInput { depth, alpha, tangent: axis, param: entry });
    }
    Flyaways::from_columns(lw, lh, table, |i, j| columns.remove(&(i, j)).unwrap_or_default()).map(Some)
}
