//! The mip chain of a hybrid model (paper §5.3.5): from a model's level 0, every
//! coarser level down to 1×1 — per-texel framed lobes fitted to their level-0
//! footprint ([`lobe_fit`]), and flyaway voxels merged with coverage α ([`flyaways`]).
//! No renderings: the fit works on BRDF evaluations over a fixed set of direction
//! pairs ([`pairs`]), the target being the plain mean of the footprint's level-0
//! responses. Two measured options weight each level-0 texel by what a distant pixel
//! sees of it ([`TargetAcc`], height-field rays): `masking` (its visible projected area
//! toward ω_o) and `light_visibility` (the light's visibility toward ω_i, after which
//! coarse levels are shaded without shadow rays: MODEL flag bit 2, format 1.2); both
//! are off by default (baker/PREFILTER_MEASUREMENTS.md). The height field is not
//! filtered; every level marches level 0's.
//!
//! Texel (i, j) of level ℓ covers level-0 texels [i·2^ℓ, (i+1)·2^ℓ) × [j·2^ℓ, (j+1)·2^ℓ)
//! clipped to the tile (runtime/HYBRID_FORMAT.md §"Levels"); its target is the mean
//! response of those texels, computed once per level as the count-weighted mean of its
//! children's targets (exact: the pairs are shared).

pub mod far_view;
pub mod flyaways;
pub mod lobe_fit;
pub mod pairs;
pub mod path_gain;
pub mod view_tilt;

use std::time::Instant;

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use serde::Serialize;

use fabric_runtime::brdf::MAX_LOBES;
use fabric_runtime::brdf::BrdfReading;
use fabric_runtime::cpu::heightfield::HeightTracer;
use fabric_runtime::brdf::{ClothOpenness, ClothTransmission, OPENNESS_Q_MAX, cloth_frame, cloth_mirror_z};
use crate::fit::gradient::{Visibility, gradient_least_squares, visibility_least_squares};
use fabric_runtime::cpu::shading::{texel_response, texel_transmission_response};
use fabric_runtime::hybrid::{PackedCurvature, PackedGradient, PackedTransmission, PackedTransmissionVisibility, TexelBrdf, decode_frame, encode_frame};
use fabric_runtime::hybrid::compact;
use fabric_runtime::hybrid::stats::luminance;
use fabric_runtime::hybrid::{BrdfTable, HybridModel, Level, ModelError, Surface, level_dims, max_levels};

use crate::fit::transmission::{GRADIENT_RIDGE as TRANSMISSION_RIDGE, TransGeo, TransTarget, TransmissionFitOptions, cap_energy, fit_transmission, refine_transmission_visibility_from, relative_residual};
use crate::progress::{Progress, stage};
use crate::reference::rng::mix64;
use lobe_fit::{Candidate, CoarseFit, FitSettings, Footprint, fit_footprint};
use pairs::{Pair, fit_pairs};

/// Most lobes per coarse texel by default. Measured on the 128² presets
/// (baker/PREFILTER_MEASUREMENTS.md, "Lobe budget"): the far views' error is the same
/// with 2 lobes as with 8 (within ±0.3 points, 70° views up to 2 better), while the
/// chain shrinks from 64–65% of level 0's bytes to ~35% (the ⅓ asked) and the
/// prefilter runs 5× faster. Up to [`MAX_LOBES`] stay available (`--prefilter-max-lobes`).
pub const DEFAULT_MAX_LOBES: usize = 2;

/// Pairs held out of each coarse texel's fit to check its frame refinement
/// ([`lobe_fit::FitSettings::validation`]).
pub const VALIDATION_PAIRS: usize = 64;
/// Most texels per level that the lobe-count sweep of the report fits past the lobe
/// budget (`LevelReport::error_by_lobes`): a mean over 512 texels is within a few percent
/// of the level's, at a fraction of the cost of every texel at 4 and 8 lobes.
pub const LOBE_SWEEP_TEXELS: u32 = 512;

