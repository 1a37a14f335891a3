//! The offscreen render target: an RGBA16F color image (linear radiance) and a D32
//! depth image, read back into a linear [`crate::image::Image`].

use std::sync::Arc;

use glam::Vec3;

use ash::vk;

use crate::vk::{Buffer, Device, Image2d, Recorder, VkError, VkResult};

pub const COLOR_FORMAT: vk::Format = vk::Format::R16G16B16A16_SFLOAT;
pub const DEPTH_FORMAT: vk::Format = vk::Format::D32_SFLOAT;

pub struct OffscreenTarget {
    pub color: Image2d,
    pub depth: Image2d,
    pub readback: Buffer,
}

impl OffscreenTarget {
    pub fn new(device: &Arc<Device>, width: u32, height: u32) -> VkResult<OffscreenTarget> {
        let color = Image2d::new(device, "offscreen color", width, height, COLOR_FORMAT, vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::SAMPLED)?;
        let depth = Image2d::new(device, "offscreen depth", width, height, DEPTH_FORMAT, vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT)?;
        let readback = color.readback_buffer()?;
        Ok(OffscreenTarget { color, depth, readback })
    }

    /// Transitions both attachments for rendering (contents discarded).
    pub fn record_begin(&self, rec: &Recorder<'_>) {
        rec.image_barrier(&self.color, vk::ImageLayout::UNDEFINED, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL);
        rec.image_barrier(&self.depth, vk::ImageLayout::UNDEFINED, vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL);
    }

    /// Records the copy of the color image (just rendered, in COLOR_ATTACHMENT_OPTIMAL)
    /// into the readback buffer.
    pub fn record_readback(&self, rec: &Recorder<'_>) {
        self.record_readback_from(rec, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL);
    }

    /// Like [`Self::record_readback`] with the color image in `layout`.
    pub fn record_readback_from(&self, rec: &Recorder<'_>, layout: vk::ImageLayout) {
        rec.copy_image_to_buffer(&self.color, layout, &self.readback);
    }

    /// The pixels of the readback buffer whose alpha is 0: the mesh pass's mark of a
    /// pixel whose loops the driver cut short (hybrid_mesh.comp).
    pub fn zero_alpha_pixels(&self) -> VkResult<u32> {
        Ok(self.halves()?.chunks_exact(4).filter(|p| half::f16::from_bits(p[3]).to_f32() == 0.0).count() as u32)
    }

    /// The readback buffer as f16 bits, RGBA per pixel.
    fn halves(&self) -> VkResult<&[u16]> {
        let bytes = self.readback.mapped().ok_or_else(|| VkError::Invalid("readback buffer is not mapped".into()))?;
        bytemuck::try_cast_slice(bytes).map_err(|e| VkError::Invalid(format!("readback layout: {e}")))
    }

    /// Decodes the readback buffer (after the submission completed) into linear RGB.
    pub fn to_image(&self) -> VkResult<crate::image::Image> {
        let (w, h) = (self.color.width, self.color.height);
        let pixels = self
            .halves()?
            .chunks_exact(4)
            .map(|p| Vec3::new(half::f16::from_bits(p[0]).to_f32(), half::f16::from_bits(p[1]).to_f32(), half::f16::from_bits(p[2]).to_f32()))
            .collect();
        Ok(crate::image::Image { width: w, height: h, pixels })
    }
}
