//! The detailed height map h0 (paper §5.2) and what it needs: which voxels are
//! non-empty, the density of a fully covered voxel, and one fiber's thickness.
//!
//! Paper: "Starting with z = s_z, we iteratively decrease z until reaching a nonempty
//! voxel. We then check the number of consecutive voxels that are nonempty. If the voxel
//! count is greater than the size of a single fiber, we set h0[x, y] = z; otherwise, we
//! skip to the next empty voxel and continue decreasing z."
//!
//! Our reading:
//! - A run's thickness is its coverage-weighted length Σ min(ρ/ρ_solid, 1) in voxels,
//!   so partially covered voxels at a fiber's edges count for what they hold; the run is
//!   the surface when that exceeds `surface_run_factor` × the fiber thickness.
//! - Sub-voxel h0 from the density profile, by partial-volume coverage: each of the
//!   run's top cells holds the fraction c = ρ / ρ_ref of its cell, ρ_ref the largest
//!   density among them (the local full-cell density: fabric density varies across
//!   yarns, so a global constant would bias h0), and h0 is the height of the solid
//!   column holding the same material ([`subvoxel_height`]). Under partial-volume
//!   voxelization that is exactly the column's mean surface height, for any slope within
//!   the column; the only loss is a top cell filled by less than the density threshold,
//!   which counts as empty (h0 low by at most the threshold fraction, 0.05 voxel by
//!   default). Interpolating the ρ = ρ_ref/2 crossing between cell centres instead is off
//!   by up to 0.08 voxel on a flat surface and more on slopes; the z index alone by up
//!   to a whole voxel.
//! - A column with no run thick enough (the paper leaves h0 undefined there) is common in
//!   fiber-resolved volumes: yarn edges thin to a fiber, porous felt has gaps in every
//!   column. Such a column takes its surface from its neighbourhood ([`fill_holes`]):
//!   the top of its own material at or below the neighbours' level; only a column with
//!   no material there is a hole through the fabric, h0 = 0 (the bottom face), and all
//!   its non-empty voxels belong to V.

use glam::Vec3;
use rayon::prelude::*;

use super::blur;
use super::cross_section::CrossSection;
use super::flyaways::wrap;
use super::{GeometryError, Progress};
use crate::volume::FabricVolume;

/// Which voxels count as non-empty: ρ > threshold. Real and generated volumes have a
/// low-density halo around fibers, so the threshold is not 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DensityThreshold {
    /// A fraction of the solid density ([`DensityScale::solid`]). Default 0.05.
    Relative(f32),
    /// An absolute density.
    Absolute(f32),
}

impl Default for DensityThreshold {
    fn default() -> Self {
        DensityThreshold::Relative(0.05)
    }
}

impl DensityThreshold {
    pub(crate) fn validate(&self) -> Result<(), GeometryError> {
        let ok = match *self {
            DensityThreshold::Relative(f) => f.is_finite() && (0.0..1.0).contains(&f),
            DensityThreshold::Absolute(a) => a.is_finite() && a >= 0.0,
        };
        if ok {
            Ok(())
        } else {
            Err(GeometryError::BadOption { name: "density_threshold", value: format!("{self:?}"), reason: "relative must be in [0, 1), absolute ≥ 0" })
        }
    }
}

/// The density scale of a volume.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DensityScale {
    /// Density of a fully covered voxel: the 90th percentile of the positive densities
    /// (fiber interiors; partial-volume edges and halo lie below it).
    pub solid: f32,
    /// Non-empty ⇔ ρ > threshold.
    pub threshold: f32,
}

impl DensityScale {
    /// Fraction of the cell a voxel of density ρ covers; 0 for empty voxels.
    #[inline]
    pub fn coverage(&self, rho: f32) -> f32 {
        if rho > self.threshold { (rho / self.solid).min(1.0) } else { 0.0 }
    }
}