/// How to prefilter.
#[derive(Clone, Debug, PartialEq)]
pub struct PrefilterOptions {
    /// Relative error (Eq. 8-like, over the pairs) at which a texel stops adding lobes.
    pub tolerance: f32,
    /// Most lobes per coarse texel (1..=8).
    pub max_lobes: usize,
    /// Direction pairs each texel is fitted on.
    pub pairs: usize,
    /// Levels in all, level 0 included (None: down to 1×1).
    pub levels: Option<usize>,
    /// Merge the flyaways into every level.
    pub flyaways: bool,
    /// How a coarse flyaway voxel's α is computed.
    pub coverage: flyaways::Coverage,
    /// Store the spread of each coarse flyaway voxel's fibre axes (shaded as a cone of
    /// axes, `brdf::axis_spread`); off: one axis with widened lobes.
    pub flyaway_spread: bool,
    /// With `flyaway_spread`: split each coarse flyaway voxel's fibres in two groups of
    /// axes where they split (warp and weft; format 1.8's `FLYAWAY_GROUP`), each shaded
    /// as its own cone; off: one cone of all of them.
    pub flyaway_groups: bool,
    /// Weight each level-0 texel by its visible projected area toward ω_o (what a far
    /// pixel sees of it) rather than equally.
    pub masking: bool,
    /// Fold the light's height-field visibility into the coarse BRDFs (and shade coarse
    /// levels without shadow rays), rather than tracing shadow rays at every level.
    pub light_visibility: bool,
    /// Trace the visibility of the footprints on a repeating tile (as fabrics are
    /// rendered: `--periodic`); otherwise rays leave at the tile's edges.
    pub periodic: bool,
    /// Nelder–Mead evaluations per free width (0: moments and NNLS only).
    pub evals_per_dim: usize,
    /// Refine each coarse lobe's frame (tangent twist, normal tilt) with its widths,
    /// rather than keeping the frame its group's moments give.
    pub free_frames: bool,
    /// Fit each coarse texel's view tilt (its frames turn toward the viewer as its
    /// footprint's visible normals do; [`view_tilt`]).
    pub view_tilt: bool,
    /// Snap the coarse levels to the compact grid, so that the file stores them in the
    /// compact records of format 1.7 ([`fabric_runtime::hybrid::compact`]): 8 + 12·L
    /// bytes per texel instead of 16 + 16·L, 6 per view tilt instead of 12, 8 per
    /// flyaway node instead of 16.
    pub compact: bool,
    /// Fit each coarse flyaway level's path gain (format 1.9, [`path_gain`]): its mean
    /// transmittance matched to level 0's at every polar angle; off: Beer's law from α.
    pub path_gain: bool,
    pub seed: u64,
}

impl Default for PrefilterOptions {
    fn default() -> Self {
        PrefilterOptions { tolerance: 0.03, max_lobes: DEFAULT_MAX_LOBES, pairs: 128, levels: None, flyaways: true, coverage: flyaways::Coverage::Projected, flyaway_spread: true, flyaway_groups: true, masking: false, light_visibility: false, periodic: true, evals_per_dim: 20, free_frames: true, view_tilt: true, compact: true, path_gain: true, seed: 1 }
    }
}

/// Why prefiltering cannot run.
#[derive(Debug, thiserror::Error)]
pub enum PrefilterError {
    #[error(transparent)]
    Model(#[from] ModelError),
    #[error("the prefiltered model is invalid ({0}): a bug in the prefilter, please report it")]
    Output(ModelError),
    #[error("invalid prefilter options: {0}")]
    Options(String),
}

/// One level's figures.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct LevelReport {
    pub level: usize,
    pub width: u32,
    pub height: u32,
    pub max_lobes: usize,
    pub mean_lobes: f64,
    /// Mean over texels of the relative error E.
    pub fit_error: f64,
    /// 95th percentile of E over texels.
    pub fit_error_p95: f64,
    /// Mean E with at most 1, 2, … 8 lobes allowed, over `lobe_sweep_texels` texels
    /// spread over the level: the pass's own fits up to the budget, then the same pass
    /// gone on to 4 and 8 lobes on those texels (`FitSettings::sweep`). The counts the
    /// doubling skips (3, 5–7) repeat the next fewer.
    pub error_by_lobes: Vec<f64>,
    /// How many texels the lobe-count sweep fitted (every texel of a level of up to
    /// [`LOBE_SWEEP_TEXELS`], about that many chosen by a hash beyond).
    pub lobe_sweep_texels: usize,
    pub surface_bytes: u64,
    pub flyaway_nodes: usize,
    /// Of those, the nodes whose fibres split in two groups of axes (format 1.8).
    pub flyaway_two_groups: usize,
    pub flyaway_bytes: u64,
    /// A BSDF's transmission term: mean relative error of its fit to the footprint's
    /// level-0 terms over the backlit pairs, and its bytes (None / 0: no transmission).
    pub transmission_fit_error: Option<f64>,
    pub transmission_bytes: u64,
    /// Mean Frobenius norm of the texels' view tilt B, and its bytes (None / 0: none).
    pub mean_view_tilt: Option<f64>,
    /// Mean relative error of the texels' responses against what distant views see of
    /// their footprints (hit-weighted level-0 responses), without and with the tilt.
    pub view_tilt_error: Option<(f64, f64)>,
    pub view_tilt_bytes: u64,
    /// The flyaways' path gain at polar 0°, 10°, … 80° (format 1.9; None: none), and the
    /// mean transmittance of level 0's flyaways and of this level's without the gain at
    /// those angles (what the gain matches).
    pub flyaway_path_gain: Option<Vec<f32>>,
    pub flyaway_transmittance_level0: Option<Vec<f64>>,
    pub flyaway_transmittance_ungained: Option<Vec<f64>>,
    pub seconds: f64,
}

