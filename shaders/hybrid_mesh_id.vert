#version 460
// hybrid_mesh_id.vert — the visibility pass of the hybrid fabric on meshes: each
// triangle of the base mesh (runtime/src/scene/mesh.rs `Vertex`, 12 floats; indices
// u32) pulled from storage buffers, drawn unindexed, and carrying its number + 1 to
// hybrid_mesh_id.frag. hybrid_mesh.comp then shades each pixel once from that number.
// (Pulled rather than gl_PrimitiveID, which a fragment shader may read only with the
// geometry or tessellation feature.)
#extension GL_GOOGLE_include_directive : require

#include "common/mesh_buffers.glsl"

layout(push_constant) uniform Push {
    mat4 view_proj;   // world -> Vulkan clip (Camera::projection_matrix * view_matrix)
    vec2 uv_scale;    // tile repeats per UV unit (u, v); read by hybrid_mesh.comp
} push;

layout(location = 0) flat out uint out_triangle;

void main() {
    uint v = mesh_indices[gl_VertexIndex];
    out_triangle = uint(gl_VertexIndex) / 3u + 1u;
    gl_Position = push.view_proj * vec4(mesh_position(v), 1.0);
}
