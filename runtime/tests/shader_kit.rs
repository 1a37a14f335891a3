//! The shader kit as an engine team would use it (shaders/README.md, "Porting the
//! shaders"): `shaders/example_texel_brdf.comp` evaluates a model's BRDF at texels of
//! every level with only the model's arrays bound, and agrees with the Rust twin; the
//! kit's README documents every include in `shaders/common/`.

#![cfg(feature = "gpu")]

use bytemuck::{Pod, Zeroable};
use fabric_runtime::brdf::twin::SplitMix64;
use fabric_runtime::cpu::shading::texel_response;
use fabric_runtime::hybrid::examples;
use fabric_runtime::hybrid::gpu_layout::GpuModel;
use fabric_runtime::vk::{Buffer, CheckedDevice};

mod support;

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct Query {
    texel: [u32; 4],
    wi: [f32; 4],
    wo: [f32; 4],
}

#[test]
fn the_example_evaluates_a_models_brdf_as_the_rust_twin_does() {
    let device = CheckedDevice::new().expect("a Vulkan device (lavapipe in CI)");
    // With visibility gradients (format 1.12), which the kit reads from binding 13.
    let mut model = examples::sample_model();
    examples::add_gradients(&mut model, 2);
    let arrays = GpuModel::new(&model, false).unwrap();
    let mut rng = SplitMix64(5);
    let mut queries = Vec::new();
    for (level, l) in model.levels.iter().enumerate() {
        for j in 0..l.height {
            for i in 0..l.width {
                let mut wi = rng.unit_vector();
                wi.z = wi.z.abs();
                let wo = glam::Vec3::new(-wi.x, -wi.y, wi.z) + 0.2 * rng.unit_vector();
                queries.push(Query { texel: [level as u32, i, j, 0], wi: wi.extend(0.0).to_array(), wo: wo.normalize().extend(0.0).to_array() });
            }
        }
    }
    let mut buffers: Vec<Buffer> = arrays.arrays().iter().map(|(name, bytes)| support::storage(&device, name, bytes)).collect();
    // Bindings 7 and 8 (frame parameters, edit mask) are declared, not read.
    buffers.push(support::storage(&device, "unused params", &[0u8; std::mem::size_of::<fabric_runtime::hybrid::gpu_layout::GpuRenderParams>()]));
    buffers.push(support::storage(&device, "unused mask", &[0u8; 4]));
    buffers.push(support::storage(&device, "queries", bytemuck::cast_slice(&queries)));
    // Bindings 10–12 are not read; 13 holds the visibility gradients (format 1.12).
    for name in ["unused 10", "unused 11", "unused 12"] {
        buffers.push(support::storage(&device, name, &[0u8; 16]));
    }
    let (name, bytes) = arrays.view_tilt_array();
    buffers.push(support::storage(&device, name, &bytes));
    let refs: Vec<&Buffer> = buffers.iter().collect();
    let out = support::run_compute(&device, "example_texel_brdf.comp", &refs, (queries.len() * 16) as u64, queries.len() as u32);
    let got: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&out);
    let mut worst = 0.0f32;
    for (q, g) in queries.iter().zip(&got) {
        let b = model.levels[q.texel[0] as usize].texel_brdf(q.texel[1], q.texel[2]);
        let want = texel_response(&b, glam::Vec4::from(q.wi).truncate(), glam::Vec4::from(q.wo).truncate(), model.meta.reading, model.meta.diffuse);
        assert!(g.iter().all(|v| v.is_finite()), "texel {:?}: the kit's response {g:?} is not finite", q.texel);
        let e = (want - glam::Vec4::from(*g).truncate()).abs().max_element() / want.max_element().max(1e-6);
        assert!(!e.is_nan(), "texel {:?}: NaN against {want}", q.texel);
        worst = worst.max(e);
    }
    println!("{} texels over {} levels: worst relative difference {worst:.1e}", queries.len(), model.levels.len());
    assert!(worst < 1e-4, "{worst}");
}

#[test]
fn the_kit_readme_documents_every_include() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shaders");
    let readme = std::fs::read_to_string(root.join("README.md")).expect("shaders/README.md");
    for entry in std::fs::read_dir(root.join("common")).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        assert!(readme.contains(&format!("common/{name}")), "shaders/README.md does not document common/{name}");
    }
    for program in ["brdf.glsl", "hybrid.comp", "hybrid_mesh.comp", "hybrid_mesh_id.vert", "example_texel_brdf.comp", "brdf_test_vectors.json"] {
        assert!(readme.contains(program), "shaders/README.md does not mention {program}");
    }
}
