// flyaways.glsl — marching a level's flyaway lists along a ray, front to back,
// alpha-compositing what it crosses (DESIGN.md §5, §7).
//
// Twin: runtime/src/cpu/flyaways.rs (flyaway_opacity, march_flyaways, whose module docs
// define the columns and the opacity 1 - (1 - alpha)^(g*l/s), g the level's path gain); the shading of a node is
// the closure the CPU's Scene::march_level_flyaways passes, run on queued nodes (the same
// sum in the same order; march_flyaways says why).
#ifndef FLYAWAYS_GLSL
#define FLYAWAYS_GLSL

#include "common/shading.glsl"

const float MIN_TRANSMITTANCE = 1e-4;
const float TILE_LIMIT = 16777216.0;
// Nodes collected before they are shaded (march_flyaways).
#define FLY_QUEUE 8u

struct FlyawayMarch {
    vec3 radiance;        // premultiplied by the nodes' opacities
    float transmittance;  // left for what lies behind
    uint columns;
    bool limited;         // the column budget ran out
};

// Opacity of a voxel of coverage alpha crossed over `path` with edge `edge`.
float flyaway_opacity(float alpha, float path, float edge) {
    if (isnan(path) || path <= 0.0) {
        return 0.0;
    }
    if (alpha >= 1.0) {
        return 1.0;
    }
    return 1.0 - pow(max(1.0 - alpha, 0.0), path / edge);
}

// A coarse level's gain on the opacity exponent for a ray of unit direction d (format
// 1.9): linear in the polar angle acos|d.z| between the nodes at 0, 10, ... 80 degrees,
// constant past 80. Twin: PathGain::at (runtime/src/hybrid/flyaway.rs).
float flyaway_path_gain(GpuLevel l, vec3 d) {
    float theta = degrees(acos(min(abs(d.z), 1.0)));
    float x = clamp(theta / 10.0, 0.0, 8.0);
    uint k = min(uint(x), 7u);
    float f = x - float(k);
    return l.fly_gain[k] + f * (l.fly_gain[k + 1u] - l.fly_gain[k]);
}

