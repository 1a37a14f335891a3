//! Environment lighting of a hit (the CPU twin of `env_shading.glsl`): each lobe as a
//! small mixture of spherical Gaussians read from the prefiltered environment, the SGs
//! merged into a few lookups per lobe ([`EnvGroup`]); how many of each, on the surface
//! and on a flyaway, is an [`EnvBudget`] (paper §7.2, "Extensions";
//! runtime/HYBRID_FORMAT.md §6).
//!
//! # The lobe's SG mixture
//! In its frame (n, t) a lobe is, as a function of ω_i at fixed ω_o (brdf/mod.rs),
//! ```text
//! I(ω_i) = G(θ_i + θ_o; β') · R(ω_i),   R = k · F · max(cos φ_i, 0)^a · P · max(n·ω_i, 0) · V_f
//! ```
//! with β' = β (bounded reading; P = P(φ_i + φ_o; γ)) or β' = max(β·P, β_min) (width
//! reading; P folded into β'), and V_f the volumetric factor of models baked with it.
//! It lives on the band θ_i ∈ −θ_o ± 3β', φ_i ∈ [−π/2, π/2] (n·ω_i > 0) narrowed to
//! −φ_o ± 3γ when the bounded falloff is on. With dω = cos θ dθ dφ the band is cut into
//! K_θ × K_φ cells (K_θ K_φ ≤ the budget's nodes, cells about square); a cell becomes
//! one SG whose
//! ```text
//! axis   = ω(θ_a, φ_c),  θ_a the Gaussian centroid of the cell's θ range
//! weight = m_a · Δφ · cos θ_a · R(ω(θ_a, φ_c)),  m_a = ∫_cell G dθ (exact, via erf)
//! width  = σ = max(min(β', 0.4 Δθ), 0.4 Δφ cos θ_a)
//! ```
//! and contributes weight · L̄_σ(axis). The Gaussian factor is integrated exactly in θ;
//! what the mixture approximates is the smooth factor R over each cell and the
//! environment over the SG's footprint (an isotropic blur of an anisotropic cell). A
//! lookup reads the chain of the map's half on its side of the horizon
//! (scene/env_prefilter.rs, "Two halves"): no reflection lobe gathers light from below
//! the sheet, nor the transmission term from above it.
//! (Columns at Gauss–Legendre nodes instead of midpoints were measured and dropped: the
//! cut at the tile plane and at n·ω_i = 0 is a step inside the band, which few-point
//! rules integrate worse — a constant map's integral up to 5% off with 16 SGs, 20% with
//! 8, against 3.7% and 16.5% with midpoints.)
//! The diffuse term is k_d · E(n_0) · V_f(n_0, ω_o) · H(n_0, ω_o), E the irradiance map
//! of the half above the horizon and H the diffuse law's factor under uniform light ([`cloth_diffuse_env_factor`]: 1
//! for Lambert; exact for a constant map, and for Lommel–Seeliger an approximation
//! where the map varies across the hemisphere).
//!
//! A texel's visibility gradient (`brdf::cloth_visibility_gradient`, linear in ω_i) is
//! read at each lookup group's mean direction, and for the diffuse term at the cosine
//! lobe's mean direction (2/3) n_0: exact for a constant map over n_0's whole hemisphere,
//! an approximation where the map varies within a group or the tile plane cuts it. Its
//! curvature (format 1.15, `brdf::cloth_visibility`, quadratic in ω_i) is read at the same
//! mean directions, which are shorter than a unit vector: the even terms in ω_i alone
//! (ω_i,x², …) are underestimated there: over the diffuse term's cosine lobe about
//! n_0 = ẑ, E[ω_i,x²] = 1/4, against 0 at its mean direction. An approximation.
//!
//! A flyaway's lobe under the cylinder law (format 1.11, `brdf::cloth_cylinder_lobe`)
//! is cut the same way over the whole circle φ_i ∈ (−π, π), with R = k F c^a cos θ c,
//! c = cos(φ_i/2), and no falloff ([`EnvSide::Cylinder`]).
//!
//! # Visibility (the stated approximation)
//! The height field does not shadow environment light (no rays are traced): a hit sees
//! the whole hemisphere of each lobe's normal, cut to the upper hemisphere of the tile
//! (ω_i.z > 0: the reflection lobes see only the map above the sheet). What that leaves
//! out is measured against the path tracer (`fabric bench`, runtime/GPU_MEASUREMENTS.md).
//! Where the model's flyaways shadow the surface (format 1.13), a surface hit's map is
//! dimmed by what they let through straight up from it (`Scene::flyaway_sky`): the
//! column above the hit stands for the whole sky, whose lower light crosses longer paths.
//!
//! # Light through the cloth ([`transmission_env_response`])
//! A texel with a transmission term (a BSDF, brdf/mod.rs `cloth_transmission`) is also
//! lit by the map below the sheet. With ω_i = ω'* (ω' mirrored through the tile plane,
//! ω'.z > 0) the integral is
//! ```text
//! ∫ L(ω'*) · (k_dt + k_t · G(θ' + θ_o; β_t) · P(φ' + φ_o; γ_t)) · A(τ; ω'.z, ω_o.z) · ω'.z dω'
//! ```
//! so the lobe is cut into the same cells as a reflection lobe (bounded reading, no
//! Fresnel, no shadowing, R = k_t · P · A · ω'.z) and each SG is read at its mirrored
//! axis. The diffuse part is k_dt · E(−ẑ) · c(τ) · e^{−τ(1/μ_o − 1)}, E the irradiance
//! map and c(τ) = 2∫₀¹ μ e^{−τ(1/μ − 1)} dμ = 1 − τ + τ² e^τ E₁(τ) the attenuation's
//! mean under a uniform map ([`transmission_env_diffuse_factor`]): exact for a constant
//! map at every τ and for any map at τ = 0; where τ is large the true weight leans
//! toward the nadir more than the cosine does (the approximation, measured in
//! runtime/ENV_MEASUREMENTS.md, "Light through the cloth"). Beside the scattered light,
//! the gaps between yarns show the map itself: O(μ_o) · L(−ω_o), O the texel's openness
//! (format 1.10, brdf/mod.rs `cloth_openness`), L the sharpest level of the chain below
//! the horizon. The renderers add this term
//! only where the map has light below the sheet ([`PrefilteredEnv::lights_below`]), so a
//! frame with none pays nothing for it, as with lights (shading.rs).

use std::f32::consts::{FRAC_PI_2, PI};

use glam::Vec3;

use super::shading::volume_factor;
use crate::brdf::{BETA_MAX, BETA_MIN, BrdfReading, ClothFrame, ClothLobe, ClothTransmission, DiffuseLaw, K_MAX, TAU_MAX, cloth_angles, cloth_diffuse_env_factor, cloth_visibility, cloth_fresnel, cloth_gaussian, cloth_half_cos, cloth_held_height, cloth_mirror_z, cloth_openness, cloth_phi_falloff, cloth_shadowing, cloth_transmission_attenuation, cloth_transmission_visibility};
use crate::hybrid::TexelBrdf;
use crate::scene::{EnvMap, PrefilteredEnv};

