//! Statistics of a hybrid model, for `fabric inspect model.hyb` (text or JSON).

use serde::Serialize;

use super::lobe::TexelBrdf;
use super::model::{HybridModel, Surface};

/// min / mean / max of a quantity over `count` samples.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Range {
    pub count: u64,
    pub min: f64,
    pub mean: f64,
    pub max: f64,
}

#[derive(Clone, Copy, Debug, Default)]
struct Acc {
    count: u64,
    sum: f64,
    min: f64,
    max: f64,
}

impl Acc {
    fn add(&mut self, v: f32) {
        let v = v as f64;
        if self.count == 0 {
            self.min = v;
            self.max = v;
        }
        self.count += 1;
        self.sum += v;
        self.min = self.min.min(v);
        self.max = self.max.max(v);
    }

    fn range(&self) -> Range {
        Range { count: self.count, min: self.min, mean: if self.count > 0 { self.sum / self.count as f64 } else { 0.0 }, max: self.max }
    }
}

/// Parameters of one level, over its texels (clustered: each texel counts its cluster).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct LevelStats {
    pub level: usize,
    pub width: u32,
    pub height: u32,
    /// "clustered" or "per-texel".
    pub encoding: &'static str,
    /// Table size of the clustered encoding.
    pub clusters: Option<usize>,
    pub lobes_stored: usize,
    pub lobes_per_texel: Range,
    /// Luminance (Rec. 709) of k_d.
    pub kd_luminance: Range,
    pub eta: Range,
    pub a: Range,
    /// Luminance of k_j over all lobes.
    pub k_luminance: Range,
    pub beta: Range,
    /// γ over lobes with the falloff on.
    pub gamma: Range,
    /// Fraction of lobes with γ off (γ = ∞).
    pub gamma_off_fraction: f64,
    pub surface_bytes: u64,
    pub flyaway_nodes: usize,
    pub flyaway_columns: usize,
    pub flyaway_longest_list: usize,
    pub flyaway_alpha: Range,
    pub flyaway_bytes: u64,
    /// The flyaways' path gain at polar 0°, 10°, … 80° (format 1.9; None: Beer's law).
    pub flyaway_path_gain: Option<Vec<f32>>,
    /// Bytes of the transmission records (0: the level is reflection only).
    pub transmission_bytes: u64,
    /// The openness straight down, o, over the texels, and the fraction of texels with
    /// o > 0 (format 1.10; None: reflection only).
    pub openness: Option<Range>,
    pub open_texels: Option<f64>,
    /// The median of the transmission gradient's |g| = |(g_u, g_l)| over the texels
    /// (format 1.16; None: none).
    pub transmission_gradient_median: Option<f32>,
    /// Bytes of the view tilt records (0: none, as at level 0).
    pub view_tilt_bytes: u64,
    /// Bytes of the visibility gradient records (format 1.12; 0: none).
    pub gradient_bytes: u64,
    /// The median of |g| = |(g_o, g_i)| over the texels (None: no gradient).
    pub gradient_median: Option<f32>,
    /// Bytes of the visibility curvature records (format 1.15; 0: none).
    pub curvature_bytes: u64,
    /// The median of |q| over the texels (None: no curvature).
    pub curvature_median: Option<f32>,
    pub fit_error: Option<f32>,
    /// "WxH".
    pub resolution: String,
    /// Lobes per texel, mean and most (= lobes_per_texel's).
    pub mean_lobes: f64,
    pub max_lobes: u32,
    /// Surface, flyaway, transmission and view tilt bytes of the level.
    pub bytes: u64,
}

/// What `fabric inspect` prints about a model.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ModelStats {
    pub width: u32,
    pub height: u32,
    pub levels: usize,
    pub tile_origin: [f32; 2],
    pub tile_size: [f32; 2],
    pub top_z: f32,
    pub height_scale: f32,
    pub voxel_depth: f32,
    /// Depth below the top plane, world units.
    pub depth: Range,
    pub reading: &'static str,
    pub fitted_with_shadowing: bool,
    pub volumetric: bool,
    pub coarse_visibility: bool,
    /// The surface's diffuse law (`lambert` or `lommel-seeliger`).
    pub diffuse: &'static str,
    /// The flyaways' lobes (`facing` or `cylinder`, format 1.11).
    pub fiber_lobes: &'static str,
    /// The flyaways shadow the surface's lights (format 1.13).
    pub flyaway_shadow: bool,
    pub source_bbox: [f32; 6],
    pub source_dims: [u32; 3],
    pub seed: u64,
    pub note: String,
    pub height_bytes: u64,
    pub level_stats: Vec<LevelStats>,
    /// Payload bytes (height field + all levels), without headers and padding.
    pub payload_bytes: u64,
}

/// Rec. 709 luminance of linear RGB.
pub fn luminance(v: glam::Vec3) -> f32 {
    0.2126 * v.x + 0.7152 * v.y + 0.0722 * v.z
}

/// The median Euclidean norm of per-texel coefficient vectors (gradients, curvatures);
/// None for none.
fn median_norm<const N: usize>(rows: impl Iterator<Item = [f32; N]>) -> Option<f32> {
    let mut m: Vec<f32> = rows.map(|r| r.iter().map(|v| v * v).sum::<f32>().sqrt()).collect();
    m.sort_by(f32::total_cmp);
    m.get(m.len() / 2).copied()
}

