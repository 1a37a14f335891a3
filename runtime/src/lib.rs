//! The runtime: hybrid fabric models (format, BRDF, CPU renderer) and the Vulkan
//! renderer that draws them (../shared/DESIGN.md §6–§7).

pub mod brdf;
pub mod hybrid;
pub mod image;
pub mod scene;
