//! The `.hyb` file: round trips, layout, and the corruption catalogue (every kind of
//! damaged, truncated or hostile file gets its own clear error, never a panic), plus a
//! quick randomized corruption run. The long run is `#[ignore]`d: see the end.

use fabric_runtime::brdf::BrdfReading;
use fabric_runtime::hybrid::format::{self, FormatError, HEADER_SIZE, MAGIC, SECTION_ENTRY_SIZE, SECTION_OPTIONAL, SectionEntry, SectionKind};
use fabric_runtime::hybrid::{HybridModel, ModelError, NO_NODE, Surface, examples};

fn sample() -> HybridModel {
    let m = examples::sample_model();
    m.validate().expect("the sample model is valid");
    m
}

/// The sample with a transmission term on every level (a BSDF, format 1.3), its texels
/// open (1.10).
fn bsdf_sample() -> HybridModel {
    use fabric_runtime::brdf::{ClothLobe, ClothOpenness, ClothTransmission};
    let mut m = sample();
    examples::add_transmission(&mut m, &ClothTransmission { kd: glam::Vec3::new(0.05, 0.04, 0.03), lobe: ClothLobe { k: glam::Vec3::new(0.3, 0.2, 0.1), beta: 0.4, gamma: 1.5 }, tau: 0.5, gap: ClothOpenness { o: 0.06, q: 2.0, aniso: [0.5, -0.25] }, grad: [0.5, -0.4, 0.6, 0.3], curv: [0.3, -0.2, 0.1, -0.4, 0.25, 0.15] }, 2);
    m.validate().expect("the BSDF sample is valid");
    m
}

/// The sample with view tilts on its coarse levels (format 1.4).
fn tilted_sample() -> HybridModel {
    let mut m = sample();
    examples::add_view_tilts(&mut m, 0.3, 2);
    m.validate().expect("the tilted sample is valid");
    m
}

/// The sample with a visibility gradient and curvature on every level (format 1.15).
fn curvature_sample() -> HybridModel {
    let mut m = gradient_sample();
    examples::add_curvatures(&mut m, 2);
    m.validate().expect("the curvature sample is valid");
    m
}

/// The sample with a visibility gradient on every level (format 1.12).
fn gradient_sample() -> HybridModel {
    let mut m = sample();
    examples::add_gradients(&mut m, 2);
    m.validate().expect("the gradient sample is valid");
    m
}

/// The sample with spread records on its coarse flyaways (format 1.5).
fn spread_sample() -> HybridModel {
    let mut m = sample();
    examples::add_axis_spreads(&mut m, 1.0);
    assert!(m.levels[1..].iter().any(|l| l.flyaways.as_ref().is_some_and(|f| f.spreads.is_some())), "the sample has coarse flyaways");
    m.validate().expect("the spread sample is valid");
    m
}

/// The tilted sample with its per-texel levels snapped to the compact grid, as
/// `fabric prefilter` leaves them: the writer stores them compactly (format 1.7).
fn compact_sample() -> HybridModel {
    use fabric_runtime::hybrid::compact;
    let mut m = tilted_sample();
    for l in &mut m.levels[1..] {
        if let Surface::PerTexel(table) = &mut l.surface {
            compact::quantize_table(table);
        }
        compact::quantize_view_tilts(l.view_tilt.as_mut().unwrap());
    }
    m.validate().expect("the compact sample is valid");
    m
}

/// The file of `m` with its compact flyaway nodes written as wide ones (1.6's records,
/// with their links), as an older writer would store them.
fn wide_node_bytes(m: &HybridModel) -> Vec<u8> {
    let mut parts = Parts::of(&format::to_bytes(m).unwrap());
    for (e, data) in parts.sections.iter_mut().filter(|(e, _)| e.kind == SectionKind::FlyawayNodesCompact as u32) {
        e.kind = SectionKind::FlyawayNodes as u32;
        *data = bytemuck::cast_slice(&m.levels[e.level as usize].flyaways.as_ref().unwrap().nodes).to_vec();
    }
    let bytes = parts.assemble();
    assert_eq!(format::read(&bytes).unwrap(), *m, "wide nodes read as the compact ones");
    bytes
}

fn sample_bytes() -> Vec<u8> {
    format::to_bytes(&sample()).unwrap()
}

/// A file taken apart into its sections, to be edited and put back together with
/// correct CRCs, so that tests reach the semantic checks behind the checksums (a
/// hostile file can carry valid CRCs).
struct Parts {
    header: Vec<u8>,
    sections: Vec<(SectionEntry, Vec<u8>)>,
}

impl Parts {
    fn of(bytes: &[u8]) -> Parts {
        let count = u32::from_le_bytes(bytes[32..36].try_into().unwrap()) as usize;
        let sections = (0..count)
            .map(|k| {
                let e = SectionEntry::from_bytes(&bytes[HEADER_SIZE + k * SECTION_ENTRY_SIZE..]);
                (e, bytes[e.offset as usize..(e.offset + e.length) as usize].to_vec())
            })
            .collect();
        Parts { header: bytes[..HEADER_SIZE].to_vec(), sections }
    }

    fn find(&mut self, kind: SectionKind, level: u32) -> &mut Vec<u8> {
        &mut self.sections.iter_mut().find(|(e, _)| e.kind == kind as u32 && e.level == level).unwrap().1
    }

    fn entry(&mut self, kind: SectionKind, level: u32) -> &mut SectionEntry {
        &mut self.sections.iter_mut().find(|(e, _)| e.kind == kind as u32 && e.level == level).unwrap().0
    }

    /// Lays the sections out again (64-aligned, in order) with fresh CRCs and sizes.
    fn assemble(&self) -> Vec<u8> {
        let table_len = self.sections.len() * SECTION_ENTRY_SIZE;
        let mut offset = ((HEADER_SIZE + table_len) as u64).div_ceil(64) * 64;
        let mut entries = Vec::new();
        for (e, data) in &self.sections {
            entries.push(SectionEntry { offset, length: data.len() as u64, crc32: crc32fast::hash(data), ..*e });
            offset = (offset + data.len() as u64).div_ceil(64) * 64;
        }
        let size = entries.last().map_or(offset, |e| e.offset + e.length) as usize;
        let mut out = vec![0u8; size];
        out[..HEADER_SIZE].copy_from_slice(&self.header);
        let table: Vec<u8> = entries.iter().flat_map(|e| e.to_bytes()).collect();
        out[HEADER_SIZE..HEADER_SIZE + table_len].copy_from_slice(&table);
        for (e, (_, data)) in entries.iter().zip(&self.sections) {
            out[e.offset as usize..(e.offset + e.length) as usize].copy_from_slice(data);
        }
        out[16..24].copy_from_slice(&(size as u64).to_le_bytes());
        out[32..36].copy_from_slice(&(entries.len() as u32).to_le_bytes());
        out[48..52].copy_from_slice(&crc32fast::hash(&table).to_le_bytes());
        reseal_header(&mut out);
        out
    }
}

/// Recomputes the header CRC after an edit of the header.
fn reseal_header(b: &mut [u8]) {
    b[44..48].fill(0);
    let crc = crc32fast::hash(&b[..HEADER_SIZE]);
    b[44..48].copy_from_slice(&crc.to_le_bytes());
}

/// Recomputes the table CRC (and then the header's) after an edit of the table.
fn reseal_table(b: &mut [u8]) {
    let count = u32::from_le_bytes(b[32..36].try_into().unwrap()) as usize;
    let crc = crc32fast::hash(&b[HEADER_SIZE..HEADER_SIZE + count * SECTION_ENTRY_SIZE]);
    b[48..52].copy_from_slice(&crc.to_le_bytes());
    reseal_header(b);
}

fn edit_entry(b: &mut [u8], index: usize, f: impl FnOnce(&mut SectionEntry)) {
    let at = HEADER_SIZE + index * SECTION_ENTRY_SIZE;
    let mut e = SectionEntry::from_bytes(&b[at..]);
    f(&mut e);
    b[at..at + SECTION_ENTRY_SIZE].copy_from_slice(&e.to_bytes());
    reseal_table(b);
}

/// What a corruption case expects of the error.
type Expect = fn(&FormatError) -> bool;

fn err(bytes: &[u8]) -> FormatError {
    match format::read(bytes) {
        Ok(_) => panic!("a corrupt file was accepted"),
        Err(e) => e,
    }
}

/// Each case's edit applied to a fresh copy of `bytes` must give the error it expects.
fn run_catalogue(bytes: &[u8], cases: Vec<(&str, fn(&mut Parts), Expect)>) {
    for (name, edit, expect) in cases {
        let mut parts = Parts::of(bytes);
        edit(&mut parts);
        let e = err(&parts.assemble());
        assert!(expect(&e), "{name}: unexpected error {e:?}");
    }
}

