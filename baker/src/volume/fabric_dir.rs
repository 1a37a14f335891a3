//! A fabric on disk: a directory with `density.vol` (1 channel), `albedo.vol` (3),
//! `orientation.vol` (3; unit vectors where ρ > 0, sign irrelevant) and an optional
//! `material.toml` (docs/DESIGN.md §3). World units are those of the `.vol`
//! bounding box.
//!
//! Loading streams the three files slab by slab, validates every voxel and packs it
//! (grid.rs says what packing loses), so a 1024×1024×128 fabric needs its 1.6 GB of
//! packed voxels plus a few tens of MB of buffers. Nothing is fixed silently: the first
//! bad voxel of each kind is reported with its file, position and value, and how many
//! there are.

use std::path::{Path, PathBuf};

use glam::Vec3;
use indicatif::ProgressBar;
use rayon::prelude::*;

use super::error::VolumeError;
use super::grid::{FabricVolume, MAX_DENSITY, Voxel};
use super::material::{MaterialFile, MaterialOverrides};
use super::vol::{Encoding, UNIT_TOLERANCE, VolHeader, VolReader, VolWriter, unflatten};

pub const DENSITY_FILE: &str = "density.vol";
pub const ALBEDO_FILE: &str = "albedo.vol";
pub const ORIENTATION_FILE: &str = "orientation.vol";
pub const MATERIAL_FILE: &str = "material.toml";

/// Voxels decoded per streamed chunk (whole slabs, at least one).
const CHUNK_VOXELS: usize = 1 << 20;
/// Voxels validated per parallel task (fixed, so results do not depend on threads).
const BLOCK_VOXELS: usize = 1 << 14;

/// Loads and validates a fabric directory. `overrides` (the `--density-scale` and
/// `--roughness` flags) win over `material.toml`.
pub fn load_fabric(dir: &Path, overrides: &MaterialOverrides) -> Result<FabricVolume, VolumeError> {
    load_fabric_with_progress(dir, overrides, &ProgressBar::hidden())
}

/// What a loader assumed for want of `material.toml`: `None` when the file exists or the
/// flags gave every value, else a line naming the defaults taken. A measured volume comes
/// without the file, and a silent density scale changes every image, so the tools print it.
pub fn material_defaults_note(dir: &Path, overrides: &MaterialOverrides) -> Option<String> {
    if dir.join(MATERIAL_FILE).exists() {
        return None;
    }
    let d = super::MaterialParams::default();
    let mut taken = Vec::new();
    if overrides.density_scale.is_none() {
        taken.push(format!("density_scale = {} per world unit (--density-scale)", d.density_scale));
    }
    if overrides.roughness.is_none() {
        taken.push(format!("roughness = {} (--roughness)", d.roughness));
    }
    (!taken.is_empty()).then(|| format!("note: {} has no {MATERIAL_FILE}; using the defaults {}", dir.display(), taken.join(" and ")))
}

/// [`load_fabric`] reporting slabs read on `progress` (its length is set here).
pub fn load_fabric_with_progress(dir: &Path, overrides: &MaterialOverrides, progress: &ProgressBar) -> Result<FabricVolume, VolumeError> {
    let meta = std::fs::metadata(dir).map_err(|e| VolumeError::io(dir, e))?;
    if !meta.is_dir() {
        return Err(VolumeError::io(dir, std::io::Error::new(std::io::ErrorKind::NotADirectory, "not a fabric directory")));
    }
    let paths = [DENSITY_FILE, ALBEDO_FILE, ORIENTATION_FILE].map(|f| dir.join(f));
    for p in &paths {
        if !p.exists() {
            return Err(VolumeError::MissingFile { path: p.clone() });
        }
    }
    let material_path = dir.join(MATERIAL_FILE);
    let material = MaterialFile::read_or_default(&material_path)?.resolve(overrides, &material_path)?;

    let mut readers = [VolReader::open(&paths[0])?, VolReader::open(&paths[1])?, VolReader::open(&paths[2])?];
    for (r, (role, channels)) in readers.iter().zip([("density", 1), ("albedo", 3), ("orientation", 3)]) {
        if r.header.channels != channels {
            return Err(VolumeError::WrongChannels { path: r.path.clone(), role, found: r.header.channels, expected: channels });
        }
    }
    let h0 = readers[0].header;
    for r in &readers[1..] {
        check_same_grid(&h0, &paths[0], &r.header, &r.path)?;
    }

    let [nx, ny, nz] = h0.dims;
    let slab = nx * ny;
    let slabs_per_chunk = (CHUNK_VOXELS / slab).max(1);
    let mut voxels = super::grid::try_voxels(h0.dims).map_err(|why| VolumeError::BadDimensions { path: paths[0].clone(), dims: h0.dims.map(|d| d as i64), why })?;
    let mut issues = Issues::default();
    let (mut raw, mut rho, mut alb, mut ori) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    progress.set_length(nz as u64);
    let mut z0 = 0;
    while z0 < nz {
        let n = slabs_per_chunk.min(nz - z0);
        readers[0].read_slabs(n, &mut raw, &mut rho)?;
        readers[1].read_slabs(n, &mut raw, &mut alb)?;
        readers[2].read_slabs(n, &mut raw, &mut ori)?;
        let base = z0 * slab;
        let out = &mut voxels[base..base + n * slab];
        let chunk_issues: Vec<Issues> = out
            .par_chunks_mut(BLOCK_VOXELS)
            .enumerate()
            .map(|(b, block)| {
                let start = b * BLOCK_VOXELS;
                let mut is = Issues::default();
                for (k, v) in block.iter_mut().enumerate() {
                    let i = start + k;
                    *v = check_and_pack(base + i, rho[i], &alb[3 * i..3 * i + 3], &ori[3 * i..3 * i + 3], &mut is);
                }
                is
            })
            .collect();
        for is in chunk_issues {
            issues.merge(is);
        }
        z0 += n;
        progress.set_position(z0 as u64);
    }
    issues.into_result(&paths, h0.dims)?;
    FabricVolume::from_voxels(h0.dims, h0.bbox, voxels, material).ok_or_else(|| VolumeError::DataLength {
        path: paths[0].clone(),
        actual: 0,
        expected: slab * nz,
        dims: h0.dims.map(|d| d as i64),
        channels: 1,
    })
}

