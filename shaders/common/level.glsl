// level.glsl — which levels of the mip chain shade a pixel, from its footprint where its
// ray meets the surface (DESIGN.md §7; the rule of LevelChoice in runtime/src/cpu/mod.rs).
//
// Twin: runtime/src/cpu/level.rs (LevelMix, linear_levels, MAX_ANISOTROPY, FILTER_OFFSET,
// FILTER_GRID, box_grid, grid_taps, fly_box_grid, fine_grid_spread, level0_grid_taps,
// fine_grid_traced) and runtime/src/cpu/render.rs (Scene::level_mix, Scene::level_mix_axes,
// Scene::footprint_axes_at). The footprint comes from
// the rays through the neighbouring pixels, as on the CPU, not from screen-space
// derivatives: the two renderers choose the same levels.
#ifndef LEVEL_GLSL
#define LEVEL_GLSL

#include "common/camera.glsl"
#include "common/model.glsl"

#define MAX_ANISOTROPY 8u
const float FILTER_OFFSET = -0.79248125;

// Surface levels lo (weight 1 - weight) and hi (weight); a grid of `taps` lookups over
// `axis` by `taps_minor` over `minor_axis`; flyaway levels fly_lo, fly_hi with fly_weight.
struct LevelMix {
    uint lo;
    uint hi;
    float weight;
    vec2 axis;
    uint taps;
    vec2 minor_axis;
    uint taps_minor;
    uint fly_lo;
    uint fly_hi;
    float fly_weight;
    // The flyaway levels a surface hit's shadow is marched through (format 1.13; twin:
    // LevelMix::shadow).
    uint shadow_lo;
    uint shadow_hi;
    float shadow_weight;
    // The flyaways' box grid: fly_taps_a x fly_taps_b parallel rays spread over the
    // spans fly_axis_a (the footprint's major axis), fly_axis_b (world x-y), each
    // marching the fly levels (1 x 1: the ray alone).
    vec2 fly_axis_a;
    vec2 fly_axis_b;
    uint fly_taps_a;
    uint fly_taps_b;
    // Level 0's grid where its footprint is wider than a quarter texel, up to
    // LEVEL0_REACH texels, blended with level 1 beyond: fine_taps_a x fine_taps_b
    // nearest-texel lookups spread
    // over fine_axis_a, fine_axis_b beside the hit (1 x 1: the hit's texel alone).
    // Twin: LevelMix::fine_*.
    vec2 fine_axis_a;
    vec2 fine_axis_b;
    uint fine_taps_a;
    uint fine_taps_b;
    // The split filter's coverage grid: cover_taps_a x cover_taps_b parallel rays over
    // cover_axis_a, cover_axis_b, each marching the levels cover_lo, cover_hi (weight
    // cover_weight) unshaded (cover_taps_a = 0: none; the box grid's rays give the
    // coverage). Twin: LevelMix::cover (FlyCover).
    uint cover_lo;
    uint cover_hi;
    float cover_weight;
    vec2 cover_axis_a;
    vec2 cover_axis_b;
    uint cover_taps_a;
    uint cover_taps_b;
};

LevelMix level_single(uint level) {
    return LevelMix(level, level, 0.0, vec2(0.0), 1u, vec2(0.0), 1u, level, level, 0.0, level, level, 0.0, vec2(0.0), vec2(0.0), 1u, 1u, vec2(0.0), vec2(0.0), 1u, 1u, level, level, 0.0, vec2(0.0), vec2(0.0), 0u, 0u);
}

// Lookups of the box grid along a footprint's major axis: G per anisotropic lookup, at
// most MAX_ANISOTROPY (or N). Twin: grid_taps.
uint grid_taps(uint n, uint grid) {
    return min(n * grid, max(MAX_ANISOTROPY, n));
}

// Level 0's grid: how far it spreads over a footprint whose minor axis spans `minor`
// level-0 texels, 0 up to FINE_GRID_FROM, 1 from FINE_GRID_FULL (closer views read the
// hit's texel alone). Twin: fine_grid_spread, FINE_GRID_FROM, FINE_GRID_FULL.
const float FINE_GRID_FROM = 0.25;
const float FINE_GRID_FULL = 0.5;

float fine_grid_spread(float minor) {
    return clamp((minor - FINE_GRID_FROM) / (FINE_GRID_FULL - FINE_GRID_FROM), 0.0, 1.0);
}

// Level 0 is read through its own grid up to footprints of LEVEL0_REACH texels, level 1
// only beyond (at 2-4 texels per pixel level 0's texels are the pixel's box, level 1 a
// fit blurred over twice its width). Twin: LEVEL0_REACH, LEVEL0_GRID_MAX; the taps in
// all are at most LEVEL0_TAPS_MAX. The reach is a footprint's size in REACH_GRID
// lookups per axis, whatever the surface's grid FILTER_GRID. Twin: FILTER_GRID in
// runtime/src/cpu/level.rs.
const float LEVEL0_REACH = 4.0;
const uint REACH_GRID = 2u;
#define LEVEL0_GRID_MAX 4u
#define LEVEL0_TAPS_MAX 32u