#[test]
fn round_trip_is_exact_and_deterministic() {
    let m = sample();
    let bytes = format::to_bytes(&m).unwrap();
    assert_eq!(format::read(&bytes).unwrap(), m);
    assert_eq!(format::to_bytes(&m).unwrap(), bytes, "same model, same bytes");
    // Through a file (memory-mapped read).
    let dir = std::env::temp_dir().join(format!("fabric-hyb-{}", std::process::id()));
    let path = dir.join("sample.hyb");
    format::write_file(&m, &path).unwrap();
    assert_eq!(format::read_file(&path).unwrap(), m);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_bsdf_round_trips_and_a_reader_that_skips_its_transmission_reads_the_brdf() {
    let m = bsdf_sample();
    let bytes = format::to_bytes(&m).unwrap();
    assert_eq!(format::read(&bytes).unwrap(), m);
    assert!(m.has_transmission() && m.levels.iter().all(|l| l.transmission.as_ref().is_some_and(|t| t.len() == (l.width * l.height) as usize)));
    // The openness (1.10) survives the trip; a record of 1.9 (zeros there) reads closed.
    let gap = m.levels[0].texel_brdf(0, 0).transmission.gap;
    assert!(gap.o > 0.0 && (gap.q - 2.0).abs() < 1e-3 && (gap.aniso[0] - 0.5).abs() < 0.01 && (gap.aniso[1] + 0.25).abs() < 0.01, "{gap:?}");
    let mut closed = m.clone();
    closed.levels.iter_mut().flat_map(|l| l.transmission.iter_mut().flatten()).for_each(|t| (t.gap, t.gap_aniso) = ([0; 2], 0));
    assert_eq!(format::read(&format::to_bytes(&closed).unwrap()).unwrap().levels[0].texel_brdf(0, 0).transmission.gap, Default::default());
    // The transmission visibility (1.16) survives the trip; a 1.15 reader skips its
    // section and reads the same terms with g = q = 0.
    let t = m.levels[0].texel_brdf(0, 0).transmission;
    let (g, q) = (t.grad, t.curv);
    assert!(m.levels.iter().all(|l| l.transmission_visibility.is_some()) && (g[0] + 0.5).abs() < 1e-3 && (g[1] + 0.4).abs() < 1e-3 && (g[2] + 0.6).abs() < 1e-3, "{g:?}");
    assert!((q[0] + 0.3).abs() < 1e-3 && (q[5] + 0.15).abs() < 1e-3, "{q:?}");
    let mut parts = Parts::of(&bytes);
    for (e, _) in parts.sections.iter_mut().filter(|(e, _)| e.kind == SectionKind::TransmissionVisibility as u32) {
        assert_eq!(e.flags & SECTION_OPTIONAL, SECTION_OPTIONAL);
        e.kind = 4004;
    }
    let ungraded = format::read(&parts.assemble()).unwrap();
    assert!(ungraded.levels.iter().all(|l| l.transmission_visibility.is_none()) && ungraded.levels[0].transmission == m.levels[0].transmission);
    assert_eq!((ungraded.levels[0].texel_brdf(0, 0).transmission.grad, ungraded.levels[0].texel_brdf(0, 0).transmission.curv), ([0.0; 4], [0.0; 6]));
    // The sections are optional: a reader that knows neither kind (a 1.2 reader) skips
    // them and gets the reflection alone.
    let mut parts = Parts::of(&bytes);
    for (e, _) in parts.sections.iter_mut().filter(|(e, _)| e.kind == SectionKind::Transmission as u32 || e.kind == SectionKind::TransmissionVisibility as u32) {
        assert_eq!(e.flags & SECTION_OPTIONAL, SECTION_OPTIONAL);
        e.kind += 4000;
    }
    let brdf = format::read(&parts.assemble()).unwrap();
    assert!(!brdf.has_transmission());
    assert_eq!(brdf.levels[0].surface, m.levels[0].surface);
}

#[test]
fn transmission_corruption_catalogue() {
    type Edit = fn(&mut Parts);
    let cases: Vec<(&str, Edit, Expect)> = vec![
        ("NaN k_dt", |p| p.find(SectionKind::Transmission, 0)[0..2].copy_from_slice(&0x7e00u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::TransmissionParam { field: "k_dt.r", .. }))),
        ("negative k_t", |p| p.find(SectionKind::Transmission, 1)[8..10].copy_from_slice(&0xbc00u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::TransmissionParam { field: "k_t.g", .. }))),
        ("β_t = 0 with k_t > 0", |p| p.find(SectionKind::Transmission, 0)[12..14].copy_from_slice(&0u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::TransmissionParam { field: "beta_t", .. }))),
        ("τ = 20", |p| p.find(SectionKind::Transmission, 2)[16..18].copy_from_slice(&0x4d00u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::TransmissionParam { field: "tau", .. }))),
        ("open beyond 1", |p| p.find(SectionKind::Transmission, 0)[18..20].copy_from_slice(&0x4000u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::TransmissionParam { field: "openness o", .. }))),
        ("NaN openness decay", |p| p.find(SectionKind::Transmission, 1)[20..22].copy_from_slice(&0x7e00u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::TransmissionParam { field: "openness q", .. }))),
        ("openness decay 100", |p| p.find(SectionKind::Transmission, 2)[20..22].copy_from_slice(&0x5640u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::TransmissionParam { field: "openness q", .. }))),
        ("one record short", |p| { let t = p.find(SectionKind::Transmission, 1); t.truncate(t.len() - 24) }, |e| matches!(e, FormatError::Invalid(ModelError::Length { what: "transmission records", level: 1, .. }))),
        ("not whole records", |p| p.find(SectionKind::Transmission, 0).push(0), |e| matches!(e, FormatError::Section { kind, .. } if kind == "TRANSMISSION")),
        ("for a level that does not exist", |p| p.entry(SectionKind::Transmission, 3).level = 12, |e| matches!(e, FormatError::Section { level: 12, .. })),
        // The transmission visibility (1.16).
        ("NaN g_u.x", |p| p.find(SectionKind::TransmissionVisibility, 0)[0..2].copy_from_slice(&0x7e00u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::TransmissionVisibilityParam { field: "g_u.x", level: 0, .. }))),
        ("g_l.y = 3", |p| p.find(SectionKind::TransmissionVisibility, 1)[6..8].copy_from_slice(&0x4200u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::TransmissionVisibilityParam { field: "g_l.y", level: 1, .. }))),
        ("infinite q_cross", |p| p.find(SectionKind::TransmissionVisibility, 2)[18..20].copy_from_slice(&0x7c00u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::TransmissionVisibilityParam { field: "q_cross", level: 2, .. }))),
        ("a visibility record short", |p| { let t = p.find(SectionKind::TransmissionVisibility, 1); t.truncate(t.len() - 20) }, |e| matches!(e, FormatError::Invalid(ModelError::Length { what: "transmission visibility records", level: 1, .. }))),
        ("visibility records not whole", |p| p.find(SectionKind::TransmissionVisibility, 0).push(0), |e| matches!(e, FormatError::Section { kind, .. } if kind == "TRANSMISSION_VISIBILITY")),
        ("a visibility without transmission", |p| p.entry(SectionKind::Transmission, 2).kind = 4000, |e| matches!(e, FormatError::Invalid(ModelError::TransmissionVisibilityAlone { level: 2 }))),
    ];
    run_catalogue(&format::to_bytes(&bsdf_sample()).unwrap(), cases);
}

#[test]
fn view_tilts_round_trip_and_a_reader_that_skips_them_reads_the_rest() {
    let m = tilted_sample();
    let bytes = format::to_bytes(&m).unwrap();
    assert_eq!(format::read(&bytes).unwrap(), m);
    assert!(m.levels[0].view_tilt.is_none() && m.levels[1..].iter().all(|l| l.view_tilt.as_ref().is_some_and(|t| t.len() == (l.width * l.height) as usize)));
    // Optional: a 1.3 reader skips the section and shades the frames as stored.
    let mut parts = Parts::of(&bytes);
    for (e, _) in parts.sections.iter_mut().filter(|(e, _)| e.kind == SectionKind::ViewTilt as u32) {
        assert_eq!(e.flags & SECTION_OPTIONAL, SECTION_OPTIONAL);
        e.kind = 4001;
    }
    let plain = format::read(&parts.assemble()).unwrap();
    assert!(plain.levels.iter().all(|l| l.view_tilt.is_none()));
    assert_eq!(plain, sample());
}

