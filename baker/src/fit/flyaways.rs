//! The flyaway fibers' BRDFs (paper §5.3.4).
//!
//! - Clusters: the flyaway voxels of V grouped by k-means on their fiber axis (as the
//!   axis tensor, sign-free) and fiber diameter; one BRDF per cluster.
//! - Shape: β_j, γ_j, a and η are fixed to the surface's — the median over the texels of
//!   their cluster's values (the paper: "β_1 and β_2 fixed to the surface's"), so only
//!   the linear parameters k_d, k_j are fitted (searching β, γ as well bought 0.1–0.7
//!   points of held-out error, not kept: baker/FIT_MEASUREMENTS.md, "The flyaways' lobes
//!   as cylinders").
//! - Law: the lobes of the model's `FiberLobes` (a cylinder's by default, format 1.11),
//!   the diffuse term Lambert's about the normal facing the viewer (`Geo::fiber`).
//! - Fit: training renderings of the *full* volume (flyaways and surface together, so
//!   their interreflection is in the data); every training ray is traced through the
//!   model with its flyaway lists by the runtime's probe, which gives each node crossed
//!   its weight (transmittance in front × opacity) and the light's visibility, and the
//!   surface behind it with the transmittance left. With the surface fixed, a pixel is
//!   linear in the flyaway clusters' k's: one NNLS over all pixels whose rays cross
//!   flyaways, per RGB channel.
//! - Coverage: a level-0 flyaway voxel is opaque (α = 1) by default; with
//!   [`FlyawayAlpha::Density`] its α is ρ / ρ_solid (partial coverage), because V holds
//!   every voxel above 5% of the solid density and fibers would otherwise render fatter
//!   than they are.

use fabric_runtime::brdf::{BrdfReading, ClothLobe, ClothParams, cloth_fiber_frame};
use fabric_runtime::cpu::shading::{texel_response, volume_factor};
use fabric_runtime::cpu::{CpuRenderOptions, Scene, ShadowMode};
use fabric_runtime::hybrid::{BrdfTable, FlyawayInput, Flyaways, HybridModel, ModelError};
use fabric_runtime::scene::{Light, Ray};
use glam::Vec3;
use rayon::prelude::*;

use super::cluster_fit::predict;
use super::kmeans::{KMeansOptions, kmeans};
use super::nnls::nnls_gram;
use super::samples::{Geo, TrainingImages, image_jitter};
use crate::geometry::FlyawayVolume;
use crate::reference::MeasureScene;

/// How a level-0 flyaway voxel covers its cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FlyawayAlpha {
    /// α = 1: the voxel is opaque.
    Full,
    /// α = min(1, ρ / ρ_solid).
    Density,
}

/// What the flyaway fit found.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FlyawayReport {
    pub voxels: usize,
    pub clusters: usize,
    /// Training pixels whose rays cross flyaways.
    pub pixels: usize,
    /// Relative RMSE of those pixels with the flyaways' BRDFs zero, and fitted.
    pub error_without: f64,
    pub error_fitted: f64,
    pub problem: Option<String>,
    /// Level 0's path gain at polar 0°, 10°, … 80° (format 1.9; None: not fitted), with
    /// the mean transmittance of the volume's flyaway voxels alone and of the model's
    /// without the gain at those angles (what the gain matches).
    pub path_gain: Option<Vec<f32>>,
    pub transmittance_volume: Option<Vec<f64>>,
    pub transmittance_ungained: Option<Vec<f64>>,
    /// Whether the flyaways shadow the surface in the model (format 1.13), and the whole
    /// model's error against the full volume's training images over 4×4 blocks with
    /// and without that shadow, each with its own flyaway fit, where both were tried
    /// (`FlyawayShadow::Auto`).
    pub shadow_surface: bool,
    pub block_error_shadowed: Option<f64>,
    pub block_error_unshadowed: Option<f64>,
}

