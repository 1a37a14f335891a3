//! `fabric render MODEL.hyb --backend gpu`: the GPU renderer of hybrid models
//! (`fabric_runtime::gpu::HybridPass`, `shaders/hybrid.comp`), with the CPU backend's
//! flags. Prints the device and the GPU frame time: the median of `--repeat` frames
//! after one warm-up frame (the first pays for the driver's shader compile), and on the
//! tile the time per frame of `--repeat` frames recorded back to back.

use std::path::Path;

use anyhow::{Context, Result};
use fabric_runtime::cpu::ShadowMode;
use fabric_runtime::gpu::HybridPass;
use fabric_runtime::hybrid::format::read_file;
use fabric_runtime::scene::Mesh;
use fabric_runtime::vk::{Device, DeviceOptions};

use super::render_cpu::CpuRenderFlags;
use crate::args::{CameraArgs, EnvArgs, LightArgs, OutputArgs};

/// Opens the Vulkan device named `name` (or the best one).
pub fn open_device(name: &Option<String>) -> Result<std::sync::Arc<Device>> {
    Device::new(&DeviceOptions { name: name.clone(), ..Default::default() }).context("cannot open a Vulkan device")
}

/// Renders `model_path` on the GPU `device` — on a tile seen by the camera, or tiled
/// over `mesh`'s UVs (`uv_scale` repeats per UV unit) — and writes the image.
#[allow(clippy::too_many_arguments)] // the command's flag groups, passed through
pub fn run(device: std::sync::Arc<Device>, model_path: &Path, mesh: Option<&str>, uv_scale: glam::Vec2, camera: &CameraArgs, light: &LightArgs, env: &EnvArgs, output: &OutputArgs, flags: &CpuRenderFlags, repeat: u32) -> Result<()> {
    output.validate()?;
    let model = read_file(model_path)?;
    let mesh = mesh.map(Mesh::by_name).transpose()?;
    let camera = camera.camera(mesh.as_ref().map_or(model.bounds(), |m| m.bounds()))?;
    let mut options = flags.options()?;
    let lights = super::render_cpu::lights_and_env(light, env, &mut options)?;
    if mesh.is_some() {
        // On a mesh the tile repeats over the UVs.
        options.periodic = true;
    }
    if options.shadows == ShadowMode::FromModel {
        println!("shadowing: {} (as the model was fitted)", if model.meta.fitted_with_shadowing { "on" } else { "off" });
    } else if (options.shadows == ShadowMode::On) != model.meta.fitted_with_shadowing {
        println!("warning: the model was fitted {} height-field shadowing; rendering {} it", if model.meta.fitted_with_shadowing { "with" } else { "without" }, if options.shadows == ShadowMode::On { "with" } else { "without" });
    }
    let info = device.info().clone();
    println!("device: {} ({}, driver {})", info.name, info.kind, info.driver);
    if info.kind == "CPU" {
        println!("note: {} is a software Vulkan driver: its frame times say nothing of a GPU's, and the CPU renderer (--backend cpu) is 2–3x faster on the same cores (runtime/GPU_MEASUREMENTS.md)", info.name);
    }
    let pass = HybridPass::new(&device)?;
    let upload_start = std::time::Instant::now();
    let gpu_model = pass.upload(&model, options.periodic).with_context(|| format!("cannot upload {}", model_path.display()))?;
    println!("uploaded {:.1} MB in {:.2?}", gpu_model.bytes as f64 / 1e6, upload_start.elapsed());
    let draw = || match &mesh {
        Some(m) => pass.render_mesh(&gpu_model, m, uv_scale, &camera, &lights, &options, None),
        None => pass.render(&gpu_model, &camera, &lights, &options, None),
    };
    let warm = std::time::Instant::now();
    let mut frame = draw().with_context(|| format!("cannot render {}", model_path.display()))?;
    let first = warm.elapsed();
    let mut times = Vec::new();
    for _ in 0..repeat.max(1) {
        frame = draw()?;
        times.push(frame.gpu_ms);
    }
    // On the tile: also `repeat` frames recorded back to back, as a frame loop runs them
    // (separate frames leave the GPU idle during the readback; a discrete GPU's clocks
    // drop in those gaps).
    let back_to_back = match &mesh {
        None if repeat > 1 => Some(pass.render_back_to_back(&gpu_model, &camera, &lights, &options, None, repeat)?.gpu_ms),
        _ => None,
    };
    let errors = device.validation_errors();
    if !errors.is_empty() {
        anyhow::bail!("{} Vulkan validation error(s); first: {}", errors.len(), errors[0]);
    }
    frame.image.write(&output.out, output.exposure)?;
    times.sort_by(f64::total_cmp);
    let s = &frame.stats;
    let v = frame.variant;
    println!(
        "{}: {}x{} on the GPU: frame time {:.3} ms (median of {}, min {:.3} ms; first frame with shader compile {:.2?}) on {}",
        model_path.display(),
        camera.width,
        camera.height,
        times[times.len() / 2],
        times.len(),
        times[0],
        first,
        info.name
    );
    if let Some(ms) = back_to_back {
        println!("{repeat} frames back to back: {ms:.3} ms per frame");
    }
    let variant = format!("variant: flyaways {}, shadows {}, {} light(s){}{}", if v.flyaways { "marched" } else { "skipped" }, if v.shadows { "on" } else { "off" }, v.lights, if v.env { ", environment map" } else { "" }, if v.transmission { ", transmission (light from behind the cloth: a light, or the map below the sheet)" } else { "" });
    match &mesh {
        Some(m) => println!("{variant}; on a mesh of {} triangles, {}x{} tiles per UV unit", m.indices.len() / 3, uv_scale.x, uv_scale.y),
        None => {
            println!("{variant}; {} pixels on the tile, {} on the surface, {} with flyaways; pixels per level {:?}", s.tile_pixels, s.surface_pixels, s.flyaway_pixels, s.level_pixels);
            super::render::warn_if_tile_unseen(s.tile_pixels);
            super::render::warn_if_lit_from_below(&model, &lights, options.env.is_some());
        }
    }
    if s.loop_cut_pixels > 0 {
        println!(
            "warning: {} pixel(s) needed more loop iterations than {} runs per shader invocation (lavapipe ends every loop after 65535 in all), so they are drawn wrong; use a hardware GPU, `--backend cpu` (the tile), fewer samples per pixel or a less grazing view (runtime/GPU_MEASUREMENTS.md, \"lavapipe's loop budget\")",
            s.loop_cut_pixels, info.name
        );
    }
    if s.step_limited_pixels > 0 || s.step_limited_shadow_rays > 0 {
        println!("warning: {} camera rays and {} shadow rays ran out of --max-steps {}", s.step_limited_pixels, s.step_limited_shadow_rays, options.max_steps);
    }
    println!("wrote {}", output.out.display());
    Ok(())
}
