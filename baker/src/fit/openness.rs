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
//! (`MeasureScene::sample_ray`) at the views [`openness_views`], each ray's transmittance
//! through the whole volume (ratio tracking, unbiased) is credited to the texel the model
//! shows along that ray (the runtime's probe, as the training samples are), so that where
//! parallax moves a gap the renderer shows it where it lies, and divided by what the
//! model's flyaways in front let through, since the renderer composites them over it.
//! (Measured on the masked surface instead, the halo above the height field that the
//! mask removes and no flyaway voxel holds passed 6× the light at 60° that the volume
//! does.) Then
//! O(ω_o) = o · exp(−q · (1 + a·cos 2φ_o + b·sin 2φ_o) · (1/μ_o − 1)), with q, a and b
//! shared by the sheet (a gap between parallel yarns closes faster seen across them than
//! along them) and o per texel, is fitted to the mean transmittance per view
//! ([`fit_openness`]).

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
use super::simplex::{NelderMead, nelder_mead};

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

/// One texel's measurement at one view.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ViewMean {
    /// The view ω_o.
    pub view: Vec3,
    /// What the surface must let through: Σ T_volume / Σ T_flyaways over the rays
    /// credited to the texel (the volume's transmittance, flyaways and all, over what the
    /// model's flyaways in front already take away), at most 1.
    pub transmittance: f32,
    /// The fit's weight: Σ T_flyaways (a ray the model's flyaways block counts for
    /// nothing; without flyaways, the rays).
    pub rays: f32,
    /// The rays credited to the texel.
    pub count: f32,
}

/// What the openness stage measured.
#[derive(Clone, Debug, Default, Serialize)]
pub struct OpennessReport {
    pub views: usize,
    /// Rays per texel per view.
    pub rays: u32,
    /// Per polar angle of [`OPENNESS_POLAR_DEG`]: the mean transmittance of the sheet
    /// along the rays (the volume, flyaways and all) and the mean the fitted openness
    /// gives along them behind the model's flyaways (the model).
    pub polar_deg: Vec<f32>,
    pub volume: Vec<f64>,
    pub model: Vec<f64>,
    /// Texels with some opening (o > 0), the largest o, and the sheet's q.
    pub open_texels: usize,
    pub max_o: f32,
    pub q: f32,
    /// The sheet's azimuth terms (a, b).
    pub aniso: [f32; 2],
    pub seconds: f64,
}

/// Per texel (x fastest) of `model`, per view of `views` (in order): the rays `measure`
/// traces through texel footprints at that view, their transmittance through the sheet
/// (the whole volume: `measure` without a mask) and through the model's level-0 flyaways
/// in front of its surface, credited to the texel `model` shows along each (rays that
/// miss the model's surface are dropped). `rays` per texel per view (straight down:
/// `OPENNESS_AZIMUTHS` times as many); deterministic per `seed`.
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
        // (texel hit, the volume's transmittance, the model's flyaways') of every ray.
        let hits: Vec<(u32, f32, f32)> = (0..texels)
            .into_par_iter()
            .flat_map_iter(|texel| {
                let (x, y) = (texel % nx, texel / nx);
                let scene = &scene;
                (0..rays).filter_map(move |s| {
                    let mut rng = Rng::new(seed, ((v as u64) << 32) | texel as u64, s as u64);
                    let (u, w) = rng.next_2d();
                    let (o, d) = measure.sample_ray(x, y, u, w, wo);
                    let hit = scene.probe_ray(&Ray::new(o, d), 0, true).surface?;
                    let (t, truncated) = medium.transmittance(&GridRay::new(&medium.medium, o, d), 0.0, f32::INFINITY, &mut rng);
                    let t = if truncated || !t.is_finite() { 0.0 } else { t };
                    let fly = if hit.transmittance.is_finite() { hit.transmittance.clamp(0.0, 1.0) } else { 0.0 };
                    Some((hit.texel.0 + model.width() * hit.texel.1, t, fly))
                })
            })
            .collect();
        for (hit, t, fly) in hits {
            let m = &mut out[hit as usize][v];
            m.transmittance += t;
            m.rays += fly;
            m.count += 1.0;
        }
        for per_texel in out.iter_mut() {
            let m = &mut per_texel[v];
            m.view = wo;
            m.transmittance = if m.rays > 0.0 { (m.transmittance / m.rays).min(1.0) } else { 0.0 };
        }
    }
    out
}