fn check_same_grid(a: &VolHeader, a_path: &Path, b: &VolHeader, b_path: &Path) -> Result<(), VolumeError> {
    let mismatch = |what, found: String, expected: String| VolumeError::Mismatch { path: b_path.to_path_buf(), reference: a_path.to_path_buf(), what, found, expected };
    if a.dims != b.dims {
        let f = |d: [usize; 3]| format!("{}x{}x{}", d[0], d[1], d[2]);
        return Err(mismatch("resolution", f(b.dims), f(a.dims)));
    }
    if a.bbox != b.bbox {
        let f = |h: &VolHeader| format!("{:?}..{:?}", h.bbox.min.to_array(), h.bbox.max.to_array());
        return Err(mismatch("bounding box", f(b), f(a)));
    }
    Ok(())
}

/// First bad voxel (flat index, value, problem) and count, for one kind of value.
#[derive(Default)]
struct Issue {
    first: Option<(usize, String, &'static str)>,
    count: u64,
}

impl Issue {
    fn add(&mut self, index: usize, value: impl FnOnce() -> String, problem: &'static str) {
        if self.first.is_none() {
            self.first = Some((index, value(), problem));
        }
        self.count += 1;
    }
}

#[derive(Default)]
struct Issues {
    density: Issue,
    albedo: Issue,
    orientation: Issue,
}

impl Issues {
    /// Appends issues found later in file order.
    fn merge(&mut self, later: Issues) {
        for (a, b) in [(&mut self.density, later.density), (&mut self.albedo, later.albedo), (&mut self.orientation, later.orientation)] {
            if a.first.is_none() {
                a.first = b.first;
            }
            a.count += b.count;
        }
    }

    fn into_result(self, paths: &[PathBuf; 3], dims: [usize; 3]) -> Result<(), VolumeError> {
        for ((issue, path), what) in [self.density, self.albedo, self.orientation].into_iter().zip(paths).zip(["density", "albedo", "orientation"]) {
            if let Some((i, value, problem)) = issue.first {
                let [x, y, z] = unflatten(i, dims);
                return Err(VolumeError::BadValue { path: path.clone(), what, x, y, z, value, problem, count: issue.count });
            }
        }
        Ok(())
    }
}

/// Validates one voxel (DESIGN.md §3: no NaN/Inf/negative density, albedo in [0, 1],
/// unit orientation where ρ > 0) and packs it. The orientation of an empty voxel is
/// never used, so it is not checked.
#[inline]
fn check_and_pack(index: usize, rho: f32, a: &[f32], w: &[f32], is: &mut Issues) -> Voxel {
    if !rho.is_finite() {
        is.density.add(index, || rho.to_string(), "not finite");
    } else if rho < 0.0 {
        is.density.add(index, || rho.to_string(), "negative");
    } else if rho > MAX_DENSITY {
        is.density.add(index, || rho.to_string(), "above 65504, the largest density a packed voxel holds");
    }
    let albedo = Vec3::new(a[0], a[1], a[2]);
    if !a.iter().all(|c| (0.0..=1.0).contains(c)) {
        is.albedo.add(index, || format!("{albedo}"), "outside [0, 1] (or not finite)");
    }
    let dir = Vec3::new(w[0], w[1], w[2]);
    if rho > 0.0 {
        let len = dir.length();
        if !dir.is_finite() {
            is.orientation.add(index, || format!("{dir}"), "not finite where density > 0");
        } else if len == 0.0 {
            is.orientation.add(index, || format!("{dir}"), "zero where density > 0");
        } else if (len - 1.0).abs() > UNIT_TOLERANCE {
            is.orientation.add(index, || format!("{dir} (length {len})"), "not a unit vector where density > 0");
        }
    }
    Voxel::pack(rho, albedo, dir)
}

/// How `save_fabric_with` stores the grids.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SaveEncoding {
    /// float32 everywhere: what Mitsuba 3 reads. Lossless for the packed voxels.
    #[default]
    Float32,
    /// Mitsuba 0.5/0.6's compact encodings: density and albedo uint8 (error ≤ 1/510;
    /// density must be ≤ 1), orientation as quantized directions (≤ 0.79°).
    /// A quarter of the size.
    Compact,
}

