#version 460
// hybrid_mesh.frag — the hybrid fabric on a base mesh (paper §6): the tile repeats over
// the mesh's UVs (push.uv_scale repeats per UV unit) with its top plane on the surface;
// per fragment, the view ray and the lights are mapped into tile space and traced through
// the model as on a plane (common/trace.glsl).
//
// The map. At a fragment with world position P, normal N and UV derivatives from the
// screen, the tile's x and y axes run along dP/du and dP/dv (divided by the world length
// of one tile unit), its z along N scaled by the geometric mean of those two lengths, so
// that the relief keeps its proportions: M = [T_w  B_w  k N], tile offset = M^-1 world
// offset. Directions (the ray, the lights, the viewer) go through M^-1 and are
// normalized: on a conformal map (plane, and locally sphere and cylinder away from
// their poles) this is the rotation into the tangent frame; elsewhere the parallax and
// the shading follow the stretched texture alike.
//
// Where this differs from the CPU renderer of a plane (stated, and tested with their
// tolerance in runtime/tests/gpu_hybrid.rs): the footprint comes from screen-space
// derivatives of the tile position on the top plane (a 2x2 pixel quad's differences),
// not from the neighbouring rays at the hit's height; lights and the view go through the
// local linear map of this fragment (exact on a plane); one sample per pixel; radiance
// is stored as f16. Silhouettes are the mesh's: a ray leaving the relief
// sideways on a curved mesh keeps marching the (periodic) plane.
#extension GL_GOOGLE_include_directive : require

// Environment light (specialization constant HAS_ENV, binding 11): lookups go back to the
// world through this fragment's M (g_env_to_world).
#define HYBRID_ENV
#include "common/trace.glsl"

layout(push_constant) uniform Push {
    mat4 view_proj;
    vec2 uv_scale;
} push;

layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;
layout(location = 2) in vec4 in_tangent;
layout(location = 3) in vec2 in_uv;

layout(location = 0) out vec4 out_color;

// The footprint of this fragment on the tile's top plane (tile x-y per pixel right, down).
vec2 g_axis_a;
vec2 g_axis_b;

LevelMix choose_levels(float z) {
    return level_mix_axes(true, g_axis_a, g_axis_b);
}

void main() {
    GpuCamera cam = params.camera;
    vec3 p = in_position;
    vec3 n = normalize(in_normal);
    // Tile position of this fragment on the top plane.
    vec2 tile_units = in_uv * push.uv_scale * model.size;
    vec2 xy = model.origin + tile_units;
    // dP/d(tile x), dP/d(tile y) from the screen derivatives of P and of the tile position.
    // Derivatives of interpolants only, scaled afterwards: a helper invocation (the
    // part of a 2x2 quad outside the triangle) need not load buffers (lavapipe's gives
    // zeros), so dFdx of anything read from memory is wrong along triangle edges. Fine
    // derivatives (per pixel, not per 2x2 quad): plain dFdx may be either, by driver,
    // and the coarse one gives a quad one footprint, hence one level, where the tile
    // pass's per-pixel rays give each pixel its own.
    vec3 dpx = dFdxFine(p), dpy = dFdyFine(p);
    vec2 tile_per_uv = push.uv_scale * model.size;
    vec2 dtx = dFdxFine(in_uv) * tile_per_uv, dty = dFdyFine(in_uv) * tile_per_uv;
    float det = dtx.x * dty.y - dtx.y * dty.x;
    vec3 t_w, b_w;
    if (abs(det) > 1e-30) {
        t_w = (dpx * dty.y - dpy * dtx.y) / det;
        b_w = (dpy * dtx.x - dpx * dty.x) / det;
    } else {
        // No UV variation across the quad: the vertex tangent frame, unit scale.
        t_w = normalize(in_tangent.xyz);
        b_w = in_tangent.w * cross(n, t_w);
    }
    float k = sqrt(length(t_w) * length(b_w));
    mat3 to_world = mat3(t_w, b_w, k * n);
    mat3 to_tile = inverse(to_world);
    g_env_to_world = to_world;
    vec3 d_world = cam.origin.w != 0.0 ? normalize(p - cam.origin.xyz) : cam.forward.xyz;
    vec3 d = to_tile * d_world;
    float len = length(d);
    out_color = vec4(params.background.rgb, 1.0);
    if (!(len > 0.0) || !(d.z < 0.0) || isinf(k) || !(k > 0.0)) {
        return;
    }
    d /= len;
    // Lights in tile space: a direction through M^-1; a point light's position through
    // the affine map about this fragment, its intensity divided by k^2 so that its
    // irradiance at tile distance d_t is I / (k d_t)^2, the world's.
    vec3 top = vec3(xy, model.top_z);
    for (uint j = 0u; j < uint(GPU_MAX_LIGHTS); ++j) {
        GpuLight l = params.lights[j];
        if (l.vec.w == 0.0) {
            vec3 wt = to_tile * l.vec.xyz;
            float lt = length(wt);
            g_lights[j] = GpuLight(vec4(lt > 0.0 ? wt / lt : vec3(0.0, 0.0, -1.0), 0.0), l.power);
        } else {
            g_lights[j] = GpuLight(vec4(top + to_tile * (l.vec.xyz - p), 1.0), vec4(l.power.rgb / (k * k), 0.0));
        }
    }
    g_axis_a = dtx;
    g_axis_b = dty;
    // Start a texel above the top plane so that the ray enters it.
    float lift = min(model.texel.x, model.texel.y);
    vec3 o = top - d * lift;
    PixelTrace t = trace_mixed(o, d);
    bool finite = !any(isnan(t.radiance)) && !any(isinf(t.radiance));
    out_color = vec4(finite ? t.radiance : vec3(0.0), 1.0);
}
