//! Hybrid geometry from a fabric volume (paper §5.2, docs/DESIGN.md §5):
//! the detailed height map h0, the flyaway volume V, the filter size from the
//! autocorrelations of h0 (Eq. 4), the smooth height h, and the normal and tangent maps.
//!
//! Conventions (every map, every file):
//! - Maps are `nx × ny` texels, texel (i, j) ↔ volume column (i, j), x fastest
//!   (index i + nx·j). All maps are periodic in x and y, as the sample is.
//! - Heights are in voxel units along z, measured up from the volume's bottom face and
//!   continuous: cell z spans [z, z + 1], so the top face of cell z is at z + 1 and a
//!   fully filled column of nz cells has height nz. A column without a run thicker than
//!   a fiber finds its surface at its neighbours' level ([`heightmap::fill_holes`]); one
//!   with no material there is a hole through the fabric: h0 = 0, the bottom face.
//! - Normals and tangents are unit vectors in the volume's world frame (x̂, ŷ, ẑ), slopes
//!   measured in world units (the voxel size may differ per axis).
//! - "Non-empty" means ρ > the density threshold ([`DensityThreshold`]); fiber
//!   thicknesses and diameters are in voxels (of the z size; voxels are usually cubic).
//!
//! The pipeline is [`extract_geometry`]; each stage lives in its own file.

pub mod autocorrelation;
pub mod blur;
pub mod cross_section;
pub mod flyaways;
pub mod heightmap;
pub mod io;
pub mod normals;
pub mod preview;
pub mod tangents;

#[cfg(test)]
mod testvol;
#[cfg(test)]
mod tests;

use std::time::Instant;

use glam::Vec3;

use crate::volume::FabricVolume;

pub use autocorrelation::{Autocorrelation, FilterRule, PeakSearch};
pub use flyaways::{FlyawayMask, FlyawayVolume, FlyawayVoxel};
pub use heightmap::{DensityScale, DensityThreshold, HeightMap};
pub use io::GeometryIoError;

/// Errors of geometry extraction. Each names what was wrong with the input or option.
#[derive(Debug, thiserror::Error)]
pub enum GeometryError {
    #[error("volume is {dims:?} voxels; geometry extraction needs at least 4×4 columns and one slab")]
    TooSmall { dims: [usize; 3] },
    #[error("volume {dims:?} is empty: no voxel has density above the threshold {threshold} (largest density {max_density})")]
    EmptyVolume { dims: [usize; 3], threshold: f32, max_density: f32 },
    #[error(
        "no fabric surface found: no column has a run of non-empty voxels thicker than {run_threshold:.3} voxels \
         ({factor} × fiber thickness {fiber_thickness:.3}); the thickest run is {thickest_run:.3} voxels. \
         The volume holds only isolated fibers or a layer thinner than a fiber; pass a smaller fiber thickness to override"
    )]
    NoSurface { fiber_thickness: f32, factor: f32, run_threshold: f32, thickest_run: f32 },
    #[error("option {name} = {value}: {reason}")]
    BadOption { name: &'static str, value: String, reason: &'static str },
}

/// What [`extract_geometry`] does, and with which settings. `Default` is what the CLI uses.
#[derive(Clone, Debug, PartialEq)]
pub struct GeometryOptions {
    /// Which voxels count as non-empty (default: ρ > 5% of the solid density).
    pub density_threshold: DensityThreshold,
    /// One fiber's thickness in voxels; `None` estimates it from the isolated fibers
    /// of the volume ([`heightmap::estimate_fiber_thickness`]).
    pub fiber_thickness: Option<f32>,
    /// Used when the estimate finds too few isolated fibers to measure (said in the result).
    pub default_fiber_thickness: f32,
    /// A run is the surface when its thickness exceeds `surface_run_factor` fibers
    /// (paper: "greater than the size of a single fiber"; 1.5 leaves room for the ±
    /// spread of one fiber's measured chord, so a single fiber is never a surface and two
    /// stacked fibers always are).
    pub surface_run_factor: f32,
    /// Forces the filter size [x, y] in texels (skips the autocorrelation choice).
    pub filter_size: Option<[f32; 2]>,
    /// How the two autocorrelation peaks become the filter size.
    pub filter_rule: FilterRule,
    /// Filter size for unpatterned (felt-like) input, in texels [x, y]; `None` uses
    /// `unpatterned_filter_fibers` fiber thicknesses.
    pub unpatterned_filter_size: Option<[f32; 2]>,
    /// Default filter size for unpatterned input, in fiber thicknesses: smoothing over a
    /// few fibers leaves the clumps of a felt in h and its fibers in n, at any voxel
    /// resolution (a size fixed in texels would not).
    pub unpatterned_filter_fibers: f32,
    /// Robust first-peak search settings.
    pub peak_search: PeakSearch,
    /// Gaussian σ = `sigma_per_filter_size` × filter size. The default 1/6 makes the
    /// ±3σ kernel span one pattern period: the yarn-scale shape (period = filter size)
    /// keeps 58% of its amplitude, detail at a quarter of it keeps < 0.02%.
    pub sigma_per_filter_size: f32,
    /// Columns without a surface run look for it at their neighbours' level, interpolated
    /// with a Gaussian of σ = this many fiber thicknesses (texels) ([`heightmap::fill_holes`]).
    pub hole_fill_sigma_fibers: f32,
    /// Scale of the fiber-level detail h0 − h in the normal map (1 = the paper).
    pub detail_strength: f32,
    /// Number of surface voxels, from the top of the column down, whose fiber axes are
    /// averaged into the tangent.
    pub tangent_depth: usize,
}

