//! Texel-ordered measurement images of the *full* volume (as the held-out references
//! see it) through the bake's own height field, for the 40 default training pairs and
//! `N` random pairs in the 60° cap, each as two halves: input to angular studies of
//! what a per-texel function of (ω_i, ω_o) can predict.
//!
//! `cargo run --release -p fabric-baker --example angular_dump FABRIC_DIR OUT.bin [N] [SPP]`
//! With `SWEEP=1` in the environment: no training pairs; each of the N random pairs is
//! followed by itself again (another noise sample) and by both directions turned by
//! 2.5°, 5°, 10° and 20° about random axes (how fast the truth itself changes).
//! Output (little-endian): u32 pairs, nx, ny; f32 heights (nx·ny voxels), normals and
//! tangents (nx·ny·3 each); per pair f32 wi[3], wo[3], half A and half B (nx·ny·3 each).

use std::io::Write;
use std::path::Path;

use fabric_baker::bake::{BakeOptions, scale_normal_slopes, surface_heights};
use fabric_baker::fit::directions::{PairOptions, training_pairs};
use fabric_baker::geometry::extract_geometry_with;
use fabric_baker::reference::rng::Rng;
use fabric_baker::reference::{Lookup, MeasureScene};
use fabric_baker::volume::{MaterialOverrides, load_fabric};
use glam::Vec3;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let volume = load_fabric(Path::new(&args[1]), &MaterialOverrides::default()).expect("read the fabric");
    let n: usize = args.get(3).map(|s| s.parse().unwrap()).unwrap_or(64);
    let spp: u32 = args.get(4).map(|s| s.parse().unwrap()).unwrap_or(32);
    let o = BakeOptions::default();
    let mut g = extract_geometry_with(&volume, &o.geometry, &fabric_baker::progress::NoProgress).expect("geometry");
    scale_normal_slopes(&mut g, o.normal_slope);
    let h = surface_heights(&g, o.relief);
    let (z0, vz) = (volume.bbox().min.z, volume.voxel_size().z);
    let world: Vec<f32> = h.iter().map(|v| z0 + v * vz).collect();
    let scene = MeasureScene::new(&volume, Lookup::Trilinear, Some(&world), None).expect("scene");
    let sweep = std::env::var("SWEEP").is_ok();
    let mut pairs: Vec<(Vec3, Vec3)> = if sweep { Vec::new() } else { training_pairs(&PairOptions::default()).iter().map(|p| (p.wi, p.wo)).collect() };
    let mut rng = Rng::new(99, 1, 2);
    let cos_max = 60f32.to_radians().cos();
    let cap = |rng: &mut Rng| {
        let z = 1.0 - rng.next_f32() * (1.0 - cos_max);
        let s = (1.0 - z * z).max(0.0).sqrt();
        let p = std::f32::consts::TAU * rng.next_f32();
        Vec3::new(s * p.cos(), s * p.sin(), z)
    };
    // `w` turned by `deg` about a random axis perpendicular to it.
    let turn = |rng: &mut Rng, w: Vec3, deg: f32| {
        let (a, b) = w.any_orthonormal_pair();
        let p = std::f32::consts::TAU * rng.next_f32();
        let axis = a * p.cos() + b * p.sin();
        glam::Quat::from_axis_angle(axis, deg.to_radians()) * w
    };
    for _ in 0..n {
        let wi = cap(&mut rng);
        let wo = cap(&mut rng);
        pairs.push((wi, wo));
        if sweep {
            // The same pair again (a second noise sample), then both directions turned.
            for deg in [0.0f32, 2.5, 5.0, 10.0, 20.0] {
                pairs.push((turn(&mut rng, wi, deg), turn(&mut rng, wo, deg)));
            }
        }
    }
    let (nx, ny) = scene.texels();
    let mut out = std::io::BufWriter::new(std::fs::File::create(&args[2]).expect("create"));
    let mut put = |v: &[f32]| {
        for x in v {
            out.write_all(&x.to_le_bytes()).unwrap();
        }
    };
    let mut head = Vec::new();
    head.extend([pairs.len() as u32, nx as u32, ny as u32].map(f32::from_bits));
    put(&head);
    put(&h);
    put(&g.normals.iter().flat_map(|v| v.to_array()).collect::<Vec<f32>>());
    put(&g.tangents.iter().flat_map(|v| v.to_array()).collect::<Vec<f32>>());
    for (k, (wi, wo)) in pairs.iter().enumerate() {
        let seed = 11 + 2 * k as u64;
        let (a, _) = scene.render_image(*wi, *wo, spp / 2, seed).expect("render");
        let (b, _) = scene.render_image(*wi, *wo, spp / 2, seed + 1).expect("render");
        put(&[wi.to_array(), wo.to_array()].concat());
        put(&a.pixels.iter().flat_map(|v| v.to_array()).collect::<Vec<f32>>());
        put(&b.pixels.iter().flat_map(|v| v.to_array()).collect::<Vec<f32>>());
        eprint!("\r{}/{}", k + 1, pairs.len());
    }
}
