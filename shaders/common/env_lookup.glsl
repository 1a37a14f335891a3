// env_lookup.glsl — reading the prefiltered environment: a direction's (u, v), a
// level's bilinear lookup, the SG-blurred radiance and the irradiance (paper §7.2,
// "Extensions"; runtime/HYBRID_FORMAT.md §6). Included by env_shading.glsl and by the
// mesh pass where no triangle is (hybrid_mesh.comp).
//
// Twin: runtime/src/scene/env_prefilter.rs (EnvLevel::bilinear, PrefilteredEnv::blurred,
// PrefilteredEnv::irradiance) and EnvMap::uv (scene/envmap.rs).
#ifndef ENV_LOOKUP_GLSL
#define ENV_LOOKUP_GLSL

#include "brdf.glsl"
#include "common/render_params.glsl"

// The prefiltered levels, then the irradiance map: rgb per texel, row 0 at the map's
// zenith, x fastest (GpuEnv, runtime/src/hybrid/gpu_layout.rs).
layout(std430, set = 0, binding = 11) readonly buffer EnvBlock { vec4 env_texels[]; };

#define ENV_PI 3.14159265358979
#define ENV_TAU 6.28318530717959

// Shading directions -> world: the identity for the tile pass; the mesh pass sets its
// pixel's M = [T_w B_w kN] (tile offsets to world, hybrid_mesh.comp).
mat3 g_env_to_world = mat3(1.0);

// EnvMap::uv: world direction -> (u, v) in [0, 1)^2 (Mitsuba's envmap layout, Z up,
// turned by the map's rotation). acos through the twins' own arctangent.
vec2 env_uv(vec3 w_shading) {
    vec3 w = normalize(g_env_to_world * w_shading);
    float c = params.env_frame.x;
    float s = params.env_frame.y;
    vec3 r = vec3(c * w.x + s * w.y, -s * w.x + c * w.y, w.z);
    vec3 l = vec3(r.x, r.z, -r.y);
    float u = cloth_atan2(l.x, -l.z) / ENV_TAU;
    if (u < 0.0) {
        u += 1.0;
    }
    float y = clamp(l.y, -1.0, 1.0);
    float v = cloth_atan2(sqrt(max(1.0 - y * y, 0.0)), y) / ENV_PI;
    const float ONE_MINUS = 1.0 - 5.96046448e-8;
    return vec2(min(u, ONE_MINUS), min(v, ONE_MINUS));
}

// EnvLevel::bilinear of slot k of env_levels (GpuEnv: 0-7 the chain above the horizon,
// 8-15 below, 16 and 17 the irradiance maps): wraps in u, clamps in v.
vec3 env_bilinear(uint k, vec2 uv) {
    uvec4 lv = params.env_levels[k];
    int w = int(lv.y);
    int h = int(lv.z);
    float x = uv.x * float(w) - 0.5;
    float y = clamp(uv.y * float(h) - 0.5, 0.0, float(h - 1));
    float x0 = floor(x);
    float y0 = floor(y);
    float fx = x - x0;
    float fy = y - y0;
    int xi = int(x0) % w;
    xi = xi < 0 ? xi + w : xi;
    int x1 = (xi + 1) % w;
    int yi = int(y0);
    int y1 = min(yi + 1, h - 1);
    uint base = lv.x;
    vec3 a = env_texels[base + uint(yi * w + xi)].rgb;
    vec3 b = env_texels[base + uint(yi * w + x1)].rgb;
    vec3 c = env_texels[base + uint(y1 * w + xi)].rgb;
    vec3 d = env_texels[base + uint(y1 * w + x1)].rgb;
    vec3 top = mix(a, b, fx);
    vec3 bottom = mix(c, d, fx);
    return mix(top, bottom, fy);
}

// PrefilteredEnv::level_of: the level nearest sigma in log2.
uint env_level_of(float sigma) {
    float sigma0 = params.env_frame.z;
    uint count = params.env_info.x;
    float l = sigma > sigma0 ? log2(sigma / sigma0) : 0.0;
    return uint(min(l, float(count - 1u)) + 0.5);
}

// PrefilteredEnv::blurred: the mean radiance under a normalized SG of width sigma of the
// map's half on w's side of its horizon (in the world: on a mesh, away from the map's
// horizon, the same as the whole map's).
vec3 env_blurred(vec3 w, float sigma) {
    vec2 uv = env_uv(w);
    return env_bilinear(((g_env_to_world * w).z < 0.0 ? 8u : 0u) + env_level_of(sigma), uv);
}

// PrefilteredEnv::irradiance: the light of the half above the horizon, what reaches a
// tile's reflection; on a mesh (env_info.w) the whole sphere's.
vec3 env_irradiance(vec3 n) {
    return env_bilinear(params.env_info.w != 0u ? 17u : 16u, env_uv(n));
}

// PrefilteredEnv::irradiance_full.
vec3 env_irradiance_full(vec3 n) {
    return env_bilinear(17u, env_uv(n));
}

#endif // ENV_LOOKUP_GLSL