/// How finely a lobe is cut into SGs and how many lookups read them: the surface's
/// lobes get [`EnvBudget::SURFACE`], a flyaway's [`EnvBudget::FLYAWAY`] (a flyaway is
/// a thin, mostly transparent fibre crossed several times per pixel, and its light a
/// small share of the pixel's: measured in runtime/ENV_MEASUREMENTS.md, "Speed").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EnvBudget {
    /// Most SGs per lobe (K_θ·K_φ ≤ nodes, K_θ ≤ min(4, nodes / 2)).
    pub nodes: usize,
    /// Most lookups of the prefiltered map per lobe: the mixture's SGs, in band order
    /// (neighbours), are merged ⌈SGs / lookups⌉ at a time into one lookup
    /// ([`EnvGroup`]). The SGs' weights are exact whatever the count (a constant map is
    /// integrated as well as with one lookup per SG); what fewer lookups give up is
    /// detail of the map within a group, which the widened blur averages.
    pub lookups: usize,
}

impl EnvBudget {
    pub const SURFACE: EnvBudget = EnvBudget { nodes: ENV_NODES, lookups: ENV_LOOKUPS };
    pub const FLYAWAY: EnvBudget = EnvBudget { nodes: ENV_FLYAWAY_NODES, lookups: ENV_FLYAWAY_LOOKUPS };
}

/// Most SGs per surface lobe.
pub const ENV_NODES: usize = 16;
/// Most lookups per surface lobe.
pub const ENV_LOOKUPS: usize = 4;
/// Most SGs per flyaway lobe.
pub const ENV_FLYAWAY_NODES: usize = 8;
/// Most lookups per flyaway lobe.
pub const ENV_FLYAWAY_LOOKUPS: usize = 1;

/// erf(x), Abramowitz & Stegun 7.1.26 (|error| ≤ 1.5e-7), the same arithmetic in GLSL.
#[inline]
pub fn env_erf(x: f32) -> f32 {
    let s = if x < 0.0 { -1.0 } else { 1.0 };
    let x = x.abs();
    let t = 1.0 / (1.0 + 0.327_591_1 * x);
    let y = 1.0 - (((((1.061_405_4 * t - 1.453_152_1) * t) + 1.421_413_7) * t - 0.284_496_74) * t + 0.254_829_6) * t * (-x * x).exp();
    s * y
}

/// One SG of a lobe's mixture: axis, weight (RGB) and angular width.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvNode {
    pub axis: Vec3,
    pub weight: Vec3,
    pub sigma: f32,
}

/// SGs merged into one lookup: their summed weight read at their mean axis (weighted by
/// the weights' mean over RGB), blurred by their mean σ² plus their spread about that
/// axis (the mean squared chord, 1 − |Σ w a|²/(Σ w)²).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EnvGroup {
    pub weight: Vec3,
    pub axis: Vec3,
    pub lum: f32,
    pub sigma2: f32,
}

impl EnvGroup {
    #[inline]
    pub fn add(&mut self, n: &EnvNode) {
        let l = (n.weight.x + n.weight.y + n.weight.z) * (1.0 / 3.0);
        self.weight += n.weight;
        self.axis += n.axis * l;
        self.lum += l;
        self.sigma2 += l * n.sigma * n.sigma;
    }

    /// The group's mean direction, weighted as its axis is (length ≤ 1; zero when empty):
    /// where a factor linear in ω_i, the visibility gradient, is read for the group.
    #[inline]
    pub fn mean_axis(&self) -> Vec3 {
        if self.lum > 0.0 { self.axis * (1.0 / self.lum) } else { Vec3::ZERO }
    }

    /// The group's lookup, and the group emptied (zero when empty).
    #[inline]
    pub fn flush(&mut self, env: &PrefilteredEnv) -> Vec3 {
        if !(self.lum > 0.0) {
            *self = EnvGroup::default();
            return Vec3::ZERO;
        }
        let len2 = self.axis.dot(self.axis);
        let spread = (1.0 - len2 / (self.lum * self.lum)).max(0.0);
        let sigma = (self.sigma2 / self.lum + spread).sqrt();
        let r = self.weight * env.blurred(self.axis * (1.0 / len2.max(1e-30).sqrt()), sigma);
        *self = EnvGroup::default();
        r
    }
}

/// Which light a lobe's mixture gathers: the map above the sheet reflected (Fresnel,
/// shadowing, n·ω_i and the volumetric factor of models baked with it), the same by a
/// flyaway's lobe under the cylinder law (`brdf::cloth_cylinder_lobe`: the band's
/// whole circle of azimuths, shadowing and cosine at the half-angle cos(φ/2), no
/// falloff), or the map below the sheet through the cloth (module docs, "Light through
/// the cloth").
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EnvSide {
    Reflected { volumetric: bool },
    Cylinder,
    Transmitted { tau: f32 },
}

/// The SG mixture of one lobe (module docs), passed node by node to `emit` with
/// whether the node closes its lookup group (every ⌈nodes / lookups⌉-th emitted). A
/// transmitted lobe takes the bounded reading and ignores η and a; its nodes' axes
/// point below the sheet.
#[allow(clippy::too_many_arguments)]
pub fn lobe_env_nodes(lobe: &ClothLobe, eta: f32, a: f32, f: &ClothFrame, wo: Vec3, reading: BrdfReading, side: EnvSide, budget: EnvBudget, mut emit: impl FnMut(EnvNode, bool)) {
    let k = lobe.k.max(Vec3::ZERO).min(Vec3::splat(K_MAX));
    if k.max_element() <= 0.0 {
        return;
    }
    let (through, tau, volumetric, cylinder) = match side {
        EnvSide::Reflected { volumetric } => (false, 0.0, volumetric, false),
        EnvSide::Cylinder => (false, 0.0, false, true),
        EnvSide::Transmitted { tau } => (true, tau, false, false),
    };
    // A cylinder's lobe has no falloff: either reading is then G(θ_i + θ_o; β).
    let reading = if through || cylinder { BrdfReading::Bounded } else { reading };
    let ao = cloth_angles(f, wo);
    let theta_c = -ao.theta;
    let beta = lobe.beta.max(BETA_MIN).min(BETA_MAX);
    let falloff_on = reading == BrdfReading::Bounded && lobe.gamma > 0.0 && !cylinder;
    let (mut phi_lo, mut phi_hi) = if cylinder { (-PI, PI) } else { (-FRAC_PI_2, FRAC_PI_2) };
    if falloff_on {
        let g3 = 3.0 * lobe.gamma;
        phi_lo = phi_lo.max(-ao.phi - g3);
        phi_hi = phi_hi.min(-ao.phi + g3);
    }
    if !(phi_hi > phi_lo) {
        return;
    }
    // Cell counts: about square cells over the band (arc lengths), K_θ·K_φ ≤ nodes.
    let nodes = budget.nodes.max(1);
    let theta_ext = (6.0 * beta).min(PI);
    let phi_arc = ((phi_hi - phi_lo) * theta_c.cos()).max(1e-4);
    // At least two φ columns where the budget allows: one column weighs R at its centre
    // over the whole band (a constant map 2× off with 4 SGs, 30% with this cap).
    let k_theta = ((nodes as f32 * theta_ext / phi_arc).sqrt().round() as usize).clamp(1, 4.min((nodes / 2).max(1)));
    let k_phi = (nodes / k_theta).max(1);
    let d_phi = (phi_hi - phi_lo) / k_phi as f32;
    let per_group = (k_theta * k_phi).div_ceil(budget.lookups.max(1)) as u32;
    let mut emitted = 0u32;
    // The bounded reading's θ cells are the same in every φ column: computed once.
    let mut cells = [ThetaCell::default(); 4];
    if reading == BrdfReading::Bounded {
        env_theta_cells(theta_c, beta, k_theta, &ao, eta, &mut cells);
    }
    for c in 0..k_phi {
        let phi = phi_lo + (c as f32 + 0.5) * d_phi;
        let (sp, cp) = phi.sin_cos();
        let falloff = if cylinder { 1.0 } else { cloth_phi_falloff(phi + ao.phi, lobe.gamma) };
        let bounded = reading == BrdfReading::Bounded;
        // The azimuth's cosine that shadows and projects: cos φ_i = cos φ on the band, or
        // a cylinder's half-angle cos(φ/2).
        let cs = if cylinder { cloth_half_cos(cp) } else { cp };
        // What of R depends on φ alone: the shadowing and the bounded reading's falloff
        // (the width and held readings fold it into β' = max(β·P, BETA_MIN); the held
        // reading's height, cloth_held_height, as well).
        let beta_eff = (beta * falloff).max(BETA_MIN);
        let height = match reading {
            BrdfReading::Bounded => falloff,
            BrdfReading::Width => 1.0,
            BrdfReading::Held => cloth_held_height(beta, beta_eff),
        };
        let r_phi = k * (if through { 1.0 } else { cloth_shadowing(cs, a) } * height);
        if r_phi.max_element() <= 0.0 {
            continue;
        }
        if !bounded {
            env_theta_cells(theta_c, beta_eff, k_theta, &ao, eta, &mut cells);
        }
        for cell in &cells[..k_theta] {
            if !(cell.mass > 0.0) {
                continue;
            }
            let wi = f.t * cell.sin + (f.n * cp + f.b * sp) * cell.cos;
            // n·ω_i = cos θ cos φ (a cylinder's: cos θ cos(φ/2)); ω_i's angles are the
            // node's own, so R needs no atan2:
            // R = k F(η, cos θ_d) max(cos φ_i, 0)^a P · n·ω_i · V_f (cloth_lobe / G).
            let cos_n = cell.cos * cs;
            if !(cos_n > 0.0) || !(wi.z > 0.0) {
                continue;
            }
            // Through the cloth: R = k_t P · A(τ; ω'.z, ω_o.z) · ω'.z, read at ω' mirrored.
            let r = if through { r_phi * (cloth_transmission_attenuation(tau, wi.z, wo.z) * wi.z) } else { r_phi * (cell.fresnel * cos_n * if volumetric { volume_factor(wi, wo) } else { 1.0 }) };
            let weight = r * (cell.mass * d_phi * cell.cos);
            if weight.max_element() <= 0.0 {
                continue;
            }
            let sigma = cell.sigma.max(0.4 * d_phi * cell.cos);
            emitted += 1;
            emit(EnvNode { axis: if through { cloth_mirror_z(wi) } else { wi }, weight, sigma }, emitted % per_group == 0);
        }
    }
}

