//! `fabric bench [--suite quick|full] --out DIR`: run time against error, measured.
//!
//! Per preset: generation and bake time per stage, model size against the volume, the
//! held-out error (from the bake), the error of one reference view drawn by the GPU
//! renderer; on the first preset, GPU frame time by resolution and by distance (level),
//! and the sweeps that trade run time for error — POM step budget, level bias, K (from
//! the bake report), lobes per level (from the prefilter's one pass), flyaways on/off,
//! each skip, the reference's samples per pixel; the environment light (the built-in
//! sky) and transmission (a `--bsdf` bake lit from behind) against their references.
//! Every sweep is a CSV and a time-against-error plot (PNG and SVG); `summary.md`
//! gathers the tables and the plots and sets our figures beside the paper's Table 1.
//!
//! The stages run as `fabric gen` / `bake` / `reference` subprocesses (their logs in
//! `DIR/logs/`); the drawing runs here.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use fabric_runtime::cpu::{CpuRenderOptions, LevelChoice, ShadowMode};
use fabric_runtime::gpu::{GpuHybridModel, HybridPass, Variant};
use fabric_runtime::hybrid::HybridModel;
use fabric_runtime::hybrid::format::read_file;
use fabric_runtime::image::Image;
use fabric_runtime::metrics::relative_rmse;
use fabric_runtime::scene::{Camera, Light, direction_from_angles};
use fabric_runtime::vk::{Device, DeviceOptions};
use glam::Vec3;

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Suite {
    /// Small volumes, one bake per preset: about 15 minutes on 2 cores.
    Quick,
    /// The large sizes (128×128×32): about an hour on 2 cores.
    Full,
}

#[derive(Args, Debug)]
pub struct BenchArgs {
    #[arg(long, value_enum, default_value = "quick")]
    pub suite: Suite,
    /// Output directory (CSVs, plots, summary.md, logs).
    #[arg(long, default_value = "bench")]
    pub out: PathBuf,
    /// Presets, comma-separated (the first one also gets the sweeps).
    #[arg(long, default_value = "twill,plain,satin,silk,felt")]
    pub presets: String,
    /// Volume size instead of the suite's (X x Y x Z).
    #[arg(long)]
    pub size: Option<String>,
    /// Run the long numerical-stability and robustness run instead (`stress.rs`).
    #[arg(long)]
    pub stress: bool,
    /// BRDF inputs of the stress run (both twins).
    #[arg(long, default_value_t = 10_000_000)]
    pub stress_brdf: usize,
    /// Corrupted model files of the stress run.
    #[arg(long, default_value_t = 1_000_000)]
    pub stress_files: usize,
}

struct Plan {
    size: &'static str,
    held_out: u32,
    ref_size: u32,
    ref_spp: u32,
    resolutions: &'static [(u32, u32)],
}

fn plan(s: Suite) -> Plan {
    match s {
        Suite::Quick => Plan { size: "48x48x12", held_out: 4, ref_size: 128, ref_spp: 64, resolutions: &[(320, 180), (640, 360)] },
        Suite::Full => Plan { size: "128x128x32", held_out: 8, ref_size: 256, ref_spp: 256, resolutions: &[(640, 360), (1280, 720), (1920, 1080)] },
    }
}

/// Runs `fabric ARGS…`, its output in `log`; returns the wall time.
fn fabric(log: &Path, args: &[&str]) -> Result<f64> {
    let exe = std::env::current_exe().context("cannot find the fabric executable")?;
    let file = std::fs::File::create(log).with_context(|| format!("cannot create {}", log.display()))?;
    let t = Instant::now();
    let status = Command::new(exe).args(args).stdout(file.try_clone()?).stderr(file).status().with_context(|| format!("cannot run fabric {}", args[0]))?;
    if !status.success() {
        bail!("fabric {} failed ({status}); see {}", args.join(" "), log.display());
    }
    Ok(t.elapsed().as_secs_f64())
}

/// One row of a sweep: a label, the run time (ms or s, as the sweep says) and the error.
struct Row {
    label: String,
    time: f64,
    error: f64,
}

struct Sweep {
    name: &'static str,
    what: &'static str,
    time_unit: &'static str,
    /// What the error is measured against.
    error_of: &'static str,
    rows: Vec<Row>,
}

