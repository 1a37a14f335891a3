//! The GPU renderer of hybrid models on a tile seen by a camera: `shaders/hybrid.comp`,
//! the GLSL twin of the CPU renderer ([`crate::cpu`]), one compute invocation per pixel.
//!
//! Upload: the model's arrays ([`GpuModel`]) go into device-local storage buffers as
//! they are; each must fit one storage-buffer binding (lavapipe: 128 MiB), else the
//! upload fails naming the array. Variants: whether flyaways are marched, whether shadow
//! rays are cast and how many lights are looped over are specialization constants
//! ([`Variant`]), so a scene pays only for what it uses; pipelines are built per variant
//! on first use and kept.
//!
//! Options and validation are the CPU renderer's ([`CpuRenderOptions`]; the model is
//! validated once at upload, each frame's view by [`validate_view`]); the image and [`RenderStats`] come back as the CPU's do.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use glam::{Vec2, Vec3};

use crate::cpu::{CpuRenderError, CpuRenderOptions, LevelChoice, RenderStats, validate_view};
use crate::hybrid::HybridModel;
use crate::hybrid::gpu_layout::{GPU_ENV_SLOTS, GPU_MAX_LIGHTS, GpuCamera, GpuEnv, GpuLight, GpuModel, GpuRenderParams, LEVEL_AUTO, LEVEL_FIXED, LEVEL_NEAREST};
use crate::image::Image;
use super::mesh_pass::depth_range;
use super::target::{DEPTH_FORMAT, OffscreenTarget};
use crate::scene::{Camera, Light, Mesh};
use crate::vk::{BindingKind, Buffer, ColorTarget, DescriptorSet, GraphicsDesc, Image2d, Recorder, DescriptorSetLayout, Device, MemoryLocation, Pipeline, PipelineLayout, Resource, ShaderModule, Specialization, Timestamps, VkError, vk};

/// Why a GPU render cannot run.
#[derive(Debug, thiserror::Error)]
pub enum GpuRenderError {
    /// The model, camera, lights or options are invalid (the CPU renderer's checks).
    #[error(transparent)]
    Input(#[from] CpuRenderError),
    #[error(transparent)]
    Vulkan(#[from] VkError),
    #[error("{count} lights; the GPU renderer draws at most {GPU_MAX_LIGHTS} per frame")]
    TooManyLights { count: usize },
    #[error("the model was uploaded for a {} tile but the render asks for a {} one", if *.uploaded { "periodic" } else { "clamped" }, if *.uploaded { "clamped" } else { "periodic" })]
    Periodic { uploaded: bool },
    #[error("the prefiltered environment has more levels than the shader's 8 slots")]
    EnvUnsupported,
    #[error("{count} pixel(s) came out NaN or infinite, the first at ({x}, {y}): a bug in the renderer, please report it")]
    NonFinite { count: u32, x: u32, y: u32 },
}

/// What the shader is specialized for (constant ids 0–3 of
/// `shaders/common/render_params.glsl`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Variant {
    /// March the flyaway lists (off when the model has none).
    pub flyaways: bool,
    /// Cast height-field shadow rays.
    pub shadows: bool,
    /// Lights looped over.
    pub lights: u32,
    /// March the height field (false: a plain normal-mapped surface with the same
    /// BRDFs at the top plane, the benchmark's baseline).
    pub relief: bool,
    /// The lobe loop's bound: the most lobes of any BRDF in the model (1..=8).
    pub lobes: u32,
    /// Environment light.
    pub env: bool,
    /// A light behind the sheet on a model with a transmission term.
    pub transmission: bool,
    /// Lookups per axis of the coarse levels' box grid (`CoarseFilter::grid`; 1: one
    /// bilinear lookup per anisotropic tap).
    pub filter_grid: u32,
    /// Rays per axis of the flyaways' box grid (`CoarseFilter::fly_grid`; 1: one ray).
    pub fly_grid: u32,
    /// Rays per axis of the grid that gives their coverage (`CoarseFilter::cover_grid`;
    /// `fly_grid`: the same rays).
    pub cover_grid: u32,
    /// Whether the coverage grid's rays are shaded with the lights
    /// (`CoarseFilter::cover_shaded`).
    pub cover_shaded: bool,
}

impl Variant {
    fn specialization(&self) -> Specialization {
        Specialization::new().bool(0, self.flyaways && self.relief).bool(1, self.shadows).u32(2, self.lights).bool(3, self.relief).u32(4, self.lobes.clamp(1, 8)).bool(5, self.env).bool(6, self.transmission).u32(7, self.filter_grid.max(1)).u32(8, self.fly_grid.max(1)).u32(9, self.cover_grid.max(1)).bool(10, self.cover_shaded)
    }

