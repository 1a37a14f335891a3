//! Reads a hybrid model file (runtime/HYBRID_FORMAT.md), trusting nothing: every
//! offset, length and count is checked (in u64, with checked arithmetic) before it is
//! used, every section's CRC-32 is verified, and the decoded model is validated
//! ([`HybridModel::validate`]: ranges, indices, acyclic flyaway lists). Allocations are
//! bounded by the file's size. Accepts any byte slice, so a memory map works directly.

use std::collections::BTreeMap;
use std::path::Path;

use bytemuck::Pod;
use glam::{Vec2, Vec3};
use serde::Serialize;

use super::error::{FileError, FormatError};
use super::{HEADER_SIZE, MAGIC, MAX_SECTIONS, MODEL_FLAG_COARSE_VISIBILITY, MODEL_FLAG_DIFFUSE_LS, MODEL_FLAG_FIBER_CYLINDER, MODEL_FLAG_FLYAWAY_SHADOW, MODEL_FLAG_SHADOWING, MODEL_FLAG_VOLUMETRIC, SECTION_ALIGN, SECTION_ENTRY_SIZE, SECTION_OPTIONAL, SectionEntry, SectionKind, VERSION_MAJOR};
use crate::brdf::{BrdfReading, DiffuseLaw, FiberLobes};
use crate::hybrid::model::{MAX_DIM, max_levels};
use crate::hybrid::stats::{ModelStats, model_stats};
use crate::hybrid::compact::{self, CompactError};
use crate::hybrid::{BakeMetadata, BrdfTable, Flyaways, HeightField, HybridModel, Level, PATH_GAIN_NODES, PathGain, Surface, Tile, level_dims};
use crate::scene::Aabb;

/// One section of a file, as `fabric inspect` lists it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SectionInfo {
    /// The kind's name, or "unknown(N)".
    pub kind: String,
    pub kind_id: u32,
    pub level: u32,
    pub optional: bool,
    pub offset: u64,
    pub length: u64,
    pub crc32: u32,
}

/// What `fabric inspect model.hyb` reports: the container and the model's statistics.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FileInfo {
    pub version: (u16, u16),
    pub file_size: u64,
    pub sections: Vec<SectionInfo>,
    pub model: ModelStats,
}

fn kind_name(kind: u32) -> String {
    SectionKind::from_u32(kind).map_or_else(|| format!("unknown({kind})"), |k| k.name().to_string())
}

fn u16_at(b: &[u8], o: usize) -> u16 {
    u16::from_le_bytes([b[o], b[o + 1]])
}

fn u32_at(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]])
}

fn u64_at(b: &[u8], o: usize) -> u64 {
    u64::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3], b[o + 4], b[o + 5], b[o + 6], b[o + 7]])
}

fn f32_at(b: &[u8], o: usize) -> f32 {
    f32::from_bits(u32_at(b, o))
}

/// The checked container: version and the section entries (bounds, alignment,
/// overlaps and CRCs verified).
struct Container {
    version: (u16, u16),
    entries: Vec<SectionEntry>,
}

