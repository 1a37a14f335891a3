//! The hybrid fabric model in memory: exactly what the file holds (the packed records
//! of [`super::lobe`] and [`super::flyaway`]), so that reading is a copy, writing is a
//! copy, the GPU uploads the same bytes, and the CPU renderer shades with the values the
//! GPU sees. Builders take f32 values; accessors decode.
//!
//! # Geometry (DESIGN.md §8)
//! The tile covers the source volume's x–y bounding box: `origin` = (x0, y0), `size`
//! its extent. Its top plane is z = `top_z` (the source bbox max z). Heights are stored
//! as **depth below the top plane**, as a unorm16 fraction of `height_scale` (world
//! units): world z of the surface = top_z − depth. Level-0 texel (i, j) covers
//! [x0 + i·Δx, x0 + (i+1)·Δx] × [y0 + j·Δy, y0 + (j+1)·Δy], Δ = size / (w, h); i along x,
//! j along y, x fastest (as the volume). The height samples sit at texel centres and the
//! surface between them is their bilinear interpolation (what a GPU's linear filter
//! gives), clamped at the tile's edges, or wrapped with `--periodic`.
//!
//! Level ℓ has ⌈w/2^ℓ⌉ × ⌈h/2^ℓ⌉ texels of size Δ·2^ℓ; its texel (i, j) covers level-0
//! texels [i·2^ℓ, (i+1)·2^ℓ) × [j·2^ℓ, (j+1)·2^ℓ). The height field is not filtered
//! across levels (paper §5.3.5): every level uses the one at level 0.

use glam::{Vec2, Vec3};

use super::error::{ModelError, TableKind};
use super::flyaway::Flyaways;
use super::lobe::{BrdfTable, ClusteredTexel, PackedCurvature, PackedGradient, PackedTransmission, PackedTransmissionVisibility, PackedViewTilt, TexelBrdf};
use super::packing::{unorm16, unorm16_value};
use crate::brdf::BrdfReading;
use crate::scene::Aabb;

/// Largest width or height of level 0.
pub const MAX_DIM: u32 = 32768;

/// Where the tile sits in world space (units of the source volume's bounding box).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tile {
    /// (x0, y0): the source bbox's min x and y.
    pub origin: Vec2,
    /// World extent in x and y (> 0).
    pub size: Vec2,
    /// World z of the top plane (the source bbox's max z).
    pub top_z: f32,
    /// The depth range: stored depths are fractions of it (> 0, world units).
    pub height_scale: f32,
    /// z size of a level-0 flyaway voxel (> 0, world units).
    pub voxel_depth: f32,
}

impl Tile {
    /// The tile of a source volume with bounding box `bbox` and `dims` voxels: covers its
    /// x–y box, top plane at max z, depth range = the whole thickness.
    pub fn from_source(bbox: Aabb, dims: [u32; 3]) -> Tile {
        let size = bbox.size();
        Tile { origin: bbox.min.truncate(), size: size.truncate(), top_z: bbox.max.z, height_scale: size.z, voxel_depth: size.z / dims[2].max(1) as f32 }
    }

    /// Checks the tile's numbers against the bounds below (the file's reader does too).
    pub fn validate(&self) -> Result<(), ModelError> {
        // Lengths within [MIN_LENGTH, MAX_LENGTH] and positions within MAX_OFFSET tile
        // sizes of the world origin: beyond them f32 world → tile arithmetic loses the
        // texel (a tile 1e-30 wide rendered black; one 1e5 widths off-origin has an ulp
        // near a texel).
        let len = |v: f32| v.is_finite() && (MIN_LENGTH..=MAX_LENGTH).contains(&v);
        let scale = self.size.x.max(self.size.y).max(self.height_scale);
        let pos = |v: f32| v.is_finite() && v.abs() <= MAX_OFFSET * scale;
        const LEN: &str = "must be finite and in [1e-6, 1e6] world units";
        const POS: &str = "must be finite and within 1e4 tile sizes of the world origin";
        let checks = [
            ("size.x", self.size.x, len(self.size.x), LEN),
            ("size.y", self.size.y, len(self.size.y), LEN),
            ("height_scale", self.height_scale, len(self.height_scale), LEN),
            ("voxel_depth", self.voxel_depth, len(self.voxel_depth), LEN),
            ("origin.x", self.origin.x, pos(self.origin.x), POS),
            ("origin.y", self.origin.y, pos(self.origin.y), POS),
            ("top_z", self.top_z, pos(self.top_z), POS),
        ];
        for (field, value, ok, why) in checks {
            if !ok {
                return Err(ModelError::Tile { field, value, why });
            }
        }
        Ok(())
    }
}