/// What a prefilter did.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct PrefilterReport {
    pub pairs: usize,
    pub tolerance: f32,
    pub levels: Vec<LevelReport>,
    pub seconds: f64,
    /// Bytes of level 0 and of the coarse levels (surface, flyaways, transmission, view
    /// tilts, visibility gradients and curvatures).
    pub level0_bytes: u64,
    pub chain_bytes: u64,
    /// Time spent fitting the view tilts of all levels.
    pub view_tilt_seconds: f64,
    /// Time spent fitting the flyaways' path gains.
    pub path_gain_seconds: f64,
}

fn level_bytes(l: &Level) -> u64 {
    l.surface_bytes() + l.flyaways.as_ref().map_or(0, |f| f.byte_size()) + l.transmission_bytes() + l.view_tilt_bytes() + l.gradient_bytes() + l.curvature_bytes()
}

/// Level-0 texels under texel (i, j) of level ℓ, along one axis of `n` texels.
pub(crate) fn extent(c: u32, level: usize, n: u32) -> u32 {
    let span = 1u32 << level;
    ((c + 1) * span).min(n).saturating_sub(c * span)
}

/// Rebuilds every level of `model` above 0 from level 0 (which, with the height field
/// and the metadata other than the fit errors, is kept as it is).
pub fn prefilter(model: &HybridModel, opts: &PrefilterOptions, progress: &dyn Progress) -> Result<(HybridModel, PrefilterReport), PrefilterError> {
    model.validate()?;
    if !(opts.tolerance >= 0.0 && opts.tolerance.is_finite()) {
        return Err(PrefilterError::Options(format!("tolerance {} must be finite and ≥ 0", opts.tolerance)));
    }
    if !(1..=MAX_LOBES).contains(&opts.max_lobes) {
        return Err(PrefilterError::Options(format!("max_lobes {} must be in 1..={MAX_LOBES}", opts.max_lobes)));
    }
    if !(4..=4096).contains(&opts.pairs) {
        return Err(PrefilterError::Options(format!("pairs {} must be in 4..=4096", opts.pairs)));
    }
    let (w0, h0) = (model.width(), model.height_px());
    let most = max_levels(w0, h0);
    let count = opts.levels.unwrap_or(most);
    if count == 0 || count > most {
        return Err(PrefilterError::Options(format!("{count} levels asked; a {w0}×{h0} model has 1..={most}")));
    }
    let start = Instant::now();
    // Frames refined with the widths are checked on pairs the fit does not see
    // (`FitSettings::validation`): they follow the fitted pairs, their targets
    // accumulated with them.
    let free_frames = opts.free_frames && opts.max_lobes <= lobe_fit::FREE_FRAME_LOBES;
    let validation = if free_frames { VALIDATION_PAIRS } else { 0 };
    let mut pairs = fit_pairs(opts.pairs, opts.seed);
    let fitted_pairs = pairs.len();
    if validation > 0 {
        pairs.extend(fit_pairs(validation, opts.seed ^ 0x5eed_0f_f0a1));
    }
    let settings = FitSettings { tolerance: opts.tolerance, max_lobes: opts.max_lobes, reading: model.meta.reading, diffuse: model.meta.diffuse, evals_per_dim: opts.evals_per_dim, free_frames, validation, sweep: false };
    // The lobe-count sweep's texels go on past the budget (FitSettings::sweep).
    let sweep_settings = FitSettings { sweep: true, ..settings };
    let mut out = model.clone();
    out.levels.truncate(1);
    let mut report = PrefilterReport { pairs: fitted_pairs, tolerance: opts.tolerance, level0_bytes: level_bytes(&model.levels[0]), ..Default::default() };
    let texels: u64 = (1..count).map(|l| level_dims(w0, h0, l)).map(|(w, h)| w as u64 * h as u64).sum();
    let bar = stage(progress, "prefilter", texels);
    // Targets of the level below (None for level 0: evaluated where needed).
    let mut finer_targets: Option<Vec<TargetAcc>> = None;
    // A BSDF: the transmission term is prefiltered too, on the pairs with the light
    // mirrored below the sheet, against the plain mean of the footprint's level-0 terms.
    let bsdf = model.levels[0].transmission.is_some();
    // Level 0's transmission visibility (format 1.16): the coarse levels fit their own
    // to their footprint's terms (which carry level 0's).
    let seen = bsdf && model.levels[0].transmission_visibility.is_some();
    // Level 0's visibility gradients (format 1.12): the coarse levels fit their own, and
    // their own curvatures where level 0 has them (format 1.15).
    let graded = model.levels[0].gradient.is_some();
    let curved = graded && model.levels[0].curvature.is_some();
    let backlit: Vec<Pair> = pairs[..fitted_pairs].iter().map(|&(wi, wo)| (cloth_mirror_z(wi), wo)).collect();
    let mut finer_trans: Option<Vec<Vec3>> = None;
    let np = pairs.len();
    let nt = backlit.len();
    let tracer = HeightTracer::new(model, opts.periodic);
    let shadowed = model.meta.fitted_with_shadowing && opts.light_visibility;
    let texel = model.texel_size();
    let t_tilt = Instant::now();
    let mut tilts = (opts.view_tilt && count > 1).then(|| view_tilt::trace_visible_hits(model, count, opts.periodic));
    report.view_tilt_seconds = t_tilt.elapsed().as_secs_f64();
    for level in 1..count {
        let t0 = Instant::now();
        let (lw, lh) = level_dims(w0, h0, level);
        let finer = &out.levels[level - 1];
        let (fw, fh) = (finer.width, finer.height);
        let reading = model.meta.reading;
        let level0 = &out.levels[0];
        // The children of coarse texel (i, j) at the finer level, with their level-0 counts.
        let children = |i: u32, j: u32| {
            let mut c = Vec::with_capacity(4);
            for (ci, cj) in [(2 * i, 2 * j), (2 * i + 1, 2 * j), (2 * i, 2 * j + 1), (2 * i + 1, 2 * j + 1)] {
                if ci < fw && cj < fh {
                    c.push((ci, cj, extent(ci, level - 1, w0) * extent(cj, level - 1, h0)));
                }
            }
            c
        };
        // About LOBE_SWEEP_TEXELS texels of the level, chosen by a hash (a regular
        // stride would alias with the weave's period).
        let sweep_stride = (lw * lh).div_ceil(LOBE_SWEEP_TEXELS).max(1) as u64;
        let in_sweep = |index: u32| mix64(((level as u64) << 32) | index as u64) % sweep_stride == 0;
        let fits: Vec<(CoarseFit, Visibility, Vec<TargetAcc>, Option<(ClothTransmission, Vec<Vec3>, f64)>, bool)> = (0..lw * lh)
            .into_par_iter()
            .map(|index| {
                let (i, j) = (index % lw, index / lw);
                let kids = children(i, j);
                let total: u32 = kids.iter().map(|k| k.2).sum();
                let mut acc = vec![TargetAcc::default(); np];
                let mut candidates = Vec::new();
                let mut kd_normal = Vec3::ZERO; // k_d-weighted; zero without diffuse
                for &(ci, cj, n) in &kids {
                    let share = n as f32 / total.max(1) as f32;
                    match &finer_targets {
                        Some(t) => {
                            for (a, v) in acc.iter_mut().zip(&t[(cj * fw + ci) as usize * np..][..np]) {
                                a.add(v);
                            }
                        }
                        None => level0_target(&level0.texel_brdf(ci, cj), &tracer, model, texel, ci, cj, &pairs, (opts.masking, shadowed), reading, &mut acc),
                    }
                    let b = finer.texel_brdf(ci, cj);
                    let p = &b.params;
                    kd_normal += share * luminance(p.kd) * b.frames[0].n;
                    for (lobe, f) in p.lobes().iter().zip(&b.frames) {
                        candidates.push(Candidate { n: f.n, t: f.t, k: lobe.k, beta: lobe.beta, gamma: lobe.gamma, eta: p.eta, a: p.a, weight: share * luminance(lobe.k).max(1e-6) });
                    }
                }
                let target: Vec<Vec3> = acc.iter().map(TargetAcc::value).collect();
                let swept = in_sweep(index);
                let fp = Footprint { candidates: &candidates, kd_normal, target: &target };
                let fit_settings = if swept { &sweep_settings } else { &settings };
                let fit = fit_footprint(&fp, &pairs, fit_settings);
                let (fit, gradient) = if graded { graded_fit(&fp, &pairs, fit_settings, fit, curved) } else { (fit, Visibility::default()) };
                let trans = bsdf.then(|| {
                    let mut t_acc = vec![Vec3::ZERO; nt];
                    for &(ci, cj, n) in &kids {
                        let share = n as f32 / total.max(1) as f32;
                        match &finer_trans {
                            Some(t) => t_acc.iter_mut().zip(&t[(cj * fw + ci) as usize * nt..][..nt]).for_each(|(a, v)| *a += share * *v),
                            None => {
                                let b = level0.texel_brdf(ci, cj);
                                t_acc.iter_mut().zip(&backlit).for_each(|(a, &(wi, wo))| *a += share * texel_transmission_response(&b, wi, wo));
                            }
                        }
                    }
                    // In the coarse texel's lobe-0 frame, which the renderers use.
                    let frame = fit.lobes.first().map_or(cloth_frame(Vec3::Z, Vec3::X), |(_, n, t)| decode_frame_of(*n, *t));
                    let samples: Vec<TransTarget> = backlit.iter().zip(&t_acc).map(|(&(wi, wo), &radiance)| TransTarget { geo: TransGeo::new(&frame, wi, wo), radiance }).collect();
                    let f = fit_transmission(&samples, &TransmissionFitOptions { max_evals: 120, restarts: 1, ..Default::default() });
                    let (t, residual) = if seen {
                        let t = refine_transmission_visibility_from(f.transmission, &samples, &f.transmission, 1e-6, TRANSMISSION_RIDGE, Some(TRANSMISSION_RIDGE));
                        (t, relative_residual(&t, &samples))
                    } else {
                        (f.transmission, f.relative_residual())
                    };
                    let gap = coarse_openness(&kids.iter().map(|&(ci, cj, n)| (finer.texel_brdf(ci, cj).transmission.gap, n as f32 / total.max(1) as f32)).collect::<Vec<_>>());
                    (ClothTransmission { gap, ..cap_energy(&t, &frame) }, t_acc, residual)
                });
                bar.advance(1);
                (fit, gradient, acc, trans, swept)
            })
            .collect();
        let mut table = BrdfTable::new();
        let mut targets = Vec::with_capacity(fits.len() * np);
        let mut errors: Vec<f64> = Vec::with_capacity(fits.len());
        let mut by_lobes = [0f64; MAX_LOBES];
        let mut lobes_total = 0usize;
        let mut lobes_max = 0usize;
        let mut trans_records = Vec::new();
        let mut trans_visibility = Vec::new();
        let mut trans_targets = Vec::new();
        let mut trans_error = 0f64;
        let mut swept = 0usize;
        let mut gradients = Vec::with_capacity(if graded { fits.len() } else { 0 });
        let mut curvatures = Vec::with_capacity(if curved { fits.len() } else { 0 });
        for (fit, gradient, acc, trans, in_sample) in fits {
            table.push_framed(fit.kd, fit.eta, fit.a, &fit.lobes);
            if graded {
                gradients.push(PackedGradient::new(gradient.g));
            }
            if curved {
                curvatures.push(PackedCurvature::new(gradient.q));
            }
            targets.extend(acc);
            if let Some((t, t_acc, e)) = trans {
                trans_records.push(PackedTransmission::new(&t));
                trans_visibility.push(PackedTransmissionVisibility::new(t.grad, t.curv));
                trans_targets.extend(t_acc);
                trans_error += e;
            }
            errors.push(fit.error as f64);
            if in_sample {
                swept += 1;
                for (acc, e) in by_lobes.iter_mut().zip(fit.error_by_count) {
                    *acc += e as f64;
                }
            }
            lobes_total += fit.lobes.len();
            lobes_max = lobes_max.max(fit.lobes.len());
        }
        let n = errors.len().max(1) as f64;
        let fit_error = errors.iter().sum::<f64>() / n;
        errors.sort_by(|a, b| a.total_cmp(b));
        let p95 = errors.get(((errors.len() as f64 * 0.95) as usize).min(errors.len().saturating_sub(1))).copied().unwrap_or(0.0);
        let mut flyaways = if opts.flyaways { flyaways::flyaway_level(model, level, opts.coverage, opts.flyaway_spread, opts.flyaway_groups).map_err(PrefilterError::Output)? } else { None };
        let transmission_fit_error = bsdf.then(|| trans_error / n);
        if opts.compact {
            compact::quantize_table(&mut table);
            flyaways.iter_mut().for_each(compact::quantize_flyaway_nodes);
        }
        let mut l = Level { width: lw, height: lh, surface: Surface::PerTexel(table), flyaways, transmission: bsdf.then_some(trans_records), transmission_visibility: seen.then_some(trans_visibility), view_tilt: None, gradient: graded.then_some(gradients), curvature: curved.then_some(curvatures) };
        let t_level = Instant::now();
        let fitted = tilts.as_mut().map(|t| t.fit_level(model, level, &l, reading));
        report.view_tilt_seconds += t_level.elapsed().as_secs_f64();
        let mean_tilt = fitted.as_ref().map(|f| f.records.iter().map(|t| t.decode().b.iter().map(|b| (b * b) as f64).sum::<f64>().sqrt()).sum::<f64>() / f.records.len().max(1) as f64);
        let view_tilt_error = fitted.as_ref().map(|f| (f.error_untilted, f.error_tilted));
        l.view_tilt = fitted.map(|mut f| {
            if opts.compact {
                compact::quantize_view_tilts(&mut f.records);
            }
            f.records
        });
        report.levels.push(LevelReport {
            level,
            width: lw,
            height: lh,
            max_lobes: lobes_max,
            mean_lobes: lobes_total as f64 / n,
            fit_error,
            fit_error_p95: p95,
            error_by_lobes: by_lobes.iter().map(|e| e / swept.max(1) as f64).collect(),
            lobe_sweep_texels: swept,
            surface_bytes: l.surface_bytes(),
            flyaway_nodes: l.flyaways.as_ref().map_or(0, |f| f.nodes.len()),
            flyaway_two_groups: l.flyaways.as_ref().and_then(|f| f.groups.as_ref()).map_or(0, |g| g.iter().filter(|g| g.share > 0).count()),
            flyaway_bytes: l.flyaways.as_ref().map_or(0, |f| f.byte_size()),
            transmission_fit_error,
            transmission_bytes: l.transmission_bytes(),
            mean_view_tilt: mean_tilt,
            view_tilt_error,
            view_tilt_bytes: l.view_tilt_bytes(),
            seconds: t0.elapsed().as_secs_f64(),
            ..Default::default()
        });
        report.chain_bytes += level_bytes(&l);
        out.levels.push(l);
        finer_targets = Some(targets);
        finer_trans = bsdf.then_some(trans_targets);
    }
    drop(bar);
    if opts.flyaways && opts.path_gain {
        let t_gain = Instant::now();
        let gains = path_gain::fit_path_gains(&out, opts.periodic, opts.seed);
        for ((l, r), g) in out.levels[1..].iter_mut().zip(report.levels.iter_mut()).zip(gains) {
            let (Some(f), Some(g)) = (l.flyaways.as_mut(), g) else { continue };
            f.path_gain = Some(g.gain);
            r.flyaway_path_gain = Some(g.gain.0.to_vec());
            r.flyaway_transmittance_level0 = Some(g.level0_transmittance.to_vec());
            r.flyaway_transmittance_ungained = Some(g.level_transmittance.to_vec());
            r.flyaway_bytes = f.byte_size();
        }
        report.chain_bytes = out.levels[1..].iter().map(level_bytes).sum();
        report.path_gain_seconds = t_gain.elapsed().as_secs_f64();
    }
    let mut errors = vec![-1.0f32; count];
    if let Some(&e0) = model.meta.fit_error.first() {
        errors[0] = e0;
    }
    for r in &report.levels {
        errors[r.level] = r.fit_error as f32;
    }
    out.meta.fit_error = errors;
    out.meta.coarse_visibility = shadowed;
    out.validate().map_err(PrefilterError::Output)?;
    report.seconds = start.elapsed().as_secs_f64();
    Ok((out, report))
}

