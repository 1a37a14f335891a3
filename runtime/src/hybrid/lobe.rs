//! Packed BRDF records of the hybrid model: the per-texel (or per-cluster) header, the
//! lobe, and the clustered texel; the tables that hold them; and their decoding into
//! the BRDF twin's types (runtime/HYBRID_FORMAT.md §"Records").
//!
//! | record            | bytes | holds                                                 |
//! |-------------------|-------|-------------------------------------------------------|
//! | [`BrdfHeader`]     | 16    | k_d (3×f16), η, a (f16), lobe count, first lobe       |
//! | [`PackedLobe`]     | 16    | n (oct 2×snorm16), t (angle 16), k (3×f16), β, γ (f16)     |
//! | [`ClusteredTexel`] | 8     | n (oct 2×snorm16), t (angle 16), cluster index (u16)       |
//! | [`PackedTransmission`] | 24 | k_dt (3×f16), k_t (3×f16), β_t, γ_t, τ (f16) (format 1.3); openness o, q (2×f16), a, b (2×snorm8) (format 1.10) |
//! | [`PackedViewTilt`] | 12 | B, the visible normal's 2×2 slope matrix, row-major (4×f16); c, the log-visibility slope (2×f16) (format 1.4) |
//!
//! A table is a header array plus a lobe array; header h uses lobes
//! `lobe_offset .. lobe_offset + lobe_count`. In cluster and flyaway tables the lobes'
//! frames are unused (written as zero): the frame comes from the texel or the fiber.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use super::error::{ModelError, TableKind};
use super::packing::{f16_bits, f16_value, snorm8, snorm8_value, octahedral_decode, octahedral_encode, tangent_angle_decode, tangent_angle_encode};
use crate::brdf::visible_normal::ViewTilt;
use crate::brdf::{A_MAX, BETA_MAX, BETA_MIN, ClothFrame, ClothLobe, ClothOpenness, ClothParams, ClothTransmission, CURVATURE_MAX, ETA_MAX, GRADIENT_MAX, OPENNESS_Q_MAX, TAU_MAX, GAMMA_MAX, GAMMA_MIN, MAX_LOBES, cloth_frame};

/// k_d, η, a and where a texel's (or cluster's) lobes are. 16 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct BrdfHeader {
    /// k_d, RGB, f16 bits.
    pub kd: [u16; 3],
    /// η, f16 bits.
    pub eta: u16,
    /// Shadowing exponent a, f16 bits.
    pub a: u16,
    /// Number of lobes, 0..=8 (≥ 1 for per-texel headers: lobe 0's frame is the texel's).
    pub lobe_count: u8,
    /// Must be 0.
    pub reserved: u8,
    /// Index of the first lobe in the table's lobe array.
    pub lobe_offset: u32,
}

/// One lobe: its frame (unused in cluster and flyaway tables) and k, β, γ. 16 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct PackedLobe {
    /// Normal, octahedral 2×snorm16.
    pub normal: [u16; 2],
    /// Tangent as an angle around the normal (see [`super::packing`]).
    pub tangent_angle: u16,
    /// k, RGB, f16 bits.
    pub k: [u16; 3],
    /// β (radians), f16 bits.
    pub beta: u16,
    /// γ (radians), f16 bits; 0 = the φ falloff is off (γ = ∞).
    pub gamma: u16,
}

/// A level-0 texel of the clustered encoding: its frame and its cluster. 8 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct ClusteredTexel {
    pub normal: [u16; 2],
    pub tangent_angle: u16,
    /// Index into the level's cluster table.
    pub cluster: u16,
}

/// A texel's transmission term (format 1.3): k_dt, and the lobe about the transmitted
/// direction, in the texel's lobe-0 frame, and its attenuation τ
/// ([`crate::brdf::cloth_transmission`]); since format 1.10 also its openness (o, q)
/// ([`crate::brdf::cloth_openness`]), zero in older files. 24 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct PackedTransmission {
    /// k_dt, RGB, f16 bits.
    pub kd: [u16; 3],
    /// k_t, RGB, f16 bits.
    pub k: [u16; 3],
    /// β_t (radians), f16 bits.
    pub beta: u16,
    /// γ_t (radians), f16 bits; 0 = the φ falloff is off.
    pub gamma: u16,
    /// τ, f16 bits.
    pub tau: u16,
    /// The openness's o and q, f16 bits, and its azimuth terms a | b << 8, snorm8
    /// (format 1.10: these were reserved, 0, before).
    pub gap: [u16; 2],
    pub gap_aniso: u16,
}

