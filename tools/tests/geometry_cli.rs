//! `fabric geometry` end to end: files written, numbers reported, errors a user sees.

use std::f32::consts::TAU;
use std::path::{Path, PathBuf};
use std::process::Command;

use fabric_baker::geometry::Geometry;
use fabric_baker::volume::{Aabb, FabricVolume, MaterialParams, Voxel, save_fabric};
use glam::Vec3;

fn fabric() -> Command {
    Command::new(env!("CARGO_BIN_EXE_fabric"))
}

fn tmp(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("geometry-cli").join(name);
    std::fs::remove_dir_all(&d).ok();
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A 64×48×20 sinusoidal surface (periods 16 and 12 texels) with one flyaway strand of
/// diameter ~2 along x at z ≈ 17.
fn write_volume(dir: &Path, empty: bool) {
    let dims = [64, 48, 20];
    let mut v = FabricVolume::new(dims, Aabb::new(Vec3::ZERO, Vec3::new(0.64, 0.48, 0.2)), MaterialParams::default());
    if !empty {
        for z in 0..20 {
            for y in 0..48 {
                for x in 0..64 {
                    let h = 9.0 + 2.0 * (TAU * (x as f32 + 0.5) / 16.0).sin() + 1.5 * (TAU * (y as f32 + 0.5) / 12.0).sin();
                    let c = (h - z as f32).clamp(0.0, 1.0);
                    let strand = (y == 30 || y == 31) && (z == 16 || z == 17);
                    if c > 0.0 || strand {
                        v.set(x, y, z, Voxel::pack(if strand { 1.0 } else { c }, Vec3::splat(0.8), Vec3::X));
                    }
                }
            }
        }
    }
    save_fabric(&v, dir).unwrap();
}

#[test]
fn geometry_writes_maps_previews_and_the_report() {
    let root = tmp("ok");
    let vol = root.join("vol");
    let out = root.join("out");
    write_volume(&vol, false);
    let o = fabric().arg("geometry").arg(&vol).arg("--out").arg(&out).output().unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "stdout: {stdout}\nstderr: {}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains("filter size") && stdout.contains("flyaway voxels") && stdout.contains("stage times"), "{stdout}");
    for f in ["geometry.json", "h0.exr", "h.exr", "surface_top.exr", "normals.exr", "tangents.exr", "flyaways.bin", "h0.png", "normals.png", "autocorrelation.png"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("geometry.json")).unwrap()).unwrap();
    let fs: Vec<f64> = json["filter_size"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    assert!((fs[0] - 16.0).abs() < 1.0 && (fs[1] - 12.0).abs() < 1.0, "filter size {fs:?}");
    assert!(json["flyaway_voxels"].as_u64().unwrap() >= 128, "{}", json["flyaway_voxels"]);
    assert!(json["fiber_thickness"].as_f64().unwrap() > 0.0);
    let range = json["height_range"].as_array().unwrap();
    assert!(range[0].as_f64().unwrap() > 5.0 && range[1].as_f64().unwrap() < 13.0, "{range:?}");
    assert!(json["stage_times"].as_array().unwrap().iter().any(|s| s["stage"] == "load_volume"));
    // The data read back is the geometry the command described.
    let g = Geometry::read_dir(&out).unwrap();
    assert_eq!(g.dims, [64, 48]);
    assert_eq!(g.flyaways.len() as u64, json["flyaway_voxels"].as_u64().unwrap());
}

#[test]
fn geometry_errors_name_the_problem() {
    let root = tmp("errors");
    let empty = root.join("empty");
    write_volume(&empty, true);
    let good = root.join("good");
    write_volume(&good, false);
    let arg = |p: &Path| p.as_os_str().to_owned();
    let cases: [(Vec<std::ffi::OsString>, &str); 5] = [
        (vec![arg(&root.join("missing"))], "missing"),
        (vec![arg(&empty)], "empty"),
        (vec![arg(&good), "--filter-size=-3".into()], "non-negative"),
        (vec![arg(&good), "--tangent-depth".into(), "0".into()], "tangent_depth"),
        (vec![arg(&good), "--fiber-thickness".into(), "40".into()], "no fabric surface"),
    ];
    for (args, expect) in cases {
        let o = fabric().arg("geometry").args(&args).arg("--out").arg(root.join("out")).output().unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} should fail");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
        assert!(stderr.to_lowercase().contains(expect), "{args:?}: expected '{expect}' in: {stderr}");
    }
}
