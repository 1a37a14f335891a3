//! Pipeline layouts and compute/graphics pipelines (dynamic rendering, no render
//! passes), with specialization constants.

use std::sync::Arc;

use ash::vk;

use super::descriptor::DescriptorSetLayout;
use super::device::Device;
use super::error::{CallContext, VkError, VkResult};
use super::shader::ShaderModule;

/// A pipeline layout, owned.
pub struct PipelineLayout {
    device: Arc<Device>,
    pub(crate) raw: vk::PipelineLayout,
    push_stages: vk::ShaderStageFlags,
}

impl PipelineLayout {
    pub fn new(device: &Arc<Device>, sets: &[&DescriptorSetLayout], push_constant_bytes: u32, push_stages: vk::ShaderStageFlags) -> VkResult<PipelineLayout> {
        if push_constant_bytes > device.info.max_push_constants_size {
            return Err(VkError::Invalid(format!("{push_constant_bytes} bytes of push constants; the device allows {}", device.info.max_push_constants_size)));
        }
        let set_layouts: Vec<_> = sets.iter().map(|s| s.raw).collect();
        let ranges = [vk::PushConstantRange { stage_flags: push_stages, offset: 0, size: push_constant_bytes }];
        let mut info = vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts);
        if push_constant_bytes > 0 {
            info = info.push_constant_ranges(&ranges);
        }
        // SAFETY: live device and set layouts.
        let raw = unsafe { device.raw.create_pipeline_layout(&info, None) }.call("vkCreatePipelineLayout", String::new)?;
        Ok(PipelineLayout { device: device.clone(), raw, push_stages })
    }

    pub fn raw(&self) -> vk::PipelineLayout {
        self.raw
    }

    /// Records push constants (bytes of a `#[repr(C)]` Pod struct).
    pub fn push(&self, cb: vk::CommandBuffer, bytes: &[u8]) {
        // SAFETY: cb is recording; the size was validated against the layout's range by
        // the caller's struct (and by the validation layer in tests).
        unsafe { self.device.raw.cmd_push_constants(cb, self.raw, self.push_stages, 0, bytes) };
    }
}

impl Drop for PipelineLayout {
    fn drop(&mut self) {
        // SAFETY: pipelines using it are dropped first (they own an Arc to it).
        unsafe { self.device.raw.destroy_pipeline_layout(self.raw, None) };
    }
}

/// Specialization constants: (constant_id, 4-byte value).
#[derive(Clone, Debug, Default)]
pub struct Specialization {
    entries: Vec<vk::SpecializationMapEntry>,
    data: Vec<u8>,
}

impl Specialization {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn u32(mut self, id: u32, value: u32) -> Self {
        self.entries.push(vk::SpecializationMapEntry { constant_id: id, offset: self.data.len() as u32, size: 4 });
        self.data.extend_from_slice(&value.to_le_bytes());
        self
    }

    pub fn bool(self, id: u32, value: bool) -> Self {
        self.u32(id, value as u32)
    }

    pub fn f32(self, id: u32, value: f32) -> Self {
        self.u32(id, value.to_bits())
    }

    fn info(&self) -> vk::SpecializationInfo<'_> {
        vk::SpecializationInfo::default().map_entries(&self.entries).data(&self.data)
    }
}

/// A compute or graphics pipeline, owned.
pub struct Pipeline {
    device: Arc<Device>,
    pub(crate) raw: vk::Pipeline,
    pub layout: Arc<PipelineLayout>,
    pub bind_point: vk::PipelineBindPoint,
}

