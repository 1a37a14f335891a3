//! A texel's openness: the light behind the sheet seen straight through the gaps between
//! yarns (format 1.10; brdf `cloth_openness`, runtime/HYBRID_FORMAT.md §6.4).
//!
//! The fitted transmission term holds light that *scattered* through the cloth. A ray
//! that crosses it untouched carries the radiance behind the sheet along its own
//! direction: a directional light is never seen that way (its direction has zero measure),
//! so no backlit training pair shows it, but under an environment map lit below the
//! horizon it was 44% of the light a twill shows from below and 31% of a felt's
//! (runtime/ENV_MEASUREMENTS.md, "Light through the cloth, and the horizon").
//!
//! Measured, not fitted to images: along the rays the reference's measurement traces
//! (`MeasureScene::sample_ray`, through the masked surface: the model's flyaways cover
//! the surface as the volume's do) at the views [`openness_views`], each ray's
//! transmittance through the whole sheet (ratio tracking, unbiased) is credited to the
//! texel the model shows along that ray (the runtime's probe, as the training samples
//! are), so that where parallax moves a gap the renderer shows it where it lies. Per
//! texel, O(μ_o) = o · exp(−q·(1/μ_o − 1)) is fitted to the mean transmittance per view
//! by least squares weighted by the rays per view ([`fit_openness`]). The form has no
//! azimuth: a gap between parallel yarns closes faster across them than along them, and
//! the fit averages the two.

use fabric_runtime::brdf::{ClothOpenness, OPENNESS_Q_MAX, cloth_openness};
use fabric_runtime::cpu::{CpuRenderOptions, Scene, ShadowMode};
use fabric_runtime::hybrid::HybridModel;
use fabric_runtime::scene::{Light, Ray, direction_from_angles};
use glam::Vec3;
use rayon::prelude::*;
use serde::Serialize;

use crate::reference::MeasureScene;
use crate::reference::rng::Rng;
use crate::reference::tracking::GridRay;

/// Polar angles of the views the openness is measured at (degrees): beyond 75° the gaps
/// of every measured preset are closed (twill: 0.02% of rays cross at 60°, none at 75°).
pub const OPENNESS_POLAR_DEG: [f32; 6] = [0.0, 15.0, 30.0, 45.0, 60.0, 75.0];
/// Azimuths per polar angle above 0° (evenly spaced, starting at 0°).
pub const OPENNESS_AZIMUTHS: usize = 8;

/// The views: straight down once, then [`OPENNESS_AZIMUTHS`] azimuths per polar angle.
pub fn openness_views() -> Vec<Vec3> {
    let mut views = vec![Vec3::Z];
    for &polar in &OPENNESS_POLAR_DEG[1..] {
        views.extend((0..OPENNESS_AZIMUTHS).map(|a| direction_from_angles(polar, 360.0 * a as f32 / OPENNESS_AZIMUTHS as f32)));
    }
    views
}

/// One texel's measurement at one view: the rays credited to it and their mean
/// transmittance.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ViewMean {
    /// 1/μ_o − 1 (the slant of the view).
    pub slant: f32,
    pub transmittance: f32,
    pub rays: f32,
}

/// What the openness stage measured.
#[derive(Clone, Debug, Default, Serialize)]
pub struct OpennessReport {
    pub views: usize,
    /// Rays per texel per view.
    pub rays: u32,
    /// Per polar angle of [`OPENNESS_POLAR_DEG`]: the mean transmittance of the sheet
    /// along the rays (the volume) and the mean the fitted openness gives along them (the
    /// model).
    pub polar_deg: Vec<f32>,
    pub volume: Vec<f64>,
    pub model: Vec<f64>,
    /// Texels with some opening (o > 0), and the largest o.
    pub open_texels: usize,
    pub max_o: f32,
    pub seconds: f64,
}

