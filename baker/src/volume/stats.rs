//! Summary numbers of a fabric volume or a single grid (what `fabric inspect` prints),
//! and the column scan that separates the fabric's surface from flyaways.
//!
//! Column scan (DESIGN.md §5, paper §5.2): scan each column from the top; the first run
//! of non-empty voxels longer than one fiber's thickness is the surface (its top is
//! h0); non-empty voxels above it are flyaways. A column without such a run counts all
//! its voxels as flyaways. This is an estimate: a hair standing vertically makes a long
//! run and reads as surface.
//!
//! Sums are taken per fixed chunk of voxels and added in order, so the numbers do not
//! depend on the number of threads.

use rayon::prelude::*;
use serde::Serialize;

use super::grid::FabricVolume;
use super::vol::VolGrid;

/// Min, max and mean of some values.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Range {
    pub min: f64,
    pub max: f64,
    pub mean: f64,
    pub count: u64,
}

#[derive(Clone, Copy, Debug)]
struct Acc {
    min: f64,
    max: f64,
    sum: f64,
    n: u64,
}

impl Default for Acc {
    fn default() -> Self {
        Acc { min: f64::INFINITY, max: f64::NEG_INFINITY, sum: 0.0, n: 0 }
    }
}

impl Acc {
    #[inline]
    fn add(&mut self, v: f64) {
        self.min = self.min.min(v);
        self.max = self.max.max(v);
        self.sum += v;
        self.n += 1;
    }

    fn merge(&mut self, o: &Acc) {
        self.min = self.min.min(o.min);
        self.max = self.max.max(o.max);
        self.sum += o.sum;
        self.n += o.n;
    }

    fn range(&self) -> Range {
        if self.n == 0 { Range::default() } else { Range { min: self.min, max: self.max, mean: self.sum / self.n as f64, count: self.n } }
    }
}

/// The column scan's result.
#[derive(Clone, Debug, Serialize)]
pub struct SurfaceScan {
    /// Runs longer than this many voxels count as surface.
    pub min_run: usize,
    /// Per column (x fastest): height of the surface top in cells (z index + 1), or 0
    /// where the column has no surface run.
    #[serde(skip)]
    pub heights: Vec<u32>,
    /// Columns with a surface run.
    pub surface_columns: u64,
    /// Surface height over those columns, in cells.
    pub surface_height: Range,
    /// Non-empty voxels above the surface (or in columns without one).
    pub flyaway_voxels: u64,
    /// Columns with at least one flyaway voxel.
    pub flyaway_columns: u64,
}

/// Scans every column from the top (see the module docs).
pub fn scan_surface(vol: &FabricVolume, min_run: usize) -> SurfaceScan {
    let [nx, ny, nz] = vol.dims();
    let per_column: Vec<(u32, u64)> = (0..nx * ny)
        .into_par_iter()
        .with_min_len(256)
        .map(|c| {
            let (x, y) = (c % nx, c / nx);
            let (mut run, mut above) = (0usize, 0u64);
            for z in (0..nz).rev() {
                if vol.voxel(x, y, z).is_empty() {
                    above += run as u64;
                    run = 0;
                    continue;
                }
                run += 1;
                if run > min_run {
                    return ((z + run) as u32, above);
                }
            }
            (0, above + run as u64)
        })
        .collect();
    let mut acc = Acc::default();
    let (mut flyaway_voxels, mut flyaway_columns) = (0, 0);
    for &(h, f) in &per_column {
        if h > 0 {
            acc.add(h as f64);
        }
        flyaway_voxels += f;
        flyaway_columns += u64::from(f > 0);
    }
    SurfaceScan {
        min_run,
        heights: per_column.iter().map(|p| p.0).collect(),
        surface_columns: acc.n,
        surface_height: acc.range(),
        flyaway_voxels,
        flyaway_columns,
    }
}

/// Summary of a fabric volume.
#[derive(Clone, Debug, Serialize)]
pub struct FabricStats {
    pub dims: [usize; 3],
    pub bbox_min: [f32; 3],
    pub bbox_max: [f32; 3],
    pub voxel_size: [f32; 3],
    pub density_scale: f32,
    pub roughness: f32,
    pub filled_voxels: u64,
    pub filled_fraction: f64,
    /// Over filled voxels.
    pub density: Range,
    pub albedo: [Range; 3],
    /// |ω_f| components over filled voxels (how much fiber runs along x, y, z).
    pub orientation_abs: [Range; 3],
    /// Packed in-memory size.
    pub memory_bytes: usize,
    pub surface: SurfaceScan,
}

const CHUNK: usize = 1 << 16;

