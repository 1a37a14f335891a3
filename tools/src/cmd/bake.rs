//! `fabric bake DIR --out model.hyb`: bakes a fabric volume into a hybrid model (level
//! 0: height field, texel frames, clustered fitted BRDFs), then measures it on held-out
//! views against the reference. Writes the model, a JSON report and a side-by-side
//! picture (reference | model | error) per held-out view.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use fabric_baker::bake::{BakeOptions, FlyawayOptions, SurfaceMask, bake};
use fabric_baker::fit::flyaways::FlyawayAlpha;
use fabric_baker::evaluate::{ViewError, ViewKind, evaluate_view, reference_medium};
use fabric_baker::fit::directions::held_out_pairs;
use fabric_baker::reference::Lookup;
use fabric_baker::volume::load_fabric;
use fabric_runtime::brdf::{BrdfReading, DiffuseLaw};
use fabric_runtime::image::Image;

use crate::args::MaterialArgs;
use crate::progress::{Bars, stage_bar};

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum MaskArg {
    /// Everything above the surface run (V and its halo).
    Above,
    /// Exactly the flyaway voxels V.
    Flyaways,
    /// Nothing removed.
    None,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum AlphaArg {
    Full,
    Density,
}

/// How the flyaways' lobes fall with the azimuth about the fibre.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum FiberLobesArg {
    /// As a cylinder: lit and seen at every azimuth but straight behind the fibre (format 1.11)
    Cylinder,
    /// As a surface facing the viewer: dark past 90° of azimuth from it (files before 1.11)
    Facing,
}

