//! The mesh pass: a textured Lambertian base mesh under one light
//! (shaders/mesh.vert + shaders/mesh_lit.frag). The first thing the GPU renderer
//! draws, and the check that cameras, lights and read-back agree with the CPU side.

use std::sync::Arc;

use glam::Vec3;

use super::frame::FrameUniforms;
use super::target::{COLOR_FORMAT, DEPTH_FORMAT, OffscreenTarget};
use crate::scene::{Camera, Light, Mesh, Vertex};
use ash::vk;

use crate::vk::{
    BindingKind, Buffer, ColorTarget, Recorder, DescriptorSet, DescriptorSetLayout, Device, GraphicsDesc, Image2d, MemoryLocation, Pipeline, PipelineLayout, Resource, Sampler, ShaderModule,
    Specialization, Timestamps, VkError, VkResult,
};

/// A 64×64 sRGB checkerboard (8×8 checks) with a red mark in the (u, v) = (0, 0)
/// corner and a green one at (1, 0), so UV orientation is visible in images.
pub fn checker_texture() -> (u32, u32, Vec<u8>) {
    let n = 64u32;
    let mut data = Vec::with_capacity((n * n * 4) as usize);
    // Row r of the texture is v = (r + 0.5)/n: Vulkan samples row 0 at v = 0.
    for r in 0..n {
        for c in 0..n {
            let check = ((c / 8) + (r / 8)) % 2 == 0;
            let mut rgb = if check { [204u8, 204, 204] } else { [90, 115, 180] };
            if r < 8 && c < 8 {
                rgb = [220, 40, 40];
            } else if r < 8 && c >= n - 8 {
                rgb = [40, 200, 60];
            }
            data.extend_from_slice(&[rgb[0], rgb[1], rgb[2], 255]);
        }
    }
    (n, n, data)
}

/// Pipeline and resources of the mesh pass, reusable across frames.
pub struct MeshPass {
    device: Arc<Device>,
    pipeline: Pipeline,
    set_layout: DescriptorSetLayout,
    texture: Image2d,
    sampler: Sampler,
}

/// One rendered frame.
pub struct RenderedFrame {
    pub image: crate::image::Image,
    /// GPU time of the draw, from timestamp queries.
    pub gpu_ms: f64,
}

impl MeshPass {
    pub fn new(device: &Arc<Device>) -> VkResult<MeshPass> {
        let set_layout = DescriptorSetLayout::new(device, &[BindingKind::UniformBuffer, BindingKind::SampledImage], vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT)?;
        let layout = Arc::new(PipelineLayout::new(device, &[&set_layout], 0, vk::ShaderStageFlags::empty())?);
        let vert = ShaderModule::embedded(device, "mesh.vert")?;
        let frag = ShaderModule::embedded(device, "mesh_lit.frag")?;
        let f = vk::Format::R32G32B32_SFLOAT;
        let pipeline = Pipeline::graphics(
            device,
            &GraphicsDesc {
                name: "mesh lit",
                vertex: &vert,
                fragment: &frag,
                layout: &layout,
                vertex_stride: core::mem::size_of::<Vertex>() as u32,
                vertex_attributes: &[(f, 0), (f, 12), (vk::Format::R32G32B32A32_SFLOAT, 24), (vk::Format::R32G32_SFLOAT, 40)],
                color_format: COLOR_FORMAT,
                depth_format: Some(DEPTH_FORMAT),
                cull: vk::CullModeFlags::NONE,
                specialization: Specialization::new(),
            },
        )?;
        let (tw, th, texels) = checker_texture();
        let texture = Image2d::new(device, "checker", tw, th, vk::Format::R8G8B8A8_SRGB, vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST)?;
        texture.upload(&texels, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL)?;
        let sampler = Sampler::new(device, true)?;
        Ok(MeshPass { device: device.clone(), pipeline, set_layout, texture, sampler })
    }

