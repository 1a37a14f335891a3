//! 2D images with one view, samplers, and the layout transitions between them.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::MemoryLocation;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};

use super::buffer::Buffer;
use super::device::Device;
use super::error::{CallContext, VkError, VkResult};

/// An image, its memory and a full view. Dropping destroys the view, frees the
/// memory, then destroys the image.
pub struct Image2d {
    device: Arc<Device>,
    pub(crate) raw: vk::Image,
    pub(crate) view: vk::ImageView,
    allocation: Option<Allocation>,
    pub width: u32,
    pub height: u32,
    pub format: vk::Format,
    aspect: vk::ImageAspectFlags,
    name: String,
}

/// Bytes per texel of the formats we use.
pub fn texel_bytes(format: vk::Format) -> Option<u32> {
    Some(match format {
        vk::Format::R8G8B8A8_UNORM | vk::Format::R8G8B8A8_SRGB | vk::Format::R32_SFLOAT | vk::Format::D32_SFLOAT | vk::Format::R32_UINT => 4,
        vk::Format::R16G16B16A16_SFLOAT | vk::Format::R32G32_SFLOAT => 8,
        vk::Format::R32G32B32A32_SFLOAT => 16,
        vk::Format::R16_SFLOAT => 2,
        _ => return None,
    })
}

impl Image2d {
    pub fn new(device: &Arc<Device>, name: &str, width: u32, height: u32, format: vk::Format, usage: vk::ImageUsageFlags) -> VkResult<Image2d> {
        let max = device.info.max_image_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(VkError::Invalid(format!("image '{name}' is {width}x{height}; the device allows 1..={max} per side")));
        }
        let aspect = if format == vk::Format::D32_SFLOAT { vk::ImageAspectFlags::DEPTH } else { vk::ImageAspectFlags::COLOR };
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(format)
            .extent(vk::Extent3D { width, height, depth: 1 })
            .mip_levels(1)
            .array_layers(1)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        // SAFETY: live device, valid create info.
        let raw = unsafe { device.raw.create_image(&info, None) }.call("vkCreateImage", || format!("'{name}' {width}x{height} {format:?}"))?;
        // SAFETY: raw was created on this device.
        let requirements = unsafe { device.raw.get_image_memory_requirements(raw) };
        let allocation = match device.allocator().allocate(&AllocationCreateDesc {
            name,
            requirements,
            location: MemoryLocation::GpuOnly,
            linear: false,
            allocation_scheme: AllocationScheme::GpuAllocatorManaged,
        }) {
            Ok(a) => a,
            Err(source) => {
                // SAFETY: unused image.
                unsafe { device.raw.destroy_image(raw, None) };
                return Err(VkError::Allocation { name: name.into(), bytes: requirements.size, source });
            }
        };
        let mut img = Image2d { device: device.clone(), raw, view: vk::ImageView::null(), allocation: None, width, height, format, aspect, name: name.into() };
        // SAFETY: memory satisfies the image's requirements.
        let bound = unsafe { device.raw.bind_image_memory(raw, allocation.memory(), allocation.offset()) };
        img.allocation = Some(allocation); // freed by Drop from here on
        bound.call("vkBindImageMemory", || name.into())?;
        let view_info = vk::ImageViewCreateInfo::default()
            .image(raw)
            .view_type(vk::ImageViewType::TYPE_2D)
            .format(format)
            .subresource_range(vk::ImageSubresourceRange { aspect_mask: aspect, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: 1 });
        // SAFETY: bound image of this device.
        img.view = unsafe { device.raw.create_image_view(&view_info, None) }.call("vkCreateImageView", || name.into())?;
        device.set_name(raw, name);
        Ok(img)
    }

    pub fn raw(&self) -> vk::Image {
        self.raw
    }

    pub fn view(&self) -> vk::ImageView {
        self.view
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    fn byte_size(&self) -> VkResult<u64> {
        let tb = texel_bytes(self.format).ok_or_else(|| VkError::Invalid(format!("image '{}': no host copies for format {:?}", self.name, self.format)))?;
        Ok(self.width as u64 * self.height as u64 * tb as u64)
    }

    fn copy_region(&self) -> vk::BufferImageCopy {
        vk::BufferImageCopy::default()
            .image_subresource(vk::ImageSubresourceLayers { aspect_mask: self.aspect, mip_level: 0, base_array_layer: 0, layer_count: 1 })
            .image_extent(vk::Extent3D { width: self.width, height: self.height, depth: 1 })
    }

    /// Fills the image with tightly packed texels and leaves it in `final_layout`.
    pub fn upload(&self, data: &[u8], final_layout: vk::ImageLayout) -> VkResult<()> {
        let size = self.byte_size()?;
        if data.len() as u64 != size {
            return Err(VkError::Invalid(format!("image '{}' needs {size} bytes, got {}", self.name, data.len())));
        }
        let staging = Buffer::new(&self.device, &format!("{} (staging)", self.name), size, vk::BufferUsageFlags::TRANSFER_SRC, MemoryLocation::CpuToGpu)?;
        staging.write_mapped(data)?;
        self.device.run_commands(&format!("upload '{}'", self.name), |cb| {
            self.barrier(cb, vk::ImageLayout::UNDEFINED, vk::ImageLayout::TRANSFER_DST_OPTIMAL);
            // SAFETY: image in TRANSFER_DST layout, staging alive until the wait.
            unsafe { self.device.raw.cmd_copy_buffer_to_image(cb, staging.raw, self.raw, vk::ImageLayout::TRANSFER_DST_OPTIMAL, &[self.copy_region()]) };
            self.barrier(cb, vk::ImageLayout::TRANSFER_DST_OPTIMAL, final_layout);
        })
    }

    /// Records a copy of the image (in `layout`) into `dst`, leaving it in TRANSFER_SRC.
    pub fn record_readback(&self, cb: vk::CommandBuffer, layout: vk::ImageLayout, dst: &Buffer) {
        self.barrier(cb, layout, vk::ImageLayout::TRANSFER_SRC_OPTIMAL);
        // SAFETY: the image is in TRANSFER_SRC layout; dst is large enough (checked by caller).
        unsafe { self.device.raw.cmd_copy_image_to_buffer(cb, self.raw, vk::ImageLayout::TRANSFER_SRC_OPTIMAL, dst.raw, &[self.copy_region()]) };
    }

    /// A host-visible buffer the size of this image, for [`Self::record_readback`].
    pub fn readback_buffer(&self) -> VkResult<Buffer> {
        Buffer::new(&self.device, &format!("{} (readback)", self.name), self.byte_size()?, vk::BufferUsageFlags::TRANSFER_DST, MemoryLocation::GpuToCpu)
    }

    /// Records a full-pipeline layout transition (sync2). Coarse but correct; the
    /// offscreen paths that use it are not bound by barrier cost.
    pub fn barrier(&self, cb: vk::CommandBuffer, old: vk::ImageLayout, new: vk::ImageLayout) {
        record_image_barrier(&self.device, cb, self.raw, self.aspect, old, new);
    }
}

