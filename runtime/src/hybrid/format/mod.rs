//! The hybrid model file (`.hyb`): one binary file per material, laid out for memory
//! mapping and GPU upload. The byte-by-byte specification is runtime/HYBRID_FORMAT.md;
//! this module holds its constants, and [`writer`] / [`reader`] implement it.
//!
//! In short: a 64-byte header (magic, version, file size, where the section table is,
//! CRC-32s of the header and of the table), a table of 32-byte section entries (kind,
//! flags, level, CRC-32, offset, length), and sections at 64-byte-aligned offsets, each
//! a little-endian array of the model's packed records. Readers reject unknown major
//! versions, skip unknown sections flagged optional (adding one is a minor version
//! bump), and reject unknown required ones.

pub mod error;
pub mod mutate;
pub mod reader;
pub mod writer;

pub use error::{FileError, FormatError};
pub use reader::{FileInfo, SectionInfo, inspect, inspect_file, read, read_file};
pub use writer::{to_bytes, write_file};

// The records are copied to and from the file as native-endian bytes.
#[cfg(target_endian = "big")]
compile_error!("the hybrid file format is little endian; this reader assumes a little-endian host");

/// The first 8 bytes: a non-ASCII byte, "HYB", CR LF, ^Z, LF (PNG's trick: text-mode
/// transfers and truncating tools damage it visibly).
pub const MAGIC: [u8; 8] = [0x89, b'H', b'Y', b'B', b'\r', b'\n', 0x1a, b'\n'];
/// Readers reject other major versions.
pub const VERSION_MAJOR: u16 = 1;
/// Bumped when optional sections or trailing fields are added.
pub const VERSION_MINOR: u16 = 16;
/// Size of the header this version writes (readers accept larger ones).
pub const HEADER_SIZE: usize = 64;
/// Size of a section-table entry this version writes (readers accept larger ones).
pub const SECTION_ENTRY_SIZE: usize = 32;
/// Every section starts at a multiple of this.
pub const SECTION_ALIGN: u64 = 64;
/// Most sections a file may declare.
pub const MAX_SECTIONS: u32 = 4096;
/// Section flag: a reader that does not know the kind may skip the section.
pub const SECTION_OPTIONAL: u32 = 1;
/// Size of the MODEL section this version writes.
pub const MODEL_SECTION_SIZE: usize = 64;
/// MODEL flags bit 0: the fit assumed height-field shadowing.
pub const MODEL_FLAG_SHADOWING: u32 = 1;
/// MODEL flags bit 1: surface hits carry the volumetric factor 2/(μ_i + μ_o) (1.1).
pub const MODEL_FLAG_VOLUMETRIC: u32 = 2;
/// MODEL flags bit 2: the coarse levels' BRDFs carry the light's height-field
/// visibility; renderers shade levels ≥ 1 without shadow rays (1.2).
pub const MODEL_FLAG_COARSE_VISIBILITY: u32 = 4;
/// MODEL flags bit 3: surface texels' diffuse term follows the Lommel–Seeliger law
/// ([`crate::brdf::DiffuseLaw::LommelSeeliger`]; 1.6).
pub const MODEL_FLAG_DIFFUSE_LS: u32 = 8;
/// The flyaways' lobes follow the cylinder law ([`crate::brdf::FiberLobes::Cylinder`];
/// 1.11).
pub const MODEL_FLAG_FIBER_CYLINDER: u32 = 16;
/// MODEL flags bit 5: the flyaways in front of a surface hit shadow its lights
/// ([`crate::hybrid::BakeMetadata::flyaway_shadow`]; 1.13).
pub const MODEL_FLAG_FLYAWAY_SHADOW: u32 = 32;

/// Section kinds (runtime/HYBRID_FORMAT.md §"Sections").
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum SectionKind {
    /// Dimensions, level count, tile geometry, BRDF reading, flags. Required, once.
    Model = 1,
    /// The level-0 height field, unorm16 depths. Required, once.
    Height = 2,
    /// Bake metadata. Optional, at most once.
    Meta = 3,
    /// Per level: clustered texels (8 bytes each); its presence selects the clustered encoding.
    SurfaceClusteredTexels = 16,
    /// Per level: BRDF headers (16 bytes each): the cluster table, or one per texel.
    SurfaceHeaders = 17,
    /// Per level: lobes (16 bytes each).
    SurfaceLobes = 18,
    /// Per per-texel level, instead of SURFACE_HEADERS (1.7): compact headers, 8 bytes
    /// each, the lobe offsets implicit ([`crate::hybrid::compact`]).
    SurfaceTexelsCompact = 19,
    /// Per per-texel level, instead of SURFACE_LOBES (1.7): compact lobes, 12 bytes each.
    SurfaceLobesCompact = 20,
    /// Per level: flyaway list heads (u32 per texel).
    FlyawayHeads = 32,
    /// Per level: flyaway nodes (16 bytes each).
    FlyawayNodes = 33,
    /// Per level: flyaway BRDF headers.
    FlyawayHeaders = 34,
    /// Per level: flyaway BRDF lobes.
    FlyawayLobes = 35,
    /// Per coarse level with flyaways, optional (1.5): the spread of each node's fibres,
    /// in direction and in depth (8 bytes per node).
    FlyawaySpread = 36,
    /// Per coarse level with flyaways, optional, instead of FLYAWAY_SPREAD (1.7): the
    /// same records without their reserved field, 6 bytes per node.
    FlyawaySpreadCompact = 37,
    /// Per level with flyaways, instead of FLYAWAY_NODES (1.7): nodes without their
    /// link, 8 bytes each (lists stored column by column).
    FlyawayNodesCompact = 38,
    /// Per coarse level with spread records, optional (1.8): each node's second group of
    /// fibre axes (4 bytes per node).
    FlyawayGroup = 39,
    /// Per coarse level with flyaways, optional (1.9): the gain on the opacity exponent
    /// by polar angle (nine f32, 36 bytes).
    FlyawayPathGain = 40,
    /// Per level, optional (1.3): the transmission term per texel (24 bytes each).
    Transmission = 48,
    /// Per coarse level, optional (1.4): the view tilt per texel (12 bytes each).
    ViewTilt = 49,
    /// Per coarse level, optional, instead of VIEW_TILT (1.7): compact view tilts, 6 bytes each.
    ViewTiltCompact = 50,
    /// Per level, optional (1.12): the visibility gradient per texel (8 bytes each).
    Gradient = 51,
    /// Per level, optional (1.15): the visibility curvature per texel (12 bytes each).
    Curvature = 52,
    /// Per level with TRANSMISSION, optional (1.16): the transmission's visibility
    /// gradient per texel (8 bytes each).
    TransmissionVisibility = 53,
}

