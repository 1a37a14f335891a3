//! `fabric demo`: the main job on a built-in default, in one command — generate a
//! fabric volume, bake it into a hybrid model (with its mip chain and held-out views),
//! path-trace a reference view, draw the model at the same view on the GPU (and on a
//! sphere), and print and write what was measured: bake time, model size against the
//! volume, held-out error, error of the demo view, GPU frame time.
//!
//! The stages run as the `fabric` subcommands they are (`gen`, `bake`, `reference`),
//! so their own progress and reports appear as they would; the drawing and comparison
//! run here. Everything lands in `--out` (default `out/`), with `report.md` last.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, Result, bail};
use clap::Args;
use fabric_runtime::cpu::{CpuRenderOptions, ShadowMode, render};
use fabric_runtime::gpu::HybridPass;
use fabric_runtime::hybrid::format::read_file;
use fabric_runtime::image::Image;
use fabric_runtime::metrics;
use fabric_runtime::scene::{Camera, Light, Mesh, Projection, direction_from_angles};
use glam::{Vec2, Vec3};

#[derive(Args, Debug)]
pub struct DemoArgs {
    /// Fabric preset to generate.
    #[arg(long, default_value = "twill", value_parser = ["plain", "twill", "satin", "silk", "felt"])]
    pub preset: String,
    /// Volume size in voxels (X x Y x Z).
    #[arg(long, default_value = "96x96x24")]
    pub size: String,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Samples per pixel of the reference view.
    #[arg(long, default_value_t = 128)]
    pub spp: u32,
    /// Where everything is written.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
}

/// Runs `fabric ARGS…` (this executable), failing with its name if it fails.
fn fabric(args: &[&str]) -> Result<()> {
    let exe = std::env::current_exe().context("cannot find the fabric executable")?;
    println!("\n$ fabric {}", args.join(" "));
    let status = Command::new(exe).args(args).status().with_context(|| format!("cannot run fabric {}", args[0]))?;
    if !status.success() {
        bail!("fabric {} failed ({status})", args[0]);
    }
    Ok(())
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap_or("out")
}

/// A and B side by side with a 4-pixel black gap.
fn side_by_side(a: &Image, b: &Image) -> Image {
    Image::from_fn(a.width + 4 + b.width, a.height.max(b.height), |x, y| {
        if x < a.width && y < a.height {
            a.get(x, y)
        } else if x >= a.width + 4 && y < b.height {
            b.get(x - a.width - 4, y)
        } else {
            Vec3::ZERO
        }
    })
}