/// Per texel (x fastest) of `model`, per view of `views` (in order): the rays `measure`
/// traces through texel footprints at that view, their transmittance through the sheet,
/// credited to the texel `model` shows along each (rays that miss the model's surface are
/// dropped). `rays` per texel per view (straight down: `OPENNESS_AZIMUTHS` times as
/// many); deterministic per `seed`.
pub fn measure_openness(model: &HybridModel, measure: &MeasureScene, views: &[Vec3], rays: u32, seed: u64) -> Vec<Vec<ViewMean>> {
    let (nx, ny) = measure.texels();
    let texels = nx * ny;
    let lights = [Light::directional(Vec3::Z, Vec3::ONE)];
    let render = CpuRenderOptions { periodic: true, shadows: ShadowMode::Off, ..Default::default() };
    let mut out = vec![vec![ViewMean::default(); views.len()]; texels];
    let Ok(scene) = Scene::for_rays(model, &lights, render) else {
        return out;
    };
    let medium = measure.medium();
    for (v, &wo) in views.iter().enumerate() {
        // Straight down is one view where each other polar angle has OPENNESS_AZIMUTHS:
        // as many rays as a ring, so that the fit weighs the angles alike.
        let rays = if wo.z >= 1.0 - 1e-6 { rays * OPENNESS_AZIMUTHS as u32 } else { rays };
        // (texel hit, transmittance) of every ray of this view.
        let hits: Vec<(u32, f32)> = (0..texels)
            .into_par_iter()
            .flat_map_iter(|texel| {
                let (x, y) = (texel % nx, texel / nx);
                let scene = &scene;
                (0..rays).filter_map(move |s| {
                    let mut rng = Rng::new(seed, ((v as u64) << 32) | texel as u64, s as u64);
                    let (u, w) = rng.next_2d();
                    let (o, d) = measure.sample_ray(x, y, u, w, wo);
                    let hit = scene.probe_ray(&Ray::new(o, d), 0, false).surface?;
                    let (t, truncated) = medium.transmittance(&GridRay::new(&medium.medium, o, d), 0.0, f32::INFINITY, &mut rng);
                    let t = if truncated || !t.is_finite() { 0.0 } else { t };
                    Some((hit.texel.0 + model.width() * hit.texel.1, t))
                })
            })
            .collect();
        let slant = 1.0 / wo.z - 1.0;
        for (hit, t) in hits {
            let m = &mut out[hit as usize][v];
            m.slant = slant;
            m.transmittance += t;
            m.rays += 1.0;
        }
        for per_texel in out.iter_mut() {
            let m = &mut per_texel[v];
            m.slant = slant;
            if m.rays > 0.0 {
                m.transmittance /= m.rays;
            }
        }
    }
    out
}

/// Σ n_v (o·e^{−q s_v} − T_v)² at the best o ∈ [0, 1] for this q (linear in o), and o.
fn residual_at(means: &[ViewMean], q: f32) -> (f64, f32) {
    let (mut ee, mut et) = (0f64, 0f64);
    for m in means {
        let e = (-(q * m.slant) as f64).exp();
        ee += m.rays as f64 * e * e;
        et += m.rays as f64 * e * m.transmittance as f64;
    }
    let o = if ee > 0.0 { (et / ee).clamp(0.0, 1.0) } else { 0.0 };
    let r = means.iter().map(|m| m.rays as f64 * (o * (-(q * m.slant) as f64).exp() - m.transmittance as f64).powi(2)).sum();
    (r, o as f32)
}

/// The openness that best fits a texel's view means (least squares weighted by rays): q
/// on a geometric grid over (0, OPENNESS_Q_MAX] and 0, refined by golden section between
/// the best node's neighbours; o in closed form. A texel no ray showed, or one that lets
/// nothing through, is closed (0, 0).
pub fn fit_openness(means: &[ViewMean]) -> ClothOpenness {
    if !means.iter().any(|m| m.rays > 0.0 && m.transmittance > 0.0) {
        return ClothOpenness::default();
    }
    let mut grid = vec![0.0f32];
    grid.extend((0..=40).map(|i| 0.01 * (OPENNESS_Q_MAX / 0.01).powf(i as f32 / 40.0)));
    let best = (0..grid.len()).min_by(|&a, &b| residual_at(means, grid[a]).0.total_cmp(&residual_at(means, grid[b]).0)).unwrap_or(0);
    let (mut lo, mut hi) = (grid[best.saturating_sub(1)], grid[(best + 1).min(grid.len() - 1)]);
    let phi = 0.618_034f32;
    for _ in 0..30 {
        let (a, b) = (hi - phi * (hi - lo), lo + phi * (hi - lo));
        if residual_at(means, a).0 <= residual_at(means, b).0 {
            hi = b;
        } else {
            lo = a;
        }
    }
    let q = 0.5 * (lo + hi);
    let q = if residual_at(means, q).0 <= residual_at(means, grid[best]).0 { q } else { grid[best] };
    let (_, o) = residual_at(means, q);
    if o > 0.0 { ClothOpenness { o, q } } else { ClothOpenness::default() }
}