impl Pipeline {
    pub fn compute(device: &Arc<Device>, name: &str, module: &ShaderModule, layout: &Arc<PipelineLayout>, spec: &Specialization) -> VkResult<Pipeline> {
        let spec_info = spec.info();
        let stage = vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::COMPUTE).module(module.raw).name(c"main").specialization_info(&spec_info);
        let info = [vk::ComputePipelineCreateInfo::default().stage(stage).layout(layout.raw)];
        // SAFETY: live device, module and layout.
        let raw = unsafe { device.raw.create_compute_pipelines(vk::PipelineCache::null(), &info, None) }
            .map_err(|(_, r)| r)
            .call("vkCreateComputePipelines", || name.into())?[0];
        device.set_name(raw, name);
        Ok(Pipeline { device: device.clone(), raw, layout: layout.clone(), bind_point: vk::PipelineBindPoint::COMPUTE })
    }

    pub fn graphics(device: &Arc<Device>, desc: &GraphicsDesc<'_>) -> VkResult<Pipeline> {
        let spec_info = desc.specialization.info();
        let stages = [
            vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::VERTEX).module(desc.vertex.raw).name(c"main").specialization_info(&spec_info),
            vk::PipelineShaderStageCreateInfo::default().stage(vk::ShaderStageFlags::FRAGMENT).module(desc.fragment.raw).name(c"main").specialization_info(&spec_info),
        ];
        let bindings = [vk::VertexInputBindingDescription { binding: 0, stride: desc.vertex_stride, input_rate: vk::VertexInputRate::VERTEX }];
        let attributes: Vec<_> = desc
            .vertex_attributes
            .iter()
            .enumerate()
            .map(|(i, (format, offset))| vk::VertexInputAttributeDescription { location: i as u32, binding: 0, format: *format, offset: *offset })
            .collect();
        let vertex_input = if desc.vertex_stride == 0 {
            vk::PipelineVertexInputStateCreateInfo::default()
        } else {
            vk::PipelineVertexInputStateCreateInfo::default().vertex_binding_descriptions(&bindings).vertex_attribute_descriptions(&attributes)
        };
        let input_assembly = vk::PipelineInputAssemblyStateCreateInfo::default().topology(vk::PrimitiveTopology::TRIANGLE_LIST);
        let viewport = vk::PipelineViewportStateCreateInfo::default().viewport_count(1).scissor_count(1);
        let raster = vk::PipelineRasterizationStateCreateInfo::default()
            .polygon_mode(vk::PolygonMode::FILL)
            .cull_mode(desc.cull)
            .front_face(vk::FrontFace::COUNTER_CLOCKWISE)
            .line_width(1.0);
        let multisample = vk::PipelineMultisampleStateCreateInfo::default().rasterization_samples(vk::SampleCountFlags::TYPE_1);
        let depth = vk::PipelineDepthStencilStateCreateInfo::default()
            .depth_test_enable(desc.depth_format.is_some())
            .depth_write_enable(desc.depth_format.is_some())
            .depth_compare_op(vk::CompareOp::LESS);
        let blend_attachments = [vk::PipelineColorBlendAttachmentState::default().color_write_mask(vk::ColorComponentFlags::RGBA)];
        let blend = vk::PipelineColorBlendStateCreateInfo::default().attachments(&blend_attachments);
        let dynamic_states = [vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
        let dynamic = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic_states);
        let color_formats = [desc.color_format];
        let mut rendering = vk::PipelineRenderingCreateInfo::default().color_attachment_formats(&color_formats).depth_attachment_format(desc.depth_format.unwrap_or(vk::Format::UNDEFINED));
        let info = [vk::GraphicsPipelineCreateInfo::default()
            .stages(&stages)
            .vertex_input_state(&vertex_input)
            .input_assembly_state(&input_assembly)
            .viewport_state(&viewport)
            .rasterization_state(&raster)
            .multisample_state(&multisample)
            .depth_stencil_state(&depth)
            .color_blend_state(&blend)
            .dynamic_state(&dynamic)
            .layout(desc.layout.raw)
            .push_next(&mut rendering)];
        // SAFETY: every referenced struct is a local alive for this call.
        let raw = unsafe { device.raw.create_graphics_pipelines(vk::PipelineCache::null(), &info, None) }
            .map_err(|(_, r)| r)
            .call("vkCreateGraphicsPipelines", || desc.name.into())?[0];
        device.set_name(raw, desc.name);
        Ok(Pipeline { device: device.clone(), raw, layout: desc.layout.clone(), bind_point: vk::PipelineBindPoint::GRAPHICS })
    }

    pub fn raw(&self) -> vk::Pipeline {
        self.raw
    }
}

impl Drop for Pipeline {
    fn drop(&mut self) {
        // SAFETY: every submission that used it has completed.
        unsafe { self.device.raw.destroy_pipeline(self.raw, None) };
    }
}

/// Everything a graphics pipeline needs.
pub struct GraphicsDesc<'a> {
    pub name: &'a str,
    pub vertex: &'a ShaderModule,
    pub fragment: &'a ShaderModule,
    pub layout: &'a Arc<PipelineLayout>,
    /// Bytes per vertex (0 = no vertex buffer).
    pub vertex_stride: u32,
    /// Per location: (format, byte offset).
    pub vertex_attributes: &'a [(vk::Format, u32)],
    pub color_format: vk::Format,
    pub depth_format: Option<vk::Format>,
    pub cull: vk::CullModeFlags,
    pub specialization: Specialization,
}
