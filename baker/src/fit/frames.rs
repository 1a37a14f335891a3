//! A cluster's frame, fitted with its BRDF (Eq. 8 with the frame free, as §5.3.5 does
//! for coarse levels; issue 9 item 5).
//!
//! The geometry stage gives every texel a frame (n from the height field's slope and
//! h0's detail, t from the fibres' orientation). Those frames are what the data is
//! fitted in, and a wrong frame cannot be undone by the lobes: a tangent that rises
//! τ out of the sheet moves the specular cone θ_i + θ_o = 0 by ~2τ cos θ at a mirror
//! view, far outside a lobe of β ≈ 0.1. So each cluster also fits a **frame offset**
//! applied to every one of its texels' frames:
//!
//! ```text
//! n_s = normalize(s·n_x, s·n_y, n_z)          the normal's slope scaled by s (tile space)
//! t₁  = cos ψ t + sin ψ b                     twist about n_s
//! t₂  = cos τ t₁ + sin τ n_s,  n₂ = cos τ n_s − sin τ t₁      rise of the fibre about b
//! n₃  = cos ρ n₂ + sin ρ (n₂ × t₂)            roll about the fibre
//! frame' = cloth_frame(n₃, t₂)
//! ```
//!
//! The identity is (s, τ, ψ, ρ) = (1, 0, 0, 0). The texels keep their own frames'
//! variation (the offset is the same rotation in every texel's own basis). A cluster
//! may fit one offset per lobe (lobe 0's also the diffuse term's): a twist of up to a
//! quarter turn lets a second lobe take the yarn that crosses the first (warp and weft
//! seen in one texel). The fitted frames are what level 0 stores, per texel and lobe
//! (the per-texel encoding's framed lobes), so the renderers need nothing new.

use fabric_runtime::brdf::{ClothFrame, cloth_frame};
use glam::Vec3;
use serde::Serialize;

/// One cluster's frame offset (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FrameOffset {
    /// Scale of the normal's slope (1: as the geometry stage gives it, 0: flat).
    pub slope: f32,
    /// Rise of the tangent out of the texel's plane, about b (radians).
    pub rise: f32,
    /// Twist of the tangent about the normal (radians).
    pub twist: f32,
    /// Roll of the normal about the tangent (radians).
    pub roll: f32,
}

impl Default for FrameOffset {
    fn default() -> Self {
        FrameOffset::IDENTITY
    }
}

impl FrameOffset {
    pub const IDENTITY: FrameOffset = FrameOffset { slope: 1.0, rise: 0.0, twist: 0.0, roll: 0.0 };
    /// Largest |rise| and |roll| searched (radians), largest |twist| (a quarter turn:
    /// the tangent is an axis, so ±π/2 covers every direction), the slope's range.
    pub const ANGLE_MAX: f32 = 1.0;
    pub const TWIST_MAX: f32 = std::f32::consts::FRAC_PI_2;
    pub const SLOPE_RANGE: [f32; 2] = [0.0, 2.0];

    pub fn is_identity(&self) -> bool {
        *self == FrameOffset::IDENTITY
    }

    /// The search vector (s, τ, ψ, ρ) and back; `None` outside the box.
    pub fn to_x(&self) -> [f64; 4] {
        [self.slope as f64, self.rise as f64, self.twist as f64, self.roll as f64]
    }

    pub fn from_x(x: &[f64]) -> Option<FrameOffset> {
        let o = FrameOffset { slope: x[0] as f32, rise: x[1] as f32, twist: x[2] as f32, roll: x[3] as f32 };
        let inside = (Self::SLOPE_RANGE[0]..=Self::SLOPE_RANGE[1]).contains(&o.slope) && [o.rise, o.roll].iter().all(|a| a.abs() <= Self::ANGLE_MAX) && o.twist.abs() <= Self::TWIST_MAX;
        inside.then_some(o)
    }

    /// The offset frame of `f` (module docs).
    pub fn apply(&self, f: &ClothFrame) -> ClothFrame {
        self.rotation().apply(f)
    }

