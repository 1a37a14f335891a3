//! `.vol` files and fabric directories: round trips of every encoding we write, a
//! volume laid out byte by byte as Mitsuba lays it out (independently of our writer),
//! and a catalogue of malformed inputs, each with the error it must produce.

use std::path::{Path, PathBuf};

use fabric_baker::volume::*;
use glam::Vec3;

fn tmp(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("volume_io").join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A `.vol` file laid out by hand from Mitsuba's documentation (not our writer).
fn mitsuba_bytes(encoding: i32, dims: [i32; 3], channels: i32, bbox: [f32; 6], data: &[u8]) -> Vec<u8> {
    let mut b = b"VOL".to_vec();
    b.push(3);
    b.extend(encoding.to_le_bytes());
    for d in dims {
        b.extend(d.to_le_bytes());
    }
    b.extend(channels.to_le_bytes());
    for v in bbox {
        b.extend(v.to_le_bytes());
    }
    b.extend_from_slice(data);
    b
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

const BOX: [f32; 6] = [0.0, 0.0, 0.0, 1.0, 2.0, 0.5];

/// Small deterministic pseudo-random numbers for test data.
fn rng(seed: u64) -> impl FnMut() -> f32 {
    let mut s = seed;
    move || {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (s >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn random_unit(r: &mut impl FnMut() -> f32) -> Vec3 {
    loop {
        let v = Vec3::new(r() * 2.0 - 1.0, r() * 2.0 - 1.0, r() * 2.0 - 1.0);
        if v.length() > 0.1 && v.length() < 1.0 {
            return v.normalize();
        }
    }
}

#[test]
fn every_encoding_round_trips_within_its_documented_error() {
    let d = tmp("encodings");
    let dims = [5, 4, 3];
    let n = 60;
    let mut r = rng(7);
    let scalars: Vec<f32> = (0..n * 3).map(|_| r()).collect();
    let dirs: Vec<f32> = (0..n).flat_map(|_| random_unit(&mut r).to_array()).collect();
    let bbox = Aabb::new(Vec3::new(-1.0, 0.0, 2.0), Vec3::new(1.0, 3.0, 2.5));
    for (enc, data, channels, bound) in [
        (Encoding::Float32, &scalars, 3, 0.0),
        (Encoding::Float16, &scalars, 3, 2f32.powi(-11)), // half: ≤ 2⁻¹¹ relative, values < 1
        (Encoding::UInt8, &scalars, 3, 0.5 / 255.0 + 1e-7), // rounding to the nearest 1/255
        (Encoding::Float32, &dirs, 3, 0.0),
    ] {
        let grid = VolGrid { dims, channels, bbox, data: data.clone() };
        let path = d.join(format!("{}.vol", enc.id()));
        write_vol(&path, &grid, enc).unwrap();
        assert_eq!(std::fs::metadata(&path).unwrap().len(), 48 + (n * enc.voxel_bytes(channels)) as u64);
        let back = read_vol(&path).unwrap();
        assert_eq!((back.dims, back.channels, back.bbox), (dims, channels, bbox));
        let worst = back.data.iter().zip(data.iter()).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        assert!(worst <= bound, "{enc:?}: worst error {worst} > {bound}");
    }
    // Quantized directions: θ steps π/255 and φ steps 2π/255, so the nearest entry is at
    // most √((π/510)² + (π/255)²) ≈ 0.79° away.
    let grid = VolGrid { dims, channels: 3, bbox, data: dirs.clone() };
    let path = d.join("4.vol");
    write_vol(&path, &grid, Encoding::QuantizedDirections).unwrap();
    assert_eq!(std::fs::metadata(&path).unwrap().len(), 48 + 2 * n as u64);
    let back = read_vol(&path).unwrap();
    let mut worst = 0.0f32;
    for (a, b) in back.data.chunks(3).zip(dirs.chunks(3)) {
        let (a, b) = (Vec3::from_slice(a), Vec3::from_slice(b));
        assert!((a.length() - 1.0).abs() < 1e-5);
        worst = worst.max(a.dot(b).clamp(-1.0, 1.0).acos().to_degrees());
    }
    assert!(worst <= 0.79, "quantized directions: worst {worst}°");
    // The poles are exact; byte 255 is θ = π (and φ = 0), as in Mitsuba's tables.
    for (w, bytes) in [(Vec3::Z, [0u8, 0u8]), (-Vec3::Z, [255, 0])] {
        assert_eq!(vol::quantize_direction(w), bytes);
        let mut out = [0.0; 3];
        vol::decode(Encoding::QuantizedDirections, 3, &bytes, &mut out);
        assert!(Vec3::from(out).abs_diff_eq(w, 1e-6), "{w} -> {bytes:?} -> {out:?}");
    }
    let mut out = [0.0; 3];
    vol::decode(Encoding::QuantizedDirections, 3, &[255, 255], &mut out);
    assert_eq!(out, [0.0, 0.0, -1.0]);
}

#[test]
fn writers_refuse_values_their_encoding_cannot_hold() {
    let d = tmp("unencodable");
    let bbox = Aabb::new(Vec3::ZERO, Vec3::ONE);
    let cases: [(Encoding, usize, Vec<f32>, &str); 5] = [
        (Encoding::Float32, 1, vec![0.0, f32::NAN], "not finite"),
        (Encoding::Float16, 1, vec![1e6, 0.0], "float16"),
        (Encoding::UInt8, 1, vec![0.5, 1.5], "[0, 1]"),
        (Encoding::QuantizedDirections, 3, vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0], "unit vectors"),
        (Encoding::Float32, 1, vec![0.0], "needs 2"),
    ];
    for (enc, channels, data, msg) in cases {
        let path = d.join("x.vol");
        let grid = VolGrid { dims: [2, 1, 1], channels, bbox, data };
        let e = write_vol(&path, &grid, enc).unwrap_err().to_string();
        assert!(e.contains("x.vol") && e.contains(msg), "{enc:?}: {e}");
    }
}

#[test]
fn reads_a_volume_laid_out_as_mitsuba_writes_it() {
    // 3×2×2 grid, x fastest then y then z, channels interleaved: value = x + 10y + 100z.
    let d = tmp("mitsuba");
    let (nx, ny, nz) = (3usize, 2usize, 2usize);
    let mut density = Vec::new();
    let mut albedo = Vec::new();
    let mut orient = Vec::new();
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                density.push((x + 10 * y + 100 * z) as f32 / 200.0);
                albedo.extend([x as f32 / 4.0, y as f32 / 4.0, z as f32 / 4.0]);
                // Sign is irrelevant: write some fibers as −ω.
                let w = Vec3::new(x as f32, 1.0, z as f32 - 1.0).normalize() * if (x + y) % 2 == 0 { 1.0 } else { -1.0 };
                orient.extend(w.to_array());
            }
        }
    }
    std::fs::write(d.join("density.vol"), mitsuba_bytes(1, [3, 2, 2], 1, BOX, &f32_bytes(&density))).unwrap();
    std::fs::write(d.join("albedo.vol"), mitsuba_bytes(1, [3, 2, 2], 3, BOX, &f32_bytes(&albedo))).unwrap();
    std::fs::write(d.join("orientation.vol"), mitsuba_bytes(1, [3, 2, 2], 3, BOX, &f32_bytes(&orient))).unwrap();

    let g = read_vol(&d.join("density.vol")).unwrap();
    assert_eq!(g.dims, [3, 2, 2]);
    assert_eq!(g.bbox, Aabb::new(Vec3::ZERO, Vec3::new(1.0, 2.0, 0.5)));
    assert_eq!(g.get(2, 1, 1, 0), 112.0 / 200.0);
    assert_eq!(read_vol(&d.join("albedo.vol")).unwrap().get(1, 0, 1, 2), 0.25);

    let vol = load_fabric(&d, &MaterialOverrides::default()).unwrap();
    assert_eq!(vol.material, MaterialParams::default()); // no material.toml
    // ... which the tools say: the defaults taken, unless the flags gave both values.
    let note = material_defaults_note(&d, &MaterialOverrides::default()).expect("a note for the missing file");
    assert!(note.contains("material.toml") && note.contains("density_scale = 1") && note.contains("roughness = 0.1"), "{note}");
    let note = material_defaults_note(&d, &MaterialOverrides { density_scale: Some(40.0), roughness: None }).unwrap();
    assert!(!note.contains("density_scale") && note.contains("roughness"), "{note}");
    assert_eq!(material_defaults_note(&d, &MaterialOverrides { density_scale: Some(40.0), roughness: Some(0.2) }), None);
    assert_eq!(vol.dims(), [3, 2, 2]);
    // Cell-centred (Mitsuba 3): cell (0,0,0) spans [0, 1/3]×[0, 1]×[0, 0.25].
    assert!(vol.cell_center(0, 0, 0).abs_diff_eq(Vec3::new(1.0 / 6.0, 0.5, 0.125), 1e-6));
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let v = vol.voxel(x, y, z);
                let i = x + nx * (y + ny * z);
                assert!((v.density() - density[i]).abs() <= density[i] * 2f32.powi(-11));
                assert!(v.albedo().abs_diff_eq(Vec3::from_slice(&albedo[3 * i..]), 1e-5));
                let w = Vec3::from_slice(&orient[3 * i..]);
                if density[i] > 0.0 {
                    assert!(v.orientation().dot(w).abs() > 1.0 - 1e-6, "({x},{y},{z})");
                }
            }
        }
    }

    // material.toml and flag overrides.
    std::fs::write(d.join("material.toml"), "density_scale = 150.0\nroughness = 0.3\n").unwrap();
    let m = load_fabric(&d, &MaterialOverrides::default()).unwrap().material;
    assert_eq!((m.density_scale, m.roughness), (150.0, 0.3));
    assert_eq!(material_defaults_note(&d, &MaterialOverrides::default()), None);
    let m = load_fabric(&d, &MaterialOverrides { density_scale: Some(40.0), roughness: None }).unwrap().material;
    assert_eq!((m.density_scale, m.roughness), (40.0, 0.3));

    // Mitsuba 0.5's compact encodings, laid out by hand: uint8 density, quantized directions.
    let bytes: Vec<u8> = (0..12u8).map(|i| i * 20).collect();
    std::fs::write(d.join("density.vol"), mitsuba_bytes(3, [3, 2, 2], 1, BOX, &bytes)).unwrap();
    let dirs: Vec<u8> = (0..12).flat_map(|_| [0u8, 0u8]).collect(); // θ = 0: +Z
    std::fs::write(d.join("orientation.vol"), mitsuba_bytes(4, [3, 2, 2], 3, BOX, &dirs)).unwrap();
    let vol = load_fabric(&d, &MaterialOverrides::default()).unwrap();
    assert!((vol.voxel(2, 1, 1).density() - 220.0 / 255.0).abs() < 1e-3);
    assert!(vol.voxel(1, 1, 0).orientation().abs_diff_eq(Vec3::Z, 1e-4));
}