impl PackedTransmission {
    pub fn new(t: &ClothTransmission) -> PackedTransmission {
        PackedTransmission { kd: t.kd.to_array().map(f16_bits), k: t.lobe.k.to_array().map(f16_bits), beta: f16_bits(t.lobe.beta), gamma: f16_bits(t.lobe.gamma), tau: f16_bits(t.tau), gap: [f16_bits(t.gap.o), f16_bits(t.gap.q)], gap_aniso: u16::from_le_bytes([snorm8(t.gap.aniso[0]), snorm8(t.gap.aniso[1])]) }
    }

    /// The record's term; its visibility (format 1.16) is in its own section, zero here
    /// (`Level::texel_brdf` fills it in).
    pub fn decode(&self) -> ClothTransmission {
        let v = |b: [u16; 3]| Vec3::new(f16_value(b[0]), f16_value(b[1]), f16_value(b[2]));
        ClothTransmission { kd: v(self.kd), lobe: ClothLobe { k: v(self.k), beta: f16_value(self.beta), gamma: f16_value(self.gamma) }, tau: f16_value(self.tau), gap: ClothOpenness { o: f16_value(self.gap[0]), q: f16_value(self.gap[1]), aniso: self.gap_aniso.to_le_bytes().map(snorm8_value) }, grad: [0.0; 4], curv: [0.0; 6] }
    }

    /// Checks one record (texel `texel` of level `level`): finite k's ≥ 0, β and γ in
    /// the BRDF's ranges (a zero record, "nothing comes through", passes).
    pub fn validate(&self, level: usize, texel: usize) -> Result<(), ModelError> {
        let t = self.decode();
        let bad = |field, value, range| ModelError::TransmissionParam { level, texel, field, value, range };
        for (field, v) in [("k_dt.r", t.kd.x), ("k_dt.g", t.kd.y), ("k_dt.b", t.kd.z), ("k_t.r", t.lobe.k.x), ("k_t.g", t.lobe.k.y), ("k_t.b", t.lobe.k.z)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(field, v, "finite, >= 0"));
            }
        }
        let (beta, gamma) = (t.lobe.beta, t.lobe.gamma);
        if !((beta == 0.0 && t.lobe.k == Vec3::ZERO) || (beta >= BETA_MIN * 0.999 && beta <= BETA_MAX)) {
            return Err(bad("beta_t", beta, "[1e-3, 1e4] (0 only with k_t = 0)"));
        }
        if !(gamma == 0.0 || (gamma >= GAMMA_MIN * 0.999 && gamma <= GAMMA_MAX)) {
            return Err(bad("gamma_t", gamma, "0 (off) or [1e-3, 1e4]"));
        }
        if !(t.tau >= 0.0 && t.tau <= TAU_MAX) {
            return Err(bad("tau", t.tau, "[0, 16]"));
        }
        if !(t.gap.o >= 0.0 && t.gap.o <= 1.0) {
            return Err(bad("openness o", t.gap.o, "[0, 1]"));
        }
        if !(t.gap.q >= 0.0 && t.gap.q <= OPENNESS_Q_MAX) {
            return Err(bad("openness q", t.gap.q, "[0, 64]"));
        }
        Ok(())
    }
}

/// A coarse texel's view tilt (format 1.4): the 2×2 matrix B and the vector c of
/// [`crate::brdf::visible_normal`], f16 bits. 12 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct PackedViewTilt {
    /// B, row-major.
    pub b: [u16; 4],
    pub c: [u16; 2],
}

/// Largest |B_ij| and |c_i| a file may hold (fitted values are ≲ 1 and ≲ 3).
pub const VIEW_TILT_MAX: f32 = 8.0;

impl PackedViewTilt {
    pub fn new(t: &ViewTilt) -> PackedViewTilt {
        let bits = |v: f32| f16_bits(if v.is_finite() { v.clamp(-VIEW_TILT_MAX, VIEW_TILT_MAX) } else { 0.0 });
        PackedViewTilt { b: t.b.map(bits), c: t.c.map(bits) }
    }

    pub fn decode(&self) -> ViewTilt {
        ViewTilt { b: self.b.map(f16_value), c: self.c.map(f16_value) }
    }

