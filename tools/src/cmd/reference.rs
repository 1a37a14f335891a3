//! `fabric reference DIR`: path-traces the input fabric volume (the ground truth every
//! accuracy figure is measured against) and prints paths per second.
//!
//! The scene flags follow Mitsuba 3's conventions (docs/DESIGN.md §8; the mapping
//! to a Mitsuba scene is written out in tools/scripts/mitsuba_compare.py), so any image
//! can be reproduced there.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use fabric_baker::reference::{Lighting, Lookup, MediumOptions, PathSettings, RenderSettings, TracedMedium, render};
use fabric_baker::volume::load_fabric_with_progress;
use glam::Vec3;
use indicatif::{ProgressBar, ProgressStyle};

use crate::args::{CameraArgs, EnvArgs, LightArgs, MaterialArgs, OutputArgs};

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum LookupArg {
    /// Trilinear interpolation of ρ, α and S between voxel centres (Mitsuba's default).
    Trilinear,
    /// The value of the containing voxel.
    Nearest,
}

#[derive(Args, Debug)]
pub struct ReferenceArgs {
    /// Fabric directory (density.vol, albedo.vol, orientation.vol, material.toml).
    pub dir: PathBuf,
    /// Samples (paths) per pixel.
    #[arg(long, default_value_t = 64)]
    pub spp: u32,
    /// Voxel lookup.
    #[arg(long, value_enum, default_value = "trilinear")]
    pub lookup: LookupArg,
    /// Longest path, Mitsuba's max_depth: 2 = single scattering; default unlimited.
    #[arg(long)]
    pub max_depth: Option<u32>,
    /// Scatterings before Russian roulette starts (Mitsuba's rr_depth).
    #[arg(long, default_value_t = 5)]
    pub rr_depth: u32,
    /// Treat the sample as an infinite sheet tiling in x and y (otherwise the medium
    /// ends at its bounding box, as Mitsuba renders it).
    #[arg(long)]
    pub periodic: bool,
    /// Random seed; the same seed gives the same image for any thread count. (0 here;
    /// `gen`, `bake` and the others default to 1, a different stream.)
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    #[command(flatten)]
    pub material: MaterialArgs,
    /// Majorant grid block in voxels, BXxBYxBZ.
    #[arg(long, value_parser = parse_block, default_value = "4x4x4")]
    pub block: [usize; 3],
    /// Print the run's figures as one JSON line (for scripts and benchmarks).
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub camera: CameraArgs,
    #[command(flatten)]
    pub light: LightArgs,
    #[command(flatten)]
    pub env: EnvArgs,
    #[command(flatten)]
    pub output: OutputArgs,
}

fn parse_block(s: &str) -> Result<[usize; 3], String> {
    let v: Vec<usize> = s.split(['x', 'X']).map(|p| p.trim().parse::<usize>().map_err(|e| format!("'{p}' in '{s}': {e}"))).collect::<Result<_, _>>()?;
    match v.as_slice() {
        [x, y, z] if (1..=256).contains(x) && (1..=256).contains(y) && (1..=256).contains(z) => Ok([*x, *y, *z]),
        _ => Err(format!("expected BXxBYxBZ with each in 1..=256, got '{s}'")),
    }
}

#[derive(serde::Serialize)]
struct RunReport {
    dims: [usize; 3],
    width: u32,
    height: u32,
    spp: u32,
    threads: usize,
    load_seconds: f64,
    setup_seconds: f64,
    render_seconds: f64,
    paths: u64,
    paths_per_second: f64,
    scatterings_per_path: f64,
    truncated_walks: u64,
    mean: f64,
}

pub fn run(args: ReferenceArgs) -> Result<()> {
    if !(args.output.exposure.is_finite() && args.output.exposure > 0.0) {
        bail!("--exposure must be a positive finite number, got {}", args.output.exposure);
    }
    let threads = args.threads.unwrap_or_else(|| std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1));
    if !(1..=crate::args::MAX_THREADS).contains(&threads) {
        bail!("--threads {threads}: must be in 1..={}", crate::args::MAX_THREADS);
    }
    if !(1..=crate::args::MAX_SPP).contains(&args.spp) {
        bail!("--spp {}: samples per pixel must be in 1..={}", args.spp, crate::args::MAX_SPP);
    }
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().context("cannot start worker threads")?;
    pool.install(|| run_in_pool(&args, threads))
}

