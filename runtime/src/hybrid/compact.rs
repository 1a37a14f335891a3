//! The compact encoding of a per-texel level (format 1.7; runtime/HYBRID_FORMAT.md §6.6):
//! smaller file records for the coarse levels of the mip chain, whose lobes are filters
//! of level 0's and need less precision than level 0's fitted ones.
//!
//! | record              | bytes | wide record        | holds                                        |
//! |---------------------|-------|--------------------|----------------------------------------------|
//! | [`CompactTexel`]    | 8     | `BrdfHeader` 16    | k_d (RGB9E5), a (f16), η (12 bits), lobe count (3 bits); the first lobe is implicit (running sum) |
//! | [`CompactLobe`]     | 12    | `PackedLobe` 16    | n (octahedral 2×11 bits), t (angle, 10 bits), k (RGB9E5), β, γ (f16) |
//! | [`CompactViewTilt`] | 6     | `PackedViewTilt` 12 | B: 4 × 7-bit integers with one exponent; c: 2 × 6-bit with one |
//! | [`CompactAxisSpread`] | 6   | `PackedAxisSpread` 8 | the same fields without the reserved one (always exact) |
//! | [`CompactFlyawayNode`] | 8  | `FlyawayNode` 16   | depth (12 bits), α (unorm16), the fibre axis (octahedral 2×11 bits), BRDF index (14 bits); the link implicit (lists stored column by column) |
//!
//! The encoding is a property of the file, not of the model: the writer stores a
//! level's records compactly exactly when every one of them is representable, and the
//! reader expands them back into the wide records, bit for bit — so a model reads back
//! equal to what was written, and the renderers (and the GPU layout) see wide records
//! only. `fabric prefilter` snaps its coarse levels to the compact grid
//! ([`quantize_table`], [`quantize_view_tilts`]); level 0, fitted at f16 precision, stays
//! wide. What the snapping costs in the far views: baker/PREFILTER_MEASUREMENTS.md,
//! "Compact coarse records".

use bytemuck::{Pod, Zeroable};

use super::flyaway::{FlyawayNode, Flyaways, NO_NODE, PackedAxisSpread};
use super::lobe::{BrdfHeader, BrdfTable, PackedLobe, PackedViewTilt};
use super::packing::{f16_bits, f16_value, octahedral_decode, tangent_angle_encode};
use crate::brdf::MAX_LOBES;

/// A per-texel header without its lobe offset. 8 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct CompactTexel {
    /// k_d, RGB9E5 ([`rgb9e5_decode`]).
    pub kd: u32,
    /// a, f16 bits.
    pub a: u16,
    /// Bits 0–11: η = 1 + 3·q/4095; bits 12–14: lobe count − 1; bit 15: must be 0.
    pub eta_count: u16,
}

/// A framed lobe. 12 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct CompactLobe {
    /// Bits 0–10 and 11–21: the normal's octahedral (u, v) as q + 1023, q ∈ [−1023, 1023]
    /// (u = q/1023; 2047 is invalid); bits 22–31: the tangent angle ψ = q·π/1024.
    pub frame: u32,
    /// k, RGB9E5.
    pub k: u32,
    /// β | γ << 16, f16 bits each.
    pub beta_gamma: u32,
}

/// A view tilt, 48 bits little endian: bits 0–3 e_B, 4–31 b00, b01, b10, b11 as 7-bit
/// two's-complement q (b = q·2^(e_B − 12)), 32–35 e_c, 36–47 c0, c1 as 6-bit q
/// (c = q·2^(e_c − 11)); the codes −64 and −32 are invalid. 6 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct CompactViewTilt {
    pub v: [u8; 6],
}

/// A flyaway node's spread: roll (u16, little endian), λ₂, λ₃, z₀, z₁ — the wide
/// record without its reserved field. 6 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct CompactAxisSpread {
    pub v: [u8; 6],
}

/// A flyaway node without its link, 64 bits little endian (two u32): bits 0–11 depth,
/// 12–27 α (unorm16 as stored), 28–38 and 39–49 the fibre axis's octahedral (u, v) as
/// q + 1023 (as a lobe's normal; 2047 is invalid), 50–63 the BRDF index. A list is the
/// nodes from its head up to the next non-empty column's head (the last: to the end),
/// so heads must rise in texel order, the first at 0. 8 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct CompactFlyawayNode {
    pub w: [u32; 2],
}

