//! Scalar and direction packings of the hybrid model, shared by the in-memory model and
//! the file (runtime/HYBRID_FORMAT.md §"Packings"), with what each costs in precision:
//!
//! - **f16**: IEEE binary16 bits; relative error ≤ 2⁻¹¹ (0.05%) in [6.1e-5, 65504].
//!   Used for k_d, η, a, k_j, β_j, γ_j.
//! - **unorm16**: v = code / 65535; absolute error ≤ 7.7e-6. Used for heights (as a
//!   fraction of the height scale) and flyaway alpha.
//! - **octahedral 2×snorm16** (Meyer et al. 2010): a unit vector; angular error
//!   ≤ 7e-5 rad (0.004°; measured worst over 200 000 directions: 6.4e-5); ±X, ±Y, ±Z
//!   exactly. snorm16 is Vulkan's: v = max(c / 32767, −1) for the i16 c, which GLSL's
//!   `unpackSnorm2x16` decodes. Used for normals and fiber axes.
//! - **tangent angle** (unorm16 over [0, π)): a tangent perpendicular to a known unit
//!   normal n, as the angle ψ from [`cloth_reference_tangent`](crate::brdf::cloth_reference_tangent)`(n)`
//!   toward n × reference; tangents are axes (t ≡ −t), so half a turn suffices. Error
//!   ≤ π/131072 = 2.4e-5 rad, and n ⊥ t exactly by construction. Encoded against the
//!   *decoded* normal, so that decoding reproduces it.


// `!(x > 0.0)` is the NaN-aware test (NaN fails it), as the GLSL writes it.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
use glam::Vec3;
use half::f16;


use crate::brdf::cloth_reference_tangent;

/// f32 → f16 bits (round to nearest; the model validates ranges, see the module docs).
#[inline]
pub fn f16_bits(v: f32) -> u16 {
    f16::from_f32(v).to_bits()
}

/// f16 bits → f32.
#[inline]
pub fn f16_value(bits: u16) -> f32 {
    f16::from_bits(bits).to_f32()
}

/// [0, 1] → unorm16 (clamped; NaN → 0).
#[inline]
pub fn unorm16(v: f32) -> u16 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    (v * 65535.0 + 0.5) as u16
}

/// [0, 1] → unorm8 (clamped; NaN and ±∞ → 0).
#[inline]
pub fn unorm8(v: f32) -> u8 {
    if v.is_finite() { (v.clamp(0.0, 1.0) * 255.0).round() as u8 } else { 0 }
}

/// unorm16 → [0, 1].
#[inline]
pub fn unorm16_value(code: u16) -> f32 {
    code as f32 * (1.0 / 65535.0)
}

/// [−1, 1] → snorm16 bits (i16 as u16; clamped; NaN → 0).
#[inline]
pub fn snorm16(v: f32) -> u16 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(-1.0, 1.0) };
    ((v * 32767.0).round() as i16) as u16
}

/// snorm16 bits → [−1, 1] (Vulkan's SNORM conversion).
#[inline]
pub fn snorm16_value(code: u16) -> f32 {
    (code as i16 as f32 * (1.0 / 32767.0)).max(-1.0)
}

/// The octahedral coordinates (u, v) ∈ [−1, 1]² of a direction (need not be unit).
/// Zero or non-finite → +Z, (0, 0).
fn octahedral_uv(w: Vec3) -> (f32, f32) {
    let l1 = w.x.abs() + w.y.abs() + w.z.abs();
    if !(l1 > 0.0 && l1.is_finite()) {
        return (0.0, 0.0);
    }
    let p = w / l1;
    let (mut u, mut v) = (p.x, p.y);
    if p.z < 0.0 {
        let (ou, ov) = (u, v);
        u = (1.0 - ov.abs()) * sign_not_zero(ou);
        v = (1.0 - ou.abs()) * sign_not_zero(ov);
    }
    (u, v)
}

/// Octahedral code of a direction (need not be unit). Zero or non-finite → +Z.
pub fn octahedral_encode(w: Vec3) -> [u16; 2] {
    let (u, v) = octahedral_uv(w);
    [snorm16(u), snorm16(v)]
}

/// [−1, 1] → snorm8 bits (i8 as u8; clamped; NaN → 0).
#[inline]
pub fn snorm8(v: f32) -> u8 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(-1.0, 1.0) };
    ((v * 127.0).round() as i8) as u8
}

/// snorm8 bits → [−1, 1] (Vulkan's SNORM conversion).
#[inline]
pub fn snorm8_value(code: u8) -> f32 {
    (code as i8 as f32 * (1.0 / 127.0)).max(-1.0)
}

/// Octahedral code of a direction at 8 bits per coordinate (format 1.8's second axis
/// group: within 0.95° of the direction, runtime/HYBRID_FORMAT.md §8). Zero or
/// non-finite → +Z.
pub fn octahedral_encode8(w: Vec3) -> [u8; 2] {
    let (u, v) = octahedral_uv(w);
    [snorm8(u), snorm8(v)]
}

/// Unit direction of an 8-bit octahedral code. Every code decodes to a unit vector.
pub fn octahedral_decode8(c: [u8; 2]) -> Vec3 {
    octahedral_from_uv(snorm8_value(c[0]), snorm8_value(c[1]))
}

/// Unit direction of an octahedral code. Every code decodes to a unit vector.
pub fn octahedral_decode(c: [u16; 2]) -> Vec3 {
    octahedral_from_uv(snorm16_value(c[0]), snorm16_value(c[1]))
}

