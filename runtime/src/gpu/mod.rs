//! The GPU renderer, built on the thin Vulkan layer in [`crate::vk`] (no `unsafe` here).

pub mod frame;
pub mod frame_loop;
pub mod hybrid_pass;
pub mod mesh_pass;
pub mod target;
pub mod tonemap;

pub use frame::FrameUniforms;
pub use frame_loop::{FrameLoop, ViewContent};
pub use hybrid_pass::{GpuHybridModel, GpuRenderError, HybridFrame, HybridMesh, HybridPass, MeshDraw, Variant};
pub use mesh_pass::{GpuMesh, MeshFrame, MeshPass, RenderedFrame};
pub use target::OffscreenTarget;
pub use tonemap::TonemapPass;
