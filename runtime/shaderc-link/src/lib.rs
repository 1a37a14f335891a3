//! Nothing to call: depending on this crate adds the static glslang/SPIRV-Tools link
//! lines that the `shaderc` crate needs on Debian (see `build.rs`).
#![no_std]
