// shading.glsl — shading a hit: a texel's lobes (or a flyaway's, in its fiber frame)
// under each light, with optional height-field shadowing (DESIGN.md §7).
//
// Twin: runtime/src/cpu/shading.rs (texel_response, volume_factor, in_fiber_frame,
// shade, shade_blend) and Scene::visibility (runtime/src/cpu/render.rs); with HYBRID_ENV
// defined, both add the environment (env_shading.glsl; Scene::env_response). Two
// differences of form, not of value: texels are evaluated from their records
// (TexelRef, model.glsl) rather than decoded first, and shade_blend gathers its texels
// itself (level 0's nearest texel, or the anisotropic taps of bilinear lookups that the
// CPU's shade_surface lists), in the CPU's order. Each BRDF evaluation and shadow ray
// has one call site per kind of hit: the driver inlines every call, and its compile
// time grows with them.
#ifndef SHADING_GLSL
#define SHADING_GLSL

#include "common/heightfield.glsl"
#include "common/render_params.glsl"
#include "common/lights.glsl"
#include "common/axis_spread.glsl"

const float VOLUME_MU_MIN = 0.1;

float max3(vec3 v) {
    return max(max(v.x, v.y), v.z);
}

// The edit at a hit (twin: Edits::at, runtime/src/cpu/edits.rs): the identity blended
// toward the frame's edit by the mask's value at the hit's place in the tile.
struct Edit {
    vec3 tint;
    float roughness_scale;
    float tangent_rotation;
};

Edit hit_edit(vec3 p) {
    float m = 1.0;
    uvec2 md = params.mask_dims;
    if (md.x > 0u && md.y > 0u) {
        vec2 u = (p.xy - model.origin) / model.size;
        u -= floor(u);
        uint i = min(uint(u.x * float(md.x)), md.x - 1u);
        uint row_from_bottom = min(uint(u.y * float(md.y)), md.y - 1u);
        m = edit_mask[(md.y - 1u - row_from_bottom) * md.x + i];
    }
    return Edit(vec3(1.0) + m * (params.edit_tint.rgb - vec3(1.0)), 1.0 + m * (params.edit_roughness - 1.0), m * params.edit_rotation);
}

// A texel's record, edited by `e` (Edit::apply): k_d, eta, a, its lobes' place, lobe
// 0's normal (which carries k_d), and the tangent rotation where `rotate`.
struct EditedTexel {
    vec3 kd;
    float eta;
    float a;
    uint count;
    uint first;
    vec3 n0;
    bool rotate;
    float rs;
    float rc;
};

EditedTexel edited_texel(TexelRef r, Edit e, bool rotate) {
    uvec4 h = brdf_headers[r.header];
    EditedTexel t;
    t.kd = min(max(vec3(f16_value(h.x), f16_value(h.x >> 16), f16_value(h.y)) * e.tint, vec3(0.0)), vec3(CLOTH_K_MAX));
    t.rs = sin(e.tangent_rotation);
    t.rc = cos(e.tangent_rotation);
    t.rotate = rotate && e.tangent_rotation != 0.0;
    t.eta = f16_value(h.y >> 16);
    t.a = f16_value(h.z);
    t.count = min((h.z >> 16) & 0xffu, min(LOBE_BOUND, uint(CLOTH_MAX_LOBES)));
    t.first = r.lobe_base + h.w;
    // Lobe 0's frame carries k_d (per-texel tables have at least one lobe).
    t.n0 = r.framed ? tilted_frame(r, ClothFrame(octahedral_decode(brdf_lobes[t.first].x), vec3(0.0), vec3(0.0))).n : r.frame.n;
    return t;
}

// Lobe j of an edited texel and its frame (tangent rotated, widths scaled, tinted).
ClothLobe edited_lobe(TexelRef r, Edit e, EditedTexel t, uint j, out ClothFrame f) {
    uvec4 l = brdf_lobes[t.first + j];
    f = r.framed ? tilted_frame(r, decode_frame(l.x, l.y & 0xffffu)) : r.frame;
    if (t.rotate) {
        vec3 tt = f.t * t.rc + f.b * t.rs;
        f.t = tt;
        f.b = cross(f.n, tt);
    }
    ClothLobe lobe = packed_lobe(l);
    lobe.k *= e.tint;
    lobe.beta *= e.roughness_scale;
    lobe.gamma *= e.roughness_scale;
    return lobe;
}

