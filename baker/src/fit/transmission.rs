//! Fitting the transmission term of a BSDF texel (paper §7.2, "Extensions": "our model
//! can be extended to full BSDF by also fitting the transmission component").
//!
//! The training renderings are lit from below the sheet (ω_i.z < 0) and seen from above.
//! For a texel with transmission (k_dt, k_t, β_t, γ_t) in its lobe-0 frame, the model's
//! radiance along a probe ray is linear in the k's once (β_t, γ_t) are chosen
//! (`fabric_runtime::brdf::cloth_transmission_response`):
//!
//! ```text
//! L = (k_dt + k_t · G(θ_l* + θ_u; β_t) · P(φ_l* + φ_u; γ_t)) · A(τ) · |ω_i.z|
//! A(τ) = exp(−τ·(1/μ_i + 1/μ_o − 2))
//! ```
//!
//! so, as for the reflection lobes (`cluster_fit`), Nelder–Mead searches
//! (ln β_t, ln γ_t, τ) and each trial solves the k's per RGB channel by NNLS on the 2×2
//! Gram matrix. τ is what a measured cloth needs most: without it (A ≡ 1, the first
//! version) the model passed 2–4× the light the volume does at grazing angles, where the
//! path through the cloth is longest (baker/FIT_MEASUREMENTS.md, "Transmission"). The
//! angles come from the runtime's own `cloth_angles` and `cloth_lobe_shape`, never a copy.
//!
//! The transmission visibility (format 1.16, `brdf::cloth_transmission_visibility`): at
//! one texel per fibre, the light that comes through a gap is seen on the wall that
//! faces the viewer and is lit through the gap from below, so what the volume shows along
//! a ray that the model says meets a texel depends on the side the ray and the light come
//! from, which a term even in their slant cannot say. Each texel's whole term is
//! multiplied by M_t = max(1 + g_u·(u_x, u_y) + g_l·(l_x, l_y) + q·e(l, u), 0) (u the
//! viewer's side above the sheet, l the light's below, e the reflection curvature's six
//! even terms: light straight through along the yarns is not light across them), fitted
//! as the reflection's visibility is (`fit::gradient`): alternating g, q by linear least
//! squares for fixed k's and the k's by [`refine_transmission`] on the samples scaled by
//! M_t ([`refine_transmission_with_visibility`]). baker/FIT_MEASUREMENTS.md,
//! "Transmission", measures what it buys.
//!
//! Energy: a texel may not pass more than it receives. The transmitted albedo
//! T(ω_i) = ∫ f_t(ω_i, ω_o) cos θ_o dω_o over the upper hemisphere is bounded by one for
//! every ω_i ([`transmission_albedo`]); a fit whose worst T exceeds [`ALBEDO_MAX`] is
//! scaled down to it ([`cap_energy`]).

use fabric_runtime::brdf::{BrdfReading, ClothFrame, ClothLobe, ClothTransmission, CURVATURE_MAX, GRADIENT_MAX, K_MAX, TAU_MAX, cloth_angles, cloth_lobe_shape, cloth_mirror_z, cloth_transmission, cloth_transmission_attenuation, cloth_transmission_visibility};
use glam::{DVec3, Vec3};

use super::cluster_fit::LOBE_SUPPORT_MIN;
use super::gradient::{Visibility, gradient_least_squares, visibility_least_squares};
use super::nnls::nnls_gram;
use super::simplex::{NelderMead, nelder_mead_restarts};

/// The largest transmitted albedo a fitted term may have.
pub const ALBEDO_MAX: f32 = 1.0;

/// The transmission visibility's ridge towards g = 0 and q = 0 (as the reflection's,
/// `fit::gradient`).
pub const GRADIENT_RIDGE: f64 = 0.05;

/// Alternations of (g for fixed k, k for fixed g) of the transmission visibility.
const GRADIENT_ROUNDS: usize = 4;