impl Default for GeometryOptions {
    fn default() -> Self {
        GeometryOptions {
            density_threshold: DensityThreshold::default(),
            fiber_thickness: None,
            default_fiber_thickness: 1.0,
            surface_run_factor: 1.5,
            filter_size: None,
            filter_rule: FilterRule::PerAxis,
            unpatterned_filter_size: None,
            unpatterned_filter_fibers: 6.0,
            peak_search: PeakSearch::default(),
            sigma_per_filter_size: 1.0 / 6.0,
            hole_fill_sigma_fibers: 2.0,
            detail_strength: 1.0,
            tangent_depth: 3,
        }
    }
}

impl GeometryOptions {
    /// Checks every setting; the error names the option and its value.
    pub fn validate(&self) -> Result<(), GeometryError> {
        fn bad(name: &'static str, value: impl std::fmt::Display, reason: &'static str) -> GeometryError {
            GeometryError::BadOption { name, value: value.to_string(), reason }
        }
        self.density_threshold.validate()?;
        if let Some(t) = self.fiber_thickness
            && !(t.is_finite() && t > 0.0 && t <= 1e4)
        {
            return Err(bad("fiber_thickness", t, "must be a positive number of voxels"));
        }
        if !(self.default_fiber_thickness.is_finite() && self.default_fiber_thickness > 0.0) {
            return Err(bad("default_fiber_thickness", self.default_fiber_thickness, "must be positive"));
        }
        if !(self.surface_run_factor.is_finite() && self.surface_run_factor >= 1.0 && self.surface_run_factor <= 100.0) {
            return Err(bad("surface_run_factor", self.surface_run_factor, "must be in [1, 100]"));
        }
        if let Some(s) = self.filter_size
            && !s.iter().all(|v| v.is_finite() && *v >= 0.0 && *v <= 1e6)
        {
            return Err(bad("filter_size", format!("{s:?}"), "must be non-negative texel counts"));
        }
        if let Some(s) = self.unpatterned_filter_size
            && !s.iter().all(|v| v.is_finite() && *v >= 0.0 && *v <= 1e6)
        {
            return Err(bad("unpatterned_filter_size", format!("{s:?}"), "must be non-negative texel counts"));
        }
        if !(self.unpatterned_filter_fibers.is_finite() && self.unpatterned_filter_fibers > 0.0 && self.unpatterned_filter_fibers <= 1e4) {
            return Err(bad("unpatterned_filter_fibers", self.unpatterned_filter_fibers, "must be in (0, 10⁴]"));
        }
        self.peak_search.validate()?;
        if !(self.sigma_per_filter_size.is_finite() && self.sigma_per_filter_size > 0.0 && self.sigma_per_filter_size <= 10.0) {
            return Err(bad("sigma_per_filter_size", self.sigma_per_filter_size, "must be in (0, 10]"));
        }
        if !(self.hole_fill_sigma_fibers.is_finite() && self.hole_fill_sigma_fibers > 0.0 && self.hole_fill_sigma_fibers <= 1e3) {
            return Err(bad("hole_fill_sigma_fibers", self.hole_fill_sigma_fibers, "must be in (0, 1000]"));
        }
        if !(self.detail_strength.is_finite() && self.detail_strength.abs() <= 100.0) {
            return Err(bad("detail_strength", self.detail_strength, "must be finite, |value| ≤ 100"));
        }
        if self.tangent_depth == 0 || self.tangent_depth > 1024 {
            return Err(bad("tangent_depth", self.tangent_depth, "must be between 1 and 1024 voxels"));
        }
        Ok(())
    }
}