    /// Checks one record (texel `texel` of level `level`): finite, within ±[`VIEW_TILT_MAX`].
    pub fn validate(&self, level: usize, texel: usize) -> Result<(), ModelError> {
        let t = self.decode();
        let fields = ["b00", "b01", "b10", "b11", "c0", "c1"];
        for (field, v) in fields.into_iter().zip(t.b.into_iter().chain(t.c)) {
            if !(v.is_finite() && v.abs() <= VIEW_TILT_MAX) {
                return Err(ModelError::ViewTiltParam { level, texel, field, value: v, max: VIEW_TILT_MAX });
            }
        }
        Ok(())
    }
}

/// A texel's visibility gradient (format 1.12): g = (g_o,x, g_o,y, g_i,x, g_i,y) of
/// [`crate::brdf::cloth_visibility_gradient`], f16 bits. 8 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct PackedGradient {
    pub g: [u16; 4],
}

impl PackedGradient {
    /// Packs `g`, each coefficient clamped to ±[`GRADIENT_MAX`] (a non-finite one to 0).
    pub fn new(g: [f32; 4]) -> PackedGradient {
        PackedGradient { g: g.map(|v| f16_bits(if v.is_finite() { v.clamp(-GRADIENT_MAX, GRADIENT_MAX) } else { 0.0 })) }
    }

    pub fn decode(&self) -> [f32; 4] {
        self.g.map(f16_value)
    }

    /// Checks one record (texel `texel` of level `level`): finite, within ±[`GRADIENT_MAX`].
    pub fn validate(&self, level: usize, texel: usize) -> Result<(), ModelError> {
        for (field, v) in ["g_o.x", "g_o.y", "g_i.x", "g_i.y"].into_iter().zip(self.decode()) {
            if !(v.is_finite() && v.abs() <= GRADIENT_MAX) {
                return Err(ModelError::GradientParam { level, texel, field, value: v, max: GRADIENT_MAX });
            }
        }
        Ok(())
    }
}

/// A texel's visibility curvature (format 1.15): q of [`crate::brdf::cloth_visibility`],
/// the coefficients of [`crate::brdf::cloth_curvature_terms`] in order, f16 bits. 12 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct PackedCurvature {
    pub q: [u16; 6],
}

impl PackedCurvature {
    /// Packs `q`, each coefficient clamped to ±[`CURVATURE_MAX`] (a non-finite one to 0).
    pub fn new(q: [f32; 6]) -> PackedCurvature {
        PackedCurvature { q: q.map(|v| f16_bits(if v.is_finite() { v.clamp(-CURVATURE_MAX, CURVATURE_MAX) } else { 0.0 })) }
    }

    pub fn decode(&self) -> [f32; 6] {
        self.q.map(f16_value)
    }

    /// Checks one record (texel `texel` of level `level`): finite, within ±[`CURVATURE_MAX`].
    pub fn validate(&self, level: usize, texel: usize) -> Result<(), ModelError> {
        for (field, v) in ["q_xx", "q_yy", "q_xy", "q_ox_ix", "q_oy_iy", "q_cross"].into_iter().zip(self.decode()) {
            if !(v.is_finite() && v.abs() <= CURVATURE_MAX) {
                return Err(ModelError::CurvatureParam { level, texel, field, value: v, max: CURVATURE_MAX });
            }
        }
        Ok(())
    }
}

/// A BSDF texel's transmission visibility (format 1.16): the gradient g and curvature q
/// of [`crate::brdf::cloth_transmission_visibility`], as the reflection's records hold
/// them. 20 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct PackedTransmissionVisibility {
    pub g: PackedGradient,
    pub q: PackedCurvature,
}

impl PackedTransmissionVisibility {
    /// Packs `g` and `q`, each clamped as its reflection twin's record clamps it.
    pub fn new(g: [f32; 4], q: [f32; 6]) -> PackedTransmissionVisibility {
        PackedTransmissionVisibility { g: PackedGradient::new(g), q: PackedCurvature::new(q) }
    }

    pub fn decode(&self) -> ([f32; 4], [f32; 6]) {
        (self.g.decode(), self.q.decode())
    }

    /// Checks one record (texel `texel` of level `level`): finite, within the clamps;
    /// the gradient's fields named for the sides of the sheet (g_u above, g_l below).
    pub fn validate(&self, level: usize, texel: usize) -> Result<(), ModelError> {
        let named = |e: ModelError| match e {
            ModelError::GradientParam { level, texel, field, value, max } | ModelError::CurvatureParam { level, texel, field, value, max } => {
                let field = match field {
                    "g_o.x" => "g_u.x",
                    "g_o.y" => "g_u.y",
                    "g_i.x" => "g_l.x",
                    "g_i.y" => "g_l.y",
                    q => q,
                };
                ModelError::TransmissionVisibilityParam { level, texel, field, value, max }
            }
            e => e,
        };
        self.g.validate(level, texel).map_err(named)?;
        self.q.validate(level, texel).map_err(named)
    }
}