/// The BSDF-independent factors of one backlit sample in the frame of the texel hit.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TransGeo {
    /// θ_l* + θ_u and φ_l* + φ_u (the lower direction mirrored through the tile plane).
    pub theta_sum: f32,
    pub phi_sum: f32,
    /// |ω_i.z| (times the ray's weight, if any): the factor both terms carry.
    pub cos: f32,
    /// ω_i and ω_o in tile space: their z for the attenuation, their slant for the
    /// gradient.
    pub wi: Vec3,
    pub wo: Vec3,
}

impl TransGeo {
    /// The factors for light from `wi` and view `wo` on opposite sides of the tile plane
    /// in `frame` (0 when they are on the same side).
    pub fn new(frame: &ClothFrame, wi: Vec3, wo: Vec3) -> TransGeo {
        if !(wi.z * wo.z < 0.0) {
            return TransGeo::default();
        }
        let (upper, lower) = if wi.z > 0.0 { (wi, wo) } else { (wo, wi) };
        let (au, al) = (cloth_angles(frame, upper), cloth_angles(frame, cloth_mirror_z(lower)));
        TransGeo { theta_sum: al.theta + au.theta, phi_sum: al.phi + au.phi, cos: wi.z.abs(), wi, wo }
    }
}

/// One backlit sample with its target radiance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TransTarget {
    pub geo: TransGeo,
    pub radiance: Vec3,
}

/// Settings of a transmission fit.
#[derive(Clone, Debug, PartialEq)]
pub struct TransmissionFitOptions {
    /// Range of β_t (radians): light that crosses a cloth is spread far wider than a
    /// reflection.
    pub beta_range: [f32; 2],
    /// Range of γ_t (radians).
    pub gamma_range: [f32; 2],
    /// Largest τ searched (≤ TAU_MAX); 0 fixes A ≡ 1.
    pub tau_max: f32,
    pub max_evals: usize,
    pub restarts: usize,
    /// Samples used by the search (a stride); the final solve uses all.
    pub search_samples: usize,
    /// Samples per texel of the backlit training renderings (0: the bake's own spp).
    pub spp: u32,
    /// Rays per texel per view that measure the openness (`fit::openness`; 0: none, the
    /// texels are closed).
    pub openness_rays: u32,
    /// With the per-texel refinement, fit each texel's transmission visibility (format
    /// 1.16): its gradient with this ridge towards g = 0, relative to the normal
    /// equations' mean diagonal; `None`: none.
    pub gradient_ridge: Option<f64>,
    /// With the gradient, its curvature too, with this ridge towards q = 0; `None`: the
    /// gradient alone.
    pub curvature_ridge: Option<f64>,
}

impl Default for TransmissionFitOptions {
    fn default() -> Self {
        TransmissionFitOptions { beta_range: [0.03, 3.0], gamma_range: [0.05, 20.0], tau_max: 4.0, max_evals: 300, restarts: 2, search_samples: 6000, spp: 0, openness_rays: 8, gradient_ridge: Some(GRADIENT_RIDGE), curvature_ridge: Some(GRADIENT_RIDGE) }
    }
}

/// The result of a transmission fit.
#[derive(Clone, Debug, PartialEq)]
pub struct TransmissionFit {
    pub transmission: ClothTransmission,
    /// Σ‖L − L_ref‖² and Σ‖L_ref‖² over the samples.
    pub residual2: f64,
    pub target2: f64,
    pub samples: usize,
    /// Why the fit fell back (no samples, non-finite data), if it did.
    pub problem: Option<String>,
}

impl TransmissionFit {
    pub fn relative_residual(&self) -> f64 {
        if self.target2 > 0.0 { (self.residual2 / self.target2).sqrt() } else { 0.0 }
    }
}

/// The model's radiance for one sample: what `cpu::shading::texel_transmission_response`
/// gives (times the sample's weight, in `g.cos`), the gradient included.
pub fn predict_transmission(t: &ClothTransmission, g: &TransGeo) -> Vec3 {
    let kd = t.kd.max(Vec3::ZERO).min(Vec3::splat(K_MAX));
    let k = t.lobe.k.max(Vec3::ZERO).min(Vec3::splat(K_MAX));
    (kd + k * cloth_lobe_shape(g.theta_sum, g.phi_sum, t.lobe.beta, t.lobe.gamma, BrdfReading::Bounded)) * (g.cos * cloth_transmission_attenuation(t.tau, g.wi.z, g.wo.z) * cloth_transmission_visibility(t.grad, t.curv, g.wi, g.wo))
}

