//! `fabric render`: draws a base mesh, or a hybrid model (`MODEL.hyb`) on the GPU
//! (printing the device and the GPU frame time) or with the CPU renderer of hybrid
//! models, and writes the image.

use anyhow::{Context, Result};
use clap::Args;
use fabric_runtime::gpu::MeshPass;
use fabric_runtime::hybrid::HybridModel;
use fabric_runtime::scene::{Light, Mesh};
use fabric_runtime::vk::{Device, DeviceOptions};

use super::render_cpu::CpuRenderFlags;
use crate::args::{CameraArgs, EnvArgs, LightArgs, MeshSceneArgs, OutputArgs};

/// Which renderer draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Backend {
    /// The GPU; for hybrid models the CPU renderer when no Vulkan device opens (said
    /// on the terminal).
    Auto,
    /// The Vulkan renderer.
    Gpu,
    /// The CPU renderer of hybrid models (rayon), the specification of the shading.
    Cpu,
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// A hybrid model (.hyb) to render; without it a base mesh is drawn.
    pub model: Option<std::path::PathBuf>,
    /// Renderer.
    #[arg(long, value_enum, default_value = "auto")]
    pub backend: Backend,
    #[command(flatten)]
    pub scene: MeshSceneArgs,
    /// Frames to render; the GPU time reported is the median (the first frame pays
    /// for shader JIT on lavapipe).
    #[arg(long, default_value_t = 3)]
    pub repeat: u32,
    #[command(flatten)]
    pub camera: CameraArgs,
    #[command(flatten)]
    pub light: LightArgs,
    #[command(flatten)]
    pub env: EnvArgs,
    #[command(flatten)]
    pub output: OutputArgs,
    #[command(flatten)]
    pub cpu: CpuRenderFlags,
}

pub fn run(args: RenderArgs) -> Result<()> {
    args.output.validate()?;
    if !(1..=crate::args::MAX_REPEAT).contains(&args.repeat) {
        anyhow::bail!("--repeat {}: frames to render, 1 to {}", args.repeat, crate::args::MAX_REPEAT);
    }
    if let Some(model) = &args.model {
        if args.backend == Backend::Cpu && args.scene.mesh.is_some() {
            anyhow::bail!("--mesh draws the fabric on a mesh, which only the GPU renderer does; the CPU renderer draws the tile on its plane");
        }
        let device = match args.backend {
            Backend::Cpu => None,
            Backend::Gpu => Some(super::render_gpu::open_device(&args.scene.device)?),
            Backend::Auto if args.scene.mesh.is_some() => Some(super::render_gpu::open_device(&args.scene.device)?),
            Backend::Auto => match super::render_gpu::open_device(&args.scene.device) {
                Ok(d) => Some(d),
                Err(e) => {
                    println!("note: {e:#}; rendering with the CPU renderer instead (--backend cpu says so up front)");
                    None
                }
            },
        };
        return match device {
            Some(device) => {
                println!("backend: GPU renderer of hybrid models");
                super::render_gpu::run(device, model, args.scene.mesh.as_deref(), args.scene.uv_scale, &args.camera, &args.light, &args.env, &args.output, &args.cpu, args.repeat)
            }
            None => {
                println!("backend: CPU renderer of hybrid models");
                super::render_cpu::run(model, &args.camera, &args.light, &args.env, &args.output, &args.cpu)
            }
        };
    }
    if args.backend == Backend::Cpu {
        anyhow::bail!("--backend cpu renders hybrid models (give MODEL.hyb); meshes are drawn on the GPU");
    }
    let mesh = Mesh::by_name(args.scene.mesh.as_deref().unwrap_or("sphere"))?;
    let camera = args.camera.camera(mesh.bounds())?;
    let light = args.light.light()?;
    let device = Device::new(&DeviceOptions { name: args.scene.device.clone(), ..Default::default() }).context("cannot open a Vulkan device")?;
    let info = device.info();
    println!("device: {} ({}, driver {})", info.name, info.kind, info.driver);
    let pass = MeshPass::new(&device)?;
    let mut times = Vec::new();
    let mut frame = None;
    for _ in 0..args.repeat.max(1) {
        let f = pass.render(&mesh, &camera, &light, args.scene.base_color)?;
        times.push(f.gpu_ms);
        frame = Some(f);
    }
    let frame = frame.context("no frame rendered")?;
    frame.image.write(&args.output.out, args.output.exposure)?;
    let errors = device.validation_errors();
    if !errors.is_empty() {
        anyhow::bail!("{} Vulkan validation error(s); first: {}", errors.len(), errors[0]);
    }
    times.sort_by(f64::total_cmp);
    println!(
        "mesh '{}' ({} triangles) at {}x{}: GPU frame time {:.3} ms (median of {}, min {:.3} ms) on {}",
        args.scene.mesh.as_deref().unwrap_or("sphere"),
        mesh.indices.len() / 3,
        camera.width,
        camera.height,
        times[times.len() / 2],
        times.len(),
        times[0],
        info.name
    );
    println!("wrote {}", args.output.out.display());
    Ok(())
}

/// Says when no light reaches the tile from above — every light a directional one at or
/// below the tile's plane (polar angle ≥ 90°) or a point light below its box, and no
/// environment map — which leaves a model without a transmission term black.
pub(super) fn warn_if_lit_from_below(model: &HybridModel, lights: &[Light], env: bool) {
    let bottom = model.bounds().min.z;
    let above = |l: &Light| match l {
        Light::Directional { dir_to_light, .. } => dir_to_light.z > 0.0,
        Light::Point { position, .. } => position.z > bottom,
    };
    if env || lights.is_empty() || lights.iter().any(above) {
        return;
    }
    if model.has_transmission() {
        println!("note: the light is below the tile: only the model's transmission term shades it (light through the cloth)");
    } else {
        println!("warning: the light is below the tile (a direction at 90° or more from its normal, or a point below its box) and the model has no transmission term (fabric bake --bsdf): no light reaches what the camera sees, and the image is black but for the background");
    }
}

/// A frame in which no pixel met the tile is the background alone: say why, rather than
/// write an empty image without a word.
pub(super) fn warn_if_tile_unseen(tile_pixels: u64) {
    if tile_pixels == 0 {
        println!("warning: no pixel sees the tile: the camera is below its top plane or looks away from it (a hybrid model is drawn from above; --view-angles takes θ < 90°); the image is the background");
    }
}
