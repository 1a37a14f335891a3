//! The tonemap pass: draws an offscreen HDR image into a display image (a swapchain
//! image) as sRGB(clamp(exposure · L)), the same mapping as PNG output.

use std::sync::Arc;

use ash::vk;

use super::target::OffscreenTarget;
use crate::vk::{BindingKind, DescriptorSet, DescriptorSetLayout, Device, GraphicsDesc, Pipeline, PipelineLayout, Recorder, Resource, Sampler, ShaderModule, Specialization, VkResult};

/// An image the tonemap pass draws into (a swapchain image), in UNDEFINED layout.
#[derive(Clone, Copy, Debug)]
pub struct DisplayImage {
    pub image: vk::Image,
    pub view: vk::ImageView,
    pub width: u32,
    pub height: u32,
}

pub struct TonemapPass {
    pipeline: Pipeline,
    set: DescriptorSet,
    _set_layout: DescriptorSetLayout,
    _sampler: Sampler,
}

impl TonemapPass {
    /// A pass reading `source`'s color image, writing `target_format` images.
    pub fn new(device: &Arc<Device>, source: &OffscreenTarget, target_format: vk::Format, hardware_srgb: bool) -> VkResult<TonemapPass> {
        let set_layout = DescriptorSetLayout::new(device, &[BindingKind::SampledImage], vk::ShaderStageFlags::FRAGMENT)?;
        let layout = Arc::new(PipelineLayout::new(device, &[&set_layout], 4, vk::ShaderStageFlags::FRAGMENT)?);
        let vert = ShaderModule::embedded(device, "fullscreen.vert")?;
        let frag = ShaderModule::embedded(device, "tonemap.frag")?;
        let pipeline = Pipeline::graphics(
            device,
            &GraphicsDesc {
                name: "tonemap",
                vertex: &vert,
                fragment: &frag,
                layout: &layout,
                vertex_stride: 0,
                vertex_attributes: &[],
                color_format: target_format,
                depth_format: None,
                cull: vk::CullModeFlags::NONE,
                specialization: Specialization::new().bool(0, !hardware_srgb),
            },
        )?;
        let sampler = Sampler::new(device, false)?;
        let set = DescriptorSet::new(device, &set_layout, &[Resource::Sampled(&source.color, &sampler)])?;
        Ok(TonemapPass { pipeline, set, _set_layout: set_layout, _sampler: sampler })
    }

    /// Records: source color (COLOR_ATTACHMENT) → shader-readable; display image
    /// (UNDEFINED) → drawn → PRESENT_SRC.
    pub fn record(&self, rec: &Recorder<'_>, source: &OffscreenTarget, display: &DisplayImage, exposure: f32) {
        let DisplayImage { image, view, width, height } = *display;
        rec.image_barrier(&source.color, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL);
        rec.raw_image_barrier(image, vk::ImageLayout::UNDEFINED, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL);
        rec.begin_rendering_view(view, width, height, [0.0, 0.0, 0.0, 1.0]);
        rec.bind_pipeline(&self.pipeline);
        rec.bind_sets(&self.pipeline, &[&self.set]);
        rec.push_constants(&self.pipeline, &exposure.to_le_bytes());
        rec.draw(3);
        rec.end_rendering();
        rec.raw_image_barrier(image, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL, vk::ImageLayout::PRESENT_SRC_KHR);
    }
}