#[test]
fn gradients_round_trip_and_a_reader_that_skips_them_reads_the_rest() {
    let m = gradient_sample();
    let bytes = format::to_bytes(&m).unwrap();
    let back = format::read(&bytes).unwrap();
    assert_eq!(back, m);
    assert!(m.levels.iter().all(|l| l.gradient.as_ref().is_some_and(|g| g.len() == (l.width * l.height) as usize)));
    let g = back.levels[0].texel_brdf(0, 0).gradient;
    assert!(g != [0.0; 4] && (g[0] + 0.2).abs() < 1e-3, "texel (0, 0) decodes its gradient: {g:?}");
    // Optional: a 1.11 reader skips the section and shades every texel with g = 0.
    let mut parts = Parts::of(&bytes);
    for (e, _) in parts.sections.iter_mut().filter(|(e, _)| e.kind == SectionKind::Gradient as u32) {
        assert_eq!(e.flags & SECTION_OPTIONAL, SECTION_OPTIONAL);
        e.kind = 4002;
    }
    let plain = format::read(&parts.assemble()).unwrap();
    assert_eq!(plain, sample());
    assert_eq!(plain.levels[0].texel_brdf(0, 0).gradient, [0.0; 4]);
}

#[test]
fn gradient_corruption_catalogue() {
    type Edit = fn(&mut Parts);
    let cases: Vec<(&str, Edit, Expect)> = vec![
        ("NaN g_o.x", |p| p.find(SectionKind::Gradient, 0)[0..2].copy_from_slice(&0x7e00u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::GradientParam { field: "g_o.x", level: 0, .. }))),
        ("infinite g_i.y", |p| p.find(SectionKind::Gradient, 1)[6..8].copy_from_slice(&0x7c00u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::GradientParam { field: "g_i.y", level: 1, .. }))),
        ("g_i.x = 3", |p| p.find(SectionKind::Gradient, 0)[4..6].copy_from_slice(&0x4200u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::GradientParam { field: "g_i.x", .. }))),
        ("one record short", |p| { let t = p.find(SectionKind::Gradient, 1); t.truncate(t.len() - 8) }, |e| matches!(e, FormatError::Invalid(ModelError::Length { what: "visibility gradient records", level: 1, .. }))),
        ("not whole records", |p| p.find(SectionKind::Gradient, 0).push(0), |e| matches!(e, FormatError::Section { kind, .. } if kind == "GRADIENT")),
        ("for a level that does not exist", |p| p.entry(SectionKind::Gradient, 2).level = 12, |e| matches!(e, FormatError::Section { level: 12, .. })),
    ];
    run_catalogue(&format::to_bytes(&gradient_sample()).unwrap(), cases);
}

#[test]
fn curvatures_round_trip_and_a_reader_that_skips_them_reads_the_rest() {
    let m = curvature_sample();
    let bytes = format::to_bytes(&m).unwrap();
    let back = format::read(&bytes).unwrap();
    assert_eq!(back, m);
    assert!(m.levels.iter().all(|l| l.curvature.as_ref().is_some_and(|q| q.len() == (l.width * l.height) as usize)));
    let q = back.levels[0].texel_brdf(0, 0).curvature;
    assert!((q[0] + 0.25).abs() < 1e-3 && (q[5] + 0.2).abs() < 1e-3, "texel (0, 0) decodes its curvature: {q:?}");
    // Optional: a 1.14 reader skips the section and shades every texel with q = 0.
    let mut parts = Parts::of(&bytes);
    for (e, _) in parts.sections.iter_mut().filter(|(e, _)| e.kind == SectionKind::Curvature as u32) {
        assert_eq!(e.flags & SECTION_OPTIONAL, SECTION_OPTIONAL);
        e.kind = 4003;
    }
    let plain = format::read(&parts.assemble()).unwrap();
    assert_eq!(plain, gradient_sample());
    assert_eq!(plain.levels[0].texel_brdf(0, 0).curvature, [0.0; 6]);
}

#[test]
fn curvature_corruption_catalogue() {
    type Edit = fn(&mut Parts);
    let cases: Vec<(&str, Edit, Expect)> = vec![
        ("NaN q_xx", |p| p.find(SectionKind::Curvature, 0)[0..2].copy_from_slice(&0x7e00u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::CurvatureParam { field: "q_xx", level: 0, .. }))),
        ("infinite q_cross", |p| p.find(SectionKind::Curvature, 1)[10..12].copy_from_slice(&0x7c00u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::CurvatureParam { field: "q_cross", level: 1, .. }))),
        ("q_xy = 3", |p| p.find(SectionKind::Curvature, 0)[4..6].copy_from_slice(&0x4200u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::CurvatureParam { field: "q_xy", .. }))),
        ("one record short", |p| { let t = p.find(SectionKind::Curvature, 1); t.truncate(t.len() - 12) }, |e| matches!(e, FormatError::Invalid(ModelError::Length { what: "visibility curvature records", level: 1, .. }))),
        ("not whole records", |p| p.find(SectionKind::Curvature, 0).push(0), |e| matches!(e, FormatError::Section { kind, .. } if kind == "CURVATURE")),
        ("for a level that does not exist", |p| p.entry(SectionKind::Curvature, 2).level = 12, |e| matches!(e, FormatError::Section { level: 12, .. })),
    ];
    run_catalogue(&format::to_bytes(&curvature_sample()).unwrap(), cases);
}

#[test]
fn view_tilt_corruption_catalogue() {
    type Edit = fn(&mut Parts);
    let cases: Vec<(&str, Edit, Expect)> = vec![
        ("NaN b00", |p| p.find(SectionKind::ViewTilt, 1)[0..2].copy_from_slice(&0x7e00u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::ViewTiltParam { field: "b00", level: 1, .. }))),
        ("infinite c1", |p| p.find(SectionKind::ViewTilt, 2)[10..12].copy_from_slice(&0x7c00u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::ViewTiltParam { field: "c1", level: 2, .. }))),
        ("b11 = 100", |p| p.find(SectionKind::ViewTilt, 1)[6..8].copy_from_slice(&0x5640u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::ViewTiltParam { field: "b11", .. }))),
        ("one record short", |p| { let t = p.find(SectionKind::ViewTilt, 1); t.truncate(t.len() - 12) }, |e| matches!(e, FormatError::Invalid(ModelError::Length { what: "view tilt records", level: 1, .. }))),
        ("not whole records", |p| p.find(SectionKind::ViewTilt, 1).push(0), |e| matches!(e, FormatError::Section { kind, .. } if kind == "VIEW_TILT")),
        ("on level 0", |p| p.entry(SectionKind::ViewTilt, 1).level = 0, |e| matches!(e, FormatError::Invalid(ModelError::ViewTiltAtLevel0))),
        ("for a level that does not exist", |p| p.entry(SectionKind::ViewTilt, 3).level = 12, |e| matches!(e, FormatError::Section { level: 12, .. })),
    ];
    run_catalogue(&format::to_bytes(&tilted_sample()).unwrap(), cases);
}

#[test]
fn compact_levels_round_trip_bit_for_bit_in_fewer_bytes() {
    let m = compact_sample();
    let bytes = format::to_bytes(&m).unwrap();
    assert_eq!(format::read(&bytes).unwrap(), m);
    let info = format::inspect(&bytes).unwrap();
    let kinds = |level: u32| info.sections.iter().filter(|s| s.level == level).map(|s| s.kind.as_str()).collect::<Vec<_>>();
    // Level 0 is clustered: wide. The per-texel levels: compact, and nothing wide beside.
    assert!(kinds(0).contains(&"SURFACE_HEADERS") && !kinds(0).iter().any(|k| k.ends_with("_COMPACT")));
    for level in 1..m.levels.len() as u32 {
        let k = kinds(level);
        for (compact, wide) in [("SURFACE_TEXELS_COMPACT", "SURFACE_HEADERS"), ("SURFACE_LOBES_COMPACT", "SURFACE_LOBES"), ("VIEW_TILT_COMPACT", "VIEW_TILT")] {
            assert!(k.contains(&compact) && !k.contains(&wide), "level {level}: {k:?}");
        }
        // The statistics count what the file holds.
        let stored: u64 = info.sections.iter().filter(|s| s.level == level && s.kind.starts_with("SURFACE") || s.level == level && s.kind.starts_with("VIEW_TILT")).map(|s| s.length).sum();
        let st = &info.model.level_stats[level as usize];
        assert_eq!(stored, st.surface_bytes + st.view_tilt_bytes, "level {level}");
        let l = &m.levels[level as usize];
        let lobes = match &l.surface {
            Surface::PerTexel(t) => t.lobes.len() as u64,
            _ => unreachable!(),
        };
        assert_eq!(st.surface_bytes, 8 * (l.width * l.height) as u64 + 12 * lobes);
        assert_eq!(st.view_tilt_bytes, 6 * (l.width * l.height) as u64);
    }
    assert!(bytes.len() < format::to_bytes(&tilted_sample()).unwrap().len());
    // The compact tilts are optional: a 1.6 reader that skipped them reads the rest.
    let mut parts = Parts::of(&bytes);
    for (e, _) in parts.sections.iter_mut().filter(|(e, _)| e.kind == SectionKind::ViewTiltCompact as u32) {
        assert_eq!(e.flags & SECTION_OPTIONAL, SECTION_OPTIONAL);
        e.kind = 4003;
    }
    assert!(format::read(&parts.assemble()).unwrap().levels.iter().all(|l| l.view_tilt.is_none()));
    // The compact surface records are required: a reader that does not know them refuses.
    let mut parts = Parts::of(&bytes);
    parts.entry(SectionKind::SurfaceTexelsCompact, 1).kind = 4004;
    assert!(matches!(err(&parts.assemble()), FormatError::UnknownRequired { kind: 4004, .. }));
}