fn parse_container(bytes: &[u8]) -> Result<Container, FormatError> {
    let len = bytes.len() as u64;
    if bytes.len() < HEADER_SIZE {
        return Err(FormatError::TooShort { len, need: HEADER_SIZE as u64 });
    }
    let mut magic = [0u8; 8];
    magic.copy_from_slice(&bytes[0..8]);
    if magic != MAGIC {
        return Err(FormatError::BadMagic { found: magic, expected: MAGIC });
    }
    let (major, minor) = (u16_at(bytes, 8), u16_at(bytes, 10));
    if major != VERSION_MAJOR {
        return Err(FormatError::UnsupportedVersion { major, minor, supported: VERSION_MAJOR });
    }
    let header_size = u32_at(bytes, 12) as u64;
    if header_size < HEADER_SIZE as u64 || header_size > len {
        return Err(FormatError::Header { field: "header_size", value: header_size, why: "below 64 or past the end of the file" });
    }
    // CRC of the header with its own CRC field zeroed.
    let stored = u32_at(bytes, 44);
    let mut h = bytes[..header_size as usize].to_vec();
    h[44..48].fill(0);
    let computed = crc32fast::hash(&h);
    if stored != computed {
        return Err(FormatError::HeaderChecksum { stored, computed });
    }
    let declared = u64_at(bytes, 16);
    if declared != len {
        return Err(FormatError::FileSize { declared, actual: len });
    }
    let table_offset = u64_at(bytes, 24);
    let count = u32_at(bytes, 32);
    let entry_size = u32_at(bytes, 36);
    if count > MAX_SECTIONS {
        return Err(FormatError::Header { field: "section_count", value: count as u64, why: "more than 4096 sections" });
    }
    if !(SECTION_ENTRY_SIZE as u32..=1024).contains(&entry_size) {
        return Err(FormatError::Header { field: "section_entry_size", value: entry_size as u64, why: "must be in 32..=1024" });
    }
    let table_end = (count as u64).checked_mul(entry_size as u64).and_then(|t| t.checked_add(table_offset));
    let table_end = match table_end {
        Some(end) if table_offset >= header_size && end <= len => end,
        _ => return Err(FormatError::TableBounds { offset: table_offset, count, entry_size, len }),
    };
    let table = &bytes[table_offset as usize..table_end as usize];
    let (stored, computed) = (u32_at(bytes, 48), crc32fast::hash(table));
    if stored != computed {
        return Err(FormatError::TableChecksum { stored, computed });
    }
    let entries: Vec<SectionEntry> = table.chunks_exact(entry_size as usize).map(SectionEntry::from_bytes).collect();
    for (index, e) in entries.iter().enumerate() {
        let bad = |why: String| FormatError::Section { index, kind: kind_name(e.kind), level: e.level, why };
        if e.offset % SECTION_ALIGN != 0 {
            return Err(bad(format!("offset {} is not a multiple of {SECTION_ALIGN}", e.offset)));
        }
        let end = e.offset.checked_add(e.length).filter(|&end| end <= len);
        let Some(end) = end else {
            return Err(bad(format!("{} bytes at offset {} run past the end of the {len}-byte file", e.length, e.offset)));
        };
        if e.offset < table_end {
            return Err(bad(format!("offset {} lies inside the header or the section table (which end at {table_end})", e.offset)));
        }
        let computed = crc32fast::hash(&bytes[e.offset as usize..end as usize]);
        if computed != e.crc32 {
            return Err(FormatError::SectionChecksum { index, kind: kind_name(e.kind), level: e.level, stored: e.crc32, computed });
        }
    }
    let mut order: Vec<usize> = (0..entries.len()).collect();
    order.sort_by_key(|&i| (entries[i].offset, entries[i].length));
    for w in order.windows(2) {
        let (a, b) = (&entries[w[0]], &entries[w[1]]);
        if a.offset + a.length > b.offset && a.length > 0 && b.length > 0 {
            return Err(FormatError::Section { index: w[1], kind: kind_name(b.kind), level: b.level, why: format!("overlaps section {} ({})", w[0], kind_name(a.kind)) });
        }
    }
    Ok(Container { version: (major, minor), entries })
}

/// The known sections by (kind, level), unknown optional ones dropped.
struct Sections<'a> {
    map: BTreeMap<(SectionKind, u32), (usize, &'a [u8])>,
}