/// Bounds of a tile's lengths (size, height_scale, voxel_depth), world units.
pub const MIN_LENGTH: f32 = 1e-6;
pub const MAX_LENGTH: f32 = 1e6;
/// How far (in tile sizes) the tile may sit from the world origin.
pub const MAX_OFFSET: f32 = 1e4;

/// The smooth height field h at level-0 resolution: depth below the top plane.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HeightField {
    pub width: u32,
    pub height: u32,
    /// depth = code / 65535 · height_scale; x fastest.
    pub codes: Vec<u16>,
}

impl HeightField {
    /// Quantizes `depths` (world units below the top plane, x fastest) to unorm16
    /// fractions of `height_scale`. Errors on non-finite or out-of-range depths.
    pub fn from_depths(width: u32, height: u32, depths: &[f32], height_scale: f32) -> Result<HeightField, ModelError> {
        if depths.len() as u64 != width as u64 * height as u64 {
            return Err(ModelError::HeightLength { expected: width as u64 * height as u64, got: depths.len() as u64 });
        }
        let mut codes = Vec::with_capacity(depths.len());
        for (k, &d) in depths.iter().enumerate() {
            // A hair of slack for depths computed as top − z in f32.
            if !(d >= -1e-6 * height_scale && d <= height_scale * (1.0 + 1e-6)) {
                let (i, j) = ((k % width as usize) as u32, (k / width as usize) as u32);
                return Err(ModelError::Depth { i, j, value: d, scale: height_scale });
            }
            codes.push(unorm16(d / height_scale));
        }
        Ok(HeightField { width, height, codes })
    }

    /// From heights as the geometry stage measures them: `heights` in voxels, z up from
    /// the source volume's bottom face (texel centres, x fastest), for a volume of `zres`
    /// voxels of depth `tile.voxel_depth` whose top face is `tile.top_z`. depth below the
    /// top plane = (zres − h)·voxel_depth.
    pub fn from_voxel_heights(width: u32, height: u32, heights: &[f32], zres: u32, tile: &Tile) -> Result<HeightField, ModelError> {
        let depths: Vec<f32> = heights.iter().map(|&h| (zres as f32 - h) * tile.voxel_depth).collect();
        HeightField::from_depths(width, height, &depths, tile.height_scale)
    }

    /// Depth of texel (i, j) as a fraction of the height scale, in [0, 1].
    #[inline]
    pub fn depth_fraction(&self, i: u32, j: u32) -> f32 {
        unorm16_value(self.codes[(j * self.width + i) as usize])
    }
}

/// A level's surface BRDFs in one of two encodings (runtime/HYBRID_FORMAT.md).
#[derive(Clone, Debug, PartialEq)]
pub enum Surface {
    /// Per texel a frame (n, t) and a cluster index into `table`, whose lobes all use the
    /// texel's frame. The paper's level 0 (K ≤ 32 clusters; up to 65536 here).
    Clustered { texels: Vec<ClusteredTexel>, table: BrdfTable },
    /// One header per texel (x fastest), each lobe with its own frame; lobe 0's frame is
    /// also the diffuse term's. The paper's coarse levels (up to 8 lobes).
    PerTexel(BrdfTable),
}