    fn name(&self, pass: &str) -> String {
        format!("{pass} (flyaways {}, shadows {}, {} lights, relief {}, {} lobes, env {}, transmission {}, filter grid {}, flyaway grid {}, coverage grid {}, coverage shaded {})", self.flyaways, self.shadows, self.lights, self.relief, self.lobes, self.env, self.transmission, self.filter_grid, self.fly_grid, self.cover_grid, self.cover_shaded)
    }
}

/// A model in GPU buffers, laid out for a clamped or a periodic tile.
pub struct GpuHybridModel {
    buffers: Vec<Buffer>,
    pub periodic: bool,
    pub has_flyaways: bool,
    /// Whether the model has a transmission term (a BSDF).
    pub has_transmission: bool,
    pub levels: usize,
    /// The most lobes of any BRDF (surface or flyaway, any level).
    pub max_lobes: u32,
    /// Bytes uploaded.
    pub bytes: u64,
    /// The model itself, for validation of each render.
    model: HybridModel,
}

/// A base mesh in GPU buffers, for the mesh pass.
pub struct HybridMesh {
    vertices: Buffer,
    indices: Buffer,
    index_count: u32,
    pub triangles: usize,
    pub bounds: crate::scene::Aabb,
}

/// One prepared frame of the mesh pass ([`HybridPass::prepare_mesh`]).
pub struct MeshDraw {
    /// The visibility pass (hybrid_mesh_id.vert/.frag): each pixel's nearest triangle.
    ids_pipeline: Arc<Pipeline>,
    /// The shading pass (hybrid_mesh.comp): each pixel traced once from its triangle.
    pipeline: Arc<Pipeline>,
    /// Each pixel's triangle number + 1 (R32_UINT, 0: none), the target's size.
    ids: Image2d,
    set: DescriptorSet,
    _params: Buffer,
    _mask: Buffer,
    _env: Buffer,
    _unused: Buffer,
    push: MeshPush,
    pub variant: Variant,
    pub levels: usize,
}

/// One rendered frame.
pub struct HybridFrame {
    pub image: Image,
    pub stats: RenderStats,
    /// GPU time of the dispatch (timestamps), milliseconds.
    pub gpu_ms: f64,
    pub variant: Variant,
}

/// The compute pass (a tile seen by a camera) and the mesh pass (the tile on a base
/// mesh's UVs), and their pipelines.
pub struct HybridPass {
    device: Arc<Device>,
    set_layout: DescriptorSetLayout,
    layout: Arc<PipelineLayout>,
    module: ShaderModule,
    pipelines: Mutex<HashMap<Variant, Arc<Pipeline>>>,
    mesh_set_layout: DescriptorSetLayout,
    mesh_layout: Arc<PipelineLayout>,
    ids_vert: ShaderModule,
    ids_frag: ShaderModule,
    ids_pipeline: Mutex<Option<Arc<Pipeline>>>,
    mesh_module: ShaderModule,
    mesh_pipelines: Mutex<HashMap<Variant, Arc<Pipeline>>>,
}

/// The mesh pass's bindings: the compute pass's 0..=13 (9 and 10, its image and
/// statistics, unused), 14 and 15 the mesh's vertices and indices, 16 the triangle
/// numbers, 17 the target's colour image.
const MESH_BINDINGS: [BindingKind; 18] = {
    let mut kinds = [BindingKind::StorageBuffer; 18];
    kinds[16] = BindingKind::StorageImage;
    kinds[17] = BindingKind::StorageImage;
    kinds
};

/// The visibility pass's target format: a triangle number + 1 per pixel.
const TRIANGLE_ID_FORMAT: vk::Format = vk::Format::R32_UINT;

/// Push constants of the mesh pass (hybrid_mesh_id.vert, hybrid_mesh.comp). 80 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct MeshPush {
    view_proj: [[f32; 4]; 4],
    uv_scale: [f32; 2],
    pad: [f32; 2],
}

