//! `fabric reference` and `fabric diff` end to end.

use std::process::Command;

use fabric_baker::volume::{Aabb, FabricVolume, MaterialParams, Voxel, save_fabric};
use fabric_runtime::image::Image;
use glam::Vec3;

fn fabric() -> Command {
    Command::new(env!("CARGO_BIN_EXE_fabric"))
}

fn tmp(name: &str) -> std::path::PathBuf {
    let d = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("reference_cli");
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// A 12×12×4 slab of fibers along x, written as a fabric directory of its own per test
/// (tests run in parallel: one must not read while another rewrites it).
fn tiny_fabric(name: &str) -> std::path::PathBuf {
    let dir = tmp(&format!("tiny-{name}"));
    let mut v = FabricVolume::new([12, 12, 4], Aabb::new(Vec3::ZERO, Vec3::new(1.0, 1.0, 0.25)), MaterialParams { density_scale: 8.0, roughness: 0.3 });
    for z in 1..4 {
        for y in 0..12 {
            for x in 0..12 {
                if (x + y) % 3 != 0 {
                    v.set(x, y, z, Voxel::pack(1.0, Vec3::new(0.9, 0.7, 0.5), Vec3::X));
                }
            }
        }
    }
    save_fabric(&v, &dir).unwrap();
    dir
}

#[test]
fn reference_renders_deterministically_and_diff_measures_it() {
    let dir = tiny_fabric("deterministic");
    let run = |out: &std::path::Path, threads: &str, seed: &str| {
        let o = fabric()
            .args(["reference"])
            .arg(&dir)
            .args(["--view-angles", "30,20", "--light-angles", "40,-60", "--size", "24x24", "--spp", "8", "--json", "--threads", threads, "--seed", seed, "--out"])
            .arg(out)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(report["paths"], 24 * 24 * 8);
        assert!(report["paths_per_second"].as_f64().unwrap() > 0.0);
        Image::read(out, 1.0).unwrap()
    };
    let (a, b, c) = (tmp("a.exr"), tmp("b.exr"), tmp("c.exr"));
    let (ia, ib, ic) = (run(&a, "1", "7"), run(&b, "2", "7"), run(&c, "2", "8"));
    assert_eq!(ia, ib, "same seed, different thread counts");
    assert_ne!(ia, ic);
    assert!(ia.mean() > 0.0);
    let o = fabric().arg("diff").arg(&a).arg(&c).args(["--json", "--diff-image"]).arg(tmp("d.png")).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    // The command's figure is the library's metric of the two images (8 spp apart: noise).
    let rel = r["relative_rmse"].as_f64().unwrap();
    let want = fabric_runtime::metrics::relative_rmse(&ia, &ic).unwrap();
    assert!((rel - want).abs() <= 1e-6 * want.max(1e-6), "diff says {rel}, the metric {want}: {r}");
    assert!(r["flip_mean"].as_f64().unwrap() > 0.0);
    let d = Image::read(&tmp("d.png"), 1.0).unwrap();
    assert!(d.width == 24 && d.height == 24 && d.mean() > 0.0, "the difference image: {}x{}, mean {}", d.width, d.height, d.mean());
    let o = fabric().arg("diff").arg(&a).arg(&b).arg("--json").output().unwrap();
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(r["relative_rmse"].as_f64().unwrap(), 0.0);
}

#[test]
fn bad_input_is_a_clear_error() {
    let dir = tiny_fabric("bad");
    for (args, needle) in [
        (vec!["reference", "/nonexistent/fabric", "--out", "/tmp/x.exr"], "/nonexistent/fabric"),
        (vec!["reference", dir.to_str().unwrap(), "--spp", "0", "--out", "/tmp/x.exr"], "samples per pixel"),
        (vec!["reference", dir.to_str().unwrap(), "--max-depth", "0", "--out", "/tmp/x.exr"], "max depth"),
        (vec!["diff", "/nonexistent/a.exr", "/nonexistent/b.exr"], "/nonexistent/a.exr"),
    ] {
        let o = fabric().args(&args).output().unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(stderr.contains(needle) && !stderr.contains("panicked"), "{args:?}: {stderr}");
    }
}

#[test]
fn reference_lights_with_an_environment_map() {
    let dir = tiny_fabric("env");
    // The built-in sky, and the same sky written to an EXR and read back: one image.
    let sky = fabric_runtime::scene::Sky::default().to_image();
    let sky_exr = tmp("sky.exr");
    sky.write(&sky_exr, 1.0).unwrap();
    let run = |map: &str, extra: &[&str], out: &std::path::Path| {
        let o = fabric().arg("reference").arg(&dir).args(["--view-angles", "30,20", "--size", "16x16", "--spp", "4", "--envmap", map]).args(extra).arg("--out").arg(out).output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        (String::from_utf8_lossy(&o.stdout).to_string(), Image::read(out, 1.0).unwrap())
    };
    let (text, a) = run("sky", &[], &tmp("env_a.exr"));
    assert!(text.contains("environment built-in sky (512x256"), "{text}");
    let (_, b) = run(sky_exr.to_str().unwrap(), &[], &tmp("env_b.exr"));
    assert_eq!(a, b, "the built-in sky and its EXR give the same image");
    assert!(a.mean() > 0.0 && a.first_non_finite().is_none());
    // Scale is linear; rotation changes the image; a delta light adds to the map.
    let (_, c) = run("sky", &["--envmap-scale", "2"], &tmp("env_c.exr"));
    assert!((c.mean() / a.mean() - 2.0).abs() < 1e-4, "{} vs {}", c.mean(), a.mean());
    let (_, d) = run("sky", &["--envmap-rotate", "90"], &tmp("env_d.exr"));
    assert_ne!(a, d);
    let (text, e) = run("sky", &["--light-angles", "30,0"], &tmp("env_e.exr"));
    assert!(text.contains("plus the delta light") && e.mean() > a.mean(), "{text}");
    // Bad maps and flags are refused with what and where.
    let bad = tmp("bad.exr");
    Image::from_fn(8, 4, |x, _| if x == 5 { Vec3::new(-1.0, 0.0, 0.0) } else { Vec3::ONE }).write(&bad, 1.0).unwrap();
    for (extra, needle) in [
        (vec!["--envmap", bad.to_str().unwrap()], "texel (5, 0)"),
        (vec!["--envmap", "/nonexistent/map.exr"], "/nonexistent/map.exr"),
        (vec!["--envmap", "sky", "--envmap-scale", "-1"], "--envmap-scale"),
        (vec!["--envmap-rotate", "10"], "need --envmap"),
    ] {
        let o = fabric().arg("reference").arg(&dir).args(["--size", "8x8", "--spp", "1"]).args(&extra).arg("--out").arg(tmp("never.exr")).output().unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && stderr.contains(needle), "{extra:?}: {stderr}");
    }
}