/// One level of the mip chain.
#[derive(Clone, Debug, PartialEq)]
pub struct Level {
    pub width: u32,
    pub height: u32,
    pub surface: Surface,
    /// The flyaway lists, if this level has any flyaway voxels.
    pub flyaways: Option<Flyaways>,
    /// The transmission term per texel (x fastest), in each texel's lobe-0 frame: a
    /// BSDF model (format 1.3). `None`: nothing comes through from below the sheet.
    pub transmission: Option<Vec<PackedTransmission>>,
    /// The transmission visibility (gradient and curvature) per texel (x fastest), only beside
    /// `transmission` (format 1.16, [`crate::brdf::cloth_transmission_visibility`]).
    /// `None`: M_t = 1 everywhere.
    pub transmission_visibility: Option<Vec<PackedTransmissionVisibility>>,
    /// The view tilt per texel (x fastest) of a coarse level: its frames turn toward
    /// the viewer as its footprint's visible normals do (format 1.4,
    /// [`crate::brdf::visible_normal`]). `None`: the frames as stored (always at level 0).
    pub view_tilt: Option<Vec<PackedViewTilt>>,
    /// The visibility gradient per texel (x fastest), at any level (format 1.12,
    /// [`crate::brdf::cloth_visibility_gradient`]). `None`: M = 1 everywhere.
    pub gradient: Option<Vec<PackedGradient>>,
    /// The visibility curvature per texel (x fastest), at any level (format 1.15,
    /// [`crate::brdf::cloth_visibility`]). `None`: q = 0 everywhere.
    pub curvature: Option<Vec<PackedCurvature>>,
}

impl Level {
    /// The BRDF of texel (i, j), decoded (assumes a validated model).
    pub fn texel_brdf(&self, i: u32, j: u32) -> TexelBrdf {
        let index = (j * self.width + i) as usize;
        let mut b = match &self.surface {
            Surface::Clustered { texels, table } => {
                let t = &texels[index];
                table.brdf_in_frame(t.cluster as usize, t.frame())
            }
            Surface::PerTexel(table) => table.brdf_framed(index),
        };
        if let Some(t) = &self.transmission {
            b.transmission = t[index].decode();
            if let Some(v) = &self.transmission_visibility {
                (b.transmission.grad, b.transmission.curv) = v[index].decode();
            }
        }
        if let Some(g) = &self.gradient {
            b.gradient = g[index].decode();
        }
        if let Some(q) = &self.curvature {
            b.curvature = q[index].decode();
        }
        b
    }

    /// Texel (i, j)'s view tilt (None without a tilt section).
    pub fn view_tilt_at(&self, i: u32, j: u32) -> Option<crate::brdf::visible_normal::ViewTilt> {
        self.view_tilt.as_ref().map(|v| v[(j * self.width + i) as usize].decode())
    }

    /// Bytes of the view tilt records in the file (0 without).
    pub fn view_tilt_bytes(&self) -> u64 {
        self.view_tilt.as_ref().map_or(0, |t| super::compact::view_tilt_bytes(t))
    }

    /// Bytes of the visibility gradient records in the file (0 without).
    pub fn gradient_bytes(&self) -> u64 {
        self.gradient.as_ref().map_or(0, |g| (g.len() * size_of::<PackedGradient>()) as u64)
    }

    /// Bytes of the visibility curvature records in the file (0 without).
    pub fn curvature_bytes(&self) -> u64 {
        self.curvature.as_ref().map_or(0, |q| (q.len() * size_of::<PackedCurvature>()) as u64)
    }

    /// Bytes of the transmission records in the file, with their visibility records (0
    /// without).
    pub fn transmission_bytes(&self) -> u64 {
        self.transmission.as_ref().map_or(0, |t| (t.len() * size_of::<PackedTransmission>()) as u64) + self.transmission_visibility.as_ref().map_or(0, |g| (g.len() * size_of::<PackedTransmissionVisibility>()) as u64)
    }

    /// Bytes of the surface encoding in the file.
    pub fn surface_bytes(&self) -> u64 {
        match &self.surface {
            Surface::Clustered { texels, table } => (texels.len() * size_of::<ClusteredTexel>()) as u64 + table.byte_size(),
            Surface::PerTexel(table) => super::compact::per_texel_table_bytes(table),
        }
    }
}