/// √(Σ‖L − L_ref‖² / Σ‖L_ref‖²) of `t` over `samples` (0 where they are all black).
pub fn relative_residual(t: &ClothTransmission, samples: &[TransTarget]) -> f64 {
    let (d2, r2) = samples.iter().fold((0f64, 0f64), |(d, r), s| (d + (predict_transmission(t, &s.geo) - s.radiance).as_dvec3().length_squared(), r + s.radiance.as_dvec3().length_squared()));
    if r2 > 0.0 { (d2 / r2).sqrt() } else { 0.0 }
}

/// Gram matrix (2×2), Aᵀb per channel and bᵀb per channel of the basis [c, S·c],
/// c = |ω_i.z|·A(τ); and the lobe's support, max S / S(0, 0) over the samples with c > 0
/// (as `cluster_fit`'s, [`LOBE_SUPPORT_MIN`]).
fn normal_equations(samples: &[TransTarget], stride: usize, beta: f32, gamma: f32, tau: f32) -> ([f64; 4], [[f64; 2]; 3], [f64; 3], f64) {
    let (mut g, mut atb, mut btb) = ([0f64; 4], [[0f64; 2]; 3], [0f64; 3]);
    let mut best = 0f32;
    for s in samples.iter().step_by(stride.max(1)) {
        let c = (s.geo.cos * cloth_transmission_attenuation(tau, s.geo.wi.z, s.geo.wo.z)) as f64;
        let shape = cloth_lobe_shape(s.geo.theta_sum, s.geo.phi_sum, beta, gamma, BrdfReading::Bounded);
        if c > 0.0 {
            best = best.max(shape);
        }
        let b = [c, c * shape as f64];
        g[0] += b[0] * b[0];
        g[1] += b[0] * b[1];
        g[3] += b[1] * b[1];
        let r = s.radiance.as_dvec3();
        for ch in 0..3 {
            atb[ch][0] += b[0] * r[ch];
            atb[ch][1] += b[1] * r[ch];
            btb[ch] += r[ch] * r[ch];
        }
    }
    g[2] = g[1];
    let support = (best / cloth_lobe_shape(0.0, 0.0, beta, gamma, BrdfReading::Bounded)) as f64;
    (g, atb, btb, support)
}

/// The k's of (β, γ) by NNLS per channel, and the residual; a lobe the samples never
/// come near ([`LOBE_SUPPORT_MIN`]) is held at k = 0.
fn solve(samples: &[TransTarget], stride: usize, beta: f32, gamma: f32, tau: f32) -> Option<([[f64; 2]; 3], f64)> {
    let (mut g, mut atb, btb, support) = normal_equations(samples, stride, beta, gamma, tau);
    if support < LOBE_SUPPORT_MIN {
        g[1] = 0.0;
        g[2] = 0.0;
        g[3] = 0.0;
        for a in &mut atb {
            a[1] = 0.0;
        }
    }
    let mut k = [[0f64; 2]; 3];
    let mut residual = 0.0;
    for ch in 0..3 {
        let sol = nnls_gram(&g, &atb[ch], btb[ch], 2).ok()?;
        if !sol.x.iter().all(|v| v.is_finite()) {
            return None;
        }
        k[ch] = [sol.x[0], sol.x[1]];
        residual += sol.residual2;
    }
    Some((k, residual))
}

