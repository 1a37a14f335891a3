// packing.glsl — decoding the packed scalars and directions of the hybrid model.
//
// Twin: runtime/src/hybrid/packing.rs (the decoding half: f16_value, unorm16_value,
// snorm16_value, snorm8_value, octahedral_decode, octahedral_decode8, tangent_angle_decode) and decode_frame of
// runtime/src/hybrid/lobe.rs. Same names, same arithmetic. Codes arrive as 16-bit fields
// of 32-bit words (little-endian: the low half is the first field).
#ifndef PACKING_GLSL
#define PACKING_GLSL

#include "brdf.glsl"

const float PACKING_PI = 3.14159265358979323846;

// IEEE binary16 bits (low 16 bits of `bits`) -> f32, exact.
float f16_value(uint bits) {
    return unpackHalf2x16(bits & 0xffffu).x;
}

// unorm16 -> [0, 1].
float unorm16_value(uint code) {
    return float(code & 0xffffu) * (1.0 / 65535.0);
}

// snorm16 bits -> [-1, 1] (Vulkan's SNORM conversion).
float snorm16_value(uint code) {
    int c = int(code << 16) >> 16;
    return max(float(c) * (1.0 / 32767.0), -1.0);
}

float packing_sign_not_zero(float x) {
    return x >= 0.0 ? 1.0 : -1.0;
}

// snorm8 byte k (0 = lowest) of `bits` -> [-1, 1] (Vulkan's SNORM conversion).
float snorm8_value(uint bits, uint k) {
    int c = int(bits << (24u - 8u * k)) >> 24;
    return max(float(c) * (1.0 / 127.0), -1.0);
}

// Unit direction of octahedral coordinates (u, v) in [-1, 1]^2.
vec3 octahedral_from_uv(float u, float v) {
    float z = 1.0 - abs(u) - abs(v);
    float x = u;
    float y = v;
    if (z < 0.0) {
        x = (1.0 - abs(v)) * packing_sign_not_zero(u);
        y = (1.0 - abs(u)) * packing_sign_not_zero(v);
    }
    vec3 w = vec3(x, y, z);
    return w * (1.0 / length(w));
}

// Unit direction of an octahedral code: u in the low half of `word`, v in the high half.
vec3 octahedral_decode(uint word) {
    return octahedral_from_uv(snorm16_value(word), snorm16_value(word >> 16));
}

// Unit direction of an 8-bit octahedral code: u in byte 0 of `word`, v in byte 1.
vec3 octahedral_decode8(uint word) {
    return octahedral_from_uv(snorm8_value(word, 0u), snorm8_value(word, 1u));
}

// The unit tangent of a tangent-angle code around unit normal n.
vec3 tangent_angle_decode(vec3 n, uint code) {
    float psi = float(code & 0xffffu) * (PACKING_PI / 65536.0);
    vec3 r = cloth_reference_tangent(n);
    vec3 s = cross(n, r);
    return r * cos(psi) + s * sin(psi);
}

// A packed frame: the normal's octahedral word and the tangent's angle code.
ClothFrame decode_frame(uint normal_word, uint tangent_angle) {
    vec3 n = octahedral_decode(normal_word);
    vec3 t = tangent_angle_decode(n, tangent_angle);
    ClothFrame f;
    f.n = n;
    f.t = t;
    f.b = cross(n, t);
    return f;
}

#endif // PACKING_GLSL