const _: () = assert!(core::mem::size_of::<PackedTransmissionVisibility>() == 20);
const _: () = assert!(core::mem::size_of::<PackedGradient>() == 8);
const _: () = assert!(core::mem::size_of::<PackedCurvature>() == 12);
const _: () = assert!(core::mem::size_of::<PackedViewTilt>() == 12);
const _: () = assert!(core::mem::size_of::<PackedTransmission>() == 24);
const _: () = assert!(core::mem::size_of::<BrdfHeader>() == 16);
const _: () = assert!(core::mem::size_of::<PackedLobe>() == 16);
const _: () = assert!(core::mem::size_of::<ClusteredTexel>() == 8);

/// Packs a frame: the normal's octahedral code and the tangent's angle around the
/// *decoded* normal (so that decoding reproduces it).
pub fn encode_frame(n: Vec3, t: Vec3) -> ([u16; 2], u16) {
    let code = octahedral_encode(n);
    (code, tangent_angle_encode(octahedral_decode(code), t))
}

/// Unpacks a frame (orthonormal by construction).
pub fn decode_frame(normal: [u16; 2], tangent_angle: u16) -> ClothFrame {
    let n = octahedral_decode(normal);
    let t = tangent_angle_decode(n, tangent_angle);
    ClothFrame { n, t, b: n.cross(t) }
}

impl PackedLobe {
    /// Packs a lobe; `frame` = (n, t), or `None` in cluster and flyaway tables.
    pub fn new(lobe: &ClothLobe, frame: Option<(Vec3, Vec3)>) -> PackedLobe {
        let (normal, tangent_angle) = frame.map(|(n, t)| encode_frame(n, t)).unwrap_or(([0, 0], 0));
        PackedLobe { normal, tangent_angle, k: lobe.k.to_array().map(f16_bits), beta: f16_bits(lobe.beta), gamma: f16_bits(lobe.gamma) }
    }

    pub fn lobe(&self) -> ClothLobe {
        ClothLobe { k: Vec3::from_array(self.k.map(f16_value)), beta: f16_value(self.beta), gamma: f16_value(self.gamma) }
    }

    pub fn frame(&self) -> ClothFrame {
        decode_frame(self.normal, self.tangent_angle)
    }
}

impl ClusteredTexel {
    pub fn new(n: Vec3, t: Vec3, cluster: u16) -> ClusteredTexel {
        let (normal, tangent_angle) = encode_frame(n, t);
        ClusteredTexel { normal, tangent_angle, cluster }
    }

    pub fn frame(&self) -> ClothFrame {
        decode_frame(self.normal, self.tangent_angle)
    }
}

impl BrdfHeader {
    pub fn kd(&self) -> Vec3 {
        Vec3::from_array(self.kd.map(f16_value))
    }

    pub fn eta(&self) -> f32 {
        f16_value(self.eta)
    }

    pub fn a(&self) -> f32 {
        f16_value(self.a)
    }

    /// The header's lobe index range (assumes a validated table).
    pub fn lobe_range(&self) -> std::ops::Range<usize> {
        let start = self.lobe_offset as usize;
        start..start + self.lobe_count as usize
    }
}

/// A BRDF decoded for shading: k_d, η, a and up to eight lobes, each with its own frame
/// (all equal for a clustered texel), and the transmission term (zero where the level
/// has none). No allocation: fixed arrays, as in the shader.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TexelBrdf {
    pub params: ClothParams,
    pub frames: [ClothFrame; MAX_LOBES],
    pub transmission: ClothTransmission,
    /// The reflection's visibility gradient ([`crate::brdf::cloth_visibility_gradient`];
    /// zero where the level has none).
    pub gradient: [f32; 4],
    /// The reflection's visibility curvature ([`crate::brdf::cloth_visibility`]; zero
    /// where the level has none).
    pub curvature: [f32; 6],
    /// A flyaway fibre whose lobes follow the cylinder law
    /// ([`crate::brdf::cloth_cylinder_lobe`]; set by `cpu::shading::in_fiber_frame`).
    pub cylinder: bool,
}