// Reflected radiance toward wo per unit irradiance from wi, the texel edited by `e`
// (its tangents rotated where `rotate`; Edit::apply):
// k_d D(n_0, wi, wo) + sum_j cloth_lobe_j max(n_j.wi, 0), D by the diffuse law
// (model_diffuse() at surface hits, CLOTH_DIFFUSE_LAMBERT at flyaways), the lobes by the
// cylinder law where r.cylinder.
vec3 texel_response(TexelRef r, Edit e, bool rotate, vec3 wi, vec3 wo, uint reading, uint diffuse) {
    EditedTexel t = edited_texel(r, e, rotate);
    vec3 resp = t.kd * cloth_diffuse_cosine(diffuse, t.n0, wi, wo);
    for (uint j = 0u; j < t.count; ++j) {
        ClothFrame f;
        ClothLobe lobe = edited_lobe(r, e, t, j, f);
        if (r.cylinder) {
            resp += cloth_cylinder_lobe(lobe, t.eta, t.a, f, wi, wo, reading);
            continue;
        }
        float cos_i = dot(f.n, wi);
        if (cos_i > 0.0) {
            resp += cloth_lobe(lobe, t.eta, t.a, f, wi, wo, reading) * cos_i;
        }
    }
    vec3 q0;
    vec3 q1;
    texel_curvature(r, q0, q1);
    return resp * cloth_visibility(texel_gradient(r), q0, q1, wi, wo);
}

// The texel's transmission term and lobe 0's frame, edited as its lobes are
// (Edit::apply); false where the texel has none.
bool edited_transmission(TexelRef r, Edit e, bool rotate, out ClothTransmission t, out ClothFrame f) {
    f = r.frame;
    if (r.trans == NO_NODE) {
        return false;
    }
    t = packed_transmission(r.trans);
    t.kd *= e.tint;
    t.lobe.k *= e.tint;
    t.lobe.beta *= e.roughness_scale;
    t.lobe.gamma *= e.roughness_scale;
    if (r.framed) {
        uvec4 h = brdf_headers[r.header];
        uvec4 l = brdf_lobes[r.lobe_base + h.w];
        f = tilted_frame(r, decode_frame(l.x, l.y & 0xffffu));
    }
    if (rotate && e.tangent_rotation != 0.0) {
        vec3 tt = f.t * cos(e.tangent_rotation) + f.b * sin(e.tangent_rotation);
        f.t = tt;
        f.b = cross(f.n, tt);
    }
    return true;
}

// Transmitted radiance toward wo per unit irradiance from wi on the other side of the
// tile plane: the texel's transmission term in lobe 0's frame (edited_transmission).
// Twin: texel_transmission_response (runtime/src/cpu/shading.rs).
vec3 texel_transmission_response(TexelRef r, Edit e, bool rotate, vec3 wi, vec3 wo) {
    ClothTransmission t;
    ClothFrame f;
    if (!edited_transmission(r, e, rotate, t, f)) {
        return vec3(0.0);
    }
    return cloth_transmission_response(t, f, wi, wo);
}

// 2 / (mu_i + mu_o): the volumetric factor of a model baked with it.
float volume_factor(vec3 wi, vec3 wo) {
    return 2.0 / max(max(wi.z, 0.0) + max(wo.z, 0.0), VOLUME_MU_MIN);
}

#ifdef HYBRID_ENV
#include "common/env_shading.glsl"
#endif

// A flyaway's BRDF (entry `param` of its level's table) in the fiber frame of axis
// `fiber` seen from wo.
TexelRef in_fiber_frame(uint level, uint param, vec3 fiber, vec3 wo) {
    GpuLevel l = model.levels[level];
    return TexelRef(l.fly_header_base + param, l.fly_lobe_base, false, cloth_fiber_frame(fiber, wo), NO_NODE, false, vec3(0.0, 0.0, 1.0), vec3(0.0, 0.0, 1.0), model_fiber_cylinder(), NO_NODE, NO_NODE);
}

// Visibility of a light from p (height-field shadow ray); counts step-limited rays.
float visibility(vec3 p, vec3 wi, float dist, inout uint limited) {
    if (!SHADOWS) {
        return 1.0;
    }
    bool hit_limit;
    bool blocked = hf_occluded(p, wi, dist, params.max_steps, hit_limit);
    limited += hit_limit ? 1u : 0u;
    return blocked ? 0.0 : 1.0;
}

// What the flyaways in front of a surface hit let through toward a light, and of the
// environment (format 1.13): defined with the flyaways' march in trace.glsl.
float flyaway_shadow_mixed(uint lo, uint hi, float w, vec3 p, vec3 wi, float dist, inout uint limited);
float flyaway_sky_mixed(uint lo, uint hi, float w, vec3 p);