/// The stages of [`extract_geometry`], in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    DensityScale,
    FiberThickness,
    HeightMap,
    Flyaways,
    Autocorrelation,
    Blur,
    Normals,
    Tangents,
}

impl Stage {
    pub fn name(self) -> &'static str {
        match self {
            Stage::DensityScale => "density_scale",
            Stage::FiberThickness => "fiber_thickness",
            Stage::HeightMap => "height_map",
            Stage::Flyaways => "flyaways",
            Stage::Autocorrelation => "autocorrelation",
            Stage::Blur => "blur",
            Stage::Normals => "normals",
            Stage::Tangents => "tangents",
        }
    }
}

pub use crate::progress::{NoProgress, Progress};

/// Wall time of one stage.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StageTime {
    pub stage: String,
    pub seconds: f64,
}

/// The geometric half of a hybrid model, and the numbers that say how it was made.
#[derive(Clone, Debug, PartialEq)]
pub struct Geometry {
    /// Map size [nx, ny] = the volume's columns.
    pub dims: [usize; 2],
    /// The volume's nz (heights lie in [0, nz]).
    pub depth: usize,
    /// World size of one voxel (x, y, z).
    pub voxel_size: Vec3,
    /// Detailed height map h0 (voxels, continuous; see the module docs).
    pub h0: Vec<f32>,
    /// Index of the top voxel of each column's surface run; −1 for holes. Voxels above
    /// it are V or empty.
    pub surface_top: Vec<i32>,
    /// Smooth height h: h0 blurred by the anisotropic periodic Gaussian (yarn-level shape).
    pub h: Vec<f32>,
    /// Unit normals: h's slope plus the fiber-level detail h0 − h ([`normals`]).
    pub normals: Vec<Vec3>,
    /// Unit tangents ⟂ normals, sign convention in [`tangents`].
    pub tangents: Vec<Vec3>,
    /// The flyaway volume V (sparse).
    pub flyaways: FlyawayVolume,
    /// Filter size [x, y] in texels (pattern periods from the autocorrelations).
    pub filter_size: [f32; 2],
    /// False when no peak was found (unpatterned input) or the size was forced.
    pub filter_auto: bool,
    /// First autocorrelation peak [C0, C1] in texels, if any.
    pub autocorrelation_peaks: [Option<f32>; 2],
    /// Normalized autocorrelations C0 (along x) and C1 (along y), `C[0] = 1` (Eq. 4).
    pub autocorrelation: [Vec<f32>; 2],
    /// One fiber's thickness in voxels.
    pub fiber_thickness: f32,
    /// True when estimated from the volume, false when given or defaulted.
    pub fiber_thickness_auto: bool,
    /// Density threshold and solid density used.
    pub density: DensityScale,
    /// Columns with no surface at all: holes through the fabric (h0 = 0).
    pub hole_columns: usize,
    /// Columns without a run thicker than a fiber whose surface was found at their
    /// neighbours' level ([`heightmap::fill_holes`]).
    pub filled_columns: usize,
    /// Columns whose surface starts in the top slab (the surface may be cut off).
    pub clipped_columns: usize,
    /// Texels whose tangent fell back to the projected x̂ (no usable fiber direction).
    pub tangent_fallback_texels: usize,
    /// Things a user should know (fallbacks, suspicious input), in plain words.
    pub warnings: Vec<String>,
    /// Wall time per stage.
    pub stage_times: Vec<StageTime>,
}

impl Geometry {
    /// Number of texels.
    pub fn texels(&self) -> usize {
        self.dims[0] * self.dims[1]
    }

    /// Index of the top voxel of column (x, y)'s surface run, or `None` for a hole.
    pub fn surface_top(&self, x: usize, y: usize) -> Option<usize> {
        let t = self.surface_top[x + self.dims[0] * y];
        (t >= 0).then_some(t as usize)
    }

