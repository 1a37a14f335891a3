//! `FABRIC_SHADER_DIR`: the hybrid programs compile from that directory instead of the
//! SPIR-V built in (`ShaderModule::embedded_or_edited`). The variable is read by the
//! process, so each case runs this test binary again as a child with it set.

#![cfg(feature = "gpu")]

use std::path::{Path, PathBuf};

use fabric_runtime::cpu::{CpuRenderOptions, ShadowMode};
use fabric_runtime::gpu::HybridPass;
use fabric_runtime::hybrid::examples;
use fabric_runtime::image::Image;
use fabric_runtime::scene::{Camera, Light};
use fabric_runtime::vk::CheckedDevice;
use glam::Vec3;

/// The frame both processes draw.
fn frame() -> Image {
    let device = CheckedDevice::new().expect("a Vulkan device (lavapipe in CI)");
    let pass = HybridPass::new(&device).unwrap();
    let model = examples::synthetic_model(32, 3);
    let g = pass.upload(&model, true).unwrap();
    let cam = Camera::orbit_orthographic(35.0, 20.0, Vec3::new(0.5, 0.5, 0.0), 40.0, 1.5, 16, 12);
    let opts = CpuRenderOptions { periodic: true, shadows: ShadowMode::On, ..Default::default() };
    pass.render(&g, &cam, &[Light::directional(Vec3::new(-0.3, 0.2, 1.0), Vec3::ONE)], &opts, None).unwrap().image
}

/// A copy of the project's shaders/ in `dir`, `hybrid.comp` passed through `edit`.
fn copy_shaders(dir: &Path, edit: impl Fn(String) -> String) {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shaders");
    for sub in ["", "common"] {
        std::fs::create_dir_all(dir.join(sub)).unwrap();
        for entry in std::fs::read_dir(src.join(sub)).unwrap() {
            let path = entry.unwrap().path();
            if path.is_file() {
                let name = path.strip_prefix(&src).unwrap();
                let text = std::fs::read_to_string(&path).unwrap_or_default();
                let text = if name == Path::new("hybrid.comp") { edit(text) } else { text };
                std::fs::write(dir.join(name), text).unwrap();
            }
        }
    }
}

/// This binary's `child_draws_the_frame` with FABRIC_SHADER_DIR = `dir`: its image.
fn frame_in_child(dir: &Path, out: &Path) -> Image {
    let status = std::process::Command::new(std::env::current_exe().unwrap())
        .args(["--ignored", "--exact", "child_draws_the_frame", "--test-threads", "1"])
        .env("FABRIC_SHADER_DIR", dir)
        .env("FABRIC_SHADER_DIR_TEST_OUT", out)
        .status()
        .unwrap();
    assert!(status.success(), "the child failed: {status}");
    Image::read(out, 1.0).unwrap()
}

#[test]
#[ignore = "run by hybrid_programs_compile_from_fabric_shader_dir as a child process"]
fn child_draws_the_frame() {
    if let Some(out) = std::env::var_os("FABRIC_SHADER_DIR_TEST_OUT") {
        frame().write(Path::new(&out), 1.0).unwrap();
    }
}

#[test]
fn hybrid_programs_compile_from_fabric_shader_dir() {
    let root: PathBuf = std::env::temp_dir().join(format!("fabric-shader-dir-{}", std::process::id()));
    let built_in = frame();
    // The same sources, compiled at run time: the same image.
    let same = root.join("same");
    copy_shaders(&same, |t| t);
    let from_source = frame_in_child(&same, &root.join("same.exr"));
    assert_eq!(from_source.pixels.len(), built_in.pixels.len());
    let worst = from_source.pixels.iter().zip(&built_in.pixels).map(|(a, b)| (*a - *b).abs().max_element()).fold(0.0f32, f32::max);
    let peak = built_in.pixels.iter().map(|p| p.max_element()).fold(0.0f32, f32::max);
    assert!(peak > 0.0 && worst <= 1e-6 * peak, "compiled from source: {worst} off (peak {peak})");
    // An edited hybrid.comp: its edit shows.
    let edited = root.join("edited");
    let line = "pixels[y * size.x + x] = vec4(finite ? t.radiance : vec3(0.0), finite ? 1.0 : 0.0);";
    copy_shaders(&edited, |t| {
        assert!(t.contains(line), "hybrid.comp no longer writes its pixel as this test expects");
        t.replace(line, "pixels[y * size.x + x] = vec4(0.25, 0.5, 0.75, 1.0);")
    });
    let flat = frame_in_child(&edited, &root.join("edited.exr"));
    assert!(flat.pixels.iter().all(|p| (*p - Vec3::new(0.25, 0.5, 0.75)).abs().max_element() < 1e-6), "the edited shader was not used");
    let _ = std::fs::remove_dir_all(&root);
}
