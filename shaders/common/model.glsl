// model.glsl — the hybrid model's arrays and the decoding of its BRDF records.
//
// Twins: runtime/src/hybrid/gpu_layout.rs (the structs, member for member, and the
// bindings; a test compares the SPIR-V member offsets with Rust's offset_of!) and
// runtime/src/hybrid/lobe.rs + model.rs (brdf_in_frame, brdf_framed, texel_brdf).
//
// Records (runtime/HYBRID_FORMAT.md "Records"), as 32-bit words:
//   BrdfHeader     uvec4: x = kd.r | kd.g << 16, y = kd.b | eta << 16,
//                         z = a | lobe_count << 16 (| reserved << 24), w = lobe_offset
//   PackedLobe     uvec4: x = normal (oct u | v << 16), y = tangent_angle | k.r << 16,
//                         z = k.g | k.b << 16, w = beta | gamma << 16
//   ClusteredTexel uvec2: x = normal, y = tangent_angle | cluster << 16
//   FlyawayNode    uvec4: x = next, y = depth | alpha << 16, z = tangent (oct), w = param
// Indices inside records are local to their table or level; add the level's *_base.
#ifndef MODEL_GLSL
#define MODEL_GLSL

#include "brdf.glsl"
#include "common/packing.glsl"
#include "common/visible_normal.glsl"

#define GPU_MAX_LEVELS 16
#define GPU_MAX_QUAD_LEVELS 18
#define GPU_FLAG_PERIODIC 1u
#define GPU_FLAG_VOLUMETRIC 2u
#define GPU_FLAG_COARSE_VISIBILITY 4u
#define GPU_FLAG_READING_WIDTH 8u
#define GPU_FLAG_DIFFUSE_LS 16u
#define GPU_FLAG_FIBER_CYLINDER 32u
#define GPU_FLAG_FLYAWAY_SHADOW 64u
#define GPU_FLAG_READING_HELD 128u
#define GPU_SURFACE_CLUSTERED 0u
#define GPU_SURFACE_PER_TEXEL 1u
#define NO_NODE 0xffffffffu

struct GpuLevel {
    uvec2 dims;
    uint surface;
    uint texel_base;
    uint header_base;
    uint lobe_base;
    uint fly_nodes;
    uint fly_head_base;
    uint fly_node_base;
    uint fly_header_base;
    uint fly_lobe_base;
    float voxel_depth;
    float fly_edge;
    uint trans_base;    // first transmission record (binding 12), NO_NODE: none
    uint tilt_base;     // first view tilt record (binding 13), NO_NODE: none
    uint spread_base;   // first flyaway spread word in binding 6 (after the nodes), NO_NODE: none
    float fly_gain[9];  // opacity exponent gain at polar 0, 10, ... 80 degrees (format 1.9; 1: none)
    uint grad_base;     // first visibility gradient word in binding 13 (after the tilts), NO_NODE: none
    uint curv_base;     // first visibility curvature word in binding 13 (format 1.15), NO_NODE: none
    uint pad;
};

struct GpuQuadLevel {
    ivec2 dims;
    uint offset;
    uint pad;
};

struct GpuModelHeader {
    vec2 origin;
    vec2 size;
    vec2 texel;
    ivec2 n;
    float top_z;
    float height_scale;
    uint level_count;
    uint quad_count;
    int leaf_offset;
    uint flags;
    vec2 inv_texel; // 1 / texel, rounded on the CPU: texel coordinates are products

    GpuLevel levels[GPU_MAX_LEVELS];
    GpuQuadLevel quad[GPU_MAX_QUAD_LEVELS];
};

layout(std430, set = 0, binding = 0) readonly buffer ModelBlock { GpuModelHeader model; };
layout(std430, set = 0, binding = 1) readonly buffer FloatBlock { float model_floats[]; };
layout(std430, set = 0, binding = 2) readonly buffer HeaderBlock { uvec4 brdf_headers[]; };
layout(std430, set = 0, binding = 3) readonly buffer LobeBlock { uvec4 brdf_lobes[]; };
layout(std430, set = 0, binding = 4) readonly buffer TexelBlock { uvec2 clustered_texels[]; };
layout(std430, set = 0, binding = 5) readonly buffer HeadBlock { uint fly_heads[]; };
layout(std430, set = 0, binding = 6) readonly buffer NodeBlock { uvec4 fly_nodes[]; };