/// Headers and lobes: a cluster table, a flyaway table, or a level's per-texel BRDFs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BrdfTable {
    pub headers: Vec<BrdfHeader>,
    pub lobes: Vec<PackedLobe>,
}

impl BrdfTable {
    pub fn new() -> BrdfTable {
        BrdfTable::default()
    }

    /// Appends a BRDF whose lobes take their frame from elsewhere (cluster and flyaway
    /// tables); returns its index. At most [`MAX_LOBES`] lobes are kept.
    pub fn push(&mut self, p: &ClothParams) -> u32 {
        self.push_lobes(p.kd, p.eta, p.a, p.lobes().iter().map(|l| PackedLobe::new(l, None)))
    }

    /// Appends a BRDF whose lobes have their own frames (n, t) (per-texel encoding).
    pub fn push_framed(&mut self, kd: Vec3, eta: f32, a: f32, lobes: &[(ClothLobe, Vec3, Vec3)]) -> u32 {
        self.push_lobes(kd, eta, a, lobes.iter().take(MAX_LOBES).map(|(l, n, t)| PackedLobe::new(l, Some((*n, *t)))))
    }

    fn push_lobes(&mut self, kd: Vec3, eta: f32, a: f32, lobes: impl Iterator<Item = PackedLobe>) -> u32 {
        let lobe_offset = self.lobes.len() as u32;
        self.lobes.extend(lobes.take(MAX_LOBES));
        let lobe_count = (self.lobes.len() as u32 - lobe_offset) as u8;
        self.headers.push(BrdfHeader { kd: kd.to_array().map(f16_bits), eta: f16_bits(eta), a: f16_bits(a), lobe_count, reserved: 0, lobe_offset });
        self.headers.len() as u32 - 1
    }

    /// Entry `index` with its lobes, all in the frame `frame` (cluster and flyaway tables).
    /// Panics on an index past the end: validate the model first.
    pub fn brdf_in_frame(&self, index: usize, frame: ClothFrame) -> TexelBrdf {
        let h = &self.headers[index];
        let mut params = ClothParams { kd: h.kd(), eta: h.eta(), a: h.a(), lobe_count: h.lobe_count as u32, ..Default::default() };
        for (j, lobe) in self.lobes[h.lobe_range()].iter().enumerate() {
            params.lobes[j] = lobe.lobe();
        }
        TexelBrdf { params, frames: [frame; MAX_LOBES], transmission: ClothTransmission::default(), gradient: [0.0; 4], curvature: [0.0; 6], cylinder: false }
    }

    /// Entry `index` with each lobe in its own frame (per-texel encoding).
    pub fn brdf_framed(&self, index: usize) -> TexelBrdf {
        let h = &self.headers[index];
        let mut params = ClothParams { kd: h.kd(), eta: h.eta(), a: h.a(), lobe_count: h.lobe_count as u32, ..Default::default() };
        let mut frames = [cloth_frame(Vec3::Z, Vec3::X); MAX_LOBES];
        for (j, lobe) in self.lobes[h.lobe_range()].iter().enumerate() {
            params.lobes[j] = lobe.lobe();
            frames[j] = lobe.frame();
        }
        TexelBrdf { params, frames, transmission: ClothTransmission::default(), gradient: [0.0; 4], curvature: [0.0; 6], cylinder: false }
    }

