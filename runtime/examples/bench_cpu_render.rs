//! Times the CPU renderer of hybrid models (prints; no pass/fail).
//!
//! `cargo run --release -p fabric-runtime --example bench_cpu_render [N] [WxH]`: a
//! synthetic N×N model (default 512), rendered at WxH (default 640x360) in a few
//! configurations, printing the time, Mrays/s and the stats of each.

use std::time::Instant;

use fabric_runtime::cpu::{CpuRenderOptions, LevelChoice, ShadowMode, render_with_stats};
use fabric_runtime::hybrid::examples::synthetic_model;
use fabric_runtime::scene::{Camera, Light, Projection};
use glam::Vec3;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: u32 = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(512);
    let (w, h) = args.get(2).and_then(|a| a.split_once('x')).and_then(|(w, h)| Some((w.parse().ok()?, h.parse().ok()?))).unwrap_or((640u32, 360u32));
    let t = Instant::now();
    let model = synthetic_model(n, 1);
    model.validate().expect("the synthetic model is valid");
    let nodes: usize = model.levels.iter().filter_map(|l| l.flyaways.as_ref()).map(|f| f.nodes.len()).sum();
    println!("model {n}x{n}, {} levels, {nodes} flyaway nodes over all levels, built in {:.2?}", model.levels.len(), t.elapsed());
    println!("threads: {}", rayon::current_num_threads());
    let lights = [Light::Point { position: Vec3::new(0.8, -0.3, 0.8), intensity: Vec3::splat(1.0) }, Light::directional(Vec3::new(-0.3, 0.4, 1.0), Vec3::splat(0.7))];
    let close = Camera { origin: Vec3::new(0.45, 0.2, 0.35), target: Vec3::new(0.5, 0.5, 0.05), up: Vec3::Z, projection: Projection::Perspective { fov_x_deg: 40.0 }, width: w, height: h };
    let far = Camera { origin: Vec3::new(0.5, -2.5, 1.8), target: Vec3::new(0.5, 0.5, 0.05), up: Vec3::Z, projection: Projection::Perspective { fov_x_deg: 40.0 }, width: w, height: h };
    let base = CpuRenderOptions { periodic: true, ..Default::default() };
    let configs: [(&str, &Camera, CpuRenderOptions); 5] = [
        ("close, auto level, no shadows", &close, CpuRenderOptions { shadows: ShadowMode::Off, ..base.clone() }),
        ("close, auto level, shadows", &close, CpuRenderOptions { shadows: ShadowMode::On, ..base.clone() }),
        ("close, level 0, shadows", &close, CpuRenderOptions { shadows: ShadowMode::On, level: LevelChoice::Fixed(0), ..base.clone() }),
        ("far (horizon), auto level, shadows", &far, CpuRenderOptions { shadows: ShadowMode::On, ..base.clone() }),
        ("far, auto level, shadows, 2x2 supersampling", &far, CpuRenderOptions { shadows: ShadowMode::On, supersampling: 2, ..base.clone() }),
    ];
    for (name, cam, opts) in configs {
        // One warm-up, then the median of three.
        let _ = render_with_stats(&model, cam, &lights, &opts);
        let mut times = Vec::new();
        let mut last = None;
        for _ in 0..3 {
            let t = Instant::now();
            let r = render_with_stats(&model, cam, &lights, &opts).expect("render");
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