// Word w of binding 6: the flyaway spread records follow the nodes, three words per node
// (the record's two, then its axis group's; format 1.8).
uint fly_spread_word(uint w) {
    return fly_nodes[w >> 2][w & 3u];
}
// PackedTransmission records of every BSDF level, 24 bytes = 3 uvec2 each (format 1.3;
// one zero record when none).
layout(std430, set = 0, binding = 12) readonly buffer TransBlock { uvec2 transmissions[]; };
// PackedViewTilt records of every coarse level that has them, 12 bytes = 3 uints each
// (format 1.4), then PackedGradient records of every level that has them, 2 uints each
// (format 1.12; one zero record when neither).
layout(std430, set = 0, binding = 13) readonly buffer TiltBlock { uint view_tilts[]; };

// i mod n in [0, n) for n > 0 (Rust's rem_euclid); GLSL's % is undefined for negative
// operands, so only non-negative ones reach it.
int wrap_index(int i, int n) {
    if (i < 0) {
        i += n * ((n - 1 - i) / n);
    }
    return i % n;
}

bool model_periodic() {
    return (model.flags & GPU_FLAG_PERIODIC) != 0u;
}

// Cell (i, j) of an n-sized grid over the tile: wrapped on a periodic tile, clamped to
// the edge on a clamped one (every lookup of the model uses this rule).
ivec2 tile_index(int i, int j, ivec2 n) {
    if (model_periodic()) {
        return ivec2(wrap_index(i, n.x), wrap_index(j, n.y));
    }
    return ivec2(clamp(i, 0, n.x - 1), clamp(j, 0, n.y - 1));
}

uint model_reading() {
    if ((model.flags & GPU_FLAG_READING_HELD) != 0u) {
        return CLOTH_READING_HELD;
    }
    return (model.flags & GPU_FLAG_READING_WIDTH) != 0u ? CLOTH_READING_WIDTH : CLOTH_READING_BOUNDED;
}

// Whether the flyaways' lobes follow the cylinder law (format 1.11).
bool model_fiber_cylinder() {
    return (model.flags & GPU_FLAG_FIBER_CYLINDER) != 0u;
}

// The surface texels' diffuse law (flyaways: always CLOTH_DIFFUSE_LAMBERT).
uint model_diffuse() {
    return (model.flags & GPU_FLAG_DIFFUSE_LS) != 0u ? CLOTH_DIFFUSE_LOMMEL_SEELIGER : CLOTH_DIFFUSE_LAMBERT;
}

// GpuTransmission record `index` (runtime/src/hybrid/gpu_layout.rs): the file's
// PackedTransmission (runtime/src/hybrid/lobe.rs), then its PackedTransmissionVisibility
// (format 1.16; zero without one) and a pad word.
ClothTransmission packed_transmission(uint index) {
    uvec2 a = transmissions[6u * index];
    uvec2 b = transmissions[6u * index + 1u];
    uvec2 c = transmissions[6u * index + 2u];
    uvec2 d = transmissions[6u * index + 3u];
    uvec2 e = transmissions[6u * index + 4u];
    uvec2 q = transmissions[6u * index + 5u];
    ClothTransmission t;
    t.kd = vec3(f16_value(a.x), f16_value(a.x >> 16), f16_value(a.y));
    t.lobe.k = vec3(f16_value(a.y >> 16), f16_value(b.x), f16_value(b.x >> 16));
    t.lobe.beta = f16_value(b.y);
    t.lobe.gamma = f16_value(b.y >> 16);
    t.tau = f16_value(c.x);
    t.gap.o = f16_value(c.x >> 16);
    t.gap.q = f16_value(c.y);
    t.gap.aniso = vec2(snorm8_value(c.y, 2u), snorm8_value(c.y, 3u));
    t.grad = vec4(f16_value(d.x), f16_value(d.x >> 16), f16_value(d.y), f16_value(d.y >> 16));
    t.q0 = vec3(f16_value(e.x), f16_value(e.x >> 16), f16_value(e.y));
    t.q1 = vec3(f16_value(e.y >> 16), f16_value(q.x), f16_value(q.x >> 16));
    return t;
}