impl Sweep {
    /// What the sweep trades for error: run time, or (in KB) a level's size.
    fn cost(&self) -> &'static str {
        if self.time_unit == "KB" { "size" } else { "time" }
    }

    fn csv(&self) -> String {
        let mut s = format!("{},{}_{},relative_rmse\n", self.what, self.cost(), self.time_unit);
        for r in &self.rows {
            let _ = writeln!(s, "{},{:.6},{:.6}", r.label, r.time, r.error);
        }
        s
    }
}

/// The font for the plots' text: DejaVu Sans (Debian: fonts-dejavu-core), or the file
/// named by FABRIC_FONT.
fn load_font() -> Option<&'static [u8]> {
    let candidates = [std::env::var("FABRIC_FONT").ok(), Some("/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf".into()), Some("/usr/share/fonts/dejavu/DejaVuSans.ttf".into())];
    for path in candidates.into_iter().flatten() {
        if let Ok(bytes) = std::fs::read(&path) {
            return Some(Box::leak(bytes.into_boxed_slice()));
        }
    }
    None
}

fn plot<DB: plotters::prelude::DrawingBackend>(root: plotters::prelude::DrawingArea<DB, plotters::coord::Shift>, s: &Sweep) -> Result<()>
where
    DB::ErrorType: 'static,
{
    use plotters::prelude::*;
    root.fill(&WHITE).map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let t_max = s.rows.iter().map(|r| r.time).fold(0.0f64, f64::max).max(1e-9) * 1.15;
    let e_max = s.rows.iter().map(|r| r.error).fold(0.0f64, f64::max).max(1e-9) * 1.15;
    let mut chart = ChartBuilder::on(&root)
        .caption(format!("{}: {} against error", s.name, s.cost()), ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..t_max, 0.0..e_max)
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    chart.configure_mesh().x_desc(format!("{} ({})", if s.cost() == "time" { "run time" } else { "level 1's size" }, s.time_unit)).y_desc("relative RMSE").draw().map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let mut by_time: Vec<(f64, f64)> = s.rows.iter().map(|r| (r.time, r.error)).collect();
    by_time.sort_by(|a, b| a.0.total_cmp(&b.0));
    chart.draw_series(LineSeries::new(by_time, &BLUE)).map_err(|e| anyhow::anyhow!("{e:?}"))?;
    chart
        .draw_series(s.rows.iter().map(|r| EmptyElement::at((r.time, r.error)) + Circle::new((0, 0), 4, BLUE.filled()) + Text::new(r.label.clone(), (6, -14), ("sans-serif", 13))))
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    root.present().map_err(|e| anyhow::anyhow!("{e:?}"))?;
    Ok(())
}

/// Writes `NAME.csv`, and `NAME.svg` and `NAME.png` if a font is available.
fn write_sweep(dir: &Path, s: &Sweep, font: bool) -> Result<()> {
    std::fs::write(dir.join(format!("{}.csv", s.name)), s.csv())?;
    if !font || s.rows.is_empty() {
        return Ok(());
    }
    use plotters::prelude::*;
    let svg = dir.join(format!("{}.svg", s.name));
    plot(SVGBackend::new(&svg, (640, 420)).into_drawing_area(), s)?;
    let (w, h) = (640u32, 420u32);
    let mut rgb = vec![0u8; (w * h * 3) as usize];
    plot(BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area(), s)?;
    image::save_buffer(dir.join(format!("{}.png", s.name)), &rgb, w, h, image::ExtendedColorType::Rgb8).context("cannot write the plot PNG")?;
    Ok(())
}

fn median3(mut f: impl FnMut() -> Result<f64>) -> Result<f64> {
    let mut t = [f()?, f()?, f()?];
    t.sort_by(f64::total_cmp);
    Ok(t[1])
}

struct Gpu {
    device: std::sync::Arc<Device>,
    pass: HybridPass,
}

impl Gpu {
    fn frame(&self, g: &GpuHybridModel, cam: &Camera, light: &Light, opts: &CpuRenderOptions, v: Option<Variant>) -> Result<(f64, Image)> {
        self.timed(g, cam, &[*light], opts, v)
    }

