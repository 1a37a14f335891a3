//! What can be wrong with a fabric volume on disk. Every variant names the file and
//! the problem (value, voxel, field), so a user can find and fix it.

use std::path::PathBuf;

/// Errors from reading, validating and writing fabric volumes.
#[derive(Debug, thiserror::Error)]
pub enum VolumeError {
    /// An operating-system error on `path`.
    #[error("{path}: {error}", path = .path.display())]
    Io { path: PathBuf, error: std::io::Error },

    /// The file does not start with the bytes `VOL`.
    #[error("{path}: not a Mitsuba grid volume: starts with {found:?}, expected the bytes \"VOL\"", path = .path.display())]
    BadMagic { path: PathBuf, found: Vec<u8> },

    /// The version byte is not 3.
    #[error("{path}: .vol format version {version}; only version 3 is supported", path = .path.display())]
    BadVersion { path: PathBuf, version: u8 },

    /// An encoding identifier nobody defined.
    #[error("{path}: unknown .vol encoding {encoding} (known: 1 float32, 2 float16, 3 uint8, 4 quantized directions)", path = .path.display())]
    UnknownEncoding { path: PathBuf, encoding: i32 },

    /// A known encoding with a channel count it cannot hold.
    #[error("{path}: encoding {encoding} cannot hold {channels} channels ({allowed})", path = .path.display())]
    BadChannels { path: PathBuf, encoding: &'static str, channels: i64, allowed: &'static str },

    /// The file ends inside the 48-byte header.
    #[error("{path}: truncated: {actual} bytes, shorter than the 48-byte .vol header", path = .path.display())]
    TruncatedHeader { path: PathBuf, actual: u64 },

    /// The file is shorter than its header says.
    #[error("{path}: truncated: {actual} bytes, but a {dims} grid with {channels} channel(s) in {encoding} needs {expected}", path = .path.display(), dims = fmt_dims(.dims))]
    Truncated { path: PathBuf, actual: u64, expected: u64, dims: [i64; 3], channels: usize, encoding: &'static str },

    /// The file is longer than its header says.
    #[error("{path}: oversized: {actual} bytes, but a {dims} grid with {channels} channel(s) in {encoding} takes {expected}; {extra} unexplained trailing bytes", path = .path.display(), dims = fmt_dims(.dims), extra = .actual - .expected)]
    Oversized { path: PathBuf, actual: u64, expected: u64, dims: [i64; 3], channels: usize, encoding: &'static str },

    /// Zero, negative or absurd resolution.
    #[error("{path}: bad dimensions {dims}: {why}", path = .path.display(), dims = fmt_dims(.dims))]
    BadDimensions { path: PathBuf, dims: [i64; 3], why: String },

    /// The bounding box is not finite or has no volume.
    #[error("{path}: bounding box min {min:?} max {max:?} must be finite with max > min on every axis", path = .path.display())]
    BadBoundingBox { path: PathBuf, min: [f32; 3], max: [f32; 3] },

    /// A grid of the fabric has the wrong number of channels for its role.
    #[error("{path}: {role} grid has {found} channel(s); it needs {expected}", path = .path.display())]
    WrongChannels { path: PathBuf, role: &'static str, found: usize, expected: usize },

    /// The grids of one fabric disagree on resolution or bounding box.
    #[error("{path}: {what} {found} differs from {reference}'s {expected}; the three grids of a fabric must match", path = .path.display(), reference = .reference.display())]
    Mismatch { path: PathBuf, reference: PathBuf, what: &'static str, found: String, expected: String },

    /// Bad values (NaN, Inf, negative density, albedo outside [0, 1], non-unit
    /// orientation where ρ > 0): the first bad voxel and how many there are.
    #[error("{path}: voxel ({x}, {y}, {z}) {what} is {value}: {problem} ({count} bad voxel(s) in all)", path = .path.display())]
    BadValue { path: PathBuf, what: &'static str, x: usize, y: usize, z: usize, value: String, problem: &'static str, count: u64 },

    /// A value that an encoding cannot store (writing).
    #[error("{path}: cannot write {value} in encoding {encoding}: {why}", path = .path.display())]
    Unencodable { path: PathBuf, encoding: &'static str, value: String, why: &'static str },

    /// A file a fabric directory needs is not there.
    #[error("{path}: missing; a fabric directory holds density.vol, albedo.vol and orientation.vol (and optionally material.toml)", path = .path.display())]
    MissingFile { path: PathBuf },

    /// `material.toml` (or an override flag) is malformed or out of range.
    #[error("{path}: {message}", path = .path.display())]
    Material { path: PathBuf, message: String },

    /// A grid handed to the writer whose data length disagrees with its header.
    #[error("{path}: grid has {actual} values but {dims} × {channels} channel(s) needs {expected}", path = .path.display(), dims = fmt_dims(.dims))]
    DataLength { path: PathBuf, actual: usize, expected: usize, dims: [i64; 3], channels: usize },
}

pub(crate) fn fmt_dims(d: &[i64; 3]) -> String {
    format!("{}x{}x{}", d[0], d[1], d[2])
}

impl VolumeError {
    pub(crate) fn io(path: impl Into<PathBuf>, error: std::io::Error) -> VolumeError {
        VolumeError::Io { path: path.into(), error }
    }
}
