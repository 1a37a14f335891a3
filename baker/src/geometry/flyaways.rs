//! The flyaway volume V (paper §5.2: "the regions of ρ and ω_f that are not captured by
//! h0"): every non-empty voxel above its column's surface run, kept sparse, with the
//! diameter of the fiber each belongs to.
//!
//! Storage: voxels grouped by column (x fastest, then y), z ascending within a column;
//! `column_start` indexes each column's slice (the per-texel linked lists of the renderer
//! are built straight from it). Voxels of hole columns (no surface) are all in V.

use glam::Vec3;
use rayon::prelude::*;

use super::Progress;
use super::cross_section::{CrossSection, ISOLATION_GAP};
use super::heightmap::{DensityScale, anisotropy};
use crate::volume::FabricVolume;

/// One voxel of V.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlyawayVoxel {
    pub x: u32,
    pub y: u32,
    pub z: u32,
    /// ρ, as in the input volume.
    pub density: f32,
    /// Single-scattering albedo (linear RGB).
    pub albedo: Vec3,
    /// Unit fiber axis ω_f (sign arbitrary).
    pub orientation: Vec3,
    /// Diameter of the fiber (connected flyaway structure) this voxel belongs to, in
    /// voxels (`assign_fiber_diameters`).
    pub fiber_diameter: f32,
}

/// The sparse flyaway volume V.
#[derive(Clone, Debug, PartialEq)]
pub struct FlyawayVolume {
    /// The input volume's dims [nx, ny, nz].
    pub dims: [usize; 3],
    /// All voxels of V, by column (x fastest), z ascending.
    pub voxels: Vec<FlyawayVoxel>,
    /// Column (i, j)'s voxels are `voxels[column_start[i + nx·j]..column_start[i + nx·j + 1]]`.
    pub column_start: Vec<usize>,
}

impl FlyawayVolume {
    /// Builds the column index of voxels already in column order (x fastest, z ascending).
    pub fn from_sorted(dims: [usize; 3], voxels: Vec<FlyawayVoxel>) -> FlyawayVolume {
        let columns = dims[0] * dims[1];
        let mut column_start = vec![0usize; columns + 1];
        for v in &voxels {
            column_start[v.x as usize + dims[0] * v.y as usize + 1] += 1;
        }
        for c in 0..columns {
            column_start[c + 1] += column_start[c];
        }
        FlyawayVolume { dims, voxels, column_start }
    }

    pub fn len(&self) -> usize {
        self.voxels.len()
    }

    pub fn is_empty(&self) -> bool {
        self.voxels.is_empty()
    }

    /// The voxels of column (x, y), z ascending.
    pub fn column(&self, x: usize, y: usize) -> &[FlyawayVoxel] {
        let c = x + self.dims[0] * y;
        &self.voxels[self.column_start[c]..self.column_start[c + 1]]
    }

    /// Largest number of flyaway voxels in one column (the longest linked list).
    pub fn max_column_len(&self) -> usize {
        self.column_start.windows(2).map(|w| w[1] - w[0]).max().unwrap_or(0)
    }

    /// A bitset of V over the whole volume.
    pub fn mask(&self) -> FlyawayMask {
        let [nx, ny, nz] = self.dims;
        let mut bits = vec![0u64; (nx * ny * nz).div_ceil(64)];
        for v in &self.voxels {
            let i = v.x as usize + nx * (v.y as usize + ny * v.z as usize);
            bits[i / 64] |= 1 << (i % 64);
        }
        FlyawayMask { dims: self.dims, bits }
    }
}

/// Membership of V as one bit per voxel of the input volume (x fastest, then y, then z):
/// what the reference renderer needs to render "the complement of V" (paper §5.3).
#[derive(Clone, Debug, PartialEq)]
pub struct FlyawayMask {
    pub dims: [usize; 3],
    bits: Vec<u64>,
}

impl FlyawayMask {
    /// True when voxel (x, y, z) is in V. Out-of-range coordinates are not.
    #[inline]
    pub fn contains(&self, x: usize, y: usize, z: usize) -> bool {
        let [nx, ny, nz] = self.dims;
        if x >= nx || y >= ny || z >= nz {
            return false;
        }
        let i = x + nx * (y + ny * z);
        self.bits[i / 64] >> (i % 64) & 1 == 1
    }

