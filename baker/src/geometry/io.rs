//! Files of an extracted geometry (what `fabric geometry --out DIR` writes and the
//! baker can read back instead of re-extracting):
//!
//! - `geometry.json`: the numbers ([`GeometryReport`]): sizes, filter size, fiber
//!   thickness, counts, warnings, stage times, the autocorrelation curves.
//! - `h0.exr`, `h.exr`: single-channel (`Y`) f32 height maps, voxels (module docs of
//!   [`crate::geometry`]); row 0 of the image is texel row j = 0.
//! - `surface_top.exr`: single-channel f32: index of the top voxel of each column's
//!   surface run, −1 for holes (exact: integers below 2²⁴).
//! - `normals.exr`, `tangents.exr`: RGB f32 = (x, y, z) of the unit vectors.
//! - `flyaways.bin`: V, little endian:
//!
//!   | offset | type      | field                                         |
//!   |--------|-----------|-----------------------------------------------|
//!   | 0      | [u8; 4]   | magic `FLYV`                                  |
//!   | 4      | u32       | version = 1                                   |
//!   | 8      | u32 × 3   | nx, ny, nz of the input volume                |
//!   | 20     | u32       | record size = 48                              |
//!   | 24     | u64       | count                                         |
//!   | 32     | record ×  | u32 x, y, z; f32 density; f32 albedo r, g, b; |
//!   |        | count     | f32 orientation x, y, z; f32 fiber diameter;  |
//!   |        |           | u32 reserved = 0                              |
//!
//!   Records are in column order (x fastest, then y), z ascending within a column.
//!
//! Readers check everything and name the file and the field that is wrong.

use std::path::{Path, PathBuf};

use fabric_runtime::image::{Image, ImageError};
use glam::Vec3;

use super::{DensityScale, FlyawayVolume, FlyawayVoxel, Geometry, StageTime};

#[derive(Debug, thiserror::Error)]
pub enum GeometryIoError {
    #[error("{path}: {error}")]
    Io { path: PathBuf, error: std::io::Error },
    #[error("{path}: EXR: {error}")]
    Exr { path: PathBuf, error: exr::error::Error },
    #[error(transparent)]
    Image(#[from] ImageError),
    #[error("{path}: JSON: {error}")]
    Json { path: PathBuf, error: serde_json::Error },
    #[error("{path}: {reason}")]
    Format { path: PathBuf, reason: String },
}

const FLYAWAY_MAGIC: &[u8; 4] = b"FLYV";
const FLYAWAY_VERSION: u32 = 1;
const FLYAWAY_RECORD: usize = 48;
const FLYAWAY_HEADER: usize = 32;
/// Identifies `geometry.json`.
pub const REPORT_FORMAT: &str = "fabric-geometry";
pub const REPORT_VERSION: u32 = 1;

/// `geometry.json`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GeometryReport {
    pub format: String,
    pub version: u32,
    /// Map size [nx, ny] (texels = volume columns).
    pub dims: [usize; 2],
    /// The volume's nz.
    pub depth: usize,
    /// World size of a voxel.
    pub voxel_size: [f32; 3],
    /// Filter size [x, y] in texels.
    pub filter_size: [f32; 2],
    pub filter_auto: bool,
    /// First peaks of C0, C1 in texels (null: none).
    pub autocorrelation_peaks: [Option<f32>; 2],
    /// Gaussian σ [x, y] in texels that made h.
    pub blur_sigma: [f32; 2],
    /// One fiber's thickness in voxels.
    pub fiber_thickness: f32,
    pub fiber_thickness_auto: bool,
    pub flyaway_voxels: usize,
    /// Longest per-column list of V.
    pub flyaway_max_column: usize,
    /// [min, max] of h0 in voxels.
    pub height_range: [f32; 2],
    /// [min, max] of h in voxels.
    pub smooth_height_range: [f32; 2],
    pub density: DensityScale,
    pub hole_columns: usize,
    pub filled_columns: usize,
    pub clipped_columns: usize,
    pub tangent_fallback_texels: usize,
    pub warnings: Vec<String>,
    /// Seconds per stage, in pipeline order.
    pub stage_times: Vec<StageTime>,
    pub total_seconds: f64,
    /// Normalized C0 (along x) and C1 (along y).
    pub autocorrelation: [Vec<f32>; 2],
    /// The data files beside this one.
    pub files: Files,
}

