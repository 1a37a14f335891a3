//! The cloth BRDF of the hybrid model (paper Eqs. 1–3, read as docs/DESIGN.md §5):
//! the Rust twin of `shaders/brdf.glsl`.
//!
//! The two files have the same functions, with the same names, in the same order, and
//! the same arithmetic, so that a port of one is a port of the other; the twin test runs
//! the GLSL on lavapipe against this file and `shaders/brdf_test_vectors.json` pins
//! both for engine teams. Change one, change the other.
//!
//! # Frame and angles
//! A lobe lives in a shading frame (n, t, b = n × t): n the normal, t the fiber tangent
//! (an axis: t ≡ −t gives the same BRDF value only up to θ ↦ −θ, which the lobes are
//! even in), both in the same space as the directions (tile space: x, y along the tile,
//! z up, out of the cloth). For a unit direction ω:
//! - θ ∈ [−π/2, π/2] is the angle from ω to the normal plane: sin θ = ω·t;
//! - φ ∈ (−π, π] is the signed angle of ω's projection in the normal plane, from n:
//!   φ = atan2(ω·b, ω·n). Along t the projection vanishes; we define φ = 0 there.
//!
//! Mirror reflection about the normal plane has θ_o = −θ_i, so the lobes peak at
//! θ_i + θ_o = 0; they fall off with φ_i + φ_o.
//!
//! # The BRDF (DESIGN.md §5, our bounded reading of Eqs. 1–3)
//! ```text
//! f_r = k_d + F(η, cos θ_d) · max(cos φ_i, 0)^a · Σ_j k_j · S_j(θ_i + θ_o, φ_i + φ_o)
//! G(x; β) = exp(−x² / (2β²)) / (√(2π) β)          β clamped to [BETA_MIN, BETA_MAX]
//! P(x; γ) = exp(−x² / (2γ²)),  P ≡ 1 for γ ≤ 0    γ > 0 clamped to [GAMMA_MIN, GAMMA_MAX]
//! S_j = G(θ_i+θ_o; β_j) · P(φ_i+φ_o; γ_j)          BrdfReading::Bounded (default)
//! S_j = G(θ_i+θ_o; max(β_j · P(φ_i+φ_o; γ_j), BETA_MIN))   BrdfReading::Width
//! S_j = G(θ_i+θ_o; w_j) · w_j / max(w_j, β_j / HELD_RISE),
//!       w_j = max(β_j · P(φ_i+φ_o; γ_j), BETA_MIN)                         BrdfReading::Held
//! ```
//! - Eq. 2 printed has no β_j and a width that shrinks without bound; the bounded
//!   reading keeps the intent (a Gaussian in θ_i + θ_o whose strength falls off with
//!   φ_i + φ_o). The "width" reading is the printed one with β_j put back and a floor.
//!   The "held" reading (format 1.14) narrows the Gaussian as the width reading does but
//!   holds its height: S_j ≤ HELD_RISE · G(0; β_j) everywhere, where the width reading's
//!   peak grows as 1/P up to 1/(√(2π)·BETA_MIN) — a needle of up to 400 k_j off the
//!   azimuth the lobe faces, which the fits never see and other views do
//!   (baker/FIT_MEASUREMENTS.md, "The held reading"). Where P ≥ 1/HELD_RISE the two
//!   are the same.
//!   All three are here and only here; a model file records which one it was fitted
//!   with.
//! - F is the unpolarized dielectric Fresnel reflectance with relative index η, fed with
//!   cos θ_d, θ_d = (θ_o − θ_i)/2 as in fiber models ([`cloth_fresnel_cos`], the one
//!   place where the choice is made). At the specular peak θ_o = −θ_i this equals the
//!   printed F(η, θ_i).
//! - max(cos φ_i, 0)^a is the shadowing term of Sadeghi et al.; 0⁰ = 1 (a = 0 switches
//!   it off everywhere, including at cos φ_i = 0).
//! - k_d and k_j are linear RGB; k_d carries no 1/π. G is normalized over x ∈ ℝ.
//!
//! # Units and ranges
//! Angles in radians. Parameters are clamped into their ranges before use, so any
//! finite input gives a finite, non-negative result: k_d, k_j ∈ [0, K_MAX];
//! η ∈ [1, ETA_MAX]; a ∈ [0, A_MAX]; β ∈ [BETA_MIN, BETA_MAX]; γ ≤ 0 means "off"
//! (γ = ∞), else γ ∈ [GAMMA_MIN, GAMMA_MAX]. Degenerate frames (zero vectors, n ∥ t)
//! are completed deterministically ([`cloth_frame`]). In Rust a NaN parameter is also
//! absorbed by the clamps (`f32::max` drops NaN); GLSL makes no such promise, so GPU
//! inputs must be finite (the model reader guarantees it).
//!
//! # What a renderer outputs
//! Radiance toward ω_o under a light of irradiance E (perpendicular to the beam) from
//! ω_i is `E · f_r · max(n·ω_i, 0)` (DESIGN.md §5, "fit radiance, not ratios");
//! [`cloth_lobe`] gives one lobe in its own frame for texels whose lobes have
//! different frames (coarse levels).

// `x.max(lo).min(hi)` rather than `clamp`: it absorbs NaN (f32::max drops it) and reads
// as the GLSL `min(max(x, lo), hi)`; `!(x > 0.0)` is the NaN-aware test, as in the GLSL.
#![allow(clippy::manual_clamp, clippy::neg_cmp_op_on_partial_ord)]

