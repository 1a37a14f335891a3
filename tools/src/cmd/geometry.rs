//! `fabric geometry DIR --out OUT`: the geometric half of a hybrid model from a fabric
//! volume (paper §5.2): h0, h, normal and tangent maps, the flyaway volume V, with PNG
//! previews and `OUT/geometry.json` (filter size, fiber thickness, counts, stage times).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use fabric_baker::geometry::{DensityThreshold, FilterRule, Geometry, GeometryOptions, StageTime, extract_geometry_with, preview};
use fabric_baker::volume::{MaterialOverrides, load_fabric_with_progress};
use crate::progress::{Bars, stage_bar};

#[derive(Args, Debug)]
pub struct GeometryArgs {
    /// Fabric volume directory (density.vol, albedo.vol, orientation.vol, material.toml).
    pub dir: PathBuf,
    /// Output directory (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// One fiber's thickness in voxels [default: estimated from the isolated fibers].
    #[arg(long)]
    pub fiber_thickness: Option<f32>,
    /// Non-empty voxels have ρ above this fraction of the solid density (the 90th
    /// percentile of the positive densities).
    #[arg(long, default_value_t = 0.05)]
    pub density_threshold: f32,
    /// Non-empty voxels have ρ above this absolute density (replaces --density-threshold).
    #[arg(long)]
    pub absolute_threshold: Option<f32>,
    /// Force the filter size, in texels: S, or X,Y [default: from the autocorrelations].
    #[arg(long, value_parser = parse_filter_size)]
    pub filter_size: Option<[f32; 2]>,
    /// Use the smaller of the two autocorrelation peaks on both axes (the paper's text)
    /// instead of one per axis.
    #[arg(long)]
    pub smaller_filter: bool,
    /// Filter size for unpatterned (felt-like) input, in texels: S, or X,Y
    /// [default: 6 fiber thicknesses].
    #[arg(long, value_parser = parse_filter_size)]
    pub unpatterned_filter_size: Option<[f32; 2]>,
    /// Gaussian σ as a fraction of the filter size.
    #[arg(long, default_value_t = 1.0 / 6.0)]
    pub sigma_per_filter_size: f32,
    /// Scale of the fiber-level detail in the normal map (1 = as measured; `fabric bake
    /// --normal-detail` sets the same scale, 0.25 by default there).
    #[arg(long, default_value_t = 1.0)]
    pub detail_strength: f32,
    /// Surface voxels (from the top of each column) whose fiber axes make the tangent.
    #[arg(long, default_value_t = 3)]
    pub tangent_depth: usize,
    /// Skip the PNG previews.
    #[arg(long)]
    pub no_previews: bool,
}

fn parse_filter_size(s: &str) -> Result<[f32; 2], String> {
    let v: Vec<f32> = s.split(',').map(|p| p.trim().parse::<f32>().map_err(|e| format!("'{p}' in '{s}': {e}"))).collect::<Result<_, _>>()?;
    let size = match v.as_slice() {
        [a] => [*a, *a],
        [a, b] => [*a, *b],
        _ => return Err(format!("expected S or X,Y texels, got '{s}'")),
    };
    if !size.iter().all(|x| x.is_finite() && *x >= 0.0) {
        return Err(format!("filter size '{s}' must be non-negative numbers of texels"));
    }
    Ok(size)
}

impl GeometryArgs {
    fn options(&self) -> GeometryOptions {
        GeometryOptions {
            density_threshold: match self.absolute_threshold {
                Some(a) => DensityThreshold::Absolute(a),
                None => DensityThreshold::Relative(self.density_threshold),
            },
            fiber_thickness: self.fiber_thickness,
            filter_size: self.filter_size,
            filter_rule: if self.smaller_filter { FilterRule::Smaller } else { FilterRule::PerAxis },
            unpatterned_filter_size: self.unpatterned_filter_size,
            sigma_per_filter_size: self.sigma_per_filter_size,
            detail_strength: self.detail_strength,
            tangent_depth: self.tangent_depth,
            ..GeometryOptions::default()
        }
    }
}

pub fn run(args: GeometryArgs) -> Result<()> {
    let options = args.options();
    options.validate()?;
    if args.out.exists() && !args.out.is_dir() {
        bail!("--out {}: exists and is not a directory", args.out.display());
    }

    let start = Instant::now();
    let bar = stage_bar("load volume", 0);
    let volume = load_fabric_with_progress(&args.dir, &MaterialOverrides::default(), &bar).with_context(|| format!("cannot load the fabric volume {}", args.dir.display()))?;
    bar.finish_and_clear();
    let load_seconds = start.elapsed().as_secs_f64();
    let [nx, ny, nz] = volume.dims();
    println!("volume {}: {nx}x{ny}x{nz} voxels, voxel size {} (loaded in {load_seconds:.2} s)", args.dir.display(), volume.voxel_size());

    let progress = Bars::default();
    let mut geometry = extract_geometry_with(&volume, &options, &progress).with_context(|| format!("geometry of {}", args.dir.display()))?;
    progress.finish();
    drop(volume);
    geometry.stage_times.insert(0, StageTime { stage: "load_volume".into(), seconds: load_seconds });

    let t = Instant::now();
    let report = geometry.write_dir(&args.out, options.sigma_per_filter_size).with_context(|| format!("cannot write the geometry to {}", args.out.display()))?;
    if !args.no_previews {
        preview::write_previews(&geometry, &args.out).with_context(|| format!("cannot write the previews to {}", args.out.display()))?;
    }
    let write_seconds = t.elapsed().as_secs_f64();

    print_summary(&geometry);
    println!("wrote {} (data, {}geometry.json) in {write_seconds:.2} s", args.out.display(), if args.no_previews { "" } else { "previews, " });
    debug_assert_eq!(report.flyaway_voxels, geometry.flyaways.len());
    Ok(())
}

fn print_summary(g: &Geometry) {
    let peaks = g.autocorrelation_peaks.map(|p| p.map_or("none".to_string(), |v| format!("{v:.2}")));
    println!(
        "filter size {:.2} x {:.2} texels ({}; autocorrelation peaks x {}, y {})",
        g.filter_size[0],
        g.filter_size[1],
        if g.filter_auto { "from the autocorrelations" } else { "fixed" },
        peaks[0],
        peaks[1]
    );
    println!("fiber thickness {:.2} voxels ({})", g.fiber_thickness, if g.fiber_thickness_auto { "estimated" } else { "given or default" });
    let [lo, hi] = Geometry::range(&g.h0);
    let [slo, shi] = Geometry::range(&g.h);
    println!(
        "h0 in [{lo:.2}, {hi:.2}] voxels, h in [{slo:.2}, {shi:.2}]; {} hole columns, {} filled from their neighbours, {} clipped at the top",
        g.hole_columns, g.filled_columns, g.clipped_columns
    );
    println!("flyaway voxels {} (longest column {})", g.flyaways.len(), g.flyaways.max_column_len());
    let total: f64 = g.stage_times.iter().map(|s| s.seconds).sum();
    let times: Vec<String> = g.stage_times.iter().map(|s| format!("{} {:.3}", s.stage, s.seconds)).collect();
    println!("stage times (s): {}; total {total:.2}", times.join(", "));
    for w in &g.warnings {
        println!("warning: {w}");
    }
}