/// Statistics of a (validated) model.
pub fn model_stats(m: &HybridModel) -> ModelStats {
    let mut depth = Acc::default();
    for &c in &m.height.codes {
        depth.add(super::packing::unorm16_value(c) * m.tile.height_scale);
    }
    let height_bytes = m.height.codes.len() as u64 * 2;
    let mut levels = Vec::new();
    for (index, level) in m.levels.iter().enumerate() {
        let (mut lobes_per_texel, mut kd, mut eta, mut a, mut k, mut beta, mut gamma) = Default::default();
        let mut gamma_off = 0u64;
        let mut add_texel = |b: &TexelBrdf| {
            let p = &b.params;
            Acc::add(&mut lobes_per_texel, p.lobe_count as f32);
            Acc::add(&mut kd, luminance(p.kd));
            Acc::add(&mut eta, p.eta);
            Acc::add(&mut a, p.a);
            for l in p.lobes() {
                Acc::add(&mut k, luminance(l.k));
                Acc::add(&mut beta, l.beta);
                if l.gamma > 0.0 {
                    Acc::add(&mut gamma, l.gamma);
                } else {
                    gamma_off += 1;
                }
            }
        };
        for j in 0..level.height {
            for i in 0..level.width {
                add_texel(&level.texel_brdf(i, j));
            }
        }
        let (encoding, clusters, lobes_stored) = match &level.surface {
            Surface::Clustered { table, .. } => ("clustered", Some(table.headers.len()), table.lobes.len()),
            Surface::PerTexel(table) => ("per-texel", None, table.lobes.len()),
        };
        let mut st = LevelStats {
            level: index,
            width: level.width,
            height: level.height,
            encoding,
            clusters,
            lobes_stored,
            lobes_per_texel: lobes_per_texel.range(),
            kd_luminance: kd.range(),
            eta: eta.range(),
            a: a.range(),
            k_luminance: k.range(),
            beta: beta.range(),
            gamma: gamma.range(),
            gamma_off_fraction: gamma_off as f64 / (gamma_off + gamma.count).max(1) as f64,
            surface_bytes: level.surface_bytes(),
            fit_error: m.meta.fit_error.get(index).copied().filter(|e| *e >= 0.0),
            ..Default::default()
        };
        if let Some(f) = &level.flyaways {
            let mut alpha = Acc::default();
            for n in &f.nodes {
                alpha.add(n.alpha());
            }
            st.flyaway_nodes = f.nodes.len();
            st.flyaway_columns = f.heads.iter().filter(|&&h| h != super::flyaway::NO_NODE).count();
            st.flyaway_longest_list = (0..f.heads.len()).map(|t| f.list(t).count()).max().unwrap_or(0);
            st.flyaway_alpha = alpha.range();
            st.flyaway_bytes = f.byte_size();
            st.flyaway_path_gain = f.path_gain.map(|g| g.0.to_vec());
        }
        st.resolution = format!("{}x{}", st.width, st.height);
        st.mean_lobes = st.lobes_per_texel.mean;
        st.max_lobes = st.lobes_per_texel.max as u32;
        st.transmission_bytes = level.transmission_bytes();
        if let Some(t) = &level.transmission {
            let mut o = Acc::default();
            t.iter().for_each(|r| o.add(r.decode().gap.o));
            st.openness = Some(o.range());
            st.open_texels = Some(t.iter().filter(|r| r.decode().gap.o > 0.0).count() as f64 / t.len().max(1) as f64);
        }
        st.transmission_gradient_median = level.transmission_visibility.as_ref().and_then(|g| median_norm(g.iter().map(|r| r.decode().0)));
        st.view_tilt_bytes = level.view_tilt_bytes();
        st.gradient_bytes = level.gradient_bytes();
        st.gradient_median = level.gradient.as_ref().and_then(|g| median_norm(g.iter().map(|r| r.decode())));
        st.curvature_bytes = level.curvature_bytes();
        st.curvature_median = level.curvature.as_ref().and_then(|q| median_norm(q.iter().map(|r| r.decode())));
        st.bytes = st.surface_bytes + st.flyaway_bytes + st.transmission_bytes + st.view_tilt_bytes + st.gradient_bytes + st.curvature_bytes;
        levels.push(st);
    }
    let payload_bytes = height_bytes + levels.iter().map(|l| l.bytes).sum::<u64>();
    let b = m.meta.source_bbox;
    ModelStats {
        width: m.width(),
        height: m.height_px(),
        levels: m.levels.len(),
        tile_origin: m.tile.origin.to_array(),
        tile_size: m.tile.size.to_array(),
        top_z: m.tile.top_z,
        height_scale: m.tile.height_scale,
        voxel_depth: m.tile.voxel_depth,
        depth: depth.range(),
        reading: m.meta.reading.name(),
        fitted_with_shadowing: m.meta.fitted_with_shadowing,
        volumetric: m.meta.volumetric,
        coarse_visibility: m.meta.coarse_visibility,
        diffuse: m.meta.diffuse.name(),
        fiber_lobes: m.meta.fiber_lobes.name(),
        flyaway_shadow: m.meta.flyaway_shadow,
        source_bbox: [b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z],
        source_dims: m.meta.source_dims,
        seed: m.meta.seed,
        note: m.meta.note.clone(),
        height_bytes,
        level_stats: levels,
        payload_bytes,
    }
}