pub mod axis_spread;
pub mod twin;
pub mod visible_normal;

use glam::Vec3;

/// Most lobes a BRDF may have (paper §5.3.5).
pub const MAX_LOBES: usize = 8;
/// Narrowest lobe width β (radians); also the floor of the width reading.
pub const BETA_MIN: f32 = 1e-3;
/// Widest lobe width β (radians); wider is flat anyway.
pub const BETA_MAX: f32 = 1e4;
/// How far the held reading lets a lobe rise above its peak G(0; β) as P narrows it:
/// at most this factor (the width reading: up to β / BETA_MIN).
pub const HELD_RISE: f32 = 4.0;
/// Narrowest φ falloff γ (radians) when it is on.
pub const GAMMA_MIN: f32 = 1e-3;
/// Widest φ falloff γ (radians).
pub const GAMMA_MAX: f32 = 1e4;
/// Largest k_d or k_j (the largest finite IEEE half, what the file can hold).
pub const K_MAX: f32 = 65504.0;
/// Largest index of refraction η.
pub const ETA_MAX: f32 = 4.0;
/// Largest shadowing exponent a.
pub const A_MAX: f32 = 1e4;
/// Below this squared length a vector counts as zero.
const EPS_LEN2: f32 = 1e-20;
/// t is taken as parallel to n when its component perpendicular to n is shorter than
/// 1e-4 (squared: 1e-8) of its length.
const EPS_PERP2: f32 = 1e-8;
/// Below this squared length the projection of ω on the normal plane is zero (ω ∥ t).
const EPS_PROJ2: f32 = 1e-12;
/// 1/√(2π).
const INV_SQRT_2PI: f32 = 0.398_942_3;

/// Which reading of the printed Eqs. 2–3 a model uses (DESIGN.md §5). The value is what
/// the file and the GLSL (`CLOTH_READING_*`) store.
#[repr(u32)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum BrdfReading {
    /// S = G(θ_i+θ_o; β) · P(φ_i+φ_o; γ): bounded (the default).
    #[default]
    Bounded = 0,
    /// S = G(θ_i+θ_o; max(β·P(φ_i+φ_o; γ), BETA_MIN)): the printed width, with β and a floor.
    Width = 1,
    /// S = G(θ_i+θ_o; w) · w / max(w, β/HELD_RISE), w = max(β·P(φ_i+φ_o; γ), BETA_MIN):
    /// the width narrowed as printed, the height held to at most HELD_RISE times the
    /// lobe's peak (format 1.14).
    Held = 2,
}

impl BrdfReading {
    pub fn from_u32(v: u32) -> Option<BrdfReading> {
        match v {
            0 => Some(BrdfReading::Bounded),
            1 => Some(BrdfReading::Width),
            2 => Some(BrdfReading::Held),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            BrdfReading::Bounded => "bounded",
            BrdfReading::Width => "width",
            BrdfReading::Held => "held",
        }
    }
}

/// How a flyaway fibre's lobes fall with the azimuth about its axis (format 1.11, MODEL
/// flag bit 4; [`cloth_cylinder_lobe`]). The value is what the GLSL (`CLOTH_FIBER_*`)
/// passes.
#[repr(u32)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum FiberLobes {
    /// Each lobe as on a surface whose normal faces the viewer (n = ω_o made
    /// perpendicular to the axis): [`cloth_lobe`] · max(n·ω_i, 0), dark once the light is
    /// more than 90° of azimuth from the viewer (files before 1.11).
    #[default]
    Facing = 0,
    /// Each lobe as on a cylinder ([`cloth_cylinder_lobe`]): lit and seen at every
    /// azimuth but straight behind the fibre.
    Cylinder = 1,
}

/// How a texel's diffuse term k_d falls with the directions (format 1.6, MODEL flag
/// bit 3; [`cloth_diffuse_cosine`]). The value is what the GLSL (`CLOTH_DIFFUSE_*`)
/// passes.
#[repr(u32)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum DiffuseLaw {
    /// k_d · max(n·ω_i, 0): Lambert's cosine, Eq. 1 as printed (the default of a file).
    #[default]
    Lambert = 0,
    /// k_d · max(n·ω_i, 0) · 2 / (μ_i + μ_o), μ = max(ω·ẑ, 0) the cosines to the tile's
    /// normal: the single scattering of a half-space medium (Lommel–Seeliger), 1 at
    /// normal incidence and view.
    LommelSeeliger = 1,
}

impl FiberLobes {
    pub fn name(self) -> &'static str {
        match self {
            FiberLobes::Facing => "facing",
            FiberLobes::Cylinder => "cylinder",
        }
    }
}

impl DiffuseLaw {
    pub fn name(self) -> &'static str {
        match self {
            DiffuseLaw::Lambert => "lambert",
            DiffuseLaw::LommelSeeliger => "lommel-seeliger",
        }
    }
}

/// One specular lobe: RGB strength k, θ width β (radians), φ falloff γ (radians;
/// γ ≤ 0 switches the falloff off, i.e. γ = ∞).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ClothLobe {
    pub k: Vec3,
    pub beta: f32,
    pub gamma: f32,
}

