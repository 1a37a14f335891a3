//! The volumetric path tracer: delta-tracking free flights, next-event estimation to
//! the lights with ratio-tracking transmittance, SGGX phase sampling, Russian roulette
//! (docs/DESIGN.md §4).
//!
//! Estimator, per path: at a real collision x (density σ_t·T, so the collision weight
//! is σ_s/σ_t = α(x)), add
//!   throughput · α(x) · f_p(−d → ω_l) · T(x → light) · E_l(x)
//! for the delta light (directional: E; point: I/r²), which camera and phase rays
//! never hit, so it needs no MIS. An environment map is sampled both ways and the two
//! are combined with the power heuristic (Veach 1997): a light sample ω_e ~ p_e adds
//!   throughput · α · f_p(ω_e) · T(x → ∞) · L(ω_e) / p_e · w_e,  w_e = p_e² / (p_e² + f_p²)
//! and a phase-sampled continuation that escapes the medium (probability T, so the
//! escape itself is the transmittance estimate) adds throughput · L(d) · w_f, with
//! w_f = f_p² / (p_e² + f_p²); the SGGX sampler draws exactly from f_p, so its density
//! is f_p. A camera ray that escapes unscattered sees the map (weight 1) when
//! `Lighting::background` is on.
//!
//! Depth counts scattering events as Mitsuba 3's `volpath` does: a collision at depth
//! k (1-based) estimates lighting only if k < max_depth, so `max_depth = 2` is single
//! scattering and no limit is full multiple scattering; the escape of the ray leaving
//! collision k belongs to depth k too. Russian roulette starts after `rr_depth`
//! scatterings, survival probability min(max(throughput), 0.95).

use fabric_runtime::scene::{EnvMap, Light};
use glam::Vec3;

use super::rng::Rng;
use super::tracking::{FreeFlight, GridRay, TracedMedium};

/// Path-length controls.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PathSettings {
    /// Mitsuba's `max_depth`; `None` = unlimited (Russian roulette ends paths).
    pub max_depth: Option<u32>,
    /// Scatterings before Russian roulette starts (Mitsuba's `rr_depth`, default 5).
    pub rr_depth: u32,
}

impl Default for PathSettings {
    fn default() -> Self {
        PathSettings { max_depth: None, rr_depth: 5 }
    }
}

/// Counters summed over paths (integers, so the sum is the same in any order).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PathStats {
    pub paths: u64,
    /// Real collisions (scattering events).
    pub scatterings: u64,
    /// Walks stopped at the DDA step limit (a bias of at most their share; expected 0).
    pub truncated: u64,
}

impl PathStats {
    pub fn add(&mut self, o: &PathStats) {
        self.paths += o.paths;
        self.scatterings += o.scatterings;
        self.truncated += o.truncated;
    }
}

/// What lights the medium: a delta light, an environment map, or both.
#[derive(Clone, Copy, Debug)]
pub struct Lighting<'a> {
    pub light: Option<&'a Light>,
    pub env: Option<&'a EnvMap>,
    /// Camera rays that leave the medium unscattered see the environment.
    pub background: bool,
}

impl<'a> From<&'a Light> for Lighting<'a> {
    fn from(light: &'a Light) -> Self {
        Lighting { light: Some(light), env: None, background: true }
    }
}

impl<'a> Lighting<'a> {
    /// An environment map alone.
    pub fn env(env: &'a EnvMap) -> Self {
        Lighting { light: None, env: Some(env), background: true }
    }
}

/// The power heuristic's weight of a strategy with density `a` against one with `b`.
#[inline]
fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 { a2 / (a2 + b2) } else { 0.0 }
}

/// Radiance arriving at the origin of `(origin, d)` from direction −d (world units;
/// the ray may start outside the medium), under `lighting`.
pub fn radiance(medium: &TracedMedium<'_>, lighting: &Lighting<'_>, settings: &PathSettings, origin: Vec3, d: Vec3, rng: &mut Rng, stats: &mut PathStats) -> Vec3 {
    stats.paths += 1;
    let max_depth = settings.max_depth.unwrap_or(u32::MAX);
    let mut ray = GridRay::new(&medium.medium, origin, d);
    let mut throughput = Vec3::ONE;
    let mut radiance = Vec3::ZERO;
    let mut depth = 0u32;
    // Phase density of the direction the ray left its last collision by (for MIS), and
    // whether that ray may only count its escape (its collision would be too deep).
    let mut last_phase_pdf = 0.0f32;
    let mut escape_only = false;
    loop {
        let collision = match medium.sample_collision(&ray, 0.0, f32::INFINITY, rng) {
            FreeFlight::Collision(c) => c,
            FreeFlight::Escaped => {
                if let Some(env) = lighting.env {
                    if depth == 0 {
                        if lighting.background {
                            radiance += throughput * env.eval(ray.d);
                        }
                    } else {
                        let w = power_heuristic(last_phase_pdf, env.pdf(ray.d));
                        radiance += throughput * env.eval(ray.d) * w;
                    }
                }
                break;
            }
            FreeFlight::Truncated => {
                stats.truncated += 1;
                break;
            }
        };
        if escape_only {
            break;
        }
        depth += 1;
        stats.scatterings += 1;
        if depth >= max_depth {
            break;
        }
        throughput *= medium.medium.albedo(&collision.footprint);
        if throughput.max_element() <= 0.0 {
            break;
        }
        let sggx = medium.medium.sggx(&collision.footprint);
        let wi = -ray.d;
        let voxel = medium.medium.volume().voxel_size();
        // Next-event estimation: the delta light.
        if let Some(light) = lighting.light {
            let p_world = medium.medium.to_world(collision.g);
            let ls = light.sample(p_world);
            let phase = sggx.phase(wi, ls.wi);
            if phase > 0.0 && ls.irradiance.max_element() > 0.0 {
                let shadow = GridRay { g0: collision.g, d: ls.wi, dg: ls.wi / voxel };
                let (tr, truncated) = medium.transmittance(&shadow, 0.0, ls.distance, rng);
                stats.truncated += truncated as u64;
                radiance += throughput * (phase * tr) * ls.irradiance;
            }
        }
        // Next-event estimation: the environment, MIS-weighted against phase sampling.
        if let Some(env) = lighting.env {
            let (u1, u2) = rng.next_2d();
            let es = env.sample(u1, u2);
            if es.pdf > 0.0 {
                let phase = sggx.phase(wi, es.wi);
                if phase > 0.0 {
                    let shadow = GridRay { g0: collision.g, d: es.wi, dg: es.wi / voxel };
                    let (tr, truncated) = medium.transmittance(&shadow, 0.0, f32::INFINITY, rng);
                    stats.truncated += truncated as u64;
                    let w = power_heuristic(es.pdf, phase);
                    radiance += throughput * (phase * tr * w / es.pdf) * es.radiance;
                }
            }
        }
        let last_bounce = depth + 1 >= max_depth;
        if last_bounce && lighting.env.is_none() {
            break;
        }
        // Russian roulette.
        if depth >= settings.rr_depth {
            let q = throughput.max_element().min(0.95);
            if rng.next_f32() >= q {
                break;
            }
            throughput /= q;
        }
        let (u1, u2) = rng.next_2d();
        let wo = sggx.sample_phase(wi, u1, u2);
        last_phase_pdf = sggx.phase(wi, wo);
        escape_only = last_bounce;
        ray = GridRay { g0: collision.g, d: wo, dg: wo / voxel };
    }
    radiance
}