/// Fits one cluster's transmission term to `samples`.
pub fn fit_transmission(samples: &[TransTarget], o: &TransmissionFitOptions) -> TransmissionFit {
    let target2: f64 = samples.iter().map(|s| s.radiance.as_dvec3().length_squared()).sum();
    let fallback = |problem: String| TransmissionFit { transmission: ClothTransmission::default(), residual2: target2, target2, samples: samples.len(), problem: Some(problem) };
    if samples.is_empty() {
        return fallback("no samples: the model shows none of this cluster's texels along any backlit training ray".into());
    }
    if !target2.is_finite() || samples.iter().any(|s| !(s.geo.cos.is_finite() && s.geo.theta_sum.is_finite() && s.geo.phi_sum.is_finite())) {
        return fallback("non-finite samples".into());
    }
    let stride = samples.len().div_ceil(o.search_samples.max(1));
    let tau_max = o.tau_max.clamp(0.0, TAU_MAX);
    // τ enters as x² (τ = 0 is reachable from inside the box).
    let decode = |x: &[f64]| {
        let (beta, gamma, tau) = (x[0].exp() as f32, x[1].exp() as f32, if tau_max > 0.0 { (x[2] * x[2]) as f32 } else { 0.0 });
        let inside = (o.beta_range[0]..=o.beta_range[1]).contains(&beta) && (o.gamma_range[0]..=o.gamma_range[1]).contains(&gamma) && tau <= tau_max;
        inside.then_some((beta, gamma, tau))
    };
    let objective = |x: &[f64]| decode(x).and_then(|(b, g, t)| solve(samples, stride, b, g, t)).map_or(f64::INFINITY, |(_, r)| r);
    let x0 = [0.5f64.ln(), 2.0f64.ln(), 0.5];
    let nm = NelderMead { max_evals: o.max_evals, ..Default::default() };
    let best = match nelder_mead_restarts(objective, &x0, &[0.7, 0.7, 0.4], &nm, o.restarts) {
        Ok(m) if m.f.is_finite() => m.x,
        Ok(_) => x0.to_vec(),
        Err(e) => return fallback(format!("search failed: {e}")),
    };
    let Some((beta, gamma, tau)) = decode(&best) else {
        return fallback("search left the parameter box".into());
    };
    let Some((k, residual2)) = solve(samples, 1, beta, gamma, tau) else {
        return fallback("linear solve failed".into());
    };
    let v = |j: usize| Vec3::new(k[0][j] as f32, k[1][j] as f32, k[2][j] as f32).clamp(Vec3::ZERO, Vec3::splat(K_MAX));
    let transmission = ClothTransmission { kd: v(0), lobe: ClothLobe { k: v(1), beta, gamma }, tau, ..Default::default() };
    TransmissionFit { transmission, residual2, target2, samples: samples.len(), problem: None }
}

/// Refines one texel's k's on its own samples, (β_t, γ_t) kept from its cluster's
/// `cluster`: NNLS with a ridge toward the cluster's k's (as `cluster_fit::refine_texel`).
pub fn refine_transmission(samples: &[TransTarget], cluster: &ClothTransmission, ridge: f64) -> ClothTransmission {
    if samples.is_empty() || cluster.lobe.beta <= 0.0 {
        return *cluster;
    }
    let (mut g, atb, btb, _) = normal_equations(samples, 1, cluster.lobe.beta, cluster.lobe.gamma, cluster.tau);
    let lambda = ridge * 0.5 * (g[0] + g[3]);
    g[0] += lambda;
    g[3] += lambda;
    let mut out = *cluster;
    for ch in 0..3 {
        let prior = [cluster.kd[ch] as f64, cluster.lobe.k[ch] as f64];
        let b = [atb[ch][0] + lambda * prior[0], atb[ch][1] + lambda * prior[1]];
        let Ok(sol) = nnls_gram(&g, &b, btb[ch] + lambda * (prior[0] * prior[0] + prior[1] * prior[1]), 2) else {
            return *cluster;
        };
        if !sol.x.iter().all(|v| v.is_finite()) {
            return *cluster;
        }
        out.kd[ch] = (sol.x[0] as f32).clamp(0.0, K_MAX);
        out.lobe.k[ch] = (sol.x[1] as f32).clamp(0.0, K_MAX);
    }
    out
}