impl ClothLobe {
    /// The γ that switches the φ falloff off (γ = ∞).
    pub const GAMMA_OFF: f32 = 0.0;
}

/// The parameters of Eq. 1 for lobes that share one frame: diffuse k_d (RGB, no 1/π),
/// Fresnel index η, shadowing exponent a and up to [`MAX_LOBES`] lobes (the first
/// `lobe_count` are used).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ClothParams {
    pub kd: Vec3,
    pub eta: f32,
    pub a: f32,
    pub lobe_count: u32,
    pub lobes: [ClothLobe; MAX_LOBES],
}

impl ClothParams {
    /// Parameters with the given lobes (at most [`MAX_LOBES`]; extra ones are dropped).
    pub fn new(kd: Vec3, eta: f32, a: f32, lobes: &[ClothLobe]) -> ClothParams {
        let mut p = ClothParams { kd, eta, a, lobe_count: lobes.len().min(MAX_LOBES) as u32, lobes: [ClothLobe::default(); MAX_LOBES] };
        p.lobes[..p.lobe_count as usize].copy_from_slice(&lobes[..p.lobe_count as usize]);
        p
    }

    /// The lobes in use.
    pub fn lobes(&self) -> &[ClothLobe] {
        &self.lobes[..(self.lobe_count as usize).min(MAX_LOBES)]
    }
}

/// An orthonormal shading frame: normal n, tangent t, b = n × t.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClothFrame {
    pub n: Vec3,
    pub t: Vec3,
    pub b: Vec3,
}

/// The angles of one direction in a frame (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClothAngles {
    pub sin_theta: f32,
    pub cos_theta: f32,
    pub theta: f32,
    pub phi: f32,
    pub cos_phi: f32,
}

/// A unit tangent perpendicular to unit `n` (Duff et al. 2017, "Building an orthonormal
/// basis, revisited"): the deterministic completion of a degenerate frame, and the
/// reference direction from which packed tangents measure their angle.
#[inline]
pub fn cloth_reference_tangent(n: Vec3) -> Vec3 {
    let s = if n.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    Vec3::new(1.0 + s * n.x * n.x * a, s * b, -s * n.x)
}

/// The orthonormal frame of normal `n` and tangent `t` (neither need be unit). t is
/// made perpendicular to n (Gram–Schmidt, twice). Fallbacks, in order: n ≈ 0 → n = +Z;
/// t ≈ 0 or t ∥ n → t = [`cloth_reference_tangent`]`(n)`.
#[inline]
pub fn cloth_frame(n: Vec3, t: Vec3) -> ClothFrame {
    let n_len2 = n.dot(n);
    let n = if n_len2 > EPS_LEN2 { n * (1.0 / n_len2.sqrt()) } else { Vec3::Z };
    let t_len2 = t.dot(t);
    let t = if t_len2 > EPS_LEN2 { t * (1.0 / t_len2.sqrt()) } else { Vec3::ZERO };
    let t_perp = t - n * t.dot(n);
    let perp2 = t_perp.dot(t_perp);
    let t = if perp2 > EPS_PERP2 {
        // A second Gram–Schmidt pass: the first leaves n·t ~ ε/sin∠(n, t) when t is
        // nearly parallel to n.
        let t1 = t_perp * (1.0 / perp2.sqrt());
        let t2 = t1 - n * t1.dot(n);
        t2 * (1.0 / t2.dot(t2).sqrt())
    } else {
        cloth_reference_tangent(n)
    };
    ClothFrame { n, t, b: n.cross(t) }
}

/// The frame of a flyaway fiber seen from `wo` (DESIGN.md §5, "the implicit surface
/// derived from the volume"): t = the fiber axis `fiber` (normalized), n = `wo` made
/// perpendicular to t (the fiber seen side-on), b = n × t. Fallbacks: fiber ≈ 0 → +X;
/// wo ∥ t → n = [`cloth_reference_tangent`]`(t)`.
#[inline]
pub fn cloth_fiber_frame(fiber: Vec3, wo: Vec3) -> ClothFrame {
    let f_len2 = fiber.dot(fiber);
    let t = if f_len2 > EPS_LEN2 { fiber * (1.0 / f_len2.sqrt()) } else { Vec3::X };
    let n_raw = wo - t * wo.dot(t);
    let n_len2 = n_raw.dot(n_raw);
    let n = if n_len2 > EPS_PROJ2 { n_raw * (1.0 / n_len2.sqrt()) } else { cloth_reference_tangent(t) };
    ClothFrame { n, t, b: n.cross(t) }
}

/// atan2(y, x) in (−π, π], computed the same way in both twins (Cephes' atanf on
/// min/max of |x|, |y|, relative error ≈ 2e-7): GPUs' built-in inverse trigonometry is an
/// approximation of their own (lavapipe's asin is off by up to 3.9e-4 rad, its atan by
/// 3e-6), which narrow lobes (β ≈ 0.005) amplify a hundredfold. atan2(0, 0) = 0; the
/// sign of a zero y is ignored (atan2(−0, −1) = π).
#[inline]
pub fn cloth_atan2(y: f32, x: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    let (hi, lo) = (ax.max(ay), ax.min(ay));
    let mut r = if hi > 0.0 { lo / hi } else { 0.0 };
    // r ∈ [0, 1]; above tan(π/8) reduce with atan r = π/4 + atan((r − 1)/(r + 1)).
    let mut base = 0.0;
    if r > 0.414_213_57 {
        base = std::f32::consts::FRAC_PI_4;
        r = (r - 1.0) / (r + 1.0);
    }
    let z = r * r;
    let mut a = base + ((((8.053_744_5e-2 * z - 1.387_768_6e-1) * z + 1.997_771_1e-1) * z - 3.333_295e-1) * z * r + r);
    if ay > ax {
        a = std::f32::consts::FRAC_PI_2 - a;
    }
    if x < 0.0 {
        a = std::f32::consts::PI - a;
    }
    if y < 0.0 { -a } else { a }
}

