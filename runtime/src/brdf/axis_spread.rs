//! The spread of a coarse flyaway voxel's fiber axes: its level-0 fibers' axis tensor
//! T = Σ α t tᵀ / Σ α = λ₁ e₁e₁ᵀ + λ₂ e₂e₂ᵀ + λ₃ e₃e₃ᵀ replaced by four axes with the same
//! tensor (an extension of paper §5.3.5; twin: `shaders/common/axis_spread.glsl`; the
//! format's `FLYAWAY_SPREAD` section, runtime/HYBRID_FORMAT.md §7.1).
//!
//! A flyaway is shaded in the fiber frame of its axis, where a lobe is lit only where
//! n · ω_i > 0 (n: ω_o made perpendicular to the axis) and its highlight sits where
//! θ_i + θ_o ≈ 0. Level 0's fibers point every way, so under a light on the far side some
//! of them are lit; a coarse voxel shaded with its one merged axis is lit wholly or not
//! at all (baker/PREFILTER_MEASUREMENTS.md, "Coarse flyaways"). Its response is the mean
//! over four axes on a cone of half-angle δ about e₁,
//!
//! ```text
//! a± = cos δ e₁ ± sin δ e₂  (weight p/2 each),   b± = cos δ e₁ ± sin δ e₃  ((1 − p)/2 each),
//! sin²δ = λ₂ + λ₃,   p = λ₂ / (λ₂ + λ₃),
//! ```
//!
//! whose tensor is T (the cross terms cancel in pairs): a single fibre (λ₁ = 1) is its
//! one axis, an isotropic footprint the cube's four diagonals. The three eigen-axes with
//! weights λ_k have the same tensor too, but put a narrow spread's weight at 90° from
//! e₁, where its fibres are not: measured, that made a 70° far view of satin's coarse
//! flyaways 2.1–2.5× too bright. e₁ is the node's tangent; the record stores the angle
//! θ ∈ [0, π) of e₂ about e₁ from a reference direction, and λ₂, λ₃.
//!
//! The reference frame of e₁ is the branchless basis of Duff et al. (the one of
//! `cloth_reference_tangent`) about ±e₁ chosen with a non-negative z: an axis's sign is
//! irrelevant, and that basis is singular only at z = −1. On the seam z = 0 the two signs
//! give different bases; the baker measures the roll in the basis of the tangent as
//! stored (decoded), which is the one both renderers rebuild.

use glam::Vec3;

/// The axes a node is shaded with and their weights (summing to 1; unused axes weigh 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpreadAxes {
    pub axes: [Vec3; 4],
    pub weights: [f32; 4],
}

impl SpreadAxes {
    /// One axis.
    pub fn single(e1: Vec3) -> SpreadAxes {
        SpreadAxes { axes: [e1, Vec3::ZERO, Vec3::ZERO, Vec3::ZERO], weights: [1.0, 0.0, 0.0, 0.0] }
    }
}

/// The reference pair (r, q) ⊥ e₁ that the roll angle is measured in (e₁ unit).
#[inline]
pub fn spread_basis(e1: Vec3) -> (Vec3, Vec3) {
    let e = if e1.z < 0.0 { -e1 } else { e1 };
    let a = -1.0 / (1.0 + e.z);
    let b = e.x * e.y * a;
    (Vec3::new(1.0 + e.x * e.x * a, b, -e.x), Vec3::new(b, 1.0 + e.y * e.y * a, -e.y))
}

/// The axes of a record: e₁ (unit) alone where λ₂ + λ₃ = 0, else the cone a±, b± with
/// e₂ = cos θ r + sin θ q, e₃ = e₁ × e₂ (λ₂ + λ₃ taken at most 1).
#[inline]
pub fn spread_axes(e1: Vec3, roll: f32, lambda2: f32, lambda3: f32) -> SpreadAxes {
    let spread = (lambda2 + lambda3).min(1.0);
    if !(spread > 0.0) {
        return SpreadAxes::single(e1);
    }
    let (r, q) = spread_basis(e1);
    let e2 = r * roll.cos() + q * roll.sin();
    let e3 = e1.cross(e2);
    let (s, c) = (spread.sqrt(), (1.0 - spread).sqrt());
    let p = 0.5 * (lambda2 / (lambda2 + lambda3));
    let along = e1 * c;
    SpreadAxes { axes: [along + e2 * s, along - e2 * s, along + e3 * s, along - e3 * s], weights: [p, p, 0.5 - p, 0.5 - p] }
}