/// Statistics words written by the shader (STAT_* of hybrid.comp): 8 counters, the
/// pixels per level, and the pixels whose loops the driver cut (`STAT_LOOPS_CUT`).
const STAT_WORDS: usize = 8 + crate::hybrid::gpu_layout::GPU_MAX_LEVELS + 1;
const STAT_LOOPS_CUT: usize = 8 + crate::hybrid::gpu_layout::GPU_MAX_LEVELS;

impl HybridPass {
    pub fn new(device: &Arc<Device>) -> Result<HybridPass, GpuRenderError> {
        let module = ShaderModule::embedded_or_edited(device, "hybrid.comp")?;
        let set_layout = DescriptorSetLayout::new(device, &[BindingKind::StorageBuffer; 14], vk::ShaderStageFlags::COMPUTE)?;
        let layout = Arc::new(PipelineLayout::new(device, &[&set_layout], 0, vk::ShaderStageFlags::COMPUTE)?);
        let mesh_stages = vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::COMPUTE;
        let mesh_set_layout = DescriptorSetLayout::new(device, &MESH_BINDINGS, mesh_stages)?;
        let mesh_layout = Arc::new(PipelineLayout::new(device, &[&mesh_set_layout], size_of::<MeshPush>() as u32, mesh_stages)?);
        let ids_vert = ShaderModule::embedded_or_edited(device, "hybrid_mesh_id.vert")?;
        let ids_frag = ShaderModule::embedded_or_edited(device, "hybrid_mesh_id.frag")?;
        let mesh_module = ShaderModule::embedded_or_edited(device, "hybrid_mesh.comp")?;
        Ok(HybridPass {
            device: device.clone(),
            set_layout,
            layout,
            module,
            pipelines: Mutex::new(HashMap::new()),
            mesh_set_layout,
            mesh_layout,
            ids_vert,
            ids_frag,
            ids_pipeline: Mutex::new(None),
            mesh_module,
            mesh_pipelines: Mutex::new(HashMap::new()),
        })
    }

    pub fn device(&self) -> &Arc<Device> {
        &self.device
    }

    /// Uploads `model` for a clamped or `periodic` tile.
    pub fn upload(&self, model: &HybridModel, periodic: bool) -> Result<GpuHybridModel, GpuRenderError> {
        let layout = GpuModel::new(model, periodic).map_err(CpuRenderError::Model)?;
        let mut buffers = Vec::new();
        let mut bytes = 0;
        // Bindings 0..=6, then 12 (buffers[7]) and 13 (buffers[8]).
        for (name, data) in layout.arrays().into_iter().chain([layout.transmission_array(), layout.view_tilt_array()]) {
            bytes += data.len() as u64;
            buffers.push(Buffer::with_data(&self.device, name, &data, vk::BufferUsageFlags::STORAGE_BUFFER)?);
        }
        let max_lobes = layout.headers.iter().map(|h| h.lobe_count as u32).max().unwrap_or(1).max(1);
        Ok(GpuHybridModel { buffers, periodic, has_flyaways: model.has_flyaways(), has_transmission: model.has_transmission(), levels: model.levels.len(), max_lobes, bytes, model: model.clone() })
    }

