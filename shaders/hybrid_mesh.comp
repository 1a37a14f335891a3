#version 460
// hybrid_mesh.comp — the hybrid fabric on a base mesh (paper §6), shaded once per pixel:
// the visibility pass (hybrid_mesh_id.vert/.frag) leaves each pixel the number of the
// nearest triangle, and this pass rebuilds what a fragment shader would have been given
// — the perspective-correct interpolants at the pixel centre (the camera ray's
// barycentrics on the triangle's plane) and their fine screen derivatives (the same
// plane at the neighbouring pixel of its 2x2 quad, as a helper invocation extrapolates)
// — then traces the tile as on a plane. Shading in a compute pass instead of the
// fragment stage: a fragment shader runs every 2x2 quad a triangle touches, so where
// triangles are a few pixels wide most pixels were traced several times over
// (runtime/GPU_MEASUREMENTS.md, "The mesh pass").
//
// The map. At a pixel with world position P, normal N and UV derivatives from the
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
// local linear map of this pixel (exact on a plane); one sample per pixel; radiance
// is stored as f16. Silhouettes are the mesh's: a ray leaving the relief
// sideways on a curved mesh keeps marching the (periodic) plane. Where no triangle is,
// the environment (its sharpest level, as the tile pass shows a ray that misses the
// tile) or the plain background.
#extension GL_GOOGLE_include_directive : require

// Environment light (specialization constant HAS_ENV, binding 11): lookups go back to the
// world through this pixel's M (g_env_to_world).
#define HYBRID_ENV
#include "common/trace.glsl"
#include "common/mesh_buffers.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(push_constant) uniform Push {
    mat4 view_proj;
    vec2 uv_scale;
} push;

layout(set = 0, binding = 16, r32ui) uniform readonly uimage2D triangle_ids;
layout(set = 0, binding = 17, rgba16f) uniform writeonly image2D out_image;

// The footprint of this pixel on the tile's top plane (tile x-y per pixel right, down).
vec2 g_axis_a;
vec2 g_axis_b;

LevelMix choose_levels(float z) {
    return level_mix_axes(true, g_axis_a, g_axis_b);
}

// Barycentrics (u, v) of the camera ray through the pixel point (px, py) on the plane
// of the triangle p0 + u e1 + v e2 (Möller–Trumbore without the inside test: a
// neighbour's ray extrapolates the plane, as a helper invocation's interpolants do).
vec2 plane_barycentrics(float px, float py, vec3 p0, vec3 e1, vec3 e2) {
    vec3 o, d;
    camera_ray(px, py, o, d);
    vec3 pv = cross(d, e2);
    vec3 tv = o - p0;
    vec3 qv = cross(tv, e1);
    return vec2(dot(tv, pv), dot(d, qv)) / dot(e1, pv);
}

bool finite2(vec2 v) {
    return !any(isnan(v)) && !any(isinf(v));
}

void main() {
    uvec2 size = params.camera.size;
    uint x = gl_GlobalInvocationID.x;
    uint y = gl_GlobalInvocationID.y;
    if (x >= size.x || y >= size.y) {
        return;
    }
    ivec2 at = ivec2(x, y);
    float cx = float(x) + 0.5;
    float cy = float(y) + 0.5;
    uint id = imageLoad(triangle_ids, at).x;
    if (id == 0u) {
        vec3 o, d;
        camera_ray(cx, cy, o, d);
        vec3 c = params.background.rgb;
        if (HAS_ENV && params.env_info.y != 0u) {
            c = env_blurred(d, 0.0);
        }
        bool finite = !any(isnan(c)) && !any(isinf(c));
        imageStore(out_image, at, vec4(finite ? c : vec3(0.0), 1.0));
        return;
    }
    uint tri = id - 1u;
    uint i0 = mesh_indices[3u * tri], i1 = mesh_indices[3u * tri + 1u], i2 = mesh_indices[3u * tri + 2u];
    vec3 p0 = mesh_position(i0);
    vec3 e1 = mesh_position(i1) - p0, e2 = mesh_position(i2) - p0;
    vec2 b = plane_barycentrics(cx, cy, p0, e1, e2);
    // The pixel pairs of dFdxFine / dFdyFine: columns x & ~1 and x | 1, rows likewise.
    float qx = float(x & ~1u) + 0.5, qy = float(y & ~1u) + 0.5;
    vec2 dbx = plane_barycentrics(qx + 1.0, cy, p0, e1, e2) - plane_barycentrics(qx, cy, p0, e1, e2);
    vec2 dby = plane_barycentrics(cx, qy + 1.0, p0, e1, e2) - plane_barycentrics(cx, qy, p0, e1, e2);
    // A neighbour's ray along the plane (a silhouette seen edge-on): no footprint there.
    if (!finite2(dbx) || !finite2(dby)) {
        dbx = vec2(0.0);
        dby = vec2(0.0);
    }
    vec3 p = p0 + b.x * e1 + b.y * e2;
    vec3 dpx = dbx.x * e1 + dbx.y * e2, dpy = dby.x * e1 + dby.y * e2;
    vec3 n0 = mesh_normal(i0);
    vec3 n_in = n0 + b.x * (mesh_normal(i1) - n0) + b.y * (mesh_normal(i2) - n0);
    vec4 t0 = mesh_tangent(i0);
    vec4 tangent = t0 + b.x * (mesh_tangent(i1) - t0) + b.y * (mesh_tangent(i2) - t0);
    vec2 uv0 = mesh_uv(i0), f1 = mesh_uv(i1) - uv0, f2 = mesh_uv(i2) - uv0;
    vec2 uv = uv0 + b.x * f1 + b.y * f2;
    vec2 duvx = dbx.x * f1 + dbx.y * f2, duvy = dby.x * f1 + dby.y * f2;
    GpuCamera cam = params.camera;
    vec3 n = normalize(n_in);
    // Tile position of this pixel on the top plane.
    vec2 tile_units = uv * push.uv_scale * model.size;
    vec2 xy = model.origin + tile_units;
    // dP/d(tile x), dP/d(tile y) from the screen derivatives of P and of the tile position.
    vec2 tile_per_uv = push.uv_scale * model.size;
    vec2 dtx = duvx * tile_per_uv, dty = duvy * tile_per_uv;
    float det = dtx.x * dty.y - dtx.y * dty.x;
    vec3 t_w, b_w;
    if (abs(det) > 1e-30) {
        t_w = (dpx * dty.y - dpy * dtx.y) / det;
        b_w = (dpy * dtx.x - dpx * dty.x) / det;
    } else {
        // No UV variation across the quad: the vertex tangent frame, unit scale.
        t_w = normalize(tangent.xyz);
        b_w = tangent.w * cross(n, t_w);
    }
    float k = sqrt(length(t_w) * length(b_w));
    mat3 to_world = mat3(t_w, b_w, k * n);
    mat3 to_tile = inverse(to_world);
    g_env_to_world = to_world;
    vec3 d_world = cam.origin.w != 0.0 ? normalize(p - cam.origin.xyz) : cam.forward.xyz;
    vec3 d = to_tile * d_world;
    float len = length(d);
    if (!(len > 0.0) || !(d.z < 0.0) || isinf(k) || !(k > 0.0)) {
        imageStore(out_image, at, vec4(params.background.rgb, 1.0));
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
    // A pixel whose loops the driver cut short leaves alpha 0, which the readback counts
    // (RenderStats::loop_cut_pixels).
    imageStore(out_image, at, vec4(finite ? t.radiance : vec3(0.0), loop_budget_spent() ? 0.0 : 1.0));
}
