// trace.glsl — one ray through the hybrid model in tile space: it enters the tile's top
// plane, the height field is marched to the first surface hit, the levels come from the
// footprint at that hit (choose_levels, which the program defines), the flyaways in
// front are composited over the surface shaded with its texels' lobes (DESIGN.md §7).
//
// Twin: runtime/src/cpu/render.rs (Scene::enter_top, trace_mixed, march_level_flyaways,
// shade_surface), function for function. Programs: hybrid.comp (a camera over the tile:
// the footprint from the neighbouring pixels' rays, as the CPU) and hybrid_mesh.comp (the
// tile mapped onto a mesh's UVs: the footprint from screen-space derivatives).
#ifndef TRACE_GLSL
#define TRACE_GLSL

#include "common/level.glsl"
#include "common/flyaways.glsl"

// The levels for a ray meeting the surface at height z (tile space): defined by the program.
LevelMix choose_levels(float z);

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

// The flyaways of `level` over [t_top, t_end]; of a coarser level where the path crosses
// more than GRAZING_COLUMNS of its columns (grazing_level).
FlyawayMarch march_level_flyaways(vec3 o, vec3 d, float t_top, float t_end, uint level_in, uint light, inout uint shadow_limited) {
    float columns = (abs(d.x) * model.inv_texel.x + abs(d.y) * model.inv_texel.y) * (t_end - t_top);
    uint level = grazing_level(level_in, columns, model.level_count - 1u);
    if (!HAS_FLYAWAYS || model.levels[level].fly_nodes == 0u) {
        return FlyawayMarch(vec3(0.0), 1.0, 0u, false);
    }
    return march_flyaways(level, o, d, t_top, t_end, params.max_flyaway_columns, light, shadow_limited);
}

// What the flyaways of `level` let through from surface point p toward a light in
// direction wi at `dist`: the path to the top plane (or to the light, if nearer), marched
// down from its upper end, unshaded; 1 unless the model's flyaways shadow the surface
// (GPU_FLAG_FLYAWAY_SHADOW), or for a light below the sheet; with or without the height
// field's shadow rays (SHADOWS). Counts a march that ran out of columns in `limited`.
// Twin: Scene::flyaway_shadow (runtime/src/cpu/render.rs).
float flyaway_shadow(uint level, vec3 p, vec3 wi, float dist, inout uint limited) {
    if (!HAS_FLYAWAYS || (model.flags & GPU_FLAG_FLYAWAY_SHADOW) == 0u || !(wi.z > 0.0)) {
        return 1.0;
    }
    float s = min((model.top_z - p.z) / wi.z, dist);
    if (!(s > 0.0) || isinf(s)) {
        return 1.0;
    }
    precise vec3 o = p + wi * s;
    uint unused = 0u;
    FlyawayMarch m = march_level_flyaways(o, -wi, 0.0, s, level, FLY_LIGHT_NONE, unused);
    limited += m.limited ? 1u : 0u;
    return m.transmittance;
}

// What the flyaways of `level` let through of the environment at surface point p: their
// transmittance straight up, one column (1 where flyaway_shadow is). Twin:
// Scene::flyaway_sky.
float flyaway_sky(uint level, vec3 p) {
    float s = model.top_z - p.z;
    if (!HAS_FLYAWAYS || (model.flags & GPU_FLAG_FLYAWAY_SHADOW) == 0u || !(s > 0.0) || isinf(s) || model.levels[level].fly_nodes == 0u) {
        return 1.0;
    }
    uint unused = 0u;
    return march_flyaways(level, vec3(p.xy, model.top_z), vec3(0.0, 0.0, -1.0), 0.0, s, params.max_flyaway_columns, FLY_LIGHT_NONE, unused).transmittance;
}

// flyaway_shadow blended over the flyaway levels lo, hi (weight w of hi) of a pixel's
// footprint, as its view ray's flyaways are; the two levels a loop, not two calls (one
// inlined march). Twin: Scene::flyaway_shadow_mixed.
float flyaway_shadow_mixed(uint lo, uint hi, float w, vec3 p, vec3 wi, float dist, inout uint limited) {
    float t = 1.0;
    for (uint k = 0u; k < ((w > 0.0 && hi != lo) ? 2u : 1u); ++k) {
        float tk = flyaway_shadow(k == 0u ? lo : hi, p, wi, dist, limited);
        t = k == 0u ? tk : t * (1.0 - w) + tk * w;
    }
    return t;
}