#[test]
fn compact_corruption_catalogue() {
    type Edit = fn(&mut Parts);
    let cases: Vec<(&str, Edit, Expect)> = vec![
        ("reserved bit 15", |p| p.find(SectionKind::SurfaceTexelsCompact, 1)[7] |= 0x80, |e| matches!(e, FormatError::Section { kind, level: 1, why, .. } if kind == "SURFACE_TEXELS_COMPACT" && why.contains("record 0") && why.contains("reserved"))),
        ("octahedral code off the grid", |p| p.find(SectionKind::SurfaceLobesCompact, 2)[12..14].copy_from_slice(&0x07ffu16.to_le_bytes()), |e| matches!(e, FormatError::Section { kind, level: 2, why, .. } if kind == "SURFACE_LOBES_COMPACT" && why.contains("record 1"))),
        ("lobe counts past the lobes", |p| p.find(SectionKind::SurfaceTexelsCompact, 1)[7] |= 0x70, |e| matches!(e, FormatError::Invalid(ModelError::LobeRange { level: 1, .. }))),
        ("one texel short", |p| { let t = p.find(SectionKind::SurfaceTexelsCompact, 1); t.truncate(t.len() - 8) }, |e| matches!(e, FormatError::Invalid(_))),
        ("not whole lobes", |p| p.find(SectionKind::SurfaceLobesCompact, 1).push(0), |e| matches!(e, FormatError::Section { kind, .. } if kind == "SURFACE_LOBES_COMPACT")),
        ("NaN β", |p| p.find(SectionKind::SurfaceLobesCompact, 1)[8..10].copy_from_slice(&0x7e00u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::LobeParam { field: "beta", level: 1, .. }))),
        ("a tilt past 8", |p| { let t = p.find(SectionKind::ViewTiltCompact, 1); t[0..4].copy_from_slice(&[0x0f, 0, 0, 0x7e]) }, |e| matches!(e, FormatError::Invalid(ModelError::ViewTiltParam { field: "b11", level: 1, .. }))),
        ("a tilt code past its range", |p| { let t = p.find(SectionKind::ViewTiltCompact, 2); t[6..12].copy_from_slice(&[0x00, 0x04, 0, 0, 0, 0]) }, |e| matches!(e, FormatError::Section { kind, level: 2, why, .. } if kind == "VIEW_TILT_COMPACT" && why.contains("record 1"))),
        ("wide and compact headers together", |p| {
            let (e, data) = p.sections.iter().find(|(e, _)| e.kind == SectionKind::SurfaceHeaders as u32 && e.level == 0).cloned().unwrap();
            p.sections.push((SectionEntry { level: 1, ..e }, data));
        }, |e| matches!(e, FormatError::Section { kind, level: 1, why, .. } if kind == "SURFACE_TEXELS_COMPACT" && why.contains("SURFACE_HEADERS"))),
        ("a node's axis off the grid", |p| { let n = p.find(SectionKind::FlyawayNodesCompact, 1); n[3] |= 0xf0; n[4] |= 0x7f }, |e| matches!(e, FormatError::Section { kind, level: 1, why, .. } if kind == "FLYAWAY_NODES_COMPACT" && why.contains("record 0") && why.contains("2047"))),
        ("a node below the slab", |p| p.find(SectionKind::FlyawayNodesCompact, 1)[0..2].copy_from_slice(&0x0fffu16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::FlyawayNode { level: 1, node: 0, .. } | ModelError::FlyawayOrder { level: 1, .. }))),
        ("a list head past the nodes", |p| { let h = p.find(SectionKind::FlyawayHeads, 1); let last = h.chunks_exact(4).rposition(|c| c != [0xff; 4]).unwrap(); h[4 * last..4 * last + 4].copy_from_slice(&1000u32.to_le_bytes()) }, |e| matches!(e, FormatError::Section { kind, level: 1, why, .. } if kind == "FLYAWAY_NODES_COMPACT" && why.contains("1000"))),
        ("a list head past its node 0", |p| { let h = p.find(SectionKind::FlyawayHeads, 1); let first = h.chunks_exact(4).position(|c| c != [0xff; 4]).unwrap(); h[4 * first..4 * first + 4].copy_from_slice(&1u32.to_le_bytes()) }, |e| matches!(e, FormatError::Invalid(ModelError::FlyawayUnreached { level: 1, node: 0 }))),
        ("compact records on the clustered level", |p| p.entry(SectionKind::SurfaceLobesCompact, 1).level = 0, |e| matches!(e, FormatError::Section { level: 0, why, .. } if why.contains("clustered"))),
    ];
    run_catalogue(&format::to_bytes(&compact_sample()).unwrap(), cases);
}

#[test]
fn flyaway_spreads_round_trip_and_a_reader_that_skips_them_reads_the_rest() {
    let m = spread_sample();
    let bytes = format::to_bytes(&m).unwrap();
    assert_eq!(format::read(&bytes).unwrap(), m);
    // Optional: a 1.4 reader skips the section and shades each node with its one axis.
    let mut parts = Parts::of(&bytes);
    let mut skipped = 0;
    for (e, _) in parts.sections.iter_mut().filter(|(e, _)| e.kind == SectionKind::FlyawaySpreadCompact as u32) {
        assert_eq!(e.flags & SECTION_OPTIONAL, SECTION_OPTIONAL);
        e.kind = 4002;
        skipped += 1;
    }
    assert!(skipped > 0);
    let plain = format::read(&parts.assemble()).unwrap();
    assert_eq!(plain, sample());
    // 1.7 writes them compact; a 1.5 file's wide records (reserved field 0) read the same.
    let mut parts = Parts::of(&bytes);
    assert!(parts.sections.iter().all(|(e, _)| e.kind != SectionKind::FlyawaySpread as u32));
    widen_spreads(&mut parts);
    assert_eq!(format::read(&parts.assemble()).unwrap(), m);
    parts.find(SectionKind::FlyawaySpread, 1)[6] = 1;
    assert!(matches!(err(&parts.assemble()), FormatError::Invalid(ModelError::FlyawayNode { level: 1, node: 0, why }) if why.contains("reserved")));
}

/// The spread sample with a second group of axes per coarse node (format 1.8).
fn group_sample() -> HybridModel {
    let mut m = spread_sample();
    examples::add_axis_groups(&mut m);
    m.validate().expect("the group sample is valid");
    m
}

#[test]
fn flyaway_groups_round_trip_and_a_reader_that_skips_them_reads_the_rest() {
    let m = group_sample();
    let bytes = format::to_bytes(&m).unwrap();
    assert_eq!(format::read(&bytes).unwrap(), m);
    // Optional: a 1.7 reader skips the section and shades each node as its first group.
    let mut parts = Parts::of(&bytes);
    let mut skipped = 0;
    for (e, data) in parts.sections.iter_mut().filter(|(e, _)| e.kind == SectionKind::FlyawayGroup as u32) {
        assert_eq!(e.flags & SECTION_OPTIONAL, SECTION_OPTIONAL);
        assert_eq!(data.len() % 4, 0);
        e.kind = 4003;
        skipped += 1;
    }
    assert!(skipped > 0);
    assert_eq!(format::read(&parts.assemble()).unwrap(), spread_sample());
}

