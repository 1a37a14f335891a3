#version 460
// mesh.vert — transforms a base-mesh vertex (runtime/src/scene/mesh.rs `Vertex`) to clip
// space and passes its world-space frame and UV on.
#include "common/frame.glsl"

layout(set = 0, binding = 0) uniform Frame { FrameUniforms frame; };

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
    gl_Position = frame.view_proj * vec4(in_position, 1.0);
}