impl<'a> Sections<'a> {
    fn new(bytes: &'a [u8], entries: &[SectionEntry]) -> Result<Sections<'a>, FormatError> {
        let mut map = BTreeMap::new();
        for (index, e) in entries.iter().enumerate() {
            let Some(kind) = SectionKind::from_u32(e.kind) else {
                if e.flags & SECTION_OPTIONAL != 0 {
                    continue;
                }
                return Err(FormatError::UnknownRequired { index, kind: e.kind });
            };
            let level = if kind.per_level() { e.level } else { 0 };
            if !kind.per_level() && e.level != 0 {
                return Err(FormatError::Section { index, kind: kind.name().into(), level: e.level, why: "level must be 0 for a per-model section".into() });
            }
            let data = &bytes[e.offset as usize..(e.offset + e.length) as usize];
            if map.insert((kind, level), (index, data)).is_some() {
                return Err(FormatError::Duplicate { kind: kind.name(), level });
            }
        }
        Ok(Sections { map })
    }

    fn get(&self, kind: SectionKind, level: u32) -> Option<(usize, &'a [u8])> {
        self.map.get(&(kind, level)).copied()
    }

    fn require(&self, kind: SectionKind, level: u32) -> Result<(usize, &'a [u8]), FormatError> {
        let where_ = if kind.per_level() { format!("for level {level}") } else { String::new() };
        self.get(kind, level).ok_or(FormatError::Missing { kind: kind.name(), where_ })
    }

    /// A section as an array of records (length a multiple of the record size).
    fn array<T: Pod>(&self, kind: SectionKind, level: u32) -> Result<Vec<T>, FormatError> {
        let (index, data) = self.require(kind, level)?;
        let size = size_of::<T>();
        if data.len() % size != 0 {
            return Err(FormatError::Section { index, kind: kind.name().into(), level, why: format!("{} bytes is not a whole number of {size}-byte records", data.len()) });
        }
        Ok(bytemuck::pod_collect_to_vec(data))
    }
}

impl Sections<'_> {
    /// A level's records from its wide section or its compact one (1.7), not both.
    fn wide_or_compact<W: Pod, C: Pod>(&self, wide: SectionKind, narrow: SectionKind, level: u32, expand: impl FnOnce(&[C]) -> Result<Vec<W>, CompactError>) -> Result<Vec<W>, FormatError> {
        match (self.get(wide, level), self.get(narrow, level)) {
            (Some(_), Some((index, _))) => Err(FormatError::Section { index, kind: narrow.name().into(), level, why: format!("present beside {}: a level holds one of the two", wide.name()) }),
            (None, Some((index, _))) => {
                let records: Vec<C> = self.array(narrow, level)?;
                expand(&records).map_err(|e| FormatError::Section { index, kind: narrow.name().into(), level, why: format!("record {}: {}", e.record, e.why) })
            }
            _ => self.array(wide, level),
        }
    }
}

struct ModelHeader {
    width: u32,
    height: u32,
    levels: usize,
    reading: BrdfReading,
    shadowing: bool,
    volumetric: bool,
    coarse_visibility: bool,
    diffuse: DiffuseLaw,
    fiber_lobes: FiberLobes,
    flyaway_shadow: bool,
    tile: Tile,
}

fn parse_model_section(index: usize, b: &[u8]) -> Result<ModelHeader, FormatError> {
    let bad = |why: String| FormatError::Section { index, kind: "MODEL".into(), level: 0, why };
    if b.len() < 52 {
        return Err(bad(format!("{} bytes; at least 52 expected", b.len())));
    }
    let (width, height, levels) = (u32_at(b, 0), u32_at(b, 4), u32_at(b, 8));
    if width == 0 || height == 0 || width > MAX_DIM || height > MAX_DIM {
        return Err(bad(format!("size {width}x{height}: each side must be in 1..={MAX_DIM}")));
    }
    let max = max_levels(width, height);
    if levels == 0 || levels as usize > max {
        return Err(bad(format!("{levels} levels; a {width}x{height} model has 1..={max}")));
    }
    let reading = BrdfReading::from_u32(u32_at(b, 12)).ok_or_else(|| bad(format!("BRDF reading {} is unknown (0 = bounded, 1 = width, 2 = held)", u32_at(b, 12))))?;
    let flags = u32_at(b, 16);
    if flags & !(MODEL_FLAG_SHADOWING | MODEL_FLAG_VOLUMETRIC | MODEL_FLAG_COARSE_VISIBILITY | MODEL_FLAG_DIFFUSE_LS | MODEL_FLAG_FIBER_CYLINDER | MODEL_FLAG_FLYAWAY_SHADOW) != 0 {
        return Err(bad(format!("unknown flags {flags:#x}")));
    }
    let f = |o| f32_at(b, o);
    let tile = Tile { origin: Vec2::new(f(24), f(28)), size: Vec2::new(f(32), f(36)), top_z: f(40), height_scale: f(44), voxel_depth: f(48) };
    Ok(ModelHeader { width, height, levels: levels as usize, reading, shadowing: flags & MODEL_FLAG_SHADOWING != 0, volumetric: flags & MODEL_FLAG_VOLUMETRIC != 0, coarse_visibility: flags & MODEL_FLAG_COARSE_VISIBILITY != 0, diffuse: if flags & MODEL_FLAG_DIFFUSE_LS != 0 { DiffuseLaw::LommelSeeliger } else { DiffuseLaw::Lambert }, fiber_lobes: if flags & MODEL_FLAG_FIBER_CYLINDER != 0 { FiberLobes::Cylinder } else { FiberLobes::Facing }, flyaway_shadow: flags & MODEL_FLAG_FLYAWAY_SHADOW != 0, tile })
}

