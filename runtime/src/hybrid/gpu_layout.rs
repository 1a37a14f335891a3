//! The hybrid model as the GPU sees it: plain-data arrays in std430, uploaded as they
//! are (runtime/HYBRID_FORMAT.md §"Records" for the packed records; DESIGN.md §7).
//!
//! GLSL twin: `shaders/common/model.glsl` declares the same structs with the same
//! members in the same order; `runtime/tests/gpu_layout.rs` reads the member offsets
//! out of the compiled SPIR-V and compares them with these (`offset_of!`).
//!
//! | binding | array                | element                                   |
//! |---------|----------------------|-------------------------------------------|
//! | 0       | [`GpuModelHeader`]    | tile, flags, per level where its data is  |
//! | 1       | `floats`             | height samples, then the min-depth quadtree |
//! | 2       | `headers`            | [`BrdfHeader`] of every table, concatenated |
//! | 3       | `lobes`              | [`PackedLobe`] of every table              |
//! | 4       | `texels`             | [`ClusteredTexel`] of every clustered level |
//! | 5       | `fly_heads`          | list heads (level-local node indices)      |
//! | 6       | `fly_nodes`          | [`FlyawayNode`] (level-local `next`, `param`), then `fly_spread_words`: per node of every level with spread records, its [`PackedAxisSpread`] (two 4-byte words) and its [`PackedAxisGroup`] (one word, zero without one): three words per node (`GpuLevel::spread_base`) |
//! | 12      | `transmissions`      | [`GpuTransmission`] of every BSDF level: the file's [`PackedTransmission`] and its [`PackedTransmissionVisibility`] (format 1.16; zero where the level has none), 48 bytes (one zero record when none) |
//! | 13      | `view_tilts`         | [`PackedViewTilt`] of every coarse level that has them (one zero record when none) |
//!
//! Indices stored in the records stay as the file has them (local to their table or
//! level); a level's `*_base` is added when they are followed. The height samples and
//! the quadtree are the CPU renderer's own ([`HeightTracer`]): both renderers march the
//! same numbers.

use bytemuck::{Pod, Zeroable};

use super::flyaway::{FlyawayNode, PackedAxisGroup, PackedAxisSpread};
use super::lobe::{BrdfHeader, ClusteredTexel, PackedLobe, PackedTransmission, PackedTransmissionVisibility, PackedViewTilt};
use super::model::{HybridModel, Surface};
use super::ModelError;
use crate::cpu::heightfield::HeightTracer;

/// Most levels a model has (a 32768² level 0: 16).
pub const GPU_MAX_LEVELS: usize = 16;
/// Most quadtree levels (32769 leaves per axis on a clamped 32768² tile: 17).
pub const GPU_MAX_QUAD_LEVELS: usize = 18;

/// [`GpuModelHeader::flags`]: the tile repeats in x and y.
pub const GPU_FLAG_PERIODIC: u32 = 1;
/// Surface hits carry the volumetric factor ([`crate::cpu::shading::volume_factor`]).
pub const GPU_FLAG_VOLUMETRIC: u32 = 2;
/// Coarse levels carry the light's visibility (no shadow rays at levels ≥ 1).
pub const GPU_FLAG_COARSE_VISIBILITY: u32 = 4;
/// The BRDFs use the width reading of Eqs. 2–3 ([`crate::brdf::BrdfReading::Width`]).
pub const GPU_FLAG_READING_WIDTH: u32 = 8;
/// Surface texels' diffuse term follows the Lommel–Seeliger law
/// ([`crate::brdf::DiffuseLaw::LommelSeeliger`]).
pub const GPU_FLAG_DIFFUSE_LS: u32 = 16;
/// Flyaways' lobes follow the cylinder law ([`crate::brdf::FiberLobes::Cylinder`]).
pub const GPU_FLAG_FIBER_CYLINDER: u32 = 32;
/// The flyaways in front of a surface hit shadow its lights
/// ([`crate::hybrid::BakeMetadata::flyaway_shadow`]).
pub const GPU_FLAG_FLYAWAY_SHADOW: u32 = 64;
/// The BRDFs use the held reading ([`crate::brdf::BrdfReading::Held`], format 1.14).
pub const GPU_FLAG_READING_HELD: u32 = 128;