// flyaway_sky blended over the flyaway levels lo, hi (weight w of hi). Twin:
// Scene::flyaway_sky_mixed.
float flyaway_sky_mixed(uint lo, uint hi, float w, vec3 p) {
    float t = 1.0;
    for (uint k = 0u; k < ((w > 0.0 && hi != lo) ? 2u : 1u); ++k) {
        float tk = flyaway_sky(k == 0u ? lo : hi, p);
        t = k == 0u ? tk : t * (1.0 - w) + tk * w;
    }
    return t;
}

// The surface hit at t shaded with `level`, filtered as `mix` says at coarse levels.
// Where the lookup at `offset` (world x-y) of a box grid reads the surface: where a ray
// parallel to the pixel's, started `offset` beside it, meets the height field; the point
// `offset` beside the pixel's hit p where it misses or runs out of steps (and without
// relief). Twin: Scene::tap_surface_point.
vec2 tap_surface_point(vec3 o, vec3 d, vec2 offset, vec3 p, int floor_level) {
    vec2 beside = p.xy + offset;
    vec3 ro = o + vec3(offset, 0.0);
    float t_top;
    if (!RELIEF || !enter_top(ro, d, t_top)) {
        return beside;
    }
    uint steps = 0u;
    HfTrace hit = hf_trace(ro, d, t_top, HF_F32_MAX, 0.0, params.max_steps, steps, floor_level);
    return hit.kind == HF_HIT ? (ro + d * hit.t).xy : beside;
}

// At level 0, tap_xy holds level 0's grid (mix_.fine_taps_*; one lookup: the hit's texel);
// tap_t scales each lookup's weight (what the flyaways let through in front of it).
vec3 shade_surface(vec3 o, vec3 d, float t, uint level, LevelMix mix_, vec2 tap_xy[MAX_SURFACE_TAPS], float tap_t[MAX_SURFACE_TAPS], inout uint shadow_limited) {
    vec3 p = o + t * d;
    bool volumetric = (model.flags & GPU_FLAG_VOLUMETRIC) != 0u;
    bool shadowed = level == 0u || (model.flags & GPU_FLAG_COARSE_VISIBILITY) == 0u;
    uint n = level == 0u ? min(mix_.fine_taps_a * mix_.fine_taps_b, MAX_SURFACE_TAPS) : min(mix_.taps * mix_.taps_minor, MAX_SURFACE_TAPS);
    return shade_blend(level, p, -d, tap_xy, tap_t, n, shadowed, volumetric, uvec2(mix_.shadow_lo, mix_.shadow_hi), mix_.shadow_weight, shadow_limited);
}

// Most rays of a flyaway grid: FLY_MAX_ANISOTROPY x FLY_FINE_GRID along the major axis by
// FLY_FINE_GRID across.
const uint MAX_FLY_RAYS = 32u;
// Most rays of the split filter's shading grid (FLY_GRID = 2: FLY_MAX_ANISOTROPY x 2 by 2).
const uint MAX_SPLIT_RAYS = 8u;

// What the flyaways let through in front of each of the n lookups of a surface grid (at
// tap_offset(axis, taps, minor_axis, taps_minor, k) from the hit): the transmittance of
// the flyaway ray (of fga x fgb over fly_a, fly_b) whose cell holds it (fly_cell), scaled so that their mean is the
// pixel's mean_t; mean_t for all where no lookup sees through. Twin:
// lookup_transmittances (runtime/src/cpu/render.rs).
void lookup_transmittances(vec2 axis, uint taps, vec2 minor_axis, uint taps_minor, uint n, float fly_t[MAX_FLY_RAYS], vec2 fly_a, uint fga, vec2 fly_b, uint fgb, float mean_t, out float tap_t[MAX_SURFACE_TAPS]) {
    float sum = 0.0;
    for (uint k = 0u; k < MAX_SURFACE_TAPS; ++k) {
        tap_t[k] = 1.0;
        if (k < n) {
            uint c = fly_cell(tap_offset(axis, taps, minor_axis, taps_minor, k), fly_a, fga, fly_b, fgb);
            tap_t[k] = c < MAX_FLY_RAYS ? fly_t[c] : mean_t;
            sum += tap_t[k];
        }
    }
    float mean = sum / float(max(n, 1u));
    for (uint k = 0u; k < n; ++k) {
        tap_t[k] = mean > 0.0 ? tap_t[k] * mean_t / mean : mean_t;
    }
}