/// θ and φ of direction `w` (unit) in frame `f`.
#[inline]
pub fn cloth_angles(f: &ClothFrame, w: Vec3) -> ClothAngles {
    let sin_theta = w.dot(f.t).clamp(-1.0, 1.0);
    let cos_theta = (1.0 - sin_theta * sin_theta).max(0.0).sqrt();
    // θ = asin(sin θ), through the twins' own arctangent (see cloth_atan2).
    let theta = cloth_atan2(sin_theta, cos_theta);
    let x = w.dot(f.n);
    let y = w.dot(f.b);
    let r2 = x * x + y * y;
    let (phi, cos_phi) = if r2 > EPS_PROJ2 { (cloth_atan2(y, x), x * (1.0 / r2.sqrt())) } else { (0.0, 1.0) };
    ClothAngles { sin_theta, cos_theta, theta, phi, cos_phi }
}

/// Unpolarized dielectric Fresnel reflectance for relative index `eta` at incidence
/// cosine `cos_i` (both clamped into range).
#[inline]
pub fn cloth_fresnel(eta: f32, cos_i: f32) -> f32 {
    let eta = eta.max(1.0).min(ETA_MAX);
    let c = cos_i.max(0.0).min(1.0);
    let sin2_t = (1.0 - c * c) / (eta * eta);
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    let rs = (c - eta * cos_t) / (c + eta * cos_t).max(1e-30);
    let rp = (eta * c - cos_t) / (eta * c + cos_t).max(1e-30);
    0.5 * (rs * rs + rp * rp)
}

/// The cosine that feeds the Fresnel term: cos θ_d, θ_d = (θ_o − θ_i)/2. The one place
/// where this choice is made. cos θ_d = √((1 + cos(θ_o − θ_i))/2) since |θ_d| ≤ π/2.
#[inline]
pub fn cloth_fresnel_cos(wi: &ClothAngles, wo: &ClothAngles) -> f32 {
    let cos_diff = wo.cos_theta * wi.cos_theta + wo.sin_theta * wi.sin_theta;
    (0.5 * (1.0 + cos_diff)).max(0.0).sqrt()
}

/// max(cos φ_i, 0)^a, with 0⁰ = 1.
#[inline]
pub fn cloth_shadowing(cos_phi_i: f32, a: f32) -> f32 {
    let a = a.max(0.0).min(A_MAX);
    if a <= 0.0 {
        return 1.0;
    }
    if cos_phi_i <= 0.0 {
        return 0.0;
    }
    cos_phi_i.min(1.0).powf(a)
}

/// G(x; β) = exp(−x²/(2β²)) / (√(2π) β), β clamped to [BETA_MIN, BETA_MAX].
#[inline]
pub fn cloth_gaussian(x: f32, beta: f32) -> f32 {
    let beta = beta.max(BETA_MIN).min(BETA_MAX);
    (-(x * x) / (2.0 * beta * beta)).exp() * (INV_SQRT_2PI / beta)
}

/// P(x; γ) = exp(−x²/(2γ²)); 1 for γ ≤ 0 (γ = ∞); γ clamped to [GAMMA_MIN, GAMMA_MAX].
#[inline]
pub fn cloth_phi_falloff(x: f32, gamma: f32) -> f32 {
    if !(gamma > 0.0) {
        return 1.0;
    }
    let gamma = gamma.max(GAMMA_MIN).min(GAMMA_MAX);
    (-(x * x) / (2.0 * gamma * gamma)).exp()
}

/// The held reading's height factor for a lobe of width β narrowed to w = max(β·P,
/// BETA_MIN): w / max(w, β/HELD_RISE), so that G(x; w) times it never exceeds
/// HELD_RISE · G(0; β) (1 where the lobe rises less than that).
#[inline]
pub fn cloth_held_height(beta: f32, w: f32) -> f32 {
    w / (beta / HELD_RISE).max(w)
}

/// The shape S_j of one lobe at θ_i + θ_o = `theta_sum`, φ_i + φ_o = `phi_sum`, under
/// any reading (the only place where the readings differ).
#[inline]
pub fn cloth_lobe_shape(theta_sum: f32, phi_sum: f32, beta: f32, gamma: f32, reading: BrdfReading) -> f32 {
    match reading {
        BrdfReading::Bounded => cloth_gaussian(theta_sum, beta) * cloth_phi_falloff(phi_sum, gamma),
        BrdfReading::Width => {
            let beta = beta.max(BETA_MIN).min(BETA_MAX);
            cloth_gaussian(theta_sum, (beta * cloth_phi_falloff(phi_sum, gamma)).max(BETA_MIN))
        }
        BrdfReading::Held => {
            let beta = beta.max(BETA_MIN).min(BETA_MAX);
            let w = (beta * cloth_phi_falloff(phi_sum, gamma)).max(BETA_MIN);
            cloth_gaussian(theta_sum, w) * cloth_held_height(beta, w)
        }
    }
}