/// A coarse texel's target at one pair, as sums over its level-0 texels τ:
/// T = Σ A_τ V_τ f_τ / Σ A_τ, A_τ = the visible projected area of τ toward ω_o (what
/// fraction of a distant pixel's rays meet τ), V_τ the light's visibility from τ (when
/// the model is shaded with shadows), f_τ its response. A far pixel's value is then the
/// mean of its coarse texels' targets, as the supersampled level 0 gives it. Where no
/// part of the footprint is seen from ω_o the plain mean stands in.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TargetAcc {
    pub num: Vec3,
    pub den: f32,
    pub plain: Vec3,
    pub count: f32,
}

impl TargetAcc {
    fn add(&mut self, o: &TargetAcc) {
        self.num += o.num;
        self.den += o.den;
        self.plain += o.plain;
        self.count += o.count;
    }

    pub fn value(&self) -> Vec3 {
        if self.den > 1e-6 * self.count {
            self.num / self.den
        } else if self.count > 0.0 {
            self.plain / self.count
        } else {
            Vec3::ZERO
        }
    }
}

/// Ridge of a coarse texel's visibility gradient towards 0 (as the bake's).
const GRADIENT_RIDGE: f64 = 0.05;
/// Alternations of (g for fixed lobes, lobes for fixed g) per coarse texel. Three
/// lowered a twill's level-1 fit error from 9.5% to 8.0% but moved no far view and the
/// distance sweep by ≤ 0.15 points, at 1.7× the level's fitting time.
const GRADIENT_ROUNDS: usize = 1;

