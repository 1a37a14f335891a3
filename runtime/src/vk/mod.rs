//! The thin Vulkan layer: every `unsafe` call into the API lives under this module,
//! each with a `SAFETY:` note. Every object is owned by one Rust value that destroys
//! it in `Drop`; resources hold an `Arc<Device>`, the device holds an
//! `Arc<Instance>`, so destruction runs resources → device → instance.

pub mod buffer;
pub mod checked;
pub mod commands;
pub mod descriptor;
pub mod device;
pub mod error;
pub mod image;
pub mod instance;
pub mod pipeline;
pub mod shader;
pub mod swapchain;
pub mod sync;
pub mod timing;

pub use buffer::Buffer;
pub use checked::CheckedDevice;
pub use commands::{ColorTarget, Recorder};
pub use descriptor::{BindingKind, DescriptorSet, DescriptorSetLayout, Resource};
pub use device::{Device, DeviceInfo, DeviceOptions, enumerate_devices};
pub use error::{VkError, VkResult};
pub use image::{Image2d, Sampler};
pub use instance::{Instance, InstanceOptions, ValidationLog};
pub use pipeline::{GraphicsDesc, Pipeline, PipelineLayout, Specialization};
pub use shader::ShaderModule;
pub use swapchain::{Acquired, Surface, Swapchain};
pub use timing::Timestamps;

pub use ash::vk;
pub use gpu_allocator::MemoryLocation;
