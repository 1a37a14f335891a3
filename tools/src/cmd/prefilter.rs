//! `fabric prefilter IN.hyb --out OUT.hyb`: rebuilds the mip chain of an existing model
//! from its level 0 (paper §5.3.5) and prints, per level, its size, lobes and fit error.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use fabric_baker::prefilter::{PrefilterOptions, PrefilterReport, prefilter};
use fabric_runtime::hybrid::format::{read_file, write_file};

use crate::progress::Bars;

/// The prefilter's flags, shared with `fabric bake`.
#[derive(Args, Debug, Clone)]
pub struct PrefilterArgs {
    /// Relative fit error at which a coarse texel stops adding lobes.
    #[arg(long, default_value_t = 0.03)]
    pub prefilter_tolerance: f32,
    /// Most lobes per coarse texel (1..=8; more measured no better far away:
    /// baker/PREFILTER_MEASUREMENTS.md, "Lobe budget").
    #[arg(long, default_value_t = fabric_baker::prefilter::DEFAULT_MAX_LOBES)]
    pub prefilter_max_lobes: usize,
    /// Direction pairs each coarse texel is fitted on.
    #[arg(long, default_value_t = 128)]
    pub prefilter_pairs: usize,
    /// Levels in all, level 0 included [default: down to 1x1].
    #[arg(long)]
    pub levels: Option<usize>,
    /// Weight each level-0 texel by its visible projected area toward the viewer
    /// (baker/PREFILTER_MEASUREMENTS.md: helps grazing views of twill, hurts bumpy models).
    #[arg(long)]
    pub masking: bool,
    /// A coarse flyaway voxel's α: what it hides seen from above ("projected"), or the
    /// mean coverage of its voxel positions ("volume").
    #[arg(long, default_value = "projected", value_parser = ["projected", "volume"])]
    pub coverage: String,
    /// Fold the light's height-field visibility into the coarse BRDFs and shade coarse
    /// levels without shadow rays (format 1.2, MODEL flag bit 2).
    #[arg(long)]
    pub light_visibility: bool,
    /// Leave coarse texels without a view tilt (their frames as fitted from every view;
    /// baker/PREFILTER_MEASUREMENTS.md, "Grazing views", measures what the tilt buys).
    #[arg(long)]
    pub no_view_tilt: bool,
    /// Shade each coarse flyaway voxel with one merged fibre axis and widened lobes,
    /// rather than the cone of axes its fibres' spread gives (format 1.5's
    /// FLYAWAY_SPREAD).
    #[arg(long)]
    pub no_flyaway_spread: bool,
    /// Shade each coarse flyaway voxel as one cone of all its fibres' axes, rather than
    /// in two groups where they split, warp and weft (format 1.8's FLYAWAY_GROUP;
    /// baker/PREFILTER_MEASUREMENTS.md, "What the coarse flyaways get wrong").
    #[arg(long)]
    pub no_flyaway_groups: bool,
    /// Cross coarse flyaway voxels by Beer's law from their α alone, rather than with
    /// the path gain by polar angle that matches level 0's mean transmittance (format
    /// 1.9's FLYAWAY_PATH_GAIN; baker/PREFILTER_MEASUREMENTS.md, "The coarse flyaways'
    /// opacity by angle").
    #[arg(long)]
    pub no_path_gain: bool,
    /// Keep the coarse levels at level 0's precision (f16 colours, 16-bit frames and
    /// tilts) instead of format 1.7's compact records (baker/PREFILTER_MEASUREMENTS.md,
    /// "Compact coarse records", measures both).
    #[arg(long)]
    pub full_precision: bool,
    /// Keep each coarse lobe in the frame its group's moments give (the mean normal,
    /// the principal tangent axis) rather than refining twist and tilt with its widths
    /// (baker/PREFILTER_MEASUREMENTS.md, "Free frames").
    #[arg(long)]
    pub moment_frames: bool,
}

impl PrefilterArgs {
    pub fn options(&self, seed: u64, flyaways: bool) -> Result<PrefilterOptions> {
        if !(self.prefilter_tolerance.is_finite() && self.prefilter_tolerance >= 0.0) {
            bail!("--prefilter-tolerance {}: must be a non-negative number", self.prefilter_tolerance);
        }
        if !(1..=8).contains(&self.prefilter_max_lobes) {
            bail!("--prefilter-max-lobes {}: must be in 1..=8", self.prefilter_max_lobes);
        }
        if !(4..=4096).contains(&self.prefilter_pairs) {
            bail!("--prefilter-pairs {}: must be in 4..=4096", self.prefilter_pairs);
        }
        Ok(PrefilterOptions { tolerance: self.prefilter_tolerance, max_lobes: self.prefilter_max_lobes, pairs: self.prefilter_pairs, levels: self.levels, flyaways, masking: self.masking, coverage: if self.coverage == "volume" { fabric_baker::prefilter::flyaways::Coverage::Volume } else { fabric_baker::prefilter::flyaways::Coverage::Projected }, light_visibility: self.light_visibility, view_tilt: !self.no_view_tilt, flyaway_spread: !self.no_flyaway_spread, flyaway_groups: !self.no_flyaway_groups, path_gain: !self.no_path_gain, compact: !self.full_precision, free_frames: !self.moment_frames, seed, ..Default::default() })
    }
}