/// One θ cell of a lobe's band: its Gaussian centroid (sin, cos), its mass of G, the
/// Fresnel factor there and its width's share of the SG's σ.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ThetaCell {
    pub sin: f32,
    pub cos: f32,
    pub mass: f32,
    pub fresnel: f32,
    pub sigma: f32,
}

/// The `k_theta` cells of θ_c ± 3β' ∩ [−π/2, π/2] (mass 0: empty), erf and G at each
/// boundary once.
pub fn env_theta_cells(theta_c: f32, beta_eff: f32, k_theta: usize, ao: &crate::brdf::ClothAngles, eta: f32, cells: &mut [ThetaCell; 4]) {
    *cells = [ThetaCell::default(); 4];
    let lo = (theta_c - 3.0 * beta_eff).max(-FRAC_PI_2);
    let hi = (theta_c + 3.0 * beta_eff).min(FRAC_PI_2);
    if !(hi > lo) {
        return;
    }
    let d_theta = (hi - lo) / k_theta as f32;
    let inv = 1.0 / (beta_eff * std::f32::consts::SQRT_2);
    let mut e0 = env_erf((lo - theta_c) * inv);
    let mut g0 = cloth_gaussian(lo - theta_c, beta_eff);
    for (i, cell) in cells.iter_mut().enumerate().take(k_theta) {
        let (t0, t1) = (lo + i as f32 * d_theta, lo + (i + 1) as f32 * d_theta);
        let e1 = env_erf((t1 - theta_c) * inv);
        let g1 = cloth_gaussian(t1 - theta_c, beta_eff);
        let mass = 0.5 * (e1 - e0);
        if mass > 1e-7 {
            // Centroid of N(θ_c, β'²) on [t0, t1]: θ_c + β'² (g(t0) − g(t1)) / mass.
            let theta = (theta_c + beta_eff * beta_eff * (g0 - g1) / mass).clamp(t0, t1);
            let (st, ct) = theta.sin_cos();
            let cos_diff = ao.cos_theta * ct + ao.sin_theta * st;
            let fresnel = cloth_fresnel(eta, (0.5 * (1.0 + cos_diff)).max(0.0).sqrt());
            *cell = ThetaCell { sin: st, cos: ct, mass, fresnel, sigma: beta_eff.min(0.4 * d_theta) };
        }
        e0 = e1;
        g0 = g1;
    }
}

/// Radiance toward `wo` from a texel lit by the environment (module docs).
pub fn texel_env_response(b: &TexelBrdf, wo: Vec3, reading: BrdfReading, volumetric: bool, diffuse: DiffuseLaw, budget: EnvBudget, env: &PrefilteredEnv) -> Vec3 {
    let p = &b.params;
    let kd = p.kd.max(Vec3::ZERO).min(Vec3::splat(K_MAX));
    let n0 = b.frames[0].n;
    let mut r = Vec3::ZERO;
    if kd.max_element() > 0.0 {
        // The gradient at the cosine lobe's mean direction, (2/3) n_0.
        let m = cloth_visibility(b.gradient, b.curvature, n0 * (2.0 / 3.0), wo);
        r += kd * env.irradiance(n0) * (if volumetric { volume_factor(n0, wo) } else { 1.0 } * cloth_diffuse_env_factor(diffuse, wo) * m);
    }
    for (lobe, frame) in p.lobes().iter().zip(&b.frames) {
        let mut group = EnvGroup::default();
        let side = if b.cylinder { EnvSide::Cylinder } else { EnvSide::Reflected { volumetric } };
        lobe_env_nodes(lobe, p.eta, p.a, frame, wo, reading, side, budget, |node, closes| {
            group.add(&node);
            if closes {
                let m = cloth_visibility(b.gradient, b.curvature, group.mean_axis(), wo);
                r += m * group.flush(env);
            }
        });
        let m = cloth_visibility(b.gradient, b.curvature, group.mean_axis(), wo);
        r += m * group.flush(env);
    }
    r
}