/// [`GpuLevel::surface`]: per texel a frame and a cluster index.
pub const GPU_SURFACE_CLUSTERED: u32 = 0;
/// [`GpuLevel::surface`]: per texel a header whose lobes have their own frames.
pub const GPU_SURFACE_PER_TEXEL: u32 = 1;

/// Where one level's data sits in the arrays. 112 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuLevel {
    /// Texels in x and y.
    pub dims: [u32; 2],
    /// [`GPU_SURFACE_CLUSTERED`] or [`GPU_SURFACE_PER_TEXEL`].
    pub surface: u32,
    /// First clustered texel of this level (clustered levels).
    pub texel_base: u32,
    /// First header of the surface table (clusters, or one per texel).
    pub header_base: u32,
    /// First lobe of the surface table.
    pub lobe_base: u32,
    /// Flyaway nodes of this level (0: none; the march is skipped).
    pub fly_nodes: u32,
    pub fly_head_base: u32,
    pub fly_node_base: u32,
    pub fly_header_base: u32,
    pub fly_lobe_base: u32,
    /// Voxel depth s_ℓ (world).
    pub voxel_depth: f32,
    /// Edge in the opacity exponent, (Δx_ℓ·Δy_ℓ·s_ℓ)^(1/3) (`cpu::flyaways::FlyawayGrid`).
    pub fly_edge: f32,
    /// First transmission record of this level in `transmissions` (binding 12), or
    /// [`crate::hybrid::NO_NODE`] where the level has none.
    pub trans_base: u32,
    /// First view tilt record of this level in `view_tilts` (binding 13), or
    /// [`crate::hybrid::NO_NODE`] where the level has none.
    pub tilt_base: u32,
    /// First spread record of this level's flyaway nodes (three 4-byte words each: the
    /// record's two, then its axis group's), as a word index into binding 6 (the records follow all levels' nodes), or [`crate::hybrid::NO_NODE`]
    /// where the level has none.
    pub spread_base: u32,
    /// The flyaways' gain on the opacity exponent at polar 0°, 10°, … 80° (format 1.9;
    /// all 1 where the level has none: [`crate::hybrid::PathGain`]).
    pub fly_gain: [f32; crate::hybrid::PATH_GAIN_NODES],
    /// First word of this level's visibility gradient records (two words each, f16
    /// pairs) in binding 13, after the view tilt records, or [`crate::hybrid::NO_NODE`]
    /// where the level has none (format 1.12).
    pub grad_base: u32,
    /// First word of this level's visibility curvature records (three words each, f16
    /// pairs) in binding 13, after the gradient records, or [`crate::hybrid::NO_NODE`]
    /// where the level has none (format 1.15).
    pub curv_base: u32,
    /// std430 rounds the struct to 8 bytes (its `dims`).
    pub pad: u32,
}

/// One level of the min-depth quadtree. 16 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct GpuQuadLevel {
    /// Cells in x and y.
    pub dims: [i32; 2],
    /// First cell in `floats`.
    pub offset: u32,
    pub pad: u32,
}

/// The model's header: the tile, the flags, and where each level is. 2144 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct GpuModelHeader {
    pub origin: [f32; 2],
    pub size: [f32; 2],
    /// Level-0 texel size (world).
    pub texel: [f32; 2],
    /// Level-0 texels (= height samples) per axis.
    pub n: [i32; 2],
    pub top_z: f32,
    pub height_scale: f32,
    pub level_count: u32,
    pub quad_count: u32,
    /// Leaf-space shift of the height-field march: 1 clamped, 0 periodic.
    pub leaf_offset: i32,
    /// `GPU_FLAG_*`.
    pub flags: u32,
    /// 1 / `texel`, rounded on the CPU (`HybridModel::inv_texel_size`).
    pub inv_texel: [f32; 2],
    pub levels: [GpuLevel; GPU_MAX_LEVELS],
    pub quad: [GpuQuadLevel; GPU_MAX_QUAD_LEVELS],
}

const _: () = assert!(size_of::<GpuLevel>() == 112);
const _: () = assert!(size_of::<GpuQuadLevel>() == 16);
const _: () = assert!(size_of::<GpuModelHeader>() == 2144);