    /// The variant a render of `model` with `options` under `lights` uses: the flyaway
    /// march only where the model has flyaways and the options want them; the
    /// transmission term only where the model has one and a light may be behind the
    /// sheet (`behind`).
    pub fn variant(model: &GpuHybridModel, lights: &[Light], behind: bool, shadows: bool, options: &CpuRenderOptions) -> Variant {
        Variant { flyaways: model.has_flyaways && options.flyaways, shadows, lights: lights.len() as u32, relief: true, lobes: model.max_lobes, env: options.env.is_some(), transmission: model.has_transmission && behind, filter_grid: options.coarse_filter.grid(), fly_grid: options.coarse_filter.fly_grid(), cover_grid: options.coarse_filter.cover_grid(), cover_shaded: options.coarse_filter.cover_shaded() }
    }

    /// Whether any of `lights` can be behind the tile's sheet (below its top plane, z up):
    /// a directional light from below, or a point light under the top plane; or the
    /// options' environment map has light below the horizon
    /// (`PrefilteredEnv::lights_below`, the CPU's rule for the map through the cloth).
    pub fn light_behind_tile(model: &GpuHybridModel, lights: &[Light], options: &CpuRenderOptions) -> bool {
        options.env.as_ref().is_some_and(|e| e.prefiltered.lights_below())
            || lights.iter().any(|l| match *l {
                Light::Directional { dir_to_light, .. } => dir_to_light.z < 0.0,
                Light::Point { position, .. } => position.z < model.model.tile.top_z,
            })
    }

    fn pipeline(&self, v: Variant) -> Result<Arc<Pipeline>, GpuRenderError> {
        let mut cache = self.pipelines.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(p) = cache.get(&v) {
            return Ok(p.clone());
        }
        let p = Arc::new(Pipeline::compute(&self.device, &v.name("hybrid"), &self.module, &self.layout, &v.specialization())?);
        cache.insert(v, p.clone());
        Ok(p)
    }

    fn mesh_pipeline(&self, v: Variant) -> Result<Arc<Pipeline>, GpuRenderError> {
        let mut cache = self.mesh_pipelines.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(p) = cache.get(&v) {
            return Ok(p.clone());
        }
        let p = Arc::new(Pipeline::compute(&self.device, &v.name("hybrid mesh"), &self.mesh_module, &self.mesh_layout, &v.specialization())?);
        cache.insert(v, p.clone());
        Ok(p)
    }

    /// The visibility pass's pipeline (one for every variant), built on first use.
    fn ids_pipeline(&self) -> Result<Arc<Pipeline>, GpuRenderError> {
        let mut slot = self.ids_pipeline.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(p) = slot.as_ref() {
            return Ok(p.clone());
        }
        let p = Arc::new(Pipeline::graphics(
            &self.device,
            &GraphicsDesc {
                name: "hybrid mesh triangles",
                vertex: &self.ids_vert,
                fragment: &self.ids_frag,
                layout: &self.mesh_layout,
                // Vertices pulled from bindings 14 and 15.
                vertex_stride: 0,
                vertex_attributes: &[],
                color_format: TRIANGLE_ID_FORMAT,
                depth_format: Some(DEPTH_FORMAT),
                cull: vk::CullModeFlags::NONE,
                specialization: Specialization::new(),
            },
        )?);
        *slot = Some(p.clone());
        Ok(p)
    }

    /// Uploads a base mesh for [`HybridPass::prepare_mesh`].
    pub fn upload_mesh(&self, mesh: &Mesh) -> Result<HybridMesh, GpuRenderError> {
        if mesh.indices.is_empty() || mesh.vertices.is_empty() {
            return Err(VkError::Invalid("mesh has no triangles".into()).into());
        }
        Ok(HybridMesh {
            vertices: Buffer::with_data(&self.device, "hybrid mesh vertices", bytemuck::cast_slice(&mesh.vertices), vk::BufferUsageFlags::STORAGE_BUFFER)?,
            indices: Buffer::with_data(&self.device, "hybrid mesh indices", bytemuck::cast_slice(&mesh.indices), vk::BufferUsageFlags::STORAGE_BUFFER)?,
            index_count: mesh.indices.len() as u32,
            triangles: mesh.indices.len() / 3,
            bounds: mesh.bounds(),
        })
    }