ClothLobe packed_lobe(uvec4 l) {
    ClothLobe lobe;
    lobe.k = vec3(f16_value(l.y >> 16), f16_value(l.z), f16_value(l.z >> 16));
    lobe.beta = f16_value(l.w);
    lobe.gamma = f16_value(l.w >> 16);
    return lobe;
}

// A texel's BRDF by reference, decoded as it is evaluated (a GPU keeps no 8-lobe
// arrays in registers): its header (absolute index), where its table's lobes start,
// and whether each lobe has its own frame (per-texel tables) or all use `frame`
// (clustered texels; flyaways, in their fiber frame). The CPU twin decodes first
// (TexelBrdf of runtime/src/hybrid/lobe.rs, Level::texel_brdf); the values are equal.
struct TexelRef {
    uint header;
    uint lobe_base;
    bool framed;
    ClothFrame frame;
    uint trans;         // its transmission record, NO_NODE: none (BRDF levels, flyaways)
    // Per-texel frames are turned from tilt_n0 to tilt_nv as they are decoded (the
    // view tilt; clustered frames are turned in place): Scene::bilinear_texels_seen.
    bool tilted;
    vec3 tilt_n0;
    vec3 tilt_nv;
    // A flyaway whose lobes follow the cylinder law (cloth_cylinder_lobe; in_fiber_frame).
    bool cylinder;
    uint grad;          // its visibility gradient's first word in binding 13, NO_NODE: none
    uint curv;          // its visibility curvature's first word in binding 13, NO_NODE: none
};

// Texel (i, j) of `level` (in range). Twin: Level::texel_brdf.
TexelRef texel_brdf(uint level, uint i, uint j) {
    GpuLevel l = model.levels[level];
    uint index = j * l.dims.x + i;
    TexelRef r;
    r.lobe_base = l.lobe_base;
    r.trans = l.trans_base == NO_NODE ? NO_NODE : l.trans_base + index;
    r.grad = l.grad_base == NO_NODE ? NO_NODE : l.grad_base + 2u * index;
    r.curv = l.curv_base == NO_NODE ? NO_NODE : l.curv_base + 3u * index;
    if (l.surface == GPU_SURFACE_CLUSTERED) {
        uvec2 t = clustered_texels[l.texel_base + index];
        r.header = l.header_base + (t.y >> 16);
        r.framed = false;
        r.frame = decode_frame(t.x, t.y & 0xffffu);
    } else {
        r.header = l.header_base + index;
        r.framed = true;
        r.frame = ClothFrame(vec3(0.0, 0.0, 1.0), vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0));
    }
    r.tilted = false;
    r.tilt_n0 = vec3(0.0, 0.0, 1.0);
    r.tilt_nv = vec3(0.0, 0.0, 1.0);
    r.cylinder = false;
    return r;
}

// Texel r's visibility gradient g = (g_o.x, g_o.y, g_i.x, g_i.y) (PackedGradient of
// runtime/src/hybrid/lobe.rs; Level::texel_brdf); zero where its level has none.
vec4 texel_gradient(TexelRef r) {
    if (r.grad == NO_NODE) {
        return vec4(0.0);
    }
    uint a = view_tilts[r.grad];
    uint b = view_tilts[r.grad + 1u];
    return vec4(f16_value(a), f16_value(a >> 16), f16_value(b), f16_value(b >> 16));
}

// Texel r's visibility curvature q (PackedCurvature of runtime/src/hybrid/lobe.rs;
// Level::texel_brdf) as q0 = q[0..3], q1 = q[3..6]; zero where its level has none.
void texel_curvature(TexelRef r, out vec3 q0, out vec3 q1) {
    if (r.curv == NO_NODE) {
        q0 = vec3(0.0);
        q1 = vec3(0.0);
        return;
    }
    uint a = view_tilts[r.curv];
    uint b = view_tilts[r.curv + 1u];
    uint c = view_tilts[r.curv + 2u];
    q0 = vec3(f16_value(a), f16_value(a >> 16), f16_value(b));
    q1 = vec3(f16_value(b >> 16), f16_value(c), f16_value(c >> 16));
}