/// A layout transition from everything before to everything after.
pub fn record_image_barrier(device: &Device, cb: vk::CommandBuffer, image: vk::Image, aspect: vk::ImageAspectFlags, old: vk::ImageLayout, new: vk::ImageLayout) {
    let barrier = [vk::ImageMemoryBarrier2::default()
        .src_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
        .src_access_mask(vk::AccessFlags2::MEMORY_WRITE)
        .dst_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
        .dst_access_mask(vk::AccessFlags2::MEMORY_READ | vk::AccessFlags2::MEMORY_WRITE)
        .old_layout(old)
        .new_layout(new)
        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .image(image)
        .subresource_range(vk::ImageSubresourceRange { aspect_mask: aspect, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: 1 })];
    let dep = vk::DependencyInfo::default().image_memory_barriers(&barrier);
    // SAFETY: cb is recording; image belongs to device.
    unsafe { device.raw.cmd_pipeline_barrier2(cb, &dep) };
}

/// A memory barrier between everything before and everything after (sync2).
pub fn record_memory_barrier(device: &Device, cb: vk::CommandBuffer) {
    let barrier = [vk::MemoryBarrier2::default()
        .src_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
        .src_access_mask(vk::AccessFlags2::MEMORY_WRITE)
        .dst_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
        .dst_access_mask(vk::AccessFlags2::MEMORY_READ | vk::AccessFlags2::MEMORY_WRITE)];
    let dep = vk::DependencyInfo::default().memory_barriers(&barrier);
    // SAFETY: cb is recording.
    unsafe { device.raw.cmd_pipeline_barrier2(cb, &dep) };
}

impl Drop for Image2d {
    fn drop(&mut self) {
        // SAFETY: work using the image has completed (submissions wait); view first.
        unsafe {
            if self.view != vk::ImageView::null() {
                self.device.raw.destroy_image_view(self.view, None);
            }
        }
        if let Some(a) = self.allocation.take() {
            let _ = self.device.allocator().free(a);
        }
        // SAFETY: as above.
        unsafe { self.device.raw.destroy_image(self.raw, None) };
    }
}

/// A sampler, owned.
pub struct Sampler {
    device: Arc<Device>,
    pub(crate) raw: vk::Sampler,
}

impl Sampler {
    /// Linear or nearest filtering with repeat addressing.
    pub fn new(device: &Arc<Device>, linear: bool) -> VkResult<Sampler> {
        let filter = if linear { vk::Filter::LINEAR } else { vk::Filter::NEAREST };
        let info = vk::SamplerCreateInfo::default()
            .mag_filter(filter)
            .min_filter(filter)
            .mipmap_mode(vk::SamplerMipmapMode::NEAREST)
            .address_mode_u(vk::SamplerAddressMode::REPEAT)
            .address_mode_v(vk::SamplerAddressMode::REPEAT)
            .address_mode_w(vk::SamplerAddressMode::REPEAT)
            .max_lod(0.0);
        // SAFETY: live device.
        let raw = unsafe { device.raw.create_sampler(&info, None) }.call("vkCreateSampler", String::new)?;
        Ok(Sampler { device: device.clone(), raw })
    }

    pub fn raw(&self) -> vk::Sampler {
        self.raw
    }
}

impl Drop for Sampler {
    fn drop(&mut self) {
        // SAFETY: no submitted work uses it any more.
        unsafe { self.device.raw.destroy_sampler(self.raw, None) };
    }
}