/// The report's figures: per polar angle, the volume's and the model's mean transmittance
/// over every ray of that angle.
pub fn openness_report(means: &[Vec<ViewMean>], fitted: &[ClothOpenness], views: &[Vec3], rays: u32, seconds: f64) -> OpennessReport {
    let polar_of = |w: Vec3| w.z.clamp(-1.0, 1.0).acos().to_degrees();
    let mut volume = vec![(0f64, 0f64); OPENNESS_POLAR_DEG.len()];
    let mut model = vec![0f64; OPENNESS_POLAR_DEG.len()];
    for (per_texel, g) in means.iter().zip(fitted) {
        for (m, &w) in per_texel.iter().zip(views) {
            let Some(p) = OPENNESS_POLAR_DEG.iter().position(|&d| (d - polar_of(w)).abs() < 0.5) else { continue };
            volume[p].0 += (m.transmittance * m.rays) as f64;
            volume[p].1 += m.rays as f64;
            model[p] += (cloth_openness(g, w.z) * m.rays) as f64;
        }
    }
    OpennessReport {
        views: views.len(),
        rays,
        polar_deg: OPENNESS_POLAR_DEG.to_vec(),
        volume: volume.iter().map(|&(s, n)| if n > 0.0 { s / n } else { 0.0 }).collect(),
        model: model.iter().zip(&volume).map(|(&s, &(_, n))| if n > 0.0 { s / n } else { 0.0 }).collect(),
        open_texels: fitted.iter().filter(|g| g.o > 0.0).count(),
        max_o: fitted.iter().map(|g| g.o).fold(0.0, f32::max),
        seconds,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn means(g: &ClothOpenness, noise: f32) -> Vec<ViewMean> {
        let mut rng = Rng::new(7, 8, 9);
        openness_views()
            .iter()
            .map(|w| ViewMean { slant: 1.0 / w.z - 1.0, transmittance: (cloth_openness(g, w.z) * (1.0 + noise * (rng.next_f32() - 0.5))).max(0.0), rays: 8.0 })
            .collect()
    }

    #[test]
    fn the_fit_recovers_a_known_openness() {
        for truth in [ClothOpenness { o: 0.3, q: 0.8 }, ClothOpenness { o: 0.02, q: 6.0 }, ClothOpenness { o: 1.0, q: 0.0 }, ClothOpenness { o: 0.1, q: 40.0 }] {
            let g = fit_openness(&means(&truth, 0.0));
            assert!((g.o - truth.o).abs() < 1e-3 * truth.o.max(1e-3) + 1e-5 && (g.q - truth.q).abs() < 0.01 * truth.q.max(1.0), "{truth:?} → {g:?}");
            // With 20% noise per view the open fraction stays within a few percent.
            let g = fit_openness(&means(&truth, 0.2));
            assert!((g.o - truth.o).abs() < 0.08 * truth.o, "{truth:?} → {g:?} (noisy)");
        }
    }

    #[test]
    fn closed_or_unseen_texels_get_no_openness() {
        assert_eq!(fit_openness(&[]), ClothOpenness::default());
        assert_eq!(fit_openness(&means(&ClothOpenness::default(), 0.0)), ClothOpenness::default());
        let unseen: Vec<ViewMean> = means(&ClothOpenness { o: 0.5, q: 1.0 }, 0.0).into_iter().map(|m| ViewMean { rays: 0.0, transmittance: 0.0, ..m }).collect();
        assert_eq!(fit_openness(&unseen), ClothOpenness::default());
        // Non-finite input never reaches the record.
        let g = fit_openness(&[ViewMean { slant: 0.0, transmittance: f32::NAN, rays: 1.0 }, ViewMean { slant: 1.0, transmittance: 0.5, rays: 1.0 }]);
        assert!(g.o.is_finite() && g.q.is_finite() && (0.0..=1.0).contains(&g.o));
    }
}