/// Percentile of the positive densities, from an exact histogram of their half-float
/// bit patterns (positive halves sort as their bits do).
pub(crate) fn density_scale(volume: &FabricVolume, rule: DensityThreshold, progress: &dyn Progress) -> Result<DensityScale, GeometryError> {
    const BINS: usize = 0x7c00; // positive finite halves: bits 1..0x7bff
    let nz = volume.dims()[2];
    let histogram = (0..nz)
        .into_par_iter()
        .fold(
            || vec![0u64; BINS],
            |mut hist, z| {
                for v in volume.slab(z) {
                    let bits = v.density as usize;
                    if bits > 0 && bits < BINS {
                        hist[bits] += 1;
                    }
                }
                progress.advance(1);
                hist
            },
        )
        .reduce(|| vec![0u64; BINS], |mut a, b| {
            a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
            a
        });
    let total: u64 = histogram.iter().sum();
    let max_bits = histogram.iter().rposition(|&c| c > 0).unwrap_or(0);
    let max_density = half::f16::from_bits(max_bits as u16).to_f32();
    let dims = volume.dims();
    if total == 0 {
        return Err(GeometryError::EmptyVolume { dims, threshold: 0.0, max_density: 0.0 });
    }
    let target = (total as f64 * 0.9).ceil() as u64;
    let mut cumulative = 0u64;
    let mut solid_bits = max_bits;
    for (bits, &count) in histogram.iter().enumerate() {
        cumulative += count;
        if cumulative >= target {
            solid_bits = bits;
            break;
        }
    }
    let solid = half::f16::from_bits(solid_bits as u16).to_f32();
    let threshold = match rule {
        DensityThreshold::Relative(f) => f * solid,
        DensityThreshold::Absolute(a) => a,
    };
    if !(max_density > threshold) {
        return Err(GeometryError::EmptyVolume { dims, threshold, max_density });
    }
    Ok(DensityScale { solid, threshold })
}

/// The result of the h0 scan.
#[derive(Clone, Debug, PartialEq)]
pub struct HeightMap {
    /// h0 per column (voxels; 0 for holes).
    pub h0: Vec<f32>,
    /// Index of the top voxel of the surface run, −1 for holes.
    pub surface_top: Vec<i32>,
    pub hole_columns: usize,
    /// Columns without a thick run whose surface was found at their neighbours' level.
    pub filled_columns: usize,
    /// Columns whose surface run starts in the top slab.
    pub clipped_columns: usize,
    /// Thickness of the thickest run anywhere (for the "no surface" error).
    pub thickest_run: f32,
}

/// Scans every column down from the top (paper §5.2): the first run of non-empty voxels
/// whose coverage-weighted thickness exceeds `run_threshold` is the surface.
/// Rows of columns are scanned slab by slab so each read is contiguous in x.
pub(crate) fn detailed_height(volume: &FabricVolume, density: &DensityScale, run_threshold: f32, progress: &dyn Progress) -> HeightMap {
    let [nx, ny, nz] = volume.dims();
    let rows: Vec<(Vec<f32>, Vec<i32>, f32)> = (0..ny)
        .into_par_iter()
        .map(|j| {
            let mut top = vec![-1i32; nx]; // surface top once found
            let mut run_top = vec![0usize; nx];
            let mut run_w = vec![0f32; nx]; // coverage-weighted length of the current run (0 = none)
            let mut thickest = 0f32;
            for z in (0..nz).rev() {
                let row = &volume.slab(z)[j * nx..(j + 1) * nx];
                for i in 0..nx {
                    if top[i] >= 0 {
                        continue;
                    }
                    let c = density.coverage(row[i].density());
                    if c > 0.0 {
                        if run_w[i] == 0.0 {
                            run_top[i] = z;
                        }
                        run_w[i] += c;
                        thickest = thickest.max(run_w[i]);
                        if run_w[i] > run_threshold {
                            top[i] = run_top[i] as i32;
                        }
                    } else {
                        run_w[i] = 0.0;
                    }
                }
            }
            // Sub-voxel h0 by partial-volume coverage of the run's top cells (module docs).
            let h0 = (0..nx)
                .map(|i| {
                    if top[i] < 0 {
                        return 0.0;
                    }
                    surface_height(volume, density, i, j, top[i] as usize)
                })
                .collect();
            progress.advance(1);
            (h0, top, thickest)
        })
        .collect();
    let mut hm = HeightMap { h0: Vec::with_capacity(nx * ny), surface_top: Vec::with_capacity(nx * ny), hole_columns: 0, filled_columns: 0, clipped_columns: 0, thickest_run: 0.0 };
    for (h0, top, thickest) in rows {
        hm.h0.extend(h0);
        hm.surface_top.extend(top);
        hm.thickest_run = hm.thickest_run.max(thickest);
    }
    hm.hole_columns = hm.surface_top.iter().filter(|&&t| t < 0).count();
    hm.clipped_columns = hm.surface_top.iter().filter(|&&t| t == nz as i32 - 1).count();
    hm
}

