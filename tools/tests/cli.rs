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
        (&["render", "--repeat", "0", "--out", "x.png"][..], "--repeat 0"),
    ] {
        let o = fabric().args(args).current_dir(env!("CARGO_TARGET_TMPDIR")).output().unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
        assert!(stderr.to_lowercase().contains(expect), "{args:?}: expected '{expect}' in: {stderr}");
    }
}

/// An X server for window tests: Xvfb on a display number of our own.
struct Xvfb(std::process::Child, String);

impl Xvfb {
    /// Starts Xvfb on a display number it picks itself (`-displayfd`), so parallel
    /// test runs never clash over a display.
    fn start() -> Xvfb {
        use std::io::BufRead;
        let mut child = Command::new("Xvfb")
            .args(["-displayfd", "1", "-screen", "0", "640x480x24", "-nolisten", "tcp"])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("Xvfb is needed for window tests (apt-get install xvfb; README's set-up installs it)");
        let mut line = String::new();
        std::io::BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
        let n: u32 = line.trim().parse().unwrap_or_else(|_| panic!("Xvfb printed '{line}' instead of its display number"));
        Xvfb(child, format!(":{n}"))
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn the_window_presents_what_offscreen_rendering_renders() {
    let x = Xvfb::start();
    let shot = tmp("view.png");
    let o = fabric().args(["view", "--frames", "4", "--size", "160x120", "--screenshot"]).arg(&shot).env("DISPLAY", &x.1).output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "fabric view failed: {stderr}");
    assert!(!stderr.contains("validation error"), "{stderr}");
    let offscreen = tmp("offscreen.png");
    let o = fabric().args(["render", "--size", "160x120", "--out"]).arg(&offscreen).output().unwrap();
    assert!(o.status.success());
    let a = fabric_runtime::image::Image::read(&shot, 1.0).unwrap();
    let b = fabric_runtime::image::Image::read(&offscreen, 1.0).unwrap();
    // Same renderer, same camera and light: identical up to nothing at all.
    let f = fabric_runtime::metrics::flip(&a, &b, 1.0).unwrap();
    assert!(f.mean < 1e-3, "window and offscreen frames differ: FLIP mean {}", f.mean);
}

#[test]
fn the_window_draws_a_hybrid_model_as_offscreen_rendering_does() {
    let x = Xvfb::start();
    let model = tmp("view-synthetic.hyb");
    fabric_runtime::hybrid::format::write_file(&fabric_runtime::hybrid::examples::synthetic_model(64, 7), &model).unwrap();
    let flags = ["--mesh", "plane", "--uv-scale", "3", "--size", "160x120", "--view-angles", "40,-60", "--light-angles", "30,120", "--roughness-scale", "1.5", "--tangent-rotation", "30"];
    let shot = tmp("view-hybrid.exr");
    let o = fabric().arg("view").arg(&model).args(["--frames", "3"]).args(flags).arg("--screenshot").arg(&shot).env("DISPLAY", &x.1).output().unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "fabric view MODEL failed: {stdout}\n{stderr}");
    assert!(stdout.contains("variant: flyaways marched"), "{stdout}");
    let offscreen = tmp("offscreen-hybrid.exr");
    let o = fabric().arg("render").arg(&model).args(flags).arg("--out").arg(&offscreen).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let a = fabric_runtime::image::Image::read(&shot, 1.0).unwrap();
    let b = fabric_runtime::image::Image::read(&offscreen, 1.0).unwrap();
    assert!(b.mean() > 1e-4, "the fabric is lit");
    // The same pass, light and edits; the window's camera went through the orbit's
    // spherical coordinates and back (rounding moves the odd hit across a texel edge:
    // measured 2.6e-3), an edit left out would differ by > 5e-2.
    let rmse = fabric_runtime::metrics::relative_rmse(&a, &b).unwrap();
    assert!(rmse < 0.01, "window and offscreen frames differ: relative RMSE {rmse}");
    // Under the built-in sky, the same.
    let sky = ["--mesh", "plane", "--uv-scale", "3", "--size", "160x120", "--view-angles", "40,-60", "--envmap", "sky"];
    let shot = tmp("view-hybrid-sky.exr");
    let o = fabric().arg("view").arg(&model).args(["--frames", "2"]).args(sky).arg("--screenshot").arg(&shot).env("DISPLAY", &x.1).output().unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && stdout.contains("environment map"), "fabric view --envmap failed: {stdout}\n{}", String::from_utf8_lossy(&o.stderr));
    let offscreen = tmp("offscreen-hybrid-sky.exr");
    let o = fabric().arg("render").arg(&model).args(sky).arg("--out").arg(&offscreen).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (a, b) = (fabric_runtime::image::Image::read(&shot, 1.0).unwrap(), fabric_runtime::image::Image::read(&offscreen, 1.0).unwrap());
    let rmse = fabric_runtime::metrics::relative_rmse(&a, &b).unwrap();
    assert!(b.mean() > 1e-4 && rmse < 0.01, "window and offscreen frames under the sky differ: relative RMSE {rmse}");
}