/// A coarse texel's fit where level 0 has visibility gradients (format 1.12): the
/// footprint's mean response carries its texels' odd part in the slant of ω_i and ω_o,
/// which lobes cannot hold (measured: the chain's fit error at level 1 of a twill 5.5%
/// without level-0 gradients, 14.4% with them and none here). From `first` (the fit to
/// the plain target), g by least squares (`fit::gradient`), then the lobes refitted to
/// the target divided by M(g) ([`GRADIENT_ROUNDS`] times); kept if the product is
/// closer to the target than `first`.
/// The fit's error is then the relative RMS of R·M against the target over all pairs.
/// With `curved` (level 0 has visibility curvatures, format 1.15) M has its curvature
/// too, fitted with g (`fit::gradient::visibility_least_squares`).
fn graded_fit(fp: &Footprint, pairs: &[Pair], s: &FitSettings, first: CoarseFit, curved: bool) -> (CoarseFit, Visibility) {
    let predicted = |f: &CoarseFit| -> Vec<Vec3> {
        let mut table = BrdfTable::new();
        table.push_framed(f.kd, f.eta, f.a, &f.lobes);
        let b = table.brdf_framed(0);
        pairs.iter().map(|&(wi, wo)| texel_response(&b, wi, wo, s.reading, s.diffuse)).collect()
    };
    let error = |r: &[Vec3], v: &Visibility| -> f32 {
        let (mut d, mut t2) = (0f64, 0f64);
        for ((r, t), &(wi, wo)) in r.iter().zip(fp.target).zip(pairs) {
            d += (*r * v.at(wi, wo) - *t).as_dvec3().length_squared();
            t2 += t.as_dvec3().length_squared();
        }
        if t2 > 0.0 { (d / t2).sqrt() as f32 } else { 0.0 }
    };
    let r0 = predicted(&first);
    let e0 = error(&r0, &Visibility::default());
    let mut best = (CoarseFit { error: e0, ..first }, Visibility::default());
    let mut r = r0;
    for _ in 0..GRADIENT_ROUNDS {
        let rows = r.iter().zip(fp.target).zip(pairs).map(|((r, t), &(wi, wo))| (*r, *t, wi, wo));
        let v = if curved { visibility_least_squares(rows, GRADIENT_RIDGE, GRADIENT_RIDGE) } else { Visibility { g: gradient_least_squares(rows, GRADIENT_RIDGE), q: [0.0; 6] } };
        let even: Vec<Vec3> = fp.target.iter().zip(pairs).map(|(t, &(wi, wo))| *t / v.at(wi, wo).max(0.05)).collect();
        let next = fit_footprint(&Footprint { target: &even, ..*fp }, pairs, s);
        r = predicted(&next);
        let e = error(&r, &v);
        if e < best.0.error {
            best = (CoarseFit { error: e, ..next }, v);
        }
    }
    best
}

