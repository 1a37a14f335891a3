// example_texel_brdf.comp — the shader kit used outside our renderer (shaders/README.md,
// "Porting the shaders"): evaluates a hybrid model's BRDF at given texels, for given
// light and view directions, with nothing but the model's arrays bound. An engine's own
// shader would do the same in its lighting code: texel_brdf() then texel_response().
//
// Bindings (set 0): 0-6 the model (common/model.glsl) and 13 its view tilt and gradient
// records (GpuModel::view_tilt_array; texel_response reads the texels' visibility
// gradients there, format 1.12); 7-8 and 10-12 are declared by the includes or left
// free but not read by this program (bind any small buffer there); 9 = readonly
// Query[], 14 = writeonly vec4[] (rgb: reflected radiance per unit irradiance).
// Push constant: the number of queries. runtime/tests/shader_kit.rs runs it against the
// Rust twin.
#version 450
#extension GL_GOOGLE_include_directive : require

#include "common/shading.glsl"

layout(local_size_x = 64) in;

struct Query {
    uvec4 texel;  // level, i, j, unused
    vec4 wi;      // toward the light, tile space, unit (xyz)
    vec4 wo;      // toward the viewer, tile space, unit (xyz)
};

layout(std430, set = 0, binding = 9) readonly buffer Queries { Query queries[]; };
layout(std430, set = 0, binding = 14) writeonly buffer Responses { vec4 responses[]; };
layout(push_constant) uniform Push { uint count; } push;

void main() {
    uint n = gl_GlobalInvocationID.x;
    if (n >= push.count) {
        return;
    }
    Query q = queries[n];
    TexelRef texel = texel_brdf(q.texel.x, q.texel.y, q.texel.z);
    Edit none = Edit(vec3(1.0), 1.0, 0.0);
    responses[n] = vec4(texel_response(texel, none, false, q.wi.xyz, q.wo.xyz, model_reading(), model_diffuse()), 0.0);
}