    /// The image and the GPU time per frame: after a warm-up frame (the shader's
    /// compile), the median of 3 runs of frames recorded back to back, as many as fill
    /// about 0.1 s (one on a software driver). Separate frames leave a discrete GPU idle
    /// during the readback and its clocks drop: their times vary 2–4× from call to call.
    fn timed(&self, g: &GpuHybridModel, cam: &Camera, lights: &[Light], opts: &CpuRenderOptions, v: Option<Variant>) -> Result<(f64, Image)> {
        let first = self.pass.render(g, cam, lights, opts, v)?;
        let frames = (100.0 / first.gpu_ms.max(1e-3)).clamp(1.0, 200.0) as u32;
        let ms = median3(|| Ok(self.pass.render_back_to_back(g, cam, lights, opts, v, frames)?.gpu_ms))?;
        Ok((ms, first.image))
    }
}

fn view_camera(m: &HybridModel, size: u32, zoom_out: f32) -> Camera {
    let b = m.bounds();
    let top = Vec3::new(b.center().x, b.center().y, b.max.z);
    Camera::orbit_orthographic(30.0, 20.0, top, b.size().length() + 1.0, b.size().x * zoom_out, size, size)
}

pub fn run(args: BenchArgs) -> Result<()> {
    if args.stress {
        return super::stress::run(args.stress_brdf, args.stress_files);
    }
    let mut p = plan(args.suite);
    let size_override = args.size.clone();
    if let Some(s) = &size_override {
        p.size = Box::leak(s.clone().into_boxed_str());
    }
    let presets: Vec<&str> = args.presets.split(',').map(str::trim).filter(|s| !s.is_empty()).collect();
    if presets.is_empty() {
        bail!("--presets names none");
    }
    let logs = args.out.join("logs");
    std::fs::create_dir_all(&logs).with_context(|| format!("cannot create {}", logs.display()))?;
    let font = load_font();
    if let Some(f) = font {
        plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, f).map_err(|_| anyhow::anyhow!("the plot font cannot be read"))?;
    } else {
        println!("note: no font found (install fonts-dejavu-core, or set FABRIC_FONT to a .ttf): CSVs and summary only, no plots");
    }
    let device = Device::new(&DeviceOptions::default()).context("fabric bench draws with the GPU renderer: cannot open a Vulkan device")?;
    let gpu = Gpu { pass: HybridPass::new(&device)?, device };
    let info = gpu.device.info().clone();
    println!("fabric bench --suite {:?}: presets {}, volumes {}, on {} ({})", args.suite, presets.join(","), p.size, info.name, info.kind);
    let light = Light::directional(direction_from_angles(40.0, 200.0), Vec3::ONE);
    let opts = CpuRenderOptions { periodic: true, shadows: ShadowMode::FromModel, ..Default::default() };
    // The reference view's camera, and its light (the sky's view takes the camera alone).
    let ref_camera = ["--periodic", "--view-angles", "30,20"];
    let ref_view: Vec<&str> = ref_camera.iter().copied().chain(["--light-angles", "40,200"]).collect();
    let ref_size = format!("{0}x{0}", p.ref_size);
    let res_heads: String = p.resolutions.iter().map(|(w, h)| format!(" GPU ms {w}x{h} |")).collect();
    let res_rule: String = p.resolutions.iter().map(|_| "---|").collect();
    let mut table = format!("| preset | generate (s) | bake (s) | training renders (s) | fitting (s) | flyaways (s) | prefilter (s) | reference view (s) | volume (MB) | model (MB) | held-out RMSE (median) | held-out over 4×4 blocks (median) | yardstick: reference lit 5° off (median) | reference view RMSE | reference view FLIP |{res_heads}\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|{res_rule}\n");
    let mut sweeps: Vec<Sweep> = Vec::new();
    // For the comparison with the paper: frame times, sizes, bake and reference times.
    let (mut frame_ms, mut sizes, mut bakes, mut refs) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut speed = String::new();
    for (pi, preset) in presets.iter().enumerate() {
        let vol = args.out.join(preset);
        let model_path = args.out.join(format!("{preset}.hyb"));
        let report_path = args.out.join(format!("{preset}-bake.json"));
        let t_gen = fabric(&logs.join(format!("{preset}-gen.log")), &["gen", "--preset", preset, "--size", p.size, "--seed", "1", "--out", vol.to_str().unwrap_or("vol")])?;
        let held = p.held_out.to_string();
        // K doubled from 4 to the default's K with no early stop: the rounds are the K
        // sweep below, and the last, the default's K, is the model (the error fell at
        // every doubling where measured: baker/FIT_MEASUREMENTS.md, "How many clusters").
        let t_bake = fabric(&logs.join(format!("{preset}-bake.log")), &["bake", vol.to_str().unwrap_or("vol"), "--out", model_path.to_str().unwrap_or("m.hyb"), "--report", report_path.to_str().unwrap_or("r.json"), "--held-out", &held, "--k-min", "4", "--min-gain", "0"])?;
        let ref_path = args.out.join(format!("{preset}-reference.exr"));
        let spp = p.ref_spp.to_string();
        let mut ra = vec!["reference", vol.to_str().unwrap_or("vol"), "--spp", &spp, "--size", &ref_size, "--out", ref_path.to_str().unwrap_or("r.exr")];
        ra.extend(&ref_view);
        let t_ref = fabric(&logs.join(format!("{preset}-reference.log")), &ra)?;
        let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report_path)?).context("the bake report")?;
        let bake = &report["bake"];
        let stage = |name: &str| bake["stage_seconds"].as_array().and_then(|a| a.iter().find(|s| s[0] == name)).and_then(|s| s[1].as_f64()).unwrap_or(0.0);
        // The held-out views per pixel and over 4×4 blocks, and the yardstick the bake
        // measured beside them (the reference lit 5° off against itself).
        let median_of = |key: &str| {
            let mut v: Vec<f64> = report["held_out"].as_array().map(|v| v.iter().filter_map(|h| h[key].as_f64()).collect()).unwrap_or_default();
            v.sort_by(f64::total_cmp);
            v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
        };
        let (held_median, held_blocks, held_turned) = (median_of("pixel_error"), median_of("block_error"), median_of("light_turned_error"));
        let model = read_file(&model_path)?;
        let g = gpu.pass.upload(&model, true)?;
        let reference = Image::read(&ref_path, 1.0)?;
        let cam = view_camera(&model, p.ref_size, 1.0);
        let (ms, img) = gpu.frame(&g, &cam, &light, &opts, None)?;
        let err = relative_rmse(&img, &reference)?;
        let exposure = (0.4 / reference.mean().max(1e-9) as f32).clamp(1e-3, 1e3);
        let flip = fabric_runtime::metrics::flip(&img, &reference, exposure)?.mean;
        let mut res_cells = String::new();
        for &(w, h) in p.resolutions {
            let c = Camera { width: w, height: h, projection: fabric_runtime::scene::Projection::Orthographic { extent: model.bounds().size().x }, ..view_camera(&model, w, 1.0) };
            let (t, _) = gpu.frame(&g, &c, &light, &opts, None)?;
            let _ = write!(res_cells, " {t:.1} |");
        }
        let input = bake["input_bytes"].as_f64().unwrap_or(0.0);
        let model_bytes = std::fs::metadata(&model_path)?.len() as f64;
        frame_ms.push(ms);
        sizes.push((model_bytes / 1e6, input / 1e6));
        bakes.push(bake["total_seconds"].as_f64().unwrap_or(t_bake));
        refs.push(t_ref);
        let _ = writeln!(
            table,
            "| {preset} | {t_gen:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {t_ref:.1} | {:.2} | {:.3} | {:.1}% | {:.1}% | {:.1}% | {:.1}% | {flip:.3} |{res_cells}",
            bake["total_seconds"].as_f64().unwrap_or(t_bake),
            stage("training renderings"),
            stage("clustering and fitting") + stage("per-texel refinement"),
            stage("flyaways"),
            stage("prefilter"),
            input / 1e6,
            model_bytes / 1e6,
            100.0 * held_median,
            100.0 * held_blocks,
            100.0 * held_turned,
            100.0 * err
        );
        println!("{preset}: bake {:.0} s, model {:.2} MB, held-out {:.1}%, reference view {:.1}% ({ms:.1} ms on the GPU, reference {t_ref:.0} s)", bake["total_seconds"].as_f64().unwrap_or(t_bake), model_bytes / 1e6, 100.0 * held_median, 100.0 * err);
        if pi > 0 {
            continue;
        }
        // The sweeps, on the first preset.
        let mut dist = String::from("| view width (tiles) | pixels per texel | GPU ms | level (most pixels) |\n|---|---|---|---|\n");
        for zoom in [1.0f32, 4.0, 16.0, 64.0] {
            let c = view_camera(&model, 128, zoom);
            let frame = gpu.pass.render(&g, &c, &[light], &opts, None)?;
            let (t, _) = gpu.frame(&g, &c, &light, &opts, None)?;
            let level = frame.stats.level_pixels.iter().enumerate().max_by_key(|(_, n)| **n).map(|(l, _)| l).unwrap_or(0);
            let _ = writeln!(dist, "| {zoom} | {:.2} | {t:.1} | {level} |", 128.0 / (model.width() as f32 * zoom));
        }
        speed = format!("### Frame time by distance ({preset}, 128×128 pixels; by resolution: the table above)\n\n{dist}\n");
        // The environment light (paper §7.2): the built-in sky against the directional
        // light, frame time and error against the reference under the same sky.
        let sky = fabric_runtime::scene::Sky::default().env_map(fabric_runtime::scene::EnvMapOptions::default())?;
        let env_opts = CpuRenderOptions { env: Some(fabric_runtime::cpu::EnvLight::new(fabric_runtime::scene::PrefilteredEnv::with_lights(&sky, Default::default())?)), ..opts.clone() };
        let (sky_ms, sky_img) = gpu.timed(&g, &cam, &[], &env_opts, None)?;
        let sky_ref_path = args.out.join(format!("{preset}-reference-sky.exr"));
        let mut ra = vec!["reference", vol.to_str().unwrap_or("vol"), "--envmap", "sky", "--spp", &spp, "--size", &ref_size, "--out", sky_ref_path.to_str().unwrap_or("r.exr")];
        ra.extend(ref_camera);
        let t_sky_ref = fabric(&logs.join(format!("{preset}-reference-sky.log")), &ra)?;
        let sky_err = relative_rmse(&sky_img, &Image::read(&sky_ref_path, 1.0)?)?;
        let _ = write!(
            speed,
            "### Environment light ({preset}, {n}×{n} pixels, the reference view)\n\n| light | GPU ms | relative RMSE vs reference |\n|---|---|---|\n| one directional light | {ms:.1} | {e_dir:.1}% |\n| built-in sky (its sun a shadowed light + SG mixtures) | {sky_ms:.1} ({ratio:.2}×) | {e_sky:.1}% (reference {t_sky_ref:.0} s) |\n\n",
            n = p.ref_size,
            e_dir = 100.0 * err,
            ratio = sky_ms / ms.max(1e-9),
            e_sky = 100.0 * sky_err
        );
        println!("{preset}: built-in sky {sky_ms:.1} ms on the GPU ({:.2}× the directional light), {:.1}% against the reference under the sky", sky_ms / ms.max(1e-9), 100.0 * sky_err);
        // Transmission (paper §7.2, Fig. 17): the same volume baked as a BSDF; its bake
        // time against the reflection-only bake, its frame lit from the front with the
        // term compiled out (the default) and in, and lit from 30° behind the sheet
        // against the reference.
        let bsdf_path = args.out.join(format!("{preset}-bsdf.hyb"));
        let bsdf_report_path = args.out.join(format!("{preset}-bsdf-bake.json"));
        fabric(&logs.join(format!("{preset}-bake-bsdf.log")), &["bake", vol.to_str().unwrap_or("vol"), "--bsdf", "--out", bsdf_path.to_str().unwrap_or("b.hyb"), "--report", bsdf_report_path.to_str().unwrap_or("b.json"), "--held-out", &held])?;
        let bsdf_report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&bsdf_report_path)?).context("the BSDF bake report")?;
        let t_bsdf = bsdf_report["bake"]["total_seconds"].as_f64().unwrap_or(f64::NAN);
        let t_brdf = bake["total_seconds"].as_f64().unwrap_or(t_bake);
        // The held-out views lit from below (ω_i.z < 0), 4×4-block error.
        let mut backlit_held: Vec<f64> = bsdf_report["held_out"].as_array().map(|v| v.iter().filter(|h| h["pair"]["wi"][2].as_f64().is_some_and(|z| z < 0.0)).filter_map(|h| h["block_error"].as_f64()).collect()).unwrap_or_default();
        backlit_held.sort_by(f64::total_cmp);
        let backlit_median = backlit_held.get(backlit_held.len() / 2).copied().unwrap_or(f64::NAN);
        let bm = read_file(&bsdf_path)?;
        let bg = gpu.pass.upload(&bm, true)?;
        let front = HybridPass::variant(&bg, std::slice::from_ref(&light), false, bm.meta.fitted_with_shadowing, &opts);
        let (t_off, img_off) = gpu.frame(&bg, &cam, &light, &opts, Some(front))?;
        let (t_on, img_on) = gpu.frame(&bg, &cam, &light, &opts, Some(Variant { transmission: true, ..front }))?;
        let front_same = img_off == img_on;
        // Two lights 30° below the sheet: at the camera's azimuth opposite (the camera
        // looks straight into the light through the cloth: the transmitted peak), and
        // 90° aside. Blocks of 4 and 16 pixels are about 1.5 and 6 texels of the quick
        // suite's 48² tile.
        let mut back_rows = String::new();
        let mut back_summary = Vec::new();
        for (what, angles) in [("straight through (light at 150°, 200°)", "150,200"), ("90° aside (light at 150°, 110°)", "150,110")] {
            let (th, ph) = angles.split_once(',').and_then(|(a, b)| Some((a.parse::<f32>().ok()?, b.parse::<f32>().ok()?))).context("backlit angles")?;
            let back_light = Light::directional(direction_from_angles(th, ph), Vec3::ONE);
            let (t_back, img_back) = gpu.frame(&bg, &cam, &back_light, &opts, None)?;
            let tag = angles.replace(',', "-");
            let reference_at = |seed: &str| -> Result<(Image, f64)> {
                let path = args.out.join(format!("{preset}-reference-backlit-{tag}-seed{seed}.exr"));
                let mut ra = vec!["reference", vol.to_str().unwrap_or("vol"), "--spp", &spp, "--seed", seed, "--size", &ref_size, "--out", path.to_str().unwrap_or("r.exr"), "--light-angles", angles];
                ra.extend(ref_camera);
                let t = fabric(&logs.join(format!("{preset}-reference-backlit-{tag}-seed{seed}.log")), &ra)?;
                Ok((Image::read(&path, 1.0)?, t))
            };
            let (back_reference, t_back_ref) = reference_at("1")?;
            // The reference's own noise: a second seed against the first.
            let (second, _) = reference_at("7")?;
            let back_noise = relative_rmse(&second, &back_reference)?;
            img_back.write(&args.out.join(format!("{preset}-backlit-{tag}-model.exr")), 1.0)?;
            let back_err = relative_rmse(&img_back, &back_reference)?;
            let back_block_err = relative_rmse(&img_back.box_downsample(4), &back_reference.box_downsample(4))?;
            let back_block16_err = relative_rmse(&img_back.box_downsample(16), &back_reference.box_downsample(16))?;
            let back_ratio = img_back.mean() / back_reference.mean().max(1e-30);
            let _ = writeln!(
                back_rows,
                "| lit from 30° behind, {what}: GPU ms; relative RMSE vs reference per pixel / 4×4 / 16×16 blocks; mean model/reference | {t_back:.1}; {:.1}% / {:.1}% / {:.1}%; {back_ratio:.2} (reference {t_back_ref:.0} s; two reference seeds differ by {:.1}% per pixel) |",
                100.0 * back_err,
                100.0 * back_block_err,
                100.0 * back_block16_err,
                100.0 * back_noise
            );
            back_summary.push(format!("{what}: {:.1}% per pixel, {:.1}% / {:.1}% over 4×4 / 16×16 blocks (reference noise {:.1}%)", 100.0 * back_err, 100.0 * back_block_err, 100.0 * back_block16_err, 100.0 * back_noise));
        }
        let _ = write!(
            speed,
            "### Transmission ({preset}, `fabric bake --bsdf`; {n}×{n} pixels, the reference view)\n\n| | value |\n|---|---|\n\
             | bake with `--bsdf` / reflection only | {t_bsdf:.1} s / {t_brdf:.1} s ({:.2}×; the paper: about 2×) |\n\
             | lit from the front: GPU ms, term compiled out / in | {t_off:.1} / {t_on:.1} ({}) |\n\
             {back_rows}\
             | backlit held-out views of the bake (4×4 blocks, median of {}) | {:.1}% |\n\n",
            t_bsdf / t_brdf.max(1e-9),
            if front_same { "the same image" } else { "the images differ" },
            backlit_held.len(),
            100.0 * backlit_median,
            n = p.ref_size,
        );
        println!("{preset}: BSDF bake {t_bsdf:.0} s ({:.2}× the reflection-only bake); front-lit {t_off:.1} / {t_on:.1} ms with the term out / in ({}); lit from behind, {}", t_bsdf / t_brdf.max(1e-9), if front_same { "same image" } else { "images differ" }, back_summary.join("; "));
        let vary = |name: &'static str, what: &'static str, cases: Vec<(String, CpuRenderOptions, Option<Variant>)>| -> Result<Sweep> {
            let mut rows = Vec::new();
            for (label, o, v) in cases {
                let (t, img) = gpu.frame(&g, &cam, &light, &o, v)?;
                rows.push(Row { label, time: t, error: relative_rmse(&img, &reference)? });
            }
            Ok(Sweep { name, what, time_unit: "ms", error_of: "the GPU frame against the reference view", rows })
        };
        sweeps.push(vary("pom_steps", "max_steps", [8u32, 16, 32, 64, 4096].iter().map(|&s| (s.to_string(), CpuRenderOptions { max_steps: s, ..opts.clone() }, None)).collect())?);
        sweeps.push(vary("level_bias", "bias", [-1.0f32, 0.0, 1.0, 2.0, 3.0].iter().map(|&b| (format!("{b:+}"), CpuRenderOptions { level: LevelChoice::Auto { bias: b }, ..opts.clone() }, None)).collect())?);
        let base = HybridPass::variant(&g, std::slice::from_ref(&light), HybridPass::light_behind_tile(&g, std::slice::from_ref(&light), &opts), model.meta.fitted_with_shadowing, &opts);
        sweeps.push(vary(
            "skips",
            "variant",
            vec![
                ("full".into(), opts.clone(), None),
                ("no flyaways".into(), CpuRenderOptions { flyaways: false, ..opts.clone() }, None),
                ("no shadows".into(), CpuRenderOptions { shadows: ShadowMode::Off, ..opts.clone() }, None),
                ("coarse relief".into(), CpuRenderOptions { coarse_relief: true, ..opts.clone() }, None),
                ("8-lobe loop".into(), opts.clone(), Some(Variant { lobes: 8, ..base })),
                ("plain surface".into(), opts.clone(), Some(Variant { relief: false, flyaways: false, ..base })),
            ],
        )?);
        let rounds = bake["rounds"].as_array().cloned().unwrap_or_default();
        sweeps.push(Sweep { name: "clusters_k", what: "K", time_unit: "s", error_of: "the bake's training error per round of K doubling", rows: rounds.iter().map(|r| Row { label: format!("K={}", r["k"]), time: r["seconds"].as_f64().unwrap_or(0.0), error: r["error"].as_f64().unwrap_or(f64::NAN) }).collect() });
        let lobes: Vec<f64> = bake["prefilter"]["levels"][0]["error_by_lobes"].as_array().map(|a| a.iter().filter_map(|v| v.as_f64()).collect()).unwrap_or_default();
        let level1 = &bake["prefilter"]["levels"][0];
        let texels = level1["width"].as_f64().unwrap_or(0.0) * level1["height"].as_f64().unwrap_or(0.0);
        // The prefilter's pass gives the error with 1..8 lobes allowed (on up to 512 texels
        // a level it goes on past the budget: LevelReport::error_by_lobes); the cost axis
        // is level 1's BRDF records at that budget in KB (the compact per-texel record,
        // 8 + 12·L bytes: runtime/HYBRID_FORMAT.md §9).
        sweeps.push(Sweep { name: "lobes_per_level", what: "lobes", time_unit: "KB", error_of: "level 1's coarse texels against their level-0 footprints (the prefilter's fit error)", rows: lobes.iter().enumerate().map(|(i, e)| Row { label: format!("{}", i + 1), time: texels * (8.0 + 12.0 * (i + 1) as f64) / 1e3, error: *e }).collect() });
        // The reference's own samples against its converged self (the bench's reference).
        let mut rows = Vec::new();
        for spp in [4u32, 8, 16, 32] {
            let out = args.out.join(format!("{preset}-reference-{spp}spp.exr"));
            let s = spp.to_string();
            let mut a = vec!["reference", vol.to_str().unwrap_or("vol"), "--spp", &s, "--seed", "7", "--size", &ref_size, "--out", out.to_str().unwrap_or("r.exr")];
            a.extend(&ref_view);
            let t = fabric(&logs.join(format!("{preset}-reference-{spp}.log")), &a)?;
            rows.push(Row { label: format!("{spp} spp"), time: t, error: relative_rmse(&Image::read(&out, 1.0)?, &reference)? });
        }
        rows.push(Row { label: format!("hybrid (GPU {ms:.0} ms)"), time: ms / 1e3, error: err });
        sweeps.push(Sweep { name: "reference_spp", what: "renderer", time_unit: "s", error_of: "each renderer against the reference view", rows });
    }
    for s in &sweeps {
        write_sweep(&args.out, s, font.is_some())?;
    }
    let mut md = format!(
        "# fabric bench --suite {:?}\n\nOn {} ({}, driver {}); volumes {}, reference view {}² at {} spp (30°, light 40°, periodic).\n\n## Per preset\n\n{table}\n",
        args.suite, info.name, info.kind, info.driver, p.size, p.ref_size, p.ref_spp
    );
    md.push_str(&speed);
    md.push_str("## Sweeps: cost against error\n\n");
    for s in &sweeps {
        let _ = writeln!(md, "### {}\n\nThe error of {}.\n\n| {} | {} ({}) | relative RMSE |\n|---|---|---|", s.name, s.error_of, s.what, s.cost(), s.time_unit);
        for r in &s.rows {
            let _ = writeln!(md, "| {} | {:.3} | {:.4} |", r.label, r.time, r.error);
        }
        if font.is_some() && !s.rows.is_empty() {
            let _ = writeln!(md, "\n![{}]({}.png)\n", s.name, s.name);
        } else {
            md.push('\n');
        }
    }
    let range = |v: &[f64]| {
        let (lo, hi) = v.iter().fold((f64::INFINITY, 0.0f64), |(a, b), x| (a.min(*x), b.max(*x)));
        (lo, hi)
    };
    let (f0, f1) = range(&frame_ms);
    let (m0, m1) = range(&sizes.iter().map(|s| s.0).collect::<Vec<_>>());
    let (v0, v1) = range(&sizes.iter().map(|s| s.1).collect::<Vec<_>>());
    let (b0, b1) = range(&bakes);
    let (r0, r1) = range(&refs);
    let _ = write!(
        md,
        "## Beside the paper (Table 1)\n\n| | paper (GTX 1080 Ti, 1k² tiles, 1280×720) | here ({}, {} volumes) |\n|---|---|---|\n\
         | frame time | 24–31 ms | {f0:.0}–{f1:.0} ms at {}² ({}) |\n\
         | model size | 25–41 MB from 0.5–1.9 GB volumes | {m0:.2}–{m1:.2} MB from {v0:.2}–{v1:.2} MB |\n\
         | bake | 20–40 h | {b0:.0}–{b1:.0} s (2 cores) |\n\
         | reference frame | 52–106 min | {r0:.0}–{r1:.0} s at {} spp, {}² (the `reference_spp` sweep gives its noise; 1% needs ~(noise/1%)² times the samples) |\n",
        info.name, p.size, p.ref_size, info.kind, p.ref_spp, p.ref_size
    );
    std::fs::write(args.out.join("summary.md"), md)?;
    println!("wrote {}", args.out.join("summary.md").display());
    Ok(())
}
