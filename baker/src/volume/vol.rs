//! Mitsuba's binary grid volume (`.vol`), read and written (docs/DESIGN.md §3).
//!
//! Layout, little endian (Mitsuba 0.5 `gridvolume`, Mitsuba 3 `VolumeGrid`):
//!
//! | bytes  | content                                                         |
//! |--------|-----------------------------------------------------------------|
//! | 0–2    | ASCII `VOL`                                                     |
//! | 3      | version, 3                                                      |
//! | 4–7    | i32 encoding: 1 float32, 2 float16, 3 uint8, 4 quantized dirs   |
//! | 8–19   | i32 xres, yres, zres                                            |
//! | 20–23  | i32 channels                                                    |
//! | 24–47  | f32 bounding box: xmin, ymin, zmin, xmax, ymax, zmax            |
//! | 48–    | data, `((z·yres + y)·xres + x)·channels + c`                    |
//!
//! Encodings:
//! - 1 float32: read and written in full (what Mitsuba 3 reads and writes).
//! - 2 float16: IEEE half per value (Mitsuba 0.5 declared it, never read it); cheap,
//!   so read and written.
//! - 3 uint8: byte b ↦ b/255 (Mitsuba 0.5/0.6). Values outside [0, 1] cannot be
//!   written.
//! - 4 quantized directions: 3 channels in 2 bytes, (θ byte i, φ byte j) ↦
//!   (cos φ_j sin θ_i, sin φ_j sin θ_i, cos θ_i) with θ_i = iπ/255, φ_j = 2jπ/255, and
//!   byte 255 meaning θ = π or φ = 0, exactly as Mitsuba 0.5's tables. Unit vectors only;
//!   quantization error (nearest entry) ≤ √((π/510)² + (π/255)²) ≈ 0.79°.
//!
//! Any other encoding is rejected by its number. Sizes are checked against the file
//! length before anything is allocated.

use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use glam::Vec3;
use rayon::prelude::*;

use super::error::VolumeError;
use super::grid::Aabb;

/// Bytes before the data.
pub const HEADER_BYTES: usize = 48;
/// Largest resolution accepted on any axis.
pub const MAX_DIM: i64 = 1 << 16;
/// Largest voxel count accepted (2³⁰ ≈ 1.07 G voxels: 12.9 GB packed in memory).
pub const MAX_VOXELS: u64 = 1 << 30;
/// How far from 1 the length of a direction may be before it counts as non-unit
/// (admits unit vectors stored in half precision or quantized by other tools).
pub const UNIT_TOLERANCE: f32 = 1e-2;

/// How values are stored in a `.vol` file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Encoding {
    Float32,
    Float16,
    UInt8,
    QuantizedDirections,
}

impl Encoding {
    /// The identifier in the header.
    pub fn id(self) -> i32 {
        match self {
            Encoding::Float32 => 1,
            Encoding::Float16 => 2,
            Encoding::UInt8 => 3,
            Encoding::QuantizedDirections => 4,
        }
    }

    pub fn from_id(id: i32) -> Option<Encoding> {
        Some(match id {
            1 => Encoding::Float32,
            2 => Encoding::Float16,
            3 => Encoding::UInt8,
            4 => Encoding::QuantizedDirections,
            _ => return None,
        })
    }

    pub fn name(self) -> &'static str {
        match self {
            Encoding::Float32 => "float32",
            Encoding::Float16 => "float16",
            Encoding::UInt8 => "uint8",
            Encoding::QuantizedDirections => "quantized directions",
        }
    }

    /// Bytes per voxel (all channels).
    pub fn voxel_bytes(self, channels: usize) -> usize {
        match self {
            Encoding::Float32 => 4 * channels,
            Encoding::Float16 => 2 * channels,
            Encoding::UInt8 => channels,
            Encoding::QuantizedDirections => 2,
        }
    }

    fn check_channels(self, channels: i64, path: &Path) -> Result<usize, VolumeError> {
        let (ok, allowed) = match self {
            Encoding::QuantizedDirections => (channels == 3, "exactly 3"),
            _ => ((1..=64).contains(&channels), "1 to 64"),
        };
        if ok {
            Ok(channels as usize)
        } else {
            Err(VolumeError::BadChannels { path: path.to_path_buf(), encoding: self.name(), channels, allowed })
        }
    }
}

/// The parsed 48-byte header.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolHeader {
    pub encoding: Encoding,
    pub dims: [usize; 3],
    pub channels: usize,
    pub bbox: Aabb,
}