const _: () = assert!(core::mem::size_of::<CompactAxisSpread>() == 6);
const _: () = assert!(core::mem::size_of::<CompactFlyawayNode>() == 8);
const _: () = assert!(core::mem::size_of::<CompactTexel>() == 8);
const _: () = assert!(core::mem::size_of::<CompactLobe>() == 12);
const _: () = assert!(core::mem::size_of::<CompactViewTilt>() == 6);

/// 2ⁿ exactly, for n in the normal f32 range.
fn exp2i(n: i32) -> f32 {
    f32::from_bits(((n + 127) as u32) << 23)
}

/// Largest RGB9E5 value: 511·2⁷.
pub const RGB9E5_MAX: f32 = 65408.0;

/// RGB9E5 (shared exponent, OpenGL's `EXT_texture_shared_exponent`): c = m_c·2^(e − 24),
/// m_c the 9-bit mantissas (bits 0–8 r, 9–17 g, 18–26 b), e bits 27–31. Every value is
/// an f16 exactly (9 significant bits, 2⁻²⁴ to 65408).
pub fn rgb9e5_decode(code: u32) -> [f32; 3] {
    let scale = exp2i((code >> 27) as i32 - 24);
    [(code & 511) as f32 * scale, ((code >> 9) & 511) as f32 * scale, ((code >> 18) & 511) as f32 * scale]
}

/// The nearest RGB9E5 code: the smallest exponent whose mantissa holds the largest
/// channel, each channel rounded to nearest (non-finite and negative → 0; clamped to
/// [`RGB9E5_MAX`]). Absolute error ≤ 2⁻⁹ of the largest channel (its mantissa ≥ 256).
pub fn rgb9e5_encode(v: [f32; 3]) -> u32 {
    let c = v.map(|x| if x.is_finite() && x > 0.0 { x.min(RGB9E5_MAX) } else { 0.0 });
    let max = c[0].max(c[1]).max(c[2]);
    if max == 0.0 {
        return 0;
    }
    let e = (0..32).find(|&e| (max / exp2i(e - 24)).round() <= 511.0).unwrap_or(31);
    let scale = exp2i(e - 24);
    let m = c.map(|x| ((x / scale).round() as u32).min(511));
    m[0] | m[1] << 9 | m[2] << 18 | (e as u32) << 27
}

/// The RGB9E5 code of three f16 values, if it holds them exactly.
fn rgb9e5_exact(bits: [u16; 3]) -> Option<u32> {
    let code = rgb9e5_encode(bits.map(f16_value));
    (rgb9e5_decode(code).map(f16_bits) == bits).then_some(code)
}

/// f16 bits of three values snapped to RGB9E5.
fn rgb9e5_snap(bits: [u16; 3]) -> [u16; 3] {
    rgb9e5_decode(rgb9e5_encode(bits.map(f16_value))).map(f16_bits)
}

/// A group of values sharing one exponent: q·2^(e − bias), e ∈ 0..=15 (4 bits), each q
/// a signed `bits`-bit integer in ±(2^(bits−1) − 1). The B group is 4 × 7 bits (bias 12),
/// the c group 2 × 6 bits (bias 11); every value is an f16 exactly.
#[derive(Clone, Copy)]
struct SharedExponent {
    bits: u32,
    bias: i32,
}

const TILT_B: SharedExponent = SharedExponent { bits: 7, bias: 12 };
const TILT_C: SharedExponent = SharedExponent { bits: 6, bias: 11 };

impl SharedExponent {
    fn max_q(self) -> i32 {
        (1 << (self.bits - 1)) - 1
    }

    fn decode(self, e: u32, q: i32) -> f32 {
        q as f32 * exp2i(e as i32 - self.bias)
    }

    /// The smallest exponent whose integers hold the largest |v| (non-finite → 0),
    /// and the rounded integers. Error ≤ 1/(2^(bits−1) − 1) of the largest |v| (≤ 8),
    /// plus half the finest step, 2^(−bias − 1).
    fn encode<const N: usize>(self, v: [f32; N]) -> (u32, [i32; N]) {
        let v = v.map(|x| if x.is_finite() { x.clamp(-8.0, 8.0) } else { 0.0 });
        let max = v.iter().fold(0f32, |a, x| a.max(x.abs()));
        let m = self.max_q() as f32;
        let e = (0..16u32).find(|&e| (max / exp2i(e as i32 - self.bias)).round() <= m).unwrap_or(15);
        let scale = exp2i(e as i32 - self.bias);
        (e, v.map(|x| (x / scale).round().clamp(-m, m) as i32))
    }