// Level 0's grid over a footprint whose minor axis spans `minor` texels, N anisotropic
// lookups: about one lookup per texel across (ceil(minor), from FILTER_GRID to
// LEVEL0_GRID_MAX), N times as many along the major axis, at most 32 in all. Twin:
// level0_grid_taps.
uvec2 level0_grid_taps(float minor, uint n) {
    uint across = minor > 0.0 ? max(uint(min(ceil(minor), float(LEVEL0_GRID_MAX))), FILTER_GRID) : FILTER_GRID;
    uint along = min(max(n, 1u) * across, max(LEVEL0_TAPS_MAX / across, across));
    return uvec2(along, across);
}

// Level 1's weight over level 0's grid for a REACH_GRID grid whose lookups' level before
// clamping is lambda_b: 0 while they span at most LEVEL0_REACH / REACH_GRID texels, 1
// where the box grid's level reaches 1, linear between. Twin: level0_reach_weight.
float level0_reach_weight(float lambda_b) {
    float reach_from = log2(LEVEL0_REACH / float(REACH_GRID)) + FILTER_OFFSET;
    float w = (lambda_b - reach_from) / (1.0 - reach_from);
    return isnan(w) ? 1.0 : clamp(w, 0.0, 1.0);
}

// Level 0's grid traces each lookup's own ray once it spans FINE_TRACE_FROM texels along
// its longer axis; a close-up's narrower grid reads beside the hit. Twin:
// fine_grid_traced, FINE_TRACE_FROM.
const float FINE_TRACE_FROM = 0.5;

bool fine_grid_traced(vec2 axis_a, vec2 axis_b) {
    return max(length(axis_a * model.inv_texel), length(axis_b * model.inv_texel)) >= FINE_TRACE_FROM;
}

// The level a flyaway march of `level` reads along a path crossing `columns` level-0
// column lines: coarser where its own columns would number more than GRAZING_COLUMNS (a
// ray near a periodic sheet's horizon). Twin: grazing_level, GRAZING_COLUMNS.
const float GRAZING_COLUMNS = 1024.0;

uint grazing_level(uint level, float columns, uint last) {
    if (!(columns > GRAZING_COLUMNS)) {
        return level;
    }
    float need = ceil(log2(columns / GRAZING_COLUMNS));
    return max(level, need >= float(last) ? last : uint(need));
}

// Most flyaway rays along a footprint's major axis per ray across it. Twin:
// FLY_MAX_ANISOTROPY.
#define FLY_MAX_ANISOTROPY 2u

// The flyaways' box grid for a footprint of `major` level-0 texels, `n` anisotropic
// lookups: min(N, FLY_MAX_ANISOTROPY) * G rays along the major axis and G across it at
// the level of N * G lookups, major / min(N * G, 8), down to level 0 (G = 2: the
// surface's; G = FLY_GRID, the fine filter's 4: a quarter of a round footprint),
// spread over the fraction `spread` of the footprint: fine_grid_spread(major / N), as
// level 0's grid of the surface (from 0 at a quarter texel to 1 at half a texel); one
// ray at that level closer (without a grid, G = 1: one ray at log2 major). Twin:
// fly_box_grid (FlyGrid).
struct FlyGrid {
    float level;
    float spread;
    uint taps_major;
    uint taps_minor;
};

FlyGrid fly_box_grid(float major, uint n, float bias, uint grid) {
    float lambda = log2(major) + bias;
    if (grid <= 1u) {
        return FlyGrid(lambda, 0.0, 1u, 1u);
    }
    uint m = max(n, 1u);
    uint taps = grid_taps(m, grid);
    float finer = max(lambda - log2(float(grid)) - log2(float(taps) / float(grid)), 0.0);
    float spread = fine_grid_spread(major / float(m));
    if (!(spread > 0.0)) {
        return FlyGrid(finer, 0.0, 1u, 1u);
    }
    return FlyGrid(finer, spread, min(m, FLY_MAX_ANISOTROPY) * grid, grid);
}

// The box filter's grid at coarse levels: FILTER_GRID lookups per axis (N * G along the
// major one) at level `level`, spread over `span_major`, `span_minor` level-0 texels so
// that each axis keeps the pixel's variance. False: the one-lookup rule. Twin: box_grid.
struct BoxGrid {
    float level;
    uint taps_major;
    uint taps_minor;
    float span_major;
    float span_minor;
};