fn run_in_pool(args: &ReferenceArgs, threads: usize) -> Result<()> {
    let t_load = Instant::now();
    let load_bar = if args.json { ProgressBar::hidden() } else { ProgressBar::new(0) };
    let overrides = args.material.overrides()?;
    let volume = load_fabric_with_progress(&args.dir, &overrides, &load_bar).with_context(|| format!("cannot load fabric {}", args.dir.display()))?;
    if let Some(note) = fabric_baker::volume::material_defaults_note(&args.dir, &overrides) {
        eprintln!("{note}");
    }
    load_bar.finish_and_clear();
    let load_seconds = t_load.elapsed().as_secs_f64();
    let camera = args.camera.camera(volume.bbox())?;
    let env = args.env.env_map()?;
    // With a map, the delta light is there only when asked for.
    let light = if env.is_none() || args.light.given() { Some(args.light.light()?) } else { None };
    let lighting = Lighting { light: light.as_ref(), env: env.as_ref(), background: !args.env.no_background };
    let lookup = match args.lookup {
        LookupArg::Trilinear => Lookup::Trilinear,
        LookupArg::Nearest => Lookup::Nearest,
    };
    let t_setup = Instant::now();
    let medium = TracedMedium::with_block(&volume, MediumOptions { lookup, periodic: args.periodic, ..Default::default() }, args.block).with_context(|| format!("cannot path-trace {}", args.dir.display()))?;
    let setup_seconds = t_setup.elapsed().as_secs_f64();
    let settings = RenderSettings { spp: args.spp, seed: args.seed, path: PathSettings { max_depth: args.max_depth, rr_depth: args.rr_depth } };
    settings.validate()?;
    let dims = volume.dims();
    if !args.json {
        println!(
            "{}: {}x{}x{} voxels ({:.1} MB packed), density scale {}, roughness {}; majorant grid {:?} cells of {:?} voxels; {} lookup{}",
            args.dir.display(),
            dims[0],
            dims[1],
            dims[2],
            volume.memory_bytes() as f64 / 1e6,
            volume.material.density_scale,
            volume.material.roughness,
            medium.majorants.cells(),
            medium.majorants.block(),
            format!("{:?}", args.lookup).to_lowercase(),
            if args.periodic { ", periodic sheet" } else { "" }
        );
        if let Some(env) = &env {
            println!("environment {} ({}x{}, scale {}, rotated {}°, ∫L dΩ = {:.4}){}", env.name().display(), env.width(), env.height(), args.env.envmap_scale, args.env.envmap_rotate, env.integral().dot(Vec3::ONE) / 3.0, if light.is_some() { " plus the delta light" } else { "" });
        }
    }
    let progress = if args.json { ProgressBar::hidden() } else { ProgressBar::new(camera.height as u64) };
    progress.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} rows, {elapsed} elapsed, ETA {eta}").unwrap_or_else(|_| ProgressStyle::default_bar()));
    let (image, stats) = render(&medium, &camera, &lighting, &settings, Some(&progress))?;
    progress.finish_and_clear();
    image.write(&args.output.out, args.output.exposure).with_context(|| format!("cannot write {}", args.output.out.display()))?;
    let report = RunReport {
        dims,
        width: camera.width,
        height: camera.height,
        spp: args.spp,
        threads,
        load_seconds,
        setup_seconds,
        render_seconds: stats.seconds,
        paths: stats.paths.paths,
        paths_per_second: stats.paths_per_second(),
        scatterings_per_path: stats.paths.scatterings as f64 / stats.paths.paths.max(1) as f64,
        truncated_walks: stats.paths.truncated,
        mean: image.mean(),
    };
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        println!(
            "{}x{} at {} spp: {} paths in {:.2} s on {} threads = {:.0} paths/s ({:.2} scatterings per path); load {:.2} s, majorants {:.3} s; image mean {:.6}",
            report.width, report.height, report.spp, report.paths, report.render_seconds, threads, report.paths_per_second, report.scatterings_per_path, load_seconds, setup_seconds, report.mean
        );
        if report.truncated_walks > 0 {
            println!("warning: {} walks stopped at the DDA step limit (rays grazing an almost empty layer of the sheet)", report.truncated_walks);
        }
        println!("wrote {}", args.output.out.display());
    }
    Ok(())
}