impl SectionKind {
    pub const ALL: [SectionKind; 23] = [
        SectionKind::Model,
        SectionKind::Height,
        SectionKind::Meta,
        SectionKind::SurfaceClusteredTexels,
        SectionKind::SurfaceHeaders,
        SectionKind::SurfaceLobes,
        SectionKind::SurfaceTexelsCompact,
        SectionKind::SurfaceLobesCompact,
        SectionKind::FlyawayHeads,
        SectionKind::FlyawayNodes,
        SectionKind::FlyawayHeaders,
        SectionKind::FlyawayLobes,
        SectionKind::FlyawaySpread,
        SectionKind::FlyawaySpreadCompact,
        SectionKind::FlyawayNodesCompact,
        SectionKind::FlyawayGroup,
        SectionKind::FlyawayPathGain,
        SectionKind::Transmission,
        SectionKind::ViewTilt,
        SectionKind::ViewTiltCompact,
        SectionKind::Gradient,
        SectionKind::Curvature,
        SectionKind::TransmissionVisibility,
    ];

    pub fn from_u32(v: u32) -> Option<SectionKind> {
        SectionKind::ALL.into_iter().find(|k| *k as u32 == v)
    }

    /// Whether the section belongs to one level (its entry's `level` field counts).
    pub fn per_level(self) -> bool {
        (self as u32) >= 16
    }

    pub fn name(self) -> &'static str {
        match self {
            SectionKind::Model => "MODEL",
            SectionKind::Height => "HEIGHT",
            SectionKind::Meta => "META",
            SectionKind::SurfaceClusteredTexels => "SURFACE_CLUSTERED_TEXELS",
            SectionKind::SurfaceHeaders => "SURFACE_HEADERS",
            SectionKind::SurfaceLobes => "SURFACE_LOBES",
            SectionKind::FlyawayHeads => "FLYAWAY_HEADS",
            SectionKind::FlyawayNodes => "FLYAWAY_NODES",
            SectionKind::FlyawayHeaders => "FLYAWAY_HEADERS",
            SectionKind::FlyawayLobes => "FLYAWAY_LOBES",
            SectionKind::FlyawaySpread => "FLYAWAY_SPREAD",
            SectionKind::FlyawaySpreadCompact => "FLYAWAY_SPREAD_COMPACT",
            SectionKind::FlyawayNodesCompact => "FLYAWAY_NODES_COMPACT",
            SectionKind::FlyawayGroup => "FLYAWAY_GROUP",
            SectionKind::FlyawayPathGain => "FLYAWAY_PATH_GAIN",
            SectionKind::Transmission => "TRANSMISSION",
            SectionKind::ViewTilt => "VIEW_TILT",
            SectionKind::SurfaceTexelsCompact => "SURFACE_TEXELS_COMPACT",
            SectionKind::SurfaceLobesCompact => "SURFACE_LOBES_COMPACT",
            SectionKind::ViewTiltCompact => "VIEW_TILT_COMPACT",
            SectionKind::Gradient => "GRADIENT",
            SectionKind::Curvature => "CURVATURE",
            SectionKind::TransmissionVisibility => "TRANSMISSION_VISIBILITY",
        }
    }
}

/// A section-table entry as stored (32 bytes, little endian).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SectionEntry {
    pub kind: u32,
    pub flags: u32,
    pub level: u32,
    pub crc32: u32,
    pub offset: u64,
    pub length: u64,
}

impl SectionEntry {
    pub fn to_bytes(&self) -> [u8; SECTION_ENTRY_SIZE] {
        let mut b = [0u8; SECTION_ENTRY_SIZE];
        b[0..4].copy_from_slice(&self.kind.to_le_bytes());
        b[4..8].copy_from_slice(&self.flags.to_le_bytes());
        b[8..12].copy_from_slice(&self.level.to_le_bytes());
        b[12..16].copy_from_slice(&self.crc32.to_le_bytes());
        b[16..24].copy_from_slice(&self.offset.to_le_bytes());
        b[24..32].copy_from_slice(&self.length.to_le_bytes());
        b
    }

    /// From the first 32 bytes of `b` (the caller checked the length).
    pub fn from_bytes(b: &[u8]) -> SectionEntry {
        let u32_at = |o: usize| u32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]);
        let u64_at = |o: usize| u64::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3], b[o + 4], b[o + 5], b[o + 6], b[o + 7]]);
        SectionEntry { kind: u32_at(0), flags: u32_at(4), level: u32_at(8), crc32: u32_at(12), offset: u64_at(16), length: u64_at(24) }
    }
}
