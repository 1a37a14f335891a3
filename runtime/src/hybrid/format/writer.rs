//! Writes a hybrid model file (runtime/HYBRID_FORMAT.md). The model is validated first:
//! a file this writer produces always reads back.

use std::io::Write;
use std::path::Path;

use super::error::{FileError, FormatError};
use super::{HEADER_SIZE, MAGIC, MODEL_FLAG_COARSE_VISIBILITY, MODEL_FLAG_DIFFUSE_LS, MODEL_FLAG_FIBER_CYLINDER, MODEL_FLAG_FLYAWAY_SHADOW, MODEL_FLAG_SHADOWING, MODEL_FLAG_VOLUMETRIC, MODEL_SECTION_SIZE, SECTION_ALIGN, SECTION_ENTRY_SIZE, SECTION_OPTIONAL, SectionEntry, SectionKind, VERSION_MAJOR, VERSION_MINOR};
use crate::hybrid::{HybridModel, Surface, compact};

/// The MODEL section (64 bytes).
fn model_section(m: &HybridModel) -> Vec<u8> {
    let mut b = Vec::with_capacity(MODEL_SECTION_SIZE);
    for v in [m.width(), m.height_px(), m.levels.len() as u32, m.meta.reading as u32, (if m.meta.fitted_with_shadowing { MODEL_FLAG_SHADOWING } else { 0 }) | (if m.meta.volumetric { MODEL_FLAG_VOLUMETRIC } else { 0 }) | (if m.meta.coarse_visibility { MODEL_FLAG_COARSE_VISIBILITY } else { 0 }) | (if m.meta.diffuse == crate::brdf::DiffuseLaw::LommelSeeliger { MODEL_FLAG_DIFFUSE_LS } else { 0 }) | (if m.meta.fiber_lobes == crate::brdf::FiberLobes::Cylinder { MODEL_FLAG_FIBER_CYLINDER } else { 0 }) | (if m.meta.flyaway_shadow { MODEL_FLAG_FLYAWAY_SHADOW } else { 0 }), 0] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    let t = &m.tile;
    for v in [t.origin.x, t.origin.y, t.size.x, t.size.y, t.top_z, t.height_scale, t.voxel_depth] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b.resize(MODEL_SECTION_SIZE, 0);
    b
}

