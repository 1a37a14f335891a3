//! The direction pairs a coarse texel is fitted on (paper §5.3.5: "minimizing an Eq. 8-like
//! error over sampled directions"): one fixed set in tile space, the same for every
//! texel of every level, so a coarse texel's target — the mean response of its level-0
//! footprint at each pair — is the count-weighted mean of its children's targets.
//!
//! Half the pairs sample ω_i and ω_o independently and uniformly in solid angle (the
//! diffuse term and the lobes' tails); a quarter mirror ω_i about the tile normal (the
//! highlights of flat texels); a quarter mirror it about a normal tilted up to
//! [`MAX_TILT`] (the highlights of tilted fibres). Polar angles stop at [`MAX_POLAR`]:
//! beyond it, renderers see the tile edge-on and the response is foreshortened away.

use glam::Vec3;

use crate::reference::rng::Rng;

/// Largest polar angle of ω_i and ω_o (radians, 80°).
pub const MAX_POLAR: f32 = 80.0 * std::f32::consts::PI / 180.0;
/// Largest tilt of the mirror normal of the tilted pairs (radians, 40°).
pub const MAX_TILT: f32 = 40.0 * std::f32::consts::PI / 180.0;

/// (ω_i, ω_o): toward the light, toward the viewer; unit, z > 0 (tile space).
pub type Pair = (Vec3, Vec3);

/// A direction at polar angle ≤ `max_polar`, uniform in solid angle, from (u, v) ∈ [0, 1)².
fn hemisphere(u: f32, v: f32, max_polar: f32) -> Vec3 {
    let cos_max = max_polar.cos();
    let z = 1.0 - u * (1.0 - cos_max);
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = std::f32::consts::TAU * v;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// `count` pairs (≥ 4), deterministic in `seed`.
pub fn fit_pairs(count: usize, seed: u64) -> Vec<Pair> {
    let count = count.max(4);
    let mut rng = Rng::new(seed, 0x9f1e_7e57, 0);
    let mut pairs = Vec::with_capacity(count);
    let min_z = MAX_POLAR.cos();
    while pairs.len() < count {
        let s = pairs.len();
        // Stratify the first dimension over the set (a 1D Latin hypercube).
        let u = (s as f32 + rng.next_f32()) / count as f32;
        let wi = hemisphere(u, rng.next_f32(), MAX_POLAR);
        let wo = match s % 4 {
            0 | 1 => hemisphere(rng.next_f32(), rng.next_f32(), MAX_POLAR),
            2 => Vec3::new(-wi.x, -wi.y, wi.z),
            _ => {
                let m = hemisphere(rng.next_f32(), rng.next_f32(), MAX_TILT);
                2.0 * wi.dot(m) * m - wi
            }
        };
        if wo.z >= min_z && wo.is_finite() {
            pairs.push((wi, wo.normalize()));
        }
    }
    pairs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pairs_are_unit_above_the_sheet_and_deterministic() {
        let p = fit_pairs(128, 3);
        assert_eq!(p.len(), 128);
        assert_eq!(p, fit_pairs(128, 3));
        let min_z = MAX_POLAR.cos() - 1e-5;
        for (wi, wo) in &p {
            assert!((wi.length() - 1.0).abs() < 1e-5 && (wo.length() - 1.0).abs() < 1e-5);
            assert!(wi.z >= min_z && wo.z >= min_z);
        }
        // A quarter are exact mirror pairs about the tile normal.
        let mirrors = p.iter().filter(|(wi, wo)| (wi.x + wo.x).abs() < 1e-6 && (wi.y + wo.y).abs() < 1e-6).count();
        assert!(mirrors >= 32, "{mirrors}");
    }
}