/// How a model was baked.
#[derive(Clone, Debug, PartialEq)]
pub struct BakeMetadata {
    /// The reading of Eqs. 2–3 the BRDFs were fitted with.
    pub reading: BrdfReading,
    /// Whether the fit assumed height-field shadowing (renderers shadow by default then).
    pub fitted_with_shadowing: bool,
    /// Whether surface hits carry the volumetric factor 2/(μ_i + μ_o)
    /// (`cpu::shading::volume_factor`; format 1.1).
    pub volumetric: bool,
    /// Whether the coarse levels' BRDFs carry the light's height-field visibility,
    /// averaged over their footprint (the prefilter's, format 1.2): renderers shade
    /// levels ≥ 1 without shadow rays then.
    pub coarse_visibility: bool,
    /// The law of the surface texels' diffuse term ([`crate::brdf::cloth_diffuse_cosine`];
    /// Lommel–Seeliger since format 1.6). Flyaways' is always Lambert's, in the frame facing the viewer.
    pub diffuse: crate::brdf::DiffuseLaw,
    /// How the flyaways' lobes fall with the azimuth about the fibre
    /// ([`crate::brdf::FiberLobes`]; the cylinder since format 1.11).
    pub fiber_lobes: crate::brdf::FiberLobes,
    /// Whether the flyaways shadow the surface's lights: at a surface hit each light's
    /// factor times what the flyaways of the footprint's level let through between the
    /// hit and the top plane toward it, the environment's times what they let through
    /// straight up (`cpu::render::Scene::flyaway_shadow_mixed`; format 1.13).
    pub flyaway_shadow: bool,
    /// Relative fit error per level (≥ 0), or negative where not measured.
    pub fit_error: Vec<f32>,
    /// Bounding box of the source volume.
    pub source_bbox: Aabb,
    /// Voxel counts of the source volume.
    pub source_dims: [u32; 3],
    /// Seed of the bake.
    pub seed: u64,
    /// Free text (e.g. the source files and the baker's version), UTF-8, ≤ 64 KiB.
    pub note: String,
}

/// A hybrid fabric model (DESIGN.md §5–§6).
#[derive(Clone, Debug, PartialEq)]
pub struct HybridModel {
    pub tile: Tile,
    pub height: HeightField,
    /// Level 0 first; 1 ≤ count ≤ ⌊log2 max(w, h)⌋ + 1.
    pub levels: Vec<Level>,
    pub meta: BakeMetadata,
}

/// Dimensions of level `level` for a level-0 size of `w`×`h`: halved, rounding up.
pub fn level_dims(w: u32, h: u32, level: usize) -> (u32, u32) {
    let shrink = |v: u32| (((v as u64) + (1u64 << level) - 1) >> level).max(1) as u32;
    (shrink(w), shrink(h))
}

/// Most levels a `w`×`h` model can have (down to 1×1).
pub fn max_levels(w: u32, h: u32) -> usize {
    (32 - w.max(h).max(1).leading_zeros()) as usize
}

impl HybridModel {
    pub fn width(&self) -> u32 {
        self.height.width
    }

    pub fn height_px(&self) -> u32 {
        self.height.height
    }

    /// World size of a level-0 texel in x and y.
    pub fn texel_size(&self) -> Vec2 {
        self.tile.size / Vec2::new(self.width() as f32, self.height_px() as f32)
    }

    /// Level-0 texels per world unit in x and y: 1 / [`HybridModel::texel_size`], rounded
    /// once here. Both renderers turn world x–y into texel coordinates by multiplying
    /// with it: a GPU's division is only within 2.5 ulp (Vulkan's precision table), so
    /// `x / texel` can land on the other side of a texel line than the CPU's, while a
    /// product is correctly rounded on both.
    pub fn inv_texel_size(&self) -> Vec2 {
        Vec2::ONE / self.texel_size()
    }

