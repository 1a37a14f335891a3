// mesh_buffers.glsl — the base mesh as storage buffers (bindings 14 and 15 of the mesh
// pass): vertices as runtime/src/scene/mesh.rs `Vertex` (position 3, normal 3, tangent 4,
// uv 2 floats), triangles as three u32 indices each.
#ifndef MESH_BUFFERS_GLSL
#define MESH_BUFFERS_GLSL

layout(std430, set = 0, binding = 14) readonly buffer MeshVertexBlock { float mesh_vertices[]; };
layout(std430, set = 0, binding = 15) readonly buffer MeshIndexBlock { uint mesh_indices[]; };

const uint MESH_VERTEX_FLOATS = 12u;

vec3 mesh_position(uint v) {
    uint b = v * MESH_VERTEX_FLOATS;
    return vec3(mesh_vertices[b], mesh_vertices[b + 1u], mesh_vertices[b + 2u]);
}

vec3 mesh_normal(uint v) {
    uint b = v * MESH_VERTEX_FLOATS + 3u;
    return vec3(mesh_vertices[b], mesh_vertices[b + 1u], mesh_vertices[b + 2u]);
}

vec4 mesh_tangent(uint v) {
    uint b = v * MESH_VERTEX_FLOATS + 6u;
    return vec4(mesh_vertices[b], mesh_vertices[b + 1u], mesh_vertices[b + 2u], mesh_vertices[b + 3u]);
}

vec2 mesh_uv(uint v) {
    uint b = v * MESH_VERTEX_FLOATS + 10u;
    return vec2(mesh_vertices[b], mesh_vertices[b + 1u]);
}

#endif
