//! Times the GPU renderer of hybrid models (prints; no pass/fail): frame time by
//! resolution, the cost of the hybrid shader against a plain normal-mapped surface with
//! the same BRDFs (the `relief` variant off), the saving of each skip, and the built-in
//! sky (environment light) against one directional light at 1280×720 (issue 13's bar:
//! at most 2×).
//!
//! `cargo run --release -p fabric-runtime --example bench_gpu_render [MODEL.hyb|N]`: a
//! model file, or a synthetic N×N model (default 512); `--env-only` times only the
//! environment light (and the far view by coarse filter), `--filters-only` only the far view
//! by coarse filter, under one light and under the sky. GPU time from timestamps around frames recorded back to back
//! (`HybridPass::render_back_to_back`, about 0.2 s of them), the median of 3 runs.

use std::time::Instant;

use fabric_runtime::cpu::{CpuRenderOptions, EnvLight, ShadowMode};
use fabric_runtime::gpu::{GpuHybridModel, HybridPass, Variant};
use fabric_runtime::hybrid::examples::synthetic_model;
use fabric_runtime::hybrid::format::read_file;
use fabric_runtime::scene::{Camera, EnvMapOptions, ExtractOptions, Light, PrefilteredEnv, Projection, Sky};
use fabric_runtime::vk::{Device, DeviceOptions};
use glam::Vec3;

fn median_ms(pass: &HybridPass, g: &GpuHybridModel, cam: &Camera, lights: &[Light], opts: &CpuRenderOptions, v: Option<Variant>) -> (f64, Variant) {
    let first = pass.render(g, cam, lights, opts, v).expect("render");
    // Frames back to back in one submission (a frame loop's figure: separate renders
    // leave the GPU idle while the image is read back, and its clocks drop), about
    // 0.2 s of them, the median of 3 such runs.
    let estimate = pass.render_back_to_back(g, cam, lights, opts, v, 4).expect("render").gpu_ms;
    let frames = (200.0 / estimate.max(1e-3)).clamp(4.0, 400.0) as u32;
    let mut t: Vec<f64> = (0..3).map(|_| pass.render_back_to_back(g, cam, lights, opts, v, frames).expect("render").gpu_ms).collect();
    t.sort_by(f64::total_cmp);
    (t[1], first.variant)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let env_only = args.iter().any(|a| a == "--env-only");
    let arg = args.iter().find(|a| !a.starts_with("--")).cloned().unwrap_or_else(|| "512".into());
    let model = match arg.parse::<u32>() {
        Ok(n) => synthetic_model(n, 1),
        Err(_) => read_file(std::path::Path::new(&arg)).expect("a readable model file"),
    };
    let device = Device::new(&DeviceOptions::default()).expect("a Vulkan device");
    println!("device: {} ({}, driver {})", device.info().name, device.info().kind, device.info().driver);
    let pass = HybridPass::new(&device).unwrap();
    let t = Instant::now();
    let g = pass.upload(&model, true).unwrap();
    println!("model {}x{}, {} levels, flyaways {}: {:.1} MB uploaded in {:.2?}", model.width(), model.height_px(), model.levels.len(), model.has_flyaways(), g.bytes as f64 / 1e6, t.elapsed());
    let b = model.bounds();
    let c = b.center();
    let span = b.size().truncate().max_element();
    let close = |w, h| Camera { origin: c + Vec3::new(0.05, -0.3, 0.35) * span, target: c, up: Vec3::Z, projection: Projection::Perspective { fov_x_deg: 40.0 }, width: w, height: h };
    let far = |w, h| Camera { origin: c + Vec3::new(0.0, -3.0, 2.0) * span, target: c, up: Vec3::Z, projection: Projection::Perspective { fov_x_deg: 40.0 }, width: w, height: h };
    let lights = [Light::directional(Vec3::new(-0.3, 0.4, 1.0), Vec3::splat(1.0)), Light::Point { position: c + Vec3::new(0.3, -0.2, 0.5) * span, intensity: Vec3::splat(0.5 * span * span) }];
    let opts = CpuRenderOptions { periodic: true, shadows: ShadowMode::On, ..Default::default() };
    if args.iter().any(|a| a == "--filters-only") {
        filter_times(&pass, &g, &far, &lights, &opts);
        return;
    }
    if !env_only {
        frame_times(&pass, &g, &close, &far, &lights, &opts);
    }
    env_times(&pass, &g, &close, &far, &lights, &opts);
}

