//! A safe recorder over one command buffer in the recording state, so code outside
//! this module never calls Vulkan directly. Every method records one command; the
//! validation layer (on in tests) checks the rest.

use ash::vk;

use super::buffer::Buffer;
use super::descriptor::DescriptorSet;
use super::device::Device;
use super::image::{Image2d, record_image_barrier, record_memory_barrier};
use super::pipeline::Pipeline;
use super::timing::Timestamps;

pub struct Recorder<'a> {
    pub(crate) device: &'a Device,
    pub(crate) cb: vk::CommandBuffer,
}

/// A color attachment for [`Recorder::begin_rendering`].
pub struct ColorTarget<'a> {
    pub image: &'a Image2d,
    pub clear: [f32; 4],
}

impl<'a> Recorder<'a> {
    pub fn raw(&self) -> vk::CommandBuffer {
        self.cb
    }

    /// Begins dynamic rendering into `color` (COLOR_ATTACHMENT_OPTIMAL) and optionally
    /// `depth` (DEPTH_ATTACHMENT_OPTIMAL, cleared to 1), with a full-size viewport.
    pub fn begin_rendering(&self, color: &ColorTarget<'_>, depth: Option<&Image2d>) {
        let (w, h) = (color.image.width, color.image.height);
        let color_att = [vk::RenderingAttachmentInfo::default()
            .image_view(color.image.view)
            .image_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
            .load_op(vk::AttachmentLoadOp::CLEAR)
            .store_op(vk::AttachmentStoreOp::STORE)
            .clear_value(vk::ClearValue { color: vk::ClearColorValue { float32: color.clear } })];
        let depth_att = depth.map(|d| {
            vk::RenderingAttachmentInfo::default()
                .image_view(d.view)
                .image_layout(vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL)
                .load_op(vk::AttachmentLoadOp::CLEAR)
                .store_op(vk::AttachmentStoreOp::DONT_CARE)
                .clear_value(vk::ClearValue { depth_stencil: vk::ClearDepthStencilValue { depth: 1.0, stencil: 0 } })
        });
        let area = vk::Rect2D { offset: vk::Offset2D { x: 0, y: 0 }, extent: vk::Extent2D { width: w, height: h } };
        let mut info = vk::RenderingInfo::default().render_area(area).layer_count(1).color_attachments(&color_att);
        if let Some(d) = depth_att.as_ref() {
            info = info.depth_attachment(d);
        }
        // SAFETY: cb is recording; attachments are alive and in the stated layouts
        // (the caller transitions them; validation checks it in tests).
        unsafe {
            self.device.raw.cmd_begin_rendering(self.cb, &info);
            self.device.raw.cmd_set_viewport(self.cb, 0, &[vk::Viewport { x: 0.0, y: 0.0, width: w as f32, height: h as f32, min_depth: 0.0, max_depth: 1.0 }]);
            self.device.raw.cmd_set_scissor(self.cb, 0, &[area]);
        }
    }

    pub fn end_rendering(&self) {
        // SAFETY: paired with begin_rendering.
        unsafe { self.device.raw.cmd_end_rendering(self.cb) };
    }

    pub fn bind_pipeline(&self, p: &Pipeline) {
        // SAFETY: live pipeline of this device.
        unsafe { self.device.raw.cmd_bind_pipeline(self.cb, p.bind_point, p.raw) };
    }

    /// Binds `sets` starting at set 0 with the pipeline's layout.
    pub fn bind_sets(&self, p: &Pipeline, sets: &[&DescriptorSet]) {
        let raw: Vec<_> = sets.iter().map(|s| s.raw).collect();
        // SAFETY: sets were made from layouts compatible with the pipeline's (validation checks).
        unsafe { self.device.raw.cmd_bind_descriptor_sets(self.cb, p.bind_point, p.layout.raw, 0, &raw, &[]) };
    }

    pub fn push_constants(&self, p: &Pipeline, bytes: &[u8]) {
        p.layout.push(self.cb, bytes);
    }

