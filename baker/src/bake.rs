//! `fabric bake`: volume → geometry → training renderings → clusters → fitted BRDFs →
//! [`HybridModel`] (paper §5, Algorithm 1).
//!
//! 1. Geometry (§5.2): h, n, t and the flyaway volume V ([`crate::geometry`]).
//! 2. Training renderings (§5.3.1): the reference's measurement images of the volume
//!    with the surface mask applied, at m configurations ([`fit::directions`]), as two
//!    halves so their noise is known.
//! 3. Samples: every training ray traced through the model by the runtime's probe, so
//!    each pixel is attributed to the texels the model shows along its rays.
//! 4. K doubling (§5.3.3, Algorithm 1 lines 3–13): k-means of the features into K
//!    clusters; the representative of each (the texel nearest its centre) is measured
//!    densely (§5.3.2); each cluster's BRDF is fitted (Eq. 8) to its representative's
//!    dense samples *and* to every training sample the model attributes to the
//!    cluster's texels — the model's output is judged on images, so the fit matches
//!    them; the error of the model on the training images decides whether K doubles.
//! 5. Transmission (a BSDF, §7.2 "Extensions"; `transmission: Some`): the same
//!    configurations lit from below the sheet ([`fit::directions::backlit_pairs`]),
//!    probed like the others, fitted per cluster and refined per texel
//!    ([`fit::transmission`]), each texel's energy capped.
//! 6. Flyaways (§5.3.4): [`fit::flyaways`].

use std::collections::HashMap;
use std::time::Instant;

use fabric_runtime::brdf::{BrdfReading, ClothFrame, ClothLobe, ClothParams, ClothTransmission, DiffuseLaw, FiberLobes};
use fabric_runtime::hybrid::{BakeMetadata, BrdfTable, ClusteredTexel, HeightField, HybridModel, Level, ModelError, PackedCurvature, PackedGradient, PackedTransmission, PackedTransmissionVisibility, Surface, Tile};
use fabric_runtime::image::Image;
use glam::Vec3;
use rayon::prelude::*;
use serde::Serialize;

use crate::fit::behind::{MIN_SAMPLES, behind_samples};
use crate::fit::cluster_fit::{ClusterFit, ClusterFitOptions, FrameFitOptions, LEVEL0_LOBES, LOBE_PEAK_MAX, LobeTarget, Target, TargetRay, cap_peaks, fit_cluster, fit_cluster_framed, predict_lobes, refine_texel};
use crate::fit::frames::FrameOffset;
use crate::fit::gradient::{GradientOptions, Visibility, refine_gradient_from, with_gradient};
use crate::fit::directions::{Pair, PairOptions, backlit_pairs, training_pairs};
use crate::fit::energy::{LOBE_ALBEDO_MAX, cap_lobes, unit_albedos};
use crate::fit::features::texel_features;
use crate::fit::flyaways::{FlyawayAlpha, FlyawayReport, fit_flyaways, flyaway_clusters, flyaway_level, full_image_errors, surface_shape};
use crate::fit::kmeans::{KMeansOptions, kmeans, representatives};
use crate::fit::samples::{Groups, ProbeOptions, Sample, TrainingImages, half_seeds, image_jitter, probe_samples, render_training, texel_jitter};
use crate::fit::openness::{OpennessReport, fit_openness, measure_openness, openness_report, openness_views};
use crate::fit::transmission::{TransGeo, TransTarget, TransmissionFit, TransmissionFitOptions, albedo_estimate, cap_energy, fit_transmission, predict_transmission, refine_transmission, refine_transmission_visibility_from};
use crate::geometry::{Geometry, GeometryError, GeometryOptions, extract_geometry_with};
use crate::prefilter::{PrefilterError, PrefilterOptions, PrefilterReport, prefilter};
use crate::progress::{Progress, stage as begin_stage};
use crate::reference::rng::mix64;
use crate::prefilter::path_gain::{all_but_level0_flyaways, fit_level0_gain};
use crate::reference::medium::MediumOptions;
use crate::reference::tracking::TracedMedium;
use crate::reference::{Lookup, MeasureScene, ReferenceError};
use crate::volume::FabricVolume;

/// Which voxels the surface fit's renderings leave out (the paper: "the complement of V").
/// Measured on the 64² presets with the surface refitted behind the flyaways
/// (baker/FIT_MEASUREMENTS.md, "What the surface fit sees"), held-out error over 4×4
/// blocks, flyaways against none: silk 19.1 / 18.2%, satin 18.3 / 17.7%, felt 13.2 /
/// 14.6% (above, the default before: 24.1, 21.6, 14.5% without the refit). The model
/// draws no halo, so its light belongs in the surface's fit; V's it draws itself.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SurfaceMask {
    /// Everything above each column's surface run: V and the low-density halo around it
    /// (the default before 2026-12-07).
    AboveSurface,
    /// Exactly the voxels of V (the default).
    Flyaways,
    /// Nothing: the surface is fitted to the full volume.
    None,
}

/// Everything `fabric bake` can set. `Default` is what the command uses.
#[derive(Clone, Debug, PartialEq)]
pub struct BakeOptions {
    pub seed: u64,
    pub geometry: GeometryOptions,
    pub lookup: Lookup,
    pub pairs: PairOptions,
    /// Samples per texel of each training rendering (split into two halves).
    pub spp: u32,
    /// Probe rays per training pixel.
    pub probe_rays: u32,
    /// Fit (and render by default) with the height field's shadowing of the light.
    pub shadows: bool,
    /// Weight each training pair's samples by the inverse of its image's RMS
    /// ([`TrainingImages::pair_weights`]).
    pub pair_weights: bool,
    /// Fit and render surface hits with the volumetric factor 2/(μ_i + μ_o).
    pub volumetric: bool,
    pub surface_mask: SurfaceMask,
    /// K starts at `k_min` and doubles up to `k_max` (Algorithm 1); [`K_AUTO`] (0) for
    /// either is [`auto_k`] of the model's texel count.
    pub k_min: usize,
    pub k_max: usize,
    /// Stop when the training-image error (relative RMSE) is below δ...
    pub delta: f64,
    /// ... or when doubling K lowers it by less than this fraction.
    pub min_gain: f64,
    pub fit: ClusterFitOptions,
    /// Fit a frame offset per cluster with its BRDF (`fit::frames`, Eq. 8 with the frame
    /// free), or `None` to keep the geometry stage's frames.
    pub frame_fit: Option<FrameFitOptions>,
    /// Dense measurement of each representative: pairs and samples per pair.
    pub dense_pairs: usize,
    pub dense_spp: u32,
    /// After the cluster fits, refine each texel's k_d and k_j on its own samples
    /// (ridge towards its cluster) and store level 0 per texel; `None` keeps the
    /// paper's clustered level 0.
    pub per_texel_ridge: Option<f64>,
    /// With the per-texel refinement, fit each texel's visibility gradient too
    /// (`fit::gradient`, format 1.12); `None`: none.
    pub gradient: Option<GradientOptions>,
    /// Scale of the normal map's slope (its tilt from +Z): 1 keeps the geometry stage's
    /// normals, 0 makes every normal +Z. Light reaches a volumetric yarn's sides that
    /// face away from it, which a fully tilted normal's max(n·ω_i, 0) cannot show.
    pub normal_slope: f32,
    /// How much of the fiber-level relief h0 − h the model's height field keeps:
    /// surface = h + relief·(h0 − h). 0 is the paper's smooth h; more relief gives the
    /// march the parallax and the shadows of the yarns' crowns and valleys.
    pub relief: f32,
    /// Shift of the model's surface along z, in voxels (negative: deeper).
    pub surface_offset: f32,
    /// Flyaway fibers in the model (§5.3.4), or `None` to leave them out.
    pub flyaways: Option<FlyawayOptions>,
    /// The mip chain (§5.3.5) built from level 0, or `None` for level 0 alone.
    pub prefilter: Option<PrefilterOptions>,
    /// Fit a transmission term too (a BSDF, format 1.3), or `None` for reflection alone.
    pub transmission: Option<TransmissionFitOptions>,
    /// Bound each lobe (cluster and texel) to add at most this multiple of the brightest
    /// radiance its cluster showed (training pixels and its representative's dense
    /// values) at any pair of directions (`cluster_fit::LOBE_PEAK_MAX`); `None`: no bound.
    pub lobe_peak_max: Option<f32>,
}

/// How the flyaways are clustered, covered and fitted.
#[derive(Clone, Debug, PartialEq)]
pub struct FlyawayOptions {
    /// Most flyaway clusters.
    pub clusters: usize,
    /// Samples per texel of the full-volume training renderings.
    pub spp: u32,
    pub alpha: FlyawayAlpha,
    /// Fit level 0's path gain against the volume (format 1.9,
    /// [`crate::prefilter::path_gain::fit_level0_gain`]): the model's flyaway voxels let
    /// through what the volume's do, on average, at every polar angle.
    pub path_gain: bool,
    /// How the flyaways' lobes fall with the azimuth about the fibre (format 1.11's
    /// cylinder law, or the frame facing the viewer of the files before).
    pub lobes: FiberLobes,
    /// Whether the flyaways shadow the surface's lights (format 1.13, MODEL flag bit 5;
    /// `BakeMetadata::flyaway_shadow`): the fit and the renderers light a surface hit
    /// through the flyaways in front of it, as the volume does.
    pub shadow_surface: FlyawayShadow,
    /// With the flyaways fitted, refit each surface texel's k_d, k_j (and gradient) on the
    /// full volume's training images behind them ([`crate::fit::behind`]), kept where the
    /// whole model's training error over 4×4 blocks falls. Off by default: it buys 0.2–0.8
    /// points at 64², but on felt 128² it still leaves texels 18 times brighter than the
    /// sheet's 99th percentile where the bake without it has none
    /// (baker/FIT_MEASUREMENTS.md, "What the surface fit sees").
    pub refit_surface: bool,
}