/// Refines one texel's k's together with its transmission visibility (module docs):
/// [`refine_transmission`] without it, then alternations of the visibility by least
/// squares for fixed k's (the gradient with ridge `gradient_ridge`; the curvature too,
/// with its ridge, where `curvature_ridge` is given) and the k's on the samples scaled by
/// M_t. (β_t, γ_t, τ) stay the cluster's.
pub fn refine_transmission_with_visibility(samples: &[TransTarget], cluster: &ClothTransmission, ridge: f64, gradient_ridge: f64, curvature_ridge: Option<f64>) -> ClothTransmission {
    let plain = ClothTransmission { grad: [0.0; 4], curv: [0.0; 6], ..*cluster };
    refine_transmission_visibility_from(refine_transmission(samples, &plain, ridge), samples, cluster, ridge, gradient_ridge, curvature_ridge)
}

/// [`refine_transmission_with_visibility`] from `first`, the texel's refinement without
/// it (`refine_transmission` on the same samples), which the caller already has.
pub fn refine_transmission_visibility_from(first: ClothTransmission, samples: &[TransTarget], cluster: &ClothTransmission, ridge: f64, gradient_ridge: f64, curvature_ridge: Option<f64>) -> ClothTransmission {
    let plain = ClothTransmission { grad: [0.0; 4], curv: [0.0; 6], ..*cluster };
    let mut t = first;
    if samples.is_empty() || plain.lobe.beta <= 0.0 {
        return t;
    }
    for _ in 0..GRADIENT_ROUNDS {
        let unseen = ClothTransmission { grad: [0.0; 4], curv: [0.0; 6], ..t };
        // The least squares' features are (ω_o,x, ω_o,y, ω_i,x, ω_i,y) and the even
        // terms: the side above as ω_o and the side below as ω_i give (g_u, g_l).
        let rows = samples.iter().map(|s| {
            let (upper, lower) = if s.geo.wi.z > 0.0 { (s.geo.wi, s.geo.wo) } else { (s.geo.wo, s.geo.wi) };
            (predict_transmission(&unseen, &s.geo), s.radiance, lower, upper)
        });
        let v = match curvature_ridge {
            Some(q_ridge) => visibility_least_squares(rows, gradient_ridge, q_ridge),
            None => Visibility { g: gradient_least_squares(rows, gradient_ridge), q: [0.0; 6] },
        };
        let scaled: Vec<TransTarget> = samples.iter().map(|s| TransTarget { geo: TransGeo { cos: s.geo.cos * cloth_transmission_visibility(v.g, v.q, s.geo.wi, s.geo.wo), ..s.geo }, radiance: s.radiance }).collect();
        t = ClothTransmission { grad: v.g, curv: v.q, ..refine_transmission(&scaled, &plain, ridge) };
    }
    t
}

/// T(ω_i) = ∫ f_t(ω_i, ω_o) cos θ_o dω_o over the hemisphere opposite ω_i, RGB: the
/// fraction of the irradiance on the sheet that comes out the other side. Midpoint rule
/// in (cos θ_o, φ_o), `n` × 4`n` cells (n = 48 resolves β_t ≥ 0.03 to about 1%).
pub fn transmission_albedo(t: &ClothTransmission, frame: &ClothFrame, wi: Vec3, n: usize) -> Vec3 {
    let side = if wi.z < 0.0 { 1.0 } else { -1.0 };
    let (nt, np) = (n.max(4), 4 * n.max(4));
    let mut sum = DVec3::ZERO;
    for a in 0..nt {
        let mu = (a as f32 + 0.5) / nt as f32;
        let s = (1.0 - mu * mu).max(0.0).sqrt();
        for b in 0..np {
            let phi = std::f32::consts::TAU * (b as f32 + 0.5) / np as f32;
            let wo = Vec3::new(s * phi.cos(), s * phi.sin(), side * mu);
            sum += (cloth_transmission(t, frame, wi, wo) * mu).as_dvec3();
        }
    }
    (sum * (std::f64::consts::TAU / (nt * np) as f64)).as_vec3()
}