    /// The two's-complement field of q.
    fn field(self, q: i32) -> u64 {
        (q as u32 & ((1 << self.bits) - 1)) as u64
    }

    /// q of a field; None for the one code past the range (−2^(bits−1)).
    fn q(self, field: u64) -> Option<i32> {
        let shift = 32 - self.bits;
        let q = ((field as u32) << shift) as i32 >> shift;
        (q >= -self.max_q()).then_some(q)
    }
}

/// A view tilt's six values snapped to the compact grid: (e_B, q_b), (e_c, q_c).
fn tilt_encode(b: [f32; 4], c: [f32; 2]) -> CompactViewTilt {
    let ((eb, qb), (ec, qc)) = (TILT_B.encode(b), TILT_C.encode(c));
    let mut w = eb as u64 | (ec as u64) << 32;
    for (k, q) in qb.iter().enumerate() {
        w |= TILT_B.field(*q) << (4 + 7 * k);
    }
    for (k, q) in qc.iter().enumerate() {
        w |= TILT_C.field(*q) << (36 + 6 * k);
    }
    let bytes = w.to_le_bytes();
    CompactViewTilt { v: [bytes[0], bytes[1], bytes[2], bytes[3], bytes[4], bytes[5]] }
}

/// b and c of a compact tilt; None where a field holds the code past its range.
fn tilt_decode(t: &CompactViewTilt) -> Option<([f32; 4], [f32; 2])> {
    let mut bytes = [0u8; 8];
    bytes[..6].copy_from_slice(&t.v);
    let w = u64::from_le_bytes(bytes);
    let (eb, ec) = ((w & 15) as u32, ((w >> 32) & 15) as u32);
    let mut b = [0f32; 4];
    for (k, v) in b.iter_mut().enumerate() {
        *v = TILT_B.decode(eb, TILT_B.q((w >> (4 + 7 * k)) & 127)?);
    }
    let mut c = [0f32; 2];
    for (k, v) in c.iter_mut().enumerate() {
        *v = TILT_C.decode(ec, TILT_C.q((w >> (36 + 6 * k)) & 63)?);
    }
    Some((b, c))
}

fn wide_tilt(b: [f32; 4], c: [f32; 2]) -> PackedViewTilt {
    PackedViewTilt { b: b.map(f16_bits), c: c.map(f16_bits) }
}

/// η = 1 + 3·q/4095 for the 12-bit q.
fn eta_decode(q: u16) -> f32 {
    1.0 + 3.0 * (q & 4095) as f32 / 4095.0
}

fn eta_encode(eta: f32) -> u16 {
    if eta.is_nan() { 0 } else { ((eta - 1.0) * (4095.0 / 3.0)).round().clamp(0.0, 4095.0) as u16 }
}

/// An octahedral snorm16 coordinate on the 11-bit grid: q ∈ [−1023, 1023].
fn oct11_of(code: u16) -> i32 {
    ((code as i16 as f32) * (1023.0 / 32767.0)).round().clamp(-1023.0, 1023.0) as i32
}

/// The snorm16 code of the 11-bit coordinate q.
fn oct11_code(q: i32) -> u16 {
    (((q as f32) * (32767.0 / 1023.0)).round() as i16) as u16
}

/// The compact header of `h` whose lobes start at `offset`, if it holds `h` exactly.
fn texel_exact(h: &BrdfHeader, offset: u32) -> Option<CompactTexel> {
    let count = h.lobe_count as usize;
    if h.lobe_offset != offset || h.reserved != 0 || !(1..=MAX_LOBES).contains(&count) {
        return None;
    }
    let kd = rgb9e5_exact(h.kd)?;
    let q = eta_encode(f16_value(h.eta));
    (f16_bits(eta_decode(q)) == h.eta).then_some(CompactTexel { kd, a: h.a, eta_count: q | ((count as u16 - 1) << 12) })
}

