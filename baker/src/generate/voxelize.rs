//! Fibers (polylines with a radius) to voxels: density = the fraction of each cell
//! that fibers cover, orientation = the tangent of the fiber covering it most, albedo =
//! that fiber's colour.
//!
//! Coverage of a cell by a tube of radius r (in voxels) at distance d from the cell
//! centre is the box-filtered step, c = clamp(r + ½ − d, 0, 1), scaled by
//! r² / (r² + 1/12) so that its integral over a cross-section is the tube's πr²
//! (∫ clamp(r + ½ − d)·2πd dd = π(r² + 1/12) for r ≥ ½). A fiber polyline covers a
//! cell with the maximum over its segments; fibers add up; ρ = min(Σ, 1). So ρ is a
//! volume fraction in [0, 1] and the optical depth through a fiber is what its
//! diameter says.
//!
//! Work is split into bands of rows (y), each with the segments that reach it
//! (binned once); bands run in parallel and write disjoint parts of the volume. Within
//! a band, segments are applied in global order, so the result is identical for any
//! number of threads. x and y wrap (the tile is periodic), z is clipped.

use glam::Vec3;
use indicatif::ProgressBar;
use rayon::prelude::*;

use crate::volume::{FabricVolume, Voxel};

/// One straight piece of a fiber, in voxel coordinates (cell (i, j, k) spans
/// [i, i+1] × [j, j+1] × [k, k+1]), unwrapped.
#[derive(Clone, Copy, Debug)]
pub struct Segment {
    pub a: Vec3,
    pub b: Vec3,
    pub fiber: u32,
}

/// Per-fiber constants.
#[derive(Clone, Copy, Debug)]
pub struct FiberStyle {
    /// Radius in voxels.
    pub radius: f32,
    pub albedo: Vec3,
}

/// Rows per band.
const BAND_ROWS: usize = 8;

/// Integer range of cells whose centre lies within `reach` of [lo, hi] on one axis.
#[inline]
fn cell_range(lo: f32, hi: f32, reach: f32) -> (i64, i64) {
    (((lo - reach) - 0.5).ceil() as i64, ((hi + reach) - 0.5).floor() as i64)
}

struct Scratch {
    sum: Vec<f32>,
    stamp: Vec<u32>,
    last: Vec<f32>,
    best: Vec<f32>,
    best_seg: Vec<u32>,
}

impl Scratch {
    fn reset(&mut self, n: usize) {
        for v in [&mut self.sum, &mut self.last, &mut self.best] {
            v.clear();
            v.resize(n, 0.0);
        }
        self.stamp.clear();
        self.stamp.resize(n, 0);
        self.best_seg.clear();
        self.best_seg.resize(n, 0);
    }
}