// PackedViewTilt record `index` (runtime/src/hybrid/lobe.rs).
ViewTilt packed_view_tilt(uint index) {
    uint a = view_tilts[3u * index];
    uint b = view_tilts[3u * index + 1u];
    uint c = view_tilts[3u * index + 2u];
    ViewTilt t;
    t.b = vec4(f16_value(a), f16_value(a >> 16), f16_value(b), f16_value(b >> 16));
    t.c = vec2(f16_value(c), f16_value(c >> 16));
    return t;
}

// A frame as texel r shows it: turned by its view tilt.
ClothFrame tilted_frame(TexelRef r, ClothFrame f) {
    if (r.tilted) {
        f.n = rotate_arc(r.tilt_n0, r.tilt_nv, f.n);
        f.t = rotate_arc(r.tilt_n0, r.tilt_nv, f.t);
        f.b = rotate_arc(r.tilt_n0, r.tilt_nv, f.b);
    }
    return f;
}

// Texel (i, j) of `level` seen from wo: its frames turned by its view tilt where the
// level has one; returns its visibility v(wo) (1 without). Twin:
// Scene::bilinear_texels_seen (runtime/src/cpu/render.rs).
float seen_from(inout TexelRef r, uint level, uvec2 ij, vec3 wo) {
    GpuLevel l = model.levels[level];
    if (l.tilt_base == NO_NODE) {
        return 1.0;
    }
    ViewTilt t = packed_view_tilt(l.tilt_base + ij.y * l.dims.x + ij.x);
    vec3 n0 = r.frame.n;
    if (r.framed) {
        uvec4 h = brdf_headers[r.header];
        n0 = octahedral_decode(brdf_lobes[r.lobe_base + h.w].x);
    }
    vec3 nv = visible_normal(n0, t.b, wo);
    if (nv != n0) {
        if (r.framed) {
            r.tilted = true;
            r.tilt_n0 = n0;
            r.tilt_nv = nv;
        } else {
            r.frame.n = rotate_arc(n0, nv, r.frame.n);
            r.frame.t = rotate_arc(n0, nv, r.frame.t);
            r.frame.b = rotate_arc(n0, nv, r.frame.b);
        }
    }
    return view_visibility(t, wo);
}

// The level-`level` texel under world point p (wrapped or clamped into the tile).
// Twin: Scene::texel_at (runtime/src/cpu/render.rs).
// `precise` (no fused multiply–add) and the product with inv_texel keep the texel
// line where the CPU draws it: the choice of texel is exact in both twins.
uvec2 texel_at(vec3 p, uint level) {
    precise vec2 u = (p.xy - model.origin) * model.inv_texel;
    ivec2 ij = tile_index(int(floor(u.x)), int(floor(u.y)), model.n);
    return uvec2(uint(ij.x) >> level, uint(ij.y) >> level);
}

// Corner c (0: (0,0), 1: (1,0), 2: (0,1), 3: (1,1)) of the four level-`level` texels
// around p: its texel and bilinear weight (texel centres at +1/2; wrapped or clamped).
// Twin: Scene::bilinear_texels, one corner at a time.
float bilinear_texel(vec3 p, uint level, int c, out uvec2 ij) {
    GpuLevel l = model.levels[level];
    ivec2 dims = ivec2(l.dims);
    precise vec2 x = (p.xy - model.origin) * model.inv_texel;
    // A periodic tile whose size 2^level does not divide: into the first repeat (the
    // level's grid is longer than the tile; see the twin).
    int span = 1 << level;
    if (model_periodic()) {
        for (int a = 0; a < 2; ++a) {
            if (model.n[a] % span != 0) {
                precise float k = floor(x[a] / float(model.n[a]));
                x[a] -= float(model.n[a]) * k;
            }
        }
    }
    precise vec2 u = ldexp(x, ivec2(-int(level))) - vec2(0.5);
    vec2 f0 = floor(u);
    precise float fx = u.x - f0.x;
    precise float fy = u.y - f0.y;
    ij = uvec2(tile_index(int(f0.x) + (c & 1), int(f0.y) + (c >> 1), dims));
    float wx = (c & 1) != 0 ? fx : 1.0 - fx;
    float wy = (c >> 1) != 0 ? fy : 1.0 - fy;
    return wx * wy;
}

#endif // MODEL_GLSL
