//! Stage times of geometry extraction (`fabric_baker::geometry`), printed, not asserted.
//!
//! `cargo bench -p fabric-baker --bench geometry [-- SIZES...]`, SIZES like 256x256x48
//! (default: 256x256x48 and 1024x1024x128). The input is a synthetic weave-like volume:
//! two families of sinusoidal yarn crowns with fiber-level noise, partial-volume
//! densities, and straight flyaway strands above it (about 0.5% of the voxels).

use std::time::Instant;

use fabric_baker::geometry::{GeometryOptions, extract_geometry};
use fabric_baker::volume::{Aabb, FabricVolume, MaterialParams, Voxel};
use glam::Vec3;
use rayon::prelude::*;

fn main() {
    let sizes: Vec<[usize; 3]> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .filter_map(|a| {
            let v: Vec<usize> = a.split('x').filter_map(|p| p.parse().ok()).collect();
            (v.len() == 3).then(|| [v[0], v[1], v[2]])
        })
        .collect();
    let sizes = if sizes.is_empty() { vec![[256, 256, 48], [1024, 1024, 128]] } else { sizes };
    println!("threads: {}", rayon::current_num_threads());
    for dims in sizes {
        let t = Instant::now();
        let vol = synthetic(dims);
        println!("\n{}x{}x{}: built in {:.2} s ({:.2} GiB of voxels)", dims[0], dims[1], dims[2], t.elapsed().as_secs_f64(), vol.memory_bytes() as f64 / (1u64 << 30) as f64);
        let t = Instant::now();
        let g = match extract_geometry(&vol, &GeometryOptions::default()) {
            Ok(g) => g,
            Err(e) => {
                println!("  extraction failed: {e}");
                continue;
            }
        };
        let total = t.elapsed().as_secs_f64();
        for s in &g.stage_times {
            println!("  {:<16} {:>8.3} s", s.stage, s.seconds);
        }
        println!("  {:<16} {:>8.3} s", "total", total);
        println!(
            "  filter size {:?} (auto {}), fiber thickness {:.2} (auto {}), {} flyaway voxels, {} holes",
            g.filter_size, g.filter_auto, g.fiber_thickness, g.fiber_thickness_auto, g.flyaways.len(), g.hole_columns
        );
    }
}

/// Weave-like volume: crowns of period 32 voxels per yarn (in x and y) scaled with the
/// tile, fiber-level noise, flyaway strands of diameter 2.
fn synthetic(dims: [usize; 3]) -> FabricVolume {
    let [nx, ny, nz] = dims;
    let size = Vec3::new(nx as f32, ny as f32, nz as f32);
    let mut vol = FabricVolume::new(dims, Aabb::new(Vec3::ZERO, size), MaterialParams::default());
    let base = 0.45 * nz as f32;
    let amp = 0.12 * nz as f32;
    let height = |i: usize, j: usize| {
        let (x, y) = (i as f32 * std::f32::consts::TAU / 32.0, j as f32 * std::f32::consts::TAU / 32.0);
        let warp = x.sin().abs() * (0.5 * y).cos().signum();
        base + amp * 0.5 * (warp + (y.sin().abs()) * (0.5 * x).sin().signum()) + 0.6 * hash01((i + nx * j) as u64)
    };
    let slab = nx * ny;
    vol.voxels_mut().par_chunks_mut(slab).enumerate().for_each(|(z, layer)| {
        for j in 0..ny {
            for i in 0..nx {
                let c = (height(i, j) - z as f32).clamp(0.0, 1.0);
                if c > 0.0 {
                    let dir = if (i / 16 + j / 16) % 2 == 0 { Vec3::X } else { Vec3::Y };
                    layer[i + nx * j] = Voxel::pack(c, Vec3::splat(0.7), dir);
                }
            }
        }
    });
    // Flyaways: straight strands of radius 1 above the crowns, about 0.5% of the voxels.
    let strands = (nx * ny * nz) / 2000 / 40;
    for s in 0..strands {
        let r = |k: u64| hash01(s as u64 * 8 + k);
        let p = Vec3::new(r(0) * nx as f32, r(1) * ny as f32, base + amp + 3.0 + r(2) * (nz as f32 - base - amp - 5.0).max(0.0));
        let a = r(3) * std::f32::consts::TAU;
        let d = Vec3::new(a.cos(), a.sin(), 0.3 * (r(4) - 0.5)).normalize();
        for t in 0..40 {
            let q = p + d * (t as f32 - 20.0);
            for dz in -1i32..=1 {
                for dy in -1i32..=1 {
                    for dx in -1i32..=1 {
                        let c = q + Vec3::new(dx as f32, dy as f32, dz as f32);
                        if c.z < 0.0 || c.z >= nz as f32 || (c - q).length() > 1.0 {
                            continue;
                        }
                        let (x, y) = ((c.x.floor() as i64).rem_euclid(nx as i64) as usize, (c.y.floor() as i64).rem_euclid(ny as i64) as usize);
                        vol.set(x, y, c.z as usize, Voxel::pack(1.0, Vec3::splat(0.9), d));
                    }
                }
            }
        }
    }
    vol
}

fn hash01(i: u64) -> f32 {
    let mut z = i.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
}