/// c(τ) = 2∫₀¹ μ e^{−τ(1/μ − 1)} dμ = 1 − τ + τ² e^τ E₁(τ) (= 2 e^τ E₃(τ)): the
/// transmission's attenuation toward the light averaged over a uniform lower
/// hemisphere, cosine-weighted; 1 at τ = 0, about 2/τ for large τ. e^τ E₁(τ) by
/// Abramowitz & Stegun 5.1.53 (τ < 1) and 5.1.56 (τ ≥ 1), |error| ≤ 2e-7 relative.
/// The attenuation's clamp at μ = TRANSMISSION_MU_MIN is left out (≤ 0.3% of c).
/// τ is clamped to [0, TAU_MAX] as the attenuation clamps it. Twin: env_shading.glsl.
pub fn transmission_env_diffuse_factor(tau: f32) -> f32 {
    let t = tau.max(0.0).min(TAU_MAX);
    if !(t > 0.0) {
        return 1.0;
    }
    let ex_e1 = if t < 1.0 {
        let e1 = -0.577_215_7 - t.ln() + t * (0.999_991_93 + t * (-0.249_910_55 + t * (0.055_199_68 + t * (-0.009_760_04 + t * 0.001_078_57))));
        t.exp() * e1
    } else {
        let num = (((t + 8.573_329) * t + 18.059_017) * t + 8.634_761) * t + 0.267_773_73;
        let den = (((t + 9.573_322) * t + 25.632_956) * t + 21.099_653) * t + 3.958_497;
        num / (den * t)
    };
    (1.0 - t + t * t * ex_e1).max(0.0)
}

/// Radiance toward `wo` (above the sheet) from a texel's transmission term lit by the
/// map below the sheet (module docs, "Light through the cloth"); `f` is lobe 0's frame,
/// as for a light behind the cloth (shading.rs). Adds the map seen straight through the
/// gaps, O(μ_o) · L(−ω_o) (format 1.10, [`crate::brdf::cloth_openness`]). Zero without a
/// term or for ω_o below.
pub fn transmission_env_response(t: &ClothTransmission, f: &ClothFrame, wo: Vec3, budget: EnvBudget, env: &PrefilteredEnv) -> Vec3 {
    if !(wo.z > 0.0) || t.is_zero() {
        return Vec3::ZERO;
    }
    let mut r = Vec3::ZERO;
    let kd = t.kd.max(Vec3::ZERO).min(Vec3::splat(K_MAX));
    if kd.max_element() > 0.0 {
        // A(τ; 1, μ_o) = e^{−τ(1/μ_o − 1)}: the view's share of the attenuation; the
        // transmission's visibility at the lower cosine lobe's mean direction, −(2/3) ẑ.
        let m = cloth_transmission_visibility(t.grad, t.curv, Vec3::new(0.0, 0.0, -2.0 / 3.0), wo);
        r += kd * env.irradiance_full(-Vec3::Z) * (transmission_env_diffuse_factor(t.tau) * cloth_transmission_attenuation(t.tau, 1.0, wo.z) * m);
    }
    // The map seen straight through the gaps along the view ray: the sharpest level of
    // the chain below the horizon, times the texel's openness O(μ_o).
    let gap = cloth_openness(&t.gap, wo);
    if gap > 0.0 {
        r += gap * env.blurred(-wo, 0.0);
    }
    // Each group's lookup scaled by the transmission's visibility at its mean direction
    // (below the sheet: the axes are mirrored), as the reflection's is.
    let mut group = EnvGroup::default();
    lobe_env_nodes(&t.lobe, 1.0, 0.0, f, wo, BrdfReading::Bounded, EnvSide::Transmitted { tau: t.tau }, budget, |node, closes| {
        group.add(&node);
        if closes {
            let m = cloth_transmission_visibility(t.grad, t.curv, group.mean_axis(), wo);
            r += m * group.flush(env);
        }
    });
    let m = cloth_transmission_visibility(t.grad, t.curv, group.mean_axis(), wo);
    r + m * group.flush(env)
}

/// [`transmission_env_response`] by brute force over the map's lower hemisphere (the
/// tests' ground truth), on the grid of [`env_quadrature`].
pub fn transmission_env_response_quadrature(t: &ClothTransmission, f: &ClothFrame, wo: Vec3, map: &EnvMap, n: usize) -> Vec3 {
    env_quadrature(map, n, |wi| if wi.z < 0.0 { crate::brdf::cloth_transmission_response(t, f, wi, wo) } else { Vec3::ZERO })
}

/// The same integral by brute force (the test's and the bench's ground truth):
/// ∫ L(ω_i) · response(ω_i, ω_o) · V_f dω_i over ω_i.z > 0, on the grid of
/// [`env_quadrature`].
pub fn texel_env_response_quadrature(b: &TexelBrdf, wo: Vec3, reading: BrdfReading, volumetric: bool, diffuse: DiffuseLaw, map: &EnvMap, n: usize) -> Vec3 {
    env_quadrature(map, n, |wi| if wi.z > 0.0 { super::shading::texel_response(b, wi, wo, reading, diffuse) * if volumetric { volume_factor(wi, wo) } else { 1.0 } } else { Vec3::ZERO })
}