/// Names of the data files.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Files {
    pub h0: String,
    pub h: String,
    pub surface_top: String,
    pub normals: String,
    pub tangents: String,
    pub flyaways: String,
}

impl Default for Files {
    fn default() -> Self {
        Files { h0: "h0.exr".into(), h: "h.exr".into(), surface_top: "surface_top.exr".into(), normals: "normals.exr".into(), tangents: "tangents.exr".into(), flyaways: "flyaways.bin".into() }
    }
}

impl Geometry {
    /// The numbers of `geometry.json`. `sigma_per_filter_size` records the blur width.
    pub fn report(&self, sigma_per_filter_size: f32) -> GeometryReport {
        GeometryReport {
            format: REPORT_FORMAT.into(),
            version: REPORT_VERSION,
            dims: self.dims,
            depth: self.depth,
            voxel_size: self.voxel_size.to_array(),
            filter_size: self.filter_size,
            filter_auto: self.filter_auto,
            autocorrelation_peaks: self.autocorrelation_peaks,
            blur_sigma: self.filter_size.map(|s| s * sigma_per_filter_size),
            fiber_thickness: self.fiber_thickness,
            fiber_thickness_auto: self.fiber_thickness_auto,
            flyaway_voxels: self.flyaways.len(),
            flyaway_max_column: self.flyaways.max_column_len(),
            height_range: Geometry::range(&self.h0),
            smooth_height_range: Geometry::range(&self.h),
            density: self.density,
            hole_columns: self.hole_columns,
            filled_columns: self.filled_columns,
            clipped_columns: self.clipped_columns,
            tangent_fallback_texels: self.tangent_fallback_texels,
            warnings: self.warnings.clone(),
            stage_times: self.stage_times.clone(),
            total_seconds: self.stage_times.iter().map(|s| s.seconds).sum(),
            autocorrelation: self.autocorrelation.clone(),
            files: Files::default(),
        }
    }

    /// Writes `geometry.json` and the data files into `dir` (created if missing).
    pub fn write_dir(&self, dir: &Path, sigma_per_filter_size: f32) -> Result<GeometryReport, GeometryIoError> {
        std::fs::create_dir_all(dir).map_err(|error| GeometryIoError::Io { path: dir.into(), error })?;
        let report = self.report(sigma_per_filter_size);
        let [nx, ny] = self.dims;
        write_scalar_exr(&dir.join(&report.files.h0), nx, ny, &self.h0)?;
        write_scalar_exr(&dir.join(&report.files.h), nx, ny, &self.h)?;
        let top: Vec<f32> = self.surface_top.iter().map(|&t| t as f32).collect();
        write_scalar_exr(&dir.join(&report.files.surface_top), nx, ny, &top)?;
        vector_image(nx, ny, &self.normals).write(&dir.join(&report.files.normals), 1.0)?;
        vector_image(nx, ny, &self.tangents).write(&dir.join(&report.files.tangents), 1.0)?;
        write_flyaways(&dir.join(&report.files.flyaways), &self.flyaways)?;
        let path = dir.join("geometry.json");
        let json = serde_json::to_string_pretty(&report).map_err(|error| GeometryIoError::Json { path: path.clone(), error })?;
        std::fs::write(&path, json).map_err(|error| GeometryIoError::Io { path, error })?;
        Ok(report)
    }