/// Σ_j k_j · S_j over the lobes in use (Eq. 2).
#[inline]
pub fn cloth_specular(p: &ClothParams, wi: &ClothAngles, wo: &ClothAngles, reading: BrdfReading) -> Vec3 {
    let theta_sum = wi.theta + wo.theta;
    let phi_sum = wi.phi + wo.phi;
    let mut sum = Vec3::ZERO;
    for lobe in p.lobes() {
        let k = lobe.k.max(Vec3::ZERO).min(Vec3::splat(K_MAX));
        sum += k * cloth_lobe_shape(theta_sum, phi_sum, lobe.beta, lobe.gamma, reading);
    }
    sum
}

/// f_r(ω_i, ω_o) of Eq. 1 for lobes sharing frame `f`; `wi` points toward the light,
/// `wo` toward the viewer, both unit. RGB, finite, ≥ 0.
#[inline]
pub fn cloth_brdf(p: &ClothParams, f: &ClothFrame, wi: Vec3, wo: Vec3, reading: BrdfReading) -> Vec3 {
    let ai = cloth_angles(f, wi);
    let ao = cloth_angles(f, wo);
    let kd = p.kd.max(Vec3::ZERO).min(Vec3::splat(K_MAX));
    let fresnel = cloth_fresnel(p.eta, cloth_fresnel_cos(&ai, &ao));
    kd + cloth_specular(p, &ai, &ao, reading) * (fresnel * cloth_shadowing(ai.cos_phi, p.a))
}

/// One lobe in its own frame `f`, with the Fresnel and shadowing factors of Eq. 1 but
/// without k_d: F · max(cos φ_i, 0)^a · k · S. For texels whose lobes have their own
/// frames (coarse levels); with a shared frame, Σ cloth_lobe + k_d = [`cloth_brdf`].
#[inline]
pub fn cloth_lobe(lobe: &ClothLobe, eta: f32, a: f32, f: &ClothFrame, wi: Vec3, wo: Vec3, reading: BrdfReading) -> Vec3 {
    let ai = cloth_angles(f, wi);
    let ao = cloth_angles(f, wo);
    let fresnel = cloth_fresnel(eta, cloth_fresnel_cos(&ai, &ao));
    let k = lobe.k.max(Vec3::ZERO).min(Vec3::splat(K_MAX));
    k * (cloth_lobe_shape(ai.theta + ao.theta, ai.phi + ao.phi, lobe.beta, lobe.gamma, reading) * fresnel * cloth_shadowing(ai.cos_phi, a))
}

/// cos(φ/2) from cos φ, φ ∈ (−π, π]: √((1 + cos φ)/2), without trigonometry.
#[inline]
pub fn cloth_half_cos(cos_phi: f32) -> f32 {
    (0.5 * (1.0 + cos_phi.max(-1.0).min(1.0))).sqrt()
}

/// One lobe of a flyaway fibre under the cylinder law (format 1.11, MODEL flag bit 4),
/// its cosine included (what [`cloth_lobe`] · max(n·ω_i, 0) is on a surface):
/// ```text
/// k · S(θ_i + θ_o, 0) · F(η, cos θ_d) · c^a · cos θ_i · c,   c = cos(φ_i / 2)
/// ```
/// in the fibre frame seen from ω_o ([`cloth_fiber_frame`], so φ_o = 0). A fibre is a
/// cylinder: it reflects where its normal bisects the light's and the viewer's azimuths
/// about the axis, at φ_i / 2 from the side it shows; that normal's cosine to ω_i is
/// cos θ_i · c, and there is a normal at every azimuth, so the azimuthal falloff P is 1
/// (φ_i + φ_o read at the bisecting normal, 0). The frame facing the viewer instead cut
/// the lobe at 90° of azimuth: a fibre lying across a mirror view at 45° and beyond
/// went dark where the volume's fibres shine brightest (baker/FIT_MEASUREMENTS.md, "The
/// flyaways' lobes as cylinders").
#[inline]
pub fn cloth_cylinder_lobe(lobe: &ClothLobe, eta: f32, a: f32, f: &ClothFrame, wi: Vec3, wo: Vec3, reading: BrdfReading) -> Vec3 {
    let ai = cloth_angles(f, wi);
    let ao = cloth_angles(f, wo);
    let c = cloth_half_cos(ai.cos_phi);
    let fresnel = cloth_fresnel(eta, cloth_fresnel_cos(&ai, &ao));
    let k = lobe.k.max(Vec3::ZERO).min(Vec3::splat(K_MAX));
    k * (cloth_lobe_shape(ai.theta + ao.theta, 0.0, lobe.beta, lobe.gamma, reading) * fresnel * cloth_shadowing(c, a) * ai.cos_theta * c)
}

/// Outgoing radiance per unit irradiance for lobes sharing frame `f`:
/// f_r · max(n·ω_i, 0) — what a renderer multiplies by E and what the fit matches.
#[inline]
pub fn cloth_response(p: &ClothParams, f: &ClothFrame, wi: Vec3, wo: Vec3, reading: BrdfReading) -> Vec3 {
    cloth_brdf(p, f, wi, wo, reading) * f.n.dot(wi).max(0.0)
}