/// What the texels of a sheet share: q and the azimuth terms (a, b) of
/// [`cloth_openness`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OpennessShape {
    pub q: f32,
    pub aniso: [f32; 2],
}

impl OpennessShape {
    /// O / o for a view: the runtime's `cloth_openness` of an open texel.
    fn falloff(&self, m: &ViewMean) -> f64 {
        cloth_openness(&ClothOpenness { o: 1.0, q: self.q, aniso: self.aniso }, m.view) as f64
    }
}

/// The open fraction o ∈ [0, 1] that best fits a texel's view means for a given shape:
/// least squares weighted by rays, Σ n_v (o·F_v − T_v)², in closed form. A texel no ray
/// showed, or one that lets nothing through, is closed (0). Non-finite means are left out.
pub fn open_fraction(means: &[ViewMean], shape: &OpennessShape) -> f32 {
    let (mut ee, mut et) = (0f64, 0f64);
    for m in means.iter().filter(|m| m.rays > 0.0 && m.transmittance.is_finite()) {
        let e = shape.falloff(m);
        ee += m.rays as f64 * e * e;
        et += m.rays as f64 * e * m.transmittance as f64;
    }
    if ee > 0.0 && et > 0.0 { (et / ee).min(1.0) as f32 } else { 0.0 }
}

/// The mismatch of the sheet's mean transmittance per view, model against volume, with
/// the shape shared and each texel's o fitted ([`open_fraction`]): Σ_v (M_v − V_v)² / V_v
/// over the views the volume lets light through (a relative error weighted by how much
/// light the view carries). Every texel's means list the same views in the same order.
fn sheet_mismatch(means: &[Vec<ViewMean>], shape: &OpennessShape) -> f64 {
    let views = means.iter().map(|m| m.len()).max().unwrap_or(0);
    let (mut volume, mut model, mut rays) = (vec![0f64; views], vec![0f64; views], vec![0f64; views]);
    for texel in means {
        let o = open_fraction(texel, shape) as f64;
        for (v, m) in texel.iter().enumerate().filter(|(_, m)| m.rays > 0.0 && m.transmittance.is_finite()) {
            volume[v] += (m.rays * m.transmittance) as f64;
            model[v] += m.rays as f64 * o * shape.falloff(m);
            rays[v] += m.rays as f64;
        }
    }
    (0..views).filter(|&v| rays[v] > 0.0 && volume[v] > 0.0).map(|v| (model[v] - volume[v]).powi(2) / (volume[v] * rays[v])).sum()
}

