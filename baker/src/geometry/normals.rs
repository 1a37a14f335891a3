//! The normal map n (paper §5.2: "the normal map n that captures fiber-level details
//! based on the difference between h and h0").
//!
//! Our reading: the surface the renderer shades is h (marched) carrying the detail
//! h0 − h (shaded), so the slope of the shaded surface is h's slope plus the detail's:
//!
//! ```text
//! ∇h_total = ∇h + k·∇(h0 − h),   n = normalize(−∂h_total/∂x, −∂h_total/∂y, 1)
//! ```
//!
//! with k = 1 (`detail_strength`; other values scale the fiber-level bumps, an edit the
//! paper's models allow). For k = 1 this is the normal of h0 itself, in the continuous
//! case and also discretely, since central differences are linear; computing it as two
//! terms keeps the decomposition explicit and lets k edit the detail alone.
//!
//! Slopes are central differences, periodic in x and y, converted to world units: heights
//! are in z-voxels and texels are x/y voxels, so ∂h_world/∂x_world = (s_z/s_x)·Δh/Δi.
//! (−gx, −gy, 1) has length ≥ 1, so every normal is finite and unit, facing +z.

use glam::Vec3;
use rayon::prelude::*;

/// Unit normals of the periodic `nx × ny` maps h (smooth) and h0 (detailed), x fastest.
pub fn normal_map(h: &[f32], h0: &[f32], nx: usize, ny: usize, voxel_size: Vec3, detail_strength: f32) -> Vec<Vec3> {
    let (kx, ky) = (voxel_size.z / voxel_size.x, voxel_size.z / voxel_size.y);
    let k = detail_strength;
    let total = |i: usize, j: usize| -> f32 {
        let t = i + nx * j;
        h[t] + k * (h0[t] - h[t])
    };
    (0..ny)
        .into_par_iter()
        .flat_map_iter(|j| {
            let (jm, jp) = ((j + ny - 1) % ny, (j + 1) % ny);
            (0..nx).map(move |i| {
                let (im, ip) = ((i + nx - 1) % nx, (i + 1) % nx);
                let gx = 0.5 * (total(ip, j) - total(im, j)) * kx;
                let gy = 0.5 * (total(i, jp) - total(i, jm)) * ky;
                Vec3::new(-gx, -gy, 1.0).normalize()
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::TAU;

    #[test]
    fn normals_match_the_analytic_slope_and_detail_adds_on() {
        // h0 = 3 sin(2πi/32) in voxels of size (0.5, 1, 2): world slope along x is
        // (2/0.5)·3·(2π/32)cos(·); central differences err by (2π/32)²/6 ≈ 0.6% relative.
        let (nx, ny) = (32, 4);
        let h0: Vec<f32> = (0..nx * ny).map(|k| 3.0 * (TAU * (k % nx) as f32 / 32.0).sin()).collect();
        let flat = vec![0.0; nx * ny];
        let n = normal_map(&flat, &h0, nx, ny, Vec3::new(0.5, 1.0, 2.0), 1.0);
        let same = normal_map(&h0, &h0, nx, ny, Vec3::new(0.5, 1.0, 2.0), 1.0);
        for i in 0..nx {
            let slope = 4.0 * 3.0 * TAU / 32.0 * (TAU * i as f32 / 32.0).cos();
            let want = Vec3::new(-slope, 0.0, 1.0).normalize();
            assert!(n[i].angle_between(want) < 0.01, "texel {i}: {} vs {want}", n[i]);
            assert!((n[i].length() - 1.0).abs() < 1e-6);
            // Detail on a flat h and the same shape all in h give one normal (k = 1).
            assert!(n[i].abs_diff_eq(same[i], 1e-6));
        }
        // k = 0 keeps only h's slope: flat.
        let none = normal_map(&flat, &h0, nx, ny, Vec3::ONE, 0.0);
        assert!(none.iter().all(|v| *v == Vec3::Z));
    }
}