/// Whether the flyaways shadow the surface (format 1.13).
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum FlyawayShadowArg {
    /// Both ways fitted; the model nearer the full volume's training images kept
    Auto,
    /// The surface lit through the flyaways in front of it
    On,
    /// The surface lit as if the flyaways were not there (as before 1.13)
    Off,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ReadingArg {
    Bounded,
    Width,
    Held,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum DiffuseArg {
    Lambert,
    LommelSeeliger,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum LookupArg {
    Trilinear,
    Nearest,
}

#[derive(Args, Debug)]
pub struct BakeArgs {
    /// Fabric volume directory (density.vol, albedo.vol, orientation.vol, material.toml).
    pub dir: PathBuf,
    /// The hybrid model to write (.hyb).
    #[arg(long)]
    pub out: PathBuf,
    /// The JSON report [default: the model's path with .json].
    #[arg(long)]
    pub report: Option<PathBuf>,
    #[command(flatten)]
    pub material: MaterialArgs,
    /// Reference lookup of the volume.
    #[arg(long, value_enum, default_value = "trilinear")]
    pub lookup: LookupArg,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Training configurations m.
    #[arg(long, default_value_t = 40)]
    pub pairs: usize,
    /// Samples per texel of each training rendering.
    #[arg(long, default_value_t = 32)]
    pub spp: u32,
    /// K doubles from --k-min to --k-max while the training error falls by at least 3% a
    /// doubling. 0 (the default): about 32 texels per cluster, a power of two from 4 to 128
    /// (one round at 64² and larger; baker/FIT_MEASUREMENTS.md, "How many clusters").
    #[arg(long, default_value_t = 0)]
    pub k_min: usize,
    /// The largest K (0: as --k-min's default).
    #[arg(long, default_value_t = 0)]
    pub k_max: usize,
    /// Stop doubling K below this training error (relative RMSE).
    #[arg(long, default_value_t = 0.05)]
    pub delta: f64,
    /// Stop doubling K where a doubling lowers the training error by less than this
    /// fraction of it (0: double up to --k-max; `fabric bench` does, for its K sweep).
    #[arg(long, default_value_t = 0.03)]
    pub min_gain: f64,
    /// Specular lobes per cluster.
    #[arg(long, default_value_t = 2)]
    pub lobes: usize,
    /// Fixed Fresnel index η, in [1.01, 4] (the start of the search with --fit-eta).
    #[arg(long, default_value_t = 1.5)]
    pub eta: f32,
    /// Search η per cluster instead of fixing it.
    #[arg(long)]
    pub fit_eta: bool,
    /// Reading of the printed Eqs. 2–3: `held` (format 1.14) is `width` with each lobe's
    /// height held to at most 4 times its peak where the azimuthal falloff narrows it.
    #[arg(long, value_enum, default_value = "held")]
    pub reading: ReadingArg,
    /// The surface's diffuse law: Lambert's k_d·max(n·ω_i, 0), or Lommel–Seeliger's
    /// k_d·max(n·ω_i, 0)·2/(μ_i + μ_o), μ the cosines to the tile's normal (format 1.6;
    /// baker/FIT_MEASUREMENTS.md measures both).
    #[arg(long, value_enum, default_value = "lommel-seeliger")]
    pub diffuse: DiffuseArg,
    /// Keep the geometry stage's texel frames instead of fitting a frame offset per
    /// cluster with its BRDF (slope, rise, twist, roll: Eq. 8 with the frame free).
    #[arg(long)]
    pub no_frame_fit: bool,
    /// One frame offset per cluster shared by its lobes, instead of one per lobe (warp
    /// and weft seen in one texel; lobe 0's is also the diffuse term's).
    #[arg(long)]
    pub shared_frame: bool,
    /// Fit (and render) with the height field's shadowing of the light (off by default:
    /// measured worse on held-out views, baker/FIT_MEASUREMENTS.md).
    #[arg(long)]
    pub shadows: bool,
    /// Weigh every training pair alike in the fit, instead of each by the inverse of its
    /// image's brightness (each pair's error relative to itself, as held-out views count;
    /// baker/FIT_MEASUREMENTS.md measures both). With `--bsdf`, the backlit pairs too.
    #[arg(long)]
    pub unweighted_pairs: bool,
    /// Fit and render surface hits with the volumetric factor 2/(μ_i + μ_o) (format 1.1).
    #[arg(long)]
    pub volumetric: bool,
    /// What the surface fit's renderings leave out: the flyaway voxels V by default, which
    /// the model draws itself (baker/FIT_MEASUREMENTS.md, "What the surface fit sees")
    #[arg(long, value_enum, default_value = "flyaways")]
    pub mask: MaskArg,
    /// Scale of the fiber-level detail h0 − h in the normal map (`fabric geometry
    /// --detail-strength`, whose default 1 is the detail as measured; the bake's 0.25 is
    /// what its held-out views preferred, baker/FIT_MEASUREMENTS.md).
    #[arg(long, default_value_t = 0.25)]
    pub normal_detail: f32,
    /// Scale of the normals' tilt from +Z (1 = the geometry stage's normals, 0 = flat).
    #[arg(long, default_value_t = 1.0)]
    pub normal_slope: f32,
    /// Fraction of the fiber-level relief h0 − h kept in the model's height field.
    #[arg(long, default_value_t = 0.0)]
    pub relief: f32,
    /// Leave the flyaway fibers out of the model.
    #[arg(long)]
    pub no_flyaways: bool,
    /// Most flyaway BRDF clusters.
    #[arg(long, default_value_t = 4)]
    pub flyaway_clusters: usize,
    /// Coverage of a level-0 flyaway voxel: opaque, or ρ/ρ_solid.
    #[arg(long, value_enum, default_value = "density")]
    pub flyaway_alpha: AlphaArg,
    /// Cross level-0 flyaway voxels by Beer's law from α alone, rather than with the path
    /// gain by polar angle fitted so that they let through what the volume's flyaway
    /// voxels do (format 1.9's FLYAWAY_PATH_GAIN at level 0; baker/FIT_MEASUREMENTS.md,
    /// "The flyaways' opacity against the volume").
    #[arg(long)]
    pub no_flyaway_path_gain: bool,
    /// The flyaways' lobes about the fibre axis: a cylinder's (the default; format 1.11's
    /// MODEL flag bit 4), or a surface's facing the viewer (as before 1.11;
    /// baker/FIT_MEASUREMENTS.md, "The flyaways' lobes as cylinders")
    #[arg(long, value_enum, default_value = "cylinder")]
    pub flyaway_lobes: FiberLobesArg,
    /// Whether the surface is lit through the flyaways in front of it toward each light
    /// (format 1.13's MODEL flag bit 5): `auto` fits the flyaways both ways and keeps the
    /// model nearer the full volume's training images; `on`, `off` (baker/FIT_MEASUREMENTS.md,
    /// "The flyaways' shadow on the surface")
    #[arg(long, value_enum, default_value = "auto")]
    pub flyaway_shadow: FlyawayShadowArg,
    /// Refit each surface texel's k_d, k_j and gradient behind the fitted flyaways on the
    /// full volume's training images (off by default: it can leave hot texels behind dense
    /// flyaways; baker/FIT_MEASUREMENTS.md, "What the surface fit sees")
    #[arg(long)]
    pub surface_refit: bool,
    /// Samples per texel of the full-volume training renderings (flyaway fit).
    #[arg(long, default_value_t = 16)]
    pub flyaway_spp: u32,
    /// Shift of the model's surface along z, in voxels (negative: deeper).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub surface_offset: f32,
    /// Keep the paper's clustered level 0 (one BRDF per cluster) instead of refining
    /// each texel's k_d and k_j on its own samples.
    #[arg(long)]
    pub clustered: bool,
    /// Ridge of the per-texel refinement towards the cluster's values (relative).
    #[arg(long, default_value_t = 0.05)]
    pub ridge: f64,
    /// Bound every lobe (cluster and texel) to add at most this multiple of the brightest
    /// radiance its cluster showed in the training images, at any pair of directions: a
    /// lobe seen only by its tail cannot put a highlight where no pair looked (0: no
    /// bound; baker/FIT_MEASUREMENTS.md, "A bound on a lobe's peak").
    #[arg(long, default_value_t = fabric_baker::fit::cluster_fit::LOBE_PEAK_MAX)]
    pub lobe_peak_max: f32,
    /// No visibility gradient per texel (format 1.12): the texel's response the same
    /// from every side (the refinement of k_d and k_j alone).
    #[arg(long)]
    pub no_gradient: bool,
    /// No visibility curvature per texel (format 1.15): the visibility's first-order
    /// gradient alone, without its even second-order part.
    #[arg(long)]
    pub no_curvature: bool,
    /// Ridge of the curvature's fit towards q = 0, relative to its normal equations' mean
    /// diagonal (the gradient's is 0.05).
    #[arg(long, default_value_t = 0.05)]
    pub curvature_ridge: f64,
    /// Held-out views to measure after the bake (0 skips the check).
    #[arg(long, default_value_t = 8)]
    pub held_out: usize,
    /// Samples per pixel of the held-out references.
    #[arg(long, default_value_t = 64)]
    pub held_out_spp: u32,
    /// The yardstick of each held-out view: the reference again with its light turned by
    /// this many degrees, against itself (how much the truth changes for a small error
    /// of angle); 0 skips it.
    #[arg(long, default_value_t = 5.0)]
    pub held_out_turn: f32,
    /// Directory for the held-out pictures [default: beside the model, NAME-views/].
    #[arg(long)]
    pub pictures: Option<PathBuf>,
    /// Write level 0 only (no mip chain).
    #[arg(long)]
    pub no_prefilter: bool,
    /// Fit a full BSDF: also the light that comes through the cloth from behind
    /// (backlit training renderings, a transmission term per texel; format 1.3). The
    /// held-out check then adds backlit views.
    #[arg(long)]
    pub bsdf: bool,
    /// Largest optical-depth parameter τ of the transmission's slant-path attenuation
    /// (0 turns the attenuation off; measured knob).
    #[arg(long, default_value_t = 4.0)]
    pub tau_max: f32,
    /// Samples per texel of the backlit training renderings [default: --spp].
    #[arg(long)]
    pub bsdf_spp: Option<u32>,
    /// Rays per texel per view that measure the gaps between yarns, where an environment
    /// map below the sheet is seen straight through (format 1.10; 0: none).
    #[arg(long, default_value_t = 8)]
    pub openness_rays: u32,
    /// With --bsdf, leave out the transmission visibility (format 1.16: each texel's
    /// transmission scaled by the slant of the viewer and the light across the tile, its
    /// gradient and curvature, fitted with its k's; baker/FIT_MEASUREMENTS.md,
    /// "Transmission").
    #[arg(long)]
    pub no_transmission_gradient: bool,
    /// With --bsdf, the transmission visibility's gradient alone (no curvature).
    #[arg(long)]
    pub no_transmission_curvature: bool,
    /// Ridge of the transmission visibility's fit towards g = 0 and q = 0, relative to
    /// its normal equations' mean diagonal.
    #[arg(long, default_value_t = fabric_baker::fit::transmission::GRADIENT_RIDGE)]
    pub transmission_gradient_ridge: f64,
    #[command(flatten)]
    pub prefilter: crate::cmd::prefilter::PrefilterArgs,
}

/// Most held-out views `--held-out` renders (each a reference at --held-out-spp).
const MAX_HELD_OUT: usize = 256;

pub fn run(args: BakeArgs) -> Result<()> {
    let mut options = BakeOptions { seed: args.seed, spp: args.spp, k_min: args.k_min, k_max: args.k_max, delta: args.delta, min_gain: args.min_gain, shadows: args.shadows, pair_weights: !args.unweighted_pairs, volumetric: args.volumetric, ..Default::default() };
    options.pairs.count = args.pairs;
    options.fit.lobes = args.lobes;
    options.fit.eta = args.eta;
    options.fit.fit_eta = args.fit_eta;
    if args.no_frame_fit {
        options.frame_fit = None;
    }
    if let Some(f) = options.frame_fit.as_mut() {
        f.per_lobe = !args.shared_frame;
    }
    options.fit.reading = match args.reading {
        ReadingArg::Bounded => BrdfReading::Bounded,
        ReadingArg::Width => BrdfReading::Width,
        ReadingArg::Held => BrdfReading::Held,
    };
    options.fit.diffuse = match args.diffuse {
        DiffuseArg::Lambert => DiffuseLaw::Lambert,
        DiffuseArg::LommelSeeliger => DiffuseLaw::LommelSeeliger,
    };
    options.surface_mask = match args.mask {
        MaskArg::Above => SurfaceMask::AboveSurface,
        MaskArg::Flyaways => SurfaceMask::Flyaways,
        MaskArg::None => SurfaceMask::None,
    };
    options.lookup = match args.lookup {
        LookupArg::Trilinear => Lookup::Trilinear,
        LookupArg::Nearest => Lookup::Nearest,
    };
    if !(args.normal_detail.is_finite() && (0.0..=4.0).contains(&args.normal_detail)) {
        bail!("--normal-detail {}: must be in [0, 4]", args.normal_detail);
    }
    options.geometry.detail_strength = args.normal_detail;
    if !(args.normal_slope.is_finite() && (0.0..=2.0).contains(&args.normal_slope)) {
        bail!("--normal-slope {}: must be in [0, 2]", args.normal_slope);
    }
    options.normal_slope = args.normal_slope;
    if !(args.relief.is_finite() && (0.0..=1.0).contains(&args.relief)) {
        bail!("--relief {}: must be in [0, 1]", args.relief);
    }
    options.relief = args.relief;
    if !(args.surface_offset.is_finite() && args.surface_offset.abs() <= 64.0) {
        bail!("--surface-offset {}: must be within ±64 voxels", args.surface_offset);
    }
    options.surface_offset = args.surface_offset;
    if !(args.ridge.is_finite() && args.ridge >= 0.0) {
        bail!("--ridge {}: must be a non-negative number", args.ridge);
    }
    options.per_texel_ridge = (!args.clustered).then_some(args.ridge);
    if !(args.lobe_peak_max.is_finite() && (args.lobe_peak_max == 0.0 || args.lobe_peak_max >= 1.0)) {
        bail!("--lobe-peak-max {}: must be 0 (no bound) or at least 1", args.lobe_peak_max);
    }
    options.lobe_peak_max = (args.lobe_peak_max > 0.0).then_some(args.lobe_peak_max);
    if args.no_gradient || args.clustered {
        options.gradient = None;
    }
    if !(args.transmission_gradient_ridge.is_finite() && args.transmission_gradient_ridge >= 0.0) {
        bail!("--transmission-gradient-ridge {}: must be a finite number >= 0", args.transmission_gradient_ridge);
    }
    if !(args.curvature_ridge.is_finite() && args.curvature_ridge >= 0.0) {
        bail!("--curvature-ridge {}: must be a finite number >= 0", args.curvature_ridge);
    }
    if let Some(g) = options.gradient.as_mut() {
        g.curvature = !args.no_curvature;
        g.curvature_ridge = args.curvature_ridge;
    }
    if args.flyaway_clusters == 0 || args.flyaway_clusters > 256 {
        bail!("--flyaway-clusters {}: must be in 1..=256", args.flyaway_clusters);
    }
    if args.flyaway_spp < 2 {
        bail!("--flyaway-spp {}: need at least 2 (two halves)", args.flyaway_spp);
    }
    options.flyaways = (!args.no_flyaways).then_some(FlyawayOptions {
        clusters: args.flyaway_clusters,
        spp: args.flyaway_spp,
        alpha: match args.flyaway_alpha {
            AlphaArg::Full => FlyawayAlpha::Full,
            AlphaArg::Density => FlyawayAlpha::Density,
        },
        path_gain: !args.no_flyaway_path_gain,
        lobes: match args.flyaway_lobes {
            FiberLobesArg::Cylinder => fabric_runtime::brdf::FiberLobes::Cylinder,
            FiberLobesArg::Facing => fabric_runtime::brdf::FiberLobes::Facing,
        },
        shadow_surface: match args.flyaway_shadow {
            FlyawayShadowArg::Auto => fabric_baker::bake::FlyawayShadow::Auto,
            FlyawayShadowArg::On => fabric_baker::bake::FlyawayShadow::On,
            FlyawayShadowArg::Off => fabric_baker::bake::FlyawayShadow::Off,
        },
        refit_surface: args.surface_refit,
    });
    options.prefilter = if args.no_prefilter { None } else { Some(args.prefilter.options(args.seed, !args.no_flyaways)?) };
    if !(args.tau_max.is_finite() && (0.0..=fabric_runtime::brdf::TAU_MAX).contains(&args.tau_max)) {
        bail!("--tau-max {}: must be in [0, {}]", args.tau_max, fabric_runtime::brdf::TAU_MAX);
    }
    if args.bsdf_spp.is_some_and(|s| s < 2) {
        bail!("--bsdf-spp {}: need at least 2 (two halves)", args.bsdf_spp.unwrap_or(0));
    }
    options.transmission = args.bsdf.then(|| fabric_baker::fit::transmission::TransmissionFitOptions { tau_max: args.tau_max, spp: args.bsdf_spp.unwrap_or(0), openness_rays: args.openness_rays, gradient_ridge: (!args.no_transmission_gradient).then_some(args.transmission_gradient_ridge), curvature_ridge: (!args.no_transmission_curvature).then_some(args.transmission_gradient_ridge), ..Default::default() });
    options.validate()?;
    options.geometry.validate()?;
    if args.held_out_spp < 2 {
        bail!("--held-out-spp {}: need at least 2 (two halves)", args.held_out_spp);
    }
    for (flag, spp) in [("--held-out-spp", Some(args.held_out_spp)), ("--flyaway-spp", Some(args.flyaway_spp)), ("--bsdf-spp", args.bsdf_spp)] {
        if spp.is_some_and(|s| s > crate::args::MAX_SPP) {
            bail!("{flag} {}: must be at most {}", spp.unwrap_or(0), crate::args::MAX_SPP);
        }
    }
    if args.held_out > MAX_HELD_OUT {
        bail!("--held-out {}: must be at most {MAX_HELD_OUT} views", args.held_out);
    }
    if args.prefilter.levels.is_some_and(|l| l == 0) {
        bail!("--levels 0: a model has at least level 0");
    }
    // Where the results go, checked before the work that would write them.
    crate::args::check_writable_file(&args.out, "--out")?;
    if let Some(report) = &args.report {
        crate::args::check_writable_file(report, "--report")?;
    }
    if let Some(p) = args.pictures.as_ref().filter(|p| p.exists() && !p.is_dir()) {
        bail!("--pictures {}: is a file; give a folder for the held-out views' pictures", p.display());
    }
    if !(args.held_out_turn.is_finite() && (0.0..=45.0).contains(&args.held_out_turn)) {
        bail!("--held-out-turn {}: a turn of the light in degrees, 0 to 45 (0 skips the yardstick)", args.held_out_turn);
    }
    let overrides = args.material.overrides()?;

    let start = Instant::now();
    let volume = load_fabric(&args.dir, &overrides).with_context(|| format!("cannot load the fabric volume {}", args.dir.display()))?;
    if let Some(note) = fabric_baker::volume::material_defaults_note(&args.dir, &overrides) {
        eprintln!("{note}");
    }
    let [nx, ny, nz] = volume.dims();
    if let Some(levels) = args.prefilter.levels {
        let most = fabric_runtime::hybrid::max_levels(nx as u32, ny as u32);
        if levels > most {
            bail!("--levels {levels}: a {nx}x{ny} volume's model has 1..={most} levels");
        }
    }
    println!("volume {}: {nx}x{ny}x{nz} voxels (loaded in {:.2} s)", args.dir.display(), start.elapsed().as_secs_f64());

    let progress = Bars::default();
    let result = bake(&volume, &options, &progress).with_context(|| format!("cannot bake {}", args.dir.display()))?;
    progress.finish();
    let r = &result.report;
    for round in &r.rounds {
        println!(
            "K = {:>3}: training error {:.2}% per texel, {:.2}% over 4x4 blocks (median cluster residual {:.1}%), {:.1} s",
            round.k,
            100.0 * round.error,
            100.0 * round.block_error,
            100.0 * round.median_cluster_residual,
            round.seconds
        );
    }
    println!("kept K = {}; training-render noise floor {:.2}%", r.k, 100.0 * r.noise_floor);
    let moved: Vec<_> = r.frame_offsets.iter().flatten().filter(|o| !o.is_identity()).collect();
    if !moved.is_empty() {
        let median = |mut v: Vec<f32>| {
            v.sort_by(f32::total_cmp);
            v[v.len() / 2]
        };
        println!(
            "frame fit: {} of {} offsets moved (median slope scale {:.2}, |rise| {:.1}°, |twist| {:.1}°, |roll| {:.1}°)",
            moved.len(),
            r.frame_offsets.iter().map(|o| o.len()).sum::<usize>(),
            median(moved.iter().map(|o| o.slope).collect()),
            median(moved.iter().map(|o| o.rise.abs().to_degrees()).collect()),
            median(moved.iter().map(|o| o.twist.abs().to_degrees()).collect()),
            median(moved.iter().map(|o| o.roll.abs().to_degrees()).collect()),
        );
    }
    if r.per_texel {
        println!(
            "per-texel refinement: training error {:.2}% per texel, {:.2}% over 4x4 blocks (clusters alone: {:.2}%, {:.2}%)",
            100.0 * r.error,
            100.0 * r.block_error,
            100.0 * r.cluster_error,
            100.0 * r.cluster_block_error
        );
    }
    if let Some(g) = &r.gradient {
        println!(
            "visibility gradient{}: |g| median {:.2}, p90 {:.2}{}; training error without it {:.2}% per texel, {:.2}% over 4x4 blocks",
            if g.curvature_median.is_some() { " and curvature" } else { "" },
            g.median,
            g.p90,
            g.curvature_median.map_or(String::new(), |q| format!(", |q| median {q:.2}")),
            100.0 * g.error_without,
            100.0 * g.block_error_without
        );
    }
    println!("training error on grazing pairs (a polar angle > 55°) {:.1}%, on the others {:.1}%", 100.0 * r.error_grazing, 100.0 * r.error_non_grazing);
    let e = &r.energy;
    let worst = e.worst_cluster_albedo.max(e.worst_texel_albedo).max(e.worst_flyaway_albedo);
    if e.clusters_capped + e.texels_capped + e.flyaway_entries_capped > 0 {
        println!(
            "lobe energy: the fitted lobes reflected up to {worst:.1}x what they receive; scaled down to an albedo of {}: {} of {k} clusters, {} texels, {} flyaway entries (few pairs constrain those lobes: more pairs fit them)",
            e.lobe_albedo_max,
            e.clusters_capped,
            e.texels_capped,
            e.flyaway_entries_capped,
            k = r.k
        );
    } else {
        println!("lobe energy: worst albedo of the fitted lobes {worst:.2} (bound {}): none scaled", e.lobe_albedo_max);
    }
    if let Some(m) = r.lobe_peak_max {
        println!(
            "lobe peaks: {} of {} cluster lobes held at {m}x their cluster's brightest training radiance, {} texel lobes lowered to it",
            r.peak_capped_lobes, r.cluster_lobes, r.texel_lobes_peak_capped
        );
    }
    if r.unseen_lobes > 0 {
        println!("unseen lobes: {} of {} cluster lobes held at k = 0: no training pair came within three widths of their ridge (more pairs place them)", r.unseen_lobes, r.cluster_lobes);
    }
    if let Some(f) = &r.flyaways {
        println!(
            "flyaways: {} voxels in {} clusters; {} training pixels cross them: error {:.1}% with them black, {:.1}% fitted{}",
            f.voxels,
            f.clusters,
            f.pixels,
            100.0 * f.error_without,
            100.0 * f.error_fitted,
            f.problem.as_ref().map(|p| format!(" ({p})")).unwrap_or_default()
        );
        if let (Some(g), Some(tv), Some(tm)) = (&f.path_gain, &f.transmittance_volume, &f.transmittance_ungained) {
            // Nodes 0, 4 and 7: 0°, 40° and 70°.
            let ratio = |k: usize| if tv[k] > 0.0 { tm[k] / tv[k] } else { 1.0 };
            println!("  level-0 path gain at 0°/40°/70°: {:.2}/{:.2}/{:.2} (Beer's law from α let through {:.2}/{:.2}/{:.2} of what the volume's flyaway voxels do)", g[0], g[4], g[7], ratio(0), ratio(4), ratio(7));
        }
        let shadow = if f.shadow_surface { "on" } else { "off" };
        match (f.block_error_shadowed, f.block_error_unshadowed) {
            (Some(on), Some(off)) => println!("  the flyaways' shadow on the surface: {shadow} (the whole model against the full volume's training images over 4x4 blocks: {:.2}% with it, {:.2}% without)", 100.0 * on, 100.0 * off),
            _ => println!("  the flyaways' shadow on the surface: {shadow}"),
        }
    }
    if let Some(s) = &r.surface_refit {
        let verdict = if s.kept { "kept" } else { "not kept" };
        println!(
            "surface refitted behind the flyaways ({} samples): the whole model against the full volume's training images over 4x4 blocks {:.2}% -> {:.2}%, {verdict}",
            s.samples,
            100.0 * s.block_error_before,
            100.0 * s.block_error_after
        );
    }
    if let Some(t) = &r.transmission {
        println!(
            "transmission: {} backlit pairs, training error {:.2}% per texel, {:.2}% over 4x4 blocks (clusters alone {:.2}%; noise floor {:.2}%); worst albedo {:.3}, {} texels capped; {:.1} s rendering + {:.1} s fitting",
            t.pairs.len(),
            100.0 * t.error,
            100.0 * t.block_error,
            100.0 * t.cluster_error,
            100.0 * t.noise_floor,
            t.worst_albedo,
            t.capped_texels,
            t.render_seconds,
            t.fit_seconds
        );
        if let (Some((e, b)), Some(g)) = (t.without_visibility, t.gradient_median) {
            println!("  transmission visibility: median gradient |g| {g:.3}; without it {:.2}% per texel, {:.2}% over 4x4 blocks", 100.0 * e, 100.0 * b);
        }
        if let Some(o) = &t.openness {
            let at = |v: &[f64]| v.iter().map(|x| format!("{:.2}%", 100.0 * x)).collect::<Vec<_>>().join("/");
            let polar = o.polar_deg.iter().map(|d| format!("{d:.0}")).collect::<Vec<_>>().join("/");
            println!("  gaps between yarns: {} of {} texels open (largest o {:.3}, q {:.2}, azimuth terms {:.2}, {:.2}); rays that cross at polar {polar}°: volume {}, model {} ({:.1} s)", o.open_texels, r.dims[0] * r.dims[1], o.max_o, o.q, o.aniso[0], o.aniso[1], at(&o.volume), at(&o.model), o.seconds);
        }
        for p in &t.problems {
            println!("warning: transmission of cluster {} ({} texels): {}", p.cluster, p.texels, p.problem);
        }
    }
    if let Some(p) = &r.prefilter {
        crate::cmd::prefilter::print_report(p);
    }
    for p in &r.cluster_problems {
        println!("warning: cluster {} ({} texels): {}", p.cluster, p.texels, p.problem);
    }
    fabric_runtime::hybrid::format::write_file(&result.model, &args.out).with_context(|| format!("cannot write {}", args.out.display()))?;
    println!("wrote {} ({} bytes; input volume {} bytes)", args.out.display(), r.model_bytes, r.input_bytes);
    let times: Vec<String> = r.stage_seconds.iter().map(|(s, t)| format!("{s} {t:.1}")).collect();
    println!("stage times (s): {}; bake total {:.1} s", times.join(", "), r.total_seconds);
    if !r.stage_peak_rss_bytes.is_empty() {
        let peaks: Vec<String> = r.stage_peak_rss_bytes.iter().map(|(s, b)| format!("{s} {:.0}", *b as f64 / 1e6)).collect();
        println!("peak memory after each stage (MB): {}", peaks.join(", "));
    }

    let pictures = args.pictures.clone().unwrap_or_else(|| sibling(&args.out, "-views"));
    std::fs::create_dir_all(&pictures).with_context(|| format!("cannot create {}", pictures.display()))?;
    // Where the fit falls short: per-texel residual maps, grazing and other pairs.
    for (grazing, name) in [(true, "residual_grazing.png"), (false, "residual_other.png")] {
        let map = residual_map(&result.predictions, &result.training.images, &r.pairs, grazing);
        map.write(&pictures.join(name), 1.0).with_context(|| format!("cannot write {}", pictures.join(name).display()))?;
    }
    let mut csv = String::from("k,training_error,training_block_error,median_cluster_residual,seconds\n");
    for round in &r.rounds {
        csv += &format!("{},{},{},{},{}\n", round.k, round.error, round.block_error, round.median_cluster_residual, round.seconds);
    }
    std::fs::write(pictures.join("error_vs_k.csv"), csv).with_context(|| format!("cannot write {}", pictures.join("error_vs_k.csv").display()))?;

    // Held-out views.
    let mut views: Vec<ViewError> = Vec::new();
    if args.held_out > 0 {
        let medium = reference_medium(&volume, options.lookup)?;
        let mut pairs = held_out_pairs(&r.pairs, args.held_out, 60.0, 5.0, options.seed ^ 0x5eed);
        // A BSDF is also checked backlit: as many views again, with the light below.
        let backlit = r.transmission.is_some();
        if backlit {
            let more = held_out_pairs(&r.pairs, args.held_out, 60.0, 5.0, options.seed ^ 0xb4c7);
            pairs.extend(fabric_baker::fit::directions::backlit_pairs(&more));
        }
        let bar = stage_bar("held-out views", pairs.len() as u64);
        for (v, pair) in pairs.iter().enumerate() {
            // Every fourth view is a perspective point-light view.
            let kind = if v % 4 == 3 { ViewKind::Perspective } else { ViewKind::Orthographic };
            let (e, images) = evaluate_view(&volume, &medium, &result.model, pair, kind, nx.max(ny) as u32, args.held_out_spp, options.seed.wrapping_add(v as u64), args.held_out_turn)?;
            side_by_side(&images.reference, &images.model, &pictures.join(format!("view{v}.png")))?;
            views.push(e);
            bar.inc(1);
        }
        bar.finish_and_clear();
        println!("held-out views (model vs reference, relative RMSE):");
        for (v, e) in views.iter().enumerate() {
            println!(
                "  view {v} {:?}{} wi θ {:>4.1}° wo θ {:>4.1}°: {:>5.1}% per 4x4 block, {:>5.1}% per pixel, {:>5.1}% per 16x16, mean ratio {:.3} (reference noise {:.1}%, net of it {:.1}%{})",
                e.kind,
                if e.pair.wi.z < 0.0 { " backlit" } else { "" },
                e.pair.wi.z.acos().to_degrees(),
                e.pair.wo.z.acos().to_degrees(),
                100.0 * e.block_error,
                100.0 * e.pixel_error,
                100.0 * e.block16_error,
                e.mean_ratio,
                100.0 * e.reference_noise,
                100.0 * e.block_error_net,
                e.light_turned_error.map(|t| format!("; the reference lit {:.0}° off: {:.1}%", e.light_turn_deg, 100.0 * t)).unwrap_or_default()
            );
        }
        for (lit, name) in [(false, "held-out error over 4x4 blocks"), (true, "backlit held-out error over 4x4 blocks")] {
            let of: Vec<f64> = views.iter().filter(|e| (e.pair.wi.z < 0.0) == lit).map(|e| e.block_error).collect();
            if of.is_empty() {
                continue;
            }
            let worst = of.iter().copied().fold(0.0, f64::max);
            let mean = of.iter().sum::<f64>() / of.len() as f64;
            let net: Vec<f64> = views.iter().filter(|e| (e.pair.wi.z < 0.0) == lit).map(|e| e.block_error_net).collect();
            let net_mean = net.iter().sum::<f64>() / net.len() as f64;
            println!("{name}: mean {:.1}%, worst {:.1}%; net of the references' noise mean {:.1}%, worst {:.1}% (pictures in {})", 100.0 * mean, 100.0 * worst, 100.0 * net_mean, 100.0 * net.iter().copied().fold(0.0, f64::max), pictures.display());
            // A reference is converged for a 10% bar when its two halves differ by at most
            // a third of it over the same blocks (‖A − B‖/‖M‖ = 2 × the mean's noise).
            let halves = views.iter().filter(|e| (e.pair.wi.z < 0.0) == lit).map(|e| 2.0 * e.reference_noise).fold(0.0, f64::max);
            if halves > 0.1 / 3.0 {
                println!("  the references' two halves differ by up to {:.1}% over 4x4 blocks: not converged for a 10% bar (at most 3.3%); --held-out-spp {} would bring them to about {:.1}%", 100.0 * halves, args.held_out_spp * 4, 50.0 * halves);
            }
            let turned: Vec<f64> = views.iter().filter(|e| (e.pair.wi.z < 0.0) == lit).filter_map(|e| e.light_turned_error).collect();
            if !turned.is_empty() {
                println!("  yardstick: the reference against itself lit {:.0}° off, mean {:.1}% over the same blocks", args.held_out_turn, 100.0 * turned.iter().sum::<f64>() / turned.len() as f64);
            }
        }
    }

    let report_path = args.report.clone().unwrap_or_else(|| args.out.with_extension("json"));
    let json = serde_json::json!({ "bake": r, "held_out": views });
    std::fs::write(&report_path, serde_json::to_string_pretty(&json)?).with_context(|| format!("cannot write {}", report_path.display()))?;
    println!("wrote {}", report_path.display());
    Ok(())
}

/// Per texel √(Σ‖model − reference‖² / Σ‖reference‖²) over the grazing (a polar angle
/// > 55°) or the other training pairs, as a picture: 0 black, 50% mid-grey, ≥ 100% white.
fn residual_map(predictions: &[Image], references: &[Image], pairs: &[fabric_baker::fit::directions::Pair], grazing: bool) -> Image {
    let (w, h) = (references[0].width, references[0].height);
    let mut d2 = vec![0f64; (w * h) as usize];
    let mut r2 = vec![0f64; (w * h) as usize];
    for ((p, r), pair) in predictions.iter().zip(references).zip(pairs) {
        if (pair.max_polar_deg() > 55.0) != grazing {
            continue;
        }
        for k in 0..d2.len() {
            d2[k] += (p.pixels[k] - r.pixels[k]).as_dvec3().length_squared();
            r2[k] += r.pixels[k].as_dvec3().length_squared();
        }
    }
    let mut out = Image::new(w, h);
    for k in 0..d2.len() {
        let e = if r2[k] > 0.0 { (d2[k] / r2[k]).sqrt() as f32 } else { 0.0 };
        // PNG writes sRGB(v): choose v so that the grey level reads linearly in e.
        out.pixels[k] = glam::Vec3::splat(fabric_runtime::image::srgb_decode(e.min(1.0)));
    }
    out
}

/// `path` with `suffix` appended to its stem, as a directory beside it.
fn sibling(path: &Path, suffix: &str) -> PathBuf {
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "model".into());
    path.with_file_name(format!("{stem}{suffix}"))
}

/// reference | model | |model − reference| (×4), one exposure chosen from the reference.
fn side_by_side(reference: &Image, model: &Image, path: &Path) -> Result<()> {
    let (w, h) = (reference.width, reference.height);
    let mut out = Image::new(3 * w, h);
    for y in 0..h {
        for x in 0..w {
            let (r, m) = (reference.get(x, y), model.get(x, y));
            out.set(x, y, r);
            out.set(w + x, y, m);
            out.set(2 * w + x, y, 4.0 * (m - r).abs());
        }
    }
    let mean = reference.mean().max(1e-6) as f32;
    out.write(path, 0.4 / mean).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}