/// What refitting the surface behind the flyaways did ([`FlyawayOptions::refit_surface`]):
/// the whole model's error against the full volume's training images over 4×4 blocks
/// before and after, and whether the refit was kept.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SurfaceRefitReport {
    pub samples: usize,
    pub block_error_before: f64,
    pub block_error_after: f64,
    pub kept: bool,
}

/// [`FlyawayOptions::shadow_surface`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlyawayShadow {
    /// The flyaways fitted both ways, the model kept whose whole image matches the full
    /// volume's training images better over 4×4 blocks. Measured at 64² (held-out over
    /// 4×4 blocks, without → with): felt 20.0 → 14.6%, twill 12.1 → 12.3%, satin 23.7 →
    /// 24.0%; the shadow also costs the chain's agreement with level 0 (felt's 16 px
    /// far views 2.6–4.6 → 9.5–14.1%, twill's 2.2–4.7 → 6.3–7.9%): where the flyaways are
    /// few it buys nothing (baker/FIT_MEASUREMENTS.md, "The flyaways' shadow on the
    /// surface").
    Auto,
    On,
    Off,
}

impl Default for FlyawayOptions {
    fn default() -> Self {
        // Density coverage measured better on twill 128×128×32: held-out 28.3% over 4×4
        // blocks against 29.8% with opaque voxels (30.6% with no flyaways).
        // The path gain: held-out twill 26.6% → 26.3% (worst 33.2 → 32.0%), satin and
        // felt in baker/FIT_MEASUREMENTS.md ("The flyaways' opacity against the volume").
        // The cylinder law: held-out satin 29.2% → 24.7% at 64² (its mirror views 39–48% →
        // 20–27%), felt 22.6 → 21.2%, twill 14.6 → 14.2%; far views at 70° 5.5–10.9% →
        // 3.5–4.9% (baker/FIT_MEASUREMENTS.md and PREFILTER_MEASUREMENTS.md, "The
        // flyaways' lobes as cylinders").
        FlyawayOptions { clusters: 4, spp: 16, alpha: FlyawayAlpha::Density, path_gain: true, lobes: FiberLobes::Cylinder, shadow_surface: FlyawayShadow::Auto, refit_surface: false }
    }
}

impl Default for BakeOptions {
    fn default() -> Self {
        BakeOptions {
            seed: 1,
            geometry: GeometryOptions { detail_strength: 0.25, ..Default::default() },
            lookup: Lookup::Trilinear,
            pairs: PairOptions::default(),
            spp: 32,
            probe_rays: 2,
            // Measured (FIT_MEASUREMENTS.md, fast settings without flyaways): held-out
            // satin 43.5% with shadows, 40.1% without; twill 28.3% and 28.2%. The smooth
            // h shadows grazing light that reaches a fuzzy yarn's crests in the volume.
            shadows: false,
            // Measured at full settings without shadows (FIT_MEASUREMENTS.md), weighted
            // against unweighted: silk 33.4% / 47.1% (its dim grazing views 1.3× / 2.3×
            // too bright), satin 35.8% / 36.8%, but twill 26.4% / 25.6%, plain 28.9% /
            // 28.4%, felt 38.1% / 36.4%: the worst preset and the mean are better weighted.
            pair_weights: true,
            // Measured worse on held-out views (FIT_MEASUREMENTS.md): twill 29.6% vs
            // 28.3%, satin 44.7% vs 42.2%, though it mends the mirror views' fall-off.
            volumetric: false,
            // V alone masked (the paper's "complement of V"): the halo above the surface
            // run, which the model does not draw, is the surface's to fit; unmasked, the
            // surface also learns V's light, which the flyaways then add again (felt's
            // grazing view 17.6 → 23.8%; FIT_MEASUREMENTS.md, "What the surface fit sees").
            surface_mask: SurfaceMask::Flyaways,
            // One round at about 32 texels per cluster, at most 128 (`auto_k`). Measured on
            // the 64² presets (baker/FIT_MEASUREMENTS.md, "How many clusters"): the
            // doubling from 4 stopped twill at 32, satin and felt at 8, where a doubling
            // gained less than `min_gain`; at 128 the held-out error is twill 16.1 →
            // 14.6%, satin 30.6 → 29.2%, felt 22.7 → 22.6%, and one round of 128 costs
            // less than the doubling to 128.
            k_min: K_AUTO,
            k_max: K_AUTO,
            delta: 0.05,
            min_gain: 0.03,
            // Lommel–Seeliger's diffuse law: held-out twill 26.4 → 25.3%, satin unchanged
            // (baker/FIT_MEASUREMENTS.md, "Lommel–Seeliger diffuse").
            fit: ClusterFitOptions { diffuse: DiffuseLaw::LommelSeeliger, ..ClusterFitOptions::default() },
            frame_fit: Some(FrameFitOptions::default()),
            dense_pairs: 48,
            dense_spp: 32,
            per_texel_ridge: Some(0.05),
            // Twill 64² (24 pairs, K = 32): held-out 16.6 → 14.3%, satin 26.8 → 25.9%
            // (baker/FIT_MEASUREMENTS.md, "The visibility gradient").
            gradient: Some(GradientOptions::default()),
            normal_slope: 1.0,
            relief: 0.0,
            surface_offset: 0.0,
            flyaways: Some(FlyawayOptions::default()),
            prefilter: Some(PrefilterOptions::default()),
            transmission: None,
            lobe_peak_max: Some(LOBE_PEAK_MAX),
        }
    }
}