/// Gives the columns without a surface run the surface of their neighbourhood.
///
/// The neighbours' level L is the normalized Gaussian interpolation of h0 over the
/// columns that have a surface run, L = G∗(h0·valid) / G∗valid with σ = `sigma` texels
/// (periodic); where no such column lies within reach, the mean of h0 over them. The
/// column's surface is then the top of its own material that starts at or below
/// L + fiber/2 (a thin yarn edge or a gap-riddled felt column at the level of its
/// neighbours belongs to the surface; material higher up is V). With no material there
/// the column is a hole through the fabric: h0 = 0.
pub fn fill_holes(volume: &FabricVolume, density: &DensityScale, hm: &mut HeightMap, fiber_thickness: f32, sigma: f32) {
    let [nx, ny, nz] = volume.dims();
    if hm.hole_columns == 0 || hm.hole_columns == nx * ny {
        return;
    }
    let valid: Vec<f32> = hm.surface_top.iter().map(|&t| if t >= 0 { 1.0 } else { 0.0 }).collect();
    let weighted: Vec<f32> = hm.h0.iter().zip(&valid).map(|(h, v)| h * v).collect();
    let num = blur::periodic_gaussian(&weighted, nx, ny, [sigma; 2]);
    let den = blur::periodic_gaussian(&valid, nx, ny, [sigma; 2]);
    let mean = weighted.iter().map(|&v| v as f64).sum::<f64>() / valid.iter().map(|&v| v as f64).sum::<f64>();
    let filled: Vec<Option<(i32, f32)>> = (0..nx * ny)
        .into_par_iter()
        .map(|c| {
            if hm.surface_top[c] >= 0 {
                return None;
            }
            let level = if den[c] > 1e-3 { num[c] / den[c] } else { mean as f32 };
            let limit = level + 0.5 * fiber_thickness;
            let (i, j) = (c % nx, c / nx);
            let top = (0..nz).rev().find(|&z| (z as f32) < limit && volume.voxel(i, j, z).density() > density.threshold)?;
            Some((top as i32, surface_height(volume, density, i, j, top)))
        })
        .collect();
    for (c, f) in filled.into_iter().enumerate() {
        if let Some((top, h)) = f {
            hm.surface_top[c] = top;
            hm.h0[c] = h;
            hm.filled_columns += 1;
            hm.hole_columns -= 1;
        }
    }
    hm.clipped_columns = hm.surface_top.iter().filter(|&&t| t == nz as i32 - 1).count();
}

/// Sub-voxel h0 of the run whose top cell is `zt` in column (i, j).
fn surface_height(volume: &FabricVolume, density: &DensityScale, i: usize, j: usize, zt: usize) -> f32 {
    let mut profile = [0f32; SUBVOXEL_CELLS];
    for (k, p) in profile.iter_mut().enumerate().take(zt + 1) {
        let rho = volume.voxel(i, j, zt - k).density();
        if rho <= density.threshold {
            break; // end of the run
        }
        *p = rho;
    }
    subvoxel_height(zt, &profile)
}

/// Cells at the top of a surface run that the sub-voxel height looks at.
pub const SUBVOXEL_CELLS: usize = 3;