/// Smallest μ_i + μ_o of the Lommel–Seeliger diffuse term (caps its factor at 20).
pub const DIFFUSE_MU_MIN: f32 = 0.1;

/// The diffuse term's cosine factor about the normal `n` (the texel's lobe-0 normal):
/// k_d times this is the diffuse radiance per unit irradiance. Lambert: max(n·ω_i, 0);
/// Lommel–Seeliger: max(n·ω_i, 0) · 2 / max(μ_i + μ_o, DIFFUSE_MU_MIN) with
/// μ = max(ω·ẑ, 0), ẑ the tile's normal. The second follows the cloth's volume: light
/// that enters at a slant and leaves at a slant crosses less of it, so the diffuse part
/// brightens toward grazing pairs. μ is taken about the tile, not about n, so the factor
/// is the same for every texel of a footprint (a coarse texel's k_d filters as
/// Lambert's does) and a texel turned away from the viewer is not lifted
/// (baker/FIT_MEASUREMENTS.md, "Lommel–Seeliger diffuse", measures both).
#[inline]
pub fn cloth_diffuse_cosine(law: DiffuseLaw, n: Vec3, wi: Vec3, wo: Vec3) -> f32 {
    let cos_i = n.dot(wi).max(0.0);
    match law {
        DiffuseLaw::Lambert => cos_i,
        DiffuseLaw::LommelSeeliger => cos_i * 2.0 / (wi.z.max(0.0) + wo.z.max(0.0)).max(DIFFUSE_MU_MIN),
    }
}

/// The diffuse law under light that is uniform over the tile's upper hemisphere,
/// relative to Lambert's, for n = ẑ: ∫ D dω_i / ∫ max(ẑ·ω_i, 0) dω_i. Lambert: 1.
/// Lommel–Seeliger: 4 · (1 − μ_o · ln(1 + 1/μ_o)), μ_o = max(ω_o·ẑ, 0) (4 at μ_o = 0;
/// 1.23 at μ_o = 1; [`DIFFUSE_MU_MIN`]'s cap left out, which changes it only for
/// μ_o < 0.1). An environment's diffuse term is k_d · E(n) · this: exact for a constant
/// map and a flat texel, an approximation for a tilted one.
#[inline]
pub fn cloth_diffuse_env_factor(law: DiffuseLaw, wo: Vec3) -> f32 {
    match law {
        DiffuseLaw::Lambert => 1.0,
        DiffuseLaw::LommelSeeliger => {
            let mu_o = wo.z.max(0.0);
            if mu_o > 1e-6 { 4.0 * (1.0 - mu_o * (1.0 + 1.0 / mu_o).ln()) } else { 4.0 }
        }
    }
}

/// Largest |g| of one coefficient of a visibility gradient.
pub const GRADIENT_MAX: f32 = 2.0;

/// A level-0 texel's visibility gradient (format 1.12): the first-order change of what
/// the texel shows with the directions' slant across the tile,
/// max(1 + g_o·(ω_o,x, ω_o,y) + g_i·(ω_i,x, ω_i,y), 0), g = (g_o,x, g_o,y, g_i,x, g_i,y),
/// each clamped to ±[`GRADIENT_MAX`]. A texel on a yarn's flank is seen more, and lit
/// more, from that flank's side: masking and shadowing by its neighbours that the
/// height field is too smooth to cast (baker/FIT_MEASUREMENTS.md, "The visibility
/// gradient"). Tile space, as μ of the diffuse law; 1 for g = 0 and for ω_i = ω_o = ẑ.
#[inline]
pub fn cloth_visibility_gradient(g: [f32; 4], wi: Vec3, wo: Vec3) -> f32 {
    let c = |x: f32| x.max(-GRADIENT_MAX).min(GRADIENT_MAX);
    (1.0 + c(g[0]) * wo.x + c(g[1]) * wo.y + c(g[2]) * wi.x + c(g[3]) * wi.y).max(0.0)
}

/// Largest |q| of one coefficient of a visibility curvature.
pub const CURVATURE_MAX: f32 = 2.0;

/// The six second-order terms of the directions' slant across the tile (format 1.15), each
/// unchanged when ω_i and ω_o trade places: (ω_o,x² + ω_i,x², ω_o,y² + ω_i,y²,
/// ω_o,x·ω_o,y + ω_i,x·ω_i,y, ω_o,x·ω_i,x, ω_o,y·ω_i,y, ω_o,x·ω_i,y + ω_o,y·ω_i,x).
#[inline]
pub fn cloth_curvature_terms(wi: Vec3, wo: Vec3) -> [f32; 6] {
    [wo.x * wo.x + wi.x * wi.x, wo.y * wo.y + wi.y * wi.y, wo.x * wo.y + wi.x * wi.y, wo.x * wi.x, wo.y * wi.y, wo.x * wi.y + wo.y * wi.x]
}