    /// True when voxel (x, y, z) lies above the surface of its column (it is either in V
    /// or empty). A renderer of "the complement of V" may drop everything above the
    /// surface, halo included, or only [`Geometry::flyaway_mask`].
    pub fn above_surface(&self, x: usize, y: usize, z: usize) -> bool {
        match self.surface_top(x, y) {
            Some(top) => z > top,
            None => true,
        }
    }

    /// A bitset over the volume of exactly the voxels in V.
    pub fn flyaway_mask(&self) -> FlyawayMask {
        self.flyaways.mask()
    }

    /// One bool per voxel in volume order, true above the surface (V and the halo
    /// around it): the stricter "complement of V" for the surface fit's renderings.
    pub fn above_surface_mask(&self) -> Vec<bool> {
        let [nx, ny] = self.dims;
        let mut mask = vec![false; nx * ny * self.depth];
        for (column, &top) in self.surface_top.iter().enumerate() {
            let from = (top + 1).max(0) as usize;
            for z in from..self.depth {
                mask[column + nx * ny * z] = true;
            }
        }
        mask
    }

    /// Range [min, max] of a map.
    pub fn range(map: &[f32]) -> [f32; 2] {
        map.iter().fold([f32::INFINITY, f32::NEG_INFINITY], |[lo, hi], &v| [lo.min(v), hi.max(v)])
    }
}

/// Extracts the hybrid geometry from a volume (paper §5.2). See [`extract_geometry_with`].
pub fn extract_geometry(volume: &FabricVolume, options: &GeometryOptions) -> Result<Geometry, GeometryError> {
    extract_geometry_with(volume, options, &NoProgress)
}

