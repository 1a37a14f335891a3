//! `fabric gen` and `fabric inspect` end to end: files written, what inspect reports,
//! and the errors a user sees for bad input.

use std::path::PathBuf;
use std::process::{Command, Output};

fn fabric() -> Command {
    Command::new(env!("CARGO_BIN_EXE_fabric"))
}

fn dir(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("gen_inspect").join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(d.parent().unwrap()).unwrap();
    d
}

fn text(o: &Output) -> String {
    format!("stdout: {}\nstderr: {}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

#[test]
fn gen_writes_a_fabric_that_inspect_reads() {
    let out = dir("felt");
    let o = fabric().args(["gen", "--preset", "felt", "--size", "64x48x16", "--seed", "5", "--roughness", "0.4", "--out"]).arg(&out).output().unwrap();
    assert!(o.status.success(), "{}", text(&o));
    for f in ["density.vol", "albedo.vol", "orientation.vol", "material.toml", "preview_albedo.png", "preview_height.png", "preview_orientation.png"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let material = std::fs::read_to_string(out.join("material.toml")).unwrap();
    assert!(material.contains("roughness = 0.4") && material.contains("preset = \"felt\"") && material.contains("seed = 5"), "{material}");
    let preview = fabric_runtime::image::Image::read(&out.join("preview_albedo.png"), 1.0).unwrap();
    assert_eq!((preview.width, preview.height), (64, 48));
    assert!(preview.mean() > 0.05, "the felt should show in the preview");

    let o = fabric().args(["inspect", "--json"]).arg(&out).output().unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["dims"], serde_json::json!([64, 48, 16]));
    assert!((v["roughness"].as_f64().unwrap() - 0.4).abs() < 1e-6);
    let filled = v["filled_fraction"].as_f64().unwrap();
    assert!(filled > 0.1 && filled < 0.8, "{filled}");
    assert!(v["density"]["max"].as_f64().unwrap() <= 1.0);
    assert!(v["surface"]["flyaway_voxels"].as_u64().unwrap() > 0, "felt is hairy");
    assert_eq!(v["fiber_voxels"]["source"], "material.toml [generator]");

    // Overrides apply wherever a volume is read.
    let o = fabric().args(["inspect", "--json", "--density-scale", "42"]).arg(&out).output().unwrap();
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["density_scale"].as_f64().unwrap(), 42.0);

    let o = fabric().args(["inspect"]).arg(out.join("orientation.vol")).output().unwrap();
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && s.contains("grid 64x48x16, 3 channel(s), float32") && s.contains("|v| non-zero"), "{}", text(&o));

    // The same seed gives the same bytes.
    let again = dir("felt_again");
    assert!(fabric().args(["gen", "--preset", "felt", "--size", "64x48x16", "--seed", "5", "--roughness", "0.4", "--no-previews", "--out"]).arg(&again).status().unwrap().success());
    for f in ["density.vol", "albedo.vol", "orientation.vol", "material.toml"] {
        assert!(std::fs::read(out.join(f)).unwrap() == std::fs::read(again.join(f)).unwrap(), "{f} differs");
    }
}

#[test]
fn compact_encoding_bench_and_params() {
    let out = dir("compact");
    let o = fabric().args(["gen", "--preset", "silk", "--size", "48x48x16", "--encoding", "compact", "--no-previews", "--out"]).arg(&out).output().unwrap();
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(std::fs::metadata(out.join("density.vol")).unwrap().len(), 48 + 48 * 48 * 16);
    assert_eq!(std::fs::metadata(out.join("orientation.vol")).unwrap().len(), 48 + 2 * 48 * 48 * 16);
    let o = fabric().args(["inspect"]).arg(out.join("orientation.vol")).output().unwrap();
    assert!(String::from_utf8_lossy(&o.stdout).contains("quantized directions"), "{}", text(&o));

    let o = fabric().args(["gen", "--preset", "plain", "--size", "64x64x16", "--bench", "--json"]).output().unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["seconds"]["voxelize"].as_f64().unwrap() > 0.0 && v["warps"].as_u64().unwrap() >= 2);

    // --print-params shows every key; a parameter file (here: a generated material.toml)
    // reproduces the fabric.
    let o = fabric().args(["gen", "--preset", "satin", "--print-params"]).output().unwrap();
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(s.contains("pattern = \"satin\"") && s.contains("crimp_balance") && s.contains("loop_probability"), "{s}");
    let first = dir("from_a");
    let second = dir("from_b");
    assert!(fabric().args(["gen", "--preset", "twill", "--size", "48x48x16", "--set", "fabric.yarn.fiber_twist=-2", "--no-previews", "--out"]).arg(&first).status().unwrap().success());
    let o = fabric().args(["gen", "--preset", "plain", "--size", "48x48x16", "--no-previews", "--params"]).arg(first.join("material.toml")).arg("--out").arg(&second).output().unwrap();
    assert!(o.status.success(), "{}", text(&o));
    assert!(std::fs::read(first.join("density.vol")).unwrap() == std::fs::read(second.join("density.vol")).unwrap());
}

#[test]
fn bad_input_is_a_clear_error() {
    let bad_vol = dir("bad").with_extension("vol");
    std::fs::write(&bad_vol, b"VOL\x03\x09\0\0\0").unwrap();
    let cases: Vec<(Vec<String>, &str)> = vec![
        (vec!["gen".into(), "--bench".into(), "--set".into(), "fabric.yarn.plys=2".into()], "plys"),
        (vec!["gen".into(), "--bench".into(), "--set".into(), "fabric.cover=9".into()], "fabric.cover"),
        (vec!["gen".into(), "--bench".into(), "--size".into(), "64x0x16".into()], "at least one voxel"),
        (vec!["gen".into(), "--bench".into(), "--preset".into(), "tweed".into()], "unknown preset"),
        (vec!["gen".into(), "--bench".into(), "--roughness".into(), "3".into()], "(0, 1]"),
        (vec!["inspect".into(), "/nonexistent/fabric".into()], "no such file"),
        (vec!["inspect".into(), bad_vol.display().to_string()], "truncated"),
        (vec!["inspect".into(), env!("CARGO_MANIFEST_DIR").into()], "density.vol"),
    ];
    for (args, msg) in cases {
        let o = fabric().args(&args).output().unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && !stderr.contains("panicked"), "{args:?}: {}", text(&o));
        assert!(stderr.contains(msg), "{args:?}: expected '{msg}' in {stderr}");
    }
}