/// Rasterizes `segments` into `vol` (which must be empty), replacing its voxels.
pub fn voxelize(vol: &mut FabricVolume, segments: &[Segment], fibers: &[FiberStyle], progress: &ProgressBar) {
    let [nx, ny, nz] = vol.dims();
    let rows = BAND_ROWS.min(ny);
    let n_bands = ny.div_ceil(rows);

    // Bin segments by the bands their rows touch (wrapped in y).
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); n_bands];
    for (i, s) in segments.iter().enumerate() {
        let reach = fibers[s.fiber as usize].radius + 0.5;
        let (z0, z1) = cell_range(s.a.z.min(s.b.z), s.a.z.max(s.b.z), reach);
        if z1 < 0 || z0 >= nz as i64 {
            continue;
        }
        let (y0, y1) = cell_range(s.a.y.min(s.b.y), s.a.y.max(s.b.y), reach);
        for y in y0..=y1.min(y0 + ny as i64 - 1) {
            let band = y.rem_euclid(ny as i64) as usize / rows;
            if bins[band].last() != Some(&(i as u32)) {
                bins[band].push(i as u32);
            }
        }
    }

    // Disjoint mutable views: for each band, its piece of every z-slab.
    let mut pieces: Vec<Vec<&mut [Voxel]>> = (0..n_bands).map(|_| Vec::with_capacity(nz)).collect();
    for slab in vol.voxels_mut().chunks_mut(nx * ny) {
        for (b, piece) in slab.chunks_mut(nx * rows).enumerate() {
            pieces[b].push(piece);
        }
    }
    progress.set_length(n_bands as u64);
    pieces.into_par_iter().zip(bins.into_par_iter()).enumerate().for_each_init(
        || Scratch { sum: Vec::new(), stamp: Vec::new(), last: Vec::new(), best: Vec::new(), best_seg: Vec::new() },
        |scratch, (band, (mut out, list))| {
            let y_start = band * rows;
            let band_rows = rows.min(ny - y_start);
            rasterize_band(scratch, [nx, ny, nz], y_start, band_rows, &list, segments, fibers);
            for (z, piece) in out.iter_mut().enumerate() {
                for (k, v) in piece.iter_mut().enumerate() {
                    let i = z * band_rows * nx + k;
                    let rho = scratch.sum[i];
                    if rho > 0.0 {
                        let s = &segments[scratch.best_seg[i] as usize];
                        *v = Voxel::pack(rho.min(1.0), fibers[s.fiber as usize].albedo, s.b - s.a);
                    }
                }
            }
            progress.inc(1);
        },
    );
}

