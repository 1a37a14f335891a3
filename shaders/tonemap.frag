#version 460
// tonemap.frag — linear HDR radiance → display: sRGB(clamp(exposure · L)), the PNG
// mapping of DESIGN.md §8. With an *_SRGB target the hardware encodes (ENCODE_SRGB =
// false); with a UNORM target this shader does.
#include "common/color.glsl"

layout(constant_id = 0) const bool ENCODE_SRGB = false;

layout(set = 0, binding = 0) uniform sampler2D hdr;
layout(push_constant) uniform Push { float exposure; } pc;

layout(location = 0) in vec2 in_uv;
layout(location = 0) out vec4 out_color;

vec3 srgb_encode(vec3 c) {
    c = clamp(c, 0.0, 1.0);
    return mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, greaterThan(c, vec3(0.0031308)));
}

void main() {
    vec3 l = clamp(texture(hdr, in_uv).rgb * pc.exposure, 0.0, 1.0);
    out_color = vec4(ENCODE_SRGB ? srgb_encode(l) : l, 1.0);
}