/// Options of [`save_fabric_with`].
#[derive(Clone, Debug, Default)]
pub struct SaveOptions {
    pub encoding: SaveEncoding,
    /// Provenance stored under `[generator]` in `material.toml`.
    pub generator: Option<toml::Table>,
}

/// Writes a fabric directory: three float32 `.vol` files and `material.toml`.
pub fn save_fabric(vol: &FabricVolume, dir: &Path) -> Result<(), VolumeError> {
    save_fabric_with(vol, dir, &SaveOptions::default(), &ProgressBar::hidden())
}

/// Writes a fabric directory (created if missing), streaming slab by slab.
pub fn save_fabric_with(vol: &FabricVolume, dir: &Path, options: &SaveOptions, progress: &ProgressBar) -> Result<(), VolumeError> {
    std::fs::create_dir_all(dir).map_err(|e| VolumeError::io(dir, e))?;
    let (enc_scalar, enc_dir) = match options.encoding {
        SaveEncoding::Float32 => (Encoding::Float32, Encoding::Float32),
        SaveEncoding::Compact => (Encoding::UInt8, Encoding::QuantizedDirections),
    };
    let (dims, bbox) = (vol.dims(), vol.bbox());
    let header = |encoding, channels| VolHeader { encoding, dims, channels, bbox };
    let mut writers = [
        VolWriter::create(&dir.join(DENSITY_FILE), header(enc_scalar, 1))?,
        VolWriter::create(&dir.join(ALBEDO_FILE), header(enc_scalar, 3))?,
        VolWriter::create(&dir.join(ORIENTATION_FILE), header(enc_dir, 3))?,
    ];
    let slab = dims[0] * dims[1];
    let slabs_per_chunk = (CHUNK_VOXELS / slab).max(1);
    let (mut rho, mut alb, mut ori) = (Vec::new(), Vec::new(), Vec::new());
    progress.set_length(dims[2] as u64);
    for (c, chunk) in vol.voxels().chunks(slabs_per_chunk * slab).enumerate() {
        rho.resize(chunk.len(), 0.0);
        alb.resize(3 * chunk.len(), 0.0);
        ori.resize(3 * chunk.len(), 0.0);
        let unit_for_empty = enc_dir == Encoding::QuantizedDirections;
        (chunk.par_chunks(BLOCK_VOXELS), rho.par_chunks_mut(BLOCK_VOXELS), alb.par_chunks_mut(3 * BLOCK_VOXELS), ori.par_chunks_mut(3 * BLOCK_VOXELS))
            .into_par_iter()
            .for_each(|(v, r, a, o)| {
                for (k, vox) in v.iter().enumerate() {
                    r[k] = vox.density();
                    a[3 * k..3 * k + 3].copy_from_slice(&vox.albedo().to_array());
                    // Empty voxels get the zero vector, as in published data, unless the
                    // encoding holds unit vectors only.
                    let w = if vox.is_empty() && !unit_for_empty { Vec3::ZERO } else { vox.orientation() };
                    o[3 * k..3 * k + 3].copy_from_slice(&w.to_array());
                }
            });
        writers[0].write(&rho)?;
        writers[1].write(&alb)?;
        writers[2].write(&ori)?;
        progress.set_position((((c + 1) * slabs_per_chunk).min(dims[2])) as u64);
    }
    for w in writers {
        w.finish()?;
    }
    let m = vol.material;
    MaterialFile { density_scale: Some(m.density_scale), roughness: Some(m.roughness), generator: options.generator.clone() }.write(&dir.join(MATERIAL_FILE))
}