/// The worst transmitted albedo over a fan of light directions below the sheet (polar
/// angles 0°, 30°, 60° and 80°, 4 azimuths each), the largest channel's.
pub fn worst_albedo(t: &ClothTransmission, frame: &ClothFrame) -> f32 {
    let mut worst = 0f32;
    for polar in [0.0f32, 30.0, 60.0, 80.0] {
        for k in 0..if polar == 0.0 { 1 } else { 4 } {
            let (p, a) = (polar.to_radians(), std::f32::consts::FRAC_PI_2 * k as f32 + 0.3);
            let wi = Vec3::new(p.sin() * a.cos(), p.sin() * a.sin(), -p.cos());
            worst = worst.max(transmission_albedo(t, frame, wi, 32).max_element());
        }
    }
    worst
}

/// A bound on the transmitted albedo with no quadrature: (π·k_dt + 2π·k_t) per channel
/// (∫ G dθ ≤ 1 over θ, P ≤ 1 over φ ∈ (−π, π], both cosines ≤ 1; dω = cos θ dθ dφ)
/// times the visibility's largest M_t, 1 + |g_u| + |g_l| + 2·Σ|q_k| (|ω_xy| ≤ 1 on
/// either side, and no even term exceeds 2 in size).
pub fn albedo_bound(t: &ClothTransmission) -> f32 {
    let pi = std::f32::consts::PI;
    let c = t.grad.map(|g| if g.is_finite() { g.clamp(-GRADIENT_MAX, GRADIENT_MAX) } else { 0.0 });
    let even: f32 = t.curv.iter().map(|q| if q.is_finite() { q.abs().min(CURVATURE_MAX) } else { 0.0 }).sum();
    let m_max = 1.0 + c[0].hypot(c[1]) + c[2].hypot(c[3]) + 2.0 * even;
    (t.kd.max(Vec3::ZERO) * pi + t.lobe.k.max(Vec3::ZERO) * (2.0 * pi)).max_element() * m_max
}

/// The transmitted albedo as the bake reports it: the bound where it is within
/// [`ALBEDO_MAX`] (cheap, and an upper bound), else the quadrature's worst value.
pub fn albedo_estimate(t: &ClothTransmission, frame: &ClothFrame) -> f32 {
    let bound = albedo_bound(t);
    if bound <= ALBEDO_MAX { bound } else { worst_albedo(t, frame) }
}

/// `t` scaled so that its worst transmitted albedo is at most [`ALBEDO_MAX`].
pub fn cap_energy(t: &ClothTransmission, frame: &ClothFrame) -> ClothTransmission {
    let worst = albedo_estimate(t, frame);
    if !(worst > ALBEDO_MAX) {
        return *t;
    }
    let s = ALBEDO_MAX / worst;
    ClothTransmission { kd: t.kd * s, lobe: ClothLobe { k: t.lobe.k * s, ..t.lobe }, ..*t }
}

#[cfg(test)]
mod tests {
    use super::*;
    use fabric_runtime::brdf::{cloth_frame, cloth_transmission_response};

    fn truth() -> ClothTransmission {
        ClothTransmission { kd: Vec3::new(0.04, 0.03, 0.02), lobe: ClothLobe { k: Vec3::new(0.3, 0.25, 0.2), beta: 0.35, gamma: 1.2 }, tau: 0.6, ..Default::default() }
    }

    /// Backlit samples of a known term over random pairs in random tilted frames.
    fn synthetic(t: &ClothTransmission, noise: f32, count: usize) -> Vec<TransTarget> {
        let mut rng = crate::reference::rng::Rng::new(9, 8, 7);
        let hemi = |rng: &mut crate::reference::rng::Rng| {
            let z = 0.15 + 0.85 * rng.next_f32();
            let p = std::f32::consts::TAU * rng.next_f32();
            let s = (1.0 - z * z).sqrt();
            Vec3::new(s * p.cos(), s * p.sin(), z)
        };
        (0..count)
            .map(|_| {
                let frame = cloth_frame((Vec3::Z + 0.3 * (hemi(&mut rng) - Vec3::Z * 0.9)).normalize(), Vec3::new(1.0, 0.3 * (rng.next_f32() - 0.5), 0.0));
                let wo = hemi(&mut rng);
                // Half the lights near straight through, where the lobe is.
                let wi = if rng.next_f32() < 0.5 { (-wo + 0.3 * (hemi(&mut rng) - Vec3::Z)).normalize() } else { -hemi(&mut rng) };
                let wi = if wi.z > -0.05 { -hemi(&mut rng) } else { wi };
                let clean = cloth_transmission_response(t, &frame, wi, wo);
                TransTarget { geo: TransGeo::new(&frame, wi, wo), radiance: clean * (1.0 + noise * (2.0 * rng.next_f32() - 1.0)) }
            })
            .collect()
    }