// The light factor of a hit: shadow ray where `shadowed`, the volumetric factor where
// `volumetric`.
float light_factor(vec3 p, vec3 wi, float dist, vec3 wo, bool shadowed, bool volumetric, inout uint limited) {
    float v = shadowed ? visibility(p, wi, dist, limited) : 1.0;
    return volumetric ? v * volume_factor(wi, wo) : v;
}

// The light factor of a surface hit: light_factor's, the flyaways' shadow at the pixel's
// shadow levels fly.x, fly.y (weight fly_w of y; flyaway_shadow_mixed) after the height
// field's where that lets the light through. Twin: the `visible` closure of
// Scene::shade_surface.
float surface_light_factor(uvec2 fly, float fly_w, vec3 p, vec3 wi, float dist, vec3 wo, bool shadowed, bool volumetric, inout uint limited) {
    float v = shadowed ? visibility(p, wi, dist, limited) : 1.0;
    if (v > 0.0) {
        v *= flyaway_shadow_mixed(fly.x, fly.y, fly_w, p, wi, dist, limited);
    }
    return volumetric ? v * volume_factor(wi, wo) : v;
}

// Light k at p: its irradiance, the direction toward it and its distance.
vec3 light_at(uint k, vec3 p, out vec3 wi, out float dist) {
    return light_incident(g_lights[k].vec, g_lights[k].power.xyz, p, wi, dist);
}

// The light a flyaway march shades its nodes with (bits: the lights, with an
// environment's extracted sources; the environment's SG part). The split-shaded filter
// shades the lights along its finer grid and the SG part along the box grid. Twin:
// FlyLight (runtime/src/cpu/render.rs).
const uint FLY_LIGHT_NONE = 0u;
const uint FLY_LIGHT_LIGHTS = 1u;
const uint FLY_LIGHT_ENV = 2u;
const uint FLY_LIGHT_ALL = 3u;

// Radiance leaving p toward wo from flyaway node (param, fiber) of `level`: its one axis
// where `spread` is NO_NODE, else the mean over the node's spread axes, one or two groups
// (axis_spread.glsl; `spread` the first word of its three in binding 6; unused axes
// weigh 0), each light's visibility once; edited without rotation, lit by the
// environment with the flyaway budget; `light` (FLY_LIGHT_*) says which of the two.
// Twin: the node closure of Scene::march_level_flyaways (shade, or shade_blend over the
// axes).
vec3 shade_fiber(uint level, uint param, vec3 fiber, uint spread, vec3 p, vec3 wo, uint light, inout uint limited) {
    SpreadAxes s = single_axis(fiber);
    if (spread != NO_NODE) {
        s = packed_grouped_axes(fiber, fly_spread_word(spread), fly_spread_word(spread + 2u));
    }
    uint reading = model_reading();
    Edit e = hit_edit(p);
    vec3 radiance = vec3(0.0);
    for (uint k = 0u; k < ((light & FLY_LIGHT_LIGHTS) != 0u ? LIGHT_COUNT : 0u); ++k) {
        vec3 wi;
        float dist;
        vec3 irradiance = light_at(k, p, wi, dist);
        if (max3(irradiance) <= 0.0) {
            continue;
        }
        // A light behind the sheet: flyaways pass nothing.
        if (wi.z < 0.0) {
            continue;
        }
        vec3 response = vec3(0.0);
        for (int a = 0; a < MAX_SPREAD_AXES; ++a) {
            if (s.weights[a] > 0.0) {
                response += s.weights[a] * texel_response(in_fiber_frame(level, param, s.axes[a], wo), e, false, wi, wo, reading, CLOTH_DIFFUSE_LAMBERT);
            }
        }
        if (max3(response) <= 0.0) {
            continue;
        }
        radiance += irradiance * response * light_factor(p, wi, dist, wo, true, false, limited);
    }
#ifdef HYBRID_ENV
    if (HAS_ENV && (light & FLY_LIGHT_ENV) != 0u) {
        for (int a = 0; a < MAX_SPREAD_AXES; ++a) {
            if (s.weights[a] > 0.0) {
                radiance += s.weights[a] * texel_env_response(in_fiber_frame(level, param, s.axes[a], wo), e, false, wo, reading, false, CLOTH_DIFFUSE_LAMBERT, ENV_FLYAWAY_NODES, ENV_FLYAWAY_LOOKUPS);
            }
        }
    }
#endif
    return radiance;
}

