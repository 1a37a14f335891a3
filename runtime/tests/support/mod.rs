//! Shared by the GPU twin tests: run a compute shader of `shaders/` over `count` inputs
//! (64 invocations per group, the count as the push constant), its bindings the given
//! storage buffers in order plus one output buffer of `out_bytes`, and read it back.

use std::sync::Arc;

use fabric_runtime::vk::{BindingKind, Buffer, DescriptorSet, DescriptorSetLayout, Device, MemoryLocation, Pipeline, PipelineLayout, Resource, ShaderModule, Specialization, vk};

/// A storage buffer holding `bytes`.
pub fn storage(device: &Arc<Device>, name: &str, bytes: &[u8]) -> Buffer {
    Buffer::with_data(device, name, bytes, vk::BufferUsageFlags::STORAGE_BUFFER).unwrap()
}

/// Runs `shader` with `inputs` bound at 0..n and the output at n; returns the output.
pub fn run_compute(device: &Arc<Device>, shader: &str, inputs: &[&Buffer], out_bytes: u64, count: u32) -> Vec<u8> {
    let module = ShaderModule::embedded(device, shader).unwrap();
    let kinds = vec![BindingKind::StorageBuffer; inputs.len() + 1];
    let set_layout = DescriptorSetLayout::new(device, &kinds, vk::ShaderStageFlags::COMPUTE).unwrap();
    let layout = Arc::new(PipelineLayout::new(device, &[&set_layout], 4, vk::ShaderStageFlags::COMPUTE).unwrap());
    let pipeline = Pipeline::compute(device, shader, &module, &layout, &Specialization::new()).unwrap();
    let out = Buffer::new(device, "outputs", out_bytes.max(4), vk::BufferUsageFlags::STORAGE_BUFFER, MemoryLocation::GpuToCpu).unwrap();
    let mut resources: Vec<Resource<'_>> = inputs.iter().map(|b| Resource::Buffer(b)).collect();
    resources.push(Resource::Buffer(&out));
    let set = DescriptorSet::new(device, &set_layout, &resources).unwrap();
    device
        .record_and_run(shader, |rec| {
            rec.bind_pipeline(&pipeline);
            rec.bind_sets(&pipeline, &[&set]);
            rec.push_constants(&pipeline, bytemuck::bytes_of(&count));
            rec.dispatch(count.div_ceil(64), 1, 1);
        })
        .unwrap();
    out.mapped().expect("host-visible output").to_vec()
}