/// The META section's fields: source bbox, source dims, seed, fit errors, note.
type MetaFields = (Aabb, [u32; 3], u64, Vec<f32>, String);

fn parse_meta_section(index: usize, b: &[u8], levels: usize) -> Result<MetaFields, FormatError> {
    let bad = |why: String| FormatError::Section { index, kind: "META".into(), level: 0, why };
    if b.len() < 48 {
        return Err(bad(format!("{} bytes; at least 48 expected", b.len())));
    }
    let f = |o| f32_at(b, o);
    let bbox = Aabb::new(Vec3::new(f(0), f(4), f(8)), Vec3::new(f(12), f(16), f(20)));
    let dims = [u32_at(b, 24), u32_at(b, 28), u32_at(b, 32)];
    let count = u32_at(b, 36) as usize;
    let seed = u64_at(b, 40);
    if count > levels {
        return Err(bad(format!("{count} fit errors for {levels} levels")));
    }
    let errors_end = 48 + 4 * count;
    if b.len() < errors_end + 4 {
        return Err(bad(format!("{} bytes cannot hold {count} fit errors and the note length", b.len())));
    }
    let fit_error = (0..count).map(|k| f(48 + 4 * k)).collect();
    let note_len = u32_at(b, errors_end) as u64;
    let note_bytes = b.get(errors_end + 4..).filter(|r| r.len() as u64 >= note_len).ok_or_else(|| bad(format!("note of {note_len} bytes runs past the section's end")))?;
    let note = std::str::from_utf8(&note_bytes[..note_len as usize]).map_err(|e| bad(format!("note is not UTF-8: {e}")))?.to_string();
    Ok((bbox, dims, seed, fit_error, note))
}

fn read_table(s: &Sections, headers: SectionKind, lobes: SectionKind, level: u32) -> Result<BrdfTable, FormatError> {
    Ok(BrdfTable { headers: s.array(headers, level)?, lobes: s.array(lobes, level)? })
}

/// Reads a model from the bytes of a `.hyb` file.
pub fn read(bytes: &[u8]) -> Result<HybridModel, FormatError> {
    let container = parse_container(bytes)?;
    read_model(bytes, &container)
}