#[test]
fn flyaway_group_corruption_catalogue() {
    type Edit = fn(&mut Parts);
    let cases: Vec<(&str, Edit, Expect)> = vec![
        ("one record short", |p| { let t = p.find(SectionKind::FlyawayGroup, 1); t.truncate(t.len() - 4) }, |e| matches!(e, FormatError::Invalid(ModelError::Length { what: "flyaway axis groups", level: 1, .. }))),
        ("one record too many", |p| p.find(SectionKind::FlyawayGroup, 1).extend_from_slice(&[0; 4]), |e| matches!(e, FormatError::Invalid(ModelError::Length { what: "flyaway axis groups", level: 1, .. }))),
        ("not whole records", |p| p.find(SectionKind::FlyawayGroup, 1).push(0), |e| matches!(e, FormatError::Section { kind, .. } if kind == "FLYAWAY_GROUP")),
        ("without spread records", |p| p.sections.retain(|(e, _)| !(e.kind == SectionKind::FlyawaySpreadCompact as u32 && e.level == 1)), |e| matches!(e, FormatError::Invalid(ModelError::Length { level: 1, got: 0, .. }))),
        ("on a level without flyaways", |p| p.entry(SectionKind::FlyawayGroup, 1).level = 2, |e| matches!(e, FormatError::Section { level: 2, why, .. } if why.contains("without FLYAWAY_HEADS"))),
    ];
    run_catalogue(&format::to_bytes(&group_sample()).unwrap(), cases);
}

fn gain_sample() -> HybridModel {
    let mut m = group_sample();
    examples::add_path_gains(&mut m);
    m.validate().expect("the path gain sample is valid");
    m
}

#[test]
fn flyaway_path_gains_round_trip_and_a_reader_that_skips_them_reads_the_rest() {
    let m = gain_sample();
    let bytes = format::to_bytes(&m).unwrap();
    assert_eq!(format::read(&bytes).unwrap(), m);
    // Optional: a 1.8 reader skips the section and crosses coarse nodes by Beer's law.
    let mut parts = Parts::of(&bytes);
    let mut skipped = 0;
    for (e, data) in parts.sections.iter_mut().filter(|(e, _)| e.kind == SectionKind::FlyawayPathGain as u32) {
        assert_eq!(e.flags & SECTION_OPTIONAL, SECTION_OPTIONAL);
        assert_eq!(data.len(), 36);
        e.kind = 4004;
        skipped += 1;
    }
    assert!(skipped > 0);
    assert_eq!(format::read(&parts.assemble()).unwrap(), group_sample());
}

#[test]
fn flyaway_path_gain_corruption_catalogue() {
    type Edit = fn(&mut Parts);
    let cases: Vec<(&str, Edit, Expect)> = vec![
        ("a gain past the range", |p| p.find(SectionKind::FlyawayPathGain, 1)[8..12].copy_from_slice(&1e9f32.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::PathGain { level: 1, why }) if why.contains("20°"))),
        ("a NaN gain", |p| p.find(SectionKind::FlyawayPathGain, 1)[32..36].copy_from_slice(&f32::NAN.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::PathGain { level: 1, why }) if why.contains("80°"))),
        ("a zero gain", |p| p.find(SectionKind::FlyawayPathGain, 1)[0..4].copy_from_slice(&0f32.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::PathGain { level: 1, .. }))),
        ("one gain short", |p| { let t = p.find(SectionKind::FlyawayPathGain, 1); t.truncate(t.len() - 4) }, |e| matches!(e, FormatError::Section { kind, why, .. } if kind == "FLYAWAY_PATH_GAIN" && why.contains("8 gains"))),
        ("one gain too many", |p| p.find(SectionKind::FlyawayPathGain, 1).extend_from_slice(&1f32.to_le_bytes()), |e| matches!(e, FormatError::Section { kind, why, .. } if kind == "FLYAWAY_PATH_GAIN" && why.contains("10 gains"))),
        ("not whole records", |p| p.find(SectionKind::FlyawayPathGain, 1).push(0), |e| matches!(e, FormatError::Section { kind, .. } if kind == "FLYAWAY_PATH_GAIN")),
        ("twice for one level", |p| {
            let (e, data) = p.sections.iter().find(|(e, _)| e.kind == SectionKind::FlyawayPathGain as u32 && e.level == 1).cloned().unwrap();
            p.sections.push((e, data));
        }, |e| matches!(e, FormatError::Duplicate { kind: "FLYAWAY_PATH_GAIN", .. })),
        ("on a level without flyaways", |p| p.entry(SectionKind::FlyawayPathGain, 1).level = 2, |e| matches!(e, FormatError::Section { level: 2, why, .. } if why.contains("without FLYAWAY_HEADS"))),
    ];
    run_catalogue(&format::to_bytes(&gain_sample()).unwrap(), cases);
}

/// Rewrites the compact spread sections as 1.5's wide ones (8 bytes, reserved 0).
fn widen_spreads(parts: &mut Parts) {
    for (e, data) in parts.sections.iter_mut().filter(|(e, _)| e.kind == SectionKind::FlyawaySpreadCompact as u32) {
        e.kind = SectionKind::FlyawaySpread as u32;
        *data = data.chunks_exact(6).flat_map(|c| [c[0], c[1], c[2], c[3], c[4], c[5], 0, 0]).collect();
    }
}

#[test]
fn flyaway_spread_corruption_catalogue() {
    type Edit = fn(&mut Parts);
    let cases: Vec<(&str, Edit, Expect)> = vec![
        ("weights past 1", |p| p.find(SectionKind::FlyawaySpreadCompact, 1)[2..4].copy_from_slice(&[200, 100]), |e| matches!(e, FormatError::Invalid(ModelError::FlyawayNode { level: 1, node: 0, why }) if why.contains("sum past 1"))),
        ("a reversed depth range", |p| p.find(SectionKind::FlyawaySpreadCompact, 1)[10..12].copy_from_slice(&[200, 100]), |e| matches!(e, FormatError::Invalid(ModelError::FlyawayNode { level: 1, node: 1, why }) if why.contains("reversed"))),
        ("one record short", |p| { let t = p.find(SectionKind::FlyawaySpreadCompact, 1); t.truncate(t.len() - 6) }, |e| matches!(e, FormatError::Invalid(ModelError::Length { what: "flyaway spread records", level: 1, .. }))),
        ("one record too many", |p| p.find(SectionKind::FlyawaySpreadCompact, 1).extend_from_slice(&[0; 6]), |e| matches!(e, FormatError::Invalid(ModelError::Length { what: "flyaway spread records", level: 1, .. }))),
        ("not whole records", |p| p.find(SectionKind::FlyawaySpreadCompact, 1).push(0), |e| matches!(e, FormatError::Section { kind, .. } if kind == "FLYAWAY_SPREAD_COMPACT")),
        ("moved to a level of another node count", |p| p.entry(SectionKind::FlyawaySpreadCompact, 1).level = 0, |e| matches!(e, FormatError::Invalid(ModelError::Length { what: "flyaway spread records", level: 0, .. }))),
        ("on a level without flyaways", |p| p.entry(SectionKind::FlyawaySpreadCompact, 1).level = 2, |e| matches!(e, FormatError::Section { level: 2, why, .. } if why.contains("without FLYAWAY_HEADS"))),
        ("for a level that does not exist", |p| p.entry(SectionKind::FlyawaySpreadCompact, 1).level = 12, |e| matches!(e, FormatError::Section { level: 12, .. })),
        ("wide and compact together", |p| {
            let (e, data) = p.sections.iter().find(|(e, _)| e.kind == SectionKind::FlyawaySpreadCompact as u32 && e.level == 1).cloned().unwrap();
            let wide: Vec<u8> = data.chunks_exact(6).flat_map(|c| [c[0], c[1], c[2], c[3], c[4], c[5], 0, 0]).collect();
            p.sections.push((SectionEntry { kind: SectionKind::FlyawaySpread as u32, ..e }, wide));
        }, |e| matches!(e, FormatError::Section { kind, level: 1, .. } if kind == "FLYAWAY_SPREAD_COMPACT")),
    ];
    run_catalogue(&format::to_bytes(&spread_sample()).unwrap(), cases);
}

#[test]
fn models_of_every_shape_round_trip() {
    let params = examples::silk_params();
    for (w, h, levels) in [(1, 1, 1), (1, 7, 3), (16, 16, 5), (5, 3, 2)] {
        let tile = fabric_runtime::hybrid::Tile { origin: glam::Vec2::ZERO, size: glam::Vec2::new(w as f32, h as f32), top_z: 1.0, height_scale: 1.0, voxel_depth: 0.25 };
        let m = examples::uniform_model(w, h, levels, tile, |x, _| 0.01 * x, &params, glam::Vec3::Z, glam::Vec3::X).unwrap();
        assert_eq!(format::read(&format::to_bytes(&m).unwrap()).unwrap(), m, "{w}x{h}, {levels} levels");
    }
}