    /// Reads what [`Geometry::write_dir`] wrote.
    pub fn read_dir(dir: &Path) -> Result<Geometry, GeometryIoError> {
        let path = dir.join("geometry.json");
        let text = std::fs::read_to_string(&path).map_err(|error| GeometryIoError::Io { path: path.clone(), error })?;
        let r: GeometryReport = serde_json::from_str(&text).map_err(|error| GeometryIoError::Json { path: path.clone(), error })?;
        let bad = |reason: String| GeometryIoError::Format { path: path.clone(), reason };
        if r.format != REPORT_FORMAT || r.version != REPORT_VERSION {
            return Err(bad(format!("format {:?} version {} (expected {REPORT_FORMAT:?} version {REPORT_VERSION})", r.format, r.version)));
        }
        let [nx, ny] = r.dims;
        if nx == 0 || ny == 0 || r.depth == 0 || nx.saturating_mul(ny).saturating_mul(r.depth) > 1 << 36 {
            return Err(bad(format!("dims {:?} × depth {} are empty or too large", r.dims, r.depth)));
        }
        if r.autocorrelation[0].len() != nx || r.autocorrelation[1].len() != ny {
            return Err(bad(format!("autocorrelation lengths {} and {} do not match dims {:?}", r.autocorrelation[0].len(), r.autocorrelation[1].len(), r.dims)));
        }
        let h0 = read_scalar_exr(&dir.join(&r.files.h0), nx, ny)?;
        let h = read_scalar_exr(&dir.join(&r.files.h), nx, ny)?;
        let top_path = dir.join(&r.files.surface_top);
        let surface_top = read_scalar_exr(&top_path, nx, ny)?
            .into_iter()
            .enumerate()
            .map(|(k, t)| {
                if t.fract() == 0.0 && t >= -1.0 && t < r.depth as f32 {
                    Ok(t as i32)
                } else {
                    Err(GeometryIoError::Format { path: top_path.clone(), reason: format!("texel ({}, {}) = {t} is not a voxel index in [-1, {})", k % nx, k / nx, r.depth) })
                }
            })
            .collect::<Result<Vec<i32>, _>>()?;
        let normals = read_vector_exr(&dir.join(&r.files.normals), nx, ny)?;
        let tangents = read_vector_exr(&dir.join(&r.files.tangents), nx, ny)?;
        let flyaways = read_flyaways(&dir.join(&r.files.flyaways), [nx, ny, r.depth])?;
        Ok(Geometry {
            dims: r.dims,
            depth: r.depth,
            voxel_size: Vec3::from_array(r.voxel_size),
            h0,
            surface_top,
            h,
            normals,
            tangents,
            flyaways,
            filter_size: r.filter_size,
            filter_auto: r.filter_auto,
            autocorrelation_peaks: r.autocorrelation_peaks,
            autocorrelation: r.autocorrelation,
            fiber_thickness: r.fiber_thickness,
            fiber_thickness_auto: r.fiber_thickness_auto,
            density: r.density,
            hole_columns: r.hole_columns,
            filled_columns: r.filled_columns,
            clipped_columns: r.clipped_columns,
            tangent_fallback_texels: r.tangent_fallback_texels,
            warnings: r.warnings,
            stage_times: r.stage_times,
        })
    }
}

fn vector_image(nx: usize, ny: usize, v: &[Vec3]) -> Image {
    Image { width: nx as u32, height: ny as u32, pixels: v.to_vec() }
}

fn write_scalar_exr(path: &Path, nx: usize, ny: usize, values: &[f32]) -> Result<(), GeometryIoError> {
    use exr::prelude::*;
    if let Some(k) = values.iter().position(|v| !v.is_finite()) {
        return Err(GeometryIoError::Format { path: path.into(), reason: format!("texel ({}, {}) is {} (not finite); refusing to write", k % nx, k / nx, values[k]) });
    }
    let channels = SpecificChannels::build().with_channel("Y").with_pixel_fn(|p: Vec2<usize>| (values[p.x() + nx * p.y()],));
    Image::from_channels((nx, ny), channels).write().to_file(path).map_err(|error| GeometryIoError::Exr { path: path.into(), error })
}