/// [`extract_geometry`] reporting progress. Deterministic: the result is bit-identical
/// for any number of threads.
pub fn extract_geometry_with(volume: &FabricVolume, options: &GeometryOptions, progress: &dyn Progress) -> Result<Geometry, GeometryError> {
    options.validate()?;
    let [nx, ny, nz] = volume.dims();
    if nx < 4 || ny < 4 || nz < 1 {
        return Err(GeometryError::TooSmall { dims: volume.dims() });
    }
    let mut times = Vec::new();
    let mut warnings = Vec::new();
    let mut timed = |stage: Stage, start: Instant| {
        let seconds = start.elapsed().as_secs_f64();
        progress.end(stage.name(), seconds);
        times.push(StageTime { stage: stage.name().into(), seconds });
    };

    // 1. Which voxels are non-empty, and what a fully covered voxel's density is.
    let t = Instant::now();
    progress.begin(Stage::DensityScale.name(), nz as u64);
    let density = heightmap::density_scale(volume, options.density_threshold, progress)?;
    timed(Stage::DensityScale, t);

    // 2. One fiber's thickness: given, or measured on the isolated fibers.
    let t = Instant::now();
    let (fiber_thickness, fiber_thickness_auto) = match options.fiber_thickness {
        Some(d) => (d, false),
        None => {
            progress.begin(Stage::FiberThickness.name(), 2 * ny as u64);
            match heightmap::estimate_fiber_thickness(volume, &density, progress) {
                Some(d) => (d, true),
                None => {
                    warnings.push(format!(
                        "too few isolated fibers to measure the fiber thickness; using the default {} voxels",
                        options.default_fiber_thickness
                    ));
                    (options.default_fiber_thickness, false)
                }
            }
        }
    };
    timed(Stage::FiberThickness, t);

    // 3. h0: the first run thicker than one fiber, scanning down (paper §5.2).
    let t = Instant::now();
    progress.begin(Stage::HeightMap.name(), ny as u64);
    let run_threshold = options.surface_run_factor * fiber_thickness;
    let mut hm = heightmap::detailed_height(volume, &density, run_threshold, progress);
    if hm.hole_columns == nx * ny {
        return Err(GeometryError::NoSurface { fiber_thickness, factor: options.surface_run_factor, run_threshold, thickest_run: hm.thickest_run });
    }
    heightmap::fill_holes(volume, &density, &mut hm, fiber_thickness, options.hole_fill_sigma_fibers * fiber_thickness);
    if hm.clipped_columns > 0 {
        warnings.push(format!(
            "the surface starts in the top slab in {} of {} columns ({:.1}%): the volume may be cut off at the top; h0 there is at most the top face ({nz})",
            hm.clipped_columns,
            nx * ny,
            100.0 * hm.clipped_columns as f64 / (nx * ny) as f64
        ));
    }
    if hm.hole_columns * 2 > nx * ny {
        warnings.push(format!(
            "{} of {} columns ({:.1}%) are holes (no material at their neighbours' surface level; h0 = 0): a very open fabric, or a fiber thickness that is too large",
            hm.hole_columns,
            nx * ny,
            100.0 * hm.hole_columns as f64 / (nx * ny) as f64
        ));
    }
    timed(Stage::HeightMap, t);

    // 4. V: everything non-empty above the surface.
    let t = Instant::now();
    progress.begin(Stage::Flyaways.name(), ny as u64);
    let flyaways = flyaways::extract_flyaways(volume, &density, &hm.surface_top, fiber_thickness, progress);
    timed(Stage::Flyaways, t);

    // 5. Filter size from the autocorrelations of h0 (Eq. 4).
    let t = Instant::now();
    progress.begin(Stage::Autocorrelation.name(), 2);
    let ac = autocorrelation::autocorrelate(&hm.h0, nx, ny);
    let peaks = match &ac {
        Some(ac) => [autocorrelation::first_peak(&ac.c0, ac.null_sd[0], &options.peak_search), autocorrelation::first_peak(&ac.c1, ac.null_sd[1], &options.peak_search)],
        None => [None, None],
    };
    progress.advance(2);
    let (filter_size, filter_auto) = match options.filter_size {
        Some(s) => (s, false),
        None => match autocorrelation::filter_size(peaks, options.filter_rule) {
            Some(s) => (s, true),
            None => {
                // Fiber thickness is in z-voxels; texels are x and y voxels.
                let vs = volume.voxel_size();
                let size = options.unpatterned_filter_size.unwrap_or_else(|| {
                    let d = options.unpatterned_filter_fibers * fiber_thickness;
                    [d * vs.z / vs.x, d * vs.z / vs.y]
                });
                warnings.push(format!(
                    "no clear autocorrelation peak (unpatterned, felt-like{}): using the fixed filter size {:.2} x {:.2} texels",
                    if ac.is_none() { "; h0 is flat" } else { "" },
                    size[0],
                    size[1]
                ));
                (size, false)
            }
        },
    };
    timed(Stage::Autocorrelation, t);

    // 6. h: anisotropic periodic Gaussian blur of h0.
    let t = Instant::now();
    progress.begin(Stage::Blur.name(), 2);
    let sigma = filter_size.map(|s| s * options.sigma_per_filter_size);
    let h = blur::periodic_gaussian(&hm.h0, nx, ny, sigma);
    progress.advance(2);
    timed(Stage::Blur, t);

    // 7. n: h's slope plus the fiber-level detail h0 − h.
    let t = Instant::now();
    progress.begin(Stage::Normals.name(), 1);
    let normals = normals::normal_map(&h, &hm.h0, nx, ny, volume.voxel_size(), options.detail_strength);
    progress.advance(1);
    timed(Stage::Normals, t);

    // 8. t: the fiber axis at the surface, in the tangent plane.
    let t = Instant::now();
    progress.begin(Stage::Tangents.name(), ny as u64);
    let tm = tangents::tangent_map(volume, &density, &hm.surface_top, &normals, options.tangent_depth, progress);
    if tm.fallback_texels > 0 {
        warnings.push(format!(
            "{} texels have no usable fiber direction at the surface (holes, or fibers along the normal); their tangent is x̂ projected into the tangent plane",
            tm.fallback_texels
        ));
    }
    timed(Stage::Tangents, t);

    let autocorrelation = ac.map(|a| [a.c0, a.c1]).unwrap_or_else(|| [vec![0.0; nx], vec![0.0; ny]]);
    Ok(Geometry {
        dims: [nx, ny],
        depth: nz,
        voxel_size: volume.voxel_size(),
        h0: hm.h0,
        surface_top: hm.surface_top,
        h,
        normals,
        tangents: tm.tangents,
        flyaways,
        filter_size,
        filter_auto,
        autocorrelation_peaks: peaks,
        autocorrelation,
        fiber_thickness,
        fiber_thickness_auto,
        density,
        hole_columns: hm.hole_columns,
        filled_columns: hm.filled_columns,
        clipped_columns: hm.clipped_columns,
        tangent_fallback_texels: tm.fallback_texels,
        warnings,
        stage_times: times,
    })
}