/// The compact lobe of `l`, if it holds `l` exactly.
fn lobe_exact(l: &PackedLobe) -> Option<CompactLobe> {
    let [u, v] = l.normal.map(oct11_of);
    if l.normal != [oct11_code(u), oct11_code(v)] || l.tangent_angle % 64 != 0 {
        return None;
    }
    let k = rgb9e5_exact(l.k)?;
    let frame = (u + 1023) as u32 | ((v + 1023) as u32) << 11 | ((l.tangent_angle / 64) as u32) << 22;
    Some(CompactLobe { frame, k, beta_gamma: l.beta as u32 | (l.gamma as u32) << 16 })
}

/// A per-texel table's headers as compact texels, if every one is representable (its
/// lobes in order, without gaps: the offsets are the running sum of the counts).
pub fn compact_texels(table: &BrdfTable) -> Option<Vec<CompactTexel>> {
    let mut offset = 0u32;
    table
        .headers
        .iter()
        .map(|h| {
            let t = texel_exact(h, offset)?;
            offset = offset.checked_add(h.lobe_count as u32)?;
            Some(t)
        })
        .collect::<Option<Vec<_>>>()
        .filter(|_| offset as usize == table.lobes.len())
}

/// A table's lobes as compact lobes, if every one is representable.
pub fn compact_lobes(lobes: &[PackedLobe]) -> Option<Vec<CompactLobe>> {
    lobes.iter().map(lobe_exact).collect()
}

/// View tilts as compact records, if every one is representable.
pub fn compact_view_tilts(tilts: &[PackedViewTilt]) -> Option<Vec<CompactViewTilt>> {
    tilts
        .iter()
        .map(|t| {
            let c = tilt_encode(t.b.map(f16_value), t.c.map(f16_value));
            let (b, cc) = tilt_decode(&c)?;
            (wide_tilt(b, cc) == *t).then_some(c)
        })
        .collect()
}

/// Spread records as compact ones (always, unless a reserved field is set).
pub fn compact_spreads(spreads: &[PackedAxisSpread]) -> Option<Vec<CompactAxisSpread>> {
    spreads
        .iter()
        .map(|s| {
            let r = s.roll.to_le_bytes();
            (s.reserved == 0).then_some(CompactAxisSpread { v: [r[0], r[1], s.lambda[0], s.lambda[1], s.slab[0], s.slab[1]] })
        })
        .collect()
}

/// The wide spread records of compact ones (validated with the model: λ₂ + λ₃ ≤ 1, z₀ ≤ z₁).
pub fn expand_spreads(spreads: &[CompactAxisSpread]) -> Vec<PackedAxisSpread> {
    spreads.iter().map(|c| PackedAxisSpread { roll: u16::from_le_bytes([c.v[0], c.v[1]]), lambda: [c.v[2], c.v[3]], slab: [c.v[4], c.v[5]], reserved: 0 }).collect()
}

/// A level's nodes as compact ones, if every list is stored column by column in texel
/// order (as [`Flyaways::from_columns`] builds them) and every field fits: depth < 4096,
/// BRDF index < 16384, the axis on the 11-bit octahedral grid.
pub fn compact_flyaway_nodes(f: &Flyaways) -> Option<Vec<CompactFlyawayNode>> {
    let mut expected = 0usize;
    for &head in f.heads.iter().filter(|&&h| h != NO_NODE) {
        if head as usize != expected {
            return None;
        }
        let mut k = expected;
        loop {
            let next = f.nodes.get(k)?.next;
            k += 1;
            if next == NO_NODE {
                break;
            }
            if next as usize != k {
                return None;
            }
        }
        expected = k;
    }
    if expected != f.nodes.len() {
        return None;
    }
    f.nodes
        .iter()
        .map(|n| {
            let [u, v] = n.tangent.map(oct11_of);
            if n.depth >= 4096 || n.param >= 16384 || n.tangent != [oct11_code(u), oct11_code(v)] {
                return None;
            }
            let w = n.depth as u64 | (n.alpha as u64) << 12 | ((u + 1023) as u64) << 28 | ((v + 1023) as u64) << 39 | (n.param as u64) << 50;
            Some(CompactFlyawayNode { w: [w as u32, (w >> 32) as u32] })
        })
        .collect()
}