/// The whole model's error against full-volume training images `training` (relative
/// RMSE per pixel and over 4×4 blocks, all pairs): each pair's image measured through
/// the model along the same rays the flyaway fit probes (`cpu::probe::measure_image`,
/// `rays` per texel, jitter from `jitter_seed`).
pub fn full_image_errors(model: &HybridModel, measure: &MeasureScene, training: &TrainingImages, jitter_seed: u64, rays: u32, shadows: bool) -> Result<(f64, f64), fabric_runtime::cpu::CpuRenderError> {
    let (w, _) = measure.texels();
    let jitter = image_jitter(jitter_seed);
    let options = CpuRenderOptions { periodic: true, shadows: if shadows { ShadowMode::On } else { ShadowMode::Off }, ..Default::default() };
    let images = training
        .pairs
        .iter()
        .map(|pair| {
            let ray = |x: u32, y: u32, s: u32| {
                let (u, v) = jitter(y * w as u32 + x, s);
                let (o, d) = measure.sample_ray(x as usize, y as usize, u, v, pair.wo);
                Ray::new(o, d)
            };
            fabric_runtime::cpu::probe::measure_image(model, &options, pair.wi, 0, rays, &ray)
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(crate::bake::image_errors(&images, &training.images, 0, 0))
}

/// Cluster of each flyaway voxel (k-means on the fiber axis tensor and the diameter),
/// and the number of clusters (≤ `k`).
pub fn flyaway_clusters(fv: &FlyawayVolume, k: usize, seed: u64) -> (Vec<u32>, usize) {
    let n = fv.voxels.len();
    if n == 0 {
        return (Vec::new(), 0);
    }
    let k = k.clamp(1, n);
    let max_d = fv.voxels.iter().map(|v| v.fiber_diameter).fold(1e-6, f32::max);
    let data: Vec<f32> = fv
        .voxels
        .iter()
        .flat_map(|v| {
            let t = v.orientation;
            let txy = (t.x * t.x + t.y * t.y).sqrt();
            [t.x * t.x - t.y * t.y, 2.0 * t.x * t.y, 2.0 * t.z.abs() * txy, v.fiber_diameter / max_d]
        })
        .collect();
    match kmeans(&data, 4, k, &KMeansOptions { seed, ..Default::default() }) {
        Ok(km) => (km.assignment, k),
        Err(_) => (vec![0; n], 1),
    }
}

/// The level-0 flyaway lists of V: voxel (x, y, z) at depth index zres − 1 − z below the
/// top plane, its fiber axis, cluster `assignment[v]` into `params`.
pub fn flyaway_level(fv: &FlyawayVolume, solid_density: f32, assignment: &[u32], params: &[ClothParams], alpha: FlyawayAlpha) -> Result<Flyaways, ModelError> {
    let [nx, ny, nz] = fv.dims;
    let mut table = BrdfTable::new();
    for p in params {
        table.push(p);
    }
    Flyaways::from_columns(nx as u32, ny as u32, table, |i, j| {
        let column = (i as usize) + nx * (j as usize);
        (fv.column_start[column]..fv.column_start[column + 1])
            .filter_map(|v| {
                let voxel = &fv.voxels[v];
                let depth = FlyawayInput::depth_of_voxel_layer(voxel.z, nz as u32)?;
                let a = match alpha {
                    FlyawayAlpha::Full => 1.0,
                    FlyawayAlpha::Density => (voxel.density / solid_density.max(1e-30)).clamp(1.0 / 65535.0 * 2.0, 1.0),
                };
                Some(FlyawayInput { depth, alpha: a, tangent: voxel.orientation, param: assignment[v] })
            })
            .collect()
    })
}

/// The surface BRDF shape shared by the flyaways: the median over texels of β_j, γ_j, a
/// and η (per lobe), with zero k's.
pub fn surface_shape(texel_params: &[ClothParams]) -> ClothParams {
    let median = |mut v: Vec<f32>| {
        v.sort_by(|a, b| a.total_cmp(b));
        v.get(v.len() / 2).copied().unwrap_or(0.0)
    };
    let lobes = texel_params.first().map_or(0, |p| p.lobe_count as usize);
    let lobe: Vec<ClothLobe> = (0..lobes)
        .map(|j| ClothLobe { k: Vec3::ZERO, beta: median(texel_params.iter().map(|p| p.lobes[j].beta).collect()), gamma: median(texel_params.iter().map(|p| p.lobes[j].gamma).collect()) })
        .collect();
    ClothParams::new(Vec3::ZERO, median(texel_params.iter().map(|p| p.eta).collect()), median(texel_params.iter().map(|p| p.a).collect()), &lobe)
}

/// One training pixel: its target less the surface seen through the flyaways, and its
/// basis row (per cluster: k_d and each lobe's unit-k response, weighted).
struct PixelRow {
    target: Vec3,
    residual: Vec3,
    row: Vec<f64>,
}

/// Fits the flyaway clusters' k's with the surface fixed. `model` holds the surface
/// (its level-0 BRDFs, each lobe in its frame) and flyaway lists whose table has
/// `clusters` entries of shape `shape`; returns their fitted BRDFs and a report.
#[allow(clippy::too_many_arguments)] // the fit's inputs, each used once
pub fn fit_flyaways(
    model: &HybridModel,
    measure: &MeasureScene,
    training: &TrainingImages,
    jitter_seed: u64,
    rays: u32,
    shadows: bool,
    shape: &ClothParams,
    clusters: usize,
    reading: BrdfReading,
) -> (Vec<ClothParams>, FlyawayReport) {
    let nb = 1 + shape.lobe_count as usize;
    let cols = clusters * nb;
    let (w, h) = measure.texels();
    let texels = w * h;
    let jitter = image_jitter(jitter_seed);
    let basis_of = |g: &Geo| -> Vec<f64> {
        let mut out = vec![g.kd_cos as f64];
        for l in shape.lobes() {
            let mut unit = *shape;
            unit.kd = Vec3::ZERO;
            unit.lobe_count = 1;
            unit.lobes[0] = ClothLobe { k: Vec3::ONE, ..*l };
            out.push(predict(&unit, g, reading).x as f64);
        }
        out
    };
    let brdfs: Vec<_> = (0..texels).map(|j| model.levels[0].texel_brdf((j % w) as u32, (j / w) as u32)).collect();
    let mut rows: Vec<PixelRow> = Vec::new();
    for (c, pair) in training.pairs.iter().enumerate() {
        let lights = [Light::directional(pair.wi, Vec3::ONE)];
        let render = CpuRenderOptions { periodic: true, shadows: if shadows { ShadowMode::On } else { ShadowMode::Off }, ..Default::default() };
        let Ok(scene) = Scene::for_rays(model, &lights, render) else { continue };

        let image = &training.images[c];
        let batch: Vec<PixelRow> = (0..texels)
            .into_par_iter()
            .filter_map(|j| {
                let (x, y) = (j % w, j / w);
                let mut row = vec![0.0f64; cols];
                let mut surface = Vec3::ZERO;
                let mut crossed = false;
                for s in 0..rays {
                    let (u, v) = jitter(j as u32, s);
                    let (o, d) = measure.sample_ray(x, y, u, v, pair.wo);
                    let probe = scene.probe_ray(&Ray::new(o, d), 0, true);
                    for f in &probe.flyaways {
                        crossed = true;
                        let frame = cloth_fiber_frame(f.fiber, pair.wo);
                        let g = Geo::fiber(&frame, pair.wi, pair.wo, f.visibility, model.meta.fiber_lobes);
                        for (b, value) in basis_of(&g).into_iter().enumerate() {
                            row[f.param as usize * nb + b] += (f.weight / rays as f32) as f64 * value;
                        }
                    }
                    if let Some(hit) = probe.surface {
                        let t = hit.texel.0 as usize + w * hit.texel.1 as usize;
                        let factor = if model.meta.volumetric { volume_factor(pair.wi, pair.wo) } else { 1.0 };
                        // The texel as the model holds it: each lobe in its own frame.
                        let b = &brdfs[t];
                        surface += hit.transmittance * hit.visibility * factor / rays as f32 * texel_response(b, pair.wi, pair.wo, reading, model.meta.diffuse);
                    }
                }
                crossed.then(|| PixelRow { target: image.pixels[j], residual: image.pixels[j] - surface, row })
            })
            .collect();
        rows.extend(batch);
    }
    let mut report = FlyawayReport { voxels: 0, clusters, pixels: rows.len(), error_without: 0.0, error_fitted: 0.0, problem: None, path_gain: None, transmittance_volume: None, transmittance_ungained: None, shadow_surface: model.meta.flyaway_shadow, block_error_shadowed: None, block_error_unshadowed: None };
    let zero = vec![*shape; clusters];
    if rows.is_empty() || clusters == 0 {
        report.problem = Some("no training ray crosses a flyaway voxel".into());
        return (zero, report);
    }
    let mut gram = vec![0.0f64; cols * cols];
    let mut atb = [vec![0.0f64; cols], vec![0.0f64; cols], vec![0.0f64; cols]];
    let mut btb = [0.0f64; 3];
    for r in &rows {
        for a in 0..cols {
            if r.row[a] == 0.0 {
                continue;
            }
            for b in 0..cols {
                gram[a * cols + b] += r.row[a] * r.row[b];
            }
        }
        let y = r.residual.as_dvec3().to_array();
        for ch in 0..3 {
            for (acc, x) in atb[ch].iter_mut().zip(&r.row) {
                *acc += x * y[ch];
            }
            btb[ch] += y[ch] * y[ch];
        }
    }
    // A tiny ridge keeps clusters no ray sees at zero instead of undetermined.
    let trace: f64 = (0..cols).map(|a| gram[a * cols + a]).sum::<f64>() / cols as f64;
    for a in 0..cols {
        gram[a * cols + a] += 1e-6 * trace.max(1e-30);
    }
    let mut params = zero;
    let mut fitted2 = 0.0;
    for ch in 0..3 {
        match nnls_gram(&gram, &atb[ch], btb[ch], cols) {
            Ok(sol) => {
                fitted2 += sol.residual2;
                for (c, p) in params.iter_mut().enumerate() {
                    p.kd[ch] = sol.x[c * nb] as f32;
                    for j in 0..nb - 1 {
                        p.lobes[j].k[ch] = sol.x[c * nb + 1 + j] as f32;
                    }
                }
            }
            Err(e) => {
                report.problem = Some(format!("flyaway solve failed: {e}"));
                return (vec![*shape; clusters], report);
            }
        }
    }
    let target2: f64 = rows.iter().map(|r| (r.residual).as_dvec3().length_squared()).sum::<f64>();
    let pixel2: f64 = rows.iter().map(|r| r.target.as_dvec3().length_squared()).sum::<f64>().max(1e-30);
    report.error_without = (target2 / pixel2).sqrt();
    report.error_fitted = (fitted2.max(0.0) / pixel2).sqrt();
    (params, report)
}
