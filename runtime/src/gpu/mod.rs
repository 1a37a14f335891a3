//! The GPU renderer, built on the thin Vulkan layer in [`crate::vk`] (no `unsafe` here).

pub mod frame;
pub mod hybrid_pass;
pub mod mesh_pass;
pub mod target;
pub mod tonemap;

pub use frame::FrameUniforms;
pub use hybrid_pass::{GpuHybridModel, GpuRenderError, HybridFrame, HybridPass, Variant};
pub use mesh_pass::{GpuMesh, MeshFrame, MeshPass, RenderedFrame};
pub use target::OffscreenTarget;
pub use tonemap::TonemapPass;