/// Computes [`FabricStats`]; `min_run` as in [`scan_surface`].
pub fn fabric_stats(vol: &FabricVolume, min_run: usize) -> FabricStats {
    let parts: Vec<[Acc; 7]> = vol
        .voxels()
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut a = [Acc::default(); 7];
            for v in chunk.iter().filter(|v| !v.is_empty()) {
                a[0].add(v.density() as f64);
                let (al, w) = (v.albedo(), v.orientation().abs());
                for c in 0..3 {
                    a[1 + c].add(al[c] as f64);
                    a[4 + c].add(w[c] as f64);
                }
            }
            a
        })
        .collect();
    let mut acc = [Acc::default(); 7];
    for p in &parts {
        for (a, b) in acc.iter_mut().zip(p) {
            a.merge(b);
        }
    }
    let b = vol.bbox();
    let filled = acc[0].n;
    FabricStats {
        dims: vol.dims(),
        bbox_min: b.min.to_array(),
        bbox_max: b.max.to_array(),
        voxel_size: vol.voxel_size().to_array(),
        density_scale: vol.material.density_scale,
        roughness: vol.material.roughness,
        filled_voxels: filled,
        filled_fraction: filled as f64 / vol.voxels().len().max(1) as f64,
        density: acc[0].range(),
        albedo: [acc[1].range(), acc[2].range(), acc[3].range()],
        orientation_abs: [acc[4].range(), acc[5].range(), acc[6].range()],
        memory_bytes: vol.memory_bytes(),
        surface: scan_surface(vol, min_run),
    }
}

/// Summary of one grid.
#[derive(Clone, Debug, Serialize)]
pub struct GridStats {
    pub dims: [usize; 3],
    pub channels: usize,
    pub bbox_min: [f32; 3],
    pub bbox_max: [f32; 3],
    /// Per channel, over all voxels.
    pub channel: Vec<Range>,
    /// Voxels with any non-zero channel.
    pub nonzero_voxels: u64,
    pub nonzero_fraction: f64,
    /// For 3-channel grids: vector length over non-zero voxels.
    pub length: Option<Range>,
    /// NaN or infinite values.
    pub non_finite: u64,
}

/// Computes [`GridStats`].
pub fn grid_stats(g: &VolGrid) -> GridStats {
    let c = g.channels;
    let parts: Vec<(Vec<Acc>, Acc, u64, u64)> = g
        .data
        .par_chunks(CHUNK * c)
        .map(|chunk| {
            let mut ch = vec![Acc::default(); c];
            let (mut len, mut nonzero, mut bad) = (Acc::default(), 0u64, 0u64);
            for v in chunk.chunks_exact(c) {
                let mut any = false;
                let mut l2 = 0.0f64;
                for (k, &x) in v.iter().enumerate() {
                    if !x.is_finite() {
                        bad += 1;
                        continue;
                    }
                    ch[k].add(x as f64);
                    any |= x != 0.0;
                    l2 += (x as f64) * (x as f64);
                }
                if any {
                    nonzero += 1;
                    if c == 3 {
                        len.add(l2.sqrt());
                    }
                }
            }
            (ch, len, nonzero, bad)
        })
        .collect();
    let mut ch = vec![Acc::default(); c];
    let (mut len, mut nonzero, mut bad) = (Acc::default(), 0, 0);
    for (pc, pl, pn, pb) in &parts {
        for (a, b) in ch.iter_mut().zip(pc) {
            a.merge(b);
        }
        len.merge(pl);
        nonzero += pn;
        bad += pb;
    }
    GridStats {
        dims: g.dims,
        channels: c,
        bbox_min: g.bbox.min.to_array(),
        bbox_max: g.bbox.max.to_array(),
        channel: ch.iter().map(Acc::range).collect(),
        nonzero_voxels: nonzero,
        nonzero_fraction: nonzero as f64 / g.voxel_count().max(1) as f64,
        length: (c == 3).then(|| len.range()),
        non_finite: bad,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{Aabb, MaterialParams, Voxel};
    use glam::Vec3;

    #[test]
    fn column_scan_separates_surface_and_flyaways() {
        // Column (0,0): a 6-voxel surface run at z 2..8 and a 2-voxel strand at z 11..13.
        // Column (1,0): only a 2-voxel strand. Column (0,1): empty.
        let mut v = FabricVolume::new([2, 2, 16], Aabb::new(Vec3::ZERO, Vec3::ONE), MaterialParams::default());
        let f = Voxel::pack(1.0, Vec3::ONE, Vec3::X);
        for z in (2..8).chain(11..13) {
            v.set(0, 0, z, f);
        }
        v.set(1, 0, 5, f);
        v.set(1, 0, 6, f);
        let s = scan_surface(&v, 3);
        assert_eq!(s.heights, vec![8, 0, 0, 0]);
        assert_eq!((s.surface_columns, s.flyaway_voxels, s.flyaway_columns), (1, 4, 2));
        let st = fabric_stats(&v, 3);
        assert_eq!(st.filled_voxels, 10);
        assert_eq!(st.orientation_abs[0].min, 1.0);
    }
}