/// ∫ L(ω) · g(ω) dω over the sphere on an `n` × 2n grid of equal solid angle in the
/// map's own frame, the map looked up texel by texel (g is skipped where L is 0).
pub fn env_quadrature(map: &EnvMap, n: usize, g: impl Fn(Vec3) -> Vec3) -> Vec3 {
    let mut sum = glam::DVec3::ZERO;
    let cell = 4.0 * PI as f64 / (2 * n * n) as f64;
    for j in 0..n {
        let cos_theta = 1.0 - 2.0 * (j as f32 + 0.5) / n as f32;
        let v = cos_theta.clamp(-1.0, 1.0).acos() / PI;
        for i in 0..2 * n {
            let wi = map.direction((i as f32 + 0.5) / (2 * n) as f32, v);
            let l = map.eval(wi);
            if l.max_element() > 0.0 {
                sum += (l * g(wi)).as_dvec3();
            }
        }
    }
    (sum * cell).as_vec3()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::{ClothOpenness, ClothParams, ClothTransmission, cloth_frame};
    use crate::scene::{EnvMapOptions, Sky, direction_from_angles};

    fn texel(kd: Vec3, lobes: &[ClothLobe], n: Vec3, t: Vec3) -> TexelBrdf {
        TexelBrdf { params: ClothParams::new(kd, 1.46, 0.5, lobes), frames: [cloth_frame(n, t); crate::brdf::MAX_LOBES], transmission: Default::default(), gradient: [0.0; 4], curvature: [0.0; 6], cylinder: false }
    }

    #[test]
    fn erf_matches_known_values() {
        for (x, e) in [(0.0f32, 0.0f32), (0.5, 0.520_499_9), (1.0, 0.842_700_8), (2.0, 0.995_322_3), (-1.0, -0.842_700_8), (5.0, 1.0)] {
            assert!((env_erf(x) - e).abs() < 3e-7, "erf({x}) = {} vs {e}", env_erf(x));
        }
    }

    #[test]
    fn a_constant_environment_gives_the_hemispherical_integral() {
        // Under L = 1 the SG mixture must integrate the lobe itself: compare with the
        // brute-force integral of the same response.
        let env_map = EnvMap::constant(Vec3::ONE).unwrap();
        let env = PrefilteredEnv::new(&env_map);
        let cases = [
            (ClothLobe { k: Vec3::ONE, beta: 0.05, gamma: 0.0 }, Vec3::Z, Vec3::X),
            (ClothLobe { k: Vec3::ONE, beta: 0.3, gamma: 0.8 }, Vec3::new(0.2, 0.1, 1.0), Vec3::Y),
            (ClothLobe { k: Vec3::ONE, beta: 0.8, gamma: 0.0 }, Vec3::new(-0.3, 0.4, 0.9), Vec3::new(1.0, 1.0, 0.0)),
        ];
        for (ci, (lobe, n, t)) in cases.into_iter().enumerate() {
            for reading in [BrdfReading::Bounded, BrdfReading::Width, BrdfReading::Held] {
                for wo in [direction_from_angles(10.0, 0.0), direction_from_angles(50.0, 70.0), direction_from_angles(75.0, 200.0)] {
                    let b = texel(Vec3::ZERO, &[lobe], n, t);
                    let exact = texel_env_response_quadrature(&b, wo, reading, false, DiffuseLaw::Lambert, &env_map, 600).x;
                    // The flyaway budget's 8 SGs are coarser in φ: measured up to 16.5% off
                    // (a wide lobe seen at 75°), against 3.7% with the surface's 16.
                    for (budget, tol) in [(EnvBudget::SURFACE, 0.03), (EnvBudget::FLYAWAY, 0.2)] {
                        let sg = texel_env_response(&b, wo, reading, false, DiffuseLaw::Lambert, budget, &env).x;
                        assert!((sg - exact).abs() <= tol * exact + 1e-4, "case {ci} {reading:?} ω_o {wo} {budget:?}: SG {sg} vs ∫ {exact}");
                    }
                }
            }
        }
    }

    #[test]
    fn a_visibility_gradient_under_an_environment_tracks_the_integral() {
        // The gradient (format 1.12) is read at each lookup group's mean direction and
        // at (2/3) n_0 for the diffuse term; the brute-force integral applies it to every
        // direction. Under a constant map, and under the sky with its sun taken out as a
        // light, as the renderers take it (the light shaded with the gradient exactly).
        let sky = Sky::default().env_map(EnvMapOptions { scale: 1.0, rotate_deg: 40.0 }).unwrap();
        let constant = EnvMap::constant(Vec3::ONE).unwrap();
        let g = [0.4, -0.3, 0.25, 0.5];
        let mut worst = [0.0f32; 2];
        for (m, map) in [&constant, &sky].into_iter().enumerate() {
            let env = if m == 0 { PrefilteredEnv::new(map) } else { PrefilteredEnv::with_lights(map, crate::scene::ExtractOptions::default()).unwrap() };
            let lit = |b: &TexelBrdf, wo: Vec3| -> Vec3 {
                env.lights.iter().map(|l| {
                    let s = l.sample(Vec3::ZERO);
                    if s.wi.z > 0.0 { s.irradiance * super::super::shading::texel_response(b, s.wi, wo, BrdfReading::Bounded, DiffuseLaw::LommelSeeliger) } else { Vec3::ZERO }
                }).sum()
            };
            for (lobe, n, t) in [
                (ClothLobe { k: Vec3::ONE, beta: 0.3, gamma: 0.8 }, Vec3::new(0.2, 0.1, 1.0), Vec3::Y),
                (ClothLobe { k: Vec3::ONE, beta: 0.1, gamma: 0.0 }, Vec3::Z, Vec3::X),
                (ClothLobe { k: Vec3::ONE, beta: 0.6, gamma: 0.0 }, Vec3::new(-0.3, 0.4, 0.9), Vec3::new(1.0, 1.0, 0.0)),
            ] {
                for kd in [Vec3::ZERO, Vec3::splat(0.3)] {
                    for wo in [direction_from_angles(10.0, 0.0), direction_from_angles(50.0, 70.0), direction_from_angles(70.0, 200.0)] {
                        let mut b = texel(kd, &[lobe], n, t);
                        b.gradient = g;
                        let exact = texel_env_response_quadrature(&b, wo, BrdfReading::Bounded, false, DiffuseLaw::LommelSeeliger, map, 600);
                        let sg = texel_env_response(&b, wo, BrdfReading::Bounded, false, DiffuseLaw::LommelSeeliger, EnvBudget::SURFACE, &env) + lit(&b, wo);
                        // The same texel without its gradient: the mixture's own error.
                        b.gradient = [0.0; 4];
                        let plain = (texel_env_response(&b, wo, BrdfReading::Bounded, false, DiffuseLaw::LommelSeeliger, EnvBudget::SURFACE, &env) + lit(&b, wo) - texel_env_response_quadrature(&b, wo, BrdfReading::Bounded, false, DiffuseLaw::LommelSeeliger, map, 600)).length();
                        let e = ((sg - exact).length() - plain).max(0.0) / exact.length().max(1e-6);
                        worst[m] = worst[m].max(e);
                    }
                }
            }
        }
        eprintln!("visibility gradient under a constant map / the sky: worst error beyond the mixture's own {:.4} / {:.4}", worst[0], worst[1]);
        // Measured 2.0% and 2.1%.
        assert!(worst[0] <= 0.03 && worst[1] <= 0.05, "{worst:?}");
    }

    #[test]
    fn the_diffuse_laws_integrate_a_constant_environment() {
        // k_d alone: E(n) · H must be the integral of k_d · D over the upper hemisphere.
        // The tile's horizon cuts a tilted normal's hemisphere, so only n = ẑ is exact;
        // the Lommel–Seeliger cap at μ_i + μ_o = 0.1 moves grazing views by < 2%.
        let env_map = EnvMap::constant(Vec3::ONE).unwrap();
        let env = PrefilteredEnv::new(&env_map);
        for law in [DiffuseLaw::Lambert, DiffuseLaw::LommelSeeliger] {
            for (theta, tol) in [(0.0, 0.01), (40.0, 0.01), (70.0, 0.01), (85.0, 0.02)] {
                let wo = direction_from_angles(theta, 30.0);
                let b = texel(Vec3::ONE, &[], Vec3::Z, Vec3::X);
                let exact = texel_env_response_quadrature(&b, wo, BrdfReading::Bounded, false, law, &env_map, 600).x;
                let sg = texel_env_response(&b, wo, BrdfReading::Bounded, false, law, EnvBudget::SURFACE, &env).x;
                assert!((sg - exact).abs() <= tol * exact, "{law:?} θ_o {theta}: {sg} vs ∫ {exact}");
            }
        }
        // Lommel–Seeliger brightens a grazing view over Lambert's π.
        let b = texel(Vec3::ONE, &[], Vec3::Z, Vec3::X);
        let grazing = texel_env_response(&b, direction_from_angles(80.0, 0.0), BrdfReading::Bounded, false, DiffuseLaw::LommelSeeliger, EnvBudget::SURFACE, &env).x;
        assert!(grazing > 2.0 * PI, "{grazing}");
    }

    #[test]
    fn extreme_lobes_stay_finite() {
        let env = PrefilteredEnv::new(&Sky::default().env_map(EnvMapOptions::default()).unwrap());
        let frames = [(Vec3::Z, Vec3::X), (Vec3::ZERO, Vec3::ZERO), (Vec3::X, Vec3::X), (Vec3::new(0.0, 0.0, -1.0), Vec3::Y)];
        for (beta, gamma) in [(BETA_MIN, 0.0), (BETA_MAX, 0.0), (BETA_MIN, crate::brdf::GAMMA_MIN), (1.0, crate::brdf::GAMMA_MAX), (-5.0, -1.0), (f32::NAN, f32::NAN)] {
            for (n, t) in frames {
                for wo in [Vec3::Z, Vec3::new(1.0, 0.0, 1e-4).normalize(), direction_from_angles(89.9, 10.0)] {
                    for reading in [BrdfReading::Bounded, BrdfReading::Width, BrdfReading::Held] {
                        let b = texel(Vec3::splat(K_MAX), &[ClothLobe { k: Vec3::splat(K_MAX), beta, gamma }], n, t);
                        let r = texel_env_response(&b, wo, reading, true, DiffuseLaw::LommelSeeliger, EnvBudget::SURFACE, &env);
                        assert!(r.is_finite() && r.min_element() >= 0.0, "β {beta} γ {gamma} n {n} ω_o {wo}: {r}");
                    }
                }
            }
        }
    }

    /// Random texels (1–3 lobes, tilted frames, both readings) under the built-in sky,
    /// its sun taken out as a light: SG mixture + light against brute force over the
    /// whole map, per texel. Returns the sorted relative errors.
    fn sky_errors(budget: EnvBudget, cylinder: bool) -> Vec<f32> {
        let map = Sky::default().env_map(EnvMapOptions { scale: 1.0, rotate_deg: 15.0 }).unwrap();
        let env = PrefilteredEnv::with_lights(&map, crate::scene::ExtractOptions::default()).unwrap();
        assert_eq!(env.lights.len(), 1, "the sun is a light");
        // What a renderer adds for the extracted lights (unshadowed here).
        let lit = |b: &TexelBrdf, wo: Vec3, reading, volumetric, diffuse| -> Vec3 {
            env.lights.iter().map(|l| {
                let s = l.sample(Vec3::ZERO);
                if s.wi.z > 0.0 { s.irradiance * super::super::shading::texel_response(b, s.wi, wo, reading, diffuse) * if volumetric { volume_factor(s.wi, wo) } else { 1.0 } } else { Vec3::ZERO }
            }).sum()
        };
        let mut h = 0x1234_5678u64;
        let mut rnd = || {
            h ^= h << 13;
            h ^= h >> 7;
            h ^= h << 17;
            (h >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut errors = Vec::new();
        for case in 0..60 {
            let n = Vec3::new(rnd() - 0.5, rnd() - 0.5, 1.0).normalize();
            let t = Vec3::new(rnd() - 0.5, rnd() - 0.5, 0.2 * (rnd() - 0.5));
            let lobes: Vec<ClothLobe> = (0..1 + case % 3).map(|_| ClothLobe { k: Vec3::new(0.5 + rnd(), 0.5 + rnd(), 0.5 + rnd()), beta: 0.03 + 0.6 * rnd() * rnd(), gamma: if rnd() < 0.5 { 0.0 } else { 0.2 + 1.5 * rnd() } }).collect();
            let mut b = texel(Vec3::splat(0.05 * rnd()), &lobes, n, t);
            let wo = direction_from_angles(70.0 * rnd(), 360.0 * rnd());
            let reading = match case % 8 {
                3 => BrdfReading::Width,
                7 => BrdfReading::Held,
                _ => BrdfReading::Bounded,
            };
            let mut volumetric = case % 2 == 0;
            let mut diffuse = if case % 3 == 1 { DiffuseLaw::LommelSeeliger } else { DiffuseLaw::Lambert };
            if cylinder {
                // A flyaway: a fibre of axis n + t (any tilt), shaded as the renderers do.
                b = super::super::shading::in_fiber_frame(b, n + t, wo, crate::brdf::FiberLobes::Cylinder);
                (volumetric, diffuse) = (false, DiffuseLaw::Lambert);
            }
            let sg = texel_env_response(&b, wo, reading, volumetric, diffuse, budget, &env) + lit(&b, wo, reading, volumetric, diffuse);
            let exact = texel_env_response_quadrature(&b, wo, reading, volumetric, diffuse, &map, 700);
            assert!(sg.is_finite() && sg.min_element() >= 0.0);
            errors.push((sg - exact).length() / exact.length().max(1e-6));
        }
        errors.sort_by(|a, b| a.total_cmp(b));
        errors
    }

    fn median_p90_max(e: &[f32]) -> (f32, f32, f32) {
        (e[e.len() / 2], e[e.len() * 9 / 10], *e.last().unwrap())
    }

    #[test]
    fn under_the_sky_the_mixture_tracks_the_integral() {
        // Measured (runtime/ENV_MEASUREMENTS.md): the surface budget, 16 SGs in 4 lookups,
        // median 2.4%, p90 7.8%, worst 16% (2.2 / 6.3 / 16% when the chain blurred the
        // ground into the horizon); bounds with margin. (With the sun left in the map:
        // median 9%, p90 28%, worst 69%.)
        let (median, p90, max) = median_p90_max(&sky_errors(EnvBudget::SURFACE, false));
        eprintln!("SG mixture vs brute force under the sky: median {median:.4}, p90 {p90:.4}, max {max:.4}");
        assert!(median <= 0.04 && p90 <= 0.1 && max <= 0.25, "median {median}, p90 {p90}, max {max}");
    }

    #[test]
    fn the_flyaway_budget_stays_close_to_the_integral() {
        // Flyaways get 8 SGs in one lookup: measured median 3.7%, p90 9.2%, worst 25.6%
        // (runtime/ENV_MEASUREMENTS.md); bounds with margin.
        let (median, p90, max) = median_p90_max(&sky_errors(EnvBudget::FLYAWAY, false));
        eprintln!("flyaway budget vs brute force under the sky: median {median:.4}, p90 {p90:.4}, max {max:.4}");
        assert!(median <= 0.07 && p90 <= 0.15 && max <= 0.35, "median {median}, p90 {p90}, max {max}");
    }

    #[test]
    fn a_cylinder_lobe_under_the_sky_tracks_the_integral() {
        // Format 1.11's flyaway lobes (EnvSide::Cylinder: the whole circle of azimuths)
        // with the flyaway budget, against brute force of `brdf::cloth_cylinder_lobe`.
        // Measured: median 1.1%, p90 15.2%, worst 37.6% (the facing lobes: 3.7 / 9.2 /
        // 25.6%); bounds with margin.
        let (median, p90, max) = median_p90_max(&sky_errors(EnvBudget::FLYAWAY, true));
        eprintln!("cylinder lobes, flyaway budget vs brute force under the sky: median {median:.4}, p90 {p90:.4}, max {max:.4}");
        assert!(median <= 0.05 && p90 <= 0.2 && max <= 0.45, "median {median}, p90 {p90}, max {max}");
    }

    #[test]
    fn a_cylinder_lobe_under_a_constant_environment_is_its_integral() {
        let env_map = EnvMap::constant(Vec3::ONE).unwrap();
        let env = PrefilteredEnv::new(&env_map);
        let mut worst = (0.0f32, 0.0f32);
        for (beta, axis) in [(0.05, Vec3::X), (0.3, Vec3::new(1.0, 1.0, 0.3)), (0.8, Vec3::new(0.2, -1.0, 0.6)), (0.15, Vec3::Z)] {
            for reading in [BrdfReading::Bounded, BrdfReading::Width, BrdfReading::Held] {
                for wo in [direction_from_angles(10.0, 0.0), direction_from_angles(50.0, 70.0), direction_from_angles(75.0, 200.0)] {
                    let lobe = ClothLobe { k: Vec3::ONE, beta, gamma: 0.7 };
                    let b = super::super::shading::in_fiber_frame(texel(Vec3::ZERO, &[lobe], Vec3::Z, Vec3::X), axis, wo, crate::brdf::FiberLobes::Cylinder);
                    let exact = texel_env_response_quadrature(&b, wo, reading, false, DiffuseLaw::Lambert, &env_map, 600).x;
                    // Measured: worst 24.8% (16 SGs) and 26.7% (8 SGs), both a lobe of β 0.8
                    // over the whole circle of azimuths, which half as many columns per
                    // radian as a facing lobe's cut coarsely (runtime/ENV_MEASUREMENTS.md).
                    for (budget, tol) in [(EnvBudget::SURFACE, 0.3), (EnvBudget::FLYAWAY, 0.3)] {
                        let sg = texel_env_response(&b, wo, reading, false, DiffuseLaw::Lambert, budget, &env).x;
                        let e = if exact > 0.01 { (sg - exact).abs() / exact } else { 0.0 };
                        if budget == EnvBudget::SURFACE { worst.0 = worst.0.max(e) } else { worst.1 = worst.1.max(e) }
                        // The floor: a vertical fibre seen at 75° has its band below the
                        // horizon (θ_i = −15°), its integral a tail of 0.005 that no SG
                        // above the horizon holds.
                        assert!((sg - exact).abs() <= tol * exact + 0.01, "β {beta} axis {axis} {reading:?} ω_o {wo} {budget:?}: SG {sg} vs ∫ {exact}");
                    }
                }
            }
        }
        eprintln!("cylinder lobes under a constant map: worst {:.4} (surface budget), {:.4} (flyaway budget)", worst.0, worst.1);
    }

    #[test]
    fn the_transmission_diffuse_factor_is_its_integral() {
        // c(τ) against 2∫₀¹ μ A(τ; μ, 1) dμ by the midpoint rule (the attenuation itself,
        // its clamp at μ = 0.05 included): within 0.3% and monotone from c(0) = 1.
        let mut last = f32::INFINITY;
        for tau in [0.0f32, 1e-4, 0.01, 0.1, 0.5, 0.999, 1.0, 1.5, 3.0, 7.0, 16.0, 100.0] {
            let n = 200_000;
            let exact: f64 = (0..n).map(|i| { let mu = (i as f64 + 0.5) / n as f64; 2.0 * mu * crate::brdf::cloth_transmission_attenuation(tau, mu as f32, 1.0) as f64 }).sum::<f64>() / n as f64;
            let c = transmission_env_diffuse_factor(tau);
            assert!(((c as f64) - exact).abs() <= 3e-3 * exact + 1e-6, "τ {tau}: c {c} vs ∫ {exact}");
            assert!(c <= last && c > 0.0, "τ {tau}: {c} after {last}");
            last = c;
        }
        assert_eq!(transmission_env_diffuse_factor(0.0), 1.0);
        assert!(transmission_env_diffuse_factor(f32::NAN) == 1.0 && transmission_env_diffuse_factor(-3.0) == 1.0);
    }

    /// The built-in sky upside down (its sun 35° below the horizon, its zenith's blue
    /// under the sheet), the sun taken out as a light, turned by 15°.
    fn sky_below() -> (EnvMap, PrefilteredEnv) {
        let sky = Sky::default().env_map(EnvMapOptions { scale: 1.0, rotate_deg: 15.0 }).unwrap();
        let (w, h) = (sky.width(), sky.height());
        let texels = (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| sky.texel(x, h - 1 - y)).collect();
        let map = sky.with_texels(texels).unwrap();
        let env = PrefilteredEnv::with_lights(&map, crate::scene::ExtractOptions::default()).unwrap();
        (map, env)
    }

    /// Random transmission terms (tilted frames, τ up to 3, with and without falloff)
    /// under `map`: mixture + the extracted lights below against brute force, per term.
    /// With `visibility`, each term has a random transmission visibility (format 1.16),
    /// |g| ≤ 0.6 and |q| ≤ 0.4 per coefficient. Sorted relative errors.
    fn through_errors(map: &EnvMap, env: &PrefilteredEnv, budget: EnvBudget, visibility: bool) -> Vec<f32> {
        let mut rng = crate::brdf::twin::SplitMix64(0x9e37_79b9);
        let mut rnd = || rng.next_f32();
        let mut errors = Vec::new();
        for case in 0..60 {
            let n = Vec3::new(rnd() - 0.5, rnd() - 0.5, 1.0).normalize();
            let f = cloth_frame(n, Vec3::new(rnd() - 0.5, rnd() - 0.5, 0.2 * (rnd() - 0.5)));
            let t = ClothTransmission {
                kd: Vec3::splat(0.05 * rnd()) * (case % 3) as f32,
                lobe: ClothLobe { k: Vec3::new(0.2 + rnd(), 0.2 + rnd(), 0.2 + rnd()), beta: 0.05 + 0.6 * rnd() * rnd(), gamma: if rnd() < 0.5 { 0.0 } else { 0.2 + 1.5 * rnd() } },
                tau: 3.0 * rnd() * rnd(),
                gap: Default::default(),
                grad: if visibility { [1.2 * rnd() - 0.6, 1.2 * rnd() - 0.6, 1.2 * rnd() - 0.6, 1.2 * rnd() - 0.6] } else { [0.0; 4] },
                curv: if visibility { std::array::from_fn(|_| 0.8 * rnd() - 0.4) } else { [0.0; 6] },
            };
            let wo = direction_from_angles(70.0 * rnd(), 360.0 * rnd());
            let lit: Vec3 = env.lights.iter().map(|l| { let s = l.sample(Vec3::ZERO); s.irradiance * crate::brdf::cloth_transmission_response(&t, &f, s.wi, wo) }).sum();
            let sg = transmission_env_response(&t, &f, wo, budget, env) + lit;
            let exact = transmission_env_response_quadrature(&t, &f, wo, map, 700);
            assert!(sg.is_finite() && sg.min_element() >= 0.0);
            errors.push((sg - exact).length() / exact.length().max(1e-6));
        }
        errors.sort_by(|a, b| a.total_cmp(b));
        errors
    }

    #[test]
    fn light_through_the_cloth_tracks_the_integral() {
        // Measured (runtime/ENV_MEASUREMENTS.md, "Light through the cloth"): a constant
        // map median 0.7%, p90 4.3%, worst 53%; the sky upside down median 2.0%, p90
        // 6.7%, worst 53%. The worst is one term, a narrow lobe (β 0.05) of a normal
        // tilted 26° whose peak lies at the tile's horizon, worth 3e-5 against the others'
        // 1e-2: SG cells straddle the cut there. Bounds with margin.
        let constant = EnvMap::constant(Vec3::ONE).unwrap();
        let (m, p, x) = median_p90_max(&through_errors(&constant, &PrefilteredEnv::new(&constant), EnvBudget::SURFACE, false));
        eprintln!("through the cloth, constant map: median {m:.4}, p90 {p:.4}, max {x:.4}");
        assert!(m <= 0.03 && p <= 0.08 && x <= 0.7, "constant map: median {m}, p90 {p}, max {x}");
        let (map, env) = sky_below();
        assert_eq!(env.lights.len(), 1, "the sun below is a light");
        assert!(env.lights_below());
        let (m, p, x) = median_p90_max(&through_errors(&map, &env, EnvBudget::SURFACE, false));
        eprintln!("through the cloth, the sky upside down: median {m:.4}, p90 {p:.4}, max {x:.4}");
        assert!(m <= 0.04 && p <= 0.15 && x <= 0.7, "sky upside down: median {m}, p90 {p}, max {x}");
    }

    #[test]
    fn the_transmission_visibility_under_a_map_tracks_the_integral() {
        // The transmission visibility (format 1.16) read at each lookup group's mean
        // direction below the sheet, and for k_dt at the lower cosine lobe's, −(2/3) ẑ,
        // against brute force with M_t at every direction. Measured (|g| ≤ 0.6, |q| ≤ 0.4
        // per coefficient): a constant map median 1.5%, p90 6.6%, worst 13%; the sky
        // upside down median 2.3%, p90 8.6%, worst 20% (without it 0.7 / 4.3 / 53% and
        // 2.0 / 6.7 / 53%; the gradient alone 1.0 / 5.4 / 19% and 2.7 / 9.6 / 23%). Bounds
        // with margin.
        let constant = EnvMap::constant(Vec3::ONE).unwrap();
        let (m, p, x) = median_p90_max(&through_errors(&constant, &PrefilteredEnv::new(&constant), EnvBudget::SURFACE, true));
        eprintln!("transmission visibility, constant map: median {m:.4}, p90 {p:.4}, max {x:.4}");
        let (map, env) = sky_below();
        let (sm, sp, sx) = median_p90_max(&through_errors(&map, &env, EnvBudget::SURFACE, true));
        eprintln!("transmission visibility, the sky upside down: median {sm:.4}, p90 {sp:.4}, max {sx:.4}");
        assert!(m <= 0.03 && p <= 0.1 && x <= 0.4, "constant map: median {m}, p90 {p}, max {x}");
        assert!(sm <= 0.05 && sp <= 0.16 && sx <= 0.45, "sky upside down: median {sm}, p90 {sp}, max {sx}");
    }

    #[test]
    fn a_map_dark_below_the_horizon_sends_nothing_through() {
        // The sky's ground is lit (0.02); with it black, nothing is below.
        let lit = Sky::default().env_map(EnvMapOptions::default()).unwrap();
        assert!(PrefilteredEnv::new(&lit).lights_below());
        let (w, h) = (lit.width(), lit.height());
        let texels = (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| if lit.direction(0.5, (y as f32 + 0.5) / h as f32).z < 0.0 { Vec3::ZERO } else { lit.texel(x, y) }).collect();
        let dark = PrefilteredEnv::new(&lit.with_texels(texels).unwrap());
        assert!(!dark.lights_below());
        // A term with no transmission passes nothing, and a view from below sees nothing.
        let (_, env) = sky_below();
        let f = cloth_frame(Vec3::Z, Vec3::X);
        let t = ClothTransmission { kd: Vec3::splat(0.1), lobe: ClothLobe { k: Vec3::ONE, beta: 0.2, gamma: 0.0 }, tau: 0.5, ..Default::default() };
        assert!(transmission_env_response(&t, &f, direction_from_angles(30.0, 0.0), EnvBudget::SURFACE, &env).min_element() > 0.0);
        assert_eq!(transmission_env_response(&ClothTransmission::default(), &f, Vec3::Z, EnvBudget::SURFACE, &env), Vec3::ZERO);
        assert_eq!(transmission_env_response(&t, &f, -Vec3::Z, EnvBudget::SURFACE, &env), Vec3::ZERO);
        // Extreme terms stay finite.
        for (beta, gamma, tau) in [(BETA_MIN, 0.0, 0.0), (BETA_MAX, crate::brdf::GAMMA_MAX, crate::brdf::TAU_MAX), (f32::NAN, f32::NAN, f32::NAN), (-1.0, -1.0, 1e9)] {
            let t = ClothTransmission { kd: Vec3::splat(K_MAX), lobe: ClothLobe { k: Vec3::splat(K_MAX), beta, gamma }, tau, gap: ClothOpenness { o: beta, q: tau, aniso: [gamma, -gamma] }, grad: [0.0; 4], curv: [0.0; 6] };
            for wo in [Vec3::Z, Vec3::new(1.0, 0.0, 1e-4).normalize()] {
                let r = transmission_env_response(&t, &f, wo, EnvBudget::SURFACE, &env);
                assert!(r.is_finite() && r.min_element() >= 0.0, "β {beta} γ {gamma} τ {tau} ω_o {wo}: {r}");
            }
        }
    }

    /// A texel's openness shows the map behind the sheet along the view ray, O(μ_o) ·
    /// L(−ω_o): exactly under a map constant below, and from the side the ray goes to.
    #[test]
    fn the_gaps_show_the_map_behind_the_sheet() {
        let sky = Sky::default().env_map(EnvMapOptions::default()).unwrap();
        let (w, h) = (sky.width(), sky.height());
        let below = |x: u32, y: u32| sky.direction((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
        let constant: Vec<Vec3> = (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| if below(x, y).z < 0.0 { Vec3::new(2.0, 1.0, 0.5) } else { Vec3::ZERO }).collect();
        let env = PrefilteredEnv::new(&sky.with_texels(constant).unwrap());
        let f = cloth_frame(Vec3::Z, Vec3::X);
        let gap = ClothOpenness { o: 0.04, q: 1.2, aniso: [0.5, -0.3] };
        let t = ClothTransmission { gap, ..Default::default() };
        assert!(!t.is_zero(), "a texel that is only open lets light through");
        for polar in [0.0f32, 30.0, 60.0, 80.0] {
            let wo = direction_from_angles(polar, 70.0);
            let expect = Vec3::new(2.0, 1.0, 0.5) * cloth_openness(&gap, wo);
            let r = transmission_env_response(&t, &f, wo, EnvBudget::SURFACE, &env);
            assert!((r - expect).abs().max_element() <= 1e-3 * expect.max_element() + 1e-9, "polar {polar}: {r} vs {expect}");
        }
        // Only the half of the ground the view ray goes on to is lit (x < 0): a view from
        // +x sees it through the gaps, a view from −x does not.
        let half: Vec<Vec3> = (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| { let d = below(x, y); if d.z < 0.0 && d.x < 0.0 { Vec3::ONE } else { Vec3::ZERO } }).collect();
        let env = PrefilteredEnv::new(&sky.with_texels(half).unwrap());
        let toward = transmission_env_response(&t, &f, direction_from_angles(40.0, 0.0), EnvBudget::SURFACE, &env);
        let away = transmission_env_response(&t, &f, direction_from_angles(40.0, 180.0), EnvBudget::SURFACE, &env);
        let open = cloth_openness(&gap, direction_from_angles(40.0, 0.0));
        assert!((toward.x - open).abs() < 0.05 * open && away.x < 0.05 * open, "{toward} / {away} vs {open}");
        // No openness, no term: the scattered part alone (none here).
        assert_eq!(transmission_env_response(&ClothTransmission::default(), &f, Vec3::Z, EnvBudget::SURFACE, &env), Vec3::ZERO);
    }

    /// The sweep behind the budgets: `cargo test -p fabric-runtime --release env_budget_sweep -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn env_budget_sweep() {
        for nodes in [16, 12, 8, 6, 4, 2, 1] {
            for lookups in [4, 2, 1] {
                if lookups > nodes {
                    continue;
                }
                let (m, p, x) = median_p90_max(&sky_errors(EnvBudget { nodes, lookups }, false));
                eprintln!("nodes {nodes:2} lookups {lookups}: median {:.1}%, p90 {:.1}%, max {:.1}%", 100.0 * m, 100.0 * p, 100.0 * x);
            }
        }
        // The transmission term under the sky upside down.
        let (map, env) = sky_below();
        for (nodes, lookups) in [(16, 4), (12, 3), (8, 2), (8, 1), (6, 1), (4, 1)] {
            let (m, p, x) = median_p90_max(&through_errors(&map, &env, EnvBudget { nodes, lookups }, false));
            eprintln!("through the cloth, nodes {nodes:2} lookups {lookups}: median {:.1}%, p90 {:.1}%, max {:.1}%", 100.0 * m, 100.0 * p, 100.0 * x);
        }
    }
}