    /// Everything one frame of `model` on `mesh` needs (`uv_scale` repeats of the tile
    /// per UV unit, seen by `camera` under `lights`, drawn into `target`, whose size is
    /// the camera's): validated, buffers written. Keep it alive until the frame that
    /// records it has completed.
    #[allow(clippy::too_many_arguments)] // render's arguments plus the mesh, its UV scale and the target
    pub fn prepare_mesh(&self, model: &GpuHybridModel, mesh: &HybridMesh, uv_scale: Vec2, camera: &Camera, lights: &[Light], options: &CpuRenderOptions, variant: Option<Variant>, target: &OffscreenTarget) -> Result<MeshDraw, GpuRenderError> {
        let lights = &options.lights_with_env(lights)[..];
        let shadows = validate_view(&model.model, camera, lights, options)?;
        if lights.len() > GPU_MAX_LIGHTS {
            return Err(GpuRenderError::TooManyLights { count: lights.len() });
        }
        if !model.periodic {
            return Err(GpuRenderError::Periodic { uploaded: false });
        }
        if !(uv_scale.is_finite() && uv_scale.min_element() > 0.0) {
            return Err(CpuRenderError::Options(format!("UV scale {uv_scale} must be positive and finite")).into());
        }
        // On a mesh every light, and every part of a map, is behind some fragment.
        let variant = variant.unwrap_or(HybridPass::variant(model, lights, !lights.is_empty() || options.env.is_some(), shadows, options));
        let pipeline = self.mesh_pipeline(variant)?;
        let (env, env_buf) = self.env_upload(options, true)?;
        let (params, mask) = self.params_buffers(camera, lights, options, env.as_ref())?;
        // Bindings 9 and 10 are the compute pass's image and statistics: unused here.
        let unused = Buffer::with_data(&self.device, "unused binding", &[0u8; 16], vk::BufferUsageFlags::STORAGE_BUFFER)?;
        let mut resources: Vec<Resource<'_>> = model.buffers[..7].iter().map(Resource::Buffer).collect();
        if (target.color.width, target.color.height) != (camera.width, camera.height) {
            return Err(VkError::Invalid(format!("target {}x{} for a {}x{} camera", target.color.width, target.color.height, camera.width, camera.height)).into());
        }
        let ids = Image2d::new(&self.device, "hybrid mesh triangles", camera.width, camera.height, TRIANGLE_ID_FORMAT, vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::STORAGE)?;
        resources.extend([Resource::Buffer(&params), Resource::Buffer(&mask), Resource::Buffer(&unused), Resource::Buffer(&unused), Resource::Buffer(&env_buf), Resource::Buffer(&model.buffers[7]), Resource::Buffer(&model.buffers[8])]);
        resources.extend([Resource::Buffer(&mesh.vertices), Resource::Buffer(&mesh.indices), Resource::Storage(&ids), Resource::Storage(&target.color)]);
        let set = DescriptorSet::new(&self.device, &self.mesh_set_layout, &resources)?;
        let (near, far) = depth_range(camera, mesh.bounds);
        let push = MeshPush { view_proj: (camera.projection_matrix(near, far) * camera.view_matrix()).to_cols_array_2d(), uv_scale: uv_scale.to_array(), pad: [0.0; 2] };
        let ids_pipeline = self.ids_pipeline()?;
        Ok(MeshDraw { ids_pipeline, pipeline, ids, set, _params: params, _mask: mask, _env: env_buf, _unused: unused, push, variant, levels: model.levels })
    }

