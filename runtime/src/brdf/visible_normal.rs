//! The visible normal of a coarse texel: its frames turned toward the viewer as the
//! footprint's visible normals are (an extension of paper §5.3.5; twin:
//! `shaders/common/visible_normal.glsl`; the format's `VIEW_TILT` section,
//! runtime/HYBRID_FORMAT.md §4.9).
//!
//! A coarse texel's lobes are fitted to the *plain* mean of its footprint's level-0
//! responses. A distant pixel sees the visible part of the footprint instead: at a
//! grazing view mostly the faces turned toward the viewer, whose mean normal tilts
//! toward ω_o (measured on felt at 70°: 18° from the plain mean, which made a coarse
//! level 36% too bright under a light on the far side; baker/PREFILTER_MEASUREMENTS.md,
//! "Grazing views"). The texel stores a 2×2 matrix B fitted by the prefilter to the
//! traced visible normals of its footprint, in slope space:
//!
//! ```text
//! σ(n) = n.xy / n.z,   u(ω_o) = ω_o.xy / √(ω_o.z),   σ_vis = σ(n_0) + B u
//! ```
//!
//! (the √ was measured: the visible normals' slope goes as ω_o.xy/√ω_o.z from 45° to
//! 70° within ±4% on felt and ±10% on twill), and every frame of the texel (its lobes',
//! the diffuse term's in lobe 0, the transmission's) is turned by the rotation that
//! takes n_0 to n_vis = normalize(σ_vis, 1). At ω_o = ẑ the tilt is zero, so a view
//! from straight above is the plain fit's; level 0 stores none (its texels are one
//! normal each, their visibility is the height field's).
//!
//! The texel also stores how much of it is seen from ω_o, relative to a view from
//! above: v(ω_o) = clamp(1 + c · u(ω_o), [`VISIBILITY_MIN`], [`VISIBILITY_MAX`]), the density of a
//! distant view's hits on it (a plane facet of slope σ has 1 + σ · ω_o.xy/ω_o.z). A hit
//! shades the coarse texels around it (bilinear corners, anisotropic taps along the
//! footprint) with weights w_k v_k / Σ w v: the taps sample texels wherever they lie,
//! while a pixel sees the ones turned toward it (without the weights the taps made a
//! 70° view of felt 16% too bright although each level alone was within 5%).

use glam::{Vec2, Vec3};

use super::ClothFrame;

/// Smallest ω_o.z in u (views more grazing tilt as at this).
pub const TILT_VIEW_Z_MIN: f32 = 0.05;
/// Largest |B u| (a slope: 45°).
pub const TILT_SLOPE_MAX: f32 = 1.0;
/// Smallest n_0.z a texel is tilted from (a texel more edge-on keeps its frames).
pub const TILT_NORMAL_Z_MIN: f32 = 0.1;

/// Largest v.
pub const VISIBILITY_MAX: f32 = 4.0;
/// Smallest v: a texel the fit says no distant view sees still counts a little, so that
/// the weights of a blend never all vanish (the hit itself is seen).
pub const VISIBILITY_MIN: f32 = 0.05;

/// A coarse texel's view tilt: B (row-major: b[0] b[1]; b[2] b[3]) and c.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ViewTilt {
    pub b: [f32; 4],
    pub c: [f32; 2],
}

/// v(ω_o) = 1 + c · u(ω_o), clamped to [[`VISIBILITY_MIN`], [`VISIBILITY_MAX`]].
#[inline]
pub fn view_visibility(tilt: &ViewTilt, wo: Vec3) -> f32 {
    let u = view_tilt_basis(wo);
    (1.0 + tilt.c[0] * u.x + tilt.c[1] * u.y).clamp(VISIBILITY_MIN, VISIBILITY_MAX)
}

/// u(ω_o) = ω_o.xy / √ω_o.z (ω_o.z clamped below at [`TILT_VIEW_Z_MIN`]).
#[inline]
pub fn view_tilt_basis(wo: Vec3) -> Vec2 {
    Vec2::new(wo.x, wo.y) / wo.z.max(TILT_VIEW_Z_MIN).sqrt()
}

/// The slope offset B u, B row-major (b[0] b[1]; b[2] b[3]), its length clamped at
/// [`TILT_SLOPE_MAX`].
#[inline]
pub fn view_tilt_offset(b: [f32; 4], wo: Vec3) -> Vec2 {
    let u = view_tilt_basis(wo);
    let d = Vec2::new(b[0] * u.x + b[1] * u.y, b[2] * u.x + b[3] * u.y);
    let len = d.length();
    if len > TILT_SLOPE_MAX { d * (TILT_SLOPE_MAX / len) } else { d }
}

/// The visible normal of a texel whose lobe-0 normal is `n0` (unit), seen from `wo`.
#[inline]
pub fn visible_normal(n0: Vec3, b: [f32; 4], wo: Vec3) -> Vec3 {
    let d = view_tilt_offset(b, wo);
    // No offset (a view from above, B = 0): n_0 itself, not its round trip through σ.
    if n0.z < TILT_NORMAL_Z_MIN || d == Vec2::ZERO {
        return n0;
    }
    let s = Vec2::new(n0.x, n0.y) / n0.z + d;
    Vec3::new(s.x, s.y, 1.0).normalize()
}

/// x turned by the rotation that takes unit a to unit b (about a × b; a·b > −1).
#[inline]
pub fn rotate_arc(a: Vec3, b: Vec3, x: Vec3) -> Vec3 {
    let c = a.dot(b);
    let v = a.cross(b);
    x * c + v.cross(x) + v * (v.dot(x) / (1.0 + c))
}