fn rasterize_band(sc: &mut Scratch, [nx, ny, nz]: [usize; 3], y_start: usize, rows: usize, list: &[u32], segments: &[Segment], fibers: &[FiberStyle]) {
    sc.reset(nz * rows * nx);
    for &si in list {
        let s = segments[si as usize];
        let style = fibers[s.fiber as usize];
        let r = style.radius;
        let reach = r + 0.5;
        let norm = r * r / (r * r + 1.0 / 12.0);
        let lo = s.a.min(s.b);
        let hi = s.a.max(s.b);
        let (x0, x1) = cell_range(lo.x, hi.x, reach);
        let (y0, y1) = cell_range(lo.y, hi.y, reach);
        let (z0, z1) = cell_range(lo.z, hi.z, reach);
        let (z0, z1) = (z0.max(0), z1.min(nz as i64 - 1));
        let ab = s.b - s.a;
        let len2 = ab.length_squared();
        let inv_len2 = if len2 > 0.0 { 1.0 / len2 } else { 0.0 };
        let stamp = s.fiber + 1;
        let x1 = x1.min(x0 + nx as i64 - 1);
        let y1 = y1.min(y0 + ny as i64 - 1);
        for y in y0..=y1 {
            let yw = y.rem_euclid(ny as i64) as usize;
            if yw < y_start || yw >= y_start + rows {
                continue;
            }
            let row = yw - y_start;
            let cy = y as f32 + 0.5;
            for z in z0..=z1 {
                let cz = z as f32 + 0.5;
                let base = (z as usize * rows + row) * nx;
                let mut xw = x0.rem_euclid(nx as i64) as usize;
                for x in x0..=x1 {
                    let c = Vec3::new(x as f32 + 0.5, cy, cz);
                    let t = ((c - s.a).dot(ab) * inv_len2).clamp(0.0, 1.0);
                    let d = (c - (s.a + ab * t)).length();
                    let cov = (reach - d).min(1.0) * norm;
                    if cov > 0.0 {
                        let i = base + xw;
                        if sc.stamp[i] != stamp {
                            sc.stamp[i] = stamp;
                            sc.sum[i] += cov;
                            sc.last[i] = cov;
                        } else if cov > sc.last[i] {
                            sc.sum[i] += cov - sc.last[i];
                            sc.last[i] = cov;
                        }
                        if cov > sc.best[i] {
                            sc.best[i] = cov;
                            sc.best_seg[i] = si;
                        }
                    }
                    xw += 1;
                    if xw == nx {
                        xw = 0;
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{Aabb, MaterialParams};

    fn empty(dims: [usize; 3]) -> FabricVolume {
        FabricVolume::new(dims, Aabb::new(Vec3::ZERO, Vec3::new(dims[0] as f32, dims[1] as f32, dims[2] as f32)), MaterialParams::default())
    }

    #[test]
    fn a_tube_has_its_volume_and_direction() {
        // A straight fiber of radius 2 along x through the middle of a periodic tile,
        // cut into uneven segments: Σρ per unit length = πr² within the box filter's
        // discretization (≤ 1 % for r = 2), and every filled cell points along x.
        let dims = [32, 24, 16];
        let mut vol = empty(dims);
        let (r, yz) = (2.0, Vec3::new(0.0, 11.3, 7.6));
        let cuts = [0.0, 1.7, 5.0, 9.1, 14.0, 20.5, 26.0, 32.0];
        let segs: Vec<Segment> = cuts.windows(2).map(|w| Segment { a: yz + Vec3::X * w[0], b: yz + Vec3::X * w[1], fiber: 0 }).collect();
        voxelize(&mut vol, &segs, &[FiberStyle { radius: r, albedo: Vec3::new(0.8, 0.5, 0.2) }], &ProgressBar::hidden());
        let total: f64 = vol.voxels().iter().map(|v| v.density() as f64).sum();
        let per_length = total / 32.0;
        let area = std::f64::consts::PI * (r as f64).powi(2);
        assert!((per_length / area - 1.0).abs() < 0.01, "{per_length} vs {area}");
        // Seamless along x: every column section has the same mass.
        let section = |x: usize| -> f64 { (0..dims[2]).flat_map(|z| (0..dims[1]).map(move |y| (y, z))).map(|(y, z)| vol.voxel(x, y, z).density() as f64).sum() };
        for x in 0..dims[0] {
            assert!((section(x) - area).abs() < 0.02 * area, "x = {x}: {}", section(x));
        }
        for v in vol.voxels().iter().filter(|v| !v.is_empty()) {
            assert!(v.orientation().x.abs() > 0.9999 && v.albedo().abs_diff_eq(Vec3::new(0.8, 0.5, 0.2), 1e-4));
            assert!(v.density() <= 1.0);
        }
    }

    #[test]
    fn fibers_add_up_and_wrap_in_y() {
        // Two crossing fibers, one wrapping across y = 0: overlap is clamped to ρ = 1 and
        // each fiber is counted once where its own segments overlap.
        let dims = [16, 16, 8];
        let mut vol = empty(dims);
        let segs = vec![
            Segment { a: Vec3::new(0.0, 8.0, 4.0), b: Vec3::new(8.0, 8.0, 4.0), fiber: 0 },
            Segment { a: Vec3::new(8.0, 8.0, 4.0), b: Vec3::new(16.0, 8.0, 4.0), fiber: 0 },
            Segment { a: Vec3::new(8.0, -8.0, 4.0), b: Vec3::new(8.0, 8.0, 4.0), fiber: 1 },
            Segment { a: Vec3::new(8.0, 8.0, 4.0), b: Vec3::new(8.0, 8.0, 4.0), fiber: 1 }, // degenerate: a point
        ];
        let style = FiberStyle { radius: 1.5, albedo: Vec3::ONE };
        voxelize(&mut vol, &segs, &[style, style], &ProgressBar::hidden());
        assert_eq!(vol.voxel(8, 8, 4).density(), 1.0);
        // Away from the crossing, the rim of fiber 0 is partial and the same on both of
        // its segments (joints are not counted twice: see the tube test's mass).
        let far = vol.voxel(3, 9, 4).density();
        assert!(far > 0.0 && far < 1.0);
        assert_eq!(vol.voxel(3, 9, 4).density(), vol.voxel(12, 9, 4).density());
        // Fiber 1 wraps: y = −8..8 covers rows 8..15 and 0..8.
        assert!(!vol.voxel(8, 12, 4).is_empty() && !vol.voxel(8, 1, 4).is_empty());
    }
}
