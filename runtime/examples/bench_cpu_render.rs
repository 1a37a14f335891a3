//! Times the CPU renderer of hybrid models (prints; no pass/fail).
//!
//! `cargo run --release -p fabric-runtime --example bench_cpu_render [N|MODEL.hyb] [WxH]`:
//! a synthetic N×N model (default 512) or a model file, rendered at WxH (default
//! 640x360) in a few configurations, printing the time, Mrays/s and the stats of each.
//! A model file is seen from `bench_gpu_render`'s close and far cameras (placed by the
//! tile's bounds), so the two benches time the same frames.

use std::time::Instant;

use fabric_runtime::cpu::{CoarseFilter, CpuRenderOptions, LevelChoice, ShadowMode, render_with_stats};
use fabric_runtime::hybrid::examples::synthetic_model;
use fabric_runtime::hybrid::format::read_file;
use fabric_runtime::scene::{Camera, Light, Projection};
use glam::Vec3;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = args.get(1).cloned().unwrap_or_else(|| "512".into());
    let (w, h) = args.get(2).and_then(|a| a.split_once('x')).and_then(|(w, h)| Some((w.parse().ok()?, h.parse().ok()?))).unwrap_or((640u32, 360u32));
    let t = Instant::now();
    let from_file = arg.parse::<u32>().is_err();
    let model = match arg.parse::<u32>() {
        Ok(n) => synthetic_model(n, 1),
        Err(_) => read_file(std::path::Path::new(&arg)).expect("a readable model file"),
    };
    model.validate().expect("the model is valid");
    let nodes: usize = model.levels.iter().filter_map(|l| l.flyaways.as_ref()).map(|f| f.nodes.len()).sum();
    println!("model {}x{}, {} levels, {nodes} flyaway nodes over all levels, ready in {:.2?}", model.width(), model.height_px(), model.levels.len(), t.elapsed());
    println!("threads: {}", rayon::current_num_threads());
    let (lights, close, far) = if from_file {
        // bench_gpu_render's scene.
        let b = model.bounds();
        let c = b.center();
        let span = b.size().truncate().max_element();
        let cam = |o: Vec3| Camera { origin: c + o * span, target: c, up: Vec3::Z, projection: Projection::Perspective { fov_x_deg: 40.0 }, width: w, height: h };
        let lights = [Light::directional(Vec3::new(-0.3, 0.4, 1.0), Vec3::splat(1.0)), Light::Point { position: c + Vec3::new(0.3, -0.2, 0.5) * span, intensity: Vec3::splat(0.5 * span * span) }];
        (lights, cam(Vec3::new(0.05, -0.3, 0.35)), cam(Vec3::new(0.0, -3.0, 2.0)))
    } else {
        let lights = [Light::Point { position: Vec3::new(0.8, -0.3, 0.8), intensity: Vec3::splat(1.0) }, Light::directional(Vec3::new(-0.3, 0.4, 1.0), Vec3::splat(0.7))];
        let close = Camera { origin: Vec3::new(0.45, 0.2, 0.35), target: Vec3::new(0.5, 0.5, 0.05), up: Vec3::Z, projection: Projection::Perspective { fov_x_deg: 40.0 }, width: w, height: h };
        let far = Camera { origin: Vec3::new(0.5, -2.5, 1.8), target: Vec3::new(0.5, 0.5, 0.05), up: Vec3::Z, projection: Projection::Perspective { fov_x_deg: 40.0 }, width: w, height: h };
        (lights, close, far)
    };
    let base = CpuRenderOptions { periodic: true, ..Default::default() };
    // (name, camera, options, lights used)
    let configs: [(&str, &Camera, CpuRenderOptions, usize); 11] = [
        ("close, auto level, no shadows", &close, CpuRenderOptions { shadows: ShadowMode::Off, ..base.clone() }, 2),
        ("close, auto level, shadows", &close, CpuRenderOptions { shadows: ShadowMode::On, ..base.clone() }, 2),
        ("close, level 0, shadows", &close, CpuRenderOptions { shadows: ShadowMode::On, level: LevelChoice::Fixed(0), ..base.clone() }, 2),
        ("far (horizon), auto level, shadows", &far, CpuRenderOptions { shadows: ShadowMode::On, ..base.clone() }, 2),
        ("far, auto level, shadows, 2x2 supersampling", &far, CpuRenderOptions { shadows: ShadowMode::On, supersampling: 2, ..base.clone() }, 2),
        ("far, auto level, one light, shadows (bench_gpu_render's far view)", &far, CpuRenderOptions { shadows: ShadowMode::On, ..base.clone() }, 1),
        ("far, level 0, one light, shadows", &far, CpuRenderOptions { shadows: ShadowMode::On, level: LevelChoice::Fixed(0), ..base.clone() }, 1),
        // What the far view's time is made of.
        ("far, auto level, one light, no shadows", &far, CpuRenderOptions { shadows: ShadowMode::Off, ..base.clone() }, 1),
        ("far, auto level, one light, shadows, no flyaways", &far, CpuRenderOptions { shadows: ShadowMode::On, flyaways: false, ..base.clone() }, 1),
        ("far, auto level, one light, shadows, bilinear coarse filter", &far, CpuRenderOptions { shadows: ShadowMode::On, coarse_filter: CoarseFilter::Bilinear, ..base.clone() }, 1),
        ("far, auto level, one light, shadows, coarse relief", &far, CpuRenderOptions { shadows: ShadowMode::On, coarse_relief: true, ..base.clone() }, 1),
    ];
    for (name, cam, opts, n_lights) in configs {
        let lights = &lights[..n_lights];
        // One warm-up, then the median of three.
        let _ = render_with_stats(&model, cam, lights, &opts);
        let mut times = Vec::new();
        let mut last = None;
        for _ in 0..3 {
            let t = Instant::now();
            let r = render_with_stats(&model, cam, lights, &opts).expect("render");
            times.push(t.elapsed().as_secs_f64());
            last = Some(r);
        }
        times.sort_by(f64::total_cmp);
        let (_, stats) = last.expect("three runs");
        let rays = (w * h * opts.supersampling * opts.supersampling) as f64;
        println!(
            "{name}: {:.1} ms, {:.2} Mrays/s, {:.1} march steps/ray; levels {:?}, surface {}, flyaway {}, step-limited {} (shadow rays {})",
            times[1] * 1e3,
            rays / times[1] / 1e6,
            stats.camera_steps as f64 / rays,
            stats.level_pixels,
            stats.surface_pixels,
            stats.flyaway_pixels,
            stats.step_limited_pixels,
            stats.step_limited_shadow_rays
        );
    }
}
