// hybrid.comp — the per-pixel program of the hybrid renderer on a tile seen by a
// camera (DESIGN.md §7): the camera ray enters the tile's top plane, the height field
// is marched to the first surface hit, the levels come from the pixel's footprint at
// that hit, the flyaways in front are composited over the surface shaded with its
// texels' lobes.
//
// Twin: runtime/src/cpu/render.rs (Scene::enter_top, trace_mixed,
// march_level_flyaways, shade_surface, trace_pixel), function for function.
//
// Bindings (set 0): 0-6 the model (common/model.glsl), 7 the frame's parameters
// (common/render_params.glsl), 8 the image (vec4 per pixel, x fastest, rgb radiance),
// 9 the statistics (uint counters, STAT_*). One invocation per pixel, 8x8 per group.
#version 450
#extension GL_GOOGLE_include_directive : require

#include "common/level.glsl"
#include "common/flyaways.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(std430, set = 0, binding = 8) writeonly buffer ImageBlock { vec4 pixels[]; };
layout(std430, set = 0, binding = 9) buffer StatsBlock { uint stats[]; };

// runtime/src/gpu/hybrid_pass.rs reads these (RenderStats).
#define STAT_TILE 0
#define STAT_SURFACE 1
#define STAT_FLYAWAY 2
#define STAT_STEP_LIMITED 3
#define STAT_SHADOW_LIMITED 4
#define STAT_NON_FINITE 5
#define STAT_STEPS_LO 6
#define STAT_LEVELS 8

struct PixelTrace {
    vec3 radiance;
    int level;           // the finer of a blend's two; -1: missed the tile
    bool surface;
    float flyaway_opacity;
    bool step_limited;
    uint shadow_step_limited;
    uint steps;
};

// Where the ray enters the top plane, or false: from below, parallel, or (clamped
// tile) outside the tile.
bool enter_top(vec3 o, vec3 d, out float t) {
    t = 0.0;
    if (!(d.z < 0.0) || o.z < model.top_z) {
        return false;
    }
    t = (model.top_z - o.z) / d.z;
    if (!model_periodic()) {
        vec2 p = (o + d * t).xy - model.origin;
        if (p.x < 0.0 || p.y < 0.0 || p.x > model.size.x || p.y > model.size.y) {
            return false;
        }
    }
    return true;
}

// The flyaways of `level` over [t_top, t_end].
FlyawayMarch march_level_flyaways(vec3 o, vec3 d, float t_top, float t_end, uint level, inout uint shadow_limited) {
    if (!HAS_FLYAWAYS || model.levels[level].fly_nodes == 0u) {
        return FlyawayMarch(vec3(0.0), 1.0, 0u, false);
    }
    return march_flyaways(level, o, d, t_top, t_end, params.max_flyaway_columns, shadow_limited);
}

// The surface hit at t shaded with `level`, filtered as `mix` says at coarse levels.
vec3 shade_surface(vec3 o, vec3 d, float t, uint level, LevelMix mix_, inout uint shadow_limited) {
    vec3 p = o + t * d;
    bool volumetric = (model.flags & GPU_FLAG_VOLUMETRIC) != 0u;
    bool shadowed = level == 0u || (model.flags & GPU_FLAG_COARSE_VISIBILITY) == 0u;
    return shade_blend(level, p, -d, mix_.axis, mix_.taps, shadowed, volumetric, shadow_limited);
}

// One ray, shaded with the levels its footprint at (px, py) gives where it meets the
// surface (the top plane if it misses). The two levels of a blend are loops, not two
// calls: one inlined copy of each march and of the shading.
PixelTrace trace_mixed(vec3 o, vec3 d, float px, float py) {
    PixelTrace out_ = PixelTrace(params.background.rgb, -1, false, 0.0, false, 0u, 0u);
    float t_top;
    if (!enter_top(o, d, t_top)) {
        return out_;
    }
    uint steps = 0u;
    HfTrace hit = hf_trace(o, d, t_top, HF_F32_MAX, 0.0, params.max_steps, steps);
    out_.step_limited = hit.kind == HF_STEP_LIMIT;
    out_.steps = steps;
    out_.surface = hit.kind == HF_HIT;
    float z = out_.surface ? (o + d * hit.t).z : model.top_z;
    LevelMix mix_ = level_mix(px, py, z);
    out_.level = int(mix_.lo);
    float t_end = out_.surface ? hit.t : t_top + model.height_scale / -d.z;
    uint shadow_limited = 0u;
    // The flyaways in front, blended over their levels.
    vec3 fly_radiance = vec3(0.0);
    float fly_transmittance = 0.0;
    bool fly_blend = mix_.fly_weight > 0.0 && mix_.fly_hi != mix_.fly_lo;
    for (uint k = 0u; k < (fly_blend ? 2u : 1u); ++k) {
        float w = fly_blend ? (k == 0u ? 1.0 - mix_.fly_weight : mix_.fly_weight) : 1.0;
        FlyawayMarch fly = march_level_flyaways(o, d, t_top, t_end, k == 0u ? mix_.fly_lo : mix_.fly_hi, shadow_limited);
        fly_radiance = k == 0u ? fly.radiance * w : fly_radiance + fly.radiance * w;
        fly_transmittance = k == 0u ? fly.transmittance * w : fly_transmittance + fly.transmittance * w;
        out_.step_limited = out_.step_limited || fly.limited;
    }
    out_.flyaway_opacity = 1.0 - fly_transmittance;
    // What they let through sees the surface, blended over its levels.
    vec3 behind = params.background.rgb;
    if (out_.surface) {
        behind = vec3(0.0);
        if (fly_transmittance > 0.0) {
            bool blend = mix_.weight > 0.0 && mix_.hi != mix_.lo;
            for (uint k = 0u; k < (blend ? 2u : 1u); ++k) {
                vec3 s = shade_surface(o, d, hit.t, k == 0u ? mix_.lo : mix_.hi, mix_, shadow_limited);
                behind = !blend ? s : (k == 0u ? s * (1.0 - mix_.weight) : behind + s * mix_.weight);
            }
        }
    }
    out_.shadow_step_limited = shadow_limited;
    out_.radiance = fly_radiance + fly_transmittance * behind;
    return out_;
}

// One pixel: s x s samples on a regular grid, levels from the pixel centre's footprint.
PixelTrace trace_pixel(uint x, uint y) {
    float cx = float(x) + 0.5;
    float cy = float(y) + 0.5;
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
        PixelTrace t = trace_mixed(o, d, cx, cy);
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
    PixelTrace t = trace_pixel(x, y);
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