/// Frame time by resolution, the variants' costs, far views.
fn frame_times(pass: &HybridPass, g: &GpuHybridModel, close: &dyn Fn(u32, u32) -> Camera, far: &dyn Fn(u32, u32) -> Camera, lights: &[Light], opts: &CpuRenderOptions) {
    println!("\nframe time by resolution (close view, 1 light, shadows, all of the model):");
    for (w, h) in [(640, 360), (1280, 720), (1920, 1080)] {
        let (ms, v) = median_ms(pass, g, &close(w, h), &lights[..1], opts, None);
        println!("  {w}x{h}: {ms:.2} ms  ({v:?})");
    }
    println!("\nvariants at 640x360 (close view):");
    let cam = close(640, 360);
    let (full, v) = median_ms(pass, g, &cam, &lights[..1], opts, None);
    println!("  hybrid, 1 light, shadows: {full:.2} ms ({v:?})");
    let plain = median_ms(pass, g, &cam, &lights[..1], opts, Some(Variant { relief: false, flyaways: false, ..v })).0;
    println!("  plain normal-mapped surface, same BRDFs: {plain:.2} ms (hybrid costs {:.2}x)", full / plain);
    let nofly = median_ms(pass, g, &cam, &lights[..1], opts, Some(Variant { flyaways: false, ..v })).0;
    println!("  without the flyaway march: {nofly:.2} ms (flyaways add {:+.0}%)", 100.0 * (full / nofly - 1.0));
    let noshadow = median_ms(pass, g, &cam, &lights[..1], &CpuRenderOptions { shadows: ShadowMode::Off, ..opts.clone() }, None).0;
    println!("  without shadow rays: {noshadow:.2} ms (shadows add {:+.0}%)", 100.0 * (full / noshadow - 1.0));
    let two = median_ms(pass, g, &cam, &lights, opts, None).0;
    println!("  two lights: {two:.2} ms ({:+.0}% for the second light)", 100.0 * (two / full - 1.0));
    let eight = median_ms(pass, g, &cam, &lights[..1], opts, Some(Variant { lobes: 8, ..v })).0;
    println!("  lobe loop compiled for 8 lobes instead of the model's {}: {eight:.2} ms", v.lobes);
    let farv = median_ms(pass, g, &far(640, 360), &lights[..1], opts, None).0;
    let far0 = median_ms(pass, g, &far(640, 360), &lights[..1], &CpuRenderOptions { level: fabric_runtime::cpu::LevelChoice::Fixed(0), ..opts.clone() }, None).0;
    let farc = median_ms(pass, g, &far(640, 360), &lights[..1], &CpuRenderOptions { coarse_relief: true, ..opts.clone() }, None).0;
    println!("  far view, automatic levels: {farv:.2} ms; level 0 forced: {far0:.2} ms; coarse relief: {farc:.2} ms");
}

/// The far view's frame time under each coarse filter, and each over the box's.
fn far_by_filter(pass: &HybridPass, g: &GpuHybridModel, cam: &Camera, lights: &[Light], opts: &CpuRenderOptions) -> String {
    use fabric_runtime::cpu::CoarseFilter;
    let mut filters = CoarseFilter::NAMES;
    // The box first: the ratios are over its time.
    filters.sort_by_key(|(_, f)| *f != CoarseFilter::Box);
    let ms: Vec<(&str, f64)> = filters
        .into_iter()
        .map(|(name, coarse_filter)| (name, median_ms(pass, g, cam, lights, &CpuRenderOptions { coarse_filter, ..opts.clone() }, None).0))
        .collect();
    ms.iter().map(|(name, t)| format!("{name} {t:.2} ms ({:.2}x)", t / ms[0].1)).collect::<Vec<_>>().join(", ")
}

/// The built-in sky against one directional light.
fn env_times(pass: &HybridPass, g: &GpuHybridModel, close: &dyn Fn(u32, u32) -> Camera, far: &dyn Fn(u32, u32) -> Camera, lights: &[Light], opts: &CpuRenderOptions) {

    // The built-in sky as `fabric render --envmap sky` shades it: its sun a shadowed
    // directional light, the rest SG mixtures against the prefiltered levels.
    let map = Sky::default().env_map(EnvMapOptions::default()).expect("the built-in sky");
    let sky = PrefilteredEnv::with_lights(&map, ExtractOptions::default()).expect("the sky prefiltered");
    let sun = sky.lights.clone();
    let env_opts = CpuRenderOptions { env: Some(EnvLight::new(sky)), ..opts.clone() };
    println!("\nenvironment light (built-in sky: {} sun light(s) + SG mixtures) against one directional light:", sun.len());
    for (name, cam) in [("close", close(1280, 720)), ("far", far(1280, 720)), ("close", close(1920, 1080))] {
        let (dir, vd) = median_ms(pass, g, &cam, &lights[..1], opts, None);
        let (env, ve) = median_ms(pass, g, &cam, &sun, &env_opts, None);
        let dir_nofly = median_ms(pass, g, &cam, &lights[..1], opts, Some(Variant { flyaways: false, ..vd })).0;
        let env_nofly = median_ms(pass, g, &cam, &sun, &env_opts, Some(Variant { flyaways: false, ..ve })).0;
        println!(
            "  {name} {}x{}: directional {dir:.2} ms, sky {env:.2} ms ({:.2}x); surface only: {dir_nofly:.2} / {env_nofly:.2} ms ({:.2}x)",
            cam.width,
            cam.height,
            env / dir,
            env_nofly / dir_nofly
        );
    }
    filter_times(pass, g, far, lights, opts);
}

/// What the coarse filter costs where it matters: the far view, under one light and under
/// the sky (the split filter's extra rays are unshaded, the fine filter's are shaded:
/// under the sky each node they cross is an SG mixture). What decided the default,
/// split (baker/PREFILTER_MEASUREMENTS.md, "The split filter as the default").
fn filter_times(pass: &HybridPass, g: &GpuHybridModel, far: &dyn Fn(u32, u32) -> Camera, lights: &[Light], opts: &CpuRenderOptions) {
    let map = Sky::default().env_map(EnvMapOptions::default()).expect("the built-in sky");
    let sky = PrefilteredEnv::with_lights(&map, ExtractOptions::default()).expect("the sky prefiltered");
    let sun = sky.lights.clone();
    let env_opts = CpuRenderOptions { env: Some(EnvLight::new(sky)), ..opts.clone() };
    let cam = far(640, 360);
    println!("\nfar view {}x{} by coarse filter (each over the box's):", cam.width, cam.height);
    println!("  directional: {}", far_by_filter(pass, g, &cam, &lights[..1], opts));
    println!("  sky: {}", far_by_filter(pass, g, &cam, &sun, &env_opts));
}
