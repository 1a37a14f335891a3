//! `fabric gen`: generate a procedural fabric volume and write it as a fabric
//! directory (density.vol, albedo.vol, orientation.vol, material.toml, previews).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use fabric_baker::generate::{self, GeneratorParams, Preset, preview};
use fabric_baker::volume::{self, SaveEncoding, SaveOptions};
use indicatif::{ProgressBar, ProgressStyle};

use crate::args::{MaterialArgs, parse_dims};

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum EncodingArg {
    /// float32 everywhere (what Mitsuba 3 reads).
    Float32,
    /// uint8 density and albedo, quantized directions (Mitsuba 0.5's compact encodings).
    Compact,
}

#[derive(Args, Debug)]
pub struct GenArgs {
    /// Preset: plain, twill, satin, silk (charmeuse) or felt.
    #[arg(long, default_value = "twill")]
    pub preset: Preset,
    /// Volume size in voxels, XxYxZ.
    #[arg(long, value_parser = parse_dims, default_value = "256x256x48")]
    pub size: [usize; 3],
    /// Random seed: the same seed gives a bit-identical volume.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output directory (created if missing).
    #[arg(long, short, required_unless_present_any = ["bench", "print_params"])]
    pub out: Option<PathBuf>,
    /// Override a generator parameter, KEY=VALUE in TOML syntax (repeatable), e.g.
    /// `--set fabric.yarn.plies=3 --set 'fabric.warp_colors=[[0.8,0.2,0.2]]'`.
    /// `--print-params` lists the keys.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Parameters over the preset's: a TOML table of generator parameters, or a
    /// material.toml whose [generator.params] table is used.
    #[arg(long, value_name = "FILE")]
    pub params: Option<PathBuf>,
    #[command(flatten)]
    pub material: MaterialArgs,
    /// How the .vol files are encoded.
    #[arg(long, value_enum, default_value = "float32")]
    pub encoding: EncodingArg,
    /// Skip the preview PNGs.
    #[arg(long)]
    pub no_previews: bool,
    /// Print the resolved parameters as TOML and exit.
    #[arg(long)]
    pub print_params: bool,
    /// Benchmark: generate without writing, then print timings and peak memory.
    #[arg(long)]
    pub bench: bool,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

fn resolve_params(args: &GenArgs) -> Result<GeneratorParams> {
    let mut p = args.preset.params();
    if let Some(path) = &args.params {
        let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
        let table: toml::Table = toml::from_str(&text).with_context(|| format!("{}: not TOML", path.display()))?;
        let params = match table.get("generator").and_then(|g| g.get("params")) {
            Some(toml::Value::Table(t)) => t.clone(),
            Some(_) => bail!("{}: [generator.params] is not a table", path.display()),
            None => table,
        };
        p.merge(&params).with_context(|| format!("{}", path.display()))?;
    }
    for s in &args.set {
        p.set(s).with_context(|| format!("--set {s}"))?;
    }
    if let Some(r) = args.material.roughness {
        p.material.roughness = r;
    }
    p.validate()?;
    Ok(p)
}

fn bar(len: u64, what: &str) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(ProgressStyle::with_template("{msg:>10} [{bar:40}] {pos}/{len} {elapsed_precise} eta {eta}").unwrap_or_else(|_| ProgressStyle::default_bar()).progress_chars("=> "));
    pb.set_message(what.to_string());
    pb
}