fn read_scalar_exr(path: &Path, nx: usize, ny: usize) -> Result<Vec<f32>, GeometryIoError> {
    use exr::prelude::*;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .specific_channels()
        .required("Y")
        .collect_pixels(|res, _| (res.width(), vec![0f32; res.width() * res.height()]), |(w, px), p, (y,): (f32,)| px[p.y() * *w + p.x()] = y)
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|error| GeometryIoError::Exr { path: path.into(), error })?;
    let size = image.layer_data.size;
    if (size.width(), size.height()) != (nx, ny) {
        return Err(GeometryIoError::Format { path: path.into(), reason: format!("is {}x{}, expected {nx}x{ny}", size.width(), size.height()) });
    }
    let (_, values) = image.layer_data.channel_data.pixels;
    if let Some(k) = values.iter().position(|v| !v.is_finite()) {
        return Err(GeometryIoError::Format { path: path.into(), reason: format!("texel ({}, {}) is not finite", k % nx, k / nx) });
    }
    Ok(values)
}

fn read_vector_exr(path: &Path, nx: usize, ny: usize) -> Result<Vec<Vec3>, GeometryIoError> {
    let img = Image::read(path, 1.0)?;
    if (img.width as usize, img.height as usize) != (nx, ny) {
        return Err(GeometryIoError::Format { path: path.into(), reason: format!("is {}x{}, expected {nx}x{ny}", img.width, img.height) });
    }
    if let Some(k) = img.pixels.iter().position(|v| !v.is_finite() || (v.length() - 1.0).abs() > 1e-3) {
        return Err(GeometryIoError::Format { path: path.into(), reason: format!("texel ({}, {}) = {} is not a unit vector", k % nx, k / nx, img.pixels[k]) });
    }
    Ok(img.pixels)
}

/// Writes V as `flyaways.bin` (layout in the module docs).
pub fn write_flyaways(path: &Path, v: &FlyawayVolume) -> Result<(), GeometryIoError> {
    let mut bytes = Vec::with_capacity(FLYAWAY_HEADER + FLYAWAY_RECORD * v.len());
    bytes.extend_from_slice(FLYAWAY_MAGIC);
    bytes.extend_from_slice(&FLYAWAY_VERSION.to_le_bytes());
    for d in v.dims {
        bytes.extend_from_slice(&(d as u32).to_le_bytes());
    }
    bytes.extend_from_slice(&(FLYAWAY_RECORD as u32).to_le_bytes());
    bytes.extend_from_slice(&(v.len() as u64).to_le_bytes());
    for f in &v.voxels {
        for u in [f.x, f.y, f.z] {
            bytes.extend_from_slice(&u.to_le_bytes());
        }
        for x in [f.density, f.albedo.x, f.albedo.y, f.albedo.z, f.orientation.x, f.orientation.y, f.orientation.z, f.fiber_diameter] {
            bytes.extend_from_slice(&x.to_le_bytes());
        }
        bytes.extend_from_slice(&0u32.to_le_bytes());
    }
    std::fs::write(path, bytes).map_err(|error| GeometryIoError::Io { path: path.into(), error })
}

/// Reads `flyaways.bin`, checking it against the expected volume dims.
pub fn read_flyaways(path: &Path, dims: [usize; 3]) -> Result<FlyawayVolume, GeometryIoError> {
    let bytes = std::fs::read(path).map_err(|error| GeometryIoError::Io { path: path.into(), error })?;
    parse_flyaways(&bytes, dims).map_err(|reason| GeometryIoError::Format { path: path.into(), reason })
}

