//! A fiber's cross-section at a voxel, measured in the volume: the fiber thickness
//! estimate (heightmap.rs) and the flyaway diameters (flyaways.rs) both rest on it.
//!
//! At voxel p with fiber axis ω, the voxels near the line through p along ω are binned by
//! their distance r from that line into a radial area profile A(r): the area of the
//! structure's cross-section within r. Each voxel adds coverage × cell volume, weighted
//! along the axis by a cubic B-spline window B(t/τ)/τ (support ±2τ, unit integral), so
//! the sum is a volume per unit fiber length, i.e. an area. The window matters: the
//! lattice points form planes ⟂ ω at most one cell edge apart, and a B-spline of knot
//! spacing τ ≥ that spacing sums to its integral over them within sinc⁴(τ/s) ≤ 0.2%
//! (a hard slab of thickness 1 sees 1 plane where there are 1.7 on average along a
//! diagonal: −25% in d). So A is unbiased for any tilt and any offset from the grid.
//!
//! - An isolated fiber of radius a has a profile that rises until r ≈ a and then stays
//!   flat: the structure is isolated when an annulus ISOLATION_GAP wide around r holds
//!   almost nothing (≤ 3% of A(r)), and its diameter is 2√(A(r)/π).
//! - Packed fibers (a yarn) never plateau within the radius: no isolated diameter.
//!
//! Units: z-voxels; `scale` is the cell size in z-voxels (1, 1, 1 for cubic voxels).

use glam::Vec3;

/// Radial bin width of the area profile (z-voxels).
const BIN: f32 = 0.5;
/// Most bins (radius up to 16 voxels).
const MAX_BINS: usize = 32;
/// Width of the empty annulus that makes a structure isolated (z-voxels): neighbours in
/// a yarn touch or nearly so; partial-volume cells reach √3/2 beyond a fiber's edge.
pub const ISOLATION_GAP: f32 = 1.5;
/// Largest fraction of A(r) the annulus may hold and still count as empty.
const ISOLATION_LEAK: f32 = 0.03;

/// The radial area profile of the structure around one voxel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CrossSection {
    /// Area (z-voxels²) in each radial bin [k·BIN, (k+1)·BIN).
    bins: [f32; MAX_BINS],
    len: usize,
}

impl CrossSection {
    /// Measures the profile at voxel `p` (indices) with fiber axis `axis`, out to
    /// `radius` (≤ 16). `coverage(x, y, z)` returns the covered fraction of a voxel that
    /// belongs to the structure measured, else 0; it must wrap x and y itself.
    pub fn measure(p: [i64; 3], axis: Vec3, radius: f32, scale: Vec3, coverage: &impl Fn(i64, i64, i64) -> f32) -> CrossSection {
        let axis = axis.normalize_or(Vec3::Z);
        let tau = scale.max_element().max(1e-6);
        let r = radius.clamp(BIN, BIN * MAX_BINS as f32);
        let len = (r / BIN).ceil() as usize;
        let reach = (Vec3::splat(r + 2.0 * tau) / scale).ceil().to_array().map(|v| v as i64);
        // Distance along the axis per index step on each grid axis. The innermost loop
        // runs along the grid axis most aligned with the fiber, over just the cells
        // inside the window |along| < 2τ (at most 4τ/|c_k| ≤ 7 of them).
        let c = (scale * axis).to_array();
        let k = (0..3).max_by(|&a, &b| c[a].abs().total_cmp(&c[b].abs())).unwrap_or(2);
        let (m1, m2) = ((k + 1) % 3, (k + 2) % 3);
        let cell = scale.x * scale.y * scale.z;
        let mut bins = [0f32; MAX_BINS];
        for a in -reach[m1]..=reach[m1] {
            for b in -reach[m2]..=reach[m2] {
                let partial = a as f32 * c[m1] + b as f32 * c[m2];
                let (t0, t1) = ((-2.0 * tau - partial) / c[k], (2.0 * tau - partial) / c[k]);
                let lo = (t0.min(t1).ceil() as i64).max(-reach[k]);
                let hi = (t0.max(t1).floor() as i64).min(reach[k]);
                for t in lo..=hi {
                    let mut o = [0i64; 3];
                    o[k] = t;
                    o[m1] = a;
                    o[m2] = b;
                    let d = Vec3::new(o[0] as f32, o[1] as f32, o[2] as f32) * scale;
                    let along = d.dot(axis);
                    let perp2 = d.length_squared() - along * along;
                    if along.abs() >= 2.0 * tau || perp2 >= r * r {
                        continue;
                    }
                    let cov = coverage(p[0] + o[0], p[1] + o[1], p[2] + o[2]);
                    if cov > 0.0 {
                        let bin = ((perp2.max(0.0).sqrt() / BIN) as usize).min(len - 1);
                        bins[bin] += cov * cubic_bspline(along / tau) * cell / tau;
                    }
                }
            }
        }
        CrossSection { bins, len }
    }

