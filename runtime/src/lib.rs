//! The runtime: hybrid fabric models (format, BRDF, CPU renderer) and the Vulkan
//! renderer that draws them (docs/DESIGN.md §6–§7).

// Linked for its glslang/SPIRV-Tools link lines (see runtime/shaderc-link).
#[cfg(feature = "gpu")]
use shaderc_link as _;

pub mod brdf;
pub mod cpu;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod hybrid;
pub mod image;
pub mod metrics;
#[cfg(feature = "gpu")]
pub mod vk;
pub mod scene;
