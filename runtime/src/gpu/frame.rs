//! Per-frame uniforms: the Rust twin of `shaders/common/frame.glsl`.

use glam::{Mat4, Vec3, Vec4};

use crate::scene::{Camera, Light, Projection};

/// std140-identical to `FrameUniforms` in frame.glsl (only mat4/vec4 members).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FrameUniforms {
    pub view_proj: [[f32; 4]; 4],
    pub camera_pos: [f32; 4],
    pub camera_forward: [f32; 4],
    pub light_vec: [f32; 4],
    pub light_power: [f32; 4],
    pub base_color: [f32; 4],
}

const _: () = assert!(core::mem::size_of::<FrameUniforms>() == 64 + 5 * 16);

impl FrameUniforms {
    /// `near`/`far` bound the depth range of the scene.
    pub fn new(camera: &Camera, light: &Light, base_color: Vec3, near: f32, far: f32) -> FrameUniforms {
        let vp: Mat4 = camera.projection_matrix(near, far) * camera.view_matrix();
        let f = camera.frame();
        let persp = matches!(camera.projection, Projection::Perspective { .. });
        let (light_vec, light_power) = match *light {
            Light::Directional { dir_to_light, irradiance } => (dir_to_light.extend(0.0), irradiance),
            Light::Point { position, intensity } => (position.extend(1.0), intensity),
        };
        FrameUniforms {
            view_proj: vp.to_cols_array_2d(),
            camera_pos: camera.origin.extend(if persp { 1.0 } else { 0.0 }).to_array(),
            camera_forward: f.forward.extend(0.0).to_array(),
            light_vec: light_vec.to_array(),
            light_power: light_power.extend(0.0).to_array(),
            base_color: Vec4::from((base_color, 1.0)).to_array(),
        }
    }
}