/// The roll angle θ ∈ [0, π) of axis `e2` (⊥ e₁, either sign) about `e1`.
#[inline]
pub fn spread_roll(e1: Vec3, e2: Vec3) -> f32 {
    let (r, q) = spread_basis(e1);
    let theta = e2.dot(q).atan2(e2.dot(r));
    theta.rem_euclid(std::f32::consts::PI).min(std::f32::consts::PI * (1.0 - f32::EPSILON))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tensor(s: &SpreadAxes) -> glam::Mat3 {
        s.axes.iter().zip(s.weights).fold(glam::Mat3::ZERO, |m, (a, w)| m + glam::Mat3::from_cols(*a * a.x, *a * a.y, *a * a.z) * w)
    }

    #[test]
    fn the_basis_is_orthonormal_for_either_sign_of_the_axis() {
        for e in [Vec3::X, Vec3::Z, -Vec3::Z, Vec3::new(0.3, -0.5, -0.81).normalize(), Vec3::new(0.6, 0.8, 0.0)] {
            let (r, q) = spread_basis(e);
            for (a, b) in [(r, q), (r, e), (q, e)] {
                assert!(a.dot(b).abs() < 1e-6, "{e}: {a} · {b}");
            }
            assert!((r.length() - 1.0).abs() < 1e-6 && (q.length() - 1.0).abs() < 1e-6);
            // The sign of the axis does not change the basis, off the z = 0 seam (where
            // the roll is measured from the decoded tangent's own basis, as the renderer
            // rebuilds it).
            if e.z != 0.0 {
                assert_eq!(spread_basis(-e), spread_basis(e), "{e}");
            }
        }
    }

    #[test]
    fn a_rolled_axis_comes_back_and_the_cone_has_the_tensor() {
        let e1 = Vec3::new(0.2, 0.9, 0.3).normalize();
        let (r, q) = spread_basis(e1);
        for theta in [0.0f32, 0.4, 1.5, 3.0] {
            let e2 = r * theta.cos() + q * theta.sin();
            assert!((spread_roll(e1, e2) - theta).abs() < 1e-5);
            // An axis's sign is irrelevant: −e₂ has the same roll.
            assert!((spread_roll(e1, -e2) - theta).abs() < 1e-5 || theta == 0.0);
            let e3 = e1.cross(e2);
            for (l2, l3) in [(0.3, 0.1), (0.02, 0.0), (1.0 / 3.0, 1.0 / 3.0)] {
                let s = spread_axes(e1, theta, l2, l3);
                for a in s.axes {
                    assert!((a.length() - 1.0).abs() < 1e-5);
                }
                let t = tensor(&s);
                assert!(((t.x_axis.x + t.y_axis.y + t.z_axis.z) - 1.0).abs() < 1e-5, "trace 1");
                assert!((e1.dot(t * e1) - (1.0 - l2 - l3)).abs() < 1e-5 && (e2.dot(t * e2) - l2).abs() < 1e-5 && (e3.dot(t * e3) - l3).abs() < 1e-5);
                assert!(e1.dot(t * e2).abs() < 1e-5 && e1.dot(t * e3).abs() < 1e-5 && e2.dot(t * e3).abs() < 1e-5, "no cross terms");
            }
        }
    }

    #[test]
    fn a_single_fibre_is_its_axis_and_an_isotropic_voxel_the_cube_diagonals() {
        assert_eq!(spread_axes(Vec3::Z, 0.3, 0.0, 0.0), SpreadAxes::single(Vec3::Z));
        let s = spread_axes(Vec3::Z, 0.0, 1.0 / 3.0, 1.0 / 3.0);
        for a in s.axes {
            // Each diagonal is at acos(1/√3) from the axis and from the others' ±.
            assert!((a.z - 1.0 / 3f32.sqrt()).abs() < 1e-5, "{a}");
        }
        assert!(s.weights.iter().all(|w| (w - 0.25).abs() < 1e-6));
    }

    #[test]
    fn weights_sum_to_one_and_never_go_negative() {
        for (l2, l3) in [(0.7, 0.6), (1.0, 0.0), (0.0, 0.4), (0.2, 0.1)] {
            let s = spread_axes(Vec3::Z, 0.0, l2, l3);
            assert!(s.weights.iter().all(|w| *w >= 0.0) && (s.weights.iter().sum::<f32>() - 1.0).abs() < 1e-6);
            assert!(s.axes.iter().all(|a| a.is_finite()));
        }
    }
}