// Marches the ray (o, d: unit, heading down) through the lists of `level` over
// [t_start, t_end], shading each node it crosses at its entry point with `light`
// (FLY_LIGHT_*; FLY_LIGHT_NONE: the transmittance alone, radiance zero; the CPU's
// visit_flyaways without a visit).
FlyawayMarch march_flyaways(uint level, vec3 o, vec3 d, float t_start, float t_end, uint max_columns, uint light, inout uint shadow_limited) {
    FlyawayMarch out_ = FlyawayMarch(vec3(0.0), 1.0, 0u, false);
    if (isnan(t_end) || t_end <= t_start || d.z >= 0.0) {
        return out_;
    }
    GpuLevel l = model.levels[level];
    ivec2 n0 = model.n;
    int span = 1 << level;
    ivec2 dims = ivec2(l.dims);
    bool periodic = model_periodic();
    // One gain per ray: it depends on the ray's slant alone (HYBRID_FORMAT.md §7.3).
    float gain = flyaway_path_gain(l, d);
    // Products with inv_texel and no fused multiply–add (`precise`): the column lines
    // fall where the CPU twin's do.
    vec2 u0 = (o.xy - model.origin) * model.inv_texel;
    vec2 du = d.xy * model.inv_texel;
    precise vec2 u_start = u0 + du * t_start;
    ivec2 tile;
    ivec2 k;
    for (int axis = 0; axis < 2; ++axis) {
        float n = float(n0[axis]);
        // Clamped to 2^24 repeats, as the CPU twin (TILE_LIMIT): no overflow far away.
        int t_ = int(clamp(floor(u_start[axis] / n), -TILE_LIMIT, TILE_LIMIT));
        float local = u_start[axis] - float(t_) * n;
        if (local <= 0.0 && du[axis] < 0.0) {
            t_ -= 1;
            local += n;
        }
        int kk = clamp(int(floor(local / float(span))), 0, dims[axis] - 1);
        if (local == float(kk * span) && du[axis] < 0.0 && kk > 0) {
            kk -= 1;
        }
        tile[axis] = t_;
        k[axis] = kk;
    }
    // The march is resumable: it collects up to FLY_QUEUE crossed nodes (entry point,
    // record, weight T·opacity), then shades them, until the ray is done. The sum and
    // its order are the CPU's; what the queue changes is that the shading runs in its
    // own short loop instead of inside the list walk, where SIMD lanes would carry it
    // through every step any one of them takes.
    float t = t_start;
    bool in_column = false;
    bool done = false;
    uint node = NO_NODE;
    uint guard = 0u;
    float t_next = t;
    float d_in = 0.0;
    float d_out = 0.0;
    vec2 exits = vec2(HF_INF);
    while (!done) {
        uint qn = 0u;
        float q_t[FLY_QUEUE];
        float q_w[FLY_QUEUE];
        uvec2 q_node[FLY_QUEUE];
        uint q_spread[FLY_QUEUE];
        while (qn < FLY_QUEUE && !done) {
            if (!in_column) {
                if (out_.columns >= max_columns) {
                    out_.limited = true;
                    done = true;
                    break;
                }
                if (!periodic && (tile.x != 0 || tile.y != 0)) {
                    done = true;
                    break;
                }
                out_.columns += 1u;
                exits = vec2(HF_INF);
                for (int axis = 0; axis < 2; ++axis) {
                    float base = float(tile[axis]) * float(n0[axis]);
                    float lo = base + float(k[axis] * span);
                    float hi = base + float(min((k[axis] + 1) * span, n0[axis]));
                    if (du[axis] > 0.0) {
                        exits[axis] = (hi - u0[axis]) / du[axis];
                    } else if (du[axis] < 0.0) {
                        exits[axis] = (lo - u0[axis]) / du[axis];
                    }
                }
                t_next = max(min(min(exits.x, exits.y), t_end), t);
                uint column = uint(k.y * dims.x + k.x);
                d_in = model.top_z - (o.z + d.z * t);
                d_out = model.top_z - (o.z + d.z * t_next);
                node = fly_heads[l.fly_head_base + column];
                guard = 0u;
                in_column = true;
            }
            if (node != NO_NODE && guard < l.fly_nodes) {
                guard += 1u;
                uint node_index = node;
                uvec4 nd = fly_nodes[l.fly_node_base + node];
                node = nd.x;
                // A coarse node's record (three words from `spread`): the roll and
                // weights (word 0), the depth range its fibres occupy (word 1; the whole
                // voxel without a record), its second axis group (word 2).
                uint spread = NO_NODE;
                float z0 = 0.0;
                float z1 = 1.0;
                if (l.spread_base != NO_NODE) {
                    spread = l.spread_base + 3u * node_index;
                    uint slab = fly_spread_word(spread + 1u);
                    z0 = float(slab & 0xffu) * (1.0 / 255.0);
                    z1 = float((slab >> 8) & 0xffu) * (1.0 / 255.0);
                }
                float top = (float(nd.y & 0xffffu) + z0) * l.voxel_depth;
                float bottom = (float(nd.y & 0xffffu) + z1) * l.voxel_depth;
                if (bottom <= d_in) {
                    continue;
                }
                if (top >= d_out) {
                    node = NO_NODE;
                    continue;
                }
                float t_in = max(t, (model.top_z - top - o.z) / d.z);
                float t_out = min(t_next, (model.top_z - bottom - o.z) / d.z);
                float opacity = flyaway_opacity(unorm16_value(nd.y >> 16), gain * (t_out - t_in), l.fly_edge);
                if (opacity > 0.0) {
                    // Unshaded, nothing is queued: the walk runs to the end in one go.
                    if (light != FLY_LIGHT_NONE) {
                        q_t[qn] = t_in;
                        q_w[qn] = out_.transmittance * opacity;
                        q_node[qn] = nd.zw;
                        q_spread[qn] = spread;
                        qn += 1u;
                    }
                    out_.transmittance *= 1.0 - opacity;
                    if (out_.transmittance < MIN_TRANSMITTANCE) {
                        out_.transmittance = 0.0;
                        done = true;
                    }
                }
                continue;
            }
            // The column is done: on to the next one the ray enters.
            in_column = false;
            if (t_next >= t_end) {
                done = true;
                break;
            }
            t = t_next;
            for (int axis = 0; axis < 2; ++axis) {
                if (exits[axis] <= t_next) {
                    if (du[axis] > 0.0) {
                        k[axis] += 1;
                        if (k[axis] >= dims[axis]) {
                            k[axis] = 0;
                            tile[axis] += 1;
                        }
                    } else {
                        k[axis] -= 1;
                        if (k[axis] < 0) {
                            k[axis] = dims[axis] - 1;
                            tile[axis] -= 1;
                        }
                    }
                }
            }
        }
        // The node's BRDF in its fiber frame, shadowed like a surface (the CPU's closure
        // in Scene::march_level_flyaways).
        for (uint i = 0u; i < qn; ++i) {
            out_.radiance += q_w[i] * shade_fiber(level, q_node[i].y, octahedral_decode(q_node[i].x), q_spread[i], o + q_t[i] * d, -d, light, shadow_limited);
        }
    }
    return out_;
}

#endif // FLYAWAYS_GLSL