/// The META section: bbox, dims, error count, seed, errors, note.
fn meta_section(m: &HybridModel) -> Vec<u8> {
    let meta = &m.meta;
    let mut b = Vec::new();
    let (lo, hi) = (meta.source_bbox.min, meta.source_bbox.max);
    for v in [lo.x, lo.y, lo.z, hi.x, hi.y, hi.z] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    for v in meta.source_dims {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b.extend_from_slice(&(meta.fit_error.len() as u32).to_le_bytes());
    b.extend_from_slice(&meta.seed.to_le_bytes());
    for e in &meta.fit_error {
        b.extend_from_slice(&e.to_le_bytes());
    }
    b.extend_from_slice(&(meta.note.len() as u32).to_le_bytes());
    b.extend_from_slice(meta.note.as_bytes());
    b
}

/// Sections of the model, in file order: (kind, flags, level, bytes).
fn sections(m: &HybridModel) -> Vec<(SectionKind, u32, u32, Vec<u8>)> {
    let bytes = |s: &[u8]| s.to_vec();
    let mut out = vec![
        (SectionKind::Model, 0, 0, model_section(m)),
        (SectionKind::Meta, SECTION_OPTIONAL, 0, meta_section(m)),
        (SectionKind::Height, 0, 0, bytes(bytemuck::cast_slice(&m.height.codes))),
    ];
    for (level, l) in m.levels.iter().enumerate() {
        let level = level as u32;
        match &l.surface {
            Surface::Clustered { texels, table } => {
                out.push((SectionKind::SurfaceClusteredTexels, 0, level, bytes(bytemuck::cast_slice(texels))));
                out.push((SectionKind::SurfaceHeaders, 0, level, bytes(bytemuck::cast_slice(&table.headers))));
                out.push((SectionKind::SurfaceLobes, 0, level, bytes(bytemuck::cast_slice(&table.lobes))));
            }
            // Compact records where every one holds its wide record exactly (1.7).
            Surface::PerTexel(table) => {
                match compact::compact_texels(table) {
                    Some(t) => out.push((SectionKind::SurfaceTexelsCompact, 0, level, bytes(bytemuck::cast_slice(&t)))),
                    None => out.push((SectionKind::SurfaceHeaders, 0, level, bytes(bytemuck::cast_slice(&table.headers)))),
                }
                match compact::compact_lobes(&table.lobes) {
                    Some(l) => out.push((SectionKind::SurfaceLobesCompact, 0, level, bytes(bytemuck::cast_slice(&l)))),
                    None => out.push((SectionKind::SurfaceLobes, 0, level, bytes(bytemuck::cast_slice(&table.lobes)))),
                }
            }
        }
        if let Some(f) = &l.flyaways {
            out.push((SectionKind::FlyawayHeads, 0, level, bytes(bytemuck::cast_slice(&f.heads))));
            match compact::compact_flyaway_nodes(f) {
                Some(c) => out.push((SectionKind::FlyawayNodesCompact, 0, level, bytes(bytemuck::cast_slice(&c)))),
                None => out.push((SectionKind::FlyawayNodes, 0, level, bytes(bytemuck::cast_slice(&f.nodes)))),
            }
            out.push((SectionKind::FlyawayHeaders, 0, level, bytes(bytemuck::cast_slice(&f.table.headers))));
            out.push((SectionKind::FlyawayLobes, 0, level, bytes(bytemuck::cast_slice(&f.table.lobes))));
            // Optional: a 1.4 reader skips it and shades each node with its one axis.
            if let Some(spreads) = &f.spreads {
                match compact::compact_spreads(spreads) {
                    Some(c) => out.push((SectionKind::FlyawaySpreadCompact, SECTION_OPTIONAL, level, bytes(bytemuck::cast_slice(&c)))),
                    None => out.push((SectionKind::FlyawaySpread, SECTION_OPTIONAL, level, bytes(bytemuck::cast_slice(spreads)))),
                }
            }
            // Optional: a 1.7 reader skips it and shades each node as its first group's cone.
            if let Some(groups) = &f.groups {
                out.push((SectionKind::FlyawayGroup, SECTION_OPTIONAL, level, bytes(bytemuck::cast_slice(groups))));
            }
            // Optional: a 1.8 reader skips it and crosses coarse nodes by Beer's law from α.
            if let Some(gain) = &f.path_gain {
                out.push((SectionKind::FlyawayPathGain, SECTION_OPTIONAL, level, bytes(bytemuck::bytes_of(gain))));
            }
        }
        // Optional: a 1.2 reader skips it and renders the reflection alone.
        if let Some(t) = &l.transmission {
            out.push((SectionKind::Transmission, SECTION_OPTIONAL, level, bytes(bytemuck::cast_slice(t))));
        }
        // Optional: a 1.15 reader skips it and shades the transmission with M_t = 1.
        if let Some(g) = &l.transmission_visibility {
            out.push((SectionKind::TransmissionVisibility, SECTION_OPTIONAL, level, bytes(bytemuck::cast_slice(g))));
        }
        if let Some(t) = &l.view_tilt {
            match compact::compact_view_tilts(t) {
                Some(c) => out.push((SectionKind::ViewTiltCompact, SECTION_OPTIONAL, level, bytes(bytemuck::cast_slice(&c)))),
                None => out.push((SectionKind::ViewTilt, SECTION_OPTIONAL, level, bytes(bytemuck::cast_slice(t)))),
            }
        }
        // Optional: a 1.11 reader skips it and shades every texel as if g = 0.
        if let Some(g) = &l.gradient {
            out.push((SectionKind::Gradient, SECTION_OPTIONAL, level, bytes(bytemuck::cast_slice(g))));
        }
        // Optional: a 1.14 reader skips it and shades every texel as if q = 0.
        if let Some(q) = &l.curvature {
            out.push((SectionKind::Curvature, SECTION_OPTIONAL, level, bytes(bytemuck::cast_slice(q))));
        }
    }
    out
}

fn align(v: u64) -> u64 {
    v.div_ceil(SECTION_ALIGN) * SECTION_ALIGN
}

/// The file's bytes. Errors only if the model is invalid.
pub fn to_bytes(m: &HybridModel) -> Result<Vec<u8>, FormatError> {
    m.validate()?;
    let sections = sections(m);
    let table_offset = HEADER_SIZE as u64;
    let mut offset = align(table_offset + (sections.len() * SECTION_ENTRY_SIZE) as u64);
    let mut entries = Vec::with_capacity(sections.len());
    for (kind, flags, level, data) in &sections {
        entries.push(SectionEntry { kind: *kind as u32, flags: *flags, level: *level, crc32: crc32fast::hash(data), offset, length: data.len() as u64 });
        offset = align(offset + data.len() as u64);
    }
    // The last section is not padded: the file ends with its last byte.
    let file_size = entries.last().map_or(offset, |e| e.offset + e.length);
    let mut out = vec![0u8; file_size as usize];
    let table: Vec<u8> = entries.iter().flat_map(|e| e.to_bytes()).collect();
    out[table_offset as usize..table_offset as usize + table.len()].copy_from_slice(&table);
    for (e, (_, _, _, data)) in entries.iter().zip(&sections) {
        out[e.offset as usize..(e.offset + e.length) as usize].copy_from_slice(data);
    }
    let h = &mut out[..HEADER_SIZE];
    h[0..8].copy_from_slice(&MAGIC);
    h[8..10].copy_from_slice(&VERSION_MAJOR.to_le_bytes());
    h[10..12].copy_from_slice(&VERSION_MINOR.to_le_bytes());
    h[12..16].copy_from_slice(&(HEADER_SIZE as u32).to_le_bytes());
    h[16..24].copy_from_slice(&file_size.to_le_bytes());
    h[24..32].copy_from_slice(&table_offset.to_le_bytes());
    h[32..36].copy_from_slice(&(entries.len() as u32).to_le_bytes());
    h[36..40].copy_from_slice(&(SECTION_ENTRY_SIZE as u32).to_le_bytes());
    // 40..44 flags (0), 44..48 header CRC, 48..52 table CRC, 52..64 reserved (0).
    h[48..52].copy_from_slice(&crc32fast::hash(&table).to_le_bytes());
    let header_crc = crc32fast::hash(h);
    h[44..48].copy_from_slice(&header_crc.to_le_bytes());
    Ok(out)
}

/// Writes the model to `path` (through a temporary file in the same directory, renamed
/// into place, so that a crash never leaves a half-written model under the real name).
pub fn write_file(m: &HybridModel, path: &Path) -> Result<(), FileError> {
    let fail = |error: FormatError| FileError { path: path.to_path_buf(), error };
    let bytes = to_bytes(m).map_err(fail)?;
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| fail(e.into()))?;
    }
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(format!(".tmp{}", std::process::id()));
    let tmp = std::path::PathBuf::from(tmp);
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(&bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(fail(e.into()));
    }
    Ok(())
}