/// h0 of a run whose top cell is `zt`, from the densities of its top cells (`profile[k]`
/// = ρ at zt − k; 0 past the run's end), by volume-preserving partial-volume coverage:
/// c_k = ρ_k / ρ_ref with ρ_ref the largest of them (the local full-cell density), and
///
/// ```text
/// h0 = zt + c_0 − Σ_{k ≥ 1} (1 − c_k)   while c_k is partial and c_k ≥ c_{k−1},
/// ```
///
/// i.e. the height of a solid column holding the same material as the cells of the
/// partial-volume transition. Coverage of a height-field surface never falls going down,
/// so a cell that holds less than the one above it is a gap between fibers, not part of
/// the surface's transition, and ends the sum (porous tops fall back to zt + c_0).
/// Exact for any surface that is a height field within the column and crosses at most
/// `SUBVOXEL_CELLS` cells.
pub fn subvoxel_height(zt: usize, profile: &[f32; SUBVOXEL_CELLS]) -> f32 {
    let rho_ref = profile.iter().copied().fold(0.0, f32::max);
    if !(rho_ref > 0.0) {
        return zt as f32 + 1.0;
    }
    let c0 = (profile[0] / rho_ref).min(1.0);
    let mut h = zt as f32 + c0;
    let mut above = c0;
    for &rho in &profile[1..] {
        let c = (rho / rho_ref).min(1.0);
        if rho == 0.0 || c >= 1.0 || c < above {
            break;
        }
        h -= 1.0 - c;
        above = c;
    }
    h
}

/// Largest number of voxels whose cross-section is measured for the thickness estimate
/// (evenly spread by a hash of the voxel index).
const THICKNESS_SAMPLES: u64 = 20_000;
/// Radius of the measured cross-sections (voxels): fibers up to ~18 voxels thick plateau
/// inside it.
const THICKNESS_RADIUS: f32 = 12.0;
/// Fewer isolated fibers than this and the estimate is not trusted.
const THICKNESS_MIN_SAMPLES: usize = 32;

/// Estimates one fiber's thickness (voxels) from the isolated fibers of the volume, or
/// `None` when there are too few to measure.
///
/// Where fibers pack into yarns the volume says nothing about a single fiber, so we look
/// where they stand alone: flyaways, loops, loose fibers at yarn edges. At a sample of
/// all non-empty voxels we measure the radial cross-section profile perpendicular to the
/// voxel's fiber axis ω_f ([`CrossSection`]); where it plateaus (an empty annulus around
/// the structure) the structure is one isolated fiber and d = 2√(A/π), exact for any
/// tilt and any offset from the grid (a vertical chord would depend on both). Packed
/// voxels never plateau and are left out. The thickness is the mode of the isolated
/// diameters: two fibers lying together (√2·d) only add a tail above it.
pub fn estimate_fiber_thickness(volume: &FabricVolume, density: &DensityScale, progress: &dyn Progress) -> Option<f32> {
    let [nx, ny, nz] = volume.dims();
    let count: u64 = (0..ny)
        .into_par_iter()
        .map(|j| {
            let n = (0..nz).map(|z| volume.slab(z)[j * nx..(j + 1) * nx].iter().filter(|v| density.coverage(v.density()) > 0.0).count() as u64).sum::<u64>();
            progress.advance(1);
            n
        })
        .sum();
    let stride = count.div_ceil(THICKNESS_SAMPLES).max(1);
    let scale = anisotropy(volume);
    let coverage = |x: i64, y: i64, z: i64| -> f32 {
        if z < 0 || z >= nz as i64 {
            return 0.0;
        }
        density.coverage(volume.voxel(wrap(x, nx), wrap(y, ny), z as usize).density())
    };
    let diameters: Vec<f32> = (0..ny)
        .into_par_iter()
        .flat_map_iter(|j| {
            let mut out = Vec::new();
            for z in 0..nz {
                let row = &volume.slab(z)[j * nx..(j + 1) * nx];
                for (i, v) in row.iter().enumerate() {
                    if density.coverage(v.density()) == 0.0 || !splitmix64(volume.index(i, j, z) as u64).is_multiple_of(stride) {
                        continue;
                    }
                    let cs = CrossSection::measure_fitted([i as i64, j as i64, z as i64], v.orientation(), THICKNESS_RADIUS, scale, &coverage);
                    out.extend(cs.and_then(|cs| cs.isolated_diameter()));
                }
            }
            progress.advance(1);
            out
        })
        .collect();
    if diameters.len() < THICKNESS_MIN_SAMPLES {
        return None;
    }
    Some(histogram_mode(&diameters, 0.25, 2.0 * THICKNESS_RADIUS))
}