pub fn run(args: DemoArgs) -> Result<()> {
    if args.spp == 0 {
        bail!("--spp must be at least 1");
    }
    std::fs::create_dir_all(&args.out).with_context(|| format!("cannot create {}", args.out.display()))?;
    let p = args.preset.as_str();
    let volume = args.out.join(p);
    let model_path = args.out.join(format!("{p}.hyb"));
    let report_path = args.out.join(format!("{p}-bake.json"));
    let seed = args.seed.to_string();
    let spp = args.spp.to_string();
    // The demo view, the same for the reference and the model: 30° from the normal, the
    // light 40° on the other side.
    let view = ["--periodic", "--view-angles", "30,20", "--light-angles", "40,200", "--size", "256x256"];
    let start = std::time::Instant::now();
    fabric(&["gen", "--preset", p, "--size", &args.size, "--seed", &seed, "--out", path(&volume)])?;
    fabric(&["bake", path(&volume), "--out", path(&model_path), "--report", path(&report_path), "--seed", &seed])?;
    let reference_path = args.out.join(format!("{p}-reference.exr"));
    let t = std::time::Instant::now();
    let mut reference_args = vec!["reference", path(&volume), "--spp", &spp, "--out", path(&reference_path)];
    reference_args.extend(view);
    fabric(&reference_args)?;
    let reference_seconds = t.elapsed().as_secs_f64();

    println!("\n== drawing the model");
    let model = read_file(&model_path)?;
    let bounds = model.bounds();
    let top = Vec3::new(bounds.center().x, bounds.center().y, bounds.max.z);
    let camera = Camera::orbit_orthographic(30.0, 20.0, top, bounds.size().length() + 1.0, bounds.size().x, 256, 256);
    let light = Light::directional(direction_from_angles(40.0, 200.0), Vec3::ONE);
    let options = CpuRenderOptions { periodic: true, shadows: ShadowMode::FromModel, ..Default::default() };
    let device = fabric_runtime::vk::Device::new(&fabric_runtime::vk::DeviceOptions::default());
    let (hybrid, gpu_line, sphere) = match device {
        Ok(device) => {
            let pass = HybridPass::new(&device)?;
            let g = pass.upload(&model, true)?;
            let _ = pass.render(&g, &camera, &[light], &options, None)?; // the shader compile
            let mut times = Vec::new();
            let mut frame = None;
            for _ in 0..3 {
                let f = pass.render(&g, &camera, &[light], &options, None)?;
                times.push(f.gpu_ms);
                frame = Some(f);
            }
            times.sort_by(f64::total_cmp);
            let sphere_cam = Camera { origin: Vec3::new(0.0, -3.2, 1.6), target: Vec3::ZERO, up: Vec3::Z, projection: Projection::Perspective { fov_x_deg: 40.0 }, width: 512, height: 512 };
            let sphere = pass.render_mesh(&g, &Mesh::sphere(1.0, 128, 64), Vec2::new(12.0, 6.0), &sphere_cam, &[light], &options, None)?;
            let mut line = format!("GPU frame time {:.2} ms at 256x256 (median of 3) on {} ({}); on a sphere at 512x512 {:.2} ms", times[1], device.info().name, device.info().kind, sphere.gpu_ms);
            // Pixels the driver's loop budget cut short (lavapipe) are drawn wrong: said.
            let cut = frame.as_ref().map_or(0, |f| f.stats.loop_cut_pixels) + sphere.stats.loop_cut_pixels;
            if cut > 0 {
                line += &format!("; {cut} pixel(s) past the driver's loop budget, drawn wrong (runtime/GPU_MEASUREMENTS.md, \"lavapipe's loop budget\")");
            }
            (frame.context("three frames")?.image, line, Some(sphere.image))
        }
        Err(e) => {
            println!("note: no Vulkan device ({e}); drawing with the CPU renderer");
            let t = std::time::Instant::now();
            let image = render(&model, &camera, &[light], &options)?;
            (image, format!("CPU renderer {:.1} ms at 256x256 (no Vulkan device)", t.elapsed().as_secs_f64() * 1e3), None)
        }
    };
    let reference = Image::read(&reference_path, 1.0)?;
    let rmse = metrics::relative_rmse(&hybrid, &reference)?;
    // Mid-grey at the reference's mean: sparkles saturate, the weave stays readable.
    let exposure = (0.4 / reference.mean().max(1e-9) as f32).clamp(1e-3, 1e3);
    let flip = metrics::flip(&hybrid, &reference, exposure)?;
    let pair_path = args.out.join(format!("{p}-reference-vs-hybrid.png"));
    side_by_side(&reference, &hybrid).write(&pair_path, exposure)?;
    hybrid.write(&args.out.join(format!("{p}-hybrid.exr")), 1.0)?;
    if let Some(s) = &sphere {
        s.write(&args.out.join(format!("{p}-sphere.png")), exposure)?;
    }

    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report_path)?).context("the bake report")?;
    let bake = &report["bake"];
    let model_bytes = std::fs::metadata(&model_path)?.len();
    let input_bytes = bake["input_bytes"].as_u64().unwrap_or(0);
    let of = |key: &str| -> Vec<f64> {
        let mut v: Vec<f64> = report["held_out"].as_array().map(|v| v.iter().filter_map(|h| h[key].as_f64()).collect()).unwrap_or_default();
        v.sort_by(f64::total_cmp);
        v
    };
    let (held, blocks, turned) = (of("pixel_error"), of("block_error"), of("light_turned_error"));
    let spread = |v: &[f64]| match (v.first(), v.last()) {
        (Some(lo), Some(hi)) => format!("median {:.1}%, range {:.1}–{:.1}%", 100.0 * v[v.len() / 2], 100.0 * lo, 100.0 * hi),
        _ => "not measured".to_string(),
    };
    let held_line = if held.is_empty() {
        "no held-out views".to_string()
    } else {
        let mut l = format!("held-out views ({}): relative RMSE per pixel {}; over 4×4 blocks {}", held.len(), spread(&held), spread(&blocks));
        if !turned.is_empty() {
            // The yardstick (`fabric bake --held-out-turn`): what a small error of angle costs.
            let deg = report["held_out"][0]["light_turn_deg"].as_f64().unwrap_or(f64::NAN);
            l += &format!(" (yardstick: the reference lit {deg:.0}° off differs from itself by {} over the same blocks)", spread(&turned));
        }
        l
    };
    let lines = [
        format!("fabric demo: {p}, {} voxels, seed {}", args.size, args.seed),
        format!("bake: {:.0} s; model {:.2} MB from a {:.2} MB volume ({:.1}x smaller)", bake["total_seconds"].as_f64().unwrap_or(f64::NAN), model_bytes as f64 / 1e6, input_bytes as f64 / 1e6, input_bytes as f64 / model_bytes.max(1) as f64),
        held_line,
        format!("demo view (30°, light 40°): relative RMSE {:.1}%, FLIP mean {:.3} against the reference at {} spp ({:.0} s)", 100.0 * rmse, flip.mean, args.spp, reference_seconds),
        gpu_line,
        format!("total {:.0} s; images and reports in {}", start.elapsed().as_secs_f64(), args.out.display()),
    ];
    println!("\n== summary");
    for l in &lines {
        println!("{l}");
    }
    let mut md = String::from("# fabric demo\n\n");
    for l in &lines {
        md.push_str(&format!("- {l}\n"));
    }
    md.push_str(&format!("\n![reference | hybrid]({p}-reference-vs-hybrid.png)\n"));
    if sphere.is_some() {
        md.push_str(&format!("\n![the model on a sphere]({p}-sphere.png)\n"));
    }
    md.push_str(&format!("\nHeld-out views (reference | model | 4x error): `{p}-views/`. Bake report: `{p}-bake.json`.\n"));
    std::fs::write(args.out.join("report.md"), md)?;
    println!("wrote {}", args.out.join("report.md").display());
    Ok(())
}