// One ray, shaded with the levels choose_levels gives where it meets the surface (the
// top plane if it misses). The two levels of a blend are loops, not two
// calls: one inlined copy of each march and of the shading.
// Radiance where a ray along d misses the tile (twin: Scene::trace_mixed's background).
// The split filter's flyaway radiance: each of the `n` shading rays' colour (radiance
// `rgb[k]` per unit of its opacity 1 - `t[k]`) times the mean opacity of the coverage rays
// in its cell (`cell_o[k]` summed over `cell_n[k]` rays; the ray's own where none fell
// in it), averaged over the cells; the pixel's mean colour where a shading ray met
// nothing its cell's coverage rays met. Twin: spread_colours (runtime/src/cpu/render.rs).
vec3 spread_colours(uint n, vec3 rgb[MAX_SPLIT_RAYS], float t[MAX_SPLIT_RAYS], float cell_o[MAX_SPLIT_RAYS], uint cell_n[MAX_SPLIT_RAYS]) {
    float opacity = 0.0;
    vec3 sum = vec3(0.0);
    for (uint k = 0u; k < n; ++k) {
        sum += rgb[k];
        opacity += 1.0 - t[k];
    }
    vec3 mean_colour = opacity > 1e-4 ? sum / opacity : vec3(0.0);
    float share = 1.0 / float(max(n, 1u));
    vec3 radiance = vec3(0.0);
    for (uint k = 0u; k < n; ++k) {
        float o = 1.0 - t[k];
        float o_cover = cell_n[k] > 0u ? cell_o[k] / float(cell_n[k]) : o;
        vec3 colour = o > 1e-4 ? rgb[k] / o : mean_colour;
        radiance += colour * o_cover * share;
    }
    return radiance;
}

vec3 background(vec3 d) {
#ifdef HYBRID_ENV
    if (HAS_ENV && params.env_info.y != 0u) {
        return env_blurred(d, 0.0);
    }
#endif
    return params.background.rgb;
}

// Where a flyaway ray of a box grid, parallel to the pixel's ray (which meets the
// surface at t_end), meets the surface itself; the bottom of the flyaway layer where it
// misses, the pixel's t_end where its step budget runs out. Steps count as the
// pixel's; `landed` where it met the surface. Twin: Scene::own_surface_end.
float own_surface_end(vec3 o, vec3 d, float t_top, float t_end, int floor_level, inout PixelTrace out_, out bool landed) {
    landed = false;
    if (!RELIEF) {
        return t_end;
    }
    uint steps = 0u;
    HfTrace hit = hf_trace(o, d, t_top, HF_F32_MAX, 0.0, params.max_steps, steps, floor_level);
    out_.steps += steps;
    if (hit.kind == HF_HIT) {
        landed = true;
        return hit.t;
    }
    if (hit.kind == HF_STEP_LIMIT) {
        out_.step_limited = true;
        return t_end;
    }
    return t_top + model.height_scale / -d.z;
}