fn parse_flyaways(bytes: &[u8], dims: [usize; 3]) -> Result<FlyawayVolume, String> {
    let u32_at = |o: usize| -> Result<u32, String> {
        bytes.get(o..o + 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])).ok_or_else(|| format!("truncated at byte {o} (file is {} bytes)", bytes.len()))
    };
    if bytes.get(0..4) != Some(FLYAWAY_MAGIC) {
        return Err(format!("bad magic {:?} (expected \"FLYV\")", bytes.get(0..4.min(bytes.len())).unwrap_or(&[])));
    }
    let version = u32_at(4)?;
    if version != FLYAWAY_VERSION {
        return Err(format!("version {version} (this reader knows {FLYAWAY_VERSION})"));
    }
    let file_dims = [u32_at(8)? as usize, u32_at(12)? as usize, u32_at(16)? as usize];
    if file_dims != dims {
        return Err(format!("volume dims {file_dims:?} do not match the geometry's {dims:?}"));
    }
    let record = u32_at(20)? as usize;
    if record != FLYAWAY_RECORD {
        return Err(format!("record size {record} (expected {FLYAWAY_RECORD})"));
    }
    let count = bytes.get(24..32).map(|b| u64::from_le_bytes(b.try_into().unwrap_or([0; 8]))).ok_or("truncated header")?;
    let expected = (count as u128) * FLYAWAY_RECORD as u128 + FLYAWAY_HEADER as u128;
    if expected != bytes.len() as u128 {
        return Err(format!("count {count} needs {expected} bytes, file has {}", bytes.len()));
    }
    let [nx, ny, nz] = dims;
    let f32_at = |o: usize| u32_at(o).map(f32::from_bits);
    let mut voxels = Vec::with_capacity(count as usize);
    let mut last_key: Option<(usize, usize)> = None;
    for k in 0..count as usize {
        let o = FLYAWAY_HEADER + k * FLYAWAY_RECORD;
        let (x, y, z) = (u32_at(o)?, u32_at(o + 4)?, u32_at(o + 8)?);
        if x as usize >= nx || y as usize >= ny || z as usize >= nz {
            return Err(format!("record {k}: voxel ({x}, {y}, {z}) outside the volume {dims:?}"));
        }
        let key = (x as usize + nx * y as usize, z as usize);
        if last_key.is_some_and(|l| key <= l) {
            return Err(format!("record {k}: voxel ({x}, {y}, {z}) out of column order"));
        }
        last_key = Some(key);
        let vals: Vec<f32> = (0..8).map(|m| f32_at(o + 12 + 4 * m)).collect::<Result<_, _>>()?;
        if vals.iter().any(|v| !v.is_finite()) {
            return Err(format!("record {k}: non-finite value {vals:?}"));
        }
        let orientation = Vec3::new(vals[4], vals[5], vals[6]);
        if !(vals[0] > 0.0) || (orientation.length() - 1.0).abs() > 1e-3 || vals[7] < 0.0 || vals[1..4].iter().any(|a| !(0.0..=1.0).contains(a)) {
            return Err(format!("record {k}: density {} must be > 0, albedo in [0, 1], orientation unit, diameter ≥ 0 (got {vals:?})", vals[0]));
        }
        voxels.push(FlyawayVoxel { x, y, z, density: vals[0], albedo: Vec3::new(vals[1], vals[2], vals[3]), orientation, fiber_diameter: vals[7] });
    }
    Ok(FlyawayVolume::from_sorted(dims, voxels))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_flyaway_files_are_rejected_with_reasons() {
        let vox = FlyawayVoxel { x: 1, y: 2, z: 3, density: 0.5, albedo: Vec3::splat(0.8), orientation: Vec3::X, fiber_diameter: 2.0 };
        let v = FlyawayVolume::from_sorted([4, 4, 8], vec![vox]);
        let dir = std::env::temp_dir().join(format!("fabric-flyaways-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("f.bin");
        write_flyaways(&path, &v).unwrap();
        assert_eq!(read_flyaways(&path, [4, 4, 8]).unwrap(), v);
        let good = std::fs::read(&path).unwrap();
        let check = |bytes: &[u8], dims: [usize; 3], want: &str| {
            let err = parse_flyaways(bytes, dims).unwrap_err();
            assert!(err.contains(want), "{err}");
        };
        check(&good, [4, 4, 9], "do not match");
        check(&good[..40], [4, 4, 8], "needs");
        check(b"NOPE", [4, 4, 8], "bad magic");
        check(&[], [4, 4, 8], "bad magic");
        let mut b = good.clone();
        b[32..36].copy_from_slice(&9u32.to_le_bytes());
        check(&b, [4, 4, 8], "outside");
        let mut b = good.clone();
        b[44..48].copy_from_slice(&f32::NAN.to_le_bytes());
        check(&b, [4, 4, 8], "non-finite");
        let mut b = good.clone();
        b[24..32].copy_from_slice(&u64::MAX.to_le_bytes());
        check(&b, [4, 4, 8], "needs");
        std::fs::remove_dir_all(&dir).ok();
    }
}
