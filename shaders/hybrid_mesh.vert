#version 460
// hybrid_mesh.vert — a base-mesh vertex (runtime/src/scene/mesh.rs `Vertex`) to clip
// space for the hybrid fabric on meshes (hybrid_mesh.frag); passes its world position,
// frame and UV on.

layout(push_constant) uniform Push {
    mat4 view_proj;   // world -> Vulkan clip (Camera::projection_matrix * view_matrix)
    vec2 uv_scale;    // tile repeats per UV unit (u, v)
} push;

layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;
layout(location = 2) in vec4 in_tangent;
layout(location = 3) in vec2 in_uv;

layout(location = 0) out vec3 out_position;
layout(location = 1) out vec3 out_normal;
layout(location = 2) out vec4 out_tangent;
layout(location = 3) out vec2 out_uv;

void main() {
    out_position = in_position;
    out_normal = in_normal;
    out_tangent = in_tangent;
    out_uv = in_uv;
    gl_Position = push.view_proj * vec4(in_position, 1.0);
}
