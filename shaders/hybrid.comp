// hybrid.comp — the hybrid renderer on a tile seen by a camera, one invocation per
// pixel: the camera's rays traced through the model (common/trace.glsl), the levels
// from the pixel's footprint where each ray meets the surface, from the rays through
// the neighbouring pixels (DESIGN.md §7).
//
// Twin: runtime/src/cpu/render.rs (Scene::trace_pixel and the image loop; the rest is
// in the includes).
//
// Bindings (set 0): 0-6 the model (common/model.glsl), 7 the frame's parameters and
// 8 the edit mask (common/render_params.glsl), 9 the image (vec4 per pixel, x fastest,
// rgb radiance), 10 the statistics (uint counters, STAT_*), 11 the prefiltered
// environment (common/env_shading.glsl). One invocation per pixel, 8x8 per group.
#version 450
#extension GL_GOOGLE_include_directive : require

// This program shades environment light (specialization constant HAS_ENV, binding 11).
#define HYBRID_ENV
#include "common/trace.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(std430, set = 0, binding = 9) writeonly buffer ImageBlock { vec4 pixels[]; };
layout(std430, set = 0, binding = 10) buffer StatsBlock { uint stats[]; };

// runtime/src/gpu/hybrid_pass.rs reads these (RenderStats).
#define STAT_TILE 0
#define STAT_SURFACE 1
#define STAT_FLYAWAY 2
#define STAT_STEP_LIMITED 3
#define STAT_SHADOW_LIMITED 4
#define STAT_NON_FINITE 5
#define STAT_STEPS_LO 6
#define STAT_LEVELS 8
#define STAT_LOOPS_CUT (STAT_LEVELS + GPU_MAX_LEVELS)

// The pixel being traced (its centre): its footprint chooses the levels.
vec2 g_pixel;

LevelMix choose_levels(float z) {
    return level_mix(g_pixel.x, g_pixel.y, z);
}

// One pixel: s x s samples on a regular grid, levels from the pixel centre's footprint
// over s (each sample filters its own sub-pixel; level_mix).
PixelTrace trace_pixel(uint x, uint y) {
    float cx = float(x) + 0.5;
    float cy = float(y) + 0.5;
    g_pixel = vec2(cx, cy);
    uint s = max(params.supersampling, 1u);
    PixelTrace acc = PixelTrace(vec3(0.0), -1, false, 0.0, false, 0u, 0u);
    float inv = 1.0 / float(s);
    for (uint k = 0u; k < s * s; ++k) {
        uint a = k / s;
        uint b = k % s;
        // s = 1: the pixel centre exactly, as the CPU's single sample.
        float sx = s == 1u ? cx : float(x) + (float(b) + 0.5) * inv;
        float sy = s == 1u ? cy : float(y) + (float(a) + 0.5) * inv;
        vec3 o, d;
        camera_ray(sx, sy, o, d);
        PixelTrace t = trace_mixed(o, d);
        acc.radiance += t.radiance;
        acc.level = acc.level >= 0 ? acc.level : t.level;
        acc.surface = acc.surface || t.surface;
        acc.flyaway_opacity += t.flyaway_opacity;
        acc.step_limited = acc.step_limited || t.step_limited;
        acc.shadow_step_limited += t.shadow_step_limited;
        acc.steps += t.steps;
    }
    float n = float(s * s);
    acc.radiance = s == 1u ? acc.radiance : acc.radiance / n;
    acc.flyaway_opacity = s == 1u ? acc.flyaway_opacity : acc.flyaway_opacity / n;
    return acc;
}

void main() {
    uvec2 size = params.camera.size;
    uint x = gl_GlobalInvocationID.x;
    uint y = gl_GlobalInvocationID.y;
    if (x >= size.x || y >= size.y) {
        return;
    }
    for (int k = 0; k < GPU_MAX_LIGHTS; ++k) {
        g_lights[k] = params.lights[k];
    }
    PixelTrace t = trace_pixel(x, y);
    // Pixels whose loops the driver cut short are counted (RenderStats::loop_cut_pixels),
    // and the command line says so.
    if (loop_budget_spent()) {
        atomicAdd(stats[STAT_LOOPS_CUT], 1u);
    }
    bool finite = !any(isnan(t.radiance)) && !any(isinf(t.radiance));
    pixels[y * size.x + x] = vec4(finite ? t.radiance : vec3(0.0), finite ? 1.0 : 0.0);
    if (t.level >= 0) {
        atomicAdd(stats[STAT_TILE], 1u);
        atomicAdd(stats[STAT_LEVELS + t.level], 1u);
    }
    if (t.surface) {
        atomicAdd(stats[STAT_SURFACE], 1u);
    }
    if (t.flyaway_opacity > 0.0) {
        atomicAdd(stats[STAT_FLYAWAY], 1u);
    }
    if (t.step_limited) {
        atomicAdd(stats[STAT_STEP_LIMITED], 1u);
    }
    if (t.shadow_step_limited > 0u) {
        atomicAdd(stats[STAT_SHADOW_LIMITED], t.shadow_step_limited);
    }
    if (!finite) {
        atomicAdd(stats[STAT_NON_FINITE], 1u);
    }
    // Steps as a 64-bit count over two words (carry on wrap).
    uint before = atomicAdd(stats[STAT_STEPS_LO], t.steps);
    if (before + t.steps < before) {
        atomicAdd(stats[STAT_STEPS_LO + 1], 1u);
    }
}