// Where lookup (or ray) `tap` of a grid lies: `taps` evenly over the span `axis` (world
// x-y) by `taps_minor` over `minor_axis`, centred on the hit; the surface's grid and the
// flyaways' rays share it. Twin: tap_offset (runtime/src/cpu/render.rs).
vec2 tap_offset(vec2 axis, uint taps, vec2 minor_axis, uint taps_minor, uint tap) {
    uint ka = tap % taps;
    uint kb = tap / taps;
    return axis * ((float(ka) + 0.5) / float(taps) - 0.5) + minor_axis * ((float(kb) + 0.5) / float(taps_minor) - 0.5);
}

// The ray of a flyaway grid (taps x taps_minor over axis, minor_axis, as tap_offset
// places them) whose cell holds the point at `offset` from the grid's centre: its
// coordinates along the two axes, clamped to the grid. Twin: fly_cell
// (runtime/src/cpu/render.rs).
uint fly_cell(vec2 offset, vec2 axis, uint taps, vec2 minor_axis, uint taps_minor) {
    float det = axis.x * minor_axis.y - axis.y * minor_axis.x;
    float s;
    float r;
    // Nearly parallel axes (|sin| under 1e-3) are taken as parallel.
    if (abs(det) > 1e-3 * length(axis) * length(minor_axis) && abs(det) > 0.0) {
        s = (offset.x * minor_axis.y - offset.y * minor_axis.x) / det;
        r = (axis.x * offset.y - axis.y * offset.x) / det;
    } else {
        // Parallel or empty axes: along the longer one alone.
        bool major = dot(axis, axis) >= dot(minor_axis, minor_axis);
        vec2 a = major ? axis : minor_axis;
        float u = dot(a, a) > 0.0 ? dot(offset, a) / dot(a, a) : 0.0;
        s = major ? u : 0.0;
        r = major ? 0.0 : u;
    }
    // A point on a cell border goes to the cell after it, whatever the rounding; the
    // cell clamped as a float (a float beyond uint's range converts to anything).
    float fs = floor((s + 0.5) * float(taps) + 1e-3);
    float fr = floor((r + 0.5) * float(taps_minor) + 1e-3);
    uint cs = uint(isnan(fs) ? 0.0 : clamp(fs, 0.0, float(max(taps, 1u) - 1u)));
    uint cr = uint(isnan(fr) ? 0.0 : clamp(fr, 0.0, float(max(taps_minor, 1u) - 1u)));
    return cs + taps * cr;
}

// Most lookups of a surface grid: level 0's LEVEL0_TAPS_MAX (32), more than a coarse box
// grid's MAX_ANISOTROPY along the major axis by G = 3 (FILTER_GRID). Twin:
// MAX_SURFACE_TAPS in runtime/src/cpu/level.rs.
const uint MAX_SURFACE_TAPS = 32u;

// Texel k of a surface hit at p on `level`: level 0's nearest texel (k = 0; with a
// grid, n > 1, distinct texel k of the grid's lookups, weight tap_w[k]), or at
// coarse levels corner k % 4 of the bilinear lookup at tap_xy[k / 4] (where that tap's
// own ray meets the height field; p itself for one lookup), its frames turned by the
// level's view tilt. Returns its weight.
float surface_texel(uint level, vec3 p, vec3 wo, vec2 tap_xy[MAX_SURFACE_TAPS], float tap_w[MAX_SURFACE_TAPS], float tap_t[MAX_SURFACE_TAPS], uint n, uint k, out TexelRef r) {
    if (level == 0u) {
        // Level 0's grid (distinct texel k, at a lookup in it, with its lookups' summed
        // weight: level0_distinct) or the hit's texel.
        uvec2 ij0 = texel_at(n <= 1u ? p : vec3(tap_xy[k], p.z), 0u);
        r = texel_brdf(0u, ij0.x, ij0.y);
        return n <= 1u ? 1.0 : tap_w[k];
    }
    vec3 q = n <= 1u ? p : vec3(tap_xy[k >> 2], p.z);
    uvec2 ij;
    float w = bilinear_texel(q, level, int(k & 3u), ij);
    r = texel_brdf(level, ij.x, ij.y);
    // The tilt's visibility v is not used: each tap's own ray already sees the footprint
    // as a distant view does (Scene::shade_surface).
    seen_from(r, level, ij, wo);
    return n <= 1u ? w : w * tap_t[k >> 2] / float(n);
}