fn read_model(bytes: &[u8], container: &Container) -> Result<HybridModel, FormatError> {
    let s = Sections::new(bytes, &container.entries)?;
    let (index, data) = s.require(SectionKind::Model, 0)?;
    let mh = parse_model_section(index, data)?;
    // Per-level sections past the level count would be silently ignored: reject them.
    if let Some(((kind, level), (index, _))) = s.map.iter().find(|((k, l), _)| k.per_level() && *l as usize >= mh.levels) {
        return Err(FormatError::Section { index: *index, kind: kind.name().into(), level: *level, why: format!("level {level} does not exist: the model has {}", mh.levels) });
    }
    let codes: Vec<u16> = s.array(SectionKind::Height, 0)?;
    let height = HeightField { width: mh.width, height: mh.height, codes };
    let mut levels = Vec::with_capacity(mh.levels);
    for level in 0..mh.levels {
        let l = level as u32;
        let (width, height) = level_dims(mh.width, mh.height, level);
        let surface = if s.get(SectionKind::SurfaceClusteredTexels, l).is_some() {
            for kind in [SectionKind::SurfaceTexelsCompact, SectionKind::SurfaceLobesCompact] {
                if let Some((index, _)) = s.get(kind, l) {
                    return Err(FormatError::Section { index, kind: kind.name().into(), level: l, why: "compact records belong to per-texel levels, and this level is clustered".into() });
                }
            }
            Surface::Clustered { texels: s.array(SectionKind::SurfaceClusteredTexels, l)?, table: read_table(&s, SectionKind::SurfaceHeaders, SectionKind::SurfaceLobes, l)? }
        } else {
            let headers = s.wide_or_compact(SectionKind::SurfaceHeaders, SectionKind::SurfaceTexelsCompact, l, compact::expand_texels)?;
            let lobes = s.wide_or_compact(SectionKind::SurfaceLobes, SectionKind::SurfaceLobesCompact, l, compact::expand_lobes)?;
            Surface::PerTexel(BrdfTable { headers, lobes })
        };
        let flyaways = match s.get(SectionKind::FlyawayHeads, l) {
            None => {
                for kind in [SectionKind::FlyawayNodes, SectionKind::FlyawayNodesCompact, SectionKind::FlyawayHeaders, SectionKind::FlyawayLobes, SectionKind::FlyawaySpread, SectionKind::FlyawaySpreadCompact, SectionKind::FlyawayGroup, SectionKind::FlyawayPathGain] {
                    if let Some((index, _)) = s.get(kind, l) {
                        return Err(FormatError::Section { index, kind: kind.name().into(), level: l, why: "present without FLYAWAY_HEADS".into() });
                    }
                }
                None
            }
            Some(_) => {
                let heads: Vec<u32> = s.array(SectionKind::FlyawayHeads, l)?;
                let nodes = s.wide_or_compact(SectionKind::FlyawayNodes, SectionKind::FlyawayNodesCompact, l, |c| compact::expand_flyaway_nodes(&heads, c))?;
                let table = read_table(&s, SectionKind::FlyawayHeaders, SectionKind::FlyawayLobes, l)?;
                let spreads = match (s.get(SectionKind::FlyawaySpread, l), s.get(SectionKind::FlyawaySpreadCompact, l)) {
                    (None, None) => None,
                    _ => Some(s.wide_or_compact(SectionKind::FlyawaySpread, SectionKind::FlyawaySpreadCompact, l, |c| Ok(compact::expand_spreads(c)))?),
                };
                let groups = match s.get(SectionKind::FlyawayGroup, l) {
                    Some(_) => Some(s.array(SectionKind::FlyawayGroup, l)?),
                    None => None,
                };
                let path_gain = match s.get(SectionKind::FlyawayPathGain, l) {
                    Some((index, _)) => {
                        let gains: Vec<f32> = s.array(SectionKind::FlyawayPathGain, l)?;
                        let gains: [f32; PATH_GAIN_NODES] = gains.try_into().map_err(|g: Vec<f32>| FormatError::Section { index, kind: SectionKind::FlyawayPathGain.name().into(), level: l, why: format!("{} gains; expected {PATH_GAIN_NODES}", g.len()) })?;
                        Some(PathGain(gains))
                    }
                    None => None,
                };
                Some(Flyaways { heads, nodes, table, spreads, groups, path_gain })
            }
        };
        let transmission = match s.get(SectionKind::Transmission, l) {
            Some(_) => Some(s.array(SectionKind::Transmission, l)?),
            None => None,
        };
        let view_tilt = match (s.get(SectionKind::ViewTilt, l), s.get(SectionKind::ViewTiltCompact, l)) {
            (None, None) => None,
            _ => Some(s.wide_or_compact(SectionKind::ViewTilt, SectionKind::ViewTiltCompact, l, compact::expand_view_tilts)?),
        };
        let gradient = match s.get(SectionKind::Gradient, l) {
            Some(_) => Some(s.array(SectionKind::Gradient, l)?),
            None => None,
        };
        let curvature = match s.get(SectionKind::Curvature, l) {
            Some(_) => Some(s.array(SectionKind::Curvature, l)?),
            None => None,
        };
        let transmission_visibility = match s.get(SectionKind::TransmissionVisibility, l) {
            Some(_) => Some(s.array(SectionKind::TransmissionVisibility, l)?),
            None => None,
        };
        levels.push(Level { width, height, surface, flyaways, transmission, transmission_visibility, view_tilt, gradient, curvature });
    }
    let (source_bbox, source_dims, seed, fit_error, note) = match s.get(SectionKind::Meta, 0) {
        Some((index, data)) => parse_meta_section(index, data, mh.levels)?,
        None => (Aabb::new(Vec3::ZERO, Vec3::ZERO), [0; 3], 0, Vec::new(), String::new()),
    };
    let meta = BakeMetadata { reading: mh.reading, fitted_with_shadowing: mh.shadowing, volumetric: mh.volumetric, coarse_visibility: mh.coarse_visibility, diffuse: mh.diffuse, fiber_lobes: mh.fiber_lobes, flyaway_shadow: mh.flyaway_shadow, fit_error, source_bbox, source_dims, seed, note };
    let model = HybridModel { tile: mh.tile, height, levels, meta };
    model.validate()?;
    Ok(model)
}