/// A model laid out for the GPU: every array as it is uploaded.
#[derive(Clone, Debug)]
pub struct GpuModel {
    pub header: GpuModelHeader,
    pub floats: Vec<f32>,
    pub headers: Vec<BrdfHeader>,
    pub lobes: Vec<PackedLobe>,
    pub texels: Vec<ClusteredTexel>,
    pub fly_heads: Vec<u32>,
    pub fly_nodes: Vec<FlyawayNode>,
    /// Per node of every level with spread records, in level order: its spread record
    /// (two words) and its second axis group (one word, zero where it has none; format
    /// 1.8), uploaded after `fly_nodes` in binding 6.
    pub fly_spread_words: Vec<u32>,
    pub transmissions: Vec<GpuTransmission>,
    pub view_tilts: Vec<PackedViewTilt>,
    /// Every level's visibility gradient records as words (two each), then its curvature
    /// records (three each, format 1.15), uploaded after
    /// `view_tilts` in binding 13 (format 1.12).
    pub gradient_words: Vec<u32>,
}

impl GpuModel {
    /// Lays out a (validated) model for a clamped or a `periodic` tile.
    pub fn new(model: &HybridModel, periodic: bool) -> Result<GpuModel, ModelError> {
        model.validate()?;
        if model.levels.len() > GPU_MAX_LEVELS {
            return Err(ModelError::Meta(format!("{} levels; the GPU layout holds {GPU_MAX_LEVELS}", model.levels.len())));
        }
        let tracer = HeightTracer::new(model, periodic);
        let mut floats: Vec<f32> = tracer.samples().to_vec();
        let mut quad = [GpuQuadLevel::default(); GPU_MAX_QUAD_LEVELS];
        let mut quad_count = 0;
        for (k, (dims, cells)) in tracer.quadtree().enumerate() {
            if k >= GPU_MAX_QUAD_LEVELS {
                return Err(ModelError::Meta(format!("the height field's quadtree has more than {GPU_MAX_QUAD_LEVELS} levels")));
            }
            quad[k] = GpuQuadLevel { dims, offset: floats.len() as u32, pad: 0 };
            floats.extend_from_slice(cells);
            quad_count = k + 1;
        }
        let t = &model.tile;
        let texel = model.texel_size();
        let m = &model.meta;
        let flags = if periodic { GPU_FLAG_PERIODIC } else { 0 }
            | if m.volumetric { GPU_FLAG_VOLUMETRIC } else { 0 }
            | if m.coarse_visibility { GPU_FLAG_COARSE_VISIBILITY } else { 0 }
            | if m.reading == crate::brdf::BrdfReading::Width { GPU_FLAG_READING_WIDTH } else { 0 }
            | if m.reading == crate::brdf::BrdfReading::Held { GPU_FLAG_READING_HELD } else { 0 }
            | if m.diffuse == crate::brdf::DiffuseLaw::LommelSeeliger { GPU_FLAG_DIFFUSE_LS } else { 0 }
            | if m.fiber_lobes == crate::brdf::FiberLobes::Cylinder { GPU_FLAG_FIBER_CYLINDER } else { 0 }
            | if m.flyaway_shadow { GPU_FLAG_FLYAWAY_SHADOW } else { 0 };
        let mut out = GpuModel {
            header: GpuModelHeader {
                origin: t.origin.to_array(),
                size: t.size.to_array(),
                texel: texel.to_array(),
                n: [model.width() as i32, model.height_px() as i32],
                top_z: t.top_z,
                height_scale: t.height_scale,
                level_count: model.levels.len() as u32,
                quad_count: quad_count as u32,
                leaf_offset: tracer.leaf_offset(),
                flags,
                inv_texel: model.inv_texel_size().to_array(),
                levels: [GpuLevel::default(); GPU_MAX_LEVELS],
                quad,
            },
            floats,
            headers: Vec::new(),
            lobes: Vec::new(),
            texels: Vec::new(),
            fly_heads: Vec::new(),
            fly_nodes: Vec::new(),
            fly_spread_words: Vec::new(),
            transmissions: Vec::new(),
            view_tilts: Vec::new(),
            gradient_words: Vec::new(),
        };
        for (k, l) in model.levels.iter().enumerate() {
            let gain = l.flyaways.as_ref().and_then(|f| f.path_gain).unwrap_or(crate::hybrid::PathGain::ONE);
            let mut g = GpuLevel { dims: [l.width, l.height], header_base: out.headers.len() as u32, lobe_base: out.lobes.len() as u32, fly_gain: gain.0, ..Default::default() };
            match &l.surface {
                Surface::Clustered { texels, table } => {
                    g.surface = GPU_SURFACE_CLUSTERED;
                    g.texel_base = out.texels.len() as u32;
                    out.texels.extend_from_slice(texels);
                    out.headers.extend_from_slice(&table.headers);
                    out.lobes.extend_from_slice(&table.lobes);
                }
                Surface::PerTexel(table) => {
                    g.surface = GPU_SURFACE_PER_TEXEL;
                    out.headers.extend_from_slice(&table.headers);
                    out.lobes.extend_from_slice(&table.lobes);
                }
            }
            let span = (1u64 << k) as f32;
            g.voxel_depth = model.voxel_depth(k);
            g.fly_edge = (texel.x * texel.y * (span * span) * g.voxel_depth).cbrt();
            if let Some(f) = l.flyaways.as_ref().filter(|f| !f.nodes.is_empty()) {
                g.fly_nodes = f.nodes.len() as u32;
                g.fly_head_base = out.fly_heads.len() as u32;
                g.fly_node_base = out.fly_nodes.len() as u32;
                g.fly_header_base = out.headers.len() as u32;
                g.fly_lobe_base = out.lobes.len() as u32;
                out.fly_heads.extend_from_slice(&f.heads);
                out.fly_nodes.extend_from_slice(&f.nodes);
                out.headers.extend_from_slice(&f.table.headers);
                out.lobes.extend_from_slice(&f.table.lobes);
            }
            // Made absolute once all nodes are laid out (they come first in binding 6).
            g.spread_base = match l.flyaways.as_ref().and_then(|f| f.spreads.as_ref()).filter(|s| !s.is_empty()) {
                Some(s) => {
                    let base = out.fly_spread_words.len() as u32;
                    let groups = l.flyaways.as_ref().and_then(|f| f.groups.as_ref());
                    for (k, record) in s.iter().enumerate() {
                        out.fly_spread_words.extend_from_slice(&bytemuck::cast::<PackedAxisSpread, [u32; 2]>(*record));
                        let group = groups.and_then(|g| g.get(k)).copied().unwrap_or(PackedAxisGroup::NONE);
                        out.fly_spread_words.push(bytemuck::cast(group));
                    }
                    base
                }
                None => crate::hybrid::NO_NODE,
            };
            g.trans_base = match &l.transmission {
                Some(t) => {
                    let vis = |k: usize| l.transmission_visibility.as_ref().map_or(PackedTransmissionVisibility::default(), |v| v[k]);
                    out.transmissions.extend(t.iter().enumerate().map(|(k, &record)| GpuTransmission { record, vis: vis(k), pad: 0 }));
                    (out.transmissions.len() - t.len()) as u32
                }
                None => crate::hybrid::NO_NODE,
            };
            g.tilt_base = match &l.view_tilt {
                Some(t) => {
                    out.view_tilts.extend_from_slice(t);
                    (out.view_tilts.len() - t.len()) as u32
                }
                None => crate::hybrid::NO_NODE,
            };
            // Made absolute once all view tilts are laid out (they come first in binding 13).
            g.grad_base = match &l.gradient {
                Some(r) => {
                    out.gradient_words.extend_from_slice(bytemuck::cast_slice(r));
                    (out.gradient_words.len() - 2 * r.len()) as u32
                }
                None => crate::hybrid::NO_NODE,
            };
            g.curv_base = match &l.curvature {
                Some(r) => {
                    out.gradient_words.extend_from_slice(bytemuck::cast_slice(r));
                    (out.gradient_words.len() - 3 * r.len()) as u32
                }
                None => crate::hybrid::NO_NODE,
            };
            out.header.levels[k] = g;
        }
        let tilt_words = 3 * out.view_tilts.len() as u64;
        if tilt_words + out.gradient_words.len() as u64 >= u32::MAX as u64 {
            return Err(ModelError::Meta("view tilt and visibility gradient records: more words than the GPU layout's 32-bit indices reach".into()));
        }
        for g in out.header.levels.iter_mut().take(model.levels.len()) {
            for base in [&mut g.grad_base, &mut g.curv_base] {
                if *base != crate::hybrid::NO_NODE {
                    *base += tilt_words as u32;
                }
            }
        }
        let node_words = 4 * out.fly_nodes.len() as u64;
        // The shaders index binding 6 by 32-bit word, NO_NODE excluded.
        if node_words + out.fly_spread_words.len() as u64 >= u32::MAX as u64 {
            return Err(ModelError::Meta("flyaway nodes and spread records: more words than the GPU layout's 32-bit indices reach".into()));
        }
        for g in out.header.levels.iter_mut().take(model.levels.len()).filter(|g| g.spread_base != crate::hybrid::NO_NODE) {
            g.spread_base = u32::try_from(node_words + g.spread_base as u64).map_err(|_| ModelError::Meta("flyaway spread records: more than the GPU layout's 32-bit indices reach".into()))?;
        }
        for (what, len) in [("BRDF headers", out.headers.len()), ("lobes", out.lobes.len()), ("texels", out.texels.len()), ("flyaway nodes", out.fly_nodes.len() + out.fly_spread_words.len().div_ceil(4)), ("floats", out.floats.len()), ("transmission records", out.transmissions.len()), ("view tilt records", out.view_tilts.len())] {
            if len >= u32::MAX as usize {
                return Err(ModelError::Meta(format!("{len} {what}: more than the GPU layout's 32-bit indices reach")));
            }
        }
        Ok(out)
    }