    /// Uploads a mesh for drawing.
    pub fn upload(&self, mesh: &Mesh) -> VkResult<GpuMesh> {
        if mesh.indices.is_empty() || mesh.vertices.is_empty() {
            return Err(VkError::Invalid("mesh has no triangles".into()));
        }
        Ok(GpuMesh {
            vertices: Buffer::with_data(&self.device, "mesh vertices", bytemuck::cast_slice(&mesh.vertices), vk::BufferUsageFlags::VERTEX_BUFFER)?,
            indices: Buffer::with_data(&self.device, "mesh indices", bytemuck::cast_slice(&mesh.indices), vk::BufferUsageFlags::INDEX_BUFFER)?,
            index_count: mesh.indices.len() as u32,
            bounds: mesh.bounds(),
        })
    }

    /// Per-frame resources (uniform buffer and descriptor set); reuse them across frames
    /// once the previous frame has completed.
    pub fn frame_resources(&self) -> VkResult<MeshFrame> {
        let ubo = Buffer::new(&self.device, "frame uniforms", core::mem::size_of::<FrameUniforms>() as u64, vk::BufferUsageFlags::UNIFORM_BUFFER, MemoryLocation::CpuToGpu)?;
        let set = DescriptorSet::new(&self.device, &self.set_layout, &[Resource::Buffer(&ubo), Resource::Sampled(&self.texture, &self.sampler)])?;
        Ok(MeshFrame { ubo, set })
    }

    /// Writes the frame's uniforms (the GPU must not be using `frame`).
    pub fn update(&self, frame: &MeshFrame, mesh: &GpuMesh, camera: &Camera, light: &Light, base_color: Vec3) -> VkResult<()> {
        let (near, far) = depth_range(camera, mesh.bounds);
        frame.ubo.write_mapped(bytemuck::bytes_of(&FrameUniforms::new(camera, light, base_color, near, far)))
    }

    /// Records the draw into `target` (attachments transitioned here; the color image
    /// is left in COLOR_ATTACHMENT_OPTIMAL).
    pub fn record(&self, rec: &Recorder<'_>, target: &OffscreenTarget, mesh: &GpuMesh, frame: &MeshFrame) {
        target.record_begin(rec);
        rec.begin_rendering(&ColorTarget { image: &target.color, clear: [0.0, 0.0, 0.0, 1.0] }, Some(&target.depth));
        rec.bind_pipeline(&self.pipeline);
        rec.bind_sets(&self.pipeline, &[&frame.set]);
        rec.bind_vertex_buffer(&mesh.vertices);
        rec.bind_index_buffer_u32(&mesh.indices);
        rec.draw_indexed(mesh.index_count);
        rec.end_rendering();
    }

    /// Renders `mesh` offscreen and reads the image back.
    pub fn render(&self, mesh: &Mesh, camera: &Camera, light: &Light, base_color: Vec3) -> VkResult<RenderedFrame> {
        let gpu_mesh = self.upload(mesh)?;
        let frame = self.frame_resources()?;
        self.update(&frame, &gpu_mesh, camera, light, base_color)?;
        let target = OffscreenTarget::new(&self.device, camera.width, camera.height)?;
        let timestamps = Timestamps::new(&self.device, 2)?;
        self.device.record_and_run("mesh pass", |rec| {
            rec.reset_timestamps(&timestamps);
            rec.timestamp(&timestamps, 0);
            self.record(rec, &target, &gpu_mesh, &frame);
            rec.timestamp(&timestamps, 1);
            target.record_readback(rec);
        })?;
        Ok(RenderedFrame { image: target.to_image()?, gpu_ms: timestamps.elapsed_ms(0, 1)? })
    }
}

/// A mesh in GPU buffers.
pub struct GpuMesh {
    vertices: Buffer,
    indices: Buffer,
    index_count: u32,
    pub bounds: crate::scene::Aabb,
}

/// Uniforms and descriptor set of one frame of the mesh pass.
pub struct MeshFrame {
    ubo: Buffer,
    set: DescriptorSet,
}

/// Near and far planes that enclose `bounds` as seen from the camera.
pub fn depth_range(camera: &Camera, bounds: crate::scene::Aabb) -> (f32, f32) {
    let f = camera.frame().forward;
    let c = bounds.center();
    let r = 0.5 * bounds.size().length().max(1e-6);
    let d = (c - camera.origin).dot(f);
    let far = (d + r) * 1.01 + 1e-4;
    match camera.projection {
        crate::scene::Projection::Perspective { .. } => ((d - r).max(far * 1e-4), far),
        crate::scene::Projection::Orthographic { .. } => (d - r - 1e-3 * r, far),
    }
}
