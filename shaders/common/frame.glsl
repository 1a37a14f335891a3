// frame.glsl — per-frame uniforms shared by every raster pass.
//
// Rust twin: runtime/src/gpu/frame.rs (`FrameUniforms`, #[repr(C)], std140 with
// vec4/mat4 members only so the two layouts are identical by construction; a test
// checks the size).
//
// Units and frames: world space, the units of the scene (for fabrics: the .vol
// bounding box's units). Radiance out is linear RGB.
#ifndef FRAME_GLSL
#define FRAME_GLSL

struct FrameUniforms {
    mat4 view_proj;      // world → Vulkan clip (y down, depth 0..1)
    vec4 camera_pos;     // xyz: camera origin; w: 1 perspective, 0 orthographic
    vec4 camera_forward; // xyz: unit view direction
    vec4 light_vec;      // w = 0: xyz = unit direction toward a directional light; w = 1: xyz = point light position
    vec4 light_power;    // rgb: irradiance ⟂ beam (directional) or intensity per sr (point)
    vec4 base_color;     // rgb: multiplies the surface texture (mesh pass)
};

#endif