fn write_fabric(d: &Path, density: &[u8], albedo: &[u8], orientation: &[u8]) {
    std::fs::write(d.join("density.vol"), density).unwrap();
    std::fs::write(d.join("albedo.vol"), albedo).unwrap();
    std::fs::write(d.join("orientation.vol"), orientation).unwrap();
}

/// A valid 2×2×1 fabric's files, as (density, albedo, orientation) values.
fn good_values() -> (Vec<f32>, Vec<f32>, Vec<f32>) {
    (vec![0.5, 0.0, 1.0, 0.25], vec![0.5; 12], [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0, 0.0].to_vec())
}

#[test]
fn malformed_files_get_errors_that_name_the_file_and_the_problem() {
    let d = tmp("malformed");
    let path = d.join("bad.vol");
    let good = mitsuba_bytes(1, [2, 2, 1], 1, BOX, &f32_bytes(&[0.5, 0.0, 1.0, 0.25]));
    let mut cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("empty file", vec![], "truncated"),
        ("wrong magic", { let mut b = good.clone(); b[..3].copy_from_slice(b"VOX"); b }, "not a Mitsuba grid volume"),
        ("a PNG", b"\x89PNG\r\n\x1a\n".to_vec(), "not a Mitsuba grid volume"),
        ("version 2", { let mut b = good.clone(); b[3] = 2; b }, "version 2"),
        ("unknown encoding", { let mut b = good.clone(); b[4] = 7; b }, "unknown .vol encoding 7"),
        ("truncated header", good[..20].to_vec(), "48-byte"),
        ("truncated data", good[..good.len() - 1].to_vec(), "truncated: 63 bytes"),
        ("oversized data", { let mut b = good.clone(); b.extend([0; 8]); b }, "8 unexplained trailing bytes"),
        ("zero dimension", mitsuba_bytes(1, [2, 0, 1], 1, BOX, &[]), "at least one cell"),
        ("negative dimension", mitsuba_bytes(1, [2, -4, 1], 1, BOX, &[]), "at least one cell"),
        ("absurd dimensions", mitsuba_bytes(1, [65536, 65536, 65536], 1, BOX, &[0; 16]), "exceed the limit"),
        ("one huge axis", mitsuba_bytes(1, [1 << 20, 1, 1], 1, BOX, &[0; 16]), "exceeds 65536"),
        ("zero channels", mitsuba_bytes(1, [2, 2, 1], 0, BOX, &[]), "cannot hold 0 channels"),
        ("1-channel quantized directions", mitsuba_bytes(4, [2, 2, 1], 1, BOX, &[0; 8]), "cannot hold 1 channels"),
        ("NaN in the bounding box", mitsuba_bytes(1, [2, 2, 1], 1, [0.0, f32::NAN, 0.0, 1.0, 1.0, 1.0], &[0; 16]), "bounding box"),
        ("inverted bounding box", mitsuba_bytes(1, [2, 2, 1], 1, [0.0, 0.0, 1.0, 1.0, 1.0, 0.0], &[0; 16]), "bounding box"),
    ];
    cases.push(("float16 truncated", mitsuba_bytes(2, [2, 2, 1], 1, BOX, &[0; 7]), "truncated"));
    for (name, bytes, expected) in cases {
        std::fs::write(&path, &bytes).unwrap();
        let e = read_vol(&path).expect_err(name).to_string();
        assert!(e.contains("bad.vol") && e.contains(expected), "{name}: got \"{e}\", expected \"{expected}\"");
    }
    let e = read_vol(&d.join("nowhere.vol")).unwrap_err().to_string();
    assert!(e.contains("nowhere.vol"), "{e}");
}