#[derive(Args, Debug)]
pub struct PrefilterCmdArgs {
    /// The hybrid model whose level 0 is kept.
    pub input: PathBuf,
    /// The model to write, with the rebuilt levels.
    #[arg(long)]
    pub out: PathBuf,
    /// Leave the coarse levels without flyaways.
    #[arg(long)]
    pub no_flyaways: bool,
    /// The JSON report [default: OUT with .json].
    #[arg(long)]
    pub report: Option<PathBuf>,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Measure the chain afterwards: far views (16 and 32 px across the tile at 0°, 45°,
    /// 70°) and a distance sweep, against level 0 with at least 4×4 samples per level-0
    /// texel (baker/PREFILTER_MEASUREMENTS.md says why 64 per pixel is not a truth).
    #[arg(long)]
    pub check: bool,
    /// The renderer's coarse filter that --check measures (as `render --coarse-filter`).
    #[arg(long, default_value = "split-shaded", value_parser = clap::builder::PossibleValuesParser::new(fabric_runtime::cpu::CoarseFilter::NAMES.map(|(n, _)| n)))]
    pub check_filter: String,
    #[command(flatten)]
    pub prefilter: PrefilterArgs,
}

/// Prints the far-view and sweep errors of `model` with the chain rendered through
/// `filter` (a `CoarseFilter::NAMES` name); returns them for the report.
pub fn check_chain(model: &fabric_runtime::hybrid::HybridModel, filter: &str) -> Result<serde_json::Value> {
    use fabric_baker::prefilter::far_view::{VIEW_AZIMUTH, distance_sweep_filtered, far_view_filtered};
    use fabric_runtime::cpu::CoarseFilter;
    let Some(coarse) = CoarseFilter::from_name(filter) else {
        anyhow::bail!("--check-filter {filter}: one of {}", CoarseFilter::NAMES.map(|(n, _)| n).join(", "));
    };
    println!("far views, coarse filter {filter} (relative RMSE against level 0 at >= 4x4 samples per texel): auto levels 1 spp | nearest level 1 spp | level 0 1 spp | truth's own noise");
    let mut views = Vec::new();
    for pixels in [16u32, 32] {
        for polar in [0.0f32, 45.0, 70.0] {
            let e = far_view_filtered(model, polar, VIEW_AZIMUTH, pixels, coarse)?;
            println!("  {pixels:>3} px ({:>4.1} texels/px) at {polar:>4.1}°: {:>6.2}% | {:>6.2}% | {:>6.2}% | {:>5.2}%", e.texels_per_pixel, 100.0 * e.chain, 100.0 * e.chain_nearest, 100.0 * e.level0, 100.0 * e.truth_noise);
            views.push(e);
        }
    }
    println!("distance sweep (32x32 px, perspective, 45°):");
    let sweep = distance_sweep_filtered(model, 32, 8, coarse)?;
    for s in &sweep {
        println!("  {:>6.2} texels/px: {:>6.2}% | {:>6.2}% | {:>6.2}% | {:>5.2}%", s.texels_per_pixel, 100.0 * s.chain, 100.0 * s.chain_nearest, 100.0 * s.level0, 100.0 * s.truth_noise);
    }
    Ok(serde_json::json!({ "coarse_filter": filter, "far_views": views, "distance_sweep": sweep }))
}

/// Prints a report's table.
pub fn print_report(r: &PrefilterReport) {
    println!("prefilter: {} direction pairs, tolerance {:.1}%", r.pairs, 100.0 * r.tolerance);
    println!("  level  size       lobes mean/max  fit error mean/p95  error with 1/2/4/8 lobes (texels)     surface B  flyaways   time");
    for l in &r.levels {
        let e = |n: usize| l.error_by_lobes.get(n - 1).map_or(f64::NAN, |e| 100.0 * e);
        println!(
            "  {:>5}  {:>4}x{:<4}  {:>5.2} / {:<3}     {:>6.2}% / {:<6.2}%   {:>5.1}/{:>5.1}/{:>5.1}/{:>5.1}% ({:>4})   {:>10}  {:>8}  {:>5.1} s",
            l.level,
            l.width,
            l.height,
            l.mean_lobes,
            l.max_lobes,
            100.0 * l.fit_error,
            100.0 * l.fit_error_p95,
            e(1),
            e(2),
            e(4),
            e(8),
            l.lobe_sweep_texels,
            l.surface_bytes,
            l.flyaway_nodes,
            l.seconds
        );
    }
    let groups: Vec<String> = r.levels.iter().filter(|l| l.flyaway_two_groups > 0).map(|l| format!("{} {}/{}", l.level, l.flyaway_two_groups, l.flyaway_nodes)).collect();
    if !groups.is_empty() {
        println!("  flyaway nodes in two groups of fibre axes per level: {}; 4 bytes per node", groups.join(", "));
    }
    // The gain at 0°, 40° and 70°, with the ungained level's mean transmittance over
    // level 0's at those angles (what the gain corrects).
    let gains: Vec<String> = r
        .levels
        .iter()
        .filter_map(|l| {
            let (g, t0, t) = (l.flyaway_path_gain.as_ref()?, l.flyaway_transmittance_level0.as_ref()?, l.flyaway_transmittance_ungained.as_ref()?);
            let ratio = |k: usize| if t0[k] > 0.0 { t[k] / t0[k] } else { 1.0 };
            Some(format!("{} {:.2}/{:.2}/{:.2} (T {:.2}/{:.2}/{:.2})", l.level, g[0], g[4], g[7], ratio(0), ratio(4), ratio(7)))
        })
        .collect();
    if !gains.is_empty() {
        println!("  flyaway path gain at 0°/40°/70° per level (ungained transmittance over level 0's): {}; {:.1} s", gains.join(", "), r.path_gain_seconds);
    }
    let trans: Vec<String> = r.levels.iter().filter_map(|l| l.transmission_fit_error.map(|e| format!("{} {:.2}%", l.level, 100.0 * e))).collect();
    if !trans.is_empty() {
        // 24 bytes per texel, 44 with the transmission visibility (format 1.16).
        let (bytes, texels) = r.levels.iter().fold((0u64, 0u64), |(b, t), l| (b + l.transmission_bytes, t + (l.width * l.height) as u64));
        println!("  transmission (BSDF), fit error per level: {}; {:.0} bytes per texel", trans.join(", "), bytes as f64 / texels.max(1) as f64);
    }
    let tilt: Vec<String> = r.levels.iter().filter_map(|l| l.view_tilt_error.map(|(a, b)| format!("{} {:.1}->{:.1}%", l.level, 100.0 * a, 100.0 * b))).collect();
    if !tilt.is_empty() {
        let (bytes, texels) = r.levels.iter().filter(|l| l.view_tilt_error.is_some()).fold((0u64, 0u64), |(b, t), l| (b + l.view_tilt_bytes, t + l.width as u64 * l.height as u64));
        println!("  view tilt, error against what distant views see, untilted->tilted per level: {}; {:.0} bytes per texel, {:.1} s", tilt.join(", "), bytes as f64 / texels.max(1) as f64, r.view_tilt_seconds);
    }
    let share = if r.level0_bytes > 0 { 100.0 * r.chain_bytes as f64 / r.level0_bytes as f64 } else { 0.0 };
    println!("  coarse levels {} bytes = {share:.1}% of level 0's {} bytes; {:.1} s", r.chain_bytes, r.level0_bytes, r.seconds);
}

pub fn run(args: PrefilterCmdArgs) -> Result<()> {
    let options = args.prefilter.options(args.seed, !args.no_flyaways)?;
    let model = read_file(&args.input).with_context(|| format!("cannot read {}", args.input.display()))?;
    let bars = Bars::default();
    let (out, report) = prefilter(&model, &options, &bars).with_context(|| format!("cannot prefilter {}", args.input.display()))?;
    bars.finish();
    print_report(&report);
    write_file(&out, &args.out).with_context(|| format!("cannot write {}", args.out.display()))?;
    let check = if args.check { Some(check_chain(&out, &args.check_filter)?) } else { None };
    let path = args.report.clone().unwrap_or_else(|| args.out.with_extension("json"));
    let json = serde_json::json!({ "prefilter": report, "check": check });
    std::fs::write(&path, serde_json::to_string_pretty(&json)?).with_context(|| format!("cannot write {}", path.display()))?;
    println!("wrote {} and {}", args.out.display(), path.display());
    Ok(())
}
