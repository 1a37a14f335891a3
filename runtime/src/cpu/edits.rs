//! Live edits of a hybrid model's appearance without re-baking (paper Fig. 14): a tint
//! of the albedo and of every lobe's strength, a scale of the lobes' widths (roughness)
//! and a rotation of the surface's fiber tangents about their normals, everywhere or
//! weighted by a mask over the tile (a logo drawn in anisotropic highlights).
//!
//! Twin: the edit part of `shaders/common/shading.glsl` (hit_edit; texel_response applies
//! it while decoding). With a mask value m ∈ [0, 1] at the hit, the edit used is the
//! identity blended toward the full edit by m: tint 1 + m·(tint − 1), width scale
//! 1 + m·(scale − 1), rotation m·angle. Flyaways take the tint and the width scale (their
//! frame is the fiber's own: no rotation).
//!
//! The mask covers one repeat of the tile, as an image seen from above: pixel column i
//! spans x ∈ origin.x + [i, i+1)·size.x/w, pixel row r (row 0 at the top) spans
//! y ∈ origin.y + [h−1−r, h−r)·size.y/h; it is looked up at the nearest pixel.

use std::sync::Arc;

use glam::{Vec2, Vec3};

use crate::brdf::MAX_LOBES;
use crate::hybrid::TexelBrdf;

/// A mask over the tile: values in [0, 1], row 0 at the top (+y), x fastest.
#[derive(Clone, Debug, PartialEq)]
pub struct EditMask {
    pub width: u32,
    pub height: u32,
    pub values: Vec<f32>,
}

impl EditMask {
    /// A mask from values (finite ones clamped to [0, 1], as an HDR image's may exceed
    /// 1). Errors on a size mismatch and on a NaN or infinite value, naming its pixel:
    /// a corrupt mask would otherwise edit the wrong texels without a word.
    pub fn new(width: u32, height: u32, values: Vec<f32>) -> Result<EditMask, String> {
        if width == 0 || height == 0 || values.len() as u64 != width as u64 * height as u64 {
            return Err(format!("edit mask of {width}x{height} needs {} values, has {}", width as u64 * height as u64, values.len()));
        }
        if let Some(k) = values.iter().position(|v| !v.is_finite()) {
            return Err(format!("edit mask pixel ({}, {}) is {}: mask values must be finite (0 = unedited, 1 = edited)", k % width as usize, k / width as usize, values[k]));
        }
        Ok(EditMask { width, height, values: values.into_iter().map(|v| v.clamp(0.0, 1.0)).collect() })
    }

    /// The value at tile fraction u ∈ [0, 1)² (wrapped), nearest pixel.
    pub fn at(&self, u: Vec2) -> f32 {
        let fx = u.x - u.x.floor();
        let fy = u.y - u.y.floor();
        let i = ((fx * self.width as f32) as u32).min(self.width - 1);
        let row_from_bottom = ((fy * self.height as f32) as u32).min(self.height - 1);
        self.values[((self.height - 1 - row_from_bottom) * self.width + i) as usize]
    }
}

/// The edits of a render (the identity by default).
#[derive(Clone, Debug, PartialEq)]
pub struct Edits {
    /// Multiplies k_d and every k_j (linear RGB, ≥ 0).
    pub tint: Vec3,
    /// Multiplies every lobe's β and γ (> 0).
    pub roughness_scale: f32,
    /// Rotates the surface lobes' tangents about their normals (radians).
    pub tangent_rotation: f32,
    /// Where the edits apply (None: everywhere).
    pub mask: Option<Arc<EditMask>>,
}

impl Default for Edits {
    fn default() -> Self {
        Edits { tint: Vec3::ONE, roughness_scale: 1.0, tangent_rotation: 0.0, mask: None }
    }
}

/// The edit at one hit: the mask applied.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Edit {
    pub tint: Vec3,
    pub roughness_scale: f32,
    pub tangent_rotation: f32,
}

impl Edits {
    pub fn is_identity(&self) -> bool {
        self.tint == Vec3::ONE && self.roughness_scale == 1.0 && self.tangent_rotation == 0.0
    }

    /// Checks the values a renderer relies on.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.tint.is_finite() && self.tint.min_element() >= 0.0) {
            return Err(format!("tint {} must be finite and non-negative", self.tint));
        }
        if !(self.roughness_scale.is_finite() && self.roughness_scale > 0.0) {
            return Err(format!("roughness scale {} must be positive and finite", self.roughness_scale));
        }
        if !self.tangent_rotation.is_finite() {
            return Err(format!("tangent rotation {} is not finite", self.tangent_rotation));
        }
        Ok(())
    }

    /// The edit at tile fraction `u` (the hit's position in the tile, in [0, 1)²).
    pub fn at(&self, u: Vec2) -> Edit {
        let m = self.mask.as_ref().map_or(1.0, |mask| mask.at(u));
        Edit { tint: Vec3::ONE + m * (self.tint - Vec3::ONE), roughness_scale: 1.0 + m * (self.roughness_scale - 1.0), tangent_rotation: m * self.tangent_rotation }
    }
}

impl Edit {
    /// `b` edited; `rotate`: also the tangents (surface texels, not flyaways).
    pub fn apply(&self, mut b: TexelBrdf, rotate: bool) -> TexelBrdf {
        b.params.kd *= self.tint;
        for lobe in b.params.lobes.iter_mut().chain(std::iter::once(&mut b.transmission.lobe)) {
            lobe.k *= self.tint;
            lobe.beta *= self.roughness_scale;
            lobe.gamma *= self.roughness_scale;
        }
        b.transmission.kd *= self.tint;
        if rotate && self.tangent_rotation != 0.0 {
            let (s, c) = self.tangent_rotation.sin_cos();
            for f in b.frames.iter_mut().take(MAX_LOBES) {
                let t = f.t * c + f.b * s;
                f.t = t;
                f.b = f.n.cross(t);
            }
        }
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn masks_clamp_finite_values_and_refuse_the_rest() {
        let m = EditMask::new(2, 1, vec![-0.5, 7.0]).unwrap();
        assert_eq!(m.values, [0.0, 1.0]);
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let e = EditMask::new(2, 2, vec![0.0, 1.0, 0.5, bad]).unwrap_err();
            assert!(e.contains("pixel (1, 1)") && e.contains("finite"), "{e}");
        }
        assert!(EditMask::new(2, 2, vec![0.0; 3]).unwrap_err().contains("needs 4 values"));
    }
}