/// Every frame turned from n_0 = `frames[0].n` to its visible normal seen from `wo`.
#[inline]
pub fn tilt_frames(frames: &mut [ClothFrame], tilt: &ViewTilt, wo: Vec3) {
    let Some(n0) = frames.first().map(|f| f.n) else {
        return;
    };
    let nv = visible_normal(n0, tilt.b, wo);
    if nv == n0 {
        return;
    }
    for f in frames.iter_mut() {
        f.n = rotate_arc(n0, nv, f.n);
        f.t = rotate_arc(n0, nv, f.t);
        f.b = rotate_arc(n0, nv, f.b);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::cloth_frame;

    #[test]
    fn rotate_arc_takes_a_to_b_and_keeps_lengths_and_angles() {
        let a = Vec3::new(0.1, -0.2, 0.97).normalize();
        let b = Vec3::new(0.5, 0.3, 0.8).normalize();
        assert!((rotate_arc(a, b, a) - b).length() < 1e-6);
        let (x, y) = (Vec3::new(0.3, 0.9, -0.1), Vec3::new(-0.7, 0.2, 0.4));
        let (rx, ry) = (rotate_arc(a, b, x), rotate_arc(a, b, y));
        assert!((rx.length() - x.length()).abs() < 1e-6);
        assert!((rx.dot(ry) - x.dot(y)).abs() < 1e-6);
        // The axis a × b is fixed.
        let axis = a.cross(b);
        assert!((rotate_arc(a, b, axis) - axis).length() < 1e-6);
    }

    #[test]
    fn no_tilt_from_straight_above_or_with_a_zero_matrix() {
        let f = cloth_frame(Vec3::new(0.2, 0.1, 0.95), Vec3::X);
        let t = ViewTilt { b: [0.3, 0.05, -0.02, 0.25], c: [0.5, -0.2] };
        let mut frames = [f; 2];
        tilt_frames(&mut frames, &t, Vec3::Z);
        assert_eq!(frames, [f; 2]);
        assert_eq!(view_visibility(&t, Vec3::Z), 1.0);
        tilt_frames(&mut frames, &ViewTilt::default(), Vec3::new(0.8, 0.0, 0.6));
        assert_eq!(frames, [f; 2]);
    }

    #[test]
    fn the_normal_tilts_toward_the_viewer_and_frames_stay_orthonormal() {
        let wo = Vec3::new(0.94 * 0.866, 0.94 * 0.5, 0.342);
        let t = ViewTilt { b: [0.25, 0.0, 0.0, 0.25], c: [0.0; 2] };
        let f = cloth_frame(Vec3::Z, Vec3::new(1.0, 0.3, 0.2));
        let mut frames = [f, cloth_frame(Vec3::new(-0.3, 0.2, 0.9), Vec3::Y)];
        tilt_frames(&mut frames, &t, wo);
        let nv = frames[0].n;
        // σ = B u = 0.25 · ω_o.xy / √ω_o.z.
        let expect = (Vec2::new(wo.x, wo.y) * 0.25 / wo.z.sqrt()).extend(1.0).normalize();
        assert!((nv - expect).length() < 1e-5, "{nv} vs {expect}");
        assert!(nv.dot(wo) > f.n.dot(wo));
        for fr in &frames {
            assert!((fr.n.length() - 1.0).abs() < 1e-5 && (fr.t.length() - 1.0).abs() < 1e-5);
            assert!(fr.n.dot(fr.t).abs() < 1e-5 && (fr.n.cross(fr.t) - fr.b).length() < 1e-5);
        }
        // The two lobes keep the angle between their normals.
        let before = f.n.dot(cloth_frame(Vec3::new(-0.3, 0.2, 0.9), Vec3::Y).n);
        assert!((frames[0].n.dot(frames[1].n) - before).abs() < 1e-5);
    }

    #[test]
    fn the_tilt_is_bounded_at_grazing_views_and_huge_matrices() {
        let n0 = Vec3::Z;
        let nv = visible_normal(n0, [1e4, 0.0, 0.0, 1e4], Vec3::new(1.0, 0.0, 1e-7).normalize());
        assert!(nv.is_finite());
        assert!((nv.z - std::f32::consts::FRAC_1_SQRT_2).abs() < 1e-5, "{nv}");
        // An edge-on texel keeps its normal.
        let edge = Vec3::new(1.0, 0.0, 0.05).normalize();
        assert_eq!(visible_normal(edge, [0.3, 0.0, 0.0, 0.3], Vec3::new(0.5, 0.0, 0.8).normalize()), edge);
    }

    #[test]
    fn visibility_grows_toward_the_texels_slope_and_is_bounded() {
        let t = ViewTilt { b: [0.0; 4], c: [0.4, 0.0] };
        let toward = view_visibility(&t, Vec3::new(0.6, 0.0, 0.8));
        let away = view_visibility(&t, Vec3::new(-0.6, 0.0, 0.8));
        assert!(toward > 1.0 && away < 1.0 && (toward + away - 2.0).abs() < 1e-5);
        let huge = ViewTilt { b: [0.0; 4], c: [1e4, 1e4] };
        let grazing = Vec3::new(1.0, 0.0, 1e-6).normalize();
        assert_eq!(view_visibility(&huge, grazing), VISIBILITY_MAX);
        assert_eq!(view_visibility(&huge, -grazing.truncate().extend(grazing.z)), VISIBILITY_MIN);
    }
}