    /// Checks every header and lobe: counts and ranges, finite parameters in range.
    /// `min_lobes` is 1 for per-texel headers (lobe 0 carries the texel's frame).
    pub fn validate(&self, table: TableKind, level: usize, min_lobes: u32) -> Result<(), ModelError> {
        for (entry, h) in self.headers.iter().enumerate() {
            let count = h.lobe_count as u32;
            if count < min_lobes || count > MAX_LOBES as u32 {
                return Err(ModelError::LobeCount { table, level, entry, count, min: min_lobes });
            }
            if h.reserved != 0 {
                return Err(ModelError::Reserved { table, level, entry, value: h.reserved });
            }
            if h.lobe_offset as u64 + count as u64 > self.lobes.len() as u64 {
                return Err(ModelError::LobeRange { table, level, entry, offset: h.lobe_offset, count, len: self.lobes.len() });
            }
            let param = |field, value: f32, ok: bool, range| if ok { Ok(()) } else { Err(ModelError::Param { table, level, entry, field, value, range }) };
            let kd = h.kd();
            for (field, v) in [("k_d.r", kd.x), ("k_d.g", kd.y), ("k_d.b", kd.z)] {
                param(field, v, v.is_finite() && v >= 0.0, "finite, >= 0")?;
            }
            param("eta", h.eta(), (1.0..=ETA_MAX).contains(&h.eta()), "[1, 4]")?;
            param("a", h.a(), (0.0..=A_MAX).contains(&h.a()), "[0, 1e4]")?;
        }
        for (index, lobe) in self.lobes.iter().enumerate() {
            let l = lobe.lobe();
            let bad = |field, value, range| {
                if table == TableKind::Flyaways {
                    ModelError::FlyawayLobeParam { level, lobe: index, field, value, range }
                } else {
                    ModelError::LobeParam { level, lobe: index, field, value, range }
                }
            };
            for (field, v) in [("k.r", l.k.x), ("k.g", l.k.y), ("k.b", l.k.z)] {
                if !(v.is_finite() && v >= 0.0) {
                    return Err(bad(field, v, "finite, >= 0"));
                }
            }
            // The BRDF clamps β and γ into range; a stored value outside it would not
            // render as stored, so it is an error here. 0.999: f16 rounding of the bounds.
            if !(l.beta >= BETA_MIN * 0.999 && l.beta <= BETA_MAX) {
                return Err(bad("beta", l.beta, "[1e-3, 1e4]"));
            }
            if !(l.gamma == 0.0 || (l.gamma >= GAMMA_MIN * 0.999 && l.gamma <= GAMMA_MAX)) {
                return Err(bad("gamma", l.gamma, "0 (off) or [1e-3, 1e4]"));
            }
        }
        Ok(())
    }

    /// Bytes this table takes in the file.
    pub fn byte_size(&self) -> u64 {
        (self.headers.len() * size_of::<BrdfHeader>() + self.lobes.len() * size_of::<PackedLobe>()) as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::{BrdfReading, cloth_brdf};

    #[test]
    fn table_round_trip_is_within_half_precision() {
        let p = ClothParams::new(
            Vec3::new(0.1, 0.2, 0.3),
            1.45,
            2.5,
            &[ClothLobe { k: Vec3::new(0.9, 0.5, 0.1), beta: 0.07, gamma: 0.4 }, ClothLobe { k: Vec3::splat(0.2), beta: 0.3, gamma: 0.0 }],
        );
        let mut table = BrdfTable::new();
        assert_eq!(table.push(&p), 0);
        table.validate(TableKind::SurfaceClusters, 0, 0).unwrap();
        let frame = cloth_frame(Vec3::Z, Vec3::X);
        let back = table.brdf_in_frame(0, frame).params;
        assert_eq!(back.lobe_count, 2);
        let (wi, wo) = (Vec3::new(0.3, 0.1, 0.9).normalize(), Vec3::new(-0.35, 0.05, 0.9).normalize());
        let a = cloth_brdf(&p, &frame, wi, wo, BrdfReading::Bounded);
        let b = cloth_brdf(&back, &frame, wi, wo, BrdfReading::Bounded);
        // f16 parameters: 2⁻¹¹ relative each; the exponent's sensitivity to β adds a few.
        assert!((a - b).abs().max_element() < 5e-3 * a.max_element(), "{a} vs {b}");
    }

    #[test]
    fn validation_names_the_bad_entry() {
        let mut table = BrdfTable::new();
        table.push(&ClothParams::new(Vec3::ONE, 1.5, 1.0, &[ClothLobe { k: Vec3::ONE, beta: 0.1, gamma: 0.0 }]));
        table.push(&ClothParams::new(Vec3::ONE, 0.5, 1.0, &[ClothLobe { k: Vec3::ONE, beta: 0.1, gamma: 0.0 }]));
        let e = table.validate(TableKind::SurfaceClusters, 2, 0).unwrap_err();
        assert!(matches!(e, ModelError::Param { entry: 1, field: "eta", level: 2, .. }), "{e}");
        let mut table = BrdfTable::new();
        table.push(&ClothParams::new(Vec3::ONE, 1.5, 1.0, &[ClothLobe { k: Vec3::new(1.0, f32::NAN, 0.0), beta: 0.1, gamma: 0.0 }]));
        assert!(matches!(table.validate(TableKind::Flyaways, 0, 0), Err(ModelError::FlyawayLobeParam { field: "k.g", .. })));
        table.headers[0].lobe_offset = u32::MAX;
        assert!(matches!(table.validate(TableKind::Flyaways, 0, 0), Err(ModelError::LobeRange { .. })));
    }
}
