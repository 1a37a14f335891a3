//! Emits the link lines that Debian's static shaderc needs.
//!
//! Debian's `libshaderc.so` leaves glslang and SPIRV-Tools symbols undefined, so the
//! `shaderc` crate is built with `prefer-static-linking` against
//! `libshaderc_combined.a`, and glslang/SPIRV-Tools are linked here, explicitly. Any
//! crate (or build script) that uses `shaderc` depends on this crate so the lines
//! reach its final link. Putting them in `.cargo/config.toml` rustflags is fragile:
//! a `RUSTFLAGS` variable silently replaces them.
fn main() {
    let dir = std::env::var("SHADERC_LIB_DIR").unwrap_or_else(|_| "/usr/lib/x86_64-linux-gnu".into());
    println!("cargo:rerun-if-env-changed=SHADERC_LIB_DIR");
    println!("cargo:rustc-link-search=native={dir}");
    for lib in [
        "glslang",
        "MachineIndependent",
        "GenericCodeGen",
        "OSDependent",
        "OGLCompiler",
        "SPIRV",
        "HLSL",
        "glslang-default-resource-limits",
        "SPIRV-Tools-opt",
        "SPIRV-Tools",
    ] {
        println!("cargo:rustc-link-lib=static={lib}");
    }
    println!("cargo:rustc-link-lib=dylib=stdc++");
}