    /// Number of voxels in V.
    pub fn count(&self) -> usize {
        self.bits.iter().map(|b| b.count_ones() as usize).sum()
    }

    /// One bool per voxel in volume order, true for V: the form the reference
    /// renderer's `MediumOptions::mask` takes (true = removed from the medium).
    pub fn to_bools(&self) -> Vec<bool> {
        let n = self.dims[0] * self.dims[1] * self.dims[2];
        (0..n).map(|i| self.bits[i / 64] >> (i % 64) & 1 == 1).collect()
    }
}

/// Collects V: the non-empty voxels above each column's surface top (`surface_top`,
/// −1 for holes), with their fiber diameters ([`assign_fiber_diameters`]).
pub(crate) fn extract_flyaways(volume: &FabricVolume, density: &DensityScale, surface_top: &[i32], fiber_thickness: f32, progress: &dyn Progress) -> FlyawayVolume {
    let [nx, ny, nz] = volume.dims();
    let rows: Vec<Vec<FlyawayVoxel>> = (0..ny)
        .into_par_iter()
        .map(|j| {
            let mut cells: Vec<(usize, usize)> = Vec::new();
            for z in 0..nz {
                let row = &volume.slab(z)[j * nx..(j + 1) * nx];
                for i in 0..nx {
                    if z as i32 > surface_top[i + nx * j] && density.coverage(row[i].density()) > 0.0 {
                        cells.push((i, z));
                    }
                }
            }
            cells.sort_unstable();
            let out = cells
                .into_iter()
                .map(|(i, z)| {
                    let v = volume.voxel(i, j, z);
                    FlyawayVoxel { x: i as u32, y: j as u32, z: z as u32, density: v.density(), albedo: v.albedo(), orientation: v.orientation(), fiber_diameter: 0.0 }
                })
                .collect();
            progress.advance(1);
            out
        })
        .collect();
    let mut flyaways = FlyawayVolume::from_sorted(volume.dims(), rows.into_iter().flatten().collect());
    assign_fiber_diameters(volume, density, surface_top, fiber_thickness, &mut flyaways);
    flyaways
}

/// Cross-sections measured per connected flyaway structure (at most).
const DIAMETER_SAMPLES: usize = 16;