/// Adds level-0 texel (i, j) to `acc`: its response at each pair, weighted by its
/// visible projected area toward ω_o (height-field ray from the texel's centre; the
/// area of a height-field patch seen along ω per unit of plane is ∇d·ω_xy + ω_z, d the
/// depth) when `masking`, and by the light's visibility toward ω_i when `shadowed`.
#[allow(clippy::too_many_arguments)] // one texel's inputs
fn level0_target(b: &TexelBrdf, tracer: &HeightTracer, model: &HybridModel, texel: Vec2, i: u32, j: u32, pairs: &[Pair], (masking, shadowed): (bool, bool), reading: BrdfReading, acc: &mut [TargetAcc]) {
    let (x, y) = (model.tile.origin.x + (i as f32 + 0.5) * texel.x, model.tile.origin.y + (j as f32 + 0.5) * texel.y);
    let d = tracer.depth_at(x, y);
    let p = Vec3::new(x, y, model.tile.top_z - d);
    let gx = (tracer.depth_at(x + 0.5 * texel.x, y) - tracer.depth_at(x - 0.5 * texel.x, y)) / texel.x;
    let gy = (tracer.depth_at(x, y + 0.5 * texel.y) - tracer.depth_at(x, y - 0.5 * texel.y)) / texel.y;
    let seen = |w: Vec3| !tracer.occluded(p, w, f32::MAX, VISIBILITY_STEPS).0;
    for (a, &(wi, wo)) in acc.iter_mut().zip(pairs) {
        let f = texel_response(b, wi, wo, reading, model.meta.diffuse);
        let lit = if !shadowed || seen(wi) { 1.0 } else { 0.0 };
        let area = if !masking { 1.0 } else if seen(wo) { (gx * wo.x + gy * wo.y + wo.z).max(0.0) } else { 0.0 };
        a.num += area * lit * f;
        a.den += area;
        a.plain += lit * f;
        a.count += 1.0;
    }
}