/// The wide nodes of compact ones, their links rebuilt from the level's list heads.
pub fn expand_flyaway_nodes(heads: &[u32], nodes: &[CompactFlyawayNode]) -> Result<Vec<FlyawayNode>, CompactError> {
    let mut out: Vec<FlyawayNode> = Vec::with_capacity(nodes.len());
    for (record, c) in nodes.iter().enumerate() {
        let w = c.w[0] as u64 | (c.w[1] as u64) << 32;
        let (u, v) = (((w >> 28) & 2047) as i32, ((w >> 39) & 2047) as i32);
        if u == 2047 || v == 2047 {
            return Err(CompactError { record, why: "octahedral coordinate 2047 is outside the grid (0..=2046)".into() });
        }
        out.push(FlyawayNode { next: NO_NODE, depth: (w & 4095) as u16, alpha: ((w >> 12) & 0xffff) as u16, tangent: [oct11_code(u - 1023), oct11_code(v - 1023)], param: (w >> 50) as u32 });
    }
    let starts: Vec<(usize, u32)> = heads.iter().copied().enumerate().filter(|&(_, h)| h != NO_NODE).collect();
    for (k, &(texel, head)) in starts.iter().enumerate() {
        let end = starts.get(k + 1).map_or(nodes.len() as u64, |&(_, h)| h as u64);
        let expected = if k == 0 { 0 } else { starts[k - 1].1 as u64 + 1 };
        if (head as u64) < expected || head as u64 >= end || end > nodes.len() as u64 {
            let why = if k == 0 && head != 0 { format!("texel {texel}'s list starts at node {head}; the first list must start at node 0") } else { format!("texel {texel}'s list head {head}: heads must rise in texel order, within the {} nodes", nodes.len()) };
            return Err(CompactError { record: head as usize, why });
        }
        for node in head as usize..end as usize - 1 {
            out[node].next = node as u32 + 1;
        }
    }
    if starts.is_empty() && !nodes.is_empty() {
        return Err(CompactError { record: 0, why: "nodes without any list head".into() });
    }
    Ok(out)
}

/// Snaps a level's fibre axes to the 11-bit octahedral grid (≤ 3·10⁻³ rad), so that
/// [`compact_flyaway_nodes`] holds lists built by [`Flyaways::from_columns`].
pub fn quantize_flyaway_nodes(f: &mut Flyaways) {
    for n in &mut f.nodes {
        n.tangent = n.tangent.map(|c| oct11_code(oct11_of(c)));
    }
}

/// What a compact record holds that no wide record can: where it is and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CompactError {
    pub record: usize,
    pub why: String,
}

/// The wide headers of compact texels (lobe offsets: the running sum of the counts).
pub fn expand_texels(texels: &[CompactTexel]) -> Result<Vec<BrdfHeader>, CompactError> {
    let mut offset = 0u32;
    texels
        .iter()
        .enumerate()
        .map(|(record, t)| {
            if t.eta_count & 0x8000 != 0 {
                return Err(CompactError { record, why: "reserved bit 15 of eta_count is set".into() });
            }
            let count = ((t.eta_count >> 12) & 7) as u8 + 1;
            let h = BrdfHeader { kd: rgb9e5_decode(t.kd).map(f16_bits), eta: f16_bits(eta_decode(t.eta_count)), a: t.a, lobe_count: count, reserved: 0, lobe_offset: offset };
            // At most 8 lobes per texel and fewer than 2³² texels per section: a u32 holds it,
            // but a hostile length is cheaper to refuse than to reason about.
            offset = offset.checked_add(count as u32).ok_or_else(|| CompactError { record, why: "lobe offsets overflow".into() })?;
            Ok(h)
        })
        .collect()
}

/// The wide lobes of compact ones.
pub fn expand_lobes(lobes: &[CompactLobe]) -> Result<Vec<PackedLobe>, CompactError> {
    lobes
        .iter()
        .enumerate()
        .map(|(record, l)| {
            let (u, v) = ((l.frame & 2047) as i32, ((l.frame >> 11) & 2047) as i32);
            if u == 2047 || v == 2047 {
                return Err(CompactError { record, why: "octahedral coordinate 2047 is outside the grid (0..=2046)".into() });
            }
            let angle = ((l.frame >> 22) as u16) * 64;
            Ok(PackedLobe { normal: [oct11_code(u - 1023), oct11_code(v - 1023)], tangent_angle: angle, k: rgb9e5_decode(l.k).map(f16_bits), beta: l.beta_gamma as u16, gamma: (l.beta_gamma >> 16) as u16 })
        })
        .collect()
}