#[test]
fn layout_follows_the_spec() {
    let bytes = sample_bytes();
    assert_eq!(&bytes[0..8], &MAGIC);
    assert_eq!(u16::from_le_bytes([bytes[8], bytes[9]]), format::VERSION_MAJOR);
    assert_eq!(u64::from_le_bytes(bytes[16..24].try_into().unwrap()), bytes.len() as u64);
    let info = format::inspect(&bytes).unwrap();
    for s in &info.sections {
        assert_eq!(s.offset % 64, 0, "{s:?}");
    }
    // MODEL, META, HEIGHT; level 0: 3 clustered + 4 flyaway; level 1: 2 + 4; levels 2, 3: 2 each.
    assert_eq!(info.sections.len(), 3 + 7 + 6 + 2 + 2);
    assert_eq!(info.sections.iter().filter(|s| s.optional).map(|s| s.kind.as_str()).collect::<Vec<_>>(), ["META"]);
    let height = info.sections.iter().find(|s| s.kind == "HEIGHT").unwrap();
    assert_eq!(height.length, 12 * 10 * 2);
    assert_eq!(info.model.level_stats[0].encoding, "clustered");
    assert_eq!(info.model.level_stats[0].clusters, Some(3));
    assert_eq!(info.model.level_stats[0].flyaway_nodes, 10);
    assert_eq!(info.model.level_stats[1].flyaway_longest_list, 2);
    assert_eq!(info.model.level_stats[1].fit_error, Some(0.045));
    assert_eq!(info.model.level_stats[2].fit_error, None, "negative = not measured");
}

#[test]
fn minor_versions_and_unknown_optional_sections_are_read() {
    let mut bytes = sample_bytes();
    bytes[10..12].copy_from_slice(&9u16.to_le_bytes());
    reseal_header(&mut bytes);
    assert_eq!(format::read(&bytes).unwrap(), sample());
    let mut parts = Parts::of(&sample_bytes());
    parts.sections.insert(2, (SectionEntry { kind: 999, flags: SECTION_OPTIONAL, level: 3, ..Default::default() }, vec![0xab; 100]));
    assert_eq!(format::read(&parts.assemble()).unwrap(), sample());
    // Without META the model reads, with empty metadata.
    let mut parts = Parts::of(&sample_bytes());
    parts.sections.retain(|(e, _)| e.kind != SectionKind::Meta as u32);
    let m = format::read(&parts.assemble()).unwrap();
    assert_eq!((m.meta.seed, m.meta.note.as_str()), (0, ""));
    assert_eq!(m.levels, sample().levels);
}

#[test]
fn container_corruption_catalogue() {
    let good = sample_bytes();
    let len = good.len();
    let cases: Vec<(&str, Vec<u8>, Expect)> = vec![
        ("empty", vec![], |e| matches!(e, FormatError::TooShort { len: 0, .. })),
        ("10 bytes", good[..10].to_vec(), |e| matches!(e, FormatError::TooShort { .. })),
        ("bad magic", { let mut b = good.clone(); b[1] = b'X'; b }, |e| matches!(e, FormatError::BadMagic { .. })),
        ("major 2", { let mut b = good.clone(); b[8] = 2; reseal_header(&mut b); b }, |e| matches!(e, FormatError::UnsupportedVersion { major: 2, .. })),
        ("truncated by one byte", good[..len - 1].to_vec(), |e| matches!(e, FormatError::FileSize { .. })),
        ("extra bytes", { let mut b = good.clone(); b.push(0); b }, |e| matches!(e, FormatError::FileSize { .. })),
        ("header bit flip", { let mut b = good.clone(); b[30] ^= 4; b }, |e| matches!(e, FormatError::HeaderChecksum { .. })),
        ("header size past the end", { let mut b = good.clone(); b[12..16].copy_from_slice(&u32::MAX.to_le_bytes()); b }, |e| matches!(e, FormatError::Header { field: "header_size", .. })),
        ("table past the end", { let mut b = good.clone(); b[24..32].copy_from_slice(&(u64::MAX - 8).to_le_bytes()); reseal_header(&mut b); b }, |e| matches!(e, FormatError::TableBounds { .. })),
        ("4 billion sections", { let mut b = good.clone(); b[32..36].copy_from_slice(&u32::MAX.to_le_bytes()); reseal_header(&mut b); b }, |e| matches!(e, FormatError::Header { field: "section_count", .. })),
        ("section count past the table", { let mut b = good.clone(); b[32..36].copy_from_slice(&4000u32.to_le_bytes()); reseal_header(&mut b); b }, |e| matches!(e, FormatError::TableBounds { .. } | FormatError::TableChecksum { .. })),
        ("entry size 8", { let mut b = good.clone(); b[36..40].copy_from_slice(&8u32.to_le_bytes()); reseal_header(&mut b); b }, |e| matches!(e, FormatError::Header { field: "section_entry_size", .. })),
        ("table bit flip", { let mut b = good.clone(); b[HEADER_SIZE + 20] ^= 1; b }, |e| matches!(e, FormatError::TableChecksum { .. })),
        ("section data bit flip", { let mut b = good.clone(); let n = b.len(); b[n - 3] ^= 0x10; b }, |e| matches!(e, FormatError::SectionChecksum { .. })),
        ("length past the end", { let mut b = good.clone(); edit_entry(&mut b, 2, |e| e.length = 1 << 40); b }, |e| matches!(e, FormatError::Section { index: 2, .. })),
        ("offset + length overflows", { let mut b = good.clone(); edit_entry(&mut b, 2, |e| { e.offset = u64::MAX - 63; e.length = 128 }); b }, |e| matches!(e, FormatError::Section { index: 2, .. })),
        ("misaligned offset", { let mut b = good.clone(); edit_entry(&mut b, 2, |e| e.offset += 4); b }, |e| matches!(e, FormatError::Section { index: 2, .. })),
        ("section inside the table", { let mut b = good.clone(); edit_entry(&mut b, 2, |e| { e.offset = 64; e.length = 0 }); b }, |e| matches!(e, FormatError::Section { index: 2, .. })),
    ];
    for (name, bytes, expect) in cases {
        let e = err(&bytes);
        assert!(expect(&e), "{name}: unexpected error {e:?}");
        assert!(!e.to_string().is_empty());
    }
}

#[test]
fn overlapping_and_duplicate_sections_are_rejected() {
    let mut b = sample_bytes();
    // Point section 3 at section 2's bytes, with the matching CRC: an overlap.
    let at2 = SectionEntry::from_bytes(&b[HEADER_SIZE + 2 * SECTION_ENTRY_SIZE..]);
    edit_entry(&mut b, 3, |e| { e.offset = at2.offset; e.length = at2.length; e.crc32 = at2.crc32 });
    assert!(matches!(err(&b), FormatError::Section { why, .. } if why.contains("overlaps")));
    let mut parts = Parts::of(&sample_bytes());
    let dup = parts.sections[2].clone();
    parts.sections.push(dup);
    assert!(matches!(err(&parts.assemble()), FormatError::Duplicate { kind: "HEIGHT", .. }));
}

