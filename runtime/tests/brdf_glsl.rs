//! The GLSL twin of the BRDF compiles (shaderc, Vulkan 1.3) and declares the records the
//! Rust twin writes: `shaders/brdf_eval.comp` with `#include "brdf.glsl"`.
//!
//! The GPU-vs-Rust agreement on lavapipe needs the Vulkan layer (runtime/src/vk); see
//! `brdf_twin_gpu.rs` once it lands.

use std::path::{Path, PathBuf};

// Brings in the static glslang/SPIRV-Tools link lines that shaderc needs.
use shaderc_link as _;

fn shader_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shaders")
}

fn compile(name: &str) -> Result<Vec<u32>, String> {
    let dir = shader_dir();
    let source = std::fs::read_to_string(dir.join(name)).map_err(|e| format!("{name}: {e}"))?;
    let compiler = shaderc::Compiler::new().map_err(|e| e.to_string())?;
    let mut options = shaderc::CompileOptions::new().map_err(|e| e.to_string())?;
    options.set_target_env(shaderc::TargetEnv::Vulkan, shaderc::EnvVersion::Vulkan1_3 as u32);
    options.set_include_callback(move |requested, _, _, _| {
        let path = dir.join(requested);
        let content = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(shaderc::ResolvedInclude { resolved_name: path.display().to_string(), content })
    });
    let kind = if name.ends_with(".comp") { shaderc::ShaderKind::Compute } else { shaderc::ShaderKind::InferFromSource };
    compiler.compile_into_spirv(&source, kind, name, "main", Some(&options)).map(|a| a.as_binary().to_vec()).map_err(|e| e.to_string())
}

#[test]
fn brdf_eval_compute_shader_compiles() {
    let spirv = compile("brdf_eval.comp").unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(spirv[0], 0x0723_0203, "SPIR-V magic");
    assert!(spirv.len() > 200, "a real module: {} words", spirv.len());
}

#[test]
fn every_glsl_function_of_the_twin_exists_in_rust_and_back() {
    // Same names in both files (the structure test a port relies on).
    let glsl = std::fs::read_to_string(shader_dir().join("brdf.glsl")).unwrap();
    let rust = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("src/brdf/mod.rs")).unwrap();
    let glsl_fns: Vec<&str> = glsl.lines().filter_map(|l| l.split_once(" cloth_").filter(|(ret, _)| !ret.starts_with(' ') && !ret.starts_with("//")).map(|(_, rest)| rest.split('(').next().unwrap_or(""))).collect();
    let rust_fns: Vec<&str> = rust.lines().filter_map(|l| l.trim_start().strip_prefix("pub fn cloth_")).map(|rest| rest.split('(').next().unwrap_or("")).collect();
    assert!(glsl_fns.len() >= 12, "{glsl_fns:?}");
    assert_eq!(glsl_fns, rust_fns, "same functions, same order");
}
