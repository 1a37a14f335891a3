//! Fuzzing the volume readers: `.vol` files in each encoding and whole fabric
//! directories, damaged thousands of ways (bytes overwritten, header fields set to
//! extremes, truncated, spliced) and read again. A reader may refuse a file with an
//! error that names it; it may not panic, abort on an allocation a header asked for,
//! or return values outside what the renderers and the baker assume (finite, the
//! grid's own size, densities in [0, MAX_DENSITY], albedo in [0, 1], unit directions).
//! The damage is `format::mutate`'s (the `.hyb` tests') plus extreme header words.
//! Deterministic (fixed seeds), a few seconds in all; `volume_io.rs` has the named cases.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use fabric_baker::volume::*;
use fabric_runtime::brdf::twin::SplitMix64;
use fabric_runtime::hybrid::format::mutate::damage;
use glam::Vec3;

fn tmp(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("volume_fuzz").join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The `.vol` header's bytes, where [`damage`] puts its extreme words.
const VOL_HEADER: usize = 48;

fn no_panic<T>(what: &str, case: usize, path: &Path, read: impl FnOnce() -> T) -> T {
    catch_unwind(AssertUnwindSafe(read)).unwrap_or_else(|_| panic!("{what}: case {case} panicked reading {}", path.display()))
}

#[test]
fn damaged_vol_files_are_refused_or_read_sound() {
    let d = tmp("vol");
    let mut r = SplitMix64(0x5851_F42D_4C95_7F2D);
    let dims = [6, 5, 4];
    let n = dims.iter().product::<usize>();
    let bbox = Aabb::new(Vec3::new(-1.0, 0.0, 0.5), Vec3::new(2.0, 2.5, 1.0));
    let scalars: Vec<f32> = (0..n).map(|_| r.next_f32()).collect();
    let colours: Vec<f32> = (0..3 * n).map(|_| r.next_f32()).collect();
    let dirs: Vec<f32> = (0..n).flat_map(|_| Vec3::new(r.next_f32() - 0.5, r.next_f32() - 0.5, r.next_f32() - 0.5).normalize_or(Vec3::Z).to_array()).collect();
    for (enc, channels, data) in [
        (Encoding::Float32, 1, &scalars),
        (Encoding::Float16, 3, &colours),
        (Encoding::UInt8, 1, &scalars),
        (Encoding::QuantizedDirections, 3, &dirs),
    ] {
        let path = d.join(format!("{}.vol", enc.id()));
        write_vol(&path, &VolGrid { dims, channels, bbox, data: data.clone() }, enc).unwrap();
        let good = std::fs::read(&path).unwrap();
        let (mut ok, mut refused) = (0, 0);
        for case in 1..=1000 {
            std::fs::write(&path, damage(&good, VOL_HEADER, &mut r)).unwrap();
            match no_panic("vol", case, &path, || read_vol(&path)) {
                Ok(g) => {
                    let cells: usize = g.dims.iter().product();
                    assert!(cells > 0 && g.data.len() == cells * g.channels, "{enc:?} case {case}: {:?} × {}", g.dims, g.channels);
                    assert!(g.bbox.min.is_finite() && g.bbox.max.is_finite() && g.bbox.max.cmpgt(g.bbox.min).all(), "{enc:?} case {case}: {:?}", g.bbox);
                    ok += 1;
                }
                Err(e) => {
                    assert!(e.to_string().contains(path.file_name().unwrap().to_str().unwrap()), "{enc:?} case {case}: the error names the file: {e}");
                    refused += 1;
                }
            }
        }
        assert!(ok > 50 && refused > 50, "{enc:?}: {ok} read, {refused} refused");
    }
}

#[test]
fn damaged_fabric_directories_are_refused_or_load_sound() {
    let d = tmp("fabric");
    let mut r = SplitMix64(0x2F69_3A5E_12B7_C0D1);
    let dims = [5, 4, 3];
    let n = dims.iter().product::<usize>();
    let bbox = Aabb::new(Vec3::ZERO, Vec3::new(1.0, 0.8, 0.3));
    let density: Vec<f32> = (0..n).map(|i| if i % 3 == 0 { 0.0 } else { r.next_f32() }).collect();
    let albedo: Vec<f32> = (0..3 * n).map(|_| r.next_f32()).collect();
    let orientation: Vec<f32> = (0..n).flat_map(|_| Vec3::new(r.next_f32() - 0.5, r.next_f32() - 0.5, r.next_f32()).normalize_or(Vec3::Z).to_array()).collect();
    let files = [(DENSITY_FILE, 1, &density), (ALBEDO_FILE, 3, &albedo), (ORIENTATION_FILE, 3, &orientation)];
    let mut good = Vec::new();
    for (name, channels, data) in files {
        let enc = if r.next_u64() % 2 == 0 { Encoding::Float32 } else { Encoding::Float16 };
        write_vol(&d.join(name), &VolGrid { dims, channels, bbox, data: data.clone() }, enc).unwrap();
        good.push(std::fs::read(d.join(name)).unwrap());
    }
    std::fs::write(d.join(MATERIAL_FILE), "density_scale = 50.0\nroughness = 0.3\n").unwrap();
    load_fabric(&d, &MaterialOverrides::default()).unwrap();
    let (mut ok, mut refused) = (0, 0);
    for case in 1..=1200 {
        let k = (r.next_u64() % 3) as usize;
        let path = d.join(files[k].0);
        std::fs::write(&path, damage(&good[k], VOL_HEADER, &mut r)).unwrap();
        match no_panic("fabric", case, &path, || load_fabric(&d, &MaterialOverrides::default())) {
            Ok(v) => {
                let [x, y, z] = v.dims();
                assert!(x * y * z == v.voxels().len() && !v.voxels().is_empty(), "case {case}");
                for vox in v.voxels() {
                    let (rho, a, o) = (vox.density(), vox.albedo(), vox.orientation());
                    assert!(rho.is_finite() && (0.0..=MAX_DENSITY).contains(&rho), "case {case}: density {rho}");
                    assert!(a.is_finite() && a.min_element() >= 0.0 && a.max_element() <= 1.0, "case {case}: albedo {a}");
                    assert!(o.is_finite() && (o.length() - 1.0).abs() < 1e-3, "case {case}: direction {o}");
                }
                ok += 1;
            }
            Err(e) => {
                assert!(e.to_string().contains(files[k].0), "case {case}: the error names the file: {e}");
                refused += 1;
            }
        }
        std::fs::write(&path, &good[k]).unwrap();
    }
    assert!(ok > 50 && refused > 50, "{ok} loaded, {refused} refused");
}