/// The wide view tilts of compact ones.
pub fn expand_view_tilts(tilts: &[CompactViewTilt]) -> Result<Vec<PackedViewTilt>, CompactError> {
    tilts
        .iter()
        .enumerate()
        .map(|(record, t)| {
            let (b, c) = tilt_decode(t).ok_or_else(|| CompactError { record, why: "an integer field holds the code past its range (−2^(bits−1))".into() })?;
            Ok(wide_tilt(b, c))
        })
        .collect()
}

/// Snaps a per-texel table to the compact grid (k_d and k to RGB9E5, η to 12 bits, the
/// frames to 11-bit octahedral normals and 10-bit tangent angles, the tangent turned
/// with its normal as little as it can be) and lays its lobes out in order, so that
/// [`compact_texels`] and [`compact_lobes`] hold it. β, γ and a keep their f16 bits.
pub fn quantize_table(table: &mut BrdfTable) {
    let mut lobes = Vec::with_capacity(table.lobes.len());
    for h in &mut table.headers {
        let range = h.lobe_range();
        let offset = lobes.len() as u32;
        for l in &table.lobes[range] {
            let t = l.frame().t;
            let normal = l.normal.map(|c| oct11_code(oct11_of(c)));
            let angle = tangent_angle_encode(octahedral_decode(normal), t);
            // Tangents are axes: ψ = π is ψ = 0.
            let angle = ((angle as u32 + 32) / 64 % 1024 * 64) as u16;
            lobes.push(PackedLobe { normal, tangent_angle: angle, k: rgb9e5_snap(l.k), ..*l });
        }
        h.kd = rgb9e5_snap(h.kd);
        h.eta = f16_bits(eta_decode(eta_encode(f16_value(h.eta))));
        h.lobe_offset = offset;
    }
    table.lobes = lobes;
}

/// Snaps view tilts to the compact grid: B's four values share one exponent and keep
/// 7-bit integers (error ≤ 1/63 of the largest |b| + 2⁻¹³), c's two share one and keep
/// 6 bits (≤ 1/31 of the largest |c| + 2⁻¹²).
pub fn quantize_view_tilts(tilts: &mut [PackedViewTilt]) {
    for t in tilts {
        let compact = tilt_encode(t.b.map(f16_value), t.c.map(f16_value));
        if let Some((b, c)) = tilt_decode(&compact) {
            *t = wide_tilt(b, c);
        }
    }
}

/// Bytes a per-texel table takes in the file (compact where the writer can store it so).
pub fn per_texel_table_bytes(table: &BrdfTable) -> u64 {
    let headers = if compact_texels(table).is_some() { size_of::<CompactTexel>() } else { size_of::<BrdfHeader>() };
    let lobes = if compact_lobes(&table.lobes).is_some() { size_of::<CompactLobe>() } else { size_of::<PackedLobe>() };
    (table.headers.len() * headers + table.lobes.len() * lobes) as u64
}