// Level 0's grid of n lookups, each distinct texel once: its first lookup's place moved
// to tap_xy[k] and the sum of its lookups' weights 1/n, in order, in tap_w[k], k in order
// of first appearance; returns how many (distinct_corners). At half a texel per pixel the
// 4-8 lookups of a grid fall in one to four texels: a list rather than a skipped lookup,
// so that a SIMD group loops over the most texels one of its lanes has, not over every
// lookup. The coarse grids' corners are shaded one by one (distinct texels there are 9
// of 16, and finding them made frames slower on lavapipe).
uint level0_distinct(vec3 p, uint n, inout vec2 tap_xy[MAX_SURFACE_TAPS], float tap_t[MAX_SURFACE_TAPS], out float tap_w[MAX_SURFACE_TAPS]) {
    uvec2 seen[MAX_SURFACE_TAPS];
    float share = 1.0 / float(n);
    uint m = 0u;
    for (uint c = 0u; c < n; ++c) {
        uvec2 ij = texel_at(vec3(tap_xy[c], p.z), 0u);
        uint k = 0u;
        while (k < m && any(notEqual(seen[k], ij))) {
            ++k;
        }
        if (k == m) {
            seen[m] = ij;
            tap_xy[m] = tap_xy[c];
            tap_w[m] = share * tap_t[c];
            ++m;
        } else {
            tap_w[k] += share * tap_t[c];
        }
    }
    return m;
}

// Radiance of a surface hit at p on `level` (filtered as surface_texel says), each
// light's visibility once.
vec3 shade_blend(uint level, vec3 p, vec3 wo, vec2 tap_xy[MAX_SURFACE_TAPS], float tap_t[MAX_SURFACE_TAPS], uint n, bool shadowed, bool volumetric, uvec2 fly, float fly_w, inout uint limited) {
    uint reading = model_reading();
    uint diffuse = model_diffuse();
    Edit e = hit_edit(p);
    uint count = level == 0u ? max(n, 1u) : 4u * n;
    float tap_w[MAX_SURFACE_TAPS];
    if (level == 0u && n > 1u) {
        count = level0_distinct(p, n, tap_xy, tap_t, tap_w);
    }
    vec3 radiance = vec3(0.0);
    for (uint k = 0u; k < LIGHT_COUNT; ++k) {
        vec3 wi;
        float dist;
        vec3 irradiance = light_at(k, p, wi, dist);
        if (max3(irradiance) <= 0.0) {
            continue;
        }
        // A light behind the sheet: the transmission term, no shadow ray, no volumetric
        // factor (shading.rs); compiled out where no light is behind (TRANSMISSION).
        if (wi.z < 0.0) {
            if (TRANSMISSION) {
                vec3 through = vec3(0.0);
                for (uint c = 0u; c < count; ++c) {
                    TexelRef r;
                    float w = surface_texel(level, p, wo, tap_xy, tap_w, tap_t, n, c, r);
                    through += w * texel_transmission_response(r, e, true, wi, wo);
                }
                radiance += irradiance * through;
            }
            continue;
        }
        vec3 response = vec3(0.0);
        for (uint c = 0u; c < count; ++c) {
            TexelRef r;
            float w = surface_texel(level, p, wo, tap_xy, tap_w, tap_t, n, c, r);
            response += w * texel_response(r, e, true, wi, wo, reading, diffuse);
        }
        if (max3(response) <= 0.0) {
            continue;
        }
        radiance += irradiance * response * surface_light_factor(fly, fly_w, p, wi, dist, wo, shadowed, volumetric, limited);
    }
#ifdef HYBRID_ENV
    if (HAS_ENV) {
        // What the flyaways let through of the map (format 1.13; Scene::shade_surface).
        float sky = flyaway_sky_mixed(fly.x, fly.y, fly_w, p);
        for (uint c = 0u; c < count; ++c) {
            TexelRef r;
            float w = surface_texel(level, p, wo, tap_xy, tap_w, tap_t, n, c, r);
            radiance += w * (sky * texel_env_response(r, e, true, wo, reading, volumetric, diffuse, ENV_NODES, ENV_LOOKUPS));
            // The map below the sheet through the cloth (Scene::env_through): TRANSMISSION
            // is on only where the map has light below (PrefilteredEnv::lights_below).
            if (TRANSMISSION && params.env_info.z != 0u) {
                radiance += w * texel_env_transmission(r, e, true, wo, ENV_NODES, ENV_LOOKUPS);
            }
        }
    }
#endif
    return radiance;
}

#endif // SHADING_GLSL