/// Why a bake cannot run or finish.
#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    #[error("geometry: {0}")]
    Geometry(#[from] GeometryError),
    #[error("training rendering: {0}")]
    Reference(#[from] ReferenceError),
    #[error("building the model: {0}")]
    Model(#[from] ModelError),
    #[error("clustering: {0}")]
    Cluster(String),
    #[error("mip chain: {0}")]
    Prefilter(#[from] PrefilterError),
    #[error("flyaways: {0}")]
    Flyaways(String),
    #[error("option {name} = {value}: {reason}")]
    BadOption { name: &'static str, value: String, reason: String },
}

/// One round of Algorithm 1's loop.
#[derive(Clone, Debug, Serialize)]
pub struct KRound {
    pub k: usize,
    /// Relative RMSE of the model against the training images, per pixel and over
    /// 4×4-texel blocks.
    pub error: f64,
    pub block_error: f64,
    /// Median relative residual of the cluster fits.
    pub median_cluster_residual: f64,
    pub seconds: f64,
    pub dense_paths: u64,
}

/// A cluster whose fit fell back.
#[derive(Clone, Debug, Serialize)]
pub struct ClusterProblem {
    pub cluster: usize,
    pub texels: usize,
    pub problem: String,
}

/// What a bake measured.
#[derive(Clone, Debug, Serialize)]
pub struct BakeReport {
    pub dims: [usize; 3],
    pub pairs: Vec<Pair>,
    pub training_spp: u32,
    pub training_paths: u64,
    /// The training renderings' own relative error (from the two halves).
    pub noise_floor: f64,
    pub rounds: Vec<KRound>,
    /// The K kept and its errors with the cluster BRDFs alone...
    pub k: usize,
    pub cluster_error: f64,
    pub cluster_block_error: f64,
    /// ... and, with `per_texel`, after the per-texel refinement (what the model holds).
    pub per_texel: bool,
    pub error: f64,
    pub block_error: f64,
    /// Training-image error split by pair kind and by grazing (either polar angle > 55°).
    pub error_by_kind: Vec<(String, f64)>,
    pub error_grazing: f64,
    pub error_non_grazing: f64,
    /// Per training pair: (relative RMSE over 4×4 blocks, mean(model)/mean(reference)).
    pub pair_errors: Vec<(f64, f64)>,
    pub cluster_problems: Vec<ClusterProblem>,
    /// Per cluster of the K kept: its fitted frame offset per lobe (`fit::frames`; all
    /// identity without the frame fit, all equal unless the lobes have their own).
    pub frame_offsets: Vec<Vec<FrameOffset>>,
    pub reading: String,
    /// The surface's diffuse law (`lambert` or `lommel-seeliger`; format 1.6).
    pub diffuse: String,
    pub shadows: bool,
    pub volumetric: bool,
    pub surface_mask: SurfaceMask,
    pub normal_detail: f32,
    pub normal_slope: f32,
    pub relief: f32,
    pub flyaway_voxels: usize,
    /// The lobes' energy bound (`fit::energy`): what it found and what it scaled down.
    pub energy: EnergyReport,
    /// The texels' visibility gradients (`fit::gradient`; None: off).
    pub gradient: Option<GradientReport>,
    /// Cluster lobes held at k = 0 because no training sample came within three widths
    /// of their ridge (`cluster_fit::LOBE_SUPPORT_MIN`), of `cluster_lobes` in all.
    pub unseen_lobes: usize,
    pub cluster_lobes: usize,
    /// The multiple of each cluster's brightest training radiance that bounds what one
    /// lobe adds anywhere (`cluster_fit::LOBE_PEAK_MAX`; none: unbounded), the cluster
    /// lobes the fit held at that bound, and the texel lobes lowered to it after the
    /// per-texel refinement.
    pub lobe_peak_max: Option<f32>,
    pub peak_capped_lobes: usize,
    pub texel_lobes_peak_capped: usize,
    pub flyaways: Option<FlyawayReport>,
    /// The surface refitted behind the flyaways (None: not tried).
    pub surface_refit: Option<SurfaceRefitReport>,
    /// The mip chain's figures per level (fit error, lobes, bytes, time).
    pub prefilter: Option<PrefilterReport>,
    /// The transmission fit's figures (a BSDF bake).
    pub transmission: Option<TransmissionReport>,
    pub stage_seconds: Vec<(String, f64)>,
    /// The process's peak resident memory (bytes) at the end of each stage, where the
    /// system reports it (`memory::peak_rss_bytes`): the stage that raised it is the
    /// bake's memory bound.
    pub stage_peak_rss_bytes: Vec<(String, u64)>,
    pub total_seconds: f64,
    pub input_bytes: u64,
    pub model_bytes: u64,
}

/// The texels' visibility gradients (`fit::gradient`): |g| over the texels, and the
/// training error (per texel, over 4×4 blocks) of the same refinement without them.
#[derive(Clone, Debug, Default, Serialize)]
pub struct GradientReport {
    pub median: f32,
    pub p90: f32,
    /// The median of |q| of the visibility curvature (format 1.15; none: not fitted).
    pub curvature_median: Option<f32>,
    pub error_without: f64,
    pub block_error_without: f64,
}

/// The lobes' energy bound (`fit::energy`): the worst albedo of the fitted lobes, before
/// the bound, and how many were scaled down to [`LOBE_ALBEDO_MAX`].
#[derive(Clone, Debug, Default, Serialize)]
pub struct EnergyReport {
    pub lobe_albedo_max: f32,
    /// The worst Σ_j k_j Â_j of a cluster's lobes as fitted, and how many clusters were
    /// scaled.
    pub worst_cluster_albedo: f32,
    pub clusters_capped: usize,
    /// The same per texel after the per-texel refinement (0 without it).
    pub worst_texel_albedo: f32,
    pub texels_capped: usize,
    /// The same per flyaway table entry (0 without flyaways).
    pub worst_flyaway_albedo: f32,
    pub flyaway_entries_capped: usize,
}

/// One texel after the per-texel refinement: its BRDF (peak- and energy-capped), the
/// lobes' albedo before the energy cap, its visibility gradient, the BRDF refined
/// without the gradient (to report what the gradient bought), and how many of its
/// lobes the peak bound lowered.
struct RefinedTexel {
    params: ClothParams,
    albedo: f32,
    vis: Visibility,
    without_gradient: Option<ClothParams>,
    peak_lowered: u32,
}

/// The worst of the lobes' albedos as fitted, and how many were above the bound (scaled).
fn albedo_summary(albedos: &[f32]) -> (f32, usize) {
    (albedos.iter().copied().fold(0.0, f32::max), albedos.iter().filter(|&&a| a > LOBE_ALBEDO_MAX).count())
}

/// What the transmission fit measured.
#[derive(Clone, Debug, Serialize)]
pub struct TransmissionReport {
    /// Backlit training pairs (the training pairs with ω_i mirrored below the sheet).
    pub pairs: Vec<Pair>,
    /// The backlit renderings' own relative error (from their two halves).
    pub noise_floor: f64,
    /// Training-image error with the cluster terms alone, and per pixel / over 4×4
    /// blocks with what the model holds (refined per texel, energy capped).
    pub cluster_error: f64,
    pub error: f64,
    pub block_error: f64,
    /// Per backlit pair: (relative RMSE over 4×4 blocks, mean(model)/mean(reference)).
    pub pair_errors: Vec<(f64, f64)>,
    /// With the transmission visibility (format 1.16): the training error per pixel and
    /// over 4×4 blocks of the same refinement without it (energy capped as the kept
    /// one), and the median |g| over the texels; None without the gradient.
    pub without_visibility: Option<(f64, f64)>,
    pub gradient_median: Option<f32>,
    /// The largest transmitted albedo of any texel after the cap (`albedo_estimate`: an
    /// upper bound where below 1), and how many texels the cap scaled down.
    pub worst_albedo: f32,
    pub capped_texels: usize,
    /// Clusters whose fit fell back (no samples, bad data).
    pub problems: Vec<ClusterProblem>,
    /// The openness (the gaps between yarns, `fit::openness`), None where not measured.
    pub openness: Option<OpennessReport>,
    /// Seconds of the backlit renderings and of the fit (the openness included).
    pub render_seconds: f64,
    pub fit_seconds: f64,
}

/// The result of a bake.
pub struct Bake {
    pub model: HybridModel,
    pub report: BakeReport,
    pub geometry: Geometry,
    pub training: TrainingImages,
    /// Per texel: its cluster; per cluster: its fit.
    pub clusters: Vec<u32>,
    pub fits: Vec<ClusterFit>,
    /// The model's training-image predictions (same layout as `training.images`).
    pub predictions: Vec<Image>,
}

/// `k_min`/`k_max` that ask for [`auto_k`].
pub const K_AUTO: usize = 0;

/// Texels per cluster of [`auto_k`].
pub const AUTO_K_TEXELS: usize = 32;

/// Bounds of [`auto_k`]: 4, the doubling's old start; 128 for time, the fitting (Nelder–Mead
/// and the frame search per cluster) growing with K: the round of 128 takes 194 s on a 64²
/// twill against 64 s for the round of 32, and 255 s at 128², of the 10 minutes a stage
/// may take there (baker/FIT_MEASUREMENTS.md, "How many clusters").
pub const AUTO_K_RANGE: [usize; 2] = [4, 128];

/// The default cluster count for `texels` texels: the largest power of two at most
/// texels / [`AUTO_K_TEXELS`], within [`AUTO_K_RANGE`] (and at most `texels`).
pub fn auto_k(texels: usize) -> usize {
    let target = (texels / AUTO_K_TEXELS).max(1);
    let pow2 = 1usize << (usize::BITS - 1 - target.leading_zeros());
    pow2.clamp(AUTO_K_RANGE[0], AUTO_K_RANGE[1]).min(texels.max(1))
}

impl BakeOptions {
    /// (k_min, k_max) for a model of `texels` texels, [`K_AUTO`] resolved by [`auto_k`].
    pub fn k_range(&self, texels: usize) -> (usize, usize) {
        let auto = auto_k(texels);
        // An explicit bound wins over the automatic other one.
        match (self.k_min, self.k_max) {
            (K_AUTO, K_AUTO) => (auto, auto),
            (K_AUTO, hi) => (auto.min(hi), hi),
            (lo, K_AUTO) => (lo, auto.max(lo)),
            (lo, hi) => (lo, hi),
        }
    }

    pub fn validate(&self) -> Result<(), BakeError> {
        let bad = |name, value: String, reason: &str| Err(BakeError::BadOption { name, value, reason: reason.into() });
        if self.spp < 2 || self.spp > 1 << 16 {
            return bad("spp", self.spp.to_string(), "training samples per texel must be in 2..=65536 (two halves)");
        }
        if self.probe_rays == 0 || self.probe_rays > 64 {
            return bad("probe_rays", self.probe_rays.to_string(), "must be in 1..=64");
        }
        if self.k_max > 65536 || self.k_min > 65536 || (self.k_min != K_AUTO && self.k_max != K_AUTO && self.k_max < self.k_min) {
            return bad("k", format!("{}..{}", self.k_min, self.k_max), "need k_min ≤ k_max ≤ 65536 (0: auto)");
        }
        if !(self.delta >= 0.0 && self.delta.is_finite() && self.min_gain >= 0.0 && self.min_gain < 1.0) {
            return bad("delta/min_gain", format!("{}/{}", self.delta, self.min_gain), "δ ≥ 0 and 0 ≤ min_gain < 1");
        }
        if self.pairs.count < 8 || self.pairs.count > 4096 {
            return bad("pairs", self.pairs.count.to_string(), "between 8 and 4096 training configurations");
        }
        if !(self.pairs.max_polar_deg > 5.0 && self.pairs.max_polar_deg <= 85.0) {
            return bad("max_polar", self.pairs.max_polar_deg.to_string(), "degrees in (5, 85]");
        }
        if self.fit.lobes == 0 || self.fit.lobes > 4 {
            return bad("lobes", self.fit.lobes.to_string(), "1..=4 lobes at level 0");
        }
        // η = 1 makes the Fresnel factor, and with it every lobe, zero: nothing to fit.
        if !(self.fit.eta >= ETA_MIN_FIT && self.fit.eta <= fabric_runtime::brdf::ETA_MAX) {
            return bad("eta", self.fit.eta.to_string(), "must be in [1.01, 4] (at η = 1 the Fresnel factor, and every lobe with it, is zero)");
        }
        if let Some(m) = self.lobe_peak_max
            && !(m.is_finite() && m >= 1.0)
        {
            return bad("lobe_peak_max", m.to_string(), "a lobe's bound must be a finite multiple ≥ 1 of its cluster's brightest radiance (None: no bound)");
        }
        if let Some(t) = &self.transmission
            && t.openness_rays > 256
        {
            return bad("openness_rays", t.openness_rays.to_string(), "rays per texel per view must be in 0..=256 (0: no openness)");
        }
        Ok(())
    }
}

/// The smallest Fresnel index `fabric bake --eta` takes.
pub const ETA_MIN_FIT: f32 = 1.01;

/// Scales every normal's slope by `c` (n ∝ (c·n_x/n_z, c·n_y/n_z, 1)) and makes the
/// tangents perpendicular to the new normals again.
pub fn scale_normal_slopes(g: &mut Geometry, c: f32) {
    if c == 1.0 {
        return;
    }
    for (n, t) in g.normals.iter_mut().zip(g.tangents.iter_mut()) {
        let z = n.z.max(1e-3);
        let m = Vec3::new(c * n.x / z, c * n.y / z, 1.0).normalize();
        let tp = *t - m * t.dot(m);
        *t = if tp.length_squared() > 1e-12 { tp.normalize() } else { fabric_runtime::brdf::cloth_reference_tangent(m) };
        *n = m;
    }
}

/// The model's surface in voxels: h + relief·(h0 − h), within the volume.
pub fn surface_heights(g: &Geometry, relief: f32) -> Vec<f32> {
    g.h.iter().zip(&g.h0).map(|(h, h0)| (h + relief * (h0 - h)).clamp(0.0, g.depth as f32)).collect()
}

/// Heights in voxels as world z per texel (what the measurement rays aim at).
fn world_heights(volume: &FabricVolume, heights: &[f32]) -> Vec<f32> {
    let (z0, vz) = (volume.bbox().min.z, volume.voxel_size().z);
    heights.iter().map(|h| z0 + h * vz).collect()
}

/// The model's level 0 with the geometry's frames, cluster `clusters[j]` per texel and
/// `params` per cluster (a skeleton with one zero BRDF when `params` is empty).
pub fn level0(g: &Geometry, clusters: &[u32], params: &[ClothParams]) -> Level {
    let frames: Vec<ClothFrame> = (0..g.texels()).map(|j| fabric_runtime::brdf::cloth_frame(g.normals[j], g.tangents[j])).collect();
    level0_framed(g, &frames, clusters, params)
}

/// Level 0 in the clustered encoding with the texels' frames `frames`.
pub fn level0_framed(g: &Geometry, frames: &[ClothFrame], clusters: &[u32], params: &[ClothParams]) -> Level {
    let mut table = BrdfTable::new();
    if params.is_empty() {
        table.push(&ClothParams::new(Vec3::ZERO, 1.5, 0.0, &[]));
    }
    for p in params {
        table.push(p);
    }
    let texels = (0..g.texels()).map(|j| ClusteredTexel::new(frames[j].n, frames[j].t, clusters.get(j).copied().unwrap_or(0) as u16)).collect();
    Level { width: g.dims[0] as u32, height: g.dims[1] as u32, surface: Surface::Clustered { texels, table }, flyaways: None, transmission: None, transmission_visibility: None, view_tilt: None, gradient: None, curvature: None }
}

/// Level 0 in the per-texel encoding: each texel its own k_d and k_j (refined), its
/// cluster's β, γ, a and η, lobe l in the frame `frames[j][l]` (lobe 0's also the
/// diffuse term's).
pub fn level0_per_texel(g: &Geometry, frames: &[TexelFrames], params: &[ClothParams]) -> Level {
    let mut table = BrdfTable::new();
    for (j, p) in params.iter().enumerate() {
        let lobes: Vec<_> = p.lobes().iter().enumerate().map(|(l, lobe)| (*lobe, frames[j][l].n, frames[j][l].t)).collect();
        table.push_framed(p.kd, p.eta, p.a, &lobes);
    }
    Level { width: g.dims[0] as u32, height: g.dims[1] as u32, surface: Surface::PerTexel(table), flyaways: None, transmission: None, transmission_visibility: None, view_tilt: None, gradient: None, curvature: None }
}

/// A level-0 texel's frame per lobe (lobe 0's also the diffuse term's).
pub type TexelFrames = [ClothFrame; LEVEL0_LOBES];

/// Each texel's frames with its cluster's offsets applied.
fn offset_frames(base: &[ClothFrame], clusters: &[u32], offsets: &[Vec<FrameOffset>]) -> Vec<TexelFrames> {
    base.iter()
        .zip(clusters)
        .map(|(f, &c)| {
            let offs = &offsets[c as usize];
            std::array::from_fn(|l| offs.get(l).or(offs.last()).map_or(*f, |o| o.apply(f)))
        })
        .collect()
}

/// Bakes `volume` into a hybrid model (level 0).
pub fn bake(volume: &FabricVolume, options: &BakeOptions, progress: &dyn Progress) -> Result<Bake, BakeError> {
    options.validate()?;
    // The volume's box must make a valid tile; say so before the hours of work, not after.
    {
        let [nx, ny, nz] = volume.dims();
        Tile::from_source(volume.bbox(), [nx as u32, ny as u32, nz as u32]).validate()?;
    }
    let start = Instant::now();
    let mut stage_seconds: Vec<(String, f64)> = Vec::new();
    let mut stage_peak_rss_bytes: Vec<(String, u64)> = Vec::new();
    let mut stage = |name: &str, t: Instant| {
        stage_seconds.push((name.to_string(), t.elapsed().as_secs_f64()));
        if let Some(peak) = crate::memory::peak_rss_bytes() {
            stage_peak_rss_bytes.push((name.to_string(), peak));
        }
    };

    // 1. Geometry.
    let t = Instant::now();
    let mut geometry = extract_geometry_with(volume, &options.geometry, progress)?;
    let nz_f = volume.dims()[2] as f32;
    scale_normal_slopes(&mut geometry, options.normal_slope);
    let surface: Vec<f32> = surface_heights(&geometry, options.relief).into_iter().map(|h| (h + options.surface_offset).clamp(0.0, nz_f)).collect();
    stage("geometry", t);
    let [nx, ny, nz] = volume.dims();
    let texels = nx * ny;
    if texels > 65536 * 65536 {
        return Err(BakeError::BadOption { name: "volume", value: format!("{nx}×{ny}"), reason: "too many texels".into() });
    }

    // The model's geometry: tile, height field, texel frames.
    let bbox = volume.bbox();
    let tile = Tile::from_source(bbox, [nx as u32, ny as u32, nz as u32]);
    let height = HeightField::from_voxel_heights(nx as u32, ny as u32, &surface, nz as u32, &tile)?;
    let meta = |fit_error: f32, note: String| BakeMetadata {
        reading: options.fit.reading,
        fitted_with_shadowing: options.shadows,
        volumetric: options.volumetric,
        coarse_visibility: false,
        diffuse: options.fit.diffuse,
        fiber_lobes: options.flyaways.as_ref().map_or(FiberLobes::Facing, |f| f.lobes),
        // Decided with the flyaways' fit (FlyawayShadow::Auto); the surface's sees none.
        flyaway_shadow: options.flyaways.as_ref().is_some_and(|f| f.shadow_surface == FlyawayShadow::On),
        fit_error: vec![fit_error],
        source_bbox: bbox,
        source_dims: [nx as u32, ny as u32, nz as u32],
        seed: options.seed,
        note,
    };
    let skeleton = HybridModel { tile, height: height.clone(), levels: vec![level0(&geometry, &[], &[])], meta: meta(-1.0, String::new()) };
    skeleton.validate()?;

    // 2. Training renderings of the surface (mask applied).
    let t = Instant::now();
    let heights = world_heights(volume, &surface);
    let mask: Option<Vec<bool>> = match options.surface_mask {
        SurfaceMask::AboveSurface => Some(geometry.above_surface_mask()),
        SurfaceMask::Flyaways => Some(geometry.flyaway_mask().to_bools()),
        SurfaceMask::None => None,
    };
    let measure = MeasureScene::new(volume, options.lookup, Some(&heights), mask.as_deref())?;
    let pairs = training_pairs(&PairOptions { seed: mix64(options.seed ^ options.pairs.seed), ..options.pairs.clone() });
    let bar = begin_stage(progress, "training renderings", pairs.len() as u64);
    let training = render_training(&measure, &pairs, options.spp, options.seed, &|| bar.advance(1))?;
    bar.finish();
    stage("training renderings", t);

    // 3. Samples: the training rays through the model.
    let t = Instant::now();
    let probe = ProbeOptions { rays: options.probe_rays, shadows: options.shadows, volumetric: options.volumetric, diffuse: options.fit.diffuse };
    let all_texels: Vec<u32> = (0..texels as u32).collect();
    let jitter = image_jitter(half_seeds(options.seed)[0]);
    let bar = begin_stage(progress, "probing the model", pairs.len() as u64);
    let mut samples: Vec<Sample> = Vec::new();
    for (c, p) in pairs.iter().enumerate() {
        let base = (c * texels) as u32;
        samples.extend(probe_samples(&skeleton, &measure, (p.wi, p.wo, c as u32), &all_texels, &probe, &jitter, &|j| base + j));
        bar.advance(1);
    }
    bar.finish();
    let target_of = |s: &Sample| training.images[s.target as usize / texels].pixels[s.target as usize % texels];
    stage("probing", t);
    // The frames the probe shaded in (as stored: packed and decoded).
    let base_frames: Vec<ClothFrame> = match &skeleton.levels[0].surface {
        Surface::Clustered { texels, .. } => texels.iter().map(|t| t.frame()).collect(),
        Surface::PerTexel(_) => unreachable!("the skeleton is clustered"),
    };

    // 4. Features and K doubling.
    let features = texel_features(&geometry.normals, &geometry.tangents, &training.images);
    let dense_set = training_pairs(&PairOptions { count: options.dense_pairs.max(8), seed: mix64(options.seed ^ 0x64656e7365), ..options.pairs.clone() });
    // Every sample's pair: the training pairs, then the dense ones.
    let dirs: Vec<(Vec3, Vec3)> = pairs.iter().chain(&dense_set).map(|p| (p.wi, p.wo)).collect();
    // Each training pair's weight s_p (1 for the dense pairs): a sample's row and
    // target are both scaled by it, its visibility carrying the scale into every frame.
    let pair_w: Vec<f32> = if options.pair_weights { training.pair_weights() } else { Vec::new() };
    let pw = |s: &Sample| pair_w.get(s.dirs as usize).copied().unwrap_or(1.0);
    let weighted = |s: &Sample| Sample { vis: s.vis * pw(s), geo: s.geo.weighted(pw(s)), ..*s };
    let ray_of = |s: &Sample| TargetRay { texel: s.hit, dirs: s.dirs, vis: s.vis * pw(s) };
    let mut dense_cache: HashMap<u32, Vec<Sample>> = HashMap::new();
    let mut dense_values: Vec<Vec3> = Vec::new();
    let dense_seed = mix64(options.seed ^ 0x6d65_6173);
    let mut rounds: Vec<KRound> = Vec::new();
    // (training error, clusters, fits, frame offsets, predictions, lobe peak bounds) of
    // the best round so far.
    type Round = (f64, Vec<u32>, Vec<ClusterFit>, Vec<Vec<FrameOffset>>, Vec<Image>, Vec<Option<Vec3>>);
    // The clustered encoding holds one frame per texel: lobes of their own need the
    // per-texel one.
    let frame_fit = options.frame_fit.clone().map(|f| FrameFitOptions { per_lobe: f.per_lobe && options.per_texel_ridge.is_some(), ..f });
    let mut best: Option<Round> = None;
    let (k_min, k_max) = options.k_range(texels);
    let mut k = k_min.min(texels);
    let t_fit = Instant::now();
    loop {
        let t_round = Instant::now();
        let bar = begin_stage(progress, format!("K = {k}: clustering"), 1);
        let km = kmeans(&features.data, features.dim, k, &KMeansOptions { seed: options.seed, ..Default::default() }).map_err(|e| BakeError::Cluster(e.to_string()))?;
        let reps = representatives(&features.data, features.dim, &km);
        bar.finish();
        // Dense measurement of new representatives.
        let new_reps: Vec<u32> = reps.iter().map(|&r| r as u32).filter(|r| !dense_cache.contains_key(r)).collect();
        let bar = begin_stage(progress, format!("K = {k}: dense measurement"), new_reps.len() as u64);
        let mut dense_paths = 0;
        for &rep in &new_reps {
            let (x, y) = (rep as usize % nx, rep as usize / nx);
            let pairs_wiwo: Vec<(Vec3, Vec3)> = dense_set.iter().map(|p| (p.wi, p.wo)).collect();
            let (values, stats) = measure.measure_texel((x, y), &pairs_wiwo, options.dense_spp, dense_seed)?;
            dense_paths += stats.paths;
            let mut rep_samples = Vec::new();
            for (c, p) in dense_set.iter().enumerate() {
                let index = dense_values.len() as u32;
                dense_values.push(values[c]);
                let jitter = |texel: u32, s: u32| texel_jitter(dense_seed, texel, c as u32, s);
                rep_samples.extend(probe_samples(&skeleton, &measure, (p.wi, p.wo, (pairs.len() + c) as u32), &[rep], &probe, &jitter, &|_| index));
            }
            dense_cache.insert(rep, rep_samples);
            bar.advance(1);
        }
        bar.finish();
        // Gather each cluster's targets: training samples by the texel hit, and the dense
        // samples of its representative.
        // Each cluster's training samples are gathered as it is fitted, not all at once
        // (a second copy of every sample's factors was the 512² bake's peak memory).
        let cluster = &km.assignment;
        let by_cluster = Groups::by_key(samples.len(), k, |i| cluster[samples[i].hit as usize] as usize);
        let mut dense_targets: Vec<(Vec<Target>, Vec<TargetRay>)> = vec![(Vec::new(), Vec::new()); k];
        for &rep in &reps {
            for s in &dense_cache[&(rep as u32)] {
                let t = &mut dense_targets[cluster[s.hit as usize] as usize];
                t.0.push(Target { geo: s.geo, radiance: dense_values[s.target as usize] });
                t.1.push(ray_of(s));
            }
        }
        // Each cluster's bound on what one lobe may add (`cluster_fit::LOBE_PEAK_MAX`):
        // the brightest the volume showed of it, in training pixels and dense values.
        let bounds: Vec<Option<Vec3>> = (0..k)
            .map(|c| {
                options.lobe_peak_max.map(|m| {
                    let trained = by_cluster.group(c).iter().map(|&i| target_of(&samples[i as usize]));
                    m * trained.chain(dense_targets[c].0.iter().map(|t| t.radiance)).fold(Vec3::ZERO, Vec3::max)
                })
            })
            .collect();
        let bar = begin_stage(progress, format!("K = {k}: fitting"), k as u64);
        let (fits, offsets): (Vec<ClusterFit>, Vec<Vec<FrameOffset>>) = dense_targets
            .into_par_iter()
            .enumerate()
            .map(|(c, (dense_t, dense_r))| {
                let members = by_cluster.group(c);
                let mut t: Vec<Target> = Vec::with_capacity(members.len() + dense_t.len());
                let mut r: Vec<TargetRay> = Vec::with_capacity(members.len() + dense_r.len());
                for &i in members {
                    let s = &samples[i as usize];
                    t.push(Target { geo: weighted(s).geo, radiance: target_of(s) * pw(s) });
                    r.push(ray_of(s));
                }
                t.extend(dense_t);
                r.extend(dense_r);
                let o = ClusterFitOptions { peak_bound: bounds[c], ..options.fit.clone() };
                let f = match &frame_fit {
                    Some(fo) => fit_cluster_framed(&t, &r, &base_frames, &dirs, &o, fo),
                    None => (fit_cluster(&t, &o), vec![FrameOffset::IDENTITY]),
                };
                bar.advance(1);
                f
            })
            .unzip();
        drop(by_cluster);
        bar.finish();
        // The model's training images, and its error against them.
        let frames = offset_frames(&base_frames, cluster, &offsets);
        let geo_of = |s: &Sample| sample_geo(s, &frames, &dirs, options.fit.diffuse);
        let predictions = predict_images(&samples, &|hit| &fits[cluster[hit] as usize].params, &geo_of, options.fit.reading, &training, texels, options.probe_rays);
        let (error, block_error) = image_errors(&predictions, &training.images, nx, ny);
        let mut residuals: Vec<f64> = fits.iter().filter(|f| f.samples > 0).map(|f| f.relative_residual()).collect();
        residuals.sort_by(|a, b| a.total_cmp(b));
        let median = residuals.get(residuals.len() / 2).copied().unwrap_or(0.0);
        rounds.push(KRound { k, error, block_error, median_cluster_residual: median, seconds: t_round.elapsed().as_secs_f64(), dense_paths });
        let improved = best.as_ref().is_none_or(|b| error < b.0);
        let gain = best.as_ref().map_or(1.0, |b| (b.0 - error) / b.0.max(1e-30));
        if improved {
            best = Some((error, cluster.clone(), fits, offsets, predictions, bounds));
        }
        if error < options.delta.max(training.noise) || gain < options.min_gain || k >= k_max.min(texels) {
            break;
        }
        k = (2 * k).min(k_max).min(texels);
    }
    stage("clustering and fitting", t_fit);
    let (cluster_error, clusters, fits, offsets, predictions, bounds) = best.expect("at least one round");
    // The texels' frames as fitted (each cluster's offset applied): what level 0 stores.
    let frames = offset_frames(&base_frames, &clusters, &offsets);
    let lobe0_frames: Vec<ClothFrame> = frames.iter().map(|f| f[0]).collect();
    let geo_of = |s: &Sample| sample_geo(s, &frames, &dirs, options.fit.diffuse);
    // The lobes' energy (fit::energy): a lobe that the pairs see only by its tail may not
    // reflect more than it receives. Each cluster's lobes are capped before the per-texel
    // refinement, which starts from them, and each texel's after it.
    let unit: Vec<Vec<f32>> = fits.par_iter().map(|f| unit_albedos(&f.params, options.fit.reading)).collect();
    let (params, cluster_albedos): (Vec<ClothParams>, Vec<f32>) = fits.iter().zip(&unit).map(|(f, u)| cap_lobes(&f.params, u)).unzip();
    let (worst_cluster_albedo, clusters_capped) = albedo_summary(&cluster_albedos);
    let k = params.len();
    let cluster_block_error = rounds.iter().find(|r| r.k == k).map_or(cluster_error, |r| r.block_error);

    // Per-texel refinement of the linear parameters.
    let t = Instant::now();
    let mut energy = EnergyReport { lobe_albedo_max: LOBE_ALBEDO_MAX, worst_cluster_albedo, clusters_capped, ..Default::default() };
    let mut texel_gradients: Option<Vec<Visibility>> = None;
    let mut gradient_report: Option<GradientReport> = None;
    let mut texel_lobes_peak_capped = 0;
    // Each texel's k_d, k_j (and visibility gradient) refined on its own samples from its
    // cluster's BRDF: `value(i)` is sample i's target radiance, `weight` its pair's weight.
    let refine_texels = |samples: &[Sample], value: &(dyn Fn(usize) -> Vec3 + Sync), weight: &(dyn Fn(&Sample) -> f32 + Sync), ridge: f64| -> Vec<RefinedTexel> {
        // Each texel's samples gathered as it is refined (Groups: four bytes a sample).
        let by_texel = Groups::by_key(samples.len(), texels, |i| samples[i].hit as usize);
        (0..texels)
            .into_par_iter()
            .map(|j| {
                let group = by_texel.group(j);
                let t: Vec<LobeTarget> = group
                    .iter()
                    .map(|&i| {
                        let s = &samples[i as usize];
                        let w = weight(s);
                        LobeTarget { radiance: value(i as usize) * w, ..geo_of(&Sample { vis: s.vis * w, ..*s }) }
                    })
                    .collect();
                let c = clusters[j] as usize;
                // A texel's lobes bounded as its cluster's were (the same β, γ).
                let peak = |p: ClothParams| match bounds[c] {
                    Some(b) => cap_peaks(&p, b, options.fit.reading),
                    None => (p, 0),
                };
                let (first, lowered_first) = peak(refine_texel(&t, &params[c], ridge, options.fit.reading));
                let plain = cap_lobes(&first, &unit[c]);
                match &options.gradient {
                    Some(go) => {
                        let pairs: Vec<(Vec3, Vec3)> = group.iter().map(|&i| dirs[samples[i as usize].dirs as usize]).collect();
                        let (p, vis) = refine_gradient_from(first, &t, &pairs, &params[c], ridge, go, options.fit.reading);
                        let (p, lowered) = peak(p);
                        let (p, albedo) = cap_lobes(&p, &unit[c]);
                        RefinedTexel { params: p, albedo, vis, without_gradient: Some(plain.0), peak_lowered: lowered }
                    }
                    None => RefinedTexel { params: plain.0, albedo: plain.1, vis: Visibility::default(), without_gradient: None, peak_lowered: lowered_first },
                }
            })
            .collect()
    };
    let (mut texel_params, predictions, error, block_error) = match options.per_texel_ridge {
        Some(ridge) => {
            let bar = begin_stage(progress, "per-texel refinement", 1);
            let refined = refine_texels(&samples, &|i| target_of(&samples[i]), &pw, ridge);
            let albedos: Vec<f32> = refined.iter().map(|r| r.albedo).collect();
            (energy.worst_texel_albedo, energy.texels_capped) = albedo_summary(&albedos);
            texel_lobes_peak_capped = refined.iter().map(|r| r.peak_lowered as usize).sum();
            if options.gradient.is_some() {
                // What the gradient bought: the training error of the refinement without it.
                let plain: Vec<ClothParams> = refined.iter().map(|r| r.without_gradient.unwrap_or(r.params)).collect();
                let predictions = predict_images(&samples, &|hit| &plain[hit], &geo_of, options.fit.reading, &training, texels, options.probe_rays);
                let (error_without, block_error_without) = image_errors(&predictions, &training.images, nx, ny);
                let sorted = |f: &dyn Fn(&Visibility) -> f32| {
                    let mut v: Vec<f32> = refined.iter().map(|r| f(&r.vis)).collect();
                    v.sort_by(f32::total_cmp);
                    v
                };
                let at = |v: &[f32], f: f64| v.get(((v.len() as f64 * f) as usize).min(v.len().saturating_sub(1))).copied().unwrap_or(0.0);
                let size = sorted(&|v| v.g.iter().map(|x| x * x).sum::<f32>().sqrt());
                let curvature_median = options.gradient.as_ref().is_some_and(|g| g.curvature).then(|| at(&sorted(&|v| v.q.iter().map(|x| x * x).sum::<f32>().sqrt()), 0.5));
                gradient_report = Some(GradientReport { median: at(&size, 0.5), p90: at(&size, 0.9), curvature_median, error_without, block_error_without });
                texel_gradients = Some(refined.iter().map(|r| r.vis).collect::<Vec<Visibility>>());
            }
            let refined: Vec<ClothParams> = refined.into_iter().map(|r| r.params).collect();
            let geo_of = |s: &Sample| match &texel_gradients {
                Some(g) => {
                    let (wi, wo) = dirs[s.dirs as usize];
                    with_gradient(geo_of(s), &g[s.hit as usize], wi, wo)
                }
                None => geo_of(s),
            };
            let predictions = predict_images(&samples, &|hit| &refined[hit], &geo_of, options.fit.reading, &training, texels, options.probe_rays);
            let (e, be) = image_errors(&predictions, &training.images, nx, ny);
            bar.finish();
            (Some(refined), predictions, e, be)
        }
        // What the model holds: the capped clusters.
        None if clusters_capped > 0 => {
            let predictions = predict_images(&samples, &|hit| &params[clusters[hit] as usize], &geo_of, options.fit.reading, &training, texels, options.probe_rays);
            let (e, be) = image_errors(&predictions, &training.images, nx, ny);
            (None, predictions, e, be)
        }
        None => (None, predictions, cluster_error, cluster_block_error),
    };
    stage("per-texel refinement", t);

    let cluster_problems = fits
        .iter()
        .enumerate()
        .filter_map(|(c, f)| f.problem.clone().map(|problem| ClusterProblem { cluster: c, texels: clusters.iter().filter(|&&x| x as usize == c).count(), problem }))
        .collect();
    let (error_by_kind, error_grazing, error_non_grazing) = split_errors(&predictions, &training);

    // 5. Transmission, with the reflection fixed.
    let t = Instant::now();
    let mut transmission_report = None;
    let mut texel_transmission = None;
    if let Some(to) = &options.transmission {
        let (t, r) = fit_texel_transmission(&skeleton, &lobe0_frames, &measure, &pairs, &clusters, k, options, to, progress)?;
        texel_transmission = Some(t);
        transmission_report = Some(r);
    }
    stage("transmission", t);

    let note = format!("fabric bake (fabric-baker {}): K = {k}, training error {:.4}, noise floor {:.4}{}", env!("CARGO_PKG_VERSION"), error, training.noise, if texel_transmission.is_some() { ", BSDF" } else { "" });
    let level = match &texel_params {
        Some(p) => level0_per_texel(&geometry, &frames, p),
        None => level0_framed(&geometry, &lobe0_frames, &clusters, &params),
    };
    let mut model = HybridModel { tile, height, levels: vec![level], meta: meta(error as f32, note) };
    let curvature = options.gradient.as_ref().is_some_and(|g| g.curvature);
    model.levels[0].gradient = texel_gradients.as_ref().map(|v| v.iter().map(|v| PackedGradient::new(v.g)).collect());
    model.levels[0].curvature = texel_gradients.as_ref().filter(|_| curvature).map(|v| v.iter().map(|v| PackedCurvature::new(v.q)).collect());
    if let Some(t) = &texel_transmission {
        model.levels[0].transmission = Some(t.iter().map(PackedTransmission::new).collect());
        model.levels[0].transmission_visibility = t.iter().any(|t| t.grad != [0.0; 4] || t.curv != [0.0; 6]).then(|| t.iter().map(|t| PackedTransmissionVisibility::new(t.grad, t.curv)).collect());
    }

    // 5. Flyaways, with the surface fixed.
    let mut flyaway_report = None;
    let mut surface_refit = None;
    if let Some(fo) = options.flyaways.as_ref().filter(|_| !geometry.flyaways.is_empty()) {
        let t = Instant::now();
        let surface_of = |texel: usize| match &texel_params {
            Some(p) => p[texel],
            None => params[clusters[texel] as usize],
        };
        let all: Vec<ClothParams> = (0..texels).map(surface_of).collect();
        let shape = surface_shape(&all);
        let (assignment, kf) = flyaway_clusters(&geometry.flyaways, fo.clusters, options.seed);
        let solid = geometry.density.solid;
        model.levels[0].flyaways = Some(flyaway_level(&geometry.flyaways, solid, &assignment, &vec![shape; kf], fo.alpha)?);
        let level0_gain = if fo.path_gain {
            let bar = begin_stage(progress, "flyaways: path gain", 1);
            // The medium of the flyaway voxels alone: every other voxel removed.
            let others = all_but_level0_flyaways(&model, volume.dims());
            let alone = TracedMedium::new(volume, MediumOptions { lookup: options.lookup, periodic: true, mask: Some(&others), ..Default::default() })?;
            let g = fit_level0_gain(&model, &alone, mix64(options.seed ^ 0x9a17));
            bar.finish();
            if let (Some(g), Some(f)) = (&g, model.levels[0].flyaways.as_mut()) {
                f.path_gain = Some(g.gain);
            }
            g
        } else {
            None
        };
        let full = MeasureScene::new(volume, options.lookup, Some(&heights), None)?;
        let bar = begin_stage(progress, "flyaways: training renderings", pairs.len() as u64);
        let full_training = render_training(&full, &pairs, fo.spp.max(2), mix64(options.seed ^ 0x666c79), &|| bar.advance(1))?;
        bar.finish();
        // The flyaways fitted with and without their shadow on the surface (format 1.13),
        // as the options say; with both, the whole model nearer the full volume's
        // training images over 4×4 blocks is kept.
        let shadows: &[bool] = match fo.shadow_surface {
            FlyawayShadow::Auto => &[true, false],
            FlyawayShadow::On => &[true],
            FlyawayShadow::Off => &[false],
        };
        let bar = begin_stage(progress, "flyaways: fitting", shadows.len() as u64);
        let jitter_seed = half_seeds(mix64(options.seed ^ 0x666c79))[0];
        let mut tried: Vec<(HybridModel, FlyawayReport, Vec<f32>, f64)> = Vec::new();
        for &shadow in shadows {
            let mut m = model.clone();
            m.meta.flyaway_shadow = shadow;
            let (fly_params, rep) = fit_flyaways(&m, &full, &full_training, jitter_seed, options.probe_rays, options.shadows, &shape, kf, options.fit.reading);
            // The flyaways' lobes under the same energy bound as the surface's.
            let fly_unit: Vec<Vec<f32>> = fly_params.par_iter().map(|p| unit_albedos(p, options.fit.reading)).collect();
            let (fly_params, fly_albedos): (Vec<ClothParams>, Vec<f32>) = fly_params.iter().zip(&fly_unit).map(|(p, u)| cap_lobes(p, u)).unzip();
            m.levels[0].flyaways = Some(flyaway_level(&geometry.flyaways, solid, &assignment, &fly_params, fo.alpha)?);
            if let (Some(g), Some(f)) = (&level0_gain, m.levels[0].flyaways.as_mut()) {
                f.path_gain = Some(g.gain);
            }
            let block = if shadows.len() > 1 {
                full_image_errors(&m, &full, &full_training, jitter_seed, options.probe_rays, options.shadows).map_err(|e| BakeError::Flyaways(format!("measuring their shadow on the training pairs: {e}")))?.1
            } else {
                f64::NAN
            };
            bar.advance(1);
            tried.push((m, rep, fly_albedos, block));
        }
        bar.finish();
        let errors = |shadow: bool| tried.iter().find(|t| t.0.meta.flyaway_shadow == shadow).map(|t| t.3).filter(|e| e.is_finite());
        let (block_error_shadowed, block_error_unshadowed) = (errors(true), errors(false));
        let best = (0..tried.len()).min_by(|&a, &b| tried[a].3.total_cmp(&tried[b].3)).unwrap_or(0);
        let (kept, mut rep, fly_albedos, kept_block_error) = tried.swap_remove(best);
        model = kept;
        rep.shadow_surface = model.meta.flyaway_shadow;
        (rep.block_error_shadowed, rep.block_error_unshadowed) = (block_error_shadowed, block_error_unshadowed);
        (energy.worst_flyaway_albedo, energy.flyaway_entries_capped) = albedo_summary(&fly_albedos);
        rep.voxels = geometry.flyaways.len();
        if let Some(g) = &level0_gain {
            rep.path_gain = Some(g.gain.0.to_vec());
            rep.transmittance_volume = Some(g.level0_transmittance.to_vec());
            rep.transmittance_ungained = Some(g.level_transmittance.to_vec());
        }
        stage("flyaways", t);
        flyaway_report = Some(rep);

        // 5a. The surface refitted behind the flyaways just fitted (fit::behind): its fit
        // saw no flyaways in front of it.
        if let (true, Some(ridge), Some(texel_now)) = (fo.refit_surface, options.per_texel_ridge, texel_params.as_ref()) {
            let t = Instant::now();
            let bar = begin_stage(progress, "surface behind the flyaways", 1);
            let level_with = |params: &[ClothParams], vis: Option<&Vec<Visibility>>, from: &Level| Level {
                flyaways: from.flyaways.clone(),
                transmission: from.transmission.clone(),
                transmission_visibility: from.transmission_visibility.clone(),
                gradient: vis.map(|v| v.iter().map(|v| PackedGradient::new(v.g)).collect()),
                curvature: vis.filter(|_| curvature).map(|v| v.iter().map(|v| PackedCurvature::new(v.q)).collect()),
                ..level0_per_texel(&geometry, &frames, params)
            };
            let black: Vec<ClothParams> = texel_now.iter().map(|p| ClothParams { kd: Vec3::ZERO, lobes: p.lobes.map(|l| ClothLobe { k: Vec3::ZERO, ..l }), ..*p }).collect();
            let mut dark = model.clone();
            dark.levels[0] = level_with(&black, None, &model.levels[0]);
            let (behind, values): (Vec<Sample>, Vec<Vec3>) = behind_samples(&model, &dark, &full, &full_training, jitter_seed, options.probe_rays, options.shadows).into_iter().unzip();
            let full_w: Vec<f32> = if options.pair_weights { full_training.pair_weights() } else { Vec::new() };
            let full_pw = |s: &Sample| full_w.get(s.dirs as usize).copied().unwrap_or(1.0);
            let mut seen = vec![0usize; texels];
            behind.iter().for_each(|s| seen[s.hit as usize] += 1);
            let refit = refine_texels(&behind, &|i| values[i], &full_pw, ridge);
            // A texel seen by too few rays keeps its first refinement (fit::behind::MIN_SAMPLES).
            let keep = |j: usize| seen[j] < MIN_SAMPLES;
            let refit_params: Vec<ClothParams> = (0..texels).map(|j| if keep(j) { texel_now[j] } else { refit[j].params }).collect();
            let refit_gradients = texel_gradients.as_ref().map(|g| (0..texels).map(|j| if keep(j) { g[j] } else { refit[j].vis }).collect::<Vec<Visibility>>());
            let mut candidate = model.clone();
            candidate.levels[0] = level_with(&refit_params, refit_gradients.as_ref(), &model.levels[0]);
            let measure = |m: &HybridModel| full_image_errors(m, &full, &full_training, jitter_seed, options.probe_rays, options.shadows).map_err(|e| BakeError::Flyaways(format!("measuring the surface refitted behind them: {e}")));
            // The kept flyaway fit's own figure where both shadows were measured.
            let before = if kept_block_error.is_finite() { kept_block_error } else { measure(&model)?.1 };
            let after = measure(&candidate)?.1;
            let kept = after < before;
            if kept {
                model = candidate;
                let albedos: Vec<f32> = refit.iter().map(|r| r.albedo).collect();
                (energy.worst_texel_albedo, energy.texels_capped) = albedo_summary(&albedos);
                texel_lobes_peak_capped = refit.iter().map(|r| r.peak_lowered as usize).sum();
                texel_params = Some(refit_params);
            }
            bar.finish();
            surface_refit = Some(SurfaceRefitReport { samples: behind.len(), block_error_before: before, block_error_after: after, kept });
            stage("surface behind the flyaways", t);
        }
    }
    // 5b. A BSDF's gaps between yarns: what a light behind is never seen through (no
    // training pair shows it), measured on the whole volume along the probe's rays, behind
    // the flyaways just fitted.
    if let (Some(to), Some(report), Some(records)) = (&options.transmission, transmission_report.as_mut(), model.levels[0].transmission.clone())
        && to.openness_rays > 0
    {
        let t = Instant::now();
        let views = openness_views();
        let bar = begin_stage(progress, "transmission: the gaps between yarns", 1);
        let full = MeasureScene::new(volume, options.lookup, Some(&heights), None)?;
        let means = measure_openness(&model, &full, &views, to.openness_rays, mix64(options.seed ^ 0x6761_7073));
        let gaps = fit_openness(&means);
        bar.finish();
        model.levels[0].transmission = Some(records.iter().zip(&gaps).map(|(r, &gap)| PackedTransmission::new(&ClothTransmission { gap, ..r.decode() })).collect());
        let seconds = t.elapsed().as_secs_f64();
        report.openness = Some(openness_report(&means, &gaps, &views, to.openness_rays, seconds));
        report.fit_seconds += seconds;
        stage("transmission: gaps", t);
    }
    model.validate()?;
    // 6. The mip chain.
    let mut prefilter_report = None;
    if let Some(po) = &options.prefilter {
        let t = Instant::now();
        let (chained, r) = prefilter(&model, po, progress)?;
        model = chained;
        stage("prefilter", t);
        prefilter_report = Some(r);
    }
    let model_bytes = fabric_runtime::hybrid::format::to_bytes(&model).map(|b| b.len() as u64).unwrap_or(0);
    let report = BakeReport {
        dims: [nx, ny, nz],
        pairs: pairs.clone(),
        training_spp: options.spp,
        training_paths: training.paths,
        noise_floor: training.noise,
        rounds,
        k,
        cluster_error,
        cluster_block_error,
        per_texel: texel_params.is_some(),
        error,
        block_error,
        error_by_kind,
        error_grazing,
        error_non_grazing,
        pair_errors: predictions.iter().zip(&training.images).map(|(p, r)| (image_errors(std::slice::from_ref(p), std::slice::from_ref(r), nx, ny).1, p.mean() / r.mean().max(1e-30))).collect(),
        cluster_problems,
        frame_offsets: offsets.clone(),
        reading: options.fit.reading.name().into(),
        diffuse: options.fit.diffuse.name().into(),
        shadows: options.shadows,
        volumetric: options.volumetric,
        surface_mask: options.surface_mask,
        normal_detail: options.geometry.detail_strength,
        normal_slope: options.normal_slope,
        relief: options.relief,
        flyaway_voxels: geometry.flyaways.len(),
        energy,
        gradient: gradient_report,
        unseen_lobes: fits.iter().map(|f| f.unseen_lobes as usize).sum(),
        lobe_peak_max: options.lobe_peak_max,
        peak_capped_lobes: fits.iter().map(|f| f.peak_capped_lobes as usize).sum(),
        texel_lobes_peak_capped,
        cluster_lobes: fits.iter().map(|f| f.params.lobe_count as usize).sum(),
        flyaways: flyaway_report,
        surface_refit,
        prefilter: prefilter_report,
        transmission: transmission_report,
        stage_seconds,
        stage_peak_rss_bytes,
        total_seconds: start.elapsed().as_secs_f64(),
        input_bytes: (texels * nz * 7 * 4) as u64,
        model_bytes,
    };
    Ok(Bake { model, report, geometry, training, clusters, fits, predictions })
}

/// The transmission stage: backlit training renderings of the masked surface, probed
/// through `skeleton` (the texel the model shows along each ray, in its fitted frame
/// `frames[texel]`, the lobe-0 frame level 0 stores), a fit per
/// cluster of `clusters` (K = `k`), a ridge refinement per texel where the bake refines
/// per texel, and each texel's energy capped. Returns the per-texel terms and the report.
#[allow(clippy::too_many_arguments)] // the stage's inputs: model, sheet, pairs, clusters and options
fn fit_texel_transmission(skeleton: &HybridModel, frames: &[ClothFrame], measure: &MeasureScene, pairs: &[Pair], clusters: &[u32], k: usize, options: &BakeOptions, to: &TransmissionFitOptions, progress: &dyn Progress) -> Result<(Vec<ClothTransmission>, TransmissionReport), BakeError> {
    let texels = clusters.len();
    let (nx, ny) = measure.texels();
    let t = Instant::now();
    let backlit = backlit_pairs(pairs);
    let seed = mix64(options.seed ^ 0x7472_616e_736d);
    let bar = begin_stage(progress, "backlit training renderings", backlit.len() as u64);
    let spp = if to.spp > 0 { to.spp } else { options.spp };
    let training = render_training(measure, &backlit, spp, seed, &|| bar.advance(1))?;
    bar.finish();
    let render_seconds = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let probe = ProbeOptions { rays: options.probe_rays, shadows: false, volumetric: false, diffuse: options.fit.diffuse };
    let all_texels: Vec<u32> = (0..texels as u32).collect();
    let jitter = image_jitter(half_seeds(seed)[0]);
    let bar = begin_stage(progress, "transmission: probing and fitting", backlit.len() as u64 + 1);
    // (texel hit, target pixel, factors)
    let mut samples: Vec<(u32, u32, TransGeo)> = Vec::new();
    for (c, p) in backlit.iter().enumerate() {
        let base = (c * texels) as u32;
        samples.extend(probe_samples(skeleton, measure, (p.wi, p.wo, c as u32), &all_texels, &probe, &jitter, &|j| base + j).into_iter().map(|s| (s.hit, s.target, TransGeo::new(&frames[s.hit as usize], p.wi, p.wo))));
        bar.advance(1);
    }
    let target_of = |target: u32| training.images[target as usize / texels].pixels[target as usize % texels];
    // Each backlit pair weighted by the inverse of its image's brightness, as the
    // reflection's pairs are (`TrainingImages::pair_weights`, `--unweighted-pairs`): row
    // and target scaled alike. Measured (baker/FIT_MEASUREMENTS.md, "Transmission"): the
    // straight-through views at 45° and 58° fell from 1.37 and 1.46 times the truth's
    // mean to 1.29 and 1.23 on twill, the backlit held-out error 53.9 → 53.3% (felt
    // 36.8 → 36.3%).
    let pair_w: Vec<f32> = if options.pair_weights { training.pair_weights() } else { Vec::new() };
    let pw = |target: u32| pair_w.get(target as usize / texels).copied().unwrap_or(1.0);
    let tt = |geo: TransGeo, target: u32| TransTarget { geo: TransGeo { cos: geo.cos * pw(target), ..geo }, radiance: target_of(target) * pw(target) };
    let mut per_cluster: Vec<Vec<TransTarget>> = vec![Vec::new(); k];
    for &(hit, target, geo) in &samples {
        per_cluster[clusters[hit as usize] as usize].push(tt(geo, target));
    }
    let fits: Vec<TransmissionFit> = per_cluster.par_iter().map(|s| fit_transmission(s, to)).collect();
    let predict_all = |of: &dyn Fn(usize) -> ClothTransmission| -> Vec<Image> {
        let weight = 1.0 / options.probe_rays as f32;
        let mut images: Vec<Image> = training.images.iter().map(|i| Image::new(i.width, i.height)).collect();
        for &(hit, target, geo) in &samples {
            images[target as usize / texels].pixels[target as usize % texels] += weight * predict_transmission(&of(hit as usize), &geo);
        }
        images
    };
    let cluster_error = image_errors(&predict_all(&|j| fits[clusters[j] as usize].transmission), &training.images, nx, ny).0;
    // Per texel: the k's refined, with the transmission visibility where asked (format
    // 1.16), and the refinement without it (what the gradient bought).
    let (refined, without): (Vec<ClothTransmission>, Option<Vec<ClothTransmission>>) = match options.per_texel_ridge {
        Some(ridge) => {
            let mut per_texel: Vec<Vec<TransTarget>> = vec![Vec::new(); texels];
            for &(hit, target, geo) in &samples {
                per_texel[hit as usize].push(tt(geo, target));
            }
            let cluster_of = |j: usize| &fits[clusters[j] as usize].transmission;
            let plain: Vec<ClothTransmission> = per_texel.par_iter().enumerate().map(|(j, s)| refine_transmission(s, cluster_of(j), ridge)).collect();
            match to.gradient_ridge {
                Some(g) => (per_texel.par_iter().zip(&plain).enumerate().map(|(j, (s, first))| refine_transmission_visibility_from(*first, s, cluster_of(j), ridge, g, to.curvature_ridge)).collect(), Some(plain)),
                None => (plain, None),
            }
        }
        None => ((0..texels).map(|j| fits[clusters[j] as usize].transmission).collect(), None),
    };
    let capped: Vec<ClothTransmission> = refined.par_iter().zip(frames).map(|(t, f)| cap_energy(t, f)).collect();
    let without_visibility = without.map(|plain| {
        let capped_plain: Vec<ClothTransmission> = plain.par_iter().zip(frames).map(|(t, f)| cap_energy(t, f)).collect();
        image_errors(&predict_all(&|j| capped_plain[j]), &training.images, nx, ny)
    });
    let gradient_median = without_visibility.is_some().then(|| median(capped.iter().map(|t| t.grad.iter().map(|x| x * x).sum::<f32>().sqrt()).collect()));
    let capped_texels = capped.iter().zip(&refined).filter(|(a, b)| a != b).count();
    let worst_albedo = capped.par_iter().zip(frames).map(|(t, f)| albedo_estimate(t, f)).reduce(|| 0.0, f32::max);
    let predictions = predict_all(&|j| capped[j]);
    let (error, block_error) = image_errors(&predictions, &training.images, nx, ny);
    bar.finish();
    let problems = fits
        .iter()
        .enumerate()
        .filter_map(|(c, f)| f.problem.clone().map(|problem| ClusterProblem { cluster: c, texels: clusters.iter().filter(|&&x| x as usize == c).count(), problem }))
        .collect();
    let pair_errors = predictions.iter().zip(&training.images).map(|(p, r)| (image_errors(std::slice::from_ref(p), std::slice::from_ref(r), nx, ny).1, p.mean() / r.mean().max(1e-30))).collect();
    let report = TransmissionReport { pairs: backlit, noise_floor: training.noise, cluster_error, error, block_error, pair_errors, without_visibility, gradient_median, worst_albedo, capped_texels, problems, openness: None, render_seconds, fit_seconds: t.elapsed().as_secs_f64() };
    Ok((capped, report))
}

/// The model's image for each training pair: per pixel, the mean of its rays'
/// predictions (a ray that missed counts as black, as in the renderer).
#[allow(clippy::too_many_arguments)] // the samples, how to shade them, and the images' layout
fn predict_images<'p>(samples: &[Sample], params_of: &dyn Fn(usize) -> &'p ClothParams, geo_of: &dyn Fn(&Sample) -> LobeTarget, reading: BrdfReading, training: &TrainingImages, texels: usize, rays: u32) -> Vec<Image> {
    let weight = 1.0 / rays as f32;
    let mut images: Vec<Image> = training.images.iter().map(|i| Image::new(i.width, i.height)).collect();
    for s in samples {
        let p = params_of(s.hit as usize);
        let image = &mut images[s.target as usize / texels];
        image.pixels[s.target as usize % texels] += weight * predict_lobes(p, &geo_of(s), reading);
    }
    images
}

/// A sample's factors in its texel's frames `frames` (its pair from `dirs`; the radiance
/// left zero).
fn sample_geo(s: &Sample, frames: &[TexelFrames], dirs: &[(Vec3, Vec3)], diffuse: DiffuseLaw) -> LobeTarget {
    let (wi, wo) = dirs[s.dirs as usize];
    LobeTarget::in_frames(&frames[s.hit as usize], wi, wo, s.vis, Vec3::ZERO, diffuse)
}

/// The median of `v` (0 for none).
fn median(mut v: Vec<f32>) -> f32 {
    v.sort_by(f32::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

/// 4×4 block means of a texel-order image (partial blocks at the edges included).
pub fn block_mean(image: &Image, block: u32) -> Image {
    let (w, h) = (image.width.div_ceil(block), image.height.div_ceil(block));
    let mut out = Image::new(w, h);
    let mut counts = vec![0u32; (w * h) as usize];
    for y in 0..image.height {
        for x in 0..image.width {
            let k = ((y / block) * w + x / block) as usize;
            out.pixels[k] += image.get(x, y);
            counts[k] += 1;
        }
    }
    for (p, c) in out.pixels.iter_mut().zip(counts) {
        *p /= c.max(1) as f32;
    }
    out
}

/// Relative RMSE over all images, per pixel and over 4×4 blocks.
pub fn image_errors(test: &[Image], reference: &[Image], _nx: usize, _ny: usize) -> (f64, f64) {
    let (mut d2, mut r2, mut bd2, mut br2) = (0f64, 0f64, 0f64, 0f64);
    for (a, b) in test.iter().zip(reference) {
        for (p, q) in a.pixels.iter().zip(&b.pixels) {
            d2 += (*p - *q).as_dvec3().length_squared();
            r2 += q.as_dvec3().length_squared();
        }
        let (ba, bb) = (block_mean(a, 4), block_mean(b, 4));
        for (p, q) in ba.pixels.iter().zip(&bb.pixels) {
            bd2 += (*p - *q).as_dvec3().length_squared();
            br2 += q.as_dvec3().length_squared();
        }
    }
    let rel = |d: f64, r: f64| if r > 0.0 { (d / r).sqrt() } else { 0.0 };
    (rel(d2, r2), rel(bd2, br2))
}

/// Training-image error by pair kind, and for grazing (either polar angle > 55°) and
/// other pairs.
fn split_errors(predictions: &[Image], training: &TrainingImages) -> (Vec<(String, f64)>, f64, f64) {
    let mut by_kind: Vec<(String, f64, f64)> = Vec::new();
    let (mut g, mut ng) = ([0f64; 2], [0f64; 2]);
    for ((p, r), pair) in predictions.iter().zip(&training.images).zip(&training.pairs) {
        let (mut d2, mut r2) = (0f64, 0f64);
        for (a, b) in p.pixels.iter().zip(&r.pixels) {
            d2 += (*a - *b).as_dvec3().length_squared();
            r2 += b.as_dvec3().length_squared();
        }
        let kind = format!("{:?}", pair.kind).to_lowercase();
        match by_kind.iter_mut().find(|(k, _, _)| *k == kind) {
            Some(e) => {
                e.1 += d2;
                e.2 += r2;
            }
            None => by_kind.push((kind, d2, r2)),
        }
        let acc = if pair.max_polar_deg() > 55.0 { &mut g } else { &mut ng };
        acc[0] += d2;
        acc[1] += r2;
    }
    let rel = |a: [f64; 2]| if a[1] > 0.0 { (a[0] / a[1]).sqrt() } else { 0.0 };
    (by_kind.into_iter().map(|(k, d, r)| (k, if r > 0.0 { (d / r).sqrt() } else { 0.0 })).collect(), rel(g), rel(ng))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_automatic_k_keeps_about_32_texels_per_cluster_within_its_range() {
        // 64² → 128 (the measured default), 128² and larger at the cap, small models fewer.
        assert_eq!(auto_k(64 * 64), 128);
        assert_eq!(auto_k(512 * 512), 128);
        assert_eq!(auto_k(32 * 32), 32);
        assert_eq!(auto_k(33 * 17), 16);
        assert_eq!(auto_k(40), 4);
        // Never more clusters than texels.
        assert_eq!(auto_k(3), 3);
        for texels in 1..5000 {
            let k = auto_k(texels);
            assert!(k.is_power_of_two() || k == texels, "{texels}: {k}");
            assert!(k <= texels.max(1) && k <= AUTO_K_RANGE[1], "{texels}: {k}");
        }
    }

    #[test]
    fn an_explicit_k_bound_wins_over_the_automatic_other() {
        let o = |k_min, k_max| BakeOptions { k_min, k_max, ..Default::default() };
        assert_eq!(o(K_AUTO, K_AUTO).k_range(4096), (128, 128));
        assert_eq!(o(4, 32).k_range(4096), (4, 32));
        assert_eq!(o(K_AUTO, 8).k_range(4096), (8, 8));
        assert_eq!(o(4, K_AUTO).k_range(4096), (4, 128));
        assert_eq!(o(256, K_AUTO).k_range(4096), (256, 256));
        assert!(o(8, 4).validate().is_err());
        assert!(o(K_AUTO, K_AUTO).validate().is_ok());
        assert!(o(K_AUTO, 1 << 20).validate().is_err());
    }

    #[test]
    fn an_absurd_lobe_peak_bound_is_refused() {
        let o = |m| BakeOptions { lobe_peak_max: m, ..Default::default() };
        assert!(o(None).validate().is_ok() && o(Some(1.0)).validate().is_ok() && o(Some(LOBE_PEAK_MAX)).validate().is_ok());
        for m in [0.5, 0.0, -1.0, f32::NAN, f32::INFINITY] {
            let e = o(Some(m)).validate().expect_err("refused").to_string();
            assert!(e.contains("lobe_peak_max"), "{m}: {e}");
        }
    }
}