#[test]
fn view_without_a_display_is_a_clear_error() {
    let o = fabric().args(["view", "--frames", "1"]).env_remove("DISPLAY").env_remove("WAYLAND_DISPLAY").output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && !stderr.contains("panicked"), "{stderr}");
    assert!(stderr.contains("DISPLAY"), "{stderr}");
}

#[test]
fn hybrid_models_render_on_the_gpu_and_the_cpu_alike_and_inspect() {
    let model = tmp("synthetic.hyb");
    fabric_runtime::hybrid::format::write_file(&fabric_runtime::hybrid::examples::synthetic_model(64, 7), &model).unwrap();
    let mut images = Vec::new();
    for backend in ["auto", "cpu"] {
        let out = tmp(&format!("synthetic-{backend}.exr"));
        let o = fabric().arg("render").arg(&model).args(["--view-angles", "30,-90", "--light-angles", "40,-60", "--size", "96x64", "--backend", backend, "--out"]).arg(&out).output().unwrap();
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&o.stderr));
        let want = if backend == "auto" { "GPU renderer" } else { "CPU renderer" };
        assert!(stdout.contains(want), "{stdout}");
        if backend == "auto" {
            assert!(stdout.contains("frame time") && stdout.contains("device:"), "{stdout}");
        }
        let img = fabric_runtime::image::Image::read(&out, 1.0).unwrap();
        assert!(img.mean() > 1e-4, "the lit tile should be visible");
        images.push(img);
    }
    // The twins agree (runtime/tests/gpu_hybrid.rs states the tolerance).
    let rmse = fabric_runtime::metrics::relative_rmse(&images[0], &images[1]).unwrap();
    assert!(rmse < 0.07, "GPU vs CPU relative RMSE {rmse}");
    // From afar with `--coarse-filter split` (the flyaways' coverage from a finer grid)
    // and `split-shaded` (their light from it too), on both backends alike.
    for filter in ["split", "split-shaded"] {
        let far: Vec<_> = ["auto", "cpu"]
            .iter()
            .map(|backend| {
                let out = tmp(&format!("synthetic-far-{filter}-{backend}.exr"));
                let o = fabric().arg("render").arg(&model).args(["--view-angles", "45,30", "--periodic", "--extent", "12", "--size", "32x32", "--coarse-filter", filter, "--backend", backend, "--out"]).arg(&out).output().unwrap();
                assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
                fabric_runtime::image::Image::read(&out, 1.0).unwrap()
            })
            .collect();
        let rmse = fabric_runtime::metrics::relative_rmse(&far[0], &far[1]).unwrap();
        assert!(far[1].mean() > 1e-4 && rmse < 0.07, "{filter}, GPU vs CPU relative RMSE {rmse}");
    }
    // On a mesh: the GPU only, and a clear error from the CPU backend.
    let out = tmp("synthetic-sphere.png");
    let o = fabric().arg("render").arg(&model).args(["--mesh", "sphere", "--uv-scale", "4,2", "--size", "64x64", "--out"]).arg(&out).output().unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && stdout.contains("on a mesh of"), "{stdout}\n{}", String::from_utf8_lossy(&o.stderr));
    assert!(fabric_runtime::image::Image::read(&out, 1.0).unwrap().mean() > 1e-4);
    let o = fabric().arg("render").arg(&model).args(["--mesh", "sphere", "--backend", "cpu", "--out"]).arg(&out).output().unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("only the GPU renderer"));
    let o = fabric().arg("render").arg(&model).args(["--mesh", "sphere", "--uv-scale", "0", "--out"]).arg(&out).output().unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("positive"));
    let o = fabric().arg("inspect").arg(&model).arg("--json").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("inspect --json prints JSON");
    let written = fabric_runtime::hybrid::examples::synthetic_model(64, 7);
    let m = &v["model"];
    assert!(m["width"] == 64 && m["height"] == 64 && m["levels"] == written.levels.len(), "{m}");
    let stats = m["level_stats"].as_array().expect("level_stats");
    assert_eq!(stats.len(), written.levels.len());
    for (l, s) in written.levels.iter().zip(stats) {
        assert_eq!(s["resolution"], format!("{}x{}", l.width, l.height), "{s}");
        assert!(s["bytes"].as_u64().is_some_and(|b| b > 0) && s["max_lobes"].as_u64().is_some_and(|n| (1..=8).contains(&n)), "{s}");
    }
    assert_eq!(v["file_size"], std::fs::metadata(&model).unwrap().len());
    // A corrupt model is a clear error.
    let mut bytes = std::fs::read(&model).unwrap();
    let n = bytes.len();
    bytes[n / 2] ^= 0x5a;
    let bad = tmp("corrupt.hyb");
    std::fs::write(&bad, &bytes).unwrap();
    for args in [vec!["inspect".to_string()], vec!["render".to_string()]] {
        let o = fabric().args(&args).arg(&bad).args(if args[0] == "render" { vec!["--out", "/tmp/never.png"] } else { vec![] }).output().unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && !stderr.contains("panicked") && stderr.contains("corrupt.hyb"), "{args:?}: {stderr}");
    }
}

