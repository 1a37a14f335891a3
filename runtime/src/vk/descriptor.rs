//! Descriptor set layouts and descriptor sets. Each [`DescriptorSet`] owns a pool
//! sized for exactly itself: simple ownership, and our passes bind few sets.

use std::sync::Arc;

use ash::vk;

use super::buffer::Buffer;
use super::device::Device;
use super::error::{CallContext, VkError, VkResult};
use super::image::{Image2d, Sampler};

/// What a binding holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BindingKind {
    StorageBuffer,
    UniformBuffer,
    SampledImage,
    StorageImage,
}

impl BindingKind {
    fn vk(self) -> vk::DescriptorType {
        match self {
            BindingKind::StorageBuffer => vk::DescriptorType::STORAGE_BUFFER,
            BindingKind::UniformBuffer => vk::DescriptorType::UNIFORM_BUFFER,
            BindingKind::SampledImage => vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
            BindingKind::StorageImage => vk::DescriptorType::STORAGE_IMAGE,
        }
    }
}

/// A descriptor set layout: bindings 0..n in order.
pub struct DescriptorSetLayout {
    device: Arc<Device>,
    pub(crate) raw: vk::DescriptorSetLayout,
    kinds: Vec<BindingKind>,
}

impl DescriptorSetLayout {
    pub fn new(device: &Arc<Device>, kinds: &[BindingKind], stages: vk::ShaderStageFlags) -> VkResult<DescriptorSetLayout> {
        let bindings: Vec<_> = kinds
            .iter()
            .enumerate()
            .map(|(i, k)| vk::DescriptorSetLayoutBinding::default().binding(i as u32).descriptor_type(k.vk()).descriptor_count(1).stage_flags(stages))
            .collect();
        let info = vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings);
        // SAFETY: live device.
        let raw = unsafe { device.raw.create_descriptor_set_layout(&info, None) }.call("vkCreateDescriptorSetLayout", String::new)?;
        Ok(DescriptorSetLayout { device: device.clone(), raw, kinds: kinds.to_vec() })
    }
}

impl Drop for DescriptorSetLayout {
    fn drop(&mut self) {
        // SAFETY: pipelines and sets made from it are created already; layouts may be
        // destroyed while those live.
        unsafe { self.device.raw.destroy_descriptor_set_layout(self.raw, None) };
    }
}

/// What to bind at one binding.
pub enum Resource<'a> {
    Buffer(&'a Buffer),
    Sampled(&'a Image2d, &'a Sampler),
    /// A storage image in GENERAL layout.
    Storage(&'a Image2d),
}

/// A descriptor set with its own pool.
pub struct DescriptorSet {
    device: Arc<Device>,
    pool: vk::DescriptorPool,
    pub(crate) raw: vk::DescriptorSet,
}

impl DescriptorSet {
    /// Allocates a set of `layout` and writes `resources` to bindings 0..n.
    pub fn new(device: &Arc<Device>, layout: &DescriptorSetLayout, resources: &[Resource<'_>]) -> VkResult<DescriptorSet> {
        if resources.len() != layout.kinds.len() {
            return Err(VkError::Invalid(format!("descriptor set needs {} resources, got {}", layout.kinds.len(), resources.len())));
        }
        let sizes: Vec<_> = layout.kinds.iter().map(|k| vk::DescriptorPoolSize { ty: k.vk(), descriptor_count: 1 }).collect();
        let info = vk::DescriptorPoolCreateInfo::default().max_sets(1).pool_sizes(&sizes);
        // SAFETY: live device.
        let pool = unsafe { device.raw.create_descriptor_pool(&info, None) }.call("vkCreateDescriptorPool", String::new)?;
        let mut set = DescriptorSet { device: device.clone(), pool, raw: vk::DescriptorSet::null() };
        let layouts = [layout.raw];
        let alloc = vk::DescriptorSetAllocateInfo::default().descriptor_pool(pool).set_layouts(&layouts);
        // SAFETY: the pool has room for exactly this set.
        set.raw = unsafe { device.raw.allocate_descriptor_sets(&alloc) }.call("vkAllocateDescriptorSets", String::new)?[0];

        let mut buffer_infos = Vec::new();
        let mut image_infos = Vec::new();
        for r in resources {
            match r {
                Resource::Buffer(b) => buffer_infos.push([vk::DescriptorBufferInfo { buffer: b.raw, offset: 0, range: vk::WHOLE_SIZE }]),
                Resource::Sampled(img, s) => image_infos.push([vk::DescriptorImageInfo { sampler: s.raw, image_view: img.view, image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL }]),
                Resource::Storage(img) => image_infos.push([vk::DescriptorImageInfo { sampler: vk::Sampler::null(), image_view: img.view, image_layout: vk::ImageLayout::GENERAL }]),
            }
        }
        let (mut bi, mut ii) = (0, 0);
        let mut writes = Vec::new();
        for (i, (r, k)) in resources.iter().zip(&layout.kinds).enumerate() {
            let ok = matches!(
                (r, k),
                (Resource::Buffer(_), BindingKind::StorageBuffer | BindingKind::UniformBuffer) | (Resource::Sampled(..), BindingKind::SampledImage) | (Resource::Storage(_), BindingKind::StorageImage)
            );
            if !ok {
                return Err(VkError::Invalid(format!("binding {i} expects {k:?}")));
            }
            let w = vk::WriteDescriptorSet::default().dst_set(set.raw).dst_binding(i as u32).descriptor_type(k.vk());
            writes.push(match r {
                Resource::Buffer(_) => {
                    bi += 1;
                    w.buffer_info(&buffer_infos[bi - 1])
                }
                _ => {
                    ii += 1;
                    w.image_info(&image_infos[ii - 1])
                }
            });
        }
        // SAFETY: the infos referenced by `writes` live until this call returns.
        unsafe { device.raw.update_descriptor_sets(&writes, &[]) };
        Ok(set)
    }

    pub fn raw(&self) -> vk::DescriptorSet {
        self.raw
    }
}

impl Drop for DescriptorSet {
    fn drop(&mut self) {
        // SAFETY: no pending work uses the set (every submission waits); destroying the
        // pool frees the set.
        unsafe { self.device.raw.destroy_descriptor_pool(self.pool, None) };
    }
}