PixelTrace trace_mixed(vec3 o, vec3 d) {
    PixelTrace out_ = PixelTrace(background(d), -1, false, 0.0, false, 0u, 0u);
    float t_top;
    if (!enter_top(o, d, t_top)) {
        return out_;
    }
    uint steps = 0u;
    // With coarse relief, the march stops descending at the level of the footprint on
    // the top plane.
    int floor_level = params.coarse_relief != 0u ? int(choose_levels(model.top_z).lo) : 0;
    HfTrace hit = RELIEF ? hf_trace(o, d, t_top, HF_F32_MAX, 0.0, params.max_steps, steps, floor_level) : HfTrace(HF_HIT, t_top);
    out_.step_limited = hit.kind == HF_STEP_LIMIT;
    out_.steps = steps;
    out_.surface = hit.kind == HF_HIT;
    float z = out_.surface ? (o + d * hit.t).z : model.top_z;
    LevelMix mix_ = choose_levels(z);
    out_.level = int(mix_.lo);
    float t_end = out_.surface ? hit.t : t_top + model.height_scale / -d.z;
    uint shadow_limited = 0u;
    // The flyaways in front: over a box grid (fly_taps_a x fly_taps_b parallel rays over
    // the fly axes, each stopping where it meets the surface itself; one ray without),
    // each ray blended over its levels. One march call site.
    vec3 fly_radiance = vec3(0.0);
    float fly_transmittance = 0.0;
    bool fly_blend = mix_.fly_weight > 0.0 && mix_.fly_hi != mix_.fly_lo;
    uint fly_levels = fly_blend ? 2u : 1u;
    uint fga = max(mix_.fly_taps_a, 1u);
    uint fgb = max(mix_.fly_taps_b, 1u);
    float share = 1.0 / float(fga * fgb);
    vec3 ray_radiance = vec3(0.0);
    float ray_transmittance = 0.0;
    float ray_end = t_end;
    // Each grid ray's transmittance, in grid order (Scene::trace_mixed's fly_rays).
    float fly_t[MAX_FLY_RAYS];
    // ... where each met the surface (bit k of fly_landed: ray k did).
    vec2 fly_xy[MAX_FLY_RAYS];
    uint fly_landed = 0u;
    for (uint k = 0u; k < MAX_FLY_RAYS; ++k) {
        fly_t[k] = 1.0;
        fly_xy[k] = vec2(0.0);
    }
    // The split filter: after the box grid's shaded rays, the cover grid's unshaded
    // ones give the coverage (Scene::trace_mixed's `Split`): each box ray's colour is
    // spread over the opacity of the cover rays in its cell. Split-shaded
    // (FLY_COVER_SHADED): the cover rays are shaded with the lights; the box rays bring
    // an environment's SG part alone, spread so, and land (their hits are level 0's
    // lookups).
    uint cga = mix_.cover_taps_a;
    uint cgb = mix_.cover_taps_b;
    bool split = FLY_COVER_GRID != FLY_GRID && HAS_FLYAWAYS && cga * cgb > 0u && fga * fgb > 1u && fga * fgb <= MAX_SPLIT_RAYS;
    uint box_rays = fga * fgb;
    uint all_rays = box_rays + (split ? cga * cgb : 0u);
    uint cover_levels = split && mix_.cover_weight > 0.0 && mix_.cover_hi != mix_.cover_lo ? 2u : 1u;
    // The grid whose rays' transmittances the surface's lookups are seen through.
    vec2 t_axis_a = mix_.fly_axis_a;
    vec2 t_axis_b = mix_.fly_axis_b;
    uint tga = fga;
    uint tgb = fgb;
    vec3 box_rgb[MAX_SPLIT_RAYS];
    float box_t[MAX_SPLIT_RAYS];
    float cell_o[MAX_SPLIT_RAYS];
    uint cell_n[MAX_SPLIT_RAYS];
    for (uint k = 0u; k < MAX_SPLIT_RAYS; ++k) {
        box_rgb[k] = vec3(0.0);
        box_t[k] = 1.0;
        cell_o[k] = 0.0;
        cell_n[k] = 0u;
    }
    // Each ray's levels in turn (a coverage ray may blend where a shading ray does not).
    uint max_levels = max(fly_levels, cover_levels);
    for (uint k = 0u; k < all_rays * max_levels; ++k) {
        uint ray = k / max_levels;
        uint lk = k % max_levels;
        bool cover = ray >= box_rays;
        uint levels = cover ? cover_levels : fly_levels;
        if (lk >= levels) {
            continue;
        }
        uint index = cover ? ray - box_rays : ray;
        vec2 offset = cover ? tap_offset(mix_.cover_axis_a, cga, mix_.cover_axis_b, cgb, index) : tap_offset(mix_.fly_axis_a, fga, mix_.fly_axis_b, fgb, index);
        vec3 ro = o;
        if (cover || fga * fgb > 1u) {
            ro = o + vec3(offset, 0.0);
            if (lk == 0u) {
                bool landed;
                ray_end = own_surface_end(ro, d, t_top, t_end, floor_level, out_, landed);
                // Level 0's lookups borrow the shading grid's hits (with the split filter
                // too: the surface is the box filter's).
                if (landed && !cover && index < MAX_FLY_RAYS) {
                    fly_xy[index] = (ro + d * ray_end).xy;
                    fly_landed |= 1u << index;
                }
            }
        }
        // Split-shaded: the box rays bring the environment's SG part alone (smooth
        // enough for their coarser grid), and without an environment only land.
        bool shaded_cover = split && FLY_COVER_SHADED;
        if (shaded_cover && !cover && !HAS_ENV) {
            continue;
        }
        float weight_hi = cover ? mix_.cover_weight : mix_.fly_weight;
        float w = levels == 2u ? (lk == 0u ? 1.0 - weight_hi : weight_hi) : 1.0;
        uint level = cover ? (lk == 0u ? mix_.cover_lo : mix_.cover_hi) : (lk == 0u ? mix_.fly_lo : mix_.fly_hi);
        uint light = cover ? (shaded_cover ? FLY_LIGHT_LIGHTS : FLY_LIGHT_NONE) : (shaded_cover ? FLY_LIGHT_ENV : FLY_LIGHT_ALL);
        FlyawayMarch fly = march_level_flyaways(ro, d, t_top, ray_end, level, light, shadow_limited);
        ray_radiance = lk == 0u ? fly.radiance * w : ray_radiance + fly.radiance * w;
        ray_transmittance = lk == 0u ? fly.transmittance * w : ray_transmittance + fly.transmittance * w;
        out_.step_limited = out_.step_limited || fly.limited;
        if (lk + 1u == levels) {
            if (cover) {
                fly_t[index] = ray_transmittance;
                uint c = fly_cell(offset, mix_.fly_axis_a, fga, mix_.fly_axis_b, fgb);
                cell_o[c] += 1.0 - ray_transmittance;
                cell_n[c] += 1u;
                if (FLY_COVER_SHADED) {
                    fly_radiance += ray_radiance / float(cga * cgb);
                }
                continue;
            }
            if (split) {
                // The cover rays give the coverage (below).
                box_rgb[ray] = ray_radiance;
                box_t[ray] = ray_transmittance;
                continue;
            }
            if (ray < MAX_FLY_RAYS) {
                fly_t[ray] = ray_transmittance;
            }
            fly_radiance += ray_radiance * share;
            fly_transmittance += ray_transmittance * share;
        }
    }
    if (split) {
        // Split-shaded: fly_radiance holds the cover rays' light; the box rays' (the
        // environment's part, or nothing) is spread as split spreads it.
        vec3 spread = spread_colours(box_rays, box_rgb, box_t, cell_o, cell_n);
        if (FLY_COVER_SHADED) {
            fly_radiance = fly_radiance + spread;
        } else {
            fly_radiance = spread;
        }
        float sum = 0.0;
        for (uint k = 0u; k < cga * cgb; ++k) {
            sum += fly_t[k];
        }
        fly_transmittance = sum / float(cga * cgb);
        // What the surface's lookups are seen through: the cover grid's rays.
        t_axis_a = mix_.cover_axis_a;
        t_axis_b = mix_.cover_axis_b;
        tga = cga;
        tgb = cgb;
    }
    out_.flyaway_opacity = 1.0 - fly_transmittance;
    // What they let through sees the surface, blended over its levels.
    vec3 behind = out_.radiance;
    bool per_lookup = false;
    if (out_.surface) {
        behind = vec3(0.0);
        if (fly_transmittance > 0.0) {
            bool blend = mix_.weight > 0.0 && mix_.hi != mix_.lo;
            // The box grid's lookup points, once for both levels of a blend.
            vec3 p = o + hit.t * d;
            uint n = min(mix_.taps * mix_.taps_minor, MAX_SURFACE_TAPS);
            bool coarse = mix_.lo > 0u || (mix_.weight > 0.0 && mix_.hi > 0u);
            vec2 tap_xy[MAX_SURFACE_TAPS];
            for (uint k = 0u; k < MAX_SURFACE_TAPS; ++k) {
                tap_xy[k] = p.xy;
            }
            if (coarse && n > 1u) {
                for (uint k = 0u; k < n; ++k) {
                    tap_xy[k] = tap_surface_point(o, d, tap_offset(mix_.axis, mix_.taps, mix_.minor_axis, mix_.taps_minor, k), p, floor_level);
                }
            }
            // Level 0's grid (a footprint past a quarter texel, up to level 0's reach), each
            // lookup, past half a texel across, where its own parallel ray meets the height
            // field (Scene::trace_mixed).
            uint n0 = min(mix_.fine_taps_a * mix_.fine_taps_b, MAX_SURFACE_TAPS);
            vec2 fine_xy[MAX_SURFACE_TAPS];
            for (uint k = 0u; k < MAX_SURFACE_TAPS; ++k) {
                fine_xy[k] = p.xy;
            }
            // A close-up's grid, under half a texel across, reads beside the hit.
            if (mix_.lo == 0u && n0 > 1u) {
                // Traced, each reads where the flyaway ray whose cell holds it met the
                // surface, moved by its offset from that ray (Scene::trace_mixed); its own
                // trace where that ray did not land.
                bool traced = fine_grid_traced(mix_.fine_axis_a, mix_.fine_axis_b);
                for (uint k = 0u; k < n0; ++k) {
                    vec2 offset = tap_offset(mix_.fine_axis_a, mix_.fine_taps_a, mix_.fine_axis_b, mix_.fine_taps_b, k);
                    fine_xy[k] = p.xy + offset;
                    if (traced) {
                        uint c = fga * fgb > 1u ? fly_cell(offset, mix_.fly_axis_a, fga, mix_.fly_axis_b, fgb) : MAX_FLY_RAYS;
                        bool borrowed = c < MAX_FLY_RAYS && (fly_landed & (1u << c)) != 0u;
                        if (borrowed) {
                            fine_xy[k] = fly_xy[c] + (offset - tap_offset(mix_.fly_axis_a, fga, mix_.fly_axis_b, fgb, c));
                        } else {
                            fine_xy[k] = tap_surface_point(o, d, offset, p, floor_level);
                        }
                    }
                }
            }
            // Each lookup seen through the flyaway ray whose cell holds it: where the
            // flyaways leave a gap, the surface under it shows (Scene::trace_mixed).
            per_lookup = fga * fgb > 1u;
            float tap_t[MAX_SURFACE_TAPS];
            float fine_t[MAX_SURFACE_TAPS];
            bool coarse_grid = per_lookup && coarse && n > 1u;
            bool fine_grid = per_lookup && mix_.lo == 0u && n0 > 1u;
            lookup_transmittances(mix_.axis, mix_.taps, mix_.minor_axis, mix_.taps_minor, coarse_grid ? n : 0u, fly_t, t_axis_a, tga, t_axis_b, tgb, fly_transmittance, tap_t);
            lookup_transmittances(mix_.fine_axis_a, mix_.fine_taps_a, mix_.fine_axis_b, mix_.fine_taps_b, fine_grid ? n0 : 0u, fly_t, t_axis_a, tga, t_axis_b, tgb, fly_transmittance, fine_t);
            for (uint k = 0u; k < (blend ? 2u : 1u); ++k) {
                uint level = k == 0u ? mix_.lo : mix_.hi;
                vec3 s = shade_surface(o, d, hit.t, level, mix_, level == 0u ? fine_xy : tap_xy, level == 0u ? fine_t : tap_t, shadow_limited);
                // A level read without a grid: the mean transmittance in front of it.
                bool weighted = level == 0u ? fine_grid : coarse_grid;
                s = per_lookup && !weighted ? fly_transmittance * s : s;
                behind = !blend ? s : (k == 0u ? s * (1.0 - mix_.weight) : behind + s * mix_.weight);
            }
        }
    }
    out_.shadow_step_limited = shadow_limited;
    out_.radiance = fly_radiance + (per_lookup ? behind : fly_transmittance * behind);
    return out_;
}

// Whether the driver cut this invocation's loops short: lavapipe (llvmpipe) counts every
// loop iteration of an invocation against one budget of 65535 (gallivm's
// LP_MAX_TGSI_LOOP_ITERATIONS) and, once it is spent, ends each loop after its current
// iteration, silently (groups of 8 pixels left black or too dark). Called last: a loop
// of two iterations whose count the compiler cannot know runs one there; elsewhere it
// always runs two (runtime/GPU_MEASUREMENTS.md, "lavapipe's loop budget").
bool loop_budget_spent() {
    uint probe = 0u;
    for (uint i = 0u; i < (params.max_steps == 0xffffffffu ? 3u : 2u); ++i) {
        ++probe;
    }
    return probe < 2u;
}

#endif // TRACE_GLSL