#[test]
fn bake_refuses_bad_input_with_a_clear_error() {
    let out = tmp("never.hyb");
    let cases: [(&[&str], &str); 12] = [
        (&["bake", "/nonexistent/fabric"], "cannot load the fabric volume"),
        (&["bake", "/nonexistent/fabric", "--bsdf", "--openness-rays", "100000"], "openness_rays"),
        (&["bake", "/nonexistent/fabric", "--bsdf", "--tau-max", "99"], "--tau-max"),
        (&["bake", "/nonexistent/fabric", "--spp", "1"], "spp"),
        (&["bake", "/nonexistent/fabric", "--k-min", "8", "--k-max", "4"], "k_min"),
        (&["bake", "/nonexistent/fabric", "--min-gain", "1"], "min_gain"),
        (&["bake", "/nonexistent/fabric", "--normal-detail", "nan"], "--normal-detail"),
        (&["bake", "/nonexistent/fabric", "--held-out-turn", "90"], "--held-out-turn"),
        (&["bake", "/nonexistent/fabric", "--held-out-turn", "nan"], "--held-out-turn"),
        (&["bake", "/nonexistent/fabric", "--lobe-peak-max", "0.5"], "--lobe-peak-max"),
        (&["bake", "/nonexistent/fabric", "--lobe-peak-max", "inf"], "--lobe-peak-max"),
        (&["bake", "/nonexistent/fabric", "--eta", "1"], "Fresnel"),
    ];
    for (args, says) in cases {
        let o = fabric().args(args).arg("--out").arg(&out).output().unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked") && stderr.contains(says), "{args:?}: {stderr}");
    }
    assert!(!out.exists());
}

#[test]
fn prefilter_rebuilds_the_chain_and_refuses_bad_input() {
    let mut m = fabric_runtime::hybrid::examples::synthetic_model(32, 3);
    m.levels.truncate(1);
    m.meta.fit_error.truncate(1);
    let model = tmp("level0.hyb");
    fabric_runtime::hybrid::format::write_file(&m, &model).unwrap();
    let out = tmp("chain.hyb");
    let o = fabric().arg("prefilter").arg(&model).arg("--out").arg(&out).output().unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains("coarse levels") && stdout.contains("1x1"), "{stdout}");
    let chain = fabric_runtime::hybrid::format::read_file(&out).unwrap();
    assert_eq!(chain.levels.len(), 6);
    assert_eq!(chain.levels[0], m.levels[0], "level 0 is kept as it is");
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(out.with_extension("json")).unwrap()).unwrap();
    assert_eq!(report["prefilter"]["levels"].as_array().map(|a| a.len()), Some(5));
    for args in [vec!["--prefilter-tolerance", "nan"], vec!["--prefilter-max-lobes", "9"], vec!["--levels", "40"], vec!["--check", "--check-filter", "nope"]] {
        let o = fabric().arg("prefilter").arg(&model).arg("--out").arg(tmp("never.hyb")).args(&args).output().unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && !stderr.contains("panicked") && stderr.contains("error"), "{args:?}: {stderr}");
    }
    let o = fabric().arg("prefilter").arg(tmp("missing.hyb")).arg("--out").arg(tmp("never.hyb")).output().unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("missing.hyb"));
}