/// Every texel's openness (x fastest) from its view means: q and (a, b) shared by the
/// sheet, each texel's o fitted for them. The shape is chosen so that the sheet's mean
/// transmittance per view matches the volume's ([`sheet_mismatch`]): q on a geometric
/// grid over (0, OPENNESS_Q_MAX] and 0 with (a, b) = 0, then (q, a, b) by Nelder–Mead.
/// A q per texel fitted to its own rays (eight per view) followed their noise and the
/// parallax that moves a gap from texel to texel: on a twill 64² the sheet's mean came
/// out 19% high straight down, 26% low at 30–45° and 40% high at 60°. Without (a, b) a
/// twill's gaps at 60° came out 3.6× too open seen across its yarns (the mean over
/// azimuths is right, the azimuth is not; baker/FIT_MEASUREMENTS.md, "Transmission").
pub fn fit_openness(means: &[Vec<ViewMean>]) -> Vec<ClothOpenness> {
    let mut grid = vec![0.0f32];
    grid.extend((0..=40).map(|i| 0.01 * (OPENNESS_Q_MAX / 0.01).powf(i as f32 / 40.0)));
    let cost: Vec<f64> = grid.par_iter().map(|&q| sheet_mismatch(means, &OpennessShape { q, aniso: [0.0; 2] })).collect();
    let best = (0..grid.len()).min_by(|&a, &b| cost[a].total_cmp(&cost[b])).unwrap_or(0);
    let shape_of = |x: &[f64]| OpennessShape { q: (x[0] as f32).clamp(0.0, OPENNESS_Q_MAX), aniso: [(x[1] as f32).clamp(-1.0, 1.0), (x[2] as f32).clamp(-1.0, 1.0)] };
    let q0 = grid[best] as f64;
    let mut shape = OpennessShape { q: grid[best], aniso: [0.0; 2] };
    let opts = NelderMead { max_evals: 300, ..Default::default() };
    if let Ok(m) = nelder_mead(|x| sheet_mismatch(means, &shape_of(x)), &[q0, 0.0, 0.0], &[0.25 * q0.max(0.1), 0.3, 0.3], &opts)
        && m.f.is_finite()
        && m.f <= cost[best]
    {
        shape = shape_of(&m.x);
    }
    means
        .par_iter()
        .map(|m| {
            let o = open_fraction(m, &shape);
            if o > 0.0 { ClothOpenness { o, q: shape.q, aniso: shape.aniso } } else { ClothOpenness::default() }
        })
        .collect()
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
            volume[p].1 += m.count as f64;
            model[p] += (cloth_openness(g, w) * m.rays) as f64;
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
        q: fitted.iter().map(|g| g.q).fold(0.0, f32::max),
        aniso: fitted.iter().find(|g| g.o > 0.0).map_or([0.0; 2], |g| g.aniso),
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
            .map(|w| ViewMean { view: *w, transmittance: (cloth_openness(g, *w) * (1.0 + noise * (rng.next_f32() - 0.5))).max(0.0), rays: 8.0, count: 8.0 })
            .collect()
    }

    #[test]
    fn the_fit_recovers_a_known_openness() {
        // A sheet whose texels share q and differ in o: q and every o come back, exactly
        // without noise and within a few percent with 20% noise per view.
        for (q, aniso) in [(0.0f32, [0.0f32; 2]), (0.8, [0.0; 2]), (2.5, [0.6, -0.3]), (9.0, [-0.2, 0.5])] {
            let truth: Vec<ClothOpenness> = (0..40).map(|j| ClothOpenness { o: if j % 3 == 0 { 0.0 } else { 0.02 * (1 + j % 7) as f32 }, q, aniso }).collect();
            for noise in [0.0f32, 0.2] {
                let fitted = fit_openness(&truth.iter().map(|g| means(g, noise)).collect::<Vec<_>>());
                for (t, g) in truth.iter().zip(&fitted) {
                    let tol = if noise > 0.0 { 0.1 } else { 2e-3 };
                    assert!((g.o - t.o).abs() <= tol * t.o + 1e-6, "q {q} noise {noise}: {t:?} → {g:?}");
                    assert!(t.o == 0.0 || (g.q - q).abs() <= tol * q.max(0.5), "q {q} noise {noise}: {t:?} → {g:?}");
                    assert!(t.o == 0.0 || q == 0.0 || (0..2).all(|i| (g.aniso[i] - aniso[i]).abs() <= 5.0 * tol + 0.02), "q {q} noise {noise}: {t:?} → {g:?}");
                }
            }
        }
    }

    #[test]
    fn closed_or_unseen_texels_get_no_openness() {
        assert!(fit_openness(&[]).is_empty());
        assert_eq!(fit_openness(&[means(&ClothOpenness::default(), 0.0)]), vec![ClothOpenness::default()]);
        let unseen: Vec<ViewMean> = means(&ClothOpenness { o: 0.5, q: 1.0, aniso: [0.0; 2] }, 0.0).into_iter().map(|m| ViewMean { rays: 0.0, count: 0.0, transmittance: 0.0, ..m }).collect();
        assert_eq!(open_fraction(&unseen, &OpennessShape { q: 1.0, aniso: [0.0; 2] }), 0.0);
        // Non-finite input never reaches the record.
        let bad = vec![ViewMean { view: Vec3::Z, transmittance: f32::NAN, rays: 1.0, count: 1.0 }, ViewMean { view: Vec3::new(1.0, 0.0, 1.0).normalize(), transmittance: 0.5, rays: 1.0, count: 1.0 }];
        let g = fit_openness(&[bad.clone(), means(&ClothOpenness { o: 0.1, q: 1.0, aniso: [0.0; 2] }, 0.0)]);
        assert!(g.iter().all(|g| g.o.is_finite() && g.q.is_finite() && (0.0..=1.0).contains(&g.o)), "{g:?}");
    }
}
