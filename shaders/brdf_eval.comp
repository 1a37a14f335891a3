// brdf_eval.comp — evaluates brdf.glsl for a buffer of inputs: the GPU half of the
// GLSL/Rust twin test (runtime/src/brdf/twin.rs has the same records and the Rust half).
//
// Bindings (set 0): 0 = readonly EvalInput[], 1 = writeonly EvalOutput[].
// Push constant: the number of inputs. One invocation per input, 64 per workgroup.
#version 450
#extension GL_GOOGLE_include_directive : require

#include "brdf.glsl"

layout(local_size_x = 64) in;

// 256 bytes, std430; runtime::brdf::twin::BrdfEvalInput.
struct EvalInput {
    vec4 n;                  // frame normal (xyz), not necessarily unit
    vec4 t;                  // frame tangent (xyz), not necessarily unit or perpendicular
    vec4 wi;                 // toward the light (xyz), unit
    vec4 wo;                 // toward the viewer (xyz), unit
    vec4 kd_eta;             // k_d (rgb), eta (w)
    float a;
    uint reading;            // CLOTH_READING_*
    uint lobe_count;
    uint pad;
    vec4 lobe_k_beta[CLOTH_MAX_LOBES];       // k (rgb), beta (w)
    vec4 lobe_gamma[CLOTH_MAX_LOBES / 4];    // gamma of lobe j at [j / 4][j % 4]
};

// 64 bytes; runtime::brdf::twin::BrdfEvalOutput.
struct EvalOutput {
    vec4 brdf;      // cloth_brdf (rgb)
    vec4 lobe0;     // cloth_lobe of lobe 0 in the same frame (rgb)
    vec4 fiber;     // cloth_brdf in cloth_fiber_frame(t, wo): t read as a fiber axis (rgb)
    vec4 cylinder;  // cloth_cylinder_lobe of lobe 0 in that fiber frame (rgb)
};

layout(std430, set = 0, binding = 0) readonly buffer Inputs { EvalInput inputs[]; };
layout(std430, set = 0, binding = 1) writeonly buffer Outputs { EvalOutput outputs[]; };
layout(push_constant) uniform Push { uint count; } push;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= push.count) {
        return;
    }
    EvalInput e = inputs[i];
    ClothParams p;
    p.kd = e.kd_eta.xyz;
    p.eta = e.kd_eta.w;
    p.a = e.a;
    p.lobe_count = min(e.lobe_count, uint(CLOTH_MAX_LOBES));
    for (int j = 0; j < CLOTH_MAX_LOBES; ++j) {
        p.lobes[j].k = e.lobe_k_beta[j].xyz;
        p.lobes[j].beta = e.lobe_k_beta[j].w;
        p.lobes[j].gamma = e.lobe_gamma[j / 4][j % 4];
    }
    ClothFrame f = cloth_frame(e.n.xyz, e.t.xyz);
    uint reading = e.reading <= CLOTH_READING_HELD ? e.reading : CLOTH_READING_BOUNDED;
    outputs[i].brdf = vec4(cloth_brdf(p, f, e.wi.xyz, e.wo.xyz, reading), 0.0);
    outputs[i].lobe0 = vec4(cloth_lobe(p.lobes[0], p.eta, p.a, f, e.wi.xyz, e.wo.xyz, reading), 0.0);
    ClothFrame ff = cloth_fiber_frame(e.t.xyz, e.wo.xyz);
    outputs[i].fiber = vec4(cloth_brdf(p, ff, e.wi.xyz, e.wo.xyz, reading), 0.0);
    outputs[i].cylinder = vec4(cloth_cylinder_lobe(p.lobes[0], p.eta, p.a, ff, e.wi.xyz, e.wo.xyz, reading), 0.0);
}