/// A level-0 texel's visibility with its curvature (format 1.15): the gradient's
/// first-order odd part plus an even second-order part q · [`cloth_curvature_terms`],
/// max(1 + g·(ω_o,x, ω_o,y, ω_i,x, ω_i,y) + q·e(ω_i, ω_o), 0), each q clamped to
/// ±[`CURVATURE_MAX`]. What the lobes' own angular form cannot say: that a yarn's
/// highlight seen along the fibres (the plane of incidence along t) is brighter than
/// across them by more than Fresnel and the shadowing exponent allow
/// (baker/FIT_MEASUREMENTS.md, "The visibility curvature"). q = 0 is
/// [`cloth_visibility_gradient`].
#[inline]
pub fn cloth_visibility(g: [f32; 4], q: [f32; 6], wi: Vec3, wo: Vec3) -> f32 {
    let c = |x: f32| x.max(-GRADIENT_MAX).min(GRADIENT_MAX);
    let d = |x: f32| x.max(-CURVATURE_MAX).min(CURVATURE_MAX);
    let e = cloth_curvature_terms(wi, wo);
    let even = d(q[0]) * e[0] + d(q[1]) * e[1] + d(q[2]) * e[2] + d(q[3]) * e[3] + d(q[4]) * e[4] + d(q[5]) * e[5];
    (1.0 + c(g[0]) * wo.x + c(g[1]) * wo.y + c(g[2]) * wi.x + c(g[3]) * wi.y + even).max(0.0)
}

/// Largest optical-depth parameter τ of a transmission term.
pub const TAU_MAX: f32 = 16.0;
/// Smallest |cos| in the transmission's attenuation (caps 1/μ at 20).
pub const TRANSMISSION_MU_MIN: f32 = 0.05;

/// The transmission term of a BSDF texel (format 1.3; runtime/HYBRID_FORMAT.md §6
/// "Transmission"): a diffuse part k_dt and one lobe about the transmitted direction,
/// both linear RGB, attenuated along the slant path with optical-depth parameter τ.
/// A texel without one has all zeros (nothing comes through).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ClothTransmission {
    pub kd: Vec3,
    pub lobe: ClothLobe,
    /// τ ∈ [0, TAU_MAX]: the attenuation exp(−τ·(1/μ_i + 1/μ_o − 2)), 1 at normal
    /// incidence and view.
    pub tau: f32,
    /// The light that crosses the texel unscattered, through the gaps between yarns
    /// (format 1.10; zero in older files).
    pub gap: ClothOpenness,
    /// The transmission's visibility gradient (g_u,x, g_u,y, g_l,x, g_l,y) and
    /// curvature (format 1.15's order of [`cloth_curvature_terms`]) of
    /// [`cloth_transmission_visibility`] (format 1.16; zero in older files and at levels
    /// without them).
    pub grad: [f32; 4],
    pub curv: [f32; 6],
}

impl ClothTransmission {
    /// Whether any light comes through.
    pub fn is_zero(&self) -> bool {
        self.kd.max_element() <= 0.0 && self.lobe.k.max_element() <= 0.0 && !(self.gap.o > 0.0)
    }
}

/// Largest decay parameter q of a texel's openness.
pub const OPENNESS_Q_MAX: f32 = 64.0;

/// A texel's openness (format 1.10; runtime/HYBRID_FORMAT.md §6.4): the fraction of
/// straight rays along −ω_o that cross the cloth untouched,
/// O(ω_o) = o · exp(−q · (1 + a·cos 2φ_o + b·sin 2φ_o) · (1/μ_o − 1)) ([`cloth_openness`]).
/// A renderer shows the light behind the sheet along the same ray (the environment map
/// below) times O. It is the delta part of the transmission, which a directional light
/// is never seen through and which the fitted term cannot hold.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ClothOpenness {
    /// o ∈ [0, 1]: the open fraction seen straight down.
    pub o: f32,
    /// q ∈ [0, OPENNESS_Q_MAX]: how fast the gaps close with the slant of the view.
    pub q: f32,
    /// (a, b) ∈ [−1, 1]²: how that rate depends on the view's azimuth φ_o in the tile
    /// (a slit between parallel yarns stays open seen along them and closes seen across).
    pub aniso: [f32; 2],
}

/// (cos 2φ, sin 2φ) of w's azimuth in the tile, ((x² − y²)/(x² + y²), 2xy/(x² + y²)):
/// an axis's azimuth, the same for w and −w; (0, 0) straight up or down.
#[inline]
pub fn cloth_azimuth_axis(w: Vec3) -> [f32; 2] {
    let r2 = w.x * w.x + w.y * w.y;
    if r2 > 1e-12 { [(w.x * w.x - w.y * w.y) / r2, 2.0 * w.x * w.y / r2] } else { [0.0, 0.0] }
}

/// O(ω_o) = o · exp(−q · (1 + a·cos 2φ_o + b·sin 2φ_o) · (1/μ_o − 1)): a slab of open
/// columns closes as its optical depth grows with the slant path 1/μ, at a rate that
/// depends on the azimuth φ_o (in the tile's frame: an axis, hence 2φ), normalized so
/// that O = o straight down. μ_o = |ω_o.z| clamped to [TRANSMISSION_MU_MIN, 1], o to
/// [0, 1], q to [0, OPENNESS_Q_MAX], a and b to [−1, 1], the azimuth factor to [0, 2].
#[inline]
pub fn cloth_openness(g: &ClothOpenness, wo: Vec3) -> f32 {
    let o = g.o.max(0.0).min(1.0);
    let q = g.q.max(0.0).min(OPENNESS_Q_MAX);
    let mo = wo.z.abs().max(TRANSMISSION_MU_MIN).min(1.0);
    let [c2, s2] = cloth_azimuth_axis(wo);
    let (a, b) = (g.aniso[0].max(-1.0).min(1.0), g.aniso[1].max(-1.0).min(1.0));
    let rate = (1.0 + a * c2 + b * s2).max(0.0).min(2.0);
    o * (-q * rate * (1.0 / mo - 1.0)).exp()
}