    /// The offset with its sines and cosines taken once (a search applies one offset
    /// to thousands of frames).
    pub fn rotation(&self) -> OffsetRotation {
        OffsetRotation { identity: self.is_identity(), slope: self.slope, twist: self.twist.sin_cos(), rise: self.rise.sin_cos(), roll: self.roll.sin_cos() }
    }
}

/// A [`FrameOffset`] ready to apply: (sin, cos) of each angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OffsetRotation {
    identity: bool,
    slope: f32,
    twist: (f32, f32),
    rise: (f32, f32),
    roll: (f32, f32),
}

impl OffsetRotation {
    /// The offset frame of `f` (module docs).
    pub fn apply(&self, f: &ClothFrame) -> ClothFrame {
        if self.identity {
            return *f;
        }
        // Slope scaling in tile space; a normal at or below the horizon keeps its own.
        let n_s = if f.n.z > 1e-4 { Vec3::new(self.slope * f.n.x, self.slope * f.n.y, f.n.z).normalize() } else { f.n };
        let base = cloth_frame(n_s, f.t);
        let (n, t, b) = (base.n, base.t, base.b);
        let (st, ct) = self.twist;
        let t1 = ct * t + st * b;
        let (sr, cr) = self.rise;
        let t2 = cr * t1 + sr * n;
        let n2 = cr * n - sr * t1;
        let (sl, cl) = self.roll;
        let n3 = cl * n2 + sl * n2.cross(t2);
        cloth_frame(n3, t2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tilted() -> ClothFrame {
        cloth_frame(Vec3::new(0.3, -0.2, 0.9), Vec3::new(1.0, 0.2, 0.1))
    }

    #[test]
    fn identity_leaves_the_frame() {
        let f = tilted();
        assert_eq!(FrameOffset::IDENTITY.apply(&f), f);
        assert_eq!(FrameOffset::from_x(&FrameOffset::IDENTITY.to_x()), Some(FrameOffset::IDENTITY));
    }

    #[test]
    fn each_parameter_does_what_it_names() {
        let f = tilted();
        // Slope 0: the normal is vertical.
        let flat = FrameOffset { slope: 0.0, ..FrameOffset::IDENTITY }.apply(&f);
        assert!((flat.n - Vec3::Z).length() < 1e-5, "{flat:?}");
        // Twist: the tangent turns about n by ψ, n unchanged.
        let base = cloth_frame(FrameOffset { slope: 1.0 + 1e-7, ..FrameOffset::IDENTITY }.apply(&f).n, f.t);
        let tw = FrameOffset { twist: 0.4, ..FrameOffset::IDENTITY }.apply(&f);
        assert!((tw.n - base.n).length() < 1e-5);
        assert!((tw.t.dot(base.t) - 0.4f32.cos()).abs() < 1e-5);
        // Rise: t leans towards n by τ.
        let up = FrameOffset { rise: 0.3, ..FrameOffset::IDENTITY }.apply(&f);
        assert!((up.t.dot(base.n) - 0.3f32.sin()).abs() < 1e-5);
        // Roll: t unchanged, n turns by ρ about it.
        let roll = FrameOffset { roll: 0.5, ..FrameOffset::IDENTITY }.apply(&f);
        assert!((roll.t - base.t).length() < 1e-5 && (roll.n.dot(base.n) - 0.5f32.cos()).abs() < 1e-5);
        // Every result is orthonormal.
        for g in [flat, tw, up, roll] {
            assert!((g.n.length() - 1.0).abs() < 1e-5 && (g.t.length() - 1.0).abs() < 1e-5 && g.n.dot(g.t).abs() < 1e-5);
        }
    }

    #[test]
    fn the_box_is_enforced() {
        assert!(FrameOffset::from_x(&[2.5, 0.0, 0.0, 0.0]).is_none());
        assert!(FrameOffset::from_x(&[1.0, 0.0, -1.6, 0.0]).is_none());
        assert!(FrameOffset::from_x(&[1.0, 1.2, 0.0, 0.0]).is_none());
        assert!(FrameOffset::from_x(&[0.5, 0.2, -0.3, 0.1]).is_some());
    }
}
