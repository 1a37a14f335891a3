//! Synthetic volumes with known answers, for the geometry tests. Densities are exact
//! partial-volume coverages (supersampled), so h0 and diameters can be checked tightly.

use glam::Vec3;

use crate::volume::{Aabb, FabricVolume, MaterialParams, Voxel};

/// Supersamples per column side for heights (4 × 4 per column).
const SS: usize = 4;

/// An empty volume of cubic unit voxels.
pub fn empty(dims: [usize; 3]) -> FabricVolume {
    let size = Vec3::new(dims[0] as f32, dims[1] as f32, dims[2] as f32);
    FabricVolume::new(dims, Aabb::new(Vec3::ZERO, size), MaterialParams::default())
}

/// A solid body under the height field `height(x, y)` (continuous voxel coordinates),
/// density = partial-volume coverage, orientation `orient(x, y, z)` (cell indices).
/// Returns the volume and each column's true mean height (the mean of `height` over the
/// column's footprint, clamped to [0, nz]).
pub fn height_field(dims: [usize; 3], height: impl Fn(f32, f32) -> f32, orient: impl Fn(usize, usize, usize) -> Vec3) -> (FabricVolume, Vec<f32>) {
    let [nx, ny, nz] = dims;
    let mut vol = empty(dims);
    let mut truth = vec![0f32; nx * ny];
    for j in 0..ny {
        for i in 0..nx {
            let hs: Vec<f32> = (0..SS * SS)
                .map(|s| {
                    let (u, v) = ((s % SS) as f32 + 0.5, (s / SS) as f32 + 0.5);
                    height(i as f32 + u / SS as f32, j as f32 + v / SS as f32).clamp(0.0, nz as f32)
                })
                .collect();
            truth[i + nx * j] = hs.iter().sum::<f32>() / hs.len() as f32;
            for z in 0..nz {
                let c = hs.iter().map(|h| (h - z as f32).clamp(0.0, 1.0)).sum::<f32>() / hs.len() as f32;
                if c > 0.0 {
                    vol.set(i, j, z, Voxel::pack(c, Vec3::splat(0.8), orient(i, j, z)));
                }
            }
        }
    }
    (vol, truth)
}

/// A straight fiber of `radius` along `dir` through `point`, added with partial-volume
/// coverage (4³ supersamples). `segment`: half-length along `dir` (∞ for an infinite
/// fiber; infinite fibers wrap periodically in x and y, so `dir` must close on the tile).
/// Voxels it touches take its orientation and max(old, new) density. Returns the voxels
/// it covers, with their coverage.
pub fn add_fiber(vol: &mut FabricVolume, point: Vec3, dir: Vec3, radius: f32, segment: f32) -> Vec<([usize; 3], f32)> {
    let [nx, ny, nz] = vol.dims();
    let dir = dir.normalize();
    let mut touched = Vec::new();
    let images: Vec<Vec3> = if segment.is_finite() {
        vec![Vec3::ZERO]
    } else {
        let mut v = Vec::new();
        for a in -1..=1 {
            for b in -1..=1 {
                v.push(Vec3::new((a * nx as i32) as f32, (b * ny as i32) as f32, 0.0));
            }
        }
        v
    };
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let centre = Vec3::new(x as f32, y as f32, z as f32) + 0.5;
                let near = images.iter().any(|o| distance(centre, point + *o, dir, segment) < radius + 1.0);
                if !near {
                    continue;
                }
                let mut inside = 0;
                for s in 0..64 {
                    let q = Vec3::new(x as f32, y as f32, z as f32) + (Vec3::new((s % 4) as f32, ((s / 4) % 4) as f32, (s / 16) as f32) + 0.5) / 4.0;
                    inside += images.iter().any(|o| distance(q, point + *o, dir, segment) <= radius) as u32;
                }
                if inside > 0 {
                    let c = inside as f32 / 64.0;
                    let old = vol.voxel(x, y, z).density();
                    vol.set(x, y, z, Voxel::pack(old.max(c), Vec3::new(0.9, 0.7, 0.5), dir));
                    touched.push(([x, y, z], c));
                }
            }
        }
    }
    touched
}

fn distance(q: Vec3, p: Vec3, dir: Vec3, segment: f32) -> f32 {
    let t = (q - p).dot(dir).clamp(-segment, segment);
    (q - (p + t * dir)).length()
}

/// Deterministic uniform value in [−1, 1] from an index and a seed.
pub fn noise(index: u64, seed: u64) -> f32 {
    let h = super::heightmap::splitmix64(index ^ seed.wrapping_mul(0x9e37_79b9_7f4a_7c15));
    (h >> 40) as f32 / (1u64 << 23) as f32 - 1.0
}
