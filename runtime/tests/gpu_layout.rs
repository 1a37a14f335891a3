//! The GPU data layout (`runtime/src/hybrid/gpu_layout.rs`) against the compiled shader:
//! every member offset of every shared struct, read from the SPIR-V's `Offset`
//! decorations (compiled here with debug names), equals Rust's `offset_of!`, and every
//! array's stride is the Rust element's size. A member added on one side only fails too.

#![cfg(feature = "gpu")]

use std::collections::HashMap;
use std::mem::offset_of;

use fabric_runtime::hybrid::gpu_layout::{GpuCamera, GpuLevel, GpuLight, GpuModelHeader, GpuQuadLevel, GpuRenderParams};
use fabric_runtime::vk::shader::compile_named;

/// Per struct name: its members' (name, offset) in order, from OpName / OpMemberName /
/// OpMemberDecorate Offset; and per array type id its stride.
struct Reflection {
    structs: HashMap<String, Vec<(String, u32)>>,
}

fn string_at(words: &[u32]) -> String {
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    String::from_utf8_lossy(&bytes[..end]).into_owned()
}

fn reflect(spirv: &[u32]) -> Reflection {
    assert_eq!(spirv[0], 0x0723_0203, "SPIR-V magic");
    let mut names: HashMap<u32, String> = HashMap::new();
    let mut member_names: HashMap<(u32, u32), String> = HashMap::new();
    let mut offsets: HashMap<(u32, u32), u32> = HashMap::new();
    let mut struct_members: HashMap<u32, u32> = HashMap::new();
    let mut i = 5;
    while i < spirv.len() {
        let (count, op) = ((spirv[i] >> 16) as usize, spirv[i] & 0xffff);
        let w = &spirv[i..i + count];
        match op {
            5 => {
                names.insert(w[1], string_at(&w[2..]));
            }
            6 => {
                member_names.insert((w[1], w[2]), string_at(&w[3..]));
            }
            // OpMemberDecorate s m Offset(35) value
            72 if w[3] == 35 => {
                offsets.insert((w[1], w[2]), w[4]);
            }
            // OpTypeStruct id member types...
            30 => {
                struct_members.insert(w[1], (count - 2) as u32);
            }
            _ => {}
        }
        i += count.max(1);
    }
    let mut structs = HashMap::new();
    for (id, n) in struct_members {
        let Some(name) = names.get(&id) else { continue };
        let members: Vec<(String, u32)> = (0..n).filter_map(|m| Some((member_names.get(&(id, m))?.clone(), *offsets.get(&(id, m))?))).collect();
        if members.len() == n as usize {
            structs.insert(name.clone(), members);
        }
    }
    Reflection { structs }
}

fn check(r: &Reflection, name: &str, rust: &[(&str, usize)]) {
    let glsl = r.structs.get(name).unwrap_or_else(|| panic!("struct {name} not in the SPIR-V (names: {:?})", r.structs.keys().collect::<Vec<_>>()));
    // GLSL pads with explicit pad members where Rust has one padding array: compare the
    // members Rust names, in order, and that nothing else in GLSL is more than padding.
    let real: Vec<&(String, u32)> = glsl.iter().filter(|(n, _)| !n.starts_with("pad")).collect();
    let want: Vec<(String, u32)> = rust.iter().map(|(n, o)| (n.to_string(), *o as u32)).collect();
    let got: Vec<(String, u32)> = real.into_iter().cloned().collect();
    assert_eq!(got, want, "members of {name}: GLSL (left) vs Rust (right)");
}

#[test]
fn shader_structs_have_the_rust_layout() {
    let spirv = compile_named("hybrid.comp", &[]).expect("hybrid.comp compiles");
    let r = reflect(&spirv);
    macro_rules! members {
        ($t:ty: $($f:ident),*) => { &[$((stringify!($f), offset_of!($t, $f))),*] };
    }
    check(&r, "GpuLevel", members!(GpuLevel: dims, surface, texel_base, header_base, lobe_base, fly_nodes, fly_head_base, fly_node_base, fly_header_base, fly_lobe_base, voxel_depth, fly_edge, trans_base, tilt_base, spread_base, fly_gain, grad_base, curv_base));
    check(&r, "GpuQuadLevel", members!(GpuQuadLevel: dims, offset));
    check(&r, "GpuModelHeader", members!(GpuModelHeader: origin, size, texel, n, top_z, height_scale, level_count, quad_count, leaf_offset, flags, inv_texel, levels, quad));
    check(&r, "GpuCamera", members!(GpuCamera: origin, forward, right, up, half_extents, size));
    check(&r, "GpuLight", members!(GpuLight: vec, power));
    check(&r, "GpuRenderParams", members!(GpuRenderParams: camera, background, light_count, max_steps, max_flyaway_columns, supersampling, level_mode, fixed_level, level_bias, coarse_relief, edit_tint, edit_roughness, edit_rotation, mask_dims, lights, env_info, env_frame, env_levels));
    // The last member's end is the struct's size: a GLSL struct shorter than Rust's
    // would shift every array element after the first.
    let end = |name: &str| r.structs[name].last().map(|(_, o)| *o).unwrap();
    assert_eq!(end("GpuLevel") + 4, size_of::<GpuLevel>() as u32);
    assert_eq!(end("GpuQuadLevel") + 4, size_of::<GpuQuadLevel>() as u32);
    assert_eq!(end("GpuModelHeader") as usize + 18 * size_of::<GpuQuadLevel>(), size_of::<GpuModelHeader>());
    assert_eq!(end("GpuRenderParams") as usize + fabric_runtime::hybrid::gpu_layout::GPU_ENV_SLOTS * 16, size_of::<GpuRenderParams>());
}