    /// Depth of height sample (i, j) below the top plane, world units.
    #[inline]
    pub fn depth(&self, i: u32, j: u32) -> f32 {
        self.height.depth_fraction(i, j) * self.tile.height_scale
    }

    /// World z size of a flyaway voxel at `level`.
    pub fn voxel_depth(&self, level: usize) -> f32 {
        self.tile.voxel_depth * (1u64 << level) as f32
    }

    /// Whether the model is a BSDF (its levels carry a transmission term).
    pub fn has_transmission(&self) -> bool {
        self.levels.iter().any(|l| l.transmission.is_some())
    }

    /// Whether any level has flyaway voxels.
    pub fn has_flyaways(&self) -> bool {
        self.levels.iter().any(|l| l.flyaways.as_ref().is_some_and(|f| !f.nodes.is_empty()))
    }

    /// The world box the model occupies: the tile's x–y box, from the deepest possible
    /// surface to the top plane.
    pub fn bounds(&self) -> Aabb {
        let min = Vec3::new(self.tile.origin.x, self.tile.origin.y, self.tile.top_z - self.tile.height_scale);
        let max = Vec3::new(self.tile.origin.x + self.tile.size.x, self.tile.origin.y + self.tile.size.y, self.tile.top_z);
        Aabb::new(min, max)
    }

    /// Checks everything a renderer relies on: sizes, level dimensions, table ranges,
    /// parameter ranges, flyaway lists (acyclic, in range, each node once) and metadata.
    /// Readers call it on every file; renderers call it on models built in code. O(size).
    pub fn validate(&self) -> Result<(), ModelError> {
        self.tile.validate()?;
        let (w, h) = (self.height.width, self.height.height);
        if w == 0 || h == 0 || w > MAX_DIM || h > MAX_DIM {
            return Err(ModelError::Dims { what: "height field", width: w, height: h, max: MAX_DIM });
        }
        if self.height.codes.len() as u64 != w as u64 * h as u64 {
            return Err(ModelError::HeightLength { expected: w as u64 * h as u64, got: self.height.codes.len() as u64 });
        }
        let max = max_levels(w, h);
        if self.levels.is_empty() || self.levels.len() > max {
            return Err(ModelError::LevelCount { count: self.levels.len(), width: w, height: h, max });
        }
        for (level, l) in self.levels.iter().enumerate() {
            let (want_w, want_h) = level_dims(w, h, level);
            if (l.width, l.height) != (want_w, want_h) {
                return Err(ModelError::LevelDims { level, got_w: l.width, got_h: l.height, want_w, want_h });
            }
            let texels = want_w as u64 * want_h as u64;
            match &l.surface {
                Surface::Clustered { texels: tx, table } => {
                    if tx.len() as u64 != texels {
                        return Err(ModelError::Length { what: "clustered texels", level, expected: texels, got: tx.len() as u64 });
                    }
                    table.validate(TableKind::SurfaceClusters, level, 0)?;
                    if let Some((k, t)) = tx.iter().enumerate().find(|(_, t)| t.cluster as usize >= table.headers.len()) {
                        let (i, j) = ((k % want_w as usize) as u32, (k / want_w as usize) as u32);
                        return Err(ModelError::ClusterIndex { level, i, j, index: t.cluster as u32, len: table.headers.len() });
                    }
                }
                Surface::PerTexel(table) => {
                    if table.headers.len() as u64 != texels {
                        return Err(ModelError::Length { what: "per-texel BRDF headers", level, expected: texels, got: table.headers.len() as u64 });
                    }
                    table.validate(TableKind::SurfaceTexels, level, 1)?;
                }
            }
            if let Some(t) = &l.transmission {
                if t.len() as u64 != texels {
                    return Err(ModelError::Length { what: "transmission records", level, expected: texels, got: t.len() as u64 });
                }
                for (texel, r) in t.iter().enumerate() {
                    r.validate(level, texel)?;
                }
            }
            if let Some(g) = &l.transmission_visibility {
                if l.transmission.is_none() {
                    return Err(ModelError::TransmissionVisibilityAlone { level });
                }
                if g.len() as u64 != texels {
                    return Err(ModelError::Length { what: "transmission visibility records", level, expected: texels, got: g.len() as u64 });
                }
                for (texel, r) in g.iter().enumerate() {
                    r.validate(level, texel)?;
                }
            }
            if let Some(g) = &l.gradient {
                if g.len() as u64 != texels {
                    return Err(ModelError::Length { what: "visibility gradient records", level, expected: texels, got: g.len() as u64 });
                }
                for (texel, r) in g.iter().enumerate() {
                    r.validate(level, texel)?;
                }
            }
            if let Some(q) = &l.curvature {
                if q.len() as u64 != texels {
                    return Err(ModelError::Length { what: "visibility curvature records", level, expected: texels, got: q.len() as u64 });
                }
                for (texel, r) in q.iter().enumerate() {
                    r.validate(level, texel)?;
                }
            }
            if let Some(t) = &l.view_tilt {
                if level == 0 {
                    return Err(ModelError::ViewTiltAtLevel0);
                }
                if t.len() as u64 != texels {
                    return Err(ModelError::Length { what: "view tilt records", level, expected: texels, got: t.len() as u64 });
                }
                for (texel, r) in t.iter().enumerate() {
                    r.validate(level, texel)?;
                }
            }
            if let Some(f) = &l.flyaways {
                // Voxels must start inside the slab [0, height_scale] below the top.
                let depth_limit = (self.tile.height_scale / self.voxel_depth(level)).ceil().min(65536.0) as u32;
                f.validate(level, want_w, want_h, depth_limit)?;
            }
        }
        self.validate_meta()
    }