    pub fn bind_vertex_buffer(&self, b: &Buffer) {
        // SAFETY: live buffer with VERTEX_BUFFER usage.
        unsafe { self.device.raw.cmd_bind_vertex_buffers(self.cb, 0, &[b.raw], &[0]) };
    }

    pub fn bind_index_buffer_u32(&self, b: &Buffer) {
        // SAFETY: live buffer with INDEX_BUFFER usage.
        unsafe { self.device.raw.cmd_bind_index_buffer(self.cb, b.raw, 0, vk::IndexType::UINT32) };
    }

    pub fn draw_indexed(&self, index_count: u32) {
        // SAFETY: inside rendering with a bound pipeline and buffers.
        unsafe { self.device.raw.cmd_draw_indexed(self.cb, index_count, 1, 0, 0, 0) };
    }

    pub fn draw(&self, vertex_count: u32) {
        // SAFETY: inside rendering with a bound pipeline.
        unsafe { self.device.raw.cmd_draw(self.cb, vertex_count, 1, 0, 0) };
    }

    pub fn dispatch(&self, x: u32, y: u32, z: u32) {
        // SAFETY: a compute pipeline is bound.
        unsafe { self.device.raw.cmd_dispatch(self.cb, x, y, z) };
    }

    pub fn image_barrier(&self, image: &Image2d, old: vk::ImageLayout, new: vk::ImageLayout) {
        image.barrier(self.cb, old, new);
    }

    pub fn raw_image_barrier(&self, image: vk::Image, old: vk::ImageLayout, new: vk::ImageLayout) {
        record_image_barrier(self.device, self.cb, image, vk::ImageAspectFlags::COLOR, old, new);
    }

    pub fn memory_barrier(&self) {
        record_memory_barrier(self.device, self.cb);
    }

    pub fn copy_image_to_buffer(&self, image: &Image2d, layout: vk::ImageLayout, dst: &Buffer) {
        image.record_readback(self.cb, layout, dst);
    }

    pub fn reset_timestamps(&self, t: &Timestamps) {
        t.reset(self.cb);
    }

    pub fn timestamp(&self, t: &Timestamps, index: u32) {
        t.write(self.cb, index);
    }
}

impl Device {
    /// Like [`Device::run_commands`], with a safe [`Recorder`].
    pub fn record_and_run<R>(&self, label: &str, record: impl FnOnce(&Recorder<'_>) -> R) -> super::VkResult<R> {
        self.run_commands(label, |cb| record(&Recorder { device: self, cb }))
    }
}

impl Recorder<'_> {
    /// Begins dynamic rendering into a raw view (a swapchain image) of `width` × `height`.
    pub fn begin_rendering_view(&self, view: vk::ImageView, width: u32, height: u32, clear: [f32; 4]) {
        let color_att = [vk::RenderingAttachmentInfo::default()
            .image_view(view)
            .image_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
            .load_op(vk::AttachmentLoadOp::CLEAR)
            .store_op(vk::AttachmentStoreOp::STORE)
            .clear_value(vk::ClearValue { color: vk::ClearColorValue { float32: clear } })];
        let area = vk::Rect2D { offset: vk::Offset2D { x: 0, y: 0 }, extent: vk::Extent2D { width, height } };
        let info = vk::RenderingInfo::default().render_area(area).layer_count(1).color_attachments(&color_att);
        // SAFETY: cb is recording; the view's image is in COLOR_ATTACHMENT_OPTIMAL (caller).
        unsafe {
            self.device.raw.cmd_begin_rendering(self.cb, &info);
            self.device.raw.cmd_set_viewport(self.cb, 0, &[vk::Viewport { x: 0.0, y: 0.0, width: width as f32, height: height as f32, min_depth: 0.0, max_depth: 1.0 }]);
            self.device.raw.cmd_set_scissor(self.cb, 0, &[area]);
        }
    }
}