#[test]
fn semantic_corruption_catalogue() {
    type Edit = fn(&mut Parts);
    let cases: Vec<(&str, Edit, Expect)> = vec![
        ("unknown required section", |p| p.sections.push((SectionEntry { kind: 999, ..Default::default() }, vec![1; 8])), |e| matches!(e, FormatError::UnknownRequired { kind: 999, .. })),
        ("missing HEIGHT", |p| p.sections.retain(|(e, _)| e.kind != SectionKind::Height as u32), |e| matches!(e, FormatError::Missing { kind: "HEIGHT", .. })),
        ("missing MODEL", |p| p.sections.retain(|(e, _)| e.kind != SectionKind::Model as u32), |e| matches!(e, FormatError::Missing { kind: "MODEL", .. })),
        ("missing level-2 lobes", |p| p.sections.retain(|(e, _)| !(e.kind == SectionKind::SurfaceLobes as u32 && e.level == 2)), |e| matches!(e, FormatError::Missing { kind: "SURFACE_LOBES", .. })),
        ("section for level 9", |p| p.entry(SectionKind::SurfaceLobes, 3).level = 9, |e| matches!(e, FormatError::Section { level: 9, .. })),
        ("MODEL width 0", |p| p.find(SectionKind::Model, 0)[0..4].copy_from_slice(&0u32.to_le_bytes()), |e| matches!(e, FormatError::Section { kind, .. } if kind == "MODEL")),
        ("MODEL width 2^31", |p| p.find(SectionKind::Model, 0)[0..4].copy_from_slice(&(1u32 << 31).to_le_bytes()), |e| matches!(e, FormatError::Section { kind, .. } if kind == "MODEL")),
        ("MODEL 99 levels", |p| p.find(SectionKind::Model, 0)[8..12].copy_from_slice(&99u32.to_le_bytes()), |e| matches!(e, FormatError::Section { kind, .. } if kind == "MODEL")),
        ("MODEL 3 levels of 4", |p| p.find(SectionKind::Model, 0)[8..12].copy_from_slice(&3u32.to_le_bytes()), |e| matches!(e, FormatError::Section { level: 3, .. })),
        ("MODEL reading 7", |p| p.find(SectionKind::Model, 0)[12..16].copy_from_slice(&7u32.to_le_bytes()), |e| matches!(e, FormatError::Section { kind, .. } if kind == "MODEL")),
        ("MODEL truncated", |p| p.find(SectionKind::Model, 0).truncate(20), |e| matches!(e, FormatError::Section { kind, .. } if kind == "MODEL")),
        ("tile size NaN", |p| p.find(SectionKind::Model, 0)[32..36].copy_from_slice(&f32::NAN.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::Tile { field: "size.x", .. }))),
        ("tile size 1e-30 (renders black)", |p| p.find(SectionKind::Model, 0)[32..36].copy_from_slice(&1e-30f32.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::Tile { field: "size.x", .. }))),
        ("tile 1e9 from the origin (f32 loses the texel)", |p| p.find(SectionKind::Model, 0)[24..28].copy_from_slice(&1e9f32.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::Tile { field: "origin.x", .. }))),
        ("height scale −1", |p| p.find(SectionKind::Model, 0)[44..48].copy_from_slice(&(-1f32).to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::Tile { field: "height_scale", .. }))),
        ("HEIGHT short", |p| p.find(SectionKind::Height, 0).truncate(100), |e| matches!(e, FormatError::Invalid(ModelError::HeightLength { .. }))),
        ("HEIGHT odd length", |p| p.find(SectionKind::Height, 0).push(0), |e| matches!(e, FormatError::Section { kind, .. } if kind == "HEIGHT")),
        ("NaN k_d", |p| p.find(SectionKind::SurfaceHeaders, 0)[0..2].copy_from_slice(&0x7e00u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::Param { field: "k_d.r", .. }))),
        ("infinite β", |p| p.find(SectionKind::SurfaceLobes, 1)[12..14].copy_from_slice(&0x7c00u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::LobeParam { field: "beta", .. }))),
        ("negative γ", |p| p.find(SectionKind::SurfaceLobes, 2)[14..16].copy_from_slice(&0xbc00u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::LobeParam { field: "gamma", .. }))),
        ("η = 0.5", |p| p.find(SectionKind::FlyawayHeaders, 0)[6..8].copy_from_slice(&0x3800u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::Param { field: "eta", .. }))),
        ("9 lobes", |p| p.find(SectionKind::SurfaceHeaders, 1)[10] = 9, |e| matches!(e, FormatError::Invalid(ModelError::LobeCount { count: 9, .. }))),
        ("no lobes in a per-texel header", |p| p.find(SectionKind::SurfaceHeaders, 1)[10] = 0, |e| matches!(e, FormatError::Invalid(ModelError::LobeCount { count: 0, .. }))),
        ("lobe offset u32::MAX", |p| p.find(SectionKind::SurfaceHeaders, 2)[12..16].copy_from_slice(&u32::MAX.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::LobeRange { .. }))),
        ("reserved byte set", |p| p.find(SectionKind::SurfaceHeaders, 0)[11] = 1, |e| matches!(e, FormatError::Invalid(ModelError::Reserved { .. }))),
        ("cluster index past the table", |p| p.find(SectionKind::SurfaceClusteredTexels, 0)[6..8].copy_from_slice(&3u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::ClusterIndex { index: 3, .. }))),
        ("clustered texels short", |p| p.find(SectionKind::SurfaceClusteredTexels, 0).truncate(80), |e| matches!(e, FormatError::Invalid(ModelError::Length { .. }))),
        ("flyaway nodes without heads", |p| p.sections.retain(|(e, _)| !(e.kind == SectionKind::FlyawayHeads as u32 && e.level == 1)), |e| matches!(e, FormatError::Section { level: 1, .. })),
        ("flyaway head past the nodes", |p| p.find(SectionKind::FlyawayHeads, 1)[4 * 14..4 * 15].copy_from_slice(&1000u32.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::FlyawayLink { index: 1000, .. }))),
        ("flyaway cycle", |p| p.find(SectionKind::FlyawayNodes, 1)[16..20].copy_from_slice(&0u32.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::FlyawayOrder { .. }))),
        ("flyaway self loop", |p| p.find(SectionKind::FlyawayNodes, 1)[0..4].copy_from_slice(&0u32.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::FlyawayOrder { .. }))),
        ("flyaway shared tail", |p| p.find(SectionKind::FlyawayHeads, 1)[0..4].copy_from_slice(&1u32.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::FlyawayShared { .. }))),
        ("flyaway stray node", |p| p.find(SectionKind::FlyawayHeads, 1)[4 * 7..4 * 8].copy_from_slice(&NO_NODE.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::FlyawayUnreached { .. }))),
        ("flyaway zero alpha", |p| p.find(SectionKind::FlyawayNodes, 0)[6..8].copy_from_slice(&0u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::FlyawayNode { .. }))),
        ("flyaway below the slab", |p| p.find(SectionKind::FlyawayNodes, 0)[4..6].copy_from_slice(&500u16.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::FlyawayNode { .. } | ModelError::FlyawayOrder { .. }))),
        ("flyaway BRDF index past the table", |p| p.find(SectionKind::FlyawayNodes, 0)[12..16].copy_from_slice(&7u32.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::FlyawayNode { .. }))),
        ("META note past the end", |p| { let m = p.find(SectionKind::Meta, 0); let at = 48 + 4 * 4; m[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes()) }, |e| matches!(e, FormatError::Section { kind, .. } if kind == "META")),
        ("META 2^31 fit errors", |p| p.find(SectionKind::Meta, 0)[36..40].copy_from_slice(&(1u32 << 31).to_le_bytes()), |e| matches!(e, FormatError::Section { kind, .. } if kind == "META")),
        ("META NaN fit error", |p| p.find(SectionKind::Meta, 0)[48..52].copy_from_slice(&f32::NAN.to_le_bytes()), |e| matches!(e, FormatError::Invalid(ModelError::Meta(_)))),
        ("META note not UTF-8", |p| { let m = p.find(SectionKind::Meta, 0); let n = m.len(); m[n - 1] = 0xff }, |e| matches!(e, FormatError::Section { kind, .. } if kind == "META")),
    ];
    // The linked lists' damage needs wide nodes (1.7 writes the sample's compactly).
    run_catalogue(&wide_node_bytes(&sample()), cases);
    // The sample's level-1 flyaways: column (1, 1) = texel 1·6 + 1 = 7 holds nodes 0 → 1.
    let m = sample();
    let f = m.levels[1].flyaways.as_ref().unwrap();
    assert_eq!((f.heads[7], f.nodes[0].next, f.nodes[1].next), (0, 1, NO_NODE));
    assert!(matches!(m.levels[0].surface, Surface::Clustered { .. }));
}

/// Flips, overwrites, truncates and splices bytes at random. A read either fails with an
/// error or returns the original model (a flip in inter-section padding is harmless);
/// never a panic. With the CRCs recomputed, semantic damage must be caught too.
fn randomized_corruption(iterations: u64, seed: u64) -> (u64, u64) {
    // The sample (wide surfaces, compact flyaway nodes), the compact sample (every
    // compact record), the gain sample (spread records and axis groups, 1.8; path
    // gains, 1.9) and the gradient sample (1.12), in turn.
    let models = [sample(), compact_sample(), gain_sample(), gradient_sample()];
    let files = models.each_ref().map(|m| format::to_bytes(m).unwrap());
    let mut rng = fabric_runtime::brdf::twin::SplitMix64(seed);
    let (mut rejected, mut accepted) = (0, 0);
    for it in 0..iterations {
        let (good, model) = (&files[(it % models.len() as u64) as usize], &models[(it % models.len() as u64) as usize]);
        let kind = rng.next_u64() % 6;
        let b = match kind {
            k if k < format::mutate::KINDS => format::mutate::mutate(good, k, &mut rng),
            // Semantic damage behind valid checksums: edit a section, re-seal.
            _ => {
                let mut parts = Parts::of(good);
                let s = (rng.next_u64() % parts.sections.len() as u64) as usize;
                let data = &mut parts.sections[s].1;
                if !data.is_empty() {
                    for _ in 0..1 + rng.next_u64() % 3 {
                        let at = (rng.next_u64() % data.len() as u64) as usize;
                        data[at] = rng.next_u64() as u8;
                    }
                }
                parts.assemble()
            }
        };
        match format::read(&b) {
            Err(e) => {
                assert!(!e.to_string().is_empty());
                rejected += 1;
            }
            Ok(m) => {
                // Accepted: raw damage must have been harmless (inter-section padding);
                // a re-sealed edit may change the model but must leave it valid.
                if kind < 4 {
                    assert!(m == *model, "iteration {it}: damaged bytes read as a different model");
                }
                m.validate().unwrap_or_else(|e| panic!("iteration {it}: accepted an invalid model: {e}"));
                // What the reader accepts, the writer writes and the reader reads back.
                assert_eq!(format::read(&format::to_bytes(&m).unwrap()).unwrap(), m, "iteration {it}");
                accepted += 1;
            }
        }
    }
    (rejected, accepted)
}