/// A coarse texel's openness from its children's (openness, share): the mean open
/// fraction, and q and (a, b) averaged with the children's open area as weights (exact
/// for a footprint of one shape, as a bake's level 0 is: it shares the sheet's).
pub fn coarse_openness(children: &[(ClothOpenness, f32)]) -> ClothOpenness {
    let o: f32 = children.iter().map(|(g, share)| share * g.o.clamp(0.0, 1.0)).sum();
    if !(o > 0.0) {
        return ClothOpenness::default();
    }
    let mean = |f: &dyn Fn(&ClothOpenness) -> f32| children.iter().map(|(g, share)| share * g.o.clamp(0.0, 1.0) * f(g)).sum::<f32>() / o;
    ClothOpenness { o: o.min(1.0), q: mean(&|g| g.q.clamp(0.0, OPENNESS_Q_MAX)), aniso: [mean(&|g| g.aniso[0].clamp(-1.0, 1.0)), mean(&|g| g.aniso[1].clamp(-1.0, 1.0))] }
}

/// The frame (n, t) as a renderer decodes it from the file (octahedral normal, tangent
/// angle): the transmission term is fitted in the frame it will be evaluated in.
fn decode_frame_of(n: Vec3, t: Vec3) -> fabric_runtime::brdf::ClothFrame {
    let (code, angle) = encode_frame(n, t);
    decode_frame(code, angle)
}