/// Reads a model from a file (memory-mapped).
pub fn read_file(path: &Path) -> Result<HybridModel, FileError> {
    with_mapped_file(path, read)
}

/// Inspects a file (memory-mapped): version, sections, model statistics.
pub fn inspect_file(path: &Path) -> Result<FileInfo, FileError> {
    with_mapped_file(path, inspect)
}

/// Maps `path` read-only and hands its bytes to `f`; errors name the file.
fn with_mapped_file<T>(path: &Path, f: impl FnOnce(&[u8]) -> Result<T, FormatError>) -> Result<T, FileError> {
    let fail = |error: FormatError| FileError { path: path.to_path_buf(), error };
    let file = std::fs::File::open(path).map_err(|e| fail(e.into()))?;
    let meta = file.metadata().map_err(|e| fail(e.into()))?;
    // A directory opens but cannot be mapped ("No such device"): say what is expected.
    if meta.is_dir() {
        return Err(fail(std::io::Error::new(std::io::ErrorKind::InvalidInput, "is a directory, not a hybrid model file (.hyb)").into()));
    }
    let len = meta.len();
    if len < HEADER_SIZE as u64 {
        return Err(fail(FormatError::TooShort { len, need: HEADER_SIZE as u64 }));
    }
    // SAFETY: the map is read-only and private to this call; a concurrent writer could
    // change bytes under us, which the CRCs and checks turn into an error, not UB in
    // our code (we only read plain bytes).
    let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| fail(e.into()))?;
    f(&map).map_err(fail)
}

/// Reads and describes a file: version, sections, model statistics.
pub fn inspect(bytes: &[u8]) -> Result<FileInfo, FormatError> {
    let container = parse_container(bytes)?;
    let model = read_model(bytes, &container)?;
    let sections = container
        .entries
        .iter()
        .map(|e| SectionInfo { kind: kind_name(e.kind), kind_id: e.kind, level: e.level, optional: e.flags & SECTION_OPTIONAL != 0, offset: e.offset, length: e.length, crc32: e.crc32 })
        .collect();
    Ok(FileInfo { version: container.version, file_size: bytes.len() as u64, sections, model: model_stats(&model) })
}