/// Voxel size in units of the z size (the unit of thicknesses and heights).
pub(crate) fn anisotropy(volume: &FabricVolume) -> Vec3 {
    let s = volume.voxel_size();
    s / s.z
}

/// Mode of positive samples: a histogram with `bin`-wide bins up to `max`, smoothed by
/// [1 2 1]/4, its highest bin refined by a parabola through it and its neighbours.
pub(crate) fn histogram_mode(samples: &[f32], bin: f32, max: f32) -> f32 {
    let n = (max / bin).ceil() as usize + 2;
    let mut hist = vec![0f64; n];
    for &s in samples {
        let b = ((s / bin) as usize).min(n - 1);
        hist[b] += 1.0;
    }
    let smooth: Vec<f64> = (0..n)
        .map(|b| {
            let l = if b > 0 { hist[b - 1] } else { 0.0 };
            let r = if b + 1 < n { hist[b + 1] } else { 0.0 };
            0.25 * l + 0.5 * hist[b] + 0.25 * r
        })
        .collect();
    let mut best = 0;
    for b in 1..n {
        if smooth[b] > smooth[best] {
            best = b;
        }
    }
    let mut offset = 0.0;
    if best > 0 && best + 1 < n {
        let (l, c, r) = (smooth[best - 1], smooth[best], smooth[best + 1]);
        let denom = l - 2.0 * c + r;
        if denom < 0.0 {
            offset = (0.5 * (l - r) / denom).clamp(-0.5, 0.5);
        }
    }
    ((best as f64 + 0.5 + offset) * bin as f64) as f32
}

/// SplitMix64: a well-mixed hash of an index, for deterministic subsampling.
#[inline]
pub(crate) fn splitmix64(x: u64) -> u64 {
    crate::reference::rng::mix64(x.wrapping_add(0x9e37_79b9_7f4a_7c15))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histogram_mode_finds_the_peak_of_a_skewed_sample() {
        // 300 samples around 2.0 (±0.2), a tail up to 8 from touching fibers.
        let mut s: Vec<f32> = (0..300).map(|k| 2.0 + 0.2 * ((k as f32 * 0.37).sin())).collect();
        s.extend((0..150).map(|k| 2.5 + 5.5 * (k as f32 / 150.0)));
        let m = histogram_mode(&s, 0.25, 10.0);
        assert!((m - 2.0).abs() < 0.2, "mode {m}");
    }

    #[test]
    fn subvoxel_height_preserves_the_material_of_the_transition() {
        // Flat surface at 7.3: top cell 7 holds 0.3.
        assert!((subvoxel_height(7, &[0.3, 1.0, 1.0]) - 7.3).abs() < 1e-6);
        // Sloped surface spanning cells 6–7 (coverage 0.1 and 0.8): mean height 6.9.
        assert!((subvoxel_height(7, &[0.1, 0.8, 1.0]) - 6.9).abs() < 1e-6);
        // Porous top (a gap below the top cell) is not a transition: zt + c0.
        assert!((subvoxel_height(7, &[0.6, 0.2, 1.0]) - 7.6).abs() < 1e-6);
        // Uniformly half-dense material is full at its own density.
        assert!((subvoxel_height(3, &[0.5, 0.5, 0.5]) - 4.0).abs() < 1e-6);
        // Run of one cell at the bottom.
        assert!((subvoxel_height(0, &[0.4, 0.0, 0.0]) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn coverage_is_zero_at_and_below_the_threshold_and_saturates() {
        let d = DensityScale { solid: 2.0, threshold: 0.1 };
        assert_eq!(d.coverage(0.1), 0.0);
        assert_eq!(d.coverage(1.0), 0.5);
        assert_eq!(d.coverage(5.0), 1.0);
    }
}