/// Unit direction of octahedral coordinates (u, v) ∈ [−1, 1]².
fn octahedral_from_uv(u: f32, v: f32) -> Vec3 {
    let z = 1.0 - u.abs() - v.abs();
    let (x, y) = if z < 0.0 { ((1.0 - v.abs()) * sign_not_zero(u), (1.0 - u.abs()) * sign_not_zero(v)) } else { (u, v) };
    let w = Vec3::new(x, y, z);
    // |w|₁ = 1, so |w|₂ ≥ 1/√3: never zero.
    w * (1.0 / w.length())
}

#[inline]
fn sign_not_zero(x: f32) -> f32 {
    if x >= 0.0 { 1.0 } else { -1.0 }
}

/// The tangent-angle code of `t` around unit normal `n` (n as decoded from the file).
/// t ∥ n or zero → code 0 (the reference tangent).
pub fn tangent_angle_encode(n: Vec3, t: Vec3) -> u16 {
    let r = cloth_reference_tangent(n);
    let s = n.cross(r);
    let (x, y) = (t.dot(r), t.dot(s));
    if !(x * x + y * y > 1e-20) {
        return 0;
    }
    // Angle of the axis in [0, π): fold ψ and ψ + π together.
    let mut psi = y.atan2(x);
    if psi < 0.0 {
        psi += std::f32::consts::PI;
    }
    let code = (psi * (65536.0 / std::f32::consts::PI)).round() as u32;
    (code & 0xffff) as u16
}

/// The unit tangent of a tangent-angle code around unit normal `n`.
pub fn tangent_angle_decode(n: Vec3, code: u16) -> Vec3 {
    let psi = code as f32 * (std::f32::consts::PI / 65536.0);
    let r = cloth_reference_tangent(n);
    let s = n.cross(r);
    r * psi.cos() + s * psi.sin()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::twin::SplitMix64;

    #[test]
    fn octahedral_round_trip_within_its_stated_error() {
        let mut rng = SplitMix64(3);
        let mut worst = 0.0f32;
        for i in 0..200_000 {
            let w = match i {
                0 => Vec3::Z,
                1 => -Vec3::Z,
                2 => Vec3::X,
                3 => Vec3::new(-1.0, -1.0, 0.0).normalize(),
                _ => rng.unit_vector(),
            };
            let d = octahedral_decode(octahedral_encode(w));
            assert!((d.length() - 1.0).abs() < 1e-6);
            // |d × w| = sin∠: resolves small angles where acos of a dot product cannot.
            worst = worst.max(d.cross(w).length());
        }
        assert!(worst < 7e-5, "worst angular error {worst}");
        for axis in [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z] {
            assert_eq!(octahedral_decode(octahedral_encode(axis)), axis);
        }
        assert_eq!(octahedral_decode(octahedral_encode(Vec3::ZERO)), Vec3::Z);
        assert_eq!(octahedral_decode(octahedral_encode(Vec3::NAN)), Vec3::Z);
    }

    #[test]
    fn octahedral8_round_trip_within_its_stated_error_and_every_code_is_unit() {
        let mut rng = SplitMix64(5);
        let mut worst = 0.0f32;
        for _ in 0..200_000 {
            let w = rng.unit_vector();
            worst = worst.max(octahedral_decode8(octahedral_encode8(w)).cross(w).length());
        }
        assert!(worst < 1.66e-2, "worst angular error {worst}");
        for axis in [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z] {
            assert_eq!(octahedral_decode8(octahedral_encode8(axis)), axis);
        }
        for a in 0..=255u8 {
            for b in 0..=255u8 {
                let d = octahedral_decode8([a, b]);
                assert!(d.is_finite() && (d.length() - 1.0).abs() < 1e-6, "{a},{b} -> {d}");
            }
        }
    }

    #[test]
    fn every_octahedral_code_decodes_to_a_unit_vector() {
        for a in (0..=65535u32).step_by(97).chain([65535]) {
            for b in (0..=65535u32).step_by(89).chain([0, 65535]) {
                let d = octahedral_decode([a as u16, b as u16]);
                assert!(d.is_finite() && (d.length() - 1.0).abs() < 1e-6, "{a},{b} -> {d}");
            }
        }
    }

    #[test]
    fn tangent_angle_round_trip_is_an_axis_perpendicular_to_n() {
        let mut rng = SplitMix64(5);
        let mut worst = 0.0f32;
        for _ in 0..100_000 {
            let n = octahedral_decode(octahedral_encode(rng.unit_vector()));
            let t = rng.unit_vector();
            let t_perp = (t - n * t.dot(n)).normalize();
            let d = tangent_angle_decode(n, tangent_angle_encode(n, t));
            assert!(d.dot(n).abs() < 1e-6 && (d.length() - 1.0).abs() < 1e-6);
            // Axes: |d × t| = sin∠ is blind to the sign.
            worst = worst.max(d.cross(t_perp).length());
        }
        assert!(worst < 6e-5, "worst axis error {worst}");
    }

    #[test]
    fn scalar_packings() {
        assert_eq!(unorm16(f32::NAN), 0);
        assert_eq!(unorm16(2.0), 65535);
        assert_eq!(unorm16_value(unorm16(0.25)), 16384.0 / 65535.0);
        assert_eq!(f16_value(f16_bits(0.5)), 0.5);
        assert!(f16_value(f16_bits(1e6)).is_infinite(), "out of range halves are inf: the model rejects them");
    }
}