/// Bytes view tilts take in the file.
pub fn view_tilt_bytes(tilts: &[PackedViewTilt]) -> u64 {
    let each = if compact_view_tilts(tilts).is_some() { size_of::<CompactViewTilt>() } else { size_of::<PackedViewTilt>() };
    (tilts.len() * each) as u64
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::brdf::ClothLobe;

    #[test]
    fn every_rgb9e5_value_is_an_f16_and_encodes_back_to_itself() {
        for e in 0..32u32 {
            for m in [0u32, 1, 2, 255, 256, 511] {
                let code = m | (m / 2) << 9 | (511 - m) << 18 | e << 27;
                let v = rgb9e5_decode(code);
                assert_eq!(v.map(|x| f16_value(f16_bits(x))), v, "code {code:#x}");
                assert_eq!(rgb9e5_decode(rgb9e5_exact(v.map(f16_bits)).unwrap()), v);
            }
        }
    }

    #[test]
    fn snapping_errors_are_within_the_stated_bounds() {
        let (mut rgb, mut tb, mut tc) = (0f32, 0f32, 0f32);
        for k in 0..20_000 {
            let x = (k as f32 * 0.618_034).fract();
            let v = [3.0 * x, 0.7 * (1.0 - x), 0.05 + x * x];
            let back = rgb9e5_decode(rgb9e5_encode(v));
            let max = v.iter().fold(0f32, |a, &b| a.max(b));
            rgb = rgb.max(v.iter().zip(back).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max) / max);
            let s = 8.0 * x.powi(1 + k % 9);
            let b = [s, -0.3 * s, 0.01 * s, -s * x];
            let c = [0.9 * s - 0.1, x - 0.5];
            let mut t = [wide_tilt(b, c)];
            let orig = t[0];
            quantize_view_tilts(&mut t);
            // Error over the bound max/(2^(bits−1) − 1) + half the finest step.
            let err = |a: &[u16], q: &[u16], g: SharedExponent| {
                let max = a.iter().fold(0f32, |m, &v| m.max(f16_value(v).abs()));
                let bound = max / g.max_q() as f32 + 0.5 * exp2i(-g.bias);
                a.iter().zip(q).map(|(&a, &q)| (f16_value(a) - f16_value(q)).abs()).fold(0f32, f32::max) / bound
            };
            tb = tb.max(err(&orig.b, &t[0].b, TILT_B));
            tc = tc.max(err(&orig.c, &t[0].c, TILT_C));
            assert_eq!(compact_view_tilts(&t).map(|c| expand_view_tilts(&c).unwrap()), Some(t.to_vec()));
        }
        assert!(rgb <= 1.0 / 512.0 + 1e-6, "RGB9E5 error {rgb} of the largest channel");
        assert!(tb <= 1.0 + 1e-4 && tc <= 1.0 + 1e-4, "tilt errors {tb} (B) and {tc} (c) of their bounds");
        assert_eq!(rgb9e5_encode([f32::NAN, -1.0, f32::INFINITY]), 0);
        assert_eq!(rgb9e5_decode(rgb9e5_encode([1e9, 0.0, 0.0]))[0], RGB9E5_MAX);
        let mut nan = [wide_tilt([f32::NAN, 100.0, 0.0, -0.0], [f32::INFINITY, 0.5])];
        quantize_view_tilts(&mut nan);
        assert_eq!(nan[0].decode().b, [0.0, 8.0, 0.0, 0.0]);
        assert_eq!(nan[0].decode().c, [0.0, 0.5]);
    }

    fn table() -> BrdfTable {
        let mut t = BrdfTable::new();
        for k in 0..50 {
            let s = k as f32 * 0.37;
            let n = Vec3::new(s.sin() * 0.6, (1.3 * s).cos() * 0.5, 1.0).normalize();
            let t0 = Vec3::new(1.0, 0.2 * s.cos(), 0.0);
            let tan = (t0 - n * n.dot(t0)).normalize();
            let lobes: Vec<(ClothLobe, Vec3, Vec3)> = (0..1 + k % 3).map(|j| (ClothLobe { k: Vec3::new(0.3 + 0.1 * j as f32, 0.2, 0.11 * s.cos().abs()), beta: 0.05 + 0.1 * j as f32, gamma: if j == 1 { 0.0 } else { 0.4 } }, n, tan)).collect();
            t.push_framed(Vec3::new(0.05, 0.1 * s.sin().abs(), 0.02), 1.2 + 0.03 * k as f32, 0.5 * k as f32, &lobes);
        }
        t
    }

    #[test]
    fn a_quantized_table_is_stored_compactly_and_expands_bit_for_bit() {
        let wide = table();
        assert!(compact_texels(&wide).is_none() && compact_lobes(&wide.lobes).is_none(), "f16 fits are not on the grid");
        let mut q = wide.clone();
        quantize_table(&mut q);
        let texels = compact_texels(&q).expect("quantized headers are compact");
        let lobes = compact_lobes(&q.lobes).expect("quantized lobes are compact");
        assert_eq!(expand_texels(&texels).unwrap(), q.headers);
        assert_eq!(expand_lobes(&lobes).unwrap(), q.lobes);
        assert_eq!(per_texel_table_bytes(&q), (8 * q.headers.len() + 12 * q.lobes.len()) as u64);
        assert_eq!(per_texel_table_bytes(&wide), (16 * q.headers.len() + 16 * q.lobes.len()) as u64);
        // Quantizing twice changes nothing.
        let mut again = q.clone();
        quantize_table(&mut again);
        assert_eq!(again, q);
        // What snapping moved: the normal < 3e-3 rad, the tangent < 5e-3 rad (half a
        // 10-bit angle step and the normal's turn), η by < 1.5e-3 (its step and f16's).
        for (h, hq) in wide.headers.iter().zip(&q.headers) {
            assert!((h.eta() - hq.eta()).abs() < 1.5e-3);
            for (a, b) in wide.lobes[h.lobe_range()].iter().zip(&q.lobes[hq.lobe_range()]) {
                let (fa, fb) = (a.frame(), b.frame());
                assert!(fa.n.angle_between(fb.n) < 3e-3, "normal moved {}", fa.n.angle_between(fb.n));
                assert!(fa.t.dot(fb.t).abs().min(1.0).acos() < 5e-3, "tangent moved");
                assert!((a.lobe().k - b.lobe().k).abs().max_element() <= a.lobe().k.max_element() / 512.0 + 1e-6);
                assert_eq!((a.beta, a.gamma), (b.beta, b.gamma));
            }
        }
        // A gap in the lobes, or a stray lobe at the end, is not the running sum.
        let mut gap = q.clone();
        gap.lobes.push(gap.lobes[0]);
        assert!(compact_texels(&gap).is_none());
    }

    #[test]
    fn snapped_flyaway_lists_are_compact_and_their_links_come_back() {
        use crate::hybrid::FlyawayInput;
        let mut table = BrdfTable::new();
        table.push(&crate::brdf::ClothParams::new(Vec3::splat(0.1), 1.5, 0.0, &[ClothLobe { k: Vec3::ONE, beta: 0.2, gamma: 0.0 }]));
        let column = |i: u32, j: u32| (0..(i * 3 + j) % 4).map(|k| FlyawayInput { depth: (k * 3 + i) as u16, alpha: 0.1 + 0.2 * k as f32, tangent: Vec3::new(0.3 + i as f32, 0.7, j as f32 - 0.5), param: 0 }).collect();
        let wide = Flyaways::from_columns(5, 3, table, column).unwrap();
        assert!(compact_flyaway_nodes(&wide).is_none(), "16-bit axes are off the grid");
        let mut f = wide.clone();
        quantize_flyaway_nodes(&mut f);
        for (a, b) in wide.nodes.iter().zip(&f.nodes) {
            assert!(a.tangent().angle_between(b.tangent()) < 3e-3);
        }
        let c = compact_flyaway_nodes(&f).expect("snapped lists are compact");
        assert_eq!(expand_flyaway_nodes(&f.heads, &c).unwrap(), f.nodes);
        // Lists out of texel order are not compact; heads that do not rise are refused.
        let mut swapped = f.clone();
        let (a, b) = (swapped.heads.iter().position(|&h| h != NO_NODE).unwrap(), swapped.heads.iter().rposition(|&h| h != NO_NODE).unwrap());
        swapped.heads.swap(a, b);
        assert!(compact_flyaway_nodes(&swapped).is_none());
        assert!(expand_flyaway_nodes(&swapped.heads, &c).is_err());
        let mut past = f.heads.clone();
        *past.iter_mut().rev().find(|h| **h != NO_NODE).unwrap() = c.len() as u32;
        assert!(expand_flyaway_nodes(&past, &c).is_err());
        assert!(expand_flyaway_nodes(&vec![NO_NODE; 15], &c).is_err());
    }

    #[test]
    fn quantized_view_tilts_are_compact_and_malformed_compact_records_are_named() {
        let mut tilts: Vec<PackedViewTilt> = (0..40).map(|k| PackedViewTilt::new(&crate::brdf::visible_normal::ViewTilt { b: [0.011 * k as f32, -0.04, 0.3 / (1 + k) as f32, -7.9], c: [1.7, -0.002 * k as f32] })).collect();
        assert!(compact_view_tilts(&tilts).is_none());
        quantize_view_tilts(&mut tilts);
        let c = compact_view_tilts(&tilts).expect("quantized tilts are compact");
        assert_eq!(expand_view_tilts(&c).unwrap(), tilts);
        assert_eq!(view_tilt_bytes(&tilts), 6 * 40);
        let bad = CompactLobe { frame: 2047, ..Default::default() };
        assert_eq!(expand_lobes(&[CompactLobe::default(), bad]).unwrap_err().record, 1);
        let bad = CompactTexel { eta_count: 0x8000, ..Default::default() };
        assert_eq!(expand_texels(&[bad]).unwrap_err().record, 0);
        // q = −64 in b00's field (bits 4–10).
        let bad = CompactViewTilt { v: [0x00, 0x04, 0, 0, 0, 0] };
        assert_eq!(expand_view_tilts(&[CompactViewTilt::default(), bad]).unwrap_err().record, 1);
    }
}