    /// Records `draw` of `mesh` into `target` (the one `draw` was prepared for): the
    /// visibility pass leaves each pixel its nearest triangle, then the compute pass
    /// shades every pixel once — the fabric where a triangle is, the environment or the
    /// background elsewhere. The color image is left in COLOR_ATTACHMENT_OPTIMAL.
    pub fn record_mesh(&self, rec: &Recorder<'_>, target: &OffscreenTarget, mesh: &HybridMesh, draw: &MeshDraw) {
        target.record_begin(rec);
        rec.image_barrier(&draw.ids, vk::ImageLayout::UNDEFINED, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL);
        // 0: no triangle (the float 0.0's bits are the integer 0).
        rec.begin_rendering(&ColorTarget { image: &draw.ids, clear: [0.0; 4] }, Some(&target.depth));
        rec.bind_pipeline(&draw.ids_pipeline);
        rec.bind_sets(&draw.ids_pipeline, &[&draw.set]);
        rec.push_constants(&draw.ids_pipeline, bytemuck::bytes_of(&draw.push));
        rec.draw(mesh.index_count);
        rec.end_rendering();
        rec.image_barrier(&draw.ids, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::ImageLayout::GENERAL);
        rec.image_barrier(&target.color, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::ImageLayout::GENERAL);
        rec.bind_pipeline(&draw.pipeline);
        rec.bind_sets(&draw.pipeline, &[&draw.set]);
        rec.push_constants(&draw.pipeline, bytemuck::bytes_of(&draw.push));
        rec.dispatch(target.color.width.div_ceil(8), target.color.height.div_ceil(8), 1);
        rec.image_barrier(&target.color, vk::ImageLayout::GENERAL, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL);
    }

    /// Renders `model` (uploaded periodic: the tile repeats) on `mesh`, `uv_scale`
    /// repeats of the tile per UV unit, seen by `camera` under `lights`, one sample per
    /// pixel (hybrid_mesh.comp states how the tile is mapped and where this differs
    /// from [`HybridPass::render`]).
    #[allow(clippy::too_many_arguments)] // render's arguments plus the mesh and its UV scale
    pub fn render_mesh(&self, model: &GpuHybridModel, mesh: &Mesh, uv_scale: Vec2, camera: &Camera, lights: &[Light], options: &CpuRenderOptions, variant: Option<Variant>) -> Result<HybridFrame, GpuRenderError> {
        let gpu_mesh = self.upload_mesh(mesh)?;
        let target = OffscreenTarget::new(&self.device, camera.width, camera.height)?;
        let draw = self.prepare_mesh(model, &gpu_mesh, uv_scale, camera, lights, options, variant, &target)?;
        let timestamps = Timestamps::new(&self.device, 2)?;
        self.device.record_and_run("hybrid mesh pass", |rec| {
            rec.reset_timestamps(&timestamps);
            rec.timestamp(&timestamps, 0);
            self.record_mesh(rec, &target, &gpu_mesh, &draw);
            rec.timestamp(&timestamps, 1);
            target.record_readback(rec);
        })?;
        let image = target.to_image()?;
        if let Some((x, y, _)) = image.first_non_finite() {
            return Err(GpuRenderError::NonFinite { count: image.pixels.iter().filter(|p| !p.is_finite()).count() as u32, x, y });
        }
        let loop_cut_pixels = target.zero_alpha_pixels()? as u64;
        let stats = RenderStats { pixels: camera.width as u64 * camera.height as u64, level_pixels: vec![0; model.levels], loop_cut_pixels, ..Default::default() };
        Ok(HybridFrame { image, stats, gpu_ms: timestamps.elapsed_ms(0, 1)?, variant: draw.variant })
    }

    /// The prefiltered environment of `options` laid out for binding 11, and the
    /// binding's buffer (one zero texel without a map: the binding is always bound).
    /// The environment's levels (binding 11) and its parameters; on a mesh (`mesh`) the
    /// whole map may light a fragment's transmission term from behind.
    fn env_upload(&self, options: &CpuRenderOptions, mesh: bool) -> Result<(Option<GpuEnv>, Buffer), GpuRenderError> {
        let env = match &options.env {
            Some(e) => {
                let mut g = GpuEnv::new(&e.prefiltered, e.background).ok_or(GpuRenderError::EnvUnsupported)?;
                g.info[2] |= mesh as u32;
                g.info[3] = mesh as u32;
                Some(g)
            }
            None => None,
        };
        let texels: &[[f32; 4]] = env.as_ref().map_or(&[[0.0; 4]][..], |e| &e.texels);
        let buf = Buffer::with_data(&self.device, "hybrid environment", bytemuck::cast_slice(texels), vk::BufferUsageFlags::STORAGE_BUFFER)?;
        Ok((env, buf))
    }