    /// The arrays as (name, bytes), in binding order 0..=6. Empty arrays are one zero
    /// element long (Vulkan buffers cannot be empty; nothing indexes them then).
    pub fn arrays(&self) -> [(&'static str, Vec<u8>); 7] {
        [
            ("model header", bytemuck::bytes_of(&self.header).to_vec()),
            ("model floats", bytes(&self.floats, 4)),
            ("BRDF headers", bytes(&self.headers, 16)),
            ("BRDF lobes", bytes(&self.lobes, 16)),
            ("clustered texels", bytes(&self.texels, 8)),
            ("flyaway heads", bytes(&self.fly_heads, 4)),
            ("flyaway nodes", self.node_array()),
        ]
    }

    /// Binding 6: the nodes, then the spread records padded to whole 16-byte elements.
    fn node_array(&self) -> Vec<u8> {
        let mut b = bytes(&self.fly_nodes, 16);
        if !self.fly_spread_words.is_empty() {
            b.truncate(self.fly_nodes.len() * 16);
            b.extend_from_slice(bytemuck::cast_slice(&self.fly_spread_words));
            b.resize(b.len().div_ceil(16) * 16, 0);
        }
        b
    }

    /// Binding 12: the transmission records of every BSDF level (one zero record when
    /// the model has none).
    pub fn transmission_array(&self) -> (&'static str, Vec<u8>) {
        ("transmission records", bytes(&self.transmissions, 48))
    }

    /// Binding 13: the view tilt records of every coarse level that has them, then the
    /// visibility gradient and curvature words of every level that has them (one zero record when
    /// neither).
    pub fn view_tilt_array(&self) -> (&'static str, Vec<u8>) {
        let mut b = bytemuck::cast_slice(&self.view_tilts).to_vec();
        b.extend_from_slice(bytemuck::cast_slice(&self.gradient_words));
        if b.is_empty() {
            b = vec![0; 12];
        }
        ("view tilt and visibility gradient records", b)
    }

    /// Total bytes uploaded.
    pub fn byte_size(&self) -> u64 {
        self.arrays().iter().map(|(_, b)| b.len() as u64).sum::<u64>() + self.transmission_array().1.len() as u64 + self.view_tilt_array().1.len() as u64
    }
}

/// `v` as bytes, at least `min` of them (zeros: Vulkan buffers cannot be empty).
fn bytes<T: Pod>(v: &[T], min: usize) -> Vec<u8> {
    let mut b = bytemuck::cast_slice(v).to_vec();
    if b.is_empty() {
        b.resize(min, 0);
    }
    b
}

/// A transmission record as binding 12 holds it: the file's record, the texel's
/// transmission visibility (format 1.16; zero without one) and a pad word, six `uvec2`
/// in GLSL (`packed_transmission` in shaders/common/model.glsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct GpuTransmission {
    pub record: PackedTransmission,
    pub vis: PackedTransmissionVisibility,
    pub pad: u32,
}