    /// Measures the profile with a radius fitted to the structure: it walks from `p` in
    /// four directions ⟂ `axis` (±u, ±v) until it leaves the structure, and measures out
    /// to the farthest exit plus ISOLATION_GAP and a cell's fringe. `None` when some walk
    /// stays inside for `max_radius` voxels: no isolated structure fits, and the full
    /// measurement (the costly part, ∝ radius²) is skipped. Cheap rejection of packed
    /// voxels is what lets the thickness estimate sample thousands of them.
    pub fn measure_fitted(p: [i64; 3], axis: Vec3, max_radius: f32, scale: Vec3, coverage: &impl Fn(i64, i64, i64) -> f32) -> Option<CrossSection> {
        let axis = axis.normalize_or(Vec3::Z);
        let u = axis.any_orthonormal_vector();
        let v = axis.cross(u);
        let steps = max_radius.floor().max(1.0) as i32;
        let mut extent = 0;
        for dir in [u, -u, v, -v] {
            // Walk in z-voxel units; convert to cell indices with the cell scale.
            let step = dir / scale;
            let exit = (1..=steps).find(|&k| {
                let q = (step * k as f32).round();
                coverage(p[0] + q.x as i64, p[1] + q.y as i64, p[2] + q.z as i64) == 0.0
            })?;
            extent = extent.max(exit);
        }
        let radius = (extent as f32 + ISOLATION_GAP + 1.0 + BIN).min(max_radius.max(BIN));
        Some(CrossSection::measure(p, axis, radius, scale, coverage))
    }

    /// Diameter of everything within the radius, 2√(A(R)/π) (saturates in packed regions).
    pub fn disk_diameter(&self) -> f32 {
        area_to_diameter(self.bins[..self.len].iter().sum())
    }

    /// Diameter of the isolated structure through the voxel: the first plateau of the
    /// profile, where an annulus ISOLATION_GAP wide holds ≤ 3% of the area inside it;
    /// `None` when there is none within the radius (packed fibers).
    pub fn isolated_diameter(&self) -> Option<f32> {
        let gap = (ISOLATION_GAP / BIN).round() as usize;
        let mut inside = 0.0f32;
        for k in 0..self.len {
            inside += self.bins[k];
            if k + gap >= self.len {
                break;
            }
            let annulus: f32 = self.bins[k + 1..=k + gap].iter().sum();
            if inside > 0.0 && annulus <= ISOLATION_LEAK * inside {
                return Some(area_to_diameter(inside));
            }
        }
        None
    }

    /// The diameter to report for one voxel: isolated if it is, else the disk's.
    pub fn diameter(&self) -> f32 {
        self.isolated_diameter().unwrap_or_else(|| self.disk_diameter())
    }
}

#[inline]
fn area_to_diameter(area: f32) -> f32 {
    2.0 * (area.max(0.0) / std::f32::consts::PI).sqrt()
}