#[test]
fn quick_randomized_corruption() {
    // 50 000 corrupt files in CI (a few seconds; the long run below goes further).
    let n = 50_000;
    let t = std::time::Instant::now();
    let (rejected, accepted) = randomized_corruption(n, 1);
    println!("{n} corrupted files in {:.1?}: {rejected} rejected, {accepted} accepted (harmless or still-valid edits)", t.elapsed());
    assert!(rejected > n * 2 / 3, "most corruptions must be caught: {rejected}");
}

/// The long run: `FABRIC_CORRUPTION_ITERS=1000000 cargo test -p fabric-runtime --test hybrid_format -- --ignored`.
#[test]
#[ignore]
fn long_randomized_corruption() {
    let iters = std::env::var("FABRIC_CORRUPTION_ITERS").ok().and_then(|v| v.parse().ok()).unwrap_or(200_000);
    let t = std::time::Instant::now();
    let (rejected, accepted) = randomized_corruption(iters, 0xc0ffee);
    println!("{iters} corrupted files in {:.1?}: {rejected} rejected, {accepted} accepted", t.elapsed());
}

#[test]
fn model_flag_bits_3_to_5_are_the_diffuse_and_flyaway_laws_and_the_flyaway_shadow_and_unknown_bits_are_rejected() {
    let mut parts = Parts::of(&sample_bytes());
    let flags = |p: &mut Parts| u32::from_le_bytes(p.find(SectionKind::Model, 0)[16..20].try_into().unwrap());
    let set = |p: &mut Parts, f: u32| p.find(SectionKind::Model, 0)[16..20].copy_from_slice(&f.to_le_bytes());
    let base = flags(&mut parts);
    assert_eq!(base & 8, 0, "the sample is Lambert's");
    set(&mut parts, base | 8);
    assert_eq!(format::read(&parts.assemble()).unwrap().meta.diffuse, fabric_runtime::brdf::DiffuseLaw::LommelSeeliger);
    assert_eq!(base & 16, 0, "the sample's flyaways face the viewer");
    assert_eq!(format::read(&parts.assemble()).unwrap().meta.fiber_lobes, fabric_runtime::brdf::FiberLobes::Facing);
    set(&mut parts, base | 16);
    assert_eq!(format::read(&parts.assemble()).unwrap().meta.fiber_lobes, fabric_runtime::brdf::FiberLobes::Cylinder);
    // And the writer sets it: a round trip keeps the law.
    let mut m = sample();
    m.meta.fiber_lobes = fabric_runtime::brdf::FiberLobes::Cylinder;
    assert_eq!(format::read(&format::to_bytes(&m).unwrap()).unwrap().meta.fiber_lobes, fabric_runtime::brdf::FiberLobes::Cylinder);
    // Bit 5 (1.13): the flyaways shadow the surface.
    assert_eq!(base & 32, 0, "the sample's flyaways do not shadow its surface");
    assert!(!format::read(&parts.assemble()).unwrap().meta.flyaway_shadow);
    set(&mut parts, base | 32);
    assert!(format::read(&parts.assemble()).unwrap().meta.flyaway_shadow);
    m.meta.flyaway_shadow = true;
    let back = format::read(&format::to_bytes(&m).unwrap()).unwrap();
    assert!(back.meta.flyaway_shadow && back.meta.fiber_lobes == fabric_runtime::brdf::FiberLobes::Cylinder);
    for bit in [64u32, 1 << 31] {
        set(&mut parts, base | bit);
        let err = format::read(&parts.assemble()).unwrap_err().to_string();
        assert!(err.contains("MODEL") && err.contains("unknown flags"), "{err}");
    }
}

#[test]
fn the_brdf_reading_is_read_and_written_and_an_unknown_one_is_rejected() {
    // MODEL offset 12: 0 = bounded, 1 = width, 2 = held (1.14).
    let mut parts = Parts::of(&sample_bytes());
    let set = |p: &mut Parts, r: u32| p.find(SectionKind::Model, 0)[12..16].copy_from_slice(&r.to_le_bytes());
    for (value, reading) in [(0u32, BrdfReading::Bounded), (1, BrdfReading::Width), (2, BrdfReading::Held)] {
        set(&mut parts, value);
        assert_eq!(format::read(&parts.assemble()).unwrap().meta.reading, reading);
        let mut m = sample();
        m.meta.reading = reading;
        assert_eq!(format::read(&format::to_bytes(&m).unwrap()).unwrap().meta.reading, reading, "round trip");
    }
    for value in [3u32, 255, u32::MAX] {
        set(&mut parts, value);
        let err = format::read(&parts.assemble()).unwrap_err().to_string();
        assert!(err.contains("MODEL") && err.contains(&format!("BRDF reading {value} is unknown")), "{err}");
    }
}

#[test]
fn fuzz_seeds_are_current() {
    // runtime/fuzz/seeds: valid files the fuzzers start from (runtime/fuzz/README.md).
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/seeds");
    let params = examples::silk_params();
    let tile = fabric_runtime::hybrid::Tile { origin: glam::Vec2::ZERO, size: glam::Vec2::ONE, top_z: 1.0, height_scale: 0.5, voxel_depth: 0.125 };
    let mut small = examples::uniform_model(4, 4, 3, tile, |x, y| 0.1 + 0.2 * x * y, &params, glam::Vec3::Z, glam::Vec3::X).unwrap();
    examples::add_flyaways(&mut small, 0, &[(1, 2, fabric_runtime::hybrid::FlyawayInput { depth: 1, alpha: 1.0, tangent: glam::Vec3::Y, param: 0 })], &params).unwrap();
    for (name, model) in [("sample.hyb", sample()), ("small.hyb", small), ("bsdf.hyb", bsdf_sample()), ("tilted.hyb", tilted_sample()), ("gradient.hyb", gradient_sample()), ("curvature.hyb", curvature_sample()), ("spread.hyb", spread_sample()), ("groups.hyb", group_sample()), ("gains.hyb", gain_sample()), ("compact.hyb", compact_sample()), ("diffuse_ls.hyb", {
        let mut m = sample();
        m.meta.diffuse = fabric_runtime::brdf::DiffuseLaw::LommelSeeliger;
        m
    }), ("cylinder.hyb", {
        let mut m = sample();
        m.meta.fiber_lobes = fabric_runtime::brdf::FiberLobes::Cylinder;
        m
    }), ("flyaway_shadow.hyb", {
        let mut m = sample();
        m.meta.flyaway_shadow = true;
        m
    }), ("held.hyb", {
        let mut m = sample();
        m.meta.reading = BrdfReading::Held;
        m
    })] {
        let bytes = format::to_bytes(&model).unwrap();
        let path = dir.join(name);
        if std::env::var_os("FABRIC_BLESS").is_some() {
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(&path, &bytes).unwrap();
        }
        let stored = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e} (write it with FABRIC_BLESS=1)", path.display()));
        assert!(stored == bytes, "{} is stale: regenerate with FABRIC_BLESS=1", path.display());
    }
}

#[test]
fn synthetic_benchmark_models_are_valid_and_round_trip() {
    let m = examples::synthetic_model(40, 3);
    m.validate().unwrap();
    assert!(m.has_flyaways() && m.levels.len() == 6);
    // Downsampled flyaways: alpha is a fraction of 8^ℓ children.
    let f3 = m.levels[3].flyaways.as_ref().unwrap();
    assert!(f3.nodes.iter().all(|n| n.alpha() > 0.0 && n.alpha() <= 1.0));
    assert_eq!(format::read(&format::to_bytes(&m).unwrap()).unwrap(), m);
}

#[test]
fn a_directory_is_named_as_not_a_model_file() {
    let dir = std::env::temp_dir();
    let e = fabric_runtime::hybrid::format::read_file(&dir).unwrap_err().to_string();
    assert!(e.contains("is a directory") && e.contains(".hyb"), "{e}");
}
