//! `fabric bench --stress`: the long numerical-stability and robustness run (the tests
//! run shorter versions of each in CI): the cloth BRDF in both twins over 10⁷ random and
//! extreme inputs (finite, non-negative, under each input's analytic bound), the model
//! reader over 10⁶ corrupted files (an error or the original model, never a panic), and
//! both renderers under extreme cameras (finite images). Prints what it checked and
//! fails on the first violation.

use std::time::Instant;

use anyhow::{Context, Result, bail};
use fabric_runtime::brdf::twin::{BrdfEvalInput, BrdfEvalOutput, SplitMix64, generate_inputs};
use fabric_runtime::brdf::{BETA_MIN, BrdfReading, ClothLobe, HELD_RISE, K_MAX};
use fabric_runtime::cpu::{CpuRenderOptions, ShadowMode, render};
use fabric_runtime::gpu::HybridPass;
use fabric_runtime::hybrid::{examples, format};
use fabric_runtime::scene::{Camera, Light, Projection, direction_from_angles};
use fabric_runtime::vk::{BindingKind, Buffer, DescriptorSet, DescriptorSetLayout, Device, DeviceOptions, MemoryLocation, Pipeline, PipelineLayout, Resource, ShaderModule, Specialization, vk};
use glam::Vec3;

/// The largest value an input's outputs can take: k_d + Σ k_j/(√(2π)·β), β the lobe's
/// width (bounded reading), that width over HELD_RISE (the held reading lets the lobe rise
/// that far) or BETA_MIN (the width reading narrows it that far).
fn bound(input: &BrdfEvalInput) -> f32 {
    let p = input.params();
    let kd = p.kd.max(Vec3::ZERO).min(Vec3::splat(K_MAX)).max_element();
    let peak = |l: &ClothLobe| {
        let beta = match input.reading() {
            BrdfReading::Width => BETA_MIN,
            BrdfReading::Held => (l.beta.clamp(BETA_MIN, 1e4) / HELD_RISE).max(BETA_MIN),
            BrdfReading::Bounded => l.beta.clamp(BETA_MIN, 1e4),
        };
        l.k.max(Vec3::ZERO).min(Vec3::splat(K_MAX)).max_element() * 0.398_942_3 / beta
    };
    1.0001 * (kd + p.lobes().iter().map(peak).sum::<f32>())
}

fn check(what: &str, i: usize, input: &BrdfEvalInput, out: &BrdfEvalOutput) -> Result<()> {
    let b = bound(input);
    for v in out.brdf.iter().chain(&out.lobe0).chain(&out.fiber) {
        if !(v.is_finite() && *v >= 0.0 && *v <= b) {
            bail!("{what}: input {i} gave {v}, outside [0, {b}]: {input:?}");
        }
    }
    Ok(())
}

/// brdf_eval.comp over `inputs`.
fn gpu_eval(device: &std::sync::Arc<Device>, pipeline: &Pipeline, set_layout: &DescriptorSetLayout, inputs: &[BrdfEvalInput]) -> Result<Vec<BrdfEvalOutput>> {
    let input = Buffer::with_data(device, "stress inputs", bytemuck::cast_slice(inputs), vk::BufferUsageFlags::STORAGE_BUFFER)?;
    let output = Buffer::new(device, "stress outputs", (inputs.len() * size_of::<BrdfEvalOutput>()) as u64, vk::BufferUsageFlags::STORAGE_BUFFER, MemoryLocation::GpuToCpu)?;
    let set = DescriptorSet::new(device, set_layout, &[Resource::Buffer(&input), Resource::Buffer(&output)])?;
    let n = inputs.len() as u32;
    device.record_and_run("stress brdf", |rec| {
        rec.bind_pipeline(pipeline);
        rec.bind_sets(pipeline, &[&set]);
        rec.push_constants(pipeline, bytemuck::bytes_of(&n));
        rec.dispatch(n.div_ceil(64), 1, 1);
    })?;
    Ok(bytemuck::pod_collect_to_vec(output.mapped().context("host-visible output")?))
}

