//! `fabric diff A B`: how far image A is from reference B (docs/DESIGN.md §9):
//! relative RMSE over linear RGB, mean per-pixel relative difference, relative
//! difference of the image means, and FLIP on the sRGB(clamp(exposure·L)) 8-bit images.
//! Optionally writes the FLIP error map in false colour (magma). With thresholds
//! (`--max-flip-mean`, `--max-flip-p95`, `--max-rel-rmse`) it is a screenshot-regression
//! check: the metrics are printed as always, then one line per exceeded threshold, and
//! the exit code is non-zero if any is exceeded (docs in README, "Screenshot regression").

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use fabric_runtime::image::Image;
use fabric_runtime::metrics;

#[derive(Args, Debug)]
pub struct DiffArgs {
    /// Test image (.exr linear, or .png sRGB).
    pub a: PathBuf,
    /// Reference image, same size.
    pub b: PathBuf,
    /// Exposure of the tone mapping used for FLIP (and to undo PNG encoding).
    #[arg(long, default_value_t = 1.0)]
    pub exposure: f32,
    /// Print the metrics as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Write the FLIP error map (magma colour scale) as a PNG.
    #[arg(long)]
    pub diff_image: Option<PathBuf>,
    /// Fail (non-zero exit) if the mean FLIP exceeds this.
    #[arg(long)]
    pub max_flip_mean: Option<f32>,
    /// Fail if the 95th percentile of the per-pixel FLIP exceeds this.
    #[arg(long)]
    pub max_flip_p95: Option<f32>,
    /// Fail if the relative RMSE exceeds this.
    #[arg(long)]
    pub max_rel_rmse: Option<f64>,
    /// Also the relative RMSE over N×N blocks (both images box-filtered first), the
    /// scale at which `fabric bake` reports its held-out error (N = 4).
    #[arg(long, value_name = "N")]
    pub block: Option<u32>,
}

#[derive(serde::Serialize)]
struct Report {
    test: String,
    reference: String,
    width: u32,
    height: u32,
    relative_rmse: f64,
    /// With `--block N`: N and the relative RMSE of the N×N block means.
    #[serde(skip_serializing_if = "Option::is_none")]
    block: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    relative_rmse_blocks: Option<f64>,
    mean_relative_difference: f64,
    relative_mean_difference: f64,
    mean_test: f64,
    mean_reference: f64,
    flip_mean: f32,
    flip_p95: f32,
    flip_max: f32,
    exposure: f32,
    /// Thresholds exceeded (empty: passed, or none given).
    failures: Vec<String>,
}

pub fn run(args: DiffArgs) -> Result<()> {
    if !(args.exposure.is_finite() && args.exposure > 0.0) {
        bail!("--exposure must be a positive finite number, got {}", args.exposure);
    }
    for (flag, v) in [("--max-flip-mean", args.max_flip_mean.map(f64::from)), ("--max-flip-p95", args.max_flip_p95.map(f64::from)), ("--max-rel-rmse", args.max_rel_rmse)] {
        if let Some(v) = v
            && !(v.is_finite() && v >= 0.0)
        {
            bail!("{flag} must be a non-negative finite number, got {v}");
        }
    }
    let a = Image::read(&args.a, args.exposure).with_context(|| format!("cannot read test image {}", args.a.display()))?;
    let b = Image::read(&args.b, args.exposure).with_context(|| format!("cannot read reference image {}", args.b.display()))?;
    let what = || format!("comparing {} with {}", args.a.display(), args.b.display());
    let flip = metrics::flip(&a, &b, args.exposure).with_context(what)?;
    let relative_rmse_blocks = match args.block {
        None => None,
        Some(n) if n == 0 || n > a.width.min(a.height) => bail!("--block {n}: a block must be 1 to {} pixels (the image's smaller side)", a.width.min(a.height)),
        Some(n) => Some(metrics::relative_rmse(&a.box_downsample(n), &b.box_downsample(n)).with_context(what)?),
    };
    let report = Report {
        test: args.a.display().to_string(),
        reference: args.b.display().to_string(),
        width: a.width,
        height: a.height,
        relative_rmse: metrics::relative_rmse(&a, &b).with_context(what)?,
        block: args.block,
        relative_rmse_blocks,
        mean_relative_difference: metrics::mean_relative_difference(&a, &b).with_context(what)?,
        relative_mean_difference: metrics::relative_mean_difference(&a, &b).with_context(what)?,
        mean_test: a.mean(),
        mean_reference: b.mean(),
        flip_mean: flip.mean,
        flip_p95: flip.p95,
        flip_max: flip.max,
        exposure: args.exposure,
        failures: Vec::new(),
    };
    let mut report = report;
    if let Some(m) = args.max_flip_mean
        && report.flip_mean > m
    {
        report.failures.push(format!("FLIP mean {:.5} > --max-flip-mean {m}", report.flip_mean));
    }
    if let Some(m) = args.max_flip_p95
        && report.flip_p95 > m
    {
        report.failures.push(format!("FLIP p95 {:.5} > --max-flip-p95 {m}", report.flip_p95));
    }
    if let Some(m) = args.max_rel_rmse
        && report.relative_rmse > m
    {
        report.failures.push(format!("relative RMSE {:.6} > --max-rel-rmse {m}", report.relative_rmse));
    }
    if let Some(path) = &args.diff_image {
        if path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()) != Some("png".into()) {
            bail!("--diff-image {}: the error map is written as PNG; use a .png name", path.display());
        }
        let rgb = flip.error_map_rgb8();
        let decoded: Vec<glam::Vec3> = rgb.chunks_exact(3).map(|c| glam::Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32) / 255.0).map(|c| c.to_array().map(fabric_runtime::image::srgb_decode).into()).collect();
        Image { width: flip.width, height: flip.height, pixels: decoded }.write(path, 1.0).with_context(|| format!("cannot write {}", path.display()))?;
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!("{} vs reference {} ({}x{})", report.test, report.reference, report.width, report.height);
        println!("  relative RMSE               {:.6}", report.relative_rmse);
        if let (Some(n), Some(e)) = (report.block, report.relative_rmse_blocks) {
            println!("  {:<28}{e:.6}", format!("... over {n}x{n} blocks"));
        }
        println!("  mean relative difference    {:.6}", report.mean_relative_difference);
        println!("  relative difference of means {:+.6} (means {:.6} vs {:.6})", report.relative_mean_difference, report.mean_test, report.mean_reference);
        println!("  FLIP (exposure {})          mean {:.5}, p95 {:.5}, max {:.5}", report.exposure, report.flip_mean, report.flip_p95, report.flip_max);
        if let Some(p) = &args.diff_image {
            println!("wrote {}", p.display());
        }
    }
    let thresholds = args.max_flip_mean.is_some() || args.max_flip_p95.is_some() || args.max_rel_rmse.is_some();
    if !report.failures.is_empty() {
        bail!("{} differs from {} beyond the thresholds: {}", report.test, report.reference, report.failures.join("; "));
    }
    if thresholds {
        println!("PASS: within the thresholds");
    }
    Ok(())
}