    /// The frame's parameters and its edit mask, in host-visible buffers.
    fn params_buffers(&self, camera: &Camera, lights: &[Light], options: &CpuRenderOptions, env: Option<&GpuEnv>) -> Result<(Buffer, Buffer), GpuRenderError> {
        let (level_mode, fixed_level, level_bias) = match options.level {
            LevelChoice::Auto { bias } => (LEVEL_AUTO, 0, bias),
            LevelChoice::Nearest { bias } => (LEVEL_NEAREST, 0, bias),
            LevelChoice::Fixed(l) => (LEVEL_FIXED, l, 0.0),
        };
        let mut gpu_lights = [GpuLight::default(); GPU_MAX_LIGHTS];
        for (g, l) in gpu_lights.iter_mut().zip(lights) {
            *g = GpuLight::new(l);
        }
        let e = &options.edits;
        let params = GpuRenderParams {
            camera: GpuCamera::new(camera),
            background: options.background.extend(0.0).to_array(),
            light_count: lights.len() as u32,
            max_steps: options.max_steps,
            max_flyaway_columns: options.max_flyaway_columns,
            supersampling: options.supersampling,
            level_mode,
            fixed_level,
            level_bias,
            coarse_relief: options.coarse_relief as u32,
            edit_tint: e.tint.extend(0.0).to_array(),
            edit_roughness: e.roughness_scale,
            edit_rotation: e.tangent_rotation,
            mask_dims: e.mask.as_ref().map_or([0, 0], |m| [m.width, m.height]),
            lights: gpu_lights,
            env_info: env.map_or([0; 4], |e| e.info),
            env_frame: env.map_or([0.0; 4], |e| e.frame),
            env_levels: env.map_or([[0; 4]; GPU_ENV_SLOTS], |e| e.levels),
        };
        let buf = Buffer::new(&self.device, "hybrid params", size_of::<GpuRenderParams>() as u64, vk::BufferUsageFlags::STORAGE_BUFFER, MemoryLocation::CpuToGpu)?;
        buf.write_mapped(bytemuck::bytes_of(&params))?;
        let mask: &[f32] = e.mask.as_ref().map_or(&[0.0][..], |m| &m.values);
        let mask_buf = Buffer::new(&self.device, "edit mask", (mask.len() * 4) as u64, vk::BufferUsageFlags::STORAGE_BUFFER, MemoryLocation::CpuToGpu)?;
        mask_buf.write_mapped(bytemuck::cast_slice(mask))?;
        Ok((buf, mask_buf))
    }

    /// Renders `model` seen by `camera` under `lights` with `options` (the CPU
    /// renderer's; `options.periodic` must match the upload). `variant` overrides the
    /// specialization (tests and benchmarks of the skips); None: what the scene needs.
    pub fn render(&self, model: &GpuHybridModel, camera: &Camera, lights: &[Light], options: &CpuRenderOptions, variant: Option<Variant>) -> Result<HybridFrame, GpuRenderError> {
        self.render_frames(model, camera, lights, options, variant, 1)
    }

    /// [`HybridPass::render`] `frames` times back to back in one submission; its
    /// `gpu_ms` is the time per frame. A real-time loop's figure: separate `render`
    /// calls leave the GPU idle between frames (the image's readback), and a discrete
    /// GPU's clocks drop in those gaps, so their times vary by 2–4× from call to call.
    pub fn render_back_to_back(&self, model: &GpuHybridModel, camera: &Camera, lights: &[Light], options: &CpuRenderOptions, variant: Option<Variant>, frames: u32) -> Result<HybridFrame, GpuRenderError> {
        self.render_frames(model, camera, lights, options, variant, frames.max(1))
    }