pub fn run(brdf_inputs: usize, corrupt_files: usize) -> Result<()> {
    let device = Device::new(&DeviceOptions::default()).context("cannot open a Vulkan device")?;
    println!("stress on {} ({})", device.info().name, device.info().kind);
    // 1. The BRDF, both twins, in batches.
    let module = ShaderModule::embedded(&device, "brdf_eval.comp")?;
    let set_layout = DescriptorSetLayout::new(&device, &[BindingKind::StorageBuffer; 2], vk::ShaderStageFlags::COMPUTE)?;
    let layout = std::sync::Arc::new(PipelineLayout::new(&device, &[&set_layout], 4, vk::ShaderStageFlags::COMPUTE)?);
    let pipeline = Pipeline::compute(&device, "brdf_eval", &module, &layout, &Specialization::new())?;
    let t = Instant::now();
    let batch = 131_072;
    let mut done = 0;
    let mut k = 0u64;
    while done < brdf_inputs {
        let n = batch.min(brdf_inputs - done);
        let inputs = generate_inputs(n, 0x5757_0000 + k);
        let gpu = gpu_eval(&device, &pipeline, &set_layout, &inputs)?;
        for (i, (input, g)) in inputs.iter().zip(&gpu).enumerate() {
            check("GLSL twin", done + i, input, g)?;
            check("Rust twin", done + i, input, &input.evaluate())?;
        }
        done += n;
        k += 1;
    }
    println!("BRDF: {brdf_inputs} random and extreme inputs in both twins, all finite, non-negative and bounded ({:.1?})", t.elapsed());
    // 2. The reader over corrupted files.
    let t = Instant::now();
    let model = examples::sample_model();
    let good = format::to_bytes(&model)?;
    let mut rng = SplitMix64(0xbad_f11e);
    let (mut rejected, mut same) = (0usize, 0usize);
    for it in 0..corrupt_files {
        let kind = rng.next_u64() % format::mutate::KINDS;
        let b = format::mutate::mutate(&good, kind, &mut rng);
        match format::read(&b) {
            Err(_) => rejected += 1,
            Ok(m) if m == model => same += 1,
            Ok(_) => bail!("corrupt file {it}: the damaged bytes read as a different model"),
        }
    }
    println!("reader: {corrupt_files} corrupted files: {rejected} rejected with an error, {same} harmless (read as the original) ({:.1?})", t.elapsed());
    // 3. Both renderers under extreme cameras.
    let t = Instant::now();
    let m = examples::synthetic_model(64, 3);
    let pass = HybridPass::new(&device)?;
    let g = pass.upload(&m, true)?;
    let lights = [Light::directional(direction_from_angles(89.9, 30.0), Vec3::splat(1e3)), Light::Point { position: Vec3::new(0.5, 0.5, 0.1), intensity: Vec3::ONE }];
    let look = |o: Vec3, t: Vec3| Camera { origin: o, target: t, up: Vec3::Z, projection: Projection::Perspective { fov_x_deg: 90.0 }, width: 48, height: 48 };
    let cams = [
        Camera::orbit_orthographic(89.95, 10.0, Vec3::new(0.5, 0.5, 0.1), 3.0, 1.0, 48, 48),
        look(Vec3::new(0.5, 0.5, 0.05), Vec3::new(0.9, 0.7, 0.0)),
        look(Vec3::new(0.5, 0.5, 0.1 + 1e-7), Vec3::new(0.6, 0.5, 0.0)),
        look(Vec3::new(0.5, -1e6, 1e6), Vec3::new(0.5, 0.5, 0.0)),
    ];
    // A driver that ends a shader's loops early (lavapipe, at 65535 iterations per
    // invocation; the grazing cameras' marches pass it) draws those pixels wrong; the
    // frame counts them, and they are reported (runtime/GPU_MEASUREMENTS.md, "lavapipe's
    // loop budget").
    let mut cut = Vec::new();
    for (i, cam) in cams.iter().enumerate() {
        let opts = CpuRenderOptions { periodic: true, shadows: ShadowMode::On, ..Default::default() };
        let cpu = render(&m, cam, &lights, &opts)?;
        let frame = pass.render(&g, cam, &lights, &opts, None)?;
        if frame.stats.loop_cut_pixels > 0 {
            cut.push(format!("camera {i}: {} pixels past the driver's loop budget", frame.stats.loop_cut_pixels));
        }
        for img in [&cpu, &frame.image] {
            if img.first_non_finite().is_some() || img.pixels.iter().any(|p| p.min_element() < 0.0) {
                bail!("camera {i}: a non-finite or negative pixel");
            }
        }
    }
    let cut = if cut.is_empty() { String::new() } else { format!("; GPU: {}", cut.join(", ")) };
    println!("renderers: {} extreme cameras (grazing, inside the slab, a hair above it, 10⁶ away), CPU and GPU, all finite{cut} ({:.1?})", cams.len(), t.elapsed());
    let errors = device.validation_errors();
    if !errors.is_empty() {
        bail!("{} Vulkan validation error(s); first: {}", errors.len(), errors[0]);
    }
    println!("stress: passed");
    Ok(())
}