const _: () = assert!(core::mem::size_of::<GpuTransmission>() == 48);

/// Most lights one frame is drawn with.
pub const GPU_MAX_LIGHTS: usize = 8;

/// [`GpuRenderParams::level_mode`].
pub const LEVEL_AUTO: u32 = 0;
pub const LEVEL_NEAREST: u32 = 1;
pub const LEVEL_FIXED: u32 = 2;

/// `Camera::ray`'s inputs, its frame precomputed. 80 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuCamera {
    /// w: 1 perspective, 0 orthographic.
    pub origin: [f32; 4],
    pub forward: [f32; 4],
    pub right: [f32; 4],
    pub up: [f32; 4],
    pub half_extents: [f32; 2],
    pub size: [u32; 2],
}

impl GpuCamera {
    pub fn new(c: &crate::scene::Camera) -> GpuCamera {
        let f = c.frame();
        let w = match c.projection {
            crate::scene::Projection::Perspective { .. } => 1.0,
            crate::scene::Projection::Orthographic { .. } => 0.0,
        };
        GpuCamera {
            origin: c.origin.extend(w).to_array(),
            forward: f.forward.extend(0.0).to_array(),
            right: f.right.extend(0.0).to_array(),
            up: f.up.extend(0.0).to_array(),
            half_extents: c.half_extents().to_array(),
            size: [c.width, c.height],
        }
    }
}