float box_span(float p, uint g, float kernel, float scale) {
    if (g <= 1u) {
        return 0.0;
    }
    float s2 = max(p * p * scale / 12.0 - kernel, 0.0) * 12.0 / float(g * g - 1u);
    return sqrt(s2) * float(g);
}

bool box_grid(float major, float minor, uint n, float lambda, float bias, out BoxGrid g) {
    g = BoxGrid(lambda, 1u, 1u, 0.0, 0.0);
    if (FILTER_GRID <= 1u || !(lambda > 1.0)) {
        return false;
    }
    uint taps_major = grid_taps(n, FILTER_GRID);
    float level = max(log2(major / float(taps_major)) + FILTER_OFFSET + bias, 1.0);
    float kernel = exp2(2.0 * level) / 4.0;
    float scale = exp2(2.0 * bias);
    float span_major = box_span(major, taps_major, kernel, scale);
    float span_minor = box_span(minor, FILTER_GRID, kernel, scale);
    g.level = level;
    if (span_major > 1e-3) {
        g.taps_major = taps_major;
        g.span_major = span_major;
    }
    if (span_minor > 1e-3) {
        g.taps_minor = FILTER_GRID;
        g.span_minor = span_minor;
    }
    return true;
}

// The level (before linear_levels) whose flyaways a surface hit's shadow is marched
// through: that of the footprint's geometric mean width. Twin: shadow_lambda
// (runtime/src/cpu/level.rs).
float shadow_lambda(float major, float minor, float bias) {
    return 0.5 * (log2(major) + log2(max(minor, 1e-6))) + bias;
}

// Levels floor(lambda) and floor(lambda) + 1 with the weight of the second, clamped.
void linear_levels(float lambda, uint last, out uint lo, out uint hi, out float w) {
    lo = 0u;
    hi = 0u;
    w = 0.0;
    if (!(lambda > 0.0)) {
        return;
    }
    float f = floor(lambda);
    if (f >= float(last)) {
        lo = last;
        hi = last;
        return;
    }
    lo = uint(f);
    hi = lo + 1u;
    w = lambda - f;
}

// The steps, in world x-y on the plane at height z, to where the rays through the next
// pixel right and down meet it; false if one of them misses the plane.
bool footprint_on_plane(float px, float py, float z, out vec2 p) {
    vec3 o, d;
    camera_ray(px, py, o, d);
    p = vec2(0.0);
    if (!(d.z < 0.0) || o.z < z) {
        return false;
    }
    p = (o + d * ((z - o.z) / d.z)).xy;
    return true;
}

bool footprint_axes_at(float px, float py, float z, out vec2 a, out vec2 b) {
    vec2 c, r, u;
    a = vec2(0.0);
    b = vec2(0.0);
    if (!footprint_on_plane(px, py, z, c) || !footprint_on_plane(px + 1.0, py, z, r) || !footprint_on_plane(px, py + 1.0, z, u)) {
        return false;
    }
    a = r - c;
    b = u - c;
    return true;
}

