//! The `fabric` binary end to end: exit codes and messages a user sees.

use std::process::Command;

fn fabric() -> Command {
    Command::new(env!("CARGO_BIN_EXE_fabric"))
}

fn tmp(name: &str) -> std::path::PathBuf {
    let d = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("cli");
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

#[test]
fn render_writes_png_and_exr_and_reports_the_gpu_time() {
    for ext in ["png", "exr"] {
        let out = tmp(&format!("sphere.{ext}"));
        let o = fabric().args(["render", "--mesh", "sphere", "--size", "160x90", "--out"]).arg(&out).output().unwrap();
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "stdout: {stdout}\nstderr: {}", String::from_utf8_lossy(&o.stderr));
        assert!(stdout.contains("device: ") && stdout.contains("GPU frame time"), "{stdout}");
        let img = fabric_runtime::image::Image::read(&out, 1.0).unwrap();
        assert_eq!((img.width, img.height), (160, 90));
        assert!(img.mean() > 0.01, "the sphere should be lit");
    }
}

#[test]
fn a_missing_vulkan_driver_is_a_clear_error_not_a_panic() {
    for args in [&["devices"][..], &["render", "--size", "32x32", "--out", "/tmp/never.png"][..]] {
        let o = fabric().args(args).env("VK_DRIVER_FILES", "/nonexistent.json").env("VK_ICD_FILENAMES", "/nonexistent.json").output().unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} should fail without a driver");
        assert_eq!(o.status.code(), Some(1), "{stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert!(stderr.contains("error:") && (stderr.contains("driver") || stderr.contains("no usable Vulkan device")), "{stderr}");
    }
}

#[test]
fn bad_flags_are_rejected_with_a_message() {
    for (args, expect) in [
        (&["render", "--size", "0x10", "--out", "x.png"][..], "size"),
        (&["render", "--fov", "200", "--out", "x.png"][..], "field of view"),
        (&["render", "--origin", "0,0,0", "--target", "0,0,0", "--out", "x.png"][..], "coincide"),
        (&["render", "--mesh", "teapot", "--out", "x.png"][..], "unknown mesh"),
        (&["render", "--out", "x.bmp"][..], "extension"),
        (&["render", "--light-dir", "0,0,0", "--out", "x.png"][..], "light"),
        (&["render", "--device", "no-such-gpu", "--out", "x.png"][..], "no vulkan device matches 'no-such-gpu'"),
        (&["render", "--exposure", "-1", "--out", "x.png"][..], "exposure"),
    ] {
        let o = fabric().args(args).current_dir(env!("CARGO_TARGET_TMPDIR")).output().unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
        assert!(stderr.to_lowercase().contains(expect), "{args:?}: expected '{expect}' in: {stderr}");
    }
}
