//! The volumetric path tracer: delta-tracking free flights, next-event estimation to
//! the (delta) light with ratio-tracking transmittance, SGGX phase sampling, Russian
//! roulette (docs/DESIGN.md §4).
//!
//! Estimator, per path: at a real collision x (density σ_t·T, so the collision weight
//! is σ_s/σ_t = α(x)), add
//!   throughput · α(x) · f_p(−d → ω_l) · T(x → light) · E_l(x)
//! where E_l is the light's irradiance perpendicular to ω_l (directional: E; point:
//! I/r²). Then draw ω_o from f_p by visible normals (weight exactly 1). Lights are
//! deltas, so camera and phase rays never hit them and NEE needs no MIS.
//!
//! Depth counts scattering events as Mitsuba 3's `volpath` does: a collision at depth
//! k (1-based) estimates lighting only if k < max_depth, so `max_depth = 2` is single
//! scattering and no limit is full multiple scattering. Russian roulette starts after
//! `rr_depth` scatterings, survival probability min(max(throughput), 0.95).

use fabric_runtime::scene::Light;
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

/// Radiance arriving at the origin of `(origin, d)` from direction −d (world units;
/// the ray may start outside the medium), lit by `light`.
pub fn radiance(medium: &TracedMedium<'_>, light: &Light, settings: &PathSettings, origin: Vec3, d: Vec3, rng: &mut Rng, stats: &mut PathStats) -> Vec3 {
    stats.paths += 1;
    let max_depth = settings.max_depth.unwrap_or(u32::MAX);
    let mut ray = GridRay::new(&medium.medium, origin, d);
    let mut throughput = Vec3::ONE;
    let mut radiance = Vec3::ZERO;
    let mut depth = 0u32;
    loop {
        let collision = match medium.sample_collision(&ray, 0.0, f32::INFINITY, rng) {
            FreeFlight::Collision(c) => c,
            FreeFlight::Escaped => break,
            FreeFlight::Truncated => {
                stats.truncated += 1;
                break;
            }
        };
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
        // Next-event estimation.
        let p_world = medium.medium.to_world(collision.g);
        let ls = light.sample(p_world);
        let phase = sggx.phase(wi, ls.wi);
        if phase > 0.0 && ls.irradiance.max_element() > 0.0 {
            let shadow = GridRay { g0: collision.g, d: ls.wi, dg: ls.wi / medium.medium.volume().voxel_size() };
            let (tr, truncated) = medium.transmittance(&shadow, 0.0, ls.distance, rng);
            stats.truncated += truncated as u64;
            radiance += throughput * (phase * tr) * ls.irradiance;
        }
        if depth + 1 >= max_depth {
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
        ray = GridRay { g0: collision.g, d: wo, dg: wo / medium.medium.volume().voxel_size() };
    }
    radiance
}
