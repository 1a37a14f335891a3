// render_params.glsl — what one frame of the hybrid renderer is drawn with: the camera,
// the lights, the options, and the variant's specialization constants.
//
// Twin: runtime/src/hybrid/gpu_layout.rs (GpuCamera, GpuLight, GpuRenderParams;
// bindings 7 and 8) and runtime/src/gpu/hybrid_pass.rs (the specialization constants).
// The environment's texels are binding 11 (env_shading.glsl).
#ifndef RENDER_PARAMS_GLSL
#define RENDER_PARAMS_GLSL

#define GPU_MAX_LIGHTS 8
#define LEVEL_AUTO 0u
#define LEVEL_NEAREST 1u
#define LEVEL_FIXED 2u

// Camera::ray's inputs, the frame precomputed by Camera::frame.
struct GpuCamera {
    vec4 origin;        // w: 1 perspective, 0 orthographic
    vec4 forward;
    vec4 right;
    vec4 up;
    vec2 half_extents;  // Camera::half_extents
    uvec2 size;         // width, height in pixels
};

// light_incident's inputs (lights.glsl): vec.w = 0 directional (xyz toward the light),
// 1 point (xyz its position); power: irradiance or intensity.
struct GpuLight {
    vec4 vec;
    vec4 power;
};

struct GpuRenderParams {
    GpuCamera camera;
    vec4 background;
    uint light_count;
    uint max_steps;
    uint max_flyaway_columns;
    uint supersampling;
    uint level_mode;    // LEVEL_*
    uint fixed_level;
    float level_bias;
    uint coarse_relief;   // 1: march the height field only down to the pixel's level
    vec4 edit_tint;       // rgb
    float edit_roughness;
    float edit_rotation;  // radians
    uvec2 mask_dims;      // 0 x 0: no mask
    GpuLight lights[GPU_MAX_LIGHTS];
    uvec4 env_info;       // x: SG levels per chain (0: no environment), y: 1 = rays that
                          // miss see it, z: 1 = it lights transmission terms from below,
                          // w: 1 = a mesh pass (diffuse reads the whole sphere's irradiance)
    vec4 env_frame;       // cos, sin of the map's rotation; sigma_0 of level 0
    uvec4 env_levels[18]; // offset into binding 11, width, height: [0, 8) the chain above
                          // the horizon, [8, 16) below it, [16] the irradiance of the half
                          // above, [17] of the whole sphere (GpuEnv)
};

layout(std430, set = 0, binding = 7) readonly buffer ParamBlock { GpuRenderParams params; };
// The edit mask: one value in [0, 1] per pixel, row 0 at the top (+y), x fastest.
layout(std430, set = 0, binding = 8) readonly buffer MaskBlock { float edit_mask[]; };

// The lights shading uses, in tile space: the program fills them (hybrid.comp copies
// params.lights; hybrid_mesh.comp maps each light into the tile's frame per pixel).
GpuLight g_lights[GPU_MAX_LIGHTS];

// Variants: what the scene does not need is compiled out, not branched over.
layout(constant_id = 0) const bool HAS_FLYAWAYS = true;  // any level has flyaway nodes
layout(constant_id = 1) const bool SHADOWS = true;       // height-field shadow rays
layout(constant_id = 2) const uint LIGHT_COUNT = 1u;     // lights[0 .. LIGHT_COUNT)
// false: a plain normal-mapped surface with the same BRDFs, for comparisons — the hit is
// where the ray enters the top plane (no height-field march, no parallax, no flyaways).
layout(constant_id = 3) const bool RELIEF = true;
// The most lobes any BRDF of the model has (1..8): the lobe loop's compiled bound.
layout(constant_id = 4) const uint LOBE_BOUND = 8u;
// Environment light (env_shading.glsl; programs that define HYBRID_ENV).
layout(constant_id = 5) const bool HAS_ENV = false;
// A light behind the sheet, or an environment map with light below the horizon, and a
// model with a transmission term (a BSDF, format 1.3): off, a frame with every light in
// front pays nothing for transmission.
layout(constant_id = 6) const bool TRANSMISSION = false;
// Lookups per axis of the coarse levels' box grid (level.glsl, box_grid; 1: one bilinear
// lookup per anisotropic tap). Twin: CoarseFilter::grid.
layout(constant_id = 7) const uint FILTER_GRID = 3u;
// Rays per axis of the flyaways' box grid (level.glsl, fly_box_grid; 1: one ray). Twin:
// CoarseFilter::fly_grid.
layout(constant_id = 8) const uint FLY_GRID = 2u;
// Rays per axis of the grid that gives the flyaways' coverage, marched unshaded, where it
// differs from FLY_GRID (the split filter's 4; level.glsl, LevelMix's cover_*). Twin:
// CoarseFilter::cover_grid.
layout(constant_id = 9) const uint FLY_COVER_GRID = 2u;
// Whether the coverage grid's rays are shaded too, with the lights (the split-shaded
// filter; the box grid's rays then shade an environment's SG part alone, or only land).
// Twin: CoarseFilter::cover_shaded.
layout(constant_id = 10) const bool FLY_COVER_SHADED = false;

#endif // RENDER_PARAMS_GLSL