    #[test]
    fn prediction_is_the_runtime_response() {
        let frame = cloth_frame(Vec3::new(0.2, -0.1, 1.0), Vec3::new(1.0, 0.5, 0.0));
        let (wi, wo) = (Vec3::new(0.3, -0.2, -0.9).normalize(), Vec3::new(-0.1, 0.4, 0.8).normalize());
        let a = predict_transmission(&truth(), &TransGeo::new(&frame, wi, wo));
        let b = cloth_transmission_response(&truth(), &frame, wi, wo);
        assert!((a - b).abs().max_element() <= 1e-6 * b.max_element(), "{a} vs {b}");
        assert_eq!(TransGeo::new(&frame, -wi, wo), TransGeo::default(), "same side: nothing");
    }

    #[test]
    fn recovers_a_known_term() {
        let fit = fit_transmission(&synthetic(&truth(), 0.0, 3000), &TransmissionFitOptions { max_evals: 800, restarts: 3, ..Default::default() });
        assert!(fit.problem.is_none());
        assert!(fit.relative_residual() < 0.01, "{}", fit.relative_residual());
        let (t, f) = (truth(), fit.transmission);
        assert!((f.lobe.beta - t.lobe.beta).abs() < 0.02 && (f.lobe.gamma - t.lobe.gamma).abs() < 0.1 && (f.tau - t.tau).abs() < 0.03, "{f:?}");
        assert!((f.kd - t.kd).abs().max_element() < 0.003 && (f.lobe.k - t.lobe.k).abs().max_element() < 0.02, "{f:?}");
        // Noisy: the residual is the noise's (uniform ±10%: RMS 5.8%).
        let fit = fit_transmission(&synthetic(&truth(), 0.1, 3000), &TransmissionFitOptions::default());
        assert!(fit.relative_residual() < 0.07, "{}", fit.relative_residual());
        assert!((fit.transmission.lobe.beta - 0.35).abs() < 0.05, "{:?}", fit.transmission);
    }

    #[test]
    fn refinement_follows_a_texel_with_many_samples_and_stays_put_without() {
        let cluster = truth();
        let brighter = ClothTransmission { kd: cluster.kd * 1.5, lobe: ClothLobe { k: cluster.lobe.k * 0.5, ..cluster.lobe }, ..cluster };
        let samples = synthetic(&brighter, 0.0, 500);
        let r = refine_transmission(&samples, &cluster, 1e-4);
        assert!((r.kd - brighter.kd).abs().max_element() < 2e-3 && (r.lobe.k - brighter.lobe.k).abs().max_element() < 1e-2, "{r:?}");
        assert_eq!(refine_transmission(&[], &cluster, 1e-4), cluster);
    }