#[test]
fn diff_thresholds_set_the_exit_code() {
    use fabric_runtime::image::Image;
    let a = Image::from_fn(48, 32, |x, y| glam::Vec3::new(x as f32 / 48.0, y as f32 / 32.0, 0.3));
    let mut b = a.clone();
    for x in 0..24 {
        b.set(x, 10, glam::Vec3::ONE);
    }
    let (pa, pb, map) = (tmp("diff-a.exr"), tmp("diff-b.exr"), tmp("diff-map.png"));
    a.write(&pa, 1.0).unwrap();
    b.write(&pb, 1.0).unwrap();
    let same = fabric().arg("diff").arg(&pa).arg(&pa).args(["--max-flip-mean", "0", "--max-rel-rmse", "0"]).output().unwrap();
    assert!(same.status.success() && String::from_utf8_lossy(&same.stdout).contains("PASS"), "{}", String::from_utf8_lossy(&same.stderr));
    let o = fabric().arg("diff").arg(&pb).arg(&pa).args(["--max-flip-mean", "0.001", "--max-flip-p95", "0.5", "--max-rel-rmse", "1.0", "--diff-image"]).arg(&map).output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && stderr.contains("beyond the thresholds") && stderr.contains("--max-flip-mean"), "{stderr}");
    assert!(!stderr.contains("--max-rel-rmse 1"), "a threshold that holds is not reported: {stderr}");
    assert!(map.exists(), "the difference image is written even when the check fails");
    let o = fabric().arg("diff").arg(&pb).arg(&pa).args(["--json", "--max-rel-rmse", "1e-9"]).output().unwrap();
    assert!(!o.status.success());
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON on stdout");
    assert_eq!(v["failures"].as_array().map(|f| f.len()), Some(1), "{v}");
    let o = fabric().arg("diff").arg(&pa).arg(&pa).args(["--max-flip-mean", "nan"]).output().unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--max-flip-mean"));
    // --block: a checkerboard of ±0.05 cancels in every 2×2 block, not per pixel.
    let c = Image::from_fn(48, 32, |x, y| a.get(x, y) + glam::Vec3::splat(if (x + y) % 2 == 0 { 0.05 } else { -0.05 }));
    let pc = tmp("diff-c.exr");
    c.write(&pc, 1.0).unwrap();
    let o = fabric().arg("diff").arg(&pc).arg(&pa).args(["--json", "--block", "2"]).output().unwrap();
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON on stdout");
    assert!(v["relative_rmse"].as_f64().unwrap() > 0.05 && v["relative_rmse_blocks"].as_f64().unwrap() < 1e-4 && v["block"] == 2, "{v}");
    let o = fabric().arg("diff").arg(&pc).arg(&pa).args(["--block", "0"]).output().unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--block 0"));
}