/// The centred cubic B-spline (support [−2, 2], integral 1).
#[inline]
fn cubic_bspline(t: f32) -> f32 {
    let a = t.abs();
    if a >= 2.0 {
        0.0
    } else if a >= 1.0 {
        (2.0 - a).powi(3) / 6.0
    } else {
        ((2.0 - a).powi(3) - 4.0 * (1.0 - a).powi(3)) / 6.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Partial-volume coverage of straight infinite cylinders, by 6³ supersampling.
    fn cylinders(list: Vec<(Vec3, Vec3, f32)>) -> impl Fn(i64, i64, i64) -> f32 {
        move |x, y, z| {
            let mut inside = 0;
            for s in 0..216 {
                let o = Vec3::new((s % 6) as f32, ((s / 6) % 6) as f32, (s / 36) as f32) / 6.0 + 1.0 / 12.0;
                let q = Vec3::new(x as f32, y as f32, z as f32) + o;
                inside += list.iter().any(|&(c, axis, radius)| {
                    let axis = axis.normalize();
                    let v = q - c;
                    (v - v.dot(axis) * axis).length_squared() <= radius * radius
                }) as u32;
            }
            inside as f32 / 216.0
        }
    }

    #[test]
    fn isolated_cylinders_are_measured_at_any_tilt_and_offset() {
        // Bounded by the B-spline window's aliasing (≤ 0.2% in area), the 6³
        // supersampling of coverage (1/216 of a cell) and the ≤ 3% of boundary cells the
        // plateau may leave outside: 3% allowed in d (2% measured), for d ≥ 1.5 voxels.
        let mut worst = 0.0f32;
        for (k, &d) in [1.5f32, 2.0, 3.0, 4.5].iter().enumerate() {
            for (m, axis) in [Vec3::X, Vec3::new(1.0, 0.7, 0.0), Vec3::new(0.3, 1.0, 0.5), Vec3::new(1.0, 1.0, 1.0)].into_iter().enumerate() {
                let offset = Vec3::new(0.13 * m as f32, 0.37 + 0.1 * k as f32, 0.71);
                let cov = cylinders(vec![(Vec3::splat(20.0) + offset, axis, 0.5 * d)]);
                let cs = CrossSection::measure([20, 20, 20], axis, d + 3.0, Vec3::ONE, &cov);
                let est = cs.isolated_diameter().expect("an isolated cylinder plateaus");
                worst = worst.max((est - d).abs() / d);
                assert!((cs.disk_diameter() - est).abs() < 0.05 * d, "nothing else within the disk");
            }
        }
        assert!(worst < 0.03, "worst relative diameter error {worst}");
    }

    #[test]
    fn packed_fibers_are_not_isolated_but_a_separate_neighbour_is_fine() {
        // A row of touching fibers (a yarn's layer): no plateau.
        let row: Vec<(Vec3, Vec3, f32)> = (0..12).map(|k| (Vec3::new(10.0, 4.0 + 2.0 * k as f32, 10.0), Vec3::X, 1.05)).collect();
        let cs = CrossSection::measure([10, 16, 10], Vec3::X, 8.0, Vec3::ONE, &cylinders(row));
        assert_eq!(cs.isolated_diameter(), None);
        assert!(cs.disk_diameter() > 5.0);
        // Two fibers with 4 voxels of gap: each is isolated (the gap must clear both
        // fibers' partial-volume fringes, √3/2 each, plus ISOLATION_GAP).
        let pair = vec![(Vec3::new(10.0, 10.5, 10.5), Vec3::X, 1.0), (Vec3::new(10.0, 16.5, 10.5), Vec3::X, 1.0)];
        let d = CrossSection::measure([10, 10, 10], Vec3::X, 8.0, Vec3::ONE, &cylinders(pair)).isolated_diameter().unwrap();
        assert!((d - 2.0).abs() < 0.06, "{d}");
    }

    #[test]
    fn anisotropic_cells_are_measured_in_z_voxels() {
        // Cells twice as wide in x as in z; a fiber along y of diameter 3 z-voxels.
        let scale = Vec3::new(2.0, 1.0, 1.0);
        let cov = move |x: i64, _y: i64, z: i64| -> f32 {
            let mut inside = 0;
            for s in 0..64 {
                let (u, w) = ((s % 8) as f32 / 8.0 + 1.0 / 16.0, (s / 8) as f32 / 8.0 + 1.0 / 16.0);
                let wx = (x as f32 + u) * 2.0 - 20.0;
                let wz = z as f32 + w - 10.0;
                inside += (wx * wx + wz * wz <= 2.25) as u32;
            }
            inside as f32 / 64.0
        };
        let d = CrossSection::measure([10, 10, 10], Vec3::Y, 6.0, scale, &cov).isolated_diameter().unwrap();
        assert!((d - 3.0).abs() < 0.15, "diameter {d}");
    }
}