// The levels for a footprint with axes a, b (world x-y steps to the next pixel right
// and down; ok = false: a neighbour's ray misses the plane). Twin: Scene::level_mix_axes.
LevelMix level_mix_axes(bool ok, vec2 a, vec2 b) {
    uint last = model.level_count - 1u;
    if (params.level_mode == LEVEL_FIXED) {
        return level_single(min(params.fixed_level, last));
    }
    float bias = params.level_bias;
    if (!ok) {
        return level_single(last);
    }
    float la = length(a * model.inv_texel);
    float lb = length(b * model.inv_texel);
    float major = la >= lb ? la : lb;
    float minor = la >= lb ? lb : la;
    vec2 axis = la >= lb ? a : b;
    vec2 minor_axis = la >= lb ? b : a;
    if (!(major > 0.0)) {
        return level_single(0u);
    }
    if (isinf(major)) {
        return level_single(last);
    }
    if (params.level_mode == LEVEL_NEAREST) {
        float lambda = log2(major) + bias;
        return level_single(min(uint(max(floor(lambda + 0.5), 0.0)), last));
    }
    uint taps = uint(clamp(ceil(major / max(minor, 1e-6) - 1e-3), 1.0, float(MAX_ANISOTROPY)));
    float lambda = log2(major / float(taps)) + FILTER_OFFSET + bias;
    LevelMix m;
    FlyGrid fly = fly_box_grid(major, taps, bias, FLY_GRID);
    linear_levels(fly.level, last, m.fly_lo, m.fly_hi, m.fly_weight);
    linear_levels(shadow_lambda(major, minor, bias), last, m.shadow_lo, m.shadow_hi, m.shadow_weight);
    bool fly_grid = fly.spread > 0.0;
    m.fly_taps_a = fly_grid ? fly.taps_major : 1u;
    m.fly_taps_b = fly_grid ? fly.taps_minor : 1u;
    m.fly_axis_a = fly_grid ? axis * fly.spread : vec2(0.0);
    m.fly_axis_b = fly_grid ? minor_axis * fly.spread : vec2(0.0);
    m.fine_axis_a = vec2(0.0);
    m.fine_axis_b = vec2(0.0);
    m.fine_taps_a = 1u;
    m.fine_taps_b = 1u;
    // The split filter: the coverage from the finer grid, where both grids spread and the
    // shading rays march a coarse level (at level 0 the finer grid's voxels are theirs).
    m.cover_lo = m.fly_lo;
    m.cover_hi = m.fly_hi;
    m.cover_weight = 0.0;
    m.cover_axis_a = vec2(0.0);
    m.cover_axis_b = vec2(0.0);
    m.cover_taps_a = 0u;
    m.cover_taps_b = 0u;
    if (FLY_COVER_GRID != FLY_GRID) {
        FlyGrid cover = fly_box_grid(major, taps, bias, FLY_COVER_GRID);
        if (fly_grid && cover.spread > 0.0 && fly.level > 0.0) {
            linear_levels(cover.level, last, m.cover_lo, m.cover_hi, m.cover_weight);
            m.cover_axis_a = axis * cover.spread;
            m.cover_axis_b = minor_axis * cover.spread;
            m.cover_taps_a = cover.taps_major;
            m.cover_taps_b = cover.taps_minor;
        }
    }
    BoxGrid g;
    if (!box_grid(major, minor, taps, lambda, bias, g)) {
        // With a grid, level 0 alone up to LEVEL0_REACH texels (lambda <= 1 here);
        // without one, Vulkan's linear-mip blend.
        float blend;
        if (FILTER_GRID > 1u) {
            m.lo = 0u;
            m.hi = 0u;
            m.weight = 0.0;
            blend = clamp(lambda, 0.0, 1.0);
        } else {
            linear_levels(lambda, last, m.lo, m.hi, m.weight);
            blend = m.weight;
        }
        m.axis = axis;
        m.taps = taps;
        m.minor_axis = vec2(0.0);
        m.taps_minor = 1u;
        // Level 0 through a grid of its nearest texels, spread from nothing at a minor
        // axis of FINE_GRID_FROM texels to the footprint at FINE_GRID_FULL, and where
        // level 1 is blended in, at least from nothing at lambda = 0 to the footprint
        // at 1/2 (Scene::level_mix_axes).
        // Along the major axis at most the minor axis's width in texels: a grazing
        // view's plane offsets land on texels its rays do not meet.
        float beyond = fine_grid_spread(minor);
        if (m.lo == 0u && (blend > 0.0 || beyond > 0.0) && FILTER_GRID > 1u) {
            float blended = min(2.0 * blend, 1.0);
            m.fine_axis_a = axis * max(blended, beyond * minor / major);
            m.fine_axis_b = minor_axis * max(blended, beyond);
            uvec2 t = level0_grid_taps(minor, taps);
            m.fine_taps_a = t.x;
            m.fine_taps_b = t.y;
        }
        return m;
    }
    m.axis = axis * (g.span_major / major);
    m.taps = g.taps_major;
    m.minor_axis = minor_axis * (g.span_minor / max(minor, 1e-6));
    m.taps_minor = g.taps_minor;
    // Level 0's grid blended with level 1's box grid up to where a REACH_GRID grid's level
    // reaches 1 (level0_reach_weight).
    // A model without a chain reads level 0 through its grid at every distance.
    float reach = level0_reach_weight(log2(major / float(grid_taps(taps, REACH_GRID))) + FILTER_OFFSET + bias);
    if (reach < 1.0 || last == 0u) {
        m.lo = 0u;
        m.hi = last == 0u ? 0u : 1u;
        m.weight = last == 0u ? 0.0 : reach;
        if (last == 0u) {
            m.axis = vec2(0.0);
            m.taps = 1u;
            m.minor_axis = vec2(0.0);
            m.taps_minor = 1u;
        }
        m.fine_axis_a = axis;
        m.fine_axis_b = minor_axis;
        uvec2 t = level0_grid_taps(minor, taps);
        m.fine_taps_a = t.x;
        m.fine_taps_b = t.y;
        return m;
    }
    linear_levels(g.level, last, m.lo, m.hi, m.weight);
    return m;
}

// The levels that shade pixel (px, py) when its ray meets the surface at height z;
// with s x s samples per pixel each sample filters its own sub-pixel, 1/s of the
// pixel's footprint across. Twin: Scene::level_mix.
LevelMix level_mix(float px, float py, float z) {
    vec2 a, b;
    bool ok = footprint_axes_at(px, py, z, a, b);
    float k = 1.0 / float(max(params.supersampling, 1u));
    return level_mix_axes(ok, a * k, b * k);
}

#endif // LEVEL_GLSL