#[test]
fn the_demo_runs_the_main_job_end_to_end() {
    // A small volume and few samples (the default is 96x96x24 at 128 spp, ~3 minutes).
    let out = tmp("demo");
    let _ = std::fs::remove_dir_all(&out);
    let o = fabric().args(["demo", "--size", "32x32x8", "--spp", "4", "--out"]).arg(&out).output().unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&o.stderr));
    let report = std::fs::read_to_string(out.join("report.md")).expect("report.md");
    for want in ["bake:", "MB from a", "held-out views (", "over 4×4 blocks median", "yardstick: the reference lit 5° off", "demo view", "frame time"] {
        assert!(report.contains(want), "report.md lacks '{want}':\n{report}");
    }
    for file in ["twill.hyb", "twill-reference.exr", "twill-reference-vs-hybrid.png", "twill-hybrid.exr", "twill-bake.json"] {
        assert!(out.join(file).exists(), "{file} missing");
    }
    // The demo's model carries the default diffuse law (format 1.6), and says so.
    let o = fabric().args(["inspect", "--json"]).arg(out.join("twill.hyb")).output().unwrap();
    let json = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && json.contains("\"diffuse\": \"lommel-seeliger\""), "{json}");
    // And its flyaways' lobes are cylinders (format 1.11).
    assert!(json.contains("\"fiber_lobes\": \"cylinder\""), "{json}");
    let o = fabric().args(["bake", "/nonexistent/fabric", "--diffuse", "phong", "--out"]).arg(out.join("never.hyb")).output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && stderr.contains("lommel-seeliger") && !stderr.contains("panicked"), "{stderr}");
    let o = fabric().args(["bake", "/nonexistent/fabric", "--flyaway-lobes", "sphere", "--out"]).arg(out.join("never.hyb")).output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && stderr.contains("cylinder") && stderr.contains("facing") && !stderr.contains("panicked"), "{stderr}");
    let o = fabric().args(["demo", "--spp", "0", "--out"]).arg(&out).output().unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--spp"));
    let o = fabric().args(["demo", "--size", "0x0x0", "--out"]).arg(&out).output().unwrap();
    assert!(!o.status.success() && !String::from_utf8_lossy(&o.stderr).contains("panicked"));
}

#[test]
fn bench_writes_its_csvs_plots_and_summary() {
    // One small preset (the quick suite bakes five at 48x48x12: under 10 minutes).
    let out = tmp("bench");
    let _ = std::fs::remove_dir_all(&out);
    let o = fabric().args(["bench", "--presets", "twill", "--size", "24x24x8", "--out"]).arg(&out).output().unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&o.stderr));
    let summary = std::fs::read_to_string(out.join("summary.md")).expect("summary.md");
    for want in ["| twill |", "GPU ms 320x180", "yardstick: reference lit 5° off", "Frame time by distance", "reference view FLIP", "pom_steps", "level_bias", "skips", "clusters_k", "lobes_per_level", "reference_spp", "Beside the paper", "### Environment light", "### Transmission"] {
        assert!(summary.contains(want), "summary.md lacks '{want}'");
    }
    // A front-lit frame of the BSDF model is the same image with the transmission term
    // compiled in as with it compiled out (the skipped variant costs nothing but time).
    assert!(summary.contains("(the same image)"), "{summary}");
    for sweep in ["pom_steps", "level_bias", "skips", "clusters_k", "lobes_per_level", "reference_spp"] {
        let csv = std::fs::read_to_string(out.join(format!("{sweep}.csv"))).unwrap_or_else(|_| panic!("{sweep}.csv"));
        assert!(csv.lines().count() >= 3, "{sweep}.csv has rows: {csv}");
        for line in csv.lines().skip(1) {
            let error: f64 = line.rsplit(',').next().unwrap().parse().unwrap();
            assert!(error.is_finite() && error >= 0.0, "{sweep}: {line}");
        }
        // Plots where a font is installed (CI installs fonts-dejavu-core).
        if std::path::Path::new("/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf").exists() {
            assert!(out.join(format!("{sweep}.png")).exists() && out.join(format!("{sweep}.svg")).exists(), "{sweep} plots");
        }
    }
    let o = fabric().args(["bench", "--presets", "", "--out"]).arg(&out).output().unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--presets"));
}

#[test]
fn bench_stress_runs_and_passes() {
    // The long run is 10^7 BRDF inputs and 10^6 files; here a short one of each.
    let o = fabric().args(["bench", "--stress", "--stress-brdf", "200000", "--stress-files", "20000"]).output().unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&o.stderr));
    for want in ["BRDF: 200000", "reader: 20000 corrupted files", "renderers:", "stress: passed"] {
        assert!(stdout.contains(want), "{stdout}");
    }
}

