#version 460
// mesh_lit.frag — a textured Lambertian surface under one light:
//   L = base_color · texture(uv) / π · E⊥ · max(n·ωi, 0)
// in linear RGB. The texture is sRGB-encoded and decoded by the sampler.
#include "common/frame.glsl"
#include "common/lights.glsl"
#include "common/color.glsl"

layout(set = 0, binding = 0) uniform Frame { FrameUniforms frame; };
layout(set = 0, binding = 1) uniform sampler2D albedo_tex;

layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;
layout(location = 2) in vec4 in_tangent;
layout(location = 3) in vec2 in_uv;

layout(location = 0) out vec4 out_color;

void main() {
    vec3 n = normalize(in_normal);
    vec3 wi;
    float dist;
    vec3 e = light_incident(frame.light_vec, frame.light_power.rgb, in_position, wi, dist);
    vec3 albedo = frame.base_color.rgb * texture(albedo_tex, in_uv).rgb;
    out_color = vec4(albedo * INV_PI * e * max(dot(n, wi), 0.0), 1.0);
}