fn le_i32(b: &[u8], at: usize) -> i32 {
    i32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn le_f32(b: &[u8], at: usize) -> f32 {
    f32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

impl VolHeader {
    /// Parses and checks a header; `bytes` is the start of the file (any length).
    pub fn parse(bytes: &[u8], path: &Path) -> Result<VolHeader, VolumeError> {
        let p = || path.to_path_buf();
        if bytes.len() < 3 || &bytes[..3] != b"VOL" {
            if bytes.len() < 3 && b"VOL".starts_with(bytes) {
                return Err(VolumeError::TruncatedHeader { path: p(), actual: bytes.len() as u64 });
            }
            return Err(VolumeError::BadMagic { path: p(), found: bytes[..bytes.len().min(3)].to_vec() });
        }
        if bytes.len() < HEADER_BYTES {
            if bytes.len() >= 4 && bytes[3] != 3 {
                return Err(VolumeError::BadVersion { path: p(), version: bytes[3] });
            }
            return Err(VolumeError::TruncatedHeader { path: p(), actual: bytes.len() as u64 });
        }
        if bytes[3] != 3 {
            return Err(VolumeError::BadVersion { path: p(), version: bytes[3] });
        }
        let id = le_i32(bytes, 4);
        let encoding = Encoding::from_id(id).ok_or(VolumeError::UnknownEncoding { path: p(), encoding: id })?;
        let raw = [le_i32(bytes, 8) as i64, le_i32(bytes, 12) as i64, le_i32(bytes, 16) as i64];
        let channels = encoding.check_channels(le_i32(bytes, 20) as i64, path)?;
        let dims = check_dims(raw, path)?;
        let min = [le_f32(bytes, 24), le_f32(bytes, 28), le_f32(bytes, 32)];
        let max = [le_f32(bytes, 36), le_f32(bytes, 40), le_f32(bytes, 44)];
        let bbox = Aabb::new(Vec3::from(min), Vec3::from(max));
        if !bbox.is_valid() {
            return Err(VolumeError::BadBoundingBox { path: p(), min, max });
        }
        Ok(VolHeader { encoding, dims, channels, bbox })
    }

    pub fn voxel_count(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    /// Bytes of data after the header.
    pub fn data_bytes(&self) -> u64 {
        self.voxel_count() as u64 * self.encoding.voxel_bytes(self.channels) as u64
    }

    /// Checks the file length against the header: truncated or oversized.
    pub fn check_file_len(&self, len: u64, path: &Path) -> Result<(), VolumeError> {
        let expected = HEADER_BYTES as u64 + self.data_bytes();
        let dims = self.dims.map(|d| d as i64);
        let (channels, encoding, path) = (self.channels, self.encoding.name(), path.to_path_buf());
        match len.cmp(&expected) {
            std::cmp::Ordering::Less => Err(VolumeError::Truncated { path, actual: len, expected, dims, channels, encoding }),
            std::cmp::Ordering::Greater => Err(VolumeError::Oversized { path, actual: len, expected, dims, channels, encoding }),
            std::cmp::Ordering::Equal => Ok(()),
        }
    }

    pub fn to_bytes(&self) -> [u8; HEADER_BYTES] {
        let mut b = [0u8; HEADER_BYTES];
        b[..3].copy_from_slice(b"VOL");
        b[3] = 3;
        b[4..8].copy_from_slice(&self.encoding.id().to_le_bytes());
        for (i, d) in self.dims.iter().enumerate() {
            b[8 + 4 * i..12 + 4 * i].copy_from_slice(&(*d as i32).to_le_bytes());
        }
        b[20..24].copy_from_slice(&(self.channels as i32).to_le_bytes());
        for (i, v) in self.bbox.min.to_array().into_iter().chain(self.bbox.max.to_array()).enumerate() {
            b[24 + 4 * i..28 + 4 * i].copy_from_slice(&v.to_le_bytes());
        }
        b
    }
}

/// Checks a resolution: every axis in 1..=MAX_DIM and at most MAX_VOXELS cells.
pub fn check_dims(raw: [i64; 3], path: &Path) -> Result<[usize; 3], VolumeError> {
    let bad = |why: String| VolumeError::BadDimensions { path: path.to_path_buf(), dims: raw, why };
    if raw.iter().any(|&d| d <= 0) {
        return Err(bad("every axis needs at least one cell".into()));
    }
    if raw.iter().any(|&d| d > MAX_DIM) {
        return Err(bad(format!("an axis exceeds {MAX_DIM} cells")));
    }
    let n = raw.iter().map(|&d| d as u64).product::<u64>();
    if n > MAX_VOXELS {
        return Err(bad(format!("{n} cells exceed the limit of {MAX_VOXELS}")));
    }
    Ok(raw.map(|d| d as usize))
}

/// Mitsuba 0.5's direction tables: θ_i = iπ/255, φ_j = 2jπ/255 for i, j < 255; byte 255
/// is the special entry (sin θ = 0, cos θ = −1; sin φ = 0, cos φ = 1).
struct DirTables {
    cos_theta: [f32; 256],
    sin_theta: [f32; 256],
    cos_phi: [f32; 256],
    sin_phi: [f32; 256],
}

fn dir_tables() -> &'static DirTables {
    static T: OnceLock<DirTables> = OnceLock::new();
    T.get_or_init(|| {
        let mut t = DirTables { cos_theta: [0.0; 256], sin_theta: [0.0; 256], cos_phi: [0.0; 256], sin_phi: [0.0; 256] };
        for i in 0..255 {
            let a = i as f32 * (std::f32::consts::PI / 255.0);
            (t.cos_theta[i], t.sin_theta[i]) = (a.cos(), a.sin());
            (t.cos_phi[i], t.sin_phi[i]) = ((2.0 * a).cos(), (2.0 * a).sin());
        }
        (t.cos_theta[255], t.sin_theta[255], t.cos_phi[255], t.sin_phi[255]) = (-1.0, 0.0, 1.0, 0.0);
        t
    })
}

/// Decodes whole voxels from `raw` into `out` (channels interleaved, f32).
/// `raw.len()` must be a multiple of the voxel size and `out` hold all its values.
pub fn decode(encoding: Encoding, channels: usize, raw: &[u8], out: &mut [f32]) {
    debug_assert_eq!(raw.len() / encoding.voxel_bytes(channels) * channels, out.len());
    match encoding {
        Encoding::Float32 => {
            for (o, b) in out.iter_mut().zip(raw.chunks_exact(4)) {
                *o = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
            }
        }
        Encoding::Float16 => {
            for (o, b) in out.iter_mut().zip(raw.chunks_exact(2)) {
                *o = half::f16::from_le_bytes([b[0], b[1]]).to_f32();
            }
        }
        Encoding::UInt8 => {
            for (o, b) in out.iter_mut().zip(raw) {
                *o = *b as f32 / 255.0;
            }
        }
        Encoding::QuantizedDirections => {
            let t = dir_tables();
            for (o, b) in out.chunks_exact_mut(3).zip(raw.chunks_exact(2)) {
                let (i, j) = (b[0] as usize, b[1] as usize);
                o[0] = t.cos_phi[j] * t.sin_theta[i];
                o[1] = t.sin_phi[j] * t.sin_theta[i];
                o[2] = t.cos_theta[i];
            }
        }
    }
}

/// A value an encoding cannot hold: (index of the value, or of the voxel for quantized
/// directions; the value as text; why).
pub type Unencodable = (usize, String, &'static str);

/// Encodes values (channels interleaved) and appends the bytes to `out`.
pub fn encode(encoding: Encoding, channels: usize, values: &[f32], out: &mut Vec<u8>) -> Result<(), Unencodable> {
    match encoding {
        Encoding::Float32 => {
            out.reserve(values.len() * 4);
            for (i, v) in values.iter().enumerate() {
                if !v.is_finite() {
                    return Err((i, v.to_string(), "not finite"));
                }
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        Encoding::Float16 => {
            out.reserve(values.len() * 2);
            for (i, v) in values.iter().enumerate() {
                if !v.is_finite() || v.abs() > half::f16::MAX.to_f32() {
                    return Err((i, v.to_string(), "not finite or beyond the float16 range ±65504"));
                }
                out.extend_from_slice(&half::f16::from_f32(*v).to_le_bytes());
            }
        }
        Encoding::UInt8 => {
            out.reserve(values.len());
            for (i, v) in values.iter().enumerate() {
                if !(0.0..=1.0).contains(v) {
                    return Err((i, v.to_string(), "uint8 holds values in [0, 1] only"));
                }
                out.push((v * 255.0).round() as u8);
            }
        }
        Encoding::QuantizedDirections => {
            debug_assert_eq!(channels, 3);
            out.reserve(values.len() / 3 * 2);
            for (i, c) in values.chunks_exact(3).enumerate() {
                let w = Vec3::new(c[0], c[1], c[2]);
                if !w.is_finite() || (w.length() - 1.0).abs() > UNIT_TOLERANCE {
                    return Err((i, format!("{w}"), "quantized directions hold unit vectors only"));
                }
                out.extend_from_slice(&quantize_direction(w.normalize()));
            }
        }
    }
    Ok(())
}

/// The (θ, φ) bytes of a unit vector, rounded to the nearest table entry.
pub fn quantize_direction(w: Vec3) -> [u8; 2] {
    let theta = w.z.clamp(-1.0, 1.0).acos();
    let i = (theta * (255.0 / std::f32::consts::PI)).round().clamp(0.0, 255.0) as u8;
    let phi = w.y.atan2(w.x).rem_euclid(std::f32::consts::TAU);
    // j = 255 would be φ = 2π·255/255 ≡ 0, which is also what byte 255 decodes to.
    let j = ((phi * (255.0 / std::f32::consts::TAU)).round() as u32 % 255) as u8;
    // At the poles φ means nothing; write 0 so ±Z have one code each.
    if i == 0 || i == 255 { [i, 0] } else { [i, j] }
}

/// A single grid held as f32 values (channels interleaved, x fastest, then y, then z).
#[derive(Clone, Debug, PartialEq)]
pub struct VolGrid {
    pub dims: [usize; 3],
    pub channels: usize,
    pub bbox: Aabb,
    pub data: Vec<f32>,
}

impl VolGrid {
    /// Value of channel `c` of voxel (x, y, z).
    pub fn get(&self, x: usize, y: usize, z: usize, c: usize) -> f32 {
        self.data[(x + self.dims[0] * (y + self.dims[1] * z)) * self.channels + c]
    }

    pub fn voxel_count(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }
}

/// A `.vol` file opened for reading: header checked against the file length, data
/// streamed in whole z-slabs.
pub struct VolReader {
    pub path: PathBuf,
    pub header: VolHeader,
    file: std::io::BufReader<File>,
    next_slab: usize,
}

impl VolReader {
    pub fn open(path: &Path) -> Result<VolReader, VolumeError> {
        let file = File::open(path).map_err(|e| VolumeError::io(path, e))?;
        let len = file.metadata().map_err(|e| VolumeError::io(path, e))?.len();
        let mut file = std::io::BufReader::with_capacity(1 << 20, file);
        let mut head = Vec::with_capacity(HEADER_BYTES);
        (&mut file).take(HEADER_BYTES as u64).read_to_end(&mut head).map_err(|e| VolumeError::io(path, e))?;
        let header = VolHeader::parse(&head, path)?;
        header.check_file_len(len, path)?;
        Ok(VolReader { path: path.to_path_buf(), header, file, next_slab: 0 })
    }

    /// Reads the next `n` z-slabs as raw bytes into `raw` (resized).
    pub fn read_slabs_raw(&mut self, n: usize, raw: &mut Vec<u8>) -> Result<(), VolumeError> {
        let h = &self.header;
        let bytes = n * h.dims[0] * h.dims[1] * h.encoding.voxel_bytes(h.channels);
        raw.resize(bytes, 0);
        // The length was checked at open; a short read means the file changed under us.
        self.file.read_exact(raw).map_err(|e| VolumeError::io(&self.path, e))?;
        self.next_slab += n;
        Ok(())
    }

    /// Reads and decodes the next `n` z-slabs into `out` (resized; channels interleaved).
    pub fn read_slabs(&mut self, n: usize, raw: &mut Vec<u8>, out: &mut Vec<f32>) -> Result<(), VolumeError> {
        self.read_slabs_raw(n, raw)?;
        let h = self.header;
        out.resize(n * h.dims[0] * h.dims[1] * h.channels, 0.0);
        decode_parallel(h.encoding, h.channels, raw, out);
        Ok(())
    }

    /// The index of the next slab `read_slabs` returns.
    pub fn next_slab(&self) -> usize {
        self.next_slab
    }
}

/// Decodes in parallel chunks (the result does not depend on the chunking).
pub fn decode_parallel(encoding: Encoding, channels: usize, raw: &[u8], out: &mut [f32]) {
    const VOXELS: usize = 1 << 16;
    let vb = encoding.voxel_bytes(channels);
    raw.par_chunks(VOXELS * vb).zip(out.par_chunks_mut(VOXELS * channels)).for_each(|(r, o)| decode(encoding, channels, r, o));
}

/// Reads a whole grid (any supported encoding) as f32 values.
pub fn read_vol(path: &Path) -> Result<VolGrid, VolumeError> {
    let mut r = VolReader::open(path)?;
    let h = r.header;
    let (mut raw, mut data) = (Vec::new(), Vec::new());
    r.read_slabs(h.dims[2], &mut raw, &mut data)?;
    Ok(VolGrid { dims: h.dims, channels: h.channels, bbox: h.bbox, data })
}

/// A `.vol` file being written slab by slab; `finish` checks that every voxel came.
pub struct VolWriter {
    path: PathBuf,
    header: VolHeader,
    file: BufWriter<File>,
    written: usize,
}

impl VolWriter {
    pub fn create(path: &Path, header: VolHeader) -> Result<VolWriter, VolumeError> {
        check_dims(header.dims.map(|d| d as i64), path)?;
        header.encoding.check_channels(header.channels as i64, path)?;
        if !header.bbox.is_valid() {
            return Err(VolumeError::BadBoundingBox { path: path.to_path_buf(), min: header.bbox.min.to_array(), max: header.bbox.max.to_array() });
        }
        let file = File::create(path).map_err(|e| VolumeError::io(path, e))?;
        let mut file = BufWriter::with_capacity(1 << 20, file);
        file.write_all(&header.to_bytes()).map_err(|e| VolumeError::io(path, e))?;
        Ok(VolWriter { path: path.to_path_buf(), header, file, written: 0 })
    }

    /// Appends values (channels interleaved, whole voxels, in file order).
    pub fn write(&mut self, values: &[f32]) -> Result<(), VolumeError> {
        let c = self.header.channels;
        let total = self.header.voxel_count();
        if !values.len().is_multiple_of(c) || self.written + values.len() / c > total {
            return Err(VolumeError::DataLength {
                path: self.path.clone(),
                actual: self.written * c + values.len(),
                expected: total * c,
                dims: self.header.dims.map(|d| d as i64),
                channels: c,
            });
        }
        // Encode in parallel fixed-size pieces (quantizing directions costs trig per voxel),
        // then write them in order; the first unencodable value in file order is reported.
        const PIECE: usize = 1 << 16;
        let enc = self.header.encoding;
        let pieces: Vec<Result<Vec<u8>, Unencodable>> = values
            .par_chunks(PIECE * c)
            .enumerate()
            .map(|(k, chunk)| {
                let mut out = Vec::new();
                encode(enc, c, chunk, &mut out).map(|_| out).map_err(|(i, v, why)| {
                    let voxel = k * PIECE + if enc == Encoding::QuantizedDirections { i } else { i / c };
                    (voxel, v, why)
                })
            })
            .collect();
        for piece in pieces {
            match piece {
                Ok(bytes) => self.file.write_all(&bytes).map_err(|e| VolumeError::io(&self.path, e))?,
                Err((voxel, value, why)) => {
                    let [x, y, z] = unflatten(self.written + voxel, self.header.dims);
                    return Err(VolumeError::Unencodable { path: self.path.clone(), encoding: enc.name(), value: format!("{value} at voxel ({x}, {y}, {z})"), why });
                }
            }
        }
        self.written += values.len() / c;
        Ok(())
    }

    /// Flushes and checks that the grid is complete.
    pub fn finish(mut self) -> Result<(), VolumeError> {
        let total = self.header.voxel_count();
        if self.written != total {
            let c = self.header.channels;
            return Err(VolumeError::DataLength { path: self.path, actual: self.written * c, expected: total * c, dims: self.header.dims.map(|d| d as i64), channels: c });
        }
        self.file.flush().map_err(|e| VolumeError::io(&self.path, e))?;
        self.file.get_ref().sync_data().ok();
        Ok(())
    }
}

/// (x, y, z) of a flat voxel index.
pub fn unflatten(i: usize, dims: [usize; 3]) -> [usize; 3] {
    [i % dims[0], (i / dims[0]) % dims[1], i / (dims[0] * dims[1])]
}

/// Writes a whole grid in `encoding`.
pub fn write_vol(path: &Path, grid: &VolGrid, encoding: Encoding) -> Result<(), VolumeError> {
    let expected = grid.voxel_count() * grid.channels;
    if grid.data.len() != expected {
        return Err(VolumeError::DataLength { path: path.to_path_buf(), actual: grid.data.len(), expected, dims: grid.dims.map(|d| d as i64), channels: grid.channels });
    }
    let mut w = VolWriter::create(path, VolHeader { encoding, dims: grid.dims, channels: grid.channels, bbox: grid.bbox })?;
    let slab = grid.dims[0] * grid.dims[1] * grid.channels;
    for chunk in grid.data.chunks(slab.max(1) * 16) {
        w.write(chunk)?;
    }
    w.finish()
}
