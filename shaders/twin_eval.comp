// twin_eval.comp — evaluates the functions of the hybrid renderer's includes for a
// buffer of inputs: the GPU half of the per-include twin test
// (runtime/tests/gpu_twins.rs has the same records and the Rust half). Each input names
// the function (kind) and its arguments; the model and frame bindings are the renderer's.
//
// Bindings (set 0): 0-8 as hybrid.comp (model, params, edit mask); 9 = readonly
// TwinInput[]; 10-11 unused (any small buffer); 12-13 as hybrid.comp (transmission,
// view tilt and gradient records); 14 = writeonly TwinOutput[]. Push constant: the
// number of inputs.
#version 450
#extension GL_GOOGLE_include_directive : require

#include "common/trace.glsl"

layout(local_size_x = 64) in;

// 80 bytes; gpu_twins.rs TwinInput.
struct TwinInput {
    uint kind;
    uint level;
    uint i;
    uint j;
    uvec4 u;
    vec4 a;
    vec4 b;
    vec4 c;
};

// 64 bytes; gpu_twins.rs TwinOutput.
struct TwinOutput {
    vec4 x;
    vec4 y;
    vec4 z;
    vec4 w;
};

layout(std430, set = 0, binding = 9) readonly buffer Inputs { TwinInput inputs[]; };
layout(std430, set = 0, binding = 14) writeonly buffer Outputs { TwinOutput outputs[]; };
layout(push_constant) uniform Push { uint count; } push;

LevelMix choose_levels(float z) {
    return level_single(0u);
}

void main() {
    uint n = gl_GlobalInvocationID.x;
    if (n >= push.count) {
        return;
    }
    for (int k = 0; k < GPU_MAX_LIGHTS; ++k) {
        g_lights[k] = params.lights[k];
    }
    TwinInput e = inputs[n];
    TwinOutput o = TwinOutput(vec4(0.0), vec4(0.0), vec4(0.0), vec4(0.0));
    if (e.kind == 0u) {
        // packing.glsl
        vec3 nrm = octahedral_decode(e.u.x);
        o.x = vec4(nrm, f16_value(e.u.z));
        o.y = vec4(tangent_angle_decode(nrm, e.u.y), snorm16_value(e.u.w));
        o.z = vec4(unorm16_value(e.u.w), 0.0, 0.0, 0.0);
    } else if (e.kind == 1u) {
        // heightfield.glsl: the march and the surface's depth
        uint steps = 0u;
        HfTrace h = hf_trace(e.a.xyz, e.b.xyz, e.a.w, e.b.w, e.c.x, e.u.x, steps, int(e.u.y));
        o.x = vec4(float(h.kind), h.t, float(steps), hf_depth_at(e.c.y, e.c.z));
    } else if (e.kind == 2u) {
        // heightfield.glsl: shadow rays
        bool limited;
        bool blocked = hf_occluded(e.a.xyz, e.b.xyz, e.b.w, e.u.x, limited);
        o.x = vec4(blocked ? 1.0 : 0.0, limited ? 1.0 : 0.0, 0.0, 0.0);
    } else if (e.kind == 3u) {
        // flyaways.glsl: the march (no light: transmittance and columns)
        uint sl = 0u;
        FlyawayMarch m = march_flyaways(e.level, e.a.xyz, e.b.xyz, e.a.w, e.b.w, e.u.x, FLY_LIGHT_ALL, sl);
        o.x = vec4(m.radiance, m.transmittance);
        o.y = vec4(float(m.columns), m.limited ? 1.0 : 0.0, 0.0, 0.0);
    } else if (e.kind == 4u) {
        // model.glsl + shading.glsl: a texel's response, unedited
        TexelRef r = texel_brdf(e.level, e.i, e.j);
        o.x = vec4(texel_response(r, Edit(vec3(1.0), 1.0, 0.0), false, e.a.xyz, e.b.xyz, model_reading(), model_diffuse()), 0.0);
    } else if (e.kind == 5u) {
        // level.glsl: levels of a footprint
        LevelMix m = level_mix_axes(e.u.x != 0u, e.a.xy, e.a.zw);
        o.x = vec4(float(m.lo), float(m.hi), m.weight, float(m.taps));
        // The shadow levels packed beside the fly levels (+ 64 · shadow_lo, hi) and beside
        // taps_minor (+ shadow_weight / 2).
        o.y = vec4(m.axis, float(m.fly_lo) + 64.0 * float(m.shadow_lo), float(m.fly_hi) + 64.0 * float(m.shadow_hi));
        o.z = vec4(m.fly_weight, float(m.taps_minor) + 0.5 * m.shadow_weight, m.minor_axis);
        o.w = vec4(m.fly_axis_a, m.fly_axis_b);
        o.x.w += 1000.0 * float(m.fly_taps_a) + 100000.0 * float(m.fly_taps_b);
    } else if (e.kind == 6u) {
        // model.glsl: texel lookups
        uvec2 ij;
        float w = bilinear_texel(e.a.xyz, e.level, int(e.u.x), ij);
        uvec2 t = texel_at(e.a.xyz, e.level);
        o.x = vec4(float(ij.x), float(ij.y), w, 0.0);
        o.y = vec4(float(t.x), float(t.y), 0.0, 0.0);
    } else if (e.kind == 8u) {
        // axis_spread.glsl: a node's axes (u.x its tangent, u.y the record, u.w its axis
        // group; u.z = h: axes 2h and 2h + 1), the weights of their group of four in z
        SpreadAxes s = packed_grouped_axes(octahedral_decode(e.u.x), e.u.y, e.u.w);
        uint first = 2u * min(e.u.z, 3u);
        uint group = first >= 4u ? 4u : 0u;
        o.x = vec4(s.axes[first], 0.0);
        o.y = vec4(s.axes[first + 1u], 0.0);
        o.z = vec4(s.weights[group], s.weights[group + 1u], s.weights[group + 2u], s.weights[group + 3u]);
    } else if (e.kind == 7u) {
        // shading.glsl and flyaways.glsl scalars
        vec3 n = normalize(vec3(e.a.y, e.b.x, 1.0));
        o.x = vec4(volume_factor(e.a.xyz, e.b.xyz), flyaway_opacity(e.c.x, e.c.y, e.c.z),
                   cloth_diffuse_cosine(CLOTH_DIFFUSE_LOMMEL_SEELIGER, n, e.a.xyz, e.b.xyz),
                   cloth_diffuse_env_factor(CLOTH_DIFFUSE_LOMMEL_SEELIGER, e.b.xyz));
        // The curvature q made from the gradient's inputs as gpu_twins.rs makes it.
        vec4 g = uintBitsToFloat(e.u);
        float v = cloth_visibility(g, vec3(g.x, g.y, g.z * g.w), vec3(g.z, g.w, g.x * g.y), e.a.xyz, e.b.xyz);
        o.y = vec4(cloth_visibility_gradient(g, e.a.xyz, e.b.xyz), v, 0.0, 0.0);
    }
    outputs[n] = o;
}