    fn render_frames(&self, model: &GpuHybridModel, camera: &Camera, lights: &[Light], options: &CpuRenderOptions, variant: Option<Variant>, frames: u32) -> Result<HybridFrame, GpuRenderError> {
        // The environment's sources are lights like the others (as the CPU's render).
        let lights = &options.lights_with_env(lights)[..];
        let shadows = validate_view(&model.model, camera, lights, options)?;
        if lights.len() > GPU_MAX_LIGHTS {
            return Err(GpuRenderError::TooManyLights { count: lights.len() });
        }
        if options.periodic != model.periodic {
            return Err(GpuRenderError::Periodic { uploaded: model.periodic });
        }
        let (env, env_buf) = self.env_upload(options, false)?;
        let variant = variant.unwrap_or(HybridPass::variant(model, lights, HybridPass::light_behind_tile(model, lights, options), shadows, options));
        let pipeline = self.pipeline(variant)?;
        let dev = &self.device;
        let (param_buf, mask_buf) = self.params_buffers(camera, lights, options, env.as_ref())?;
        let (w, h) = (camera.width, camera.height);
        // Device-local: on a discrete GPU the shader must not write across the bus.
        let pixels = Buffer::new(dev, "hybrid image", w as u64 * h as u64 * 16, vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC, MemoryLocation::GpuOnly)?;
        let stats = Buffer::new(dev, "hybrid stats", (STAT_WORDS * 4) as u64, vk::BufferUsageFlags::STORAGE_BUFFER, MemoryLocation::CpuToGpu)?;
        stats.write_mapped(&[0u8; STAT_WORDS * 4])?;
        let mut resources: Vec<Resource<'_>> = model.buffers[..7].iter().map(Resource::Buffer).collect();
        resources.extend([Resource::Buffer(&param_buf), Resource::Buffer(&mask_buf), Resource::Buffer(&pixels), Resource::Buffer(&stats), Resource::Buffer(&env_buf), Resource::Buffer(&model.buffers[7]), Resource::Buffer(&model.buffers[8])]);
        let set = DescriptorSet::new(dev, &self.set_layout, &resources)?;
        let timestamps = Timestamps::new(dev, 2)?;
        dev.record_and_run("hybrid pass", |rec| {
            rec.reset_timestamps(&timestamps);
            rec.timestamp(&timestamps, 0);
            rec.bind_pipeline(&pipeline);
            rec.bind_sets(&pipeline, &[&set]);
            for k in 0..frames {
                if k > 0 {
                    // Each frame after the last, as in a frame loop.
                    rec.memory_barrier();
                }
                rec.dispatch(w.div_ceil(8), h.div_ceil(8), 1);
            }
            rec.timestamp(&timestamps, 1);
            rec.memory_barrier();
        })?;
        let gpu_ms = timestamps.elapsed_ms(0, 1)? / frames as f64;
        let raw: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&pixels.download()?);
        let mut words: Vec<u32> = bytemuck::pod_collect_to_vec(stats.mapped().ok_or_else(|| VkError::Invalid("hybrid stats are not host-visible".into()))?);
        if frames > 1 {
            // Every frame counted the same pixels.
            let steps = (words[6] as u64 | (words[7] as u64) << 32) / frames as u64;
            words.iter_mut().for_each(|v| *v /= frames);
            (words[6], words[7]) = (steps as u32, (steps >> 32) as u32);
        }
        let non_finite = words[5];
        if non_finite > 0 {
            let k = raw.iter().position(|p| p[3] == 0.0).unwrap_or(0) as u32;
            return Err(GpuRenderError::NonFinite { count: non_finite, x: k % w, y: k / w });
        }
        let image = Image { width: w, height: h, pixels: raw.iter().map(|p| Vec3::new(p[0], p[1], p[2])).collect() };
        let levels = model.levels;
        let stats = RenderStats {
            pixels: w as u64 * h as u64,
            tile_pixels: words[0] as u64,
            surface_pixels: words[1] as u64,
            flyaway_pixels: words[2] as u64,
            level_pixels: words[8..8 + levels].iter().map(|&v| v as u64).collect(),
            step_limited_pixels: words[3] as u64,
            step_limited_shadow_rays: words[4] as u64,
            camera_steps: words[6] as u64 | (words[7] as u64) << 32,
            loop_cut_pixels: words[STAT_LOOPS_CUT] as u64,
        };
        Ok(HybridFrame { image, stats, gpu_ms, variant })
    }
}