/// One light (`shaders/common/lights.glsl`): `vec.w` 0 directional (xyz toward the
/// light), 1 point (xyz its position). 32 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuLight {
    pub vec: [f32; 4],
    pub power: [f32; 4],
}

impl GpuLight {
    pub fn new(l: &crate::scene::Light) -> GpuLight {
        match *l {
            crate::scene::Light::Directional { dir_to_light, irradiance } => GpuLight { vec: dir_to_light.extend(0.0).to_array(), power: irradiance.extend(0.0).to_array() },
            crate::scene::Light::Point { position, intensity } => GpuLight { vec: position.extend(1.0).to_array(), power: intensity.extend(0.0).to_array() },
        }
    }
}

/// One frame's camera, lights, options and edits (binding 7; the edit mask is binding 8,
/// one f32 per mask pixel as `cpu::EditMask` stores them; the environment's texels are
/// binding 11). 736 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct GpuRenderParams {
    pub camera: GpuCamera,
    pub background: [f32; 4],
    pub light_count: u32,
    pub max_steps: u32,
    pub max_flyaway_columns: u32,
    pub supersampling: u32,
    /// `LEVEL_*`.
    pub level_mode: u32,
    pub fixed_level: u32,
    pub level_bias: f32,
    /// 1: march the height field only down to the pixel's level (`coarse_relief`).
    pub coarse_relief: u32,
    /// Edits (`cpu::edits`): tint (rgb), then the width scale, the tangent rotation
    /// (radians) and the mask's size (0×0: no mask, edits everywhere).
    pub edit_tint: [f32; 4],
    pub edit_roughness: f32,
    pub edit_rotation: f32,
    pub mask_dims: [u32; 2],
    pub lights: [GpuLight; GPU_MAX_LIGHTS],
    /// Environment light (env_shading.glsl; [`GpuEnv`]): x the SG levels per chain (0:
    /// none), y 1 where rays that miss see the map, z 1 where the map lights transmission
    /// terms from below (`PrefilteredEnv::lights_below`; on a mesh always), w 1 on a mesh
    /// (diffuse terms read the whole sphere's irradiance).
    pub env_info: [u32; 4],
    /// cos and sin of the map's rotation, σ_0 of level 0.
    pub env_frame: [f32; 4],
    /// Per level (offset in texels of binding 11, width, height, 0): [0, 8) the chain
    /// above the horizon, [8, 16) the chain below it, [16] the irradiance of the half
    /// above, [17] the whole sphere's (`PrefilteredEnv`, "Two halves").
    pub env_levels: [[u32; 4]; GPU_ENV_SLOTS],
}