#[test]
fn malformed_fabrics_get_errors_that_name_the_file_and_the_voxel() {
    let d = tmp("malformed_fabric");
    let (rho, alb, ori) = good_values();
    let vol = |c: i32, v: &[f32]| mitsuba_bytes(1, [2, 2, 1], c, BOX, &f32_bytes(v));
    write_fabric(&d, &vol(1, &rho), &vol(3, &alb), &vol(3, &ori));
    load_fabric(&d, &MaterialOverrides::default()).expect("the good fabric loads");

    let with = |i: usize, x: f32, v: &[f32]| {
        let mut v = v.to_vec();
        v[i] = x;
        v
    };
    // (case, density, albedo, orientation, file named, message)
    type Case = (&'static str, Vec<u8>, Vec<u8>, Vec<u8>, &'static str, &'static str);
    let cases: Vec<Case> = vec![
        ("NaN density", vol(1, &with(3, f32::NAN, &rho)), vol(3, &alb), vol(3, &ori), "density.vol", "voxel (1, 1, 0) density is NaN: not finite"),
        ("Inf density", vol(1, &with(2, f32::INFINITY, &rho)), vol(3, &alb), vol(3, &ori), "density.vol", "not finite"),
        ("negative density", vol(1, &with(0, -0.1, &rho)), vol(3, &alb), vol(3, &ori), "density.vol", "voxel (0, 0, 0) density is -0.1: negative (1 bad"),
        ("huge density", vol(1, &with(0, 1e6, &rho)), vol(3, &alb), vol(3, &ori), "density.vol", "65504"),
        ("albedo above 1", vol(1, &rho), vol(3, &with(4, 1.5, &alb)), vol(3, &ori), "albedo.vol", "voxel (1, 0, 0) albedo"),
        ("NaN albedo", vol(1, &rho), vol(3, &with(0, f32::NAN, &alb)), vol(3, &ori), "albedo.vol", "outside [0, 1]"),
        ("zero orientation where filled", vol(1, &rho), vol(3, &alb), vol(3, &with(2, 0.0, &ori)), "orientation.vol", "zero where density > 0"),
        ("short orientation", vol(1, &rho), vol(3, &alb), vol(3, &with(6, 0.5, &ori)), "orientation.vol", "not a unit vector"),
        ("NaN orientation", vol(1, &rho), vol(3, &alb), vol(3, &with(10, f32::NAN, &ori)), "orientation.vol", "not finite"),
        ("albedo with 1 channel", vol(1, &rho), vol(1, &rho), vol(3, &ori), "albedo.vol", "albedo grid has 1 channel(s); it needs 3"),
        ("grids of different sizes", vol(1, &rho), mitsuba_bytes(1, [4, 1, 1], 3, BOX, &f32_bytes(&alb)), vol(3, &ori), "albedo.vol", "resolution 4x1x1 differs from"),
        ("grids with different boxes", vol(1, &rho), vol(3, &alb), mitsuba_bytes(1, [2, 2, 1], 3, [0.0, 0.0, 0.0, 1.0, 2.0, 0.6], &f32_bytes(&ori)), "orientation.vol", "bounding box"),
        ("truncated albedo", vol(1, &rho), vol(3, &alb)[..60].to_vec(), vol(3, &ori), "albedo.vol", "truncated"),
    ];
    for (name, a, b, c, file, msg) in cases {
        write_fabric(&d, &a, &b, &c);
        let e = load_fabric(&d, &MaterialOverrides::default()).expect_err(name).to_string();
        assert!(e.contains(file) && e.contains(msg), "{name}: got \"{e}\", expected {file}: \"{msg}\"");
    }
    // The orientation of an empty voxel (ρ = 0 at index 1) is not used: zero is fine.
    assert_eq!(rho[1], 0.0, "voxel 1 is the empty one");
    write_fabric(&d, &vol(1, &rho), &vol(3, &alb), &vol(3, &with(4, 0.0, &ori)));
    let v = load_fabric(&d, &MaterialOverrides::default()).expect("a zero orientation in an empty voxel loads");
    assert!(v.voxel(1, 0, 0).is_empty() && !v.voxel(0, 0, 0).is_empty(), "densities as written");

    std::fs::remove_file(d.join("albedo.vol")).unwrap();
    let e = load_fabric(&d, &MaterialOverrides::default()).unwrap_err().to_string();
    assert!(e.contains("albedo.vol") && e.contains("missing"), "{e}");
    write_fabric(&d, &vol(1, &rho), &vol(3, &alb), &vol(3, &ori));
    std::fs::write(d.join("material.toml"), "roughness = -2\n").unwrap();
    let e = load_fabric(&d, &MaterialOverrides::default()).unwrap_err().to_string();
    assert!(e.contains("material.toml") && e.contains("roughness = -2"), "{e}");
    let v = load_fabric(&d, &MaterialOverrides { roughness: Some(0.2), ..Default::default() }).expect("the flag overrides the bad key");
    assert_eq!(v.material.roughness, 0.2);
    let e = load_fabric(&d.join("density.vol"), &MaterialOverrides::default()).unwrap_err().to_string();
    assert!(e.contains("not a fabric directory"), "{e}");
}

#[test]
fn fabric_directories_round_trip_in_both_encodings() {
    let dims = [7, 5, 4];
    let bbox = Aabb::new(Vec3::ZERO, Vec3::new(0.07, 0.05, 0.04));
    let mut vol = FabricVolume::new(dims, bbox, MaterialParams { density_scale: 123.0, roughness: 0.17 });
    let mut r = rng(3);
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                if r() < 0.6 {
                    let a = Vec3::new(r(), r(), r());
                    vol.set(x, y, z, Voxel::pack(r(), a, random_unit(&mut r)));
                }
            }
        }
    }
    for (enc, rho_err, alb_err, deg) in [
        (SaveEncoding::Float32, 0.0, 0.0, 0.05), // lossless but the octahedral re-encode (≤ 0.05°, grid.rs)
        (SaveEncoding::Compact, 0.5 / 255.0 + 1e-6, 0.5 / 255.0 + 1e-6, 0.85), // uint8; 0.79° + octahedral
    ] {
        let d = tmp(&format!("roundtrip_{enc:?}"));
        let opts = SaveOptions { encoding: enc, generator: Some(toml::toml! { preset = "test" }) };
        save_fabric_with(&vol, &d, &opts, &indicatif::ProgressBar::hidden()).unwrap();
        let back = load_fabric(&d, &MaterialOverrides::default()).unwrap();
        assert_eq!((back.dims(), back.bbox(), back.material), (dims, bbox, vol.material));
        let file = MaterialFile::read_or_default(&d.join(MATERIAL_FILE)).unwrap();
        assert_eq!(file.generator.unwrap()["preset"].as_str(), Some("test"));
        for (a, b) in vol.voxels().iter().zip(back.voxels()) {
            assert!((a.density() - b.density()).abs() <= rho_err, "{enc:?}");
            assert!((a.albedo() - b.albedo()).abs().max_element() <= alb_err, "{enc:?}");
            if !a.is_empty() {
                let angle = a.orientation().dot(b.orientation()).abs().min(1.0).acos().to_degrees();
                assert!(angle <= deg, "{enc:?}: {angle}°");
            }
        }
        if enc == SaveEncoding::Float32 {
            assert_eq!(vol.voxels().iter().map(|v| v.density).collect::<Vec<_>>(), back.voxels().iter().map(|v| v.density).collect::<Vec<_>>());
        }
    }
}
