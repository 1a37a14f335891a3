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

//!
//! **Two groups** (format 1.8, `FLYAWAY_GROUP`). A tensor cannot tell warp and weft in one
//! voxel from fibres at the diagonals: diag(½, ½, 0) is both, and the cone puts its axes
//! at the diagonals, where under a grazing view the lit fibres are not (satin's coarse
//! flyaways at 70° came out 1.31× the truth at level 2; baker/PREFILTER_MEASUREMENTS.md,
//! "What the coarse flyaways get wrong"). A node may split its fibres in two groups: the
//! first is e₁ with its record's cone as above, the second an axis b with a circular cone
//! of spread s (λ₂ = λ₃ = s/2; its roll is then irrelevant), weighted by its share w:
//!
//! ```text
//! axes = (1 − w) · cone(e₁, θ, λ₂, λ₃)  ∪  w · cone(b, 0, s/2, s/2)   (up to 8 axes)
//! ```

use glam::Vec3;

/// Most axes a node is shaded with: two groups of four.
pub const MAX_SPREAD_AXES: usize = 8;

/// The axes a node is shaded with and their weights (summing to 1; unused axes weigh 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpreadAxes {
    pub axes: [Vec3; MAX_SPREAD_AXES],
    pub weights: [f32; MAX_SPREAD_AXES],
}

impl SpreadAxes {
    /// One axis.
    pub fn single(e1: Vec3) -> SpreadAxes {
        let mut s = SpreadAxes { axes: [Vec3::ZERO; MAX_SPREAD_AXES], weights: [0.0; MAX_SPREAD_AXES] };
        s.axes[0] = e1;
        s.weights[0] = 1.0;
        s
    }

    /// The axes in use and their weights.
    pub fn weighted(&self) -> impl Iterator<Item = (Vec3, f32)> + '_ {
        self.axes.iter().zip(self.weights).filter(|(_, w)| *w > 0.0).map(|(a, w)| (*a, w))
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
    let mut out = SpreadAxes::single(e1);
    out.axes[..4].copy_from_slice(&[along + e2 * s, along - e2 * s, along + e3 * s, along - e3 * s]);
    out.weights[..4].copy_from_slice(&[p, p, 0.5 - p, 0.5 - p]);
    out
}

/// Two groups of axes (format 1.8): the four of `first` weighted by 1 − `share`, then
/// the four of `second` by `share` (clamped to [0, 1]; `first` alone where it is 0).
#[inline]
pub fn grouped_axes(first: SpreadAxes, second: SpreadAxes, share: f32) -> SpreadAxes {
    let w = share.max(0.0).min(1.0);
    if !(w > 0.0) {
        return first;
    }
    let mut out = first;
    for k in 0..4 {
        out.weights[k] = first.weights[k] * (1.0 - w);
        out.axes[4 + k] = second.axes[k];
        out.weights[4 + k] = second.weights[k] * w;
    }
    out
}

/// The second group of a record (format 1.8): axis `b` (unit) on a circular cone of
/// spread `s` = sin²δ ∈ [0, 1] (λ₂ = λ₃ = s/2, roll 0).
#[inline]
pub fn group_axes(b: Vec3, s: f32) -> SpreadAxes {
    let half = 0.5 * s.max(0.0).min(1.0);
    spread_axes(b, 0.0, half, half)
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
        s.weighted().fold(glam::Mat3::ZERO, |m, (a, w)| m + glam::Mat3::from_cols(a * a.x, a * a.y, a * a.z) * w)
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
                for (a, _) in s.weighted() {
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
        for (a, _) in s.weighted() {
            // Each diagonal is at acos(1/√3) from the axis and from the others' ±.
            assert!((a.z - 1.0 / 3f32.sqrt()).abs() < 1e-5, "{a}");
        }
        assert!(s.weights[..4].iter().all(|w| (w - 0.25).abs() < 1e-6) && s.weights[4..].iter().all(|w| *w == 0.0));
    }

    #[test]
    fn weights_sum_to_one_and_never_go_negative() {
        for (l2, l3) in [(0.7, 0.6), (1.0, 0.0), (0.0, 0.4), (0.2, 0.1)] {
            let s = spread_axes(Vec3::Z, 0.0, l2, l3);
            assert!(s.weights.iter().all(|w| *w >= 0.0) && (s.weights.iter().sum::<f32>() - 1.0).abs() < 1e-6);
            assert!(s.axes.iter().all(|a| a.is_finite()));
        }
    }

    #[test]
    fn two_groups_keep_warp_and_weft_where_one_cone_puts_the_diagonals() {
        // Warp (x) and weft (y) half and half: the tensor diag(½, ½, 0). One cone about x
        // with λ₂ = ½ puts its axes at the diagonals; two groups keep x and y.
        let one = spread_axes(Vec3::X, spread_roll(Vec3::X, Vec3::Y), 0.5, 0.0);
        for (a, _) in one.weighted() {
            assert!((a.x.abs() - 0.5f32.sqrt()).abs() < 1e-5 && (a.y.abs() - 0.5f32.sqrt()).abs() < 1e-5, "{a}");
        }
        let two = grouped_axes(SpreadAxes::single(Vec3::X), group_axes(Vec3::Y, 0.0), 0.5);
        let axes: Vec<(Vec3, f32)> = two.weighted().collect();
        assert_eq!(axes, vec![(Vec3::X, 0.5), (Vec3::Y, 0.5)]);
        // Both have the same tensor.
        let (t1, t2) = (tensor(&one), tensor(&two));
        assert!((t1 - t2).abs().to_cols_array().iter().all(|d| *d < 1e-5), "{t1} {t2}");
    }

    #[test]
    fn grouped_weights_sum_to_one_and_the_tensor_is_the_mixture() {
        let a = spread_axes(Vec3::new(0.3, 0.1, 0.9).normalize(), 0.7, 0.2, 0.05);
        let b = group_axes(Vec3::new(-0.5, 0.8, 0.1).normalize(), 0.3);
        for share in [0.0f32, 0.25, 0.5, 1.0, 1.5, -1.0] {
            let g = grouped_axes(a, b, share);
            assert!((g.weights.iter().sum::<f32>() - 1.0).abs() < 1e-6 && g.weights.iter().all(|w| *w >= 0.0));
            let w = share.clamp(0.0, 1.0);
            let mix = tensor(&a) * (1.0 - w) + tensor(&b) * w;
            assert!((tensor(&g) - mix).abs().to_cols_array().iter().all(|d| *d < 1e-5), "share {share}");
        }
        // A circular cone: λ₂ = λ₃, whatever the roll.
        let t = tensor(&b);
        let e = Vec3::new(-0.5, 0.8, 0.1).normalize();
        assert!((e.dot(t * e) - 0.7).abs() < 1e-5);
    }
}