    #[test]
    fn the_visibility_is_recovered_with_the_texels_ks() {
        // A texel whose term is its cluster's brighter and scaled by a known M_t: the
        // refinement with the gradient finds both, the one without cannot fit it.
        let cluster = truth();
        let g = [0.6, -0.4, -0.5, 0.3];
        let texel = ClothTransmission { kd: cluster.kd * 1.3, lobe: ClothLobe { k: cluster.lobe.k * 0.7, ..cluster.lobe }, grad: g, ..cluster };
        let samples = synthetic(&texel, 0.0, 1500);
        let residual = |t: &ClothTransmission| relative_residual(t, &samples);
        let r = refine_transmission_with_visibility(&samples, &cluster, 1e-4, 1e-4, None);
        assert!(r.grad.iter().zip(g).all(|(a, b)| (a - b).abs() < 0.03), "{:?}", r.grad);
        assert!((r.kd - texel.kd).abs().max_element() < 2e-3 && (r.lobe.k - texel.lobe.k).abs().max_element() < 1e-2, "{r:?}");
        assert!(residual(&r) < 0.01, "{}", residual(&r));
        let plain = refine_transmission(&samples, &cluster, 1e-4);
        assert!(residual(&plain) > 0.1, "without the gradient: {}", residual(&plain));
        // Without samples, the cluster's own term (no gradient).
        assert_eq!(refine_transmission_with_visibility(&[], &cluster, 1e-4, 0.05, Some(0.05)), cluster);
        // With the curvature: a texel with both is recovered too.
        let q = [0.3, -0.2, 0.1, -0.4, 0.25, 0.15];
        let texel = ClothTransmission { curv: q, ..texel };
        let samples = synthetic(&texel, 0.0, 2500);
        let r = refine_transmission_with_visibility(&samples, &cluster, 1e-4, 1e-5, Some(1e-5));
        assert!(r.grad.iter().zip(g).all(|(a, b)| (a - b).abs() < 0.05) && r.curv.iter().zip(q).all(|(a, b)| (a - b).abs() < 0.08), "{:?} {:?}", r.grad, r.curv);
        assert!(relative_residual(&r, &samples) < 0.01, "{}", relative_residual(&r, &samples));
    }

    #[test]
    fn energy_is_bounded() {
        let frame = cloth_frame(Vec3::Z, Vec3::X);
        // A diffuse k_dt passes π·k_dt (k_d carries no 1/π): the quadrature knows it.
        let diffuse = ClothTransmission { kd: Vec3::splat(0.2), ..Default::default() };
        let albedo = transmission_albedo(&diffuse, &frame, -Vec3::Z, 48);
        assert!((albedo.x - 0.2 * std::f32::consts::PI).abs() < 2e-3, "{albedo}");
        // A term passing more than it gets is scaled down to an albedo of 1, and one
        // within bounds is left alone.
        let bright = ClothTransmission { kd: Vec3::splat(0.5), lobe: ClothLobe { k: Vec3::splat(2.0), beta: 0.3, gamma: 0.0 }, tau: 0.0, ..Default::default() };
        assert!(worst_albedo(&bright, &frame) > 1.5);
        let capped = cap_energy(&bright, &frame);
        assert!((worst_albedo(&capped, &frame) - 1.0).abs() < 1e-3, "{}", worst_albedo(&capped, &frame));
        assert_eq!(cap_energy(&truth(), &frame), truth());
        assert!(worst_albedo(&truth(), &frame) < 1.0);
        // The cheap bound is a bound, on tilted frames too, with a transmission visibility.
        let graded = ClothTransmission { grad: [0.8, -0.5, -0.9, 0.4], curv: [0.6, -0.4, 0.5, -0.7, 0.3, 0.45], ..truth() };
        for t in [truth(), bright, diffuse, graded] {
            for n in [Vec3::Z, Vec3::new(0.5, 0.2, 1.0)] {
                let f = cloth_frame(n, Vec3::new(1.0, 0.3, 0.0));
                assert!(albedo_bound(&t) >= worst_albedo(&t, &f) * 0.999, "{t:?}");
            }
        }
    }

    #[test]
    fn degenerate_inputs_end_with_a_clear_result() {
        assert!(fit_transmission(&[], &TransmissionFitOptions::default()).problem.unwrap().contains("no samples"));
        let black: Vec<TransTarget> = synthetic(&truth(), 0.0, 40).into_iter().map(|s| TransTarget { radiance: Vec3::ZERO, ..s }).collect();
        let fit = fit_transmission(&black, &TransmissionFitOptions::default());
        assert!(fit.problem.is_none() && fit.transmission.is_zero() && fit.residual2 == 0.0, "{fit:?}");
        let nan = vec![TransTarget { geo: TransGeo { theta_sum: f32::NAN, phi_sum: 0.0, cos: 1.0, wi: -Vec3::Z, wo: Vec3::Z }, radiance: Vec3::ONE }];
        assert!(fit_transmission(&nan, &TransmissionFitOptions::default()).problem.is_some());
    }
}