pub fn run(args: GenArgs) -> Result<()> {
    let overrides = args.material.overrides()?;
    let params = resolve_params(&args)?;
    if args.print_params {
        print!("{}", toml::to_string_pretty(&params)?);
        return Ok(());
    }
    let start = Instant::now();
    let pb = bar(0, "voxelize");
    let generated = generate::generate_with_progress(&params, args.size, args.seed, &pb)?;
    pb.finish_and_clear();
    let mut vol = generated.volume;
    if let Some(d) = overrides.density_scale {
        vol.material.density_scale = d;
    }
    let (lo, hi) = (fabric_baker::volume::material::DENSITY_SCALE_MIN, fabric_baker::volume::material::DENSITY_SCALE_MAX);
    if !(lo..=hi).contains(&vol.material.density_scale) {
        anyhow::bail!("the generated density scale {} per mm (material.fiber_optical_depth / fiber.diameter) is outside [{lo}, {hi}]", vol.material.density_scale);
    }
    let stats = generated.stats;
    let generate_seconds = start.elapsed().as_secs_f64();

    let (mut write_seconds, mut preview_seconds) = (0.0, 0.0);
    if let (false, Some(out)) = (args.bench, &args.out) {
        let t = Instant::now();
        let pb = bar(0, "write");
        let encoding = match args.encoding {
            EncodingArg::Float32 => SaveEncoding::Float32,
            EncodingArg::Compact => SaveEncoding::Compact,
        };
        let generator = generate::provenance(Some(args.preset), &params, args.size, args.seed, &stats);
        volume::save_fabric_with(&vol, out, &SaveOptions { encoding, generator: Some(generator) }, &pb)?;
        pb.finish_and_clear();
        write_seconds = t.elapsed().as_secs_f64();
        if !args.no_previews {
            let t = Instant::now();
            preview::write_previews(&vol, out)?;
            preview_seconds = t.elapsed().as_secs_f64();
        }
    }
    let peak = fabric_baker::memory::peak_rss_bytes();
    let summary = serde_json::json!({
        "preset": args.preset.name(),
        "seed": args.seed,
        "size": args.size,
        "voxel_size_mm": stats.voxel_size,
        "extent_mm": stats.extent,
        "fiber_diameter_voxels": stats.fiber_diameter_voxels,
        "warps": stats.warps,
        "wefts": stats.wefts,
        "fibers": stats.fibers,
        "flyaways": stats.hairs,
        "segments": stats.segments,
        "filled_fraction": vol.filled_fraction(),
        "density_scale": vol.material.density_scale,
        "roughness": vol.material.roughness,
        "seconds": { "curves": stats.curves_seconds, "voxelize": stats.voxelize_seconds, "generate": generate_seconds, "write": write_seconds, "previews": preview_seconds },
        "threads": rayon::current_num_threads(),
        "peak_rss_bytes": peak,
        "volume_bytes": vol.memory_bytes(),
        "out": args.out.as_ref().filter(|_| !args.bench).map(|p| p.display().to_string()),
    });
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
        return Ok(());
    }
    let [x, y, z] = args.size;
    println!("{} {x}x{y}x{z}, seed {}: voxel {:.2} µm, tile {:.3} × {:.3} × {:.3} mm", args.preset, args.seed, stats.voxel_size * 1000.0, stats.extent[0], stats.extent[1], stats.extent[2]);
    if stats.warps > 0 {
        println!("  {} warps × {} wefts", stats.warps, stats.wefts);
    }
    println!(
        "  {} fibers ({} flyaway), {} segments, fiber ⌀ {:.2} voxels, {:.1} % filled",
        stats.fibers,
        stats.hairs,
        stats.segments,
        stats.fiber_diameter_voxels,
        100.0 * vol.filled_fraction()
    );
    println!("  density_scale {:.1} per mm, roughness {}", vol.material.density_scale, vol.material.roughness);
    println!(
        "  time: curves {:.2} s, voxelize {:.2} s, write {:.2} s, previews {:.2} s ({} threads)",
        stats.curves_seconds,
        stats.voxelize_seconds,
        write_seconds,
        preview_seconds,
        rayon::current_num_threads()
    );
    if let Some(p) = peak {
        println!("  peak memory {:.0} MiB (voxels {:.0} MiB)", p as f64 / 1048576.0, vol.memory_bytes() as f64 / 1048576.0);
    }
    if let (false, Some(out)) = (args.bench, &args.out) {
        println!("  wrote {}", out.display());
    }
    Ok(())
}
