// heightfield.glsl — marching the height field: parallax occlusion mapping made exact
// with a conservative min-depth quadtree and a per-leaf quadratic root (DESIGN.md §7).
//
// Twin: runtime/src/cpu/heightfield.rs, whose module docs define leaf space, the
// quadtree and the refinement; the functions here have its names with an hf_ prefix,
// in its order, with its arithmetic. The samples and the quadtree are the CPU's own
// arrays (model.glsl, binding 1). Rays are parameterized by world distance t.
#ifndef HEIGHTFIELD_GLSL
#define HEIGHTFIELD_GLSL

#include "common/model.glsl"

#define HF_REFINE_STEPS 20
// The most tile repeats from the origin a periodic march starts at (flyaways::TILE_LIMIT).
const float TILE_LIMIT_HF = 16777216.0;
#define HF_MISS 0u
#define HF_HIT 1u
#define HF_STEP_LIMIT 2u

#define HF_INF uintBitsToFloat(0x7f800000u)
const float HF_F32_MAX = 3.40282347e38;

struct HfTrace {
    uint kind;  // HF_MISS, HF_HIT, HF_STEP_LIMIT
    float t;    // ray parameter of the hit
};

// A ray in leaf space: q(t) = q0 + dq t, depth D(t) = d0 + dd t below the top plane.
struct HfRay {
    vec2 q0;
    vec2 dq;
    float d0;
    float dd;
};

vec2 hf_q(HfRay r, float t) {
    return r.q0 + r.dq * t;
}

float hf_depth(HfRay r, float t) {
    return r.d0 + r.dd * t;
}

// Depth sample (i, j), wrapped (periodic) or clamped to the edge.
float hf_sample(int i, int j) {
    ivec2 ij = tile_index(i, j, model.n);
    return model_floats[ij.y * model.n.x + ij.x];
}

// Depths at the corners of leaf (cx, cy): (0,0), (1,0), (0,1), (1,1).
vec4 hf_corners(int cx, int cy) {
    int i = cx - model.leaf_offset;
    int j = cy - model.leaf_offset;
    return vec4(hf_sample(i, j), hf_sample(i + 1, j), hf_sample(i, j + 1), hf_sample(i + 1, j + 1));
}

// The surface's depth at world (x, y): bilinear between texel centres.
float hf_depth_at(float x, float y) {
    precise vec2 q = (vec2(x, y) - model.origin) * model.inv_texel - vec2(0.5);
    vec2 f = floor(q);
    float s = q.x - f.x;
    float t = q.y - f.y;
    int i = int(f.x);
    int j = int(f.y);
    float h00 = hf_sample(i, j), h10 = hf_sample(i + 1, j), h01 = hf_sample(i, j + 1), h11 = hf_sample(i + 1, j + 1);
    return (h00 * (1.0 - s) + h10 * s) * (1.0 - t) + (h01 * (1.0 - s) + h11 * s) * t;
}

// The leaf-space ray of (o, d), with t = 0 at o + d t0.
HfRay hf_leaf_ray(vec3 o, vec3 d, float t0) {
    // `precise` and products with inv_texel: the leaf lines fall where the CPU's do.
    precise vec3 p = o + d * t0;
    HfRay r;
    precise vec2 q0 = (p.xy - model.origin) * model.inv_texel - vec2(0.5) + vec2(float(model.leaf_offset));
    r.q0 = q0;
    r.dq = d.xy * model.inv_texel;
    r.d0 = model.top_z - p.z;
    r.dd = -d.z;
    return r;
}

// Clips [ta, tb] to the t where lo <= x0 + dx t <= hi; false if nothing is left.
bool hf_clip(float x0, float dx, float lo, float hi, inout float ta, inout float tb) {
    if (dx == 0.0) {
        return x0 >= lo && x0 <= hi && ta <= tb;
    }
    float t0 = (lo - x0) / dx;
    float t1 = (hi - x0) / dx;
    if (!(t0 < t1)) {
        float s = t0;
        t0 = t1;
        t1 = s;
    }
    ta = max(ta, t0);
    tb = min(tb, t1);
    return ta <= tb;
}

// Where x0 + dx t leaves [lo, hi] moving along dx (inf if dx = 0).
float hf_axis_exit(float x0, float dx, float lo, float hi) {
    if (dx > 0.0) {
        return (hi - x0) / dx;
    } else if (dx < 0.0) {
        return (lo - x0) / dx;
    }
    return HF_INF;
}

// The child of `cell` (children of size `size`) containing q; on the midline, the one
// the ray moves into.
ivec2 hf_child(ivec2 cell, vec2 q, vec2 dq, float size, ivec2 dims) {
    ivec2 o;
    for (int axis = 0; axis < 2; ++axis) {
        float mid = float(2 * cell[axis] + 1) * size;
        bool upper = q[axis] > mid || (q[axis] == mid && dq[axis] >= 0.0);
        o[axis] = min(2 * cell[axis] + (upper ? 1 : 0), dims[axis] - 1);
    }
    return o;
}

