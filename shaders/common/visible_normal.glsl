// visible_normal.glsl — a coarse texel's frames turned toward the viewer as its
// footprint's visible normals are, and how much of it a distant view sees (format 1.4,
// VIEW_TILT; runtime/HYBRID_FORMAT.md §4.9).
//
// Twin: runtime/src/brdf/visible_normal.rs (same names, same order):
//   sigma(n) = n.xy / n.z,  u(wo) = wo.xy / sqrt(wo.z),  sigma_vis = sigma(n_0) + B u,
//   v(wo) = clamp(1 + c . u, VISIBILITY_MIN, VISIBILITY_MAX).
#ifndef VISIBLE_NORMAL_GLSL
#define VISIBLE_NORMAL_GLSL

const float TILT_VIEW_Z_MIN = 0.05;
const float TILT_SLOPE_MAX = 1.0;
const float TILT_NORMAL_Z_MIN = 0.1;
const float VISIBILITY_MAX = 4.0;
const float VISIBILITY_MIN = 0.05;

struct ViewTilt {
    vec4 b;     // B row-major: b.x b.y; b.z b.w
    vec2 c;
};

vec2 view_tilt_basis(vec3 wo) {
    return vec2(wo.x, wo.y) / sqrt(max(wo.z, TILT_VIEW_Z_MIN));
}

vec2 view_tilt_offset(vec4 b, vec3 wo) {
    vec2 u = view_tilt_basis(wo);
    vec2 d = vec2(b.x * u.x + b.y * u.y, b.z * u.x + b.w * u.y);
    float len = length(d);
    return len > TILT_SLOPE_MAX ? d * (TILT_SLOPE_MAX / len) : d;
}

vec3 visible_normal(vec3 n0, vec4 b, vec3 wo) {
    vec2 d = view_tilt_offset(b, wo);
    // No offset (a view from above, B = 0): n_0 itself, not its round trip through sigma.
    if (n0.z < TILT_NORMAL_Z_MIN || d == vec2(0.0)) {
        return n0;
    }
    vec2 s = vec2(n0.x, n0.y) / n0.z + d;
    return normalize(vec3(s.x, s.y, 1.0));
}

// x turned by the rotation that takes unit a to unit b (about a x b; a.b > -1).
vec3 rotate_arc(vec3 a, vec3 b, vec3 x) {
    float c = dot(a, b);
    vec3 v = cross(a, b);
    return x * c + cross(v, x) + v * (dot(v, x) / (1.0 + c));
}

float view_visibility(ViewTilt t, vec3 wo) {
    vec2 u = view_tilt_basis(wo);
    return clamp(1.0 + t.c.x * u.x + t.c.y * u.y, VISIBILITY_MIN, VISIBILITY_MAX);
}

#endif // VISIBLE_NORMAL_GLSL