/// Gives every voxel of V the diameter of the fiber it belongs to.
///
/// A fiber is a connected structure of V (26-connected, periodic in x and y; touching
/// flyaways merge into one). Its diameter is the median of [`CrossSection`] diameters
/// (the isolated plateau, else V's area within the disk) measured at up to
/// `DIAMETER_SAMPLES` of its voxels spread along its voxel order, with V as the
/// structure: one number per fiber, robust to the fringes and crossings that make
/// single measurements scatter, and ~10× cheaper than measuring at every voxel.
fn assign_fiber_diameters(volume: &FabricVolume, density: &DensityScale, surface_top: &[i32], fiber_thickness: f32, v: &mut FlyawayVolume) {
    let [nx, ny, nz] = volume.dims();
    let n = v.len();
    if n == 0 {
        return;
    }
    // Union-find over V; each voxel joins its already-visited neighbours (the 13 of the
    // 26 that come earlier in (z, y, x) order), found in their column lists.
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn find(parent: &mut [u32], mut k: u32) -> u32 {
        while parent[k as usize] != k {
            parent[k as usize] = parent[parent[k as usize] as usize];
            k = parent[k as usize];
        }
        k
    }
    let lookup = |x: i64, y: i64, z: i64| -> Option<usize> {
        if z < 0 || z >= nz as i64 {
            return None;
        }
        let c = wrap(x, nx) + nx * wrap(y, ny);
        let (lo, hi) = (v.column_start[c], v.column_start[c + 1]);
        v.voxels[lo..hi].binary_search_by_key(&(z as u32), |f| f.z).ok().map(|k| lo + k)
    };
    for k in 0..n {
        let f = v.voxels[k];
        let (x, y, z) = (f.x as i64, f.y as i64, f.z as i64);
        for (dx, dy, dz) in BACKWARD_NEIGHBOURS {
            if let Some(m) = lookup(x + dx, y + dy, z + dz) {
                let (a, b) = (find(&mut parent, k as u32), find(&mut parent, m as u32));
                if a != b {
                    parent[a.max(b) as usize] = a.min(b);
                }
            }
        }
    }
    // Components in order of first voxel, and their voxels in V's order.
    let roots: Vec<u32> = (0..n as u32).map(|k| find(&mut parent, k)).collect();
    let mut label = vec![u32::MAX; n];
    let mut members: Vec<Vec<u32>> = Vec::new();
    for (k, &root) in roots.iter().enumerate() {
        let r = root as usize;
        if label[r] == u32::MAX {
            label[r] = members.len() as u32;
            members.push(Vec::new());
        }
        members[label[r] as usize].push(k as u32);
    }
    let coverage = |x: i64, y: i64, z: i64| -> f32 {
        if z < 0 || z >= nz as i64 {
            return 0.0;
        }
        let (xi, yi) = (wrap(x, nx), wrap(y, ny));
        if z as i32 > surface_top[xi + nx * yi] { density.coverage(volume.voxel(xi, yi, z as usize).density()) } else { 0.0 }
    };
    // Disk radius: fibers up to ~2× the fiber thickness plateau inside it.
    let radius = (fiber_thickness + ISOLATION_GAP + 2.0).clamp(3.0, 16.0);
    let scale = anisotropy(volume);
    let voxels = &v.voxels;
    let diameters: Vec<f32> = members
        .par_iter()
        .map(|m| {
            let step = m.len().div_ceil(DIAMETER_SAMPLES).max(1);
            let mut d: Vec<f32> = m
                .iter()
                .step_by(step)
                .map(|&k| {
                    let f = voxels[k as usize];
                    let p = [f.x as i64, f.y as i64, f.z as i64];
                    CrossSection::measure_fitted(p, f.orientation, radius, scale, &coverage)
                        .unwrap_or_else(|| CrossSection::measure(p, f.orientation, radius, scale, &coverage))
                        .diameter()
                })
                .collect();
            d.sort_by(f32::total_cmp);
            d[d.len() / 2]
        })
        .collect();
    for (m, d) in members.iter().zip(diameters) {
        for &k in m {
            v.voxels[k as usize].fiber_diameter = d;
        }
    }
}

/// The 13 of the 26 neighbours that precede a voxel in (z, y, x) order.
const BACKWARD_NEIGHBOURS: [(i64, i64, i64); 13] = [
    (-1, -1, -1), (0, -1, -1), (1, -1, -1),
    (-1, 0, -1), (0, 0, -1), (1, 0, -1),
    (-1, 1, -1), (0, 1, -1), (1, 1, -1),
    (-1, -1, 0), (0, -1, 0), (1, -1, 0),
    (-1, 0, 0),
];

/// `i` wrapped into [0, n) (periodic x and y); cheap for the small offsets of a disk.
#[inline]
pub(crate) fn wrap(i: i64, n: usize) -> usize {
    let n = n as i64;
    if i < 0 {
        if i >= -n { (i + n) as usize } else { i.rem_euclid(n) as usize }
    } else if i >= n {
        if i < 2 * n { (i - n) as usize } else { i.rem_euclid(n) as usize }
    } else {
        i as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_is_rem_euclid() {
        for n in [1usize, 3, 8] {
            for i in -30i64..30 {
                assert_eq!(wrap(i, n), i.rem_euclid(n as i64) as usize);
            }
        }
    }

    #[test]
    fn mask_and_columns_agree() {
        let vox = |x, y, z| FlyawayVoxel { x, y, z, density: 1.0, albedo: Vec3::ONE, orientation: Vec3::X, fiber_diameter: 2.0 };
        let v = FlyawayVolume::from_sorted([3, 2, 5], vec![vox(1, 0, 2), vox(1, 0, 4), vox(2, 1, 0)]);
        assert_eq!(v.column(1, 0).len(), 2);
        assert_eq!(v.column(2, 1)[0].z, 0);
        assert!(v.column(0, 0).is_empty());
        assert_eq!(v.max_column_len(), 2);
        let m = v.mask();
        assert_eq!(m.count(), 3);
        assert!(m.contains(1, 0, 4) && m.contains(2, 1, 0) && !m.contains(1, 0, 3) && !m.contains(9, 0, 0));
    }
}