float hf_bound(int level, ivec2 cell) {
    GpuQuadLevel l = model.quad[level];
    return model_floats[l.offset + uint(cell.y * l.dims.x + cell.x)];
}

// The first t in [ta, tb] inside leaf `cell` where g = D - h - bias >= 0 (found: true).
bool hf_leaf_hit(HfRay r, ivec2 cell, float ta, float tb, float bias, out float t_hit) {
    vec4 c = hf_corners(cell.x, cell.y);
    float a = c.x, b = c.y - c.x, cc = c.z - c.x, e = c.x - c.y - c.z + c.w;
    vec2 qa = hf_q(r, ta) - vec2(cell);
    float len = tb - ta;
    float u0 = qa.x, v0 = qa.y, du = r.dq.x * len, dv = r.dq.y * len;
    float g0 = hf_depth(r, ta) - (a + b * u0 + cc * v0 + e * u0 * v0) - bias;
    float g1 = r.dd * len - (b * du + cc * dv + e * (u0 * dv + v0 * du));
    float g2 = -e * du * dv;
    t_hit = ta;
    if (g0 >= 0.0) {
        return true;
    }
    float hi = 1.0;
    if (g2 < 0.0) {
        float s_max = -g1 / (2.0 * g2);
        if (s_max > 0.0 && s_max < 1.0 && g0 + s_max * (g1 + s_max * g2) >= 0.0) {
            hi = s_max;
        }
    }
    if (g0 + hi * (g1 + hi * g2) < 0.0) {
        return false;
    }
    float lo = 0.0;
    for (int k = 0; k < HF_REFINE_STEPS; ++k) {
        float mid = 0.5 * (lo + hi);
        if (g0 + mid * (g1 + mid * g2) >= 0.0) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    t_hit = ta + hi * len;
    return true;
}

// Steps after which a march descends one quadtree level less, and one more per as many
// again (a ray skimming the crests near a periodic sheet's horizon). Twin:
// STEPS_PER_FLOOR (runtime/src/cpu/heightfield.rs).
const uint HF_STEPS_PER_FLOOR = 512u;

// Repeats of a periodic tile a march crosses below the shallowest depth before it takes
// the next repeat's flat top as the hit (a ray within a fraction of a degree of the
// horizon). Twin: SKIM_TILES.
const uint HF_SKIM_TILES = 16u;

// The quadtree traversal of one tile's leaves over [ta, tb].
HfTrace hf_traverse(HfRay r, float ta, float tb, float bias, uint max_steps, inout uint steps, int floor_level) {
    int top = int(model.quad_count) - 1;
    int level = top;
    ivec2 cell = ivec2(0);
    float t = ta;
    for (;;) {
        if (steps >= max_steps) {
            return HfTrace(HF_STEP_LIMIT, 0.0);
        }
        steps += 1u;
        float size = float(1 << level);
        vec2 exits = vec2(hf_axis_exit(r.q0.x, r.dq.x, float(cell.x) * size, float(cell.x + 1) * size),
                          hf_axis_exit(r.q0.y, r.dq.y, float(cell.y) * size, float(cell.y + 1) * size));
        float t_exit = max(min(min(exits.x, exits.y), tb), t);
        float bound = hf_bound(level, cell);
        float deepest = max(hf_depth(r, t), hf_depth(r, t_exit));
        if (deepest >= bound + bias) {
            if (level == 0) {
                float th;
                if (hf_leaf_hit(r, cell, t, t_exit, bias, th)) {
                    return HfTrace(HF_HIT, th);
                }
            } else if (level <= max(floor_level, int(steps / HF_STEPS_PER_FLOOR))) {
                // The node's flat top: where the (linear) depth reaches its bound.
                float th = hf_depth(r, t) >= bound + bias ? t : (bound + bias - r.d0) / r.dd;
                return HfTrace(HF_HIT, clamp(th, t, t_exit));
            } else {
                level -= 1;
                cell = hf_child(cell, hf_q(r, t), r.dq, float(1 << level), model.quad[level].dims);
                continue;
            }
        }
        if (t_exit >= tb) {
            return HfTrace(HF_MISS, 0.0);
        }
        t = t_exit;
        ivec2 old = cell;
        for (int axis = 0; axis < 2; ++axis) {
            if (exits[axis] <= t_exit) {
                cell[axis] += r.dq[axis] > 0.0 ? 1 : -1;
            }
        }
        ivec2 dims = model.quad[level].dims;
        if (cell.x < 0 || cell.y < 0 || cell.x >= dims.x || cell.y >= dims.y) {
            return HfTrace(HF_MISS, 0.0);
        }
        if (level < top && ((cell.x >> 1) != (old.x >> 1) || (cell.y >> 1) != (old.y >> 1))) {
            level += 1;
            cell = ivec2(cell.x >> 1, cell.y >> 1);
        }
    }
    return HfTrace(HF_MISS, 0.0);
}

HfTrace hf_trace_clamped(HfRay r, float ta, float tb, float bias, uint max_steps, inout uint steps, int floor_level) {
    for (int axis = 0; axis < 2; ++axis) {
        if (!hf_clip(r.q0[axis], r.dq[axis], 0.5, float(model.n[axis]) + 0.5, ta, tb)) {
            return HfTrace(HF_MISS, 0.0);
        }
    }
    return hf_traverse(r, ta, tb, bias, max_steps, steps, floor_level);
}

HfTrace hf_trace_periodic(HfRay r, float ta, float tb, float bias, uint max_steps, inout uint steps, int floor_level) {
    vec2 n = vec2(model.n);
    vec2 q = hf_q(r, ta);
    ivec2 tile;
    for (int axis = 0; axis < 2; ++axis) {
        float f = floor(q[axis] / n[axis]);
        tile[axis] = int(clamp(f, -TILE_LIMIT_HF, TILE_LIMIT_HF));
        if (q[axis] == f * n[axis] && r.dq[axis] < 0.0) {
            tile[axis] -= 1;
        }
    }
    float t = ta;
    uint walked = 0u;
    for (;;) {
        vec2 lo = vec2(tile) * n;
        vec2 exits = vec2(hf_axis_exit(r.q0.x, r.dq.x, lo.x, lo.x + n.x), hf_axis_exit(r.q0.y, r.dq.y, lo.y, lo.y + n.y));
        float t_tile = max(min(min(exits.x, exits.y), tb), t);
        HfRay local = r;
        local.q0 = r.q0 - lo;
        int tile_floor = walked >= HF_SKIM_TILES ? int(model.quad_count) - 1 : floor_level;
        walked += 1u;
        HfTrace h = hf_traverse(local, t, t_tile, bias, max_steps, steps, tile_floor);
        if (h.kind != HF_MISS) {
            return h;
        }
        if (t_tile >= tb) {
            return HfTrace(HF_MISS, 0.0);
        }
        t = t_tile;
        for (int axis = 0; axis < 2; ++axis) {
            if (exits[axis] <= t_tile) {
                tile[axis] += r.dq[axis] > 0.0 ? 1 : -1;
            }
        }
    }
    return HfTrace(HF_MISS, 0.0);
}

// The first t in [t_start, t_stop] where the ray (o, d) is at least `bias` below the
// surface, descending the quadtree no further than `floor_level` (0: exact; above, the
// node's flat top is the hit: HeightTracer::trace_to). Counts traversal steps in `steps`
// and stops at `max_steps`.
HfTrace hf_trace(vec3 o, vec3 d, float t_start, float t_stop, float bias, uint max_steps, inout uint steps, int floor_level) {
    HfRay r = hf_leaf_ray(o, d, t_start);
    float ta = 0.0;
    float tb = t_stop - t_start;
    // The slab from the shallowest depth (the quadtree's root bound) down: no ray meets the
    // surface above it (twin: HeightTracer::trace_to).
    float shallowest = clamp(hf_bound(int(model.quad_count) - 1, ivec2(0)), 0.0, model.height_scale);
    if (!hf_clip(r.d0, r.dd, shallowest, model.height_scale, ta, tb)) {
        return HfTrace(HF_MISS, 0.0);
    }
    floor_level = min(floor_level, int(model.quad_count) - 1);
    HfTrace h = model_periodic() ? hf_trace_periodic(r, ta, tb, bias, max_steps, steps, floor_level) : hf_trace_clamped(r, ta, tb, bias, max_steps, steps, floor_level);
    if (h.kind == HF_HIT) {
        h.t += t_start;
    }
    return h;
}

// Whether the height field blocks the way from surface point p toward wi over
// max_dist: true if blocked; `limited` is set when the march ran out of steps (blocked).
bool hf_occluded(vec3 p, vec3 wi, float max_dist, uint max_steps, out bool limited) {
    limited = false;
    if (wi.z <= 0.0) {
        return true;
    }
    float scale = min(model.texel.x, model.texel.y);
    uint steps = 0u;
    HfTrace h = hf_trace(p, wi, 1e-3 * scale, max_dist, 1e-4 * scale, max_steps, steps, 0);
    limited = h.kind == HF_STEP_LIMIT;
    return h.kind != HF_MISS;
}

#endif // HEIGHTFIELD_GLSL
