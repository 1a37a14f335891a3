//! `fabric inspect PATH`: what a fabric directory or a single `.vol` grid holds:
//! dimensions, bounding box, value ranges, filled fraction and an estimate of the
//! flyaway voxels; `--json` for machines.
//!
//! Dispatch is by what PATH is, so other file kinds (hybrid models, `*.hyb`) plug in
//! as one more arm of [`run`].

use std::path::Path;

use anyhow::{Result, bail};
use clap::Args;
use fabric_baker::volume::stats::{FabricStats, GridStats, Range, fabric_stats, grid_stats};
use fabric_baker::volume::{self, MaterialFile};
use indicatif::{ProgressBar, ProgressStyle};

use crate::args::MaterialArgs;

#[derive(Args, Debug)]
pub struct InspectArgs {
    /// A fabric directory (density.vol, albedo.vol, orientation.vol), one .vol file, or a
    /// hybrid model (.hyb).
    pub path: std::path::PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Fiber thickness in voxels for the flyaway estimate (runs longer than this are
    /// surface). Default: the generator's record in material.toml, else 3.
    #[arg(long)]
    pub fiber_voxels: Option<f32>,
    #[command(flatten)]
    pub material: MaterialArgs,
}

pub fn run(args: InspectArgs) -> Result<()> {
    let p = args.path.as_path();
    let ext = p.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    if p.is_dir() {
        inspect_fabric(&args)
    } else {
        match ext.as_deref() {
            Some("vol") => inspect_vol(&args),
            Some("hyb") => super::inspect_model::run(p, args.json),
            _ if !p.exists() => bail!("{}: no such file or directory", p.display()),
            _ => bail!("{}: cannot inspect this (expected a fabric directory, a .vol file or a .hyb model)", p.display()),
        }
    }
}

/// The fiber thickness the flyaway estimate uses, and where it came from.
fn fiber_voxels(args: &InspectArgs) -> Result<(f32, &'static str)> {
    if let Some(v) = args.fiber_voxels {
        if !(v.is_finite() && v > 0.0) {
            bail!("--fiber-voxels {v} must be a positive number");
        }
        return Ok((v, "--fiber-voxels"));
    }
    let m = MaterialFile::read_or_default(&args.path.join(volume::MATERIAL_FILE))?;
    let recorded = m.generator.as_ref().and_then(|g| g.get("fiber_diameter_voxels")).and_then(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)));
    Ok(match recorded {
        Some(v) if v > 0.0 => (v as f32, "material.toml [generator]"),
        _ => (3.0, "assumed"),
    })
}

fn inspect_fabric(args: &InspectArgs) -> Result<()> {
    let overrides = args.material.overrides()?;
    let (fiber, source) = fiber_voxels(args)?;
    let pb = if args.json { ProgressBar::hidden() } else { ProgressBar::new(0) };
    pb.set_style(ProgressStyle::with_template("      load [{bar:40}] {pos}/{len} slabs {elapsed_precise}").unwrap_or_else(|_| ProgressStyle::default_bar()).progress_chars("=> "));
    let vol = volume::load_fabric_with_progress(&args.path, &overrides, &pb)?;
    if let Some(note) = fabric_baker::volume::material_defaults_note(&args.path, &overrides) {
        eprintln!("{note}");
    }
    pb.finish_and_clear();
    // A run longer than one fiber (its diameter plus the partial-volume rim) is surface.
    let min_run = fiber.ceil() as usize + 1;
    let s = fabric_stats(&vol, min_run);
    if args.json {
        let mut v = serde_json::to_value(&s)?;
        v["path"] = args.path.display().to_string().into();
        v["fiber_voxels"] = serde_json::json!({ "value": fiber, "source": source });
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    print_fabric(&args.path, &s, fiber, source);
    Ok(())
}

fn fmt_range(r: &Range) -> String {
    if r.count == 0 { "(none)".into() } else { format!("{:.4} … {:.4} (mean {:.4})", r.min, r.max, r.mean) }
}

fn print_fabric(path: &Path, s: &FabricStats, fiber: f32, source: &str) {
    let [x, y, z] = s.dims;
    println!("{}: fabric {x}x{y}x{z}", path.display());
    println!("  bounding box  {:?} … {:?}", s.bbox_min, s.bbox_max);
    println!("  voxel size    {:?}", s.voxel_size);
    println!("  material      density_scale {}, roughness {}", s.density_scale, s.roughness);
    println!("  filled        {} voxels, {:.2} %", s.filled_voxels, 100.0 * s.filled_fraction);
    println!("  density       {}", fmt_range(&s.density));
    for (c, name) in ["albedo R", "albedo G", "albedo B"].iter().enumerate() {
        println!("  {name:<13} {}", fmt_range(&s.albedo[c]));
    }
    println!("  |ω_f| x y z   mean {:.3} {:.3} {:.3}", s.orientation_abs[0].mean, s.orientation_abs[1].mean, s.orientation_abs[2].mean);
    let sf = &s.surface;
    let columns = (x * y) as f64;
    println!(
        "  surface       {:.1} % of columns, height {} cells (runs > {} voxels; fiber {fiber} voxels, {source})",
        100.0 * sf.surface_columns as f64 / columns,
        fmt_range(&sf.surface_height),
        sf.min_run
    );
    println!(
        "  flyaways      ~{} voxels ({:.2} % of filled) in {:.1} % of columns",
        sf.flyaway_voxels,
        100.0 * sf.flyaway_voxels as f64 / s.filled_voxels.max(1) as f64,
        100.0 * sf.flyaway_columns as f64 / columns
    );
    println!("  memory        {:.1} MiB packed", s.memory_bytes as f64 / 1048576.0);
}

fn inspect_vol(args: &InspectArgs) -> Result<()> {
    let reader = volume::VolReader::open(&args.path)?;
    let header = reader.header;
    drop(reader);
    let grid = volume::read_vol(&args.path)?;
    let s = grid_stats(&grid);
    if args.json {
        let mut v = serde_json::to_value(&s)?;
        v["path"] = args.path.display().to_string().into();
        v["encoding"] = header.encoding.name().into();
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    print_grid(&args.path, header.encoding.name(), &s);
    Ok(())
}

fn print_grid(path: &Path, encoding: &str, s: &GridStats) {
    let [x, y, z] = s.dims;
    println!("{}: grid {x}x{y}x{z}, {} channel(s), {encoding}", path.display(), s.channels);
    println!("  bounding box  {:?} … {:?}", s.bbox_min, s.bbox_max);
    for (c, r) in s.channel.iter().enumerate() {
        println!("  channel {c}     {}", fmt_range(r));
    }
    println!("  non-zero      {} voxels, {:.2} %", s.nonzero_voxels, 100.0 * s.nonzero_fraction);
    if let Some(l) = &s.length {
        println!("  |v| non-zero  {}", fmt_range(l));
    }
    if s.non_finite > 0 {
        println!("  NON-FINITE    {} values", s.non_finite);
    }
}