/// Step budget of the prefilter's visibility rays.
const VISIBILITY_STEPS: u32 = 4096;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_footprint_of_one_openness_keeps_it_and_closed_children_dilute_it() {
        let g = ClothOpenness { o: 0.2, q: 1.3, aniso: [0.4, -0.2] };
        let same = coarse_openness(&[(g, 0.25); 4]);
        assert!((same.o - g.o).abs() < 1e-6 && (same.q - g.q).abs() < 1e-5 && (same.aniso[0] - 0.4).abs() < 1e-6 && (same.aniso[1] + 0.2).abs() < 1e-6, "{same:?}");
        let half = coarse_openness(&[(g, 0.25), (g, 0.25), (ClothOpenness::default(), 0.25), (ClothOpenness::default(), 0.25)]);
        assert!((half.o - 0.1).abs() < 1e-6 && (half.q - g.q).abs() < 1e-5 && half.aniso == same.aniso, "{half:?}");
        assert_eq!(coarse_openness(&[(ClothOpenness::default(), 1.0)]), ClothOpenness::default());
        // Two rates: weighted by open area.
        let mixed = coarse_openness(&[(ClothOpenness { o: 0.3, q: 1.0, ..g }, 0.5), (ClothOpenness { o: 0.1, q: 3.0, ..g }, 0.5)]);
        assert!((mixed.o - 0.2).abs() < 1e-6 && (mixed.q - 1.5).abs() < 1e-5, "{mixed:?}");
    }
}