    fn validate_meta(&self) -> Result<(), ModelError> {
        let m = &self.meta;
        if m.fit_error.len() > self.levels.len() {
            return Err(ModelError::Meta(format!("{} fit errors for {} levels", m.fit_error.len(), self.levels.len())));
        }
        if let Some(e) = m.fit_error.iter().find(|e| !e.is_finite()) {
            return Err(ModelError::Meta(format!("fit error {e} is not finite (use a negative value for 'not measured')")));
        }
        if !(m.source_bbox.min.is_finite() && m.source_bbox.max.is_finite()) || m.source_bbox.size().min_element() < 0.0 {
            return Err(ModelError::Meta(format!("source bounding box {:?} is not finite or inverted", m.source_bbox)));
        }
        if m.note.len() > 65536 {
            return Err(ModelError::Meta(format!("note is {} bytes; at most 65536", m.note.len())));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hybrid::FlyawayInput;

    #[test]
    fn source_conventions_convert_to_depths_below_the_top() {
        // A volume of 64 layers over z ∈ [−1, 0.6]: Δz = 0.025.
        let bbox = Aabb::new(Vec3::new(0.0, 0.0, -1.0), Vec3::new(2.0, 1.0, 0.6));
        let tile = Tile::from_source(bbox, [40, 20, 64]);
        assert_eq!((tile.top_z, tile.height_scale, tile.voxel_depth), (0.6, 1.6, 0.025));
        // A surface 10 voxels below the top (height 54 voxels from the bottom) has depth 0.25.
        let h = HeightField::from_voxel_heights(2, 1, &[54.0, 64.0], 64, &tile).unwrap();
        assert!((h.depth_fraction(0, 0) * tile.height_scale - 0.25).abs() < 1.6 / 65535.0);
        assert_eq!(h.depth_fraction(1, 0), 0.0);
        assert!(HeightField::from_voxel_heights(1, 1, &[-1.0], 64, &tile).is_err(), "below the bottom face");
        assert_eq!(FlyawayInput::depth_of_voxel_layer(63, 64), Some(0));
        assert_eq!(FlyawayInput::depth_of_voxel_layer(0, 64), Some(63));
        assert_eq!(FlyawayInput::depth_of_voxel_layer(64, 64), None);
    }
}