/// Most SG levels per chain.
pub const GPU_ENV_LEVELS: usize = 8;
/// Slots of `env_levels`: two chains of [`GPU_ENV_LEVELS`], then the two irradiance maps.
pub const GPU_ENV_SLOTS: usize = 2 * GPU_ENV_LEVELS + 2;

const _: () = assert!(size_of::<GpuCamera>() == 80);
const _: () = assert!(size_of::<GpuRenderParams>() == 736);

/// A prefiltered environment as binding 11 reads it: every level's texels (rgb, w = 0)
/// one after another (the chain above the horizon, the chain below), then the two
/// irradiance maps; where each starts and its size.
pub struct GpuEnv {
    pub texels: Vec<[f32; 4]>,
    pub info: [u32; 4],
    pub frame: [f32; 4],
    pub levels: [[u32; 4]; GPU_ENV_SLOTS],
}

impl GpuEnv {
    /// None: a chain has more levels than the shader's 8 slots (the prefilter makes at
    /// most 7).
    pub fn new(env: &crate::scene::PrefilteredEnv, background: bool) -> Option<GpuEnv> {
        if env.levels.len() > GPU_ENV_LEVELS || env.levels.is_empty() || env.levels_below.len() != env.levels.len() {
            return None;
        }
        let mut texels = Vec::new();
        let mut levels = [[0u32; 4]; GPU_ENV_SLOTS];
        let mut push = |slot: usize, l: &crate::scene::env_prefilter::EnvLevel| {
            levels[slot] = [texels.len() as u32, l.width, l.height, 0];
            texels.extend(l.texels.iter().map(|t| t.extend(0.0).to_array()));
        };
        for (k, (above, below)) in env.levels.iter().zip(&env.levels_below).enumerate() {
            push(k, above);
            push(GPU_ENV_LEVELS + k, below);
        }
        push(2 * GPU_ENV_LEVELS, &env.irradiance);
        push(2 * GPU_ENV_LEVELS + 1, &env.irradiance_full);
        let (sin, cos) = env.map.rotate_deg().to_radians().sin_cos();
        Some(GpuEnv { texels, info: [env.levels.len() as u32, background as u32, env.lights_below() as u32, 0], frame: [cos, sin, env.sigma0, 0.0], levels })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::{BrdfReading, HELD_RISE};

    #[test]
    fn the_flags_and_readings_are_the_shaders() {
        let model = include_str!("../../../shaders/common/model.glsl");
        let flags = [
            ("PERIODIC", GPU_FLAG_PERIODIC),
            ("VOLUMETRIC", GPU_FLAG_VOLUMETRIC),
            ("COARSE_VISIBILITY", GPU_FLAG_COARSE_VISIBILITY),
            ("READING_WIDTH", GPU_FLAG_READING_WIDTH),
            ("DIFFUSE_LS", GPU_FLAG_DIFFUSE_LS),
            ("FIBER_CYLINDER", GPU_FLAG_FIBER_CYLINDER),
            ("FLYAWAY_SHADOW", GPU_FLAG_FLYAWAY_SHADOW),
            ("READING_HELD", GPU_FLAG_READING_HELD),
        ];
        for (name, value) in flags {
            assert!(model.contains(&format!("#define GPU_FLAG_{name} {value}u\n")), "GPU_FLAG_{name} = {value} in model.glsl");
        }
        assert_eq!(flags.iter().fold(0, |acc, f| acc | f.1).count_ones() as usize, flags.len(), "one bit each");
        let brdf = include_str!("../../../shaders/brdf.glsl");
        for reading in [BrdfReading::Bounded, BrdfReading::Width, BrdfReading::Held] {
            let name = reading.name().to_uppercase();
            assert!(brdf.contains(&format!("#define CLOTH_READING_{name} {}u\n", reading as u32)), "CLOTH_READING_{name}");
        }
        assert!(brdf.contains(&format!("const float CLOTH_HELD_RISE = {HELD_RISE:.1};\n")));
    }
}
