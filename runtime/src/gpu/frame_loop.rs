//! The window's frame loop, independent of the window system: a swapchain on a surface,
//! an offscreen HDR target that the content draws into, and the tonemap pass that puts
//! it on screen. The content is a base mesh (the mesh pass) or a hybrid model drawn on a
//! base mesh (the hybrid mesh pass, with live camera, lights, options and edits).
//! `fabric view` (tools) owns the window and its events and calls [`FrameLoop::draw`].
//!
//! One frame in flight: [`Swapchain::acquire`] waits for the previous frame, after which
//! that frame's per-frame resources (the hybrid pass's [`MeshDraw`]) are replaced.

use std::sync::Arc;

use glam::{Vec2, Vec3};

use super::hybrid_pass::{GpuHybridModel, GpuRenderError, HybridMesh, HybridPass, MeshDraw, Variant};
use super::mesh_pass::{GpuMesh, MeshFrame, MeshPass};
use super::target::OffscreenTarget;
use super::tonemap::{DisplayImage, TonemapPass};
use crate::cpu::CpuRenderOptions;
use crate::scene::{Camera, Light};
use crate::vk::{Acquired, Device, Surface, Swapchain, Timestamps, vk};

/// What the window shows (one per window: the size difference of the variants is moot).
#[allow(clippy::large_enum_variant)]
pub enum ViewContent {
    /// A textured Lambertian base mesh under the first light.
    Mesh { pass: MeshPass, mesh: GpuMesh, frame: MeshFrame, base_color: Vec3 },
    /// A hybrid model tiled over a base mesh's UVs (`uv_scale` repeats per UV unit).
    Hybrid { pass: HybridPass, model: GpuHybridModel, mesh: HybridMesh, uv_scale: Vec2, draw: Option<MeshDraw> },
}

/// Everything that lives while the window is open. Fields drop in order: the passes and
/// their resources, then the swapchain, the surface and last the device.
pub struct FrameLoop {
    tonemap: TonemapPass,
    target: OffscreenTarget,
    content: ViewContent,
    timestamps: Timestamps,
    swapchain: Swapchain,
    surface: Arc<Surface>,
    device: Arc<Device>,
    /// Frames presented.
    pub frames: u32,
    /// GPU time of the content's pass in the last completed frame (ms).
    pub gpu_ms: f64,
    /// The variant the hybrid content was last drawn with.
    pub variant: Option<Variant>,
    resized: bool,
}

impl FrameLoop {
    pub fn new(device: &Arc<Device>, surface: Arc<Surface>, width: u32, height: u32, content: ViewContent) -> Result<FrameLoop, GpuRenderError> {
        let swapchain = Swapchain::new(device, &surface, width.max(1), height.max(1))?;
        let target = OffscreenTarget::new(device, swapchain.extent.width, swapchain.extent.height)?;
        let tonemap = TonemapPass::new(device, &target, swapchain.format, swapchain.is_srgb())?;
        let timestamps = Timestamps::new(device, 2)?;
        Ok(FrameLoop { tonemap, target, content, timestamps, swapchain, surface, device: device.clone(), frames: 0, gpu_ms: 0.0, variant: None, resized: false })
    }

    pub fn device(&self) -> &Arc<Device> {
        &self.device
    }

    /// The swapchain's size (what cameras should render at).
    pub fn extent(&self) -> (u32, u32) {
        (self.swapchain.extent.width, self.swapchain.extent.height)
    }

    pub fn swapchain_format(&self) -> vk::Format {
        self.swapchain.format
    }

    /// The window changed size: rebuild before the next frame.
    pub fn mark_resized(&mut self) {
        self.resized = true;
    }

    /// Rebuilds the size-dependent objects for `width` × `height` (0: minimized, kept).
    pub fn recreate(&mut self, width: u32, height: u32) -> Result<(), GpuRenderError> {
        if width == 0 || height == 0 {
            return Ok(());
        }
        self.device.wait_idle()?;
        // Drop the old swapchain's dependants before making the new one for the surface.
        let placeholder = OffscreenTarget::new(&self.device, 1, 1)?;
        self.tonemap = TonemapPass::new(&self.device, &placeholder, self.swapchain.format, self.swapchain.is_srgb())?;
        self.target = placeholder;
        self.swapchain = Swapchain::new(&self.device, &self.surface, width, height)?;
        self.target = OffscreenTarget::new(&self.device, self.swapchain.extent.width, self.swapchain.extent.height)?;
        self.tonemap = TonemapPass::new(&self.device, &self.target, self.swapchain.format, self.swapchain.is_srgb())?;
        self.resized = false;
        Ok(())
    }

    /// Draws and presents one frame of `camera` (resized to the swapchain) under
    /// `lights` with `options` (hybrid content), at `exposure`. `window_size` is the
    /// window's current size, used when it changed.
    pub fn draw(&mut self, window_size: (u32, u32), camera: &mut Camera, lights: &[Light], options: &CpuRenderOptions, exposure: f32) -> Result<(), GpuRenderError> {
        if self.resized {
            self.recreate(window_size.0, window_size.1)?;
        }
        let index = match self.swapchain.acquire()? {
            Acquired::Image(i) => i,
            Acquired::OutOfDate => {
                self.resized = true;
                return Ok(());
            }
        };
        // The previous frame has completed (acquire waited): its timings are readable and
        // its resources free.
        if self.frames > 0 {
            self.gpu_ms = self.timestamps.elapsed_ms(0, 1)?;
        }
        (camera.width, camera.height) = self.extent();
        match &mut self.content {
            ViewContent::Mesh { pass, mesh, frame, base_color } => {
                let light = lights.first().copied().unwrap_or(Light::directional(Vec3::Z, Vec3::ZERO));
                pass.update(frame, mesh, camera, &light, *base_color)?;
            }
            ViewContent::Hybrid { pass, model, mesh, uv_scale, draw } => {
                let d = pass.prepare_mesh(model, mesh, *uv_scale, camera, lights, options, None, &self.target)?;
                self.variant = Some(d.variant);
                *draw = Some(d);
            }
        }
        let (w, h) = self.extent();
        let (timestamps, target, content, tonemap) = (&self.timestamps, &self.target, &self.content, &self.tonemap);
        let presented = self.swapchain.submit_and_present(index, |rec, image, view| {
            rec.reset_timestamps(timestamps);
            rec.timestamp(timestamps, 0);
            match content {
                ViewContent::Mesh { pass, mesh, frame, .. } => pass.record(rec, target, mesh, frame),
                ViewContent::Hybrid { pass, mesh, draw, .. } => {
                    if let Some(d) = draw {
                        pass.record_mesh(rec, target, mesh, d);
                    }
                }
            }
            rec.timestamp(timestamps, 1);
            tonemap.record(rec, target, &DisplayImage { image, view, width: w, height: h }, exposure);
        })?;
        if !presented {
            self.resized = true;
        }
        self.frames += 1;
        Ok(())
    }

    /// Reads the last frame's linear image back.
    pub fn screenshot(&self) -> Result<crate::image::Image, GpuRenderError> {
        self.device.wait_idle()?;
        self.device.record_and_run("screenshot", |rec| self.target.record_readback_from(rec, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL))?;
        Ok(self.target.to_image()?)
    }
}

impl Drop for FrameLoop {
    fn drop(&mut self) {
        // The last frame may still be in flight: let it finish before the fields (its
        // pipelines, images and buffers) are destroyed.
        let _ = self.device.wait_idle();
    }
}
