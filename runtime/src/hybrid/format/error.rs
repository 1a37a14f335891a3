//! Why a hybrid file cannot be read or written.

use std::path::PathBuf;

use crate::hybrid::ModelError;

/// What is wrong with the bytes of a hybrid file (or with a model about to be written).
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    #[error("file is {len} bytes, shorter than the {need}-byte header: not a hybrid model, or truncated")]
    TooShort { len: u64, need: u64 },
    #[error("bad magic {found:02x?}: not a hybrid model file (expected {expected:02x?})")]
    BadMagic { found: [u8; 8], expected: [u8; 8] },
    #[error("format version {major}.{minor} is not supported: this reader reads {supported}.x")]
    UnsupportedVersion { major: u16, minor: u16, supported: u16 },
    #[error("header field {field} = {value} is invalid ({why})")]
    Header { field: &'static str, value: u64, why: &'static str },
    #[error("header checksum mismatch (stored {stored:08x}, computed {computed:08x}): the header is corrupt")]
    HeaderChecksum { stored: u32, computed: u32 },
    #[error("file is {actual} bytes but its header says {declared}: truncated or padded")]
    FileSize { declared: u64, actual: u64 },
    #[error("section table ({count} entries of {entry_size} bytes at offset {offset}) does not fit in the {len}-byte file")]
    TableBounds { offset: u64, count: u32, entry_size: u32, len: u64 },
    #[error("section table checksum mismatch (stored {stored:08x}, computed {computed:08x}): the table is corrupt")]
    TableChecksum { stored: u32, computed: u32 },
    #[error("section {index} ({kind}, level {level}): {why}")]
    Section { index: usize, kind: String, level: u32, why: String },
    #[error("section {index} ({kind}, level {level}): checksum mismatch (stored {stored:08x}, computed {computed:08x}): the data is corrupt")]
    SectionChecksum { index: usize, kind: String, level: u32, stored: u32, computed: u32 },
    #[error("section {index} has unknown kind {kind} and is not flagged optional: written by a newer format version?")]
    UnknownRequired { index: usize, kind: u32 },
    #[error("section {kind} for level {level} appears twice")]
    Duplicate { kind: &'static str, level: u32 },
    #[error("section {kind} {where_} is missing")]
    Missing { kind: &'static str, where_: String },
    #[error("invalid model: {0}")]
    Invalid(#[from] ModelError),
    #[error(transparent)]
    Io(#[from] std::io::Error),
}

/// A [`FormatError`] with the file it is about.
#[derive(Debug, thiserror::Error)]
#[error("{}: {error}", path.display())]
pub struct FileError {
    pub path: PathBuf,
    // Not `#[source]`: the message already carries it, and `{:#}` chains would print it twice.
    pub error: FormatError,
}