#[test]
fn hybrid_models_render_under_an_environment_map() {
    let model = tmp("synthetic-env.hyb");
    fabric_runtime::hybrid::format::write_file(&fabric_runtime::hybrid::examples::synthetic_model(32, 3), &model).unwrap();
    let run = |extra: &[&str], out: &str| {
        let out = tmp(out);
        let o = fabric().arg("render").arg(&model).args(["--view-angles", "30,-90", "--size", "48x32", "--envmap", "sky"]).args(extra).arg("--out").arg(&out).output().unwrap();
        (o.status.success(), String::from_utf8_lossy(&o.stdout).to_string() + &String::from_utf8_lossy(&o.stderr), out)
    };
    // Both backends draw it alike; the sun becomes a light.
    let (ok, text, out) = run(&["--backend", "auto"], "env-auto.exr");
    assert!(ok && text.contains("GPU renderer") && text.contains("environment map") && text.contains("1 source(s) shaded as directional lights"), "{text}");
    let gpu = fabric_runtime::image::Image::read(&out, 1.0).unwrap();
    let (ok, text, out) = run(&["--backend", "cpu"], "env-cpu.exr");
    assert!(ok && text.contains("CPU renderer"), "{text}");
    let lit = fabric_runtime::image::Image::read(&out, 1.0).unwrap();
    assert!(lit.mean() > 1e-3 && lit.first_non_finite().is_none());
    let rmse = fabric_runtime::metrics::relative_rmse(&gpu, &lit).unwrap();
    assert!(rmse < 1e-3, "GPU vs CPU under the sky: relative RMSE {rmse}");
    // Brighter map, brighter image (linear).
    let (ok, text, out) = run(&["--backend", "cpu", "--envmap-scale", "2"], "env-x2.exr");
    assert!(ok, "{text}");
    let twice = fabric_runtime::image::Image::read(&out, 1.0).unwrap();
    assert!((twice.mean() / lit.mean() - 2.0).abs() < 1e-3, "{} vs {}", twice.mean(), lit.mean());
    // On a mesh too (the GPU's mesh pass).
    let (ok, text, out) = run(&["--mesh", "sphere", "--uv-scale", "4,2"], "env-mesh.exr");
    assert!(ok && text.contains("environment map"), "{text}");
    assert!(fabric_runtime::image::Image::read(&out, 1.0).unwrap().mean() > 1e-3);
}

/// A BSDF model lit from behind on the GPU: the frame says it shades the transmission
/// and light comes through; the same scene through the CPU backend agrees.
#[test]
fn render_shades_a_light_behind_a_bsdf() {
    use fabric_runtime::brdf::{ClothLobe, ClothTransmission};
    let mut m = fabric_runtime::hybrid::examples::synthetic_model(32, 5);
    fabric_runtime::hybrid::examples::add_transmission(&mut m, &ClothTransmission { kd: glam::Vec3::splat(0.05), lobe: ClothLobe { k: glam::Vec3::splat(0.2), beta: 0.4, gamma: 1.5 }, tau: 0.5, ..Default::default() }, 4);
    let model = tmp("bsdf.hyb");
    fabric_runtime::hybrid::format::write_file(&m, &model).unwrap();
    let mut images = Vec::new();
    for backend in ["gpu", "cpu"] {
        let out = tmp(&format!("backlit-{backend}.exr"));
        let o = fabric().arg("render").arg(&model).args(["--backend", backend, "--light-dir=0.2,0.3,-1", "--periodic", "--size", "48x32", "--out"]).arg(&out).output().unwrap();
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "{backend}: {stdout}\n{}", String::from_utf8_lossy(&o.stderr));
        if backend == "gpu" {
            assert!(stdout.contains("transmission (light from behind the cloth"), "{stdout}");
        }
        assert!(stdout.contains("only the model's transmission term shades it"), "{backend}: {stdout}");
        images.push(fabric_runtime::image::Image::read(&out, 1.0).unwrap());
    }
    assert!(images[0].mean() > 0.0, "light comes through");
    let rmse = fabric_runtime::metrics::relative_rmse(&images[0], &images[1]).unwrap();
    assert!(rmse < 1e-3, "GPU vs CPU {rmse}");
    // Without a transmission term the same light leaves the frame black, and says so.
    let reflective = tmp("reflective.hyb");
    fabric_runtime::hybrid::format::write_file(&fabric_runtime::hybrid::examples::synthetic_model(32, 5), &reflective).unwrap();
    let out = tmp("backlit-reflective.exr");
    let o = fabric().arg("render").arg(&reflective).args(["--backend", "cpu", "--light-dir=0.2,0.3,-1", "--periodic", "--size", "48x32", "--out"]).arg(&out).output().unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && stdout.contains("warning: the light is below the tile") && stdout.contains("no transmission term"), "{stdout}");
    assert_eq!(fabric_runtime::image::Image::read(&out, 1.0).unwrap().mean(), 0.0);
}