/// The attenuation of light crossing the sheet between cosines μ_i, μ_o (to the tile's
/// normal): exp(−τ·(1/μ_i + 1/μ_o − 2)), μ clamped to [TRANSMISSION_MU_MIN, 1], τ to
/// [0, TAU_MAX]. A slab's direct transmission goes as exp(−τ₀/μ) each way; normalized
/// to 1 at normal incidence so that k_dt and k_t keep their meaning. Symmetric.
#[inline]
pub fn cloth_transmission_attenuation(tau: f32, mu_i: f32, mu_o: f32) -> f32 {
    let tau = tau.max(0.0).min(TAU_MAX);
    let mi = mu_i.abs().max(TRANSMISSION_MU_MIN).min(1.0);
    let mo = mu_o.abs().max(TRANSMISSION_MU_MIN).min(1.0);
    (-tau * (1.0 / mi + 1.0 / mo - 2.0)).exp()
}

/// The transmission's visibility (format 1.16): with u whichever of ω_i, ω_o lies above
/// the tile plane and l the other,
/// M_t = max(1 + g_u·(u_x, u_y) + g_l·(l_x, l_y) + q · e(l, u), 0), each g clamped to
/// ±[`GRADIENT_MAX`], each q to ±[`CURVATURE_MAX`] — [`cloth_visibility`] with the
/// viewer's side above and the light's below, so that f_t stays symmetric in
/// (ω_i, ω_o) (e is symmetric). What the volume shows along a ray that the model says
/// meets a texel beside a gap depends on the side the ray and the light come from: the
/// gap's light is seen on the wall that faces the viewer and is lit through the gap
/// from below (the odd part g); and light straight through the sheet along the yarns
/// differs from light across them by more than the lobe's form allows (the even part
/// q) (baker/FIT_MEASUREMENTS.md, "Transmission"). 1 for g = q = 0 and for both
/// directions along ±ẑ.
#[inline]
pub fn cloth_transmission_visibility(g: [f32; 4], q: [f32; 6], wi: Vec3, wo: Vec3) -> f32 {
    let (upper, lower) = if wi.z > 0.0 { (wi, wo) } else { (wo, wi) };
    cloth_visibility(g, q, lower, upper)
}

/// `w` mirrored through the tile plane (z ↦ −z).
#[inline]
pub fn cloth_mirror_z(w: Vec3) -> Vec3 {
    Vec3::new(w.x, w.y, -w.z)
}

/// f_t(ω_i, ω_o) for directions on opposite sides of the tile plane (ω_i.z · ω_o.z < 0):
/// ```text
/// f_t = (k_dt + k_t · G(θ_l* + θ_u; β_t) · P(φ_l* + φ_u; γ_t)) · A(τ; ω_i.z, ω_o.z) · M_t
/// ```
/// u is whichever of ω_i, ω_o lies above the plane, l* the other mirrored through it
/// ([`cloth_mirror_z`]); angles in frame `f` (the texel's lobe-0 frame); ω in tile
/// space. The lobe is the reflection lobe's bounded shape (no Fresnel, no shadowing)
/// seen from the mirrored side, so with n = ẑ it peaks at ω_o = −ω_i, the
/// straight-through direction; A is [`cloth_transmission_attenuation`], M_t
/// [`cloth_transmission_visibility`] (format 1.16). The value is symmetric in
/// (ω_i, ω_o): reciprocal by construction. Directions on the same side give 0. RGB,
/// finite, ≥ 0.
#[inline]
pub fn cloth_transmission(t: &ClothTransmission, f: &ClothFrame, wi: Vec3, wo: Vec3) -> Vec3 {
    if !(wi.z * wo.z < 0.0) {
        return Vec3::ZERO;
    }
    let (upper, lower) = if wi.z > 0.0 { (wi, wo) } else { (wo, wi) };
    let au = cloth_angles(f, upper);
    let al = cloth_angles(f, cloth_mirror_z(lower));
    let kd = t.kd.max(Vec3::ZERO).min(Vec3::splat(K_MAX));
    let k = t.lobe.k.max(Vec3::ZERO).min(Vec3::splat(K_MAX));
    (kd + k * cloth_lobe_shape(al.theta + au.theta, al.phi + au.phi, t.lobe.beta, t.lobe.gamma, BrdfReading::Bounded)) * (cloth_transmission_attenuation(t.tau, wi.z, wo.z) * cloth_transmission_visibility(t.grad, t.curv, wi, wo))
}

/// Transmitted radiance per unit irradiance: f_t · |ω_i.z| (the tile's cosine, since the
/// light crosses the sheet rather than meeting a facet) — what a renderer multiplies by
/// E for a light on the other side and what the transmission fit matches.
#[inline]
pub fn cloth_transmission_response(t: &ClothTransmission, f: &ClothFrame, wi: Vec3, wo: Vec3) -> Vec3 {
    cloth_transmission(t, f, wi, wo) * wi.z.abs()
}

#[cfg(test)]
mod tests;
