//! The held-out measurement (the CPU renderer of the whole model against the reference of
//! the whole volume, texel-ordered, over 4×4 blocks) at mirror pairs of one plane of
//! incidence, swept in polar angle: where a model's highlight falls off with angle
//! differently from the volume's along and across the fibres
//! (baker/FIT_MEASUREMENTS.md, "The visibility curvature").
//!
//! `cargo run --release -p fabric-baker --example mirror_sweep MODEL.hyb FABRIC_DIR AZIMUTH_DEG POLAR_DEG,POLAR_DEG,... [SPP] [--perspective]`
//!
//! ω_i is at the azimuth and each polar angle, ω_o its mirror image; orthographic views
//! with a directional light, or with `--perspective` the bake's perspective views (a
//! pinhole camera and a point light, `evaluate::ViewKind::Perspective`).

use std::path::Path;

use fabric_baker::evaluate::{ViewKind, evaluate_view, reference_medium};
use fabric_baker::fit::directions::{Pair, PairKind};
use fabric_baker::reference::Lookup;
use fabric_baker::volume::{MaterialOverrides, load_fabric};
use fabric_runtime::hybrid::format;
use glam::Vec3;

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let perspective = args.iter().any(|a| a == "--perspective");
    args.retain(|a| a != "--perspective");
    let usage = "usage: mirror_sweep MODEL.hyb FABRIC_DIR AZIMUTH_DEG POLAR_DEG,... [SPP] [--perspective]";
    if args.len() < 4 {
        eprintln!("{usage}");
        std::process::exit(2);
    }
    let model = format::read_file(Path::new(&args[0])).unwrap_or_else(|e| panic!("{}: {e}", args[0]));
    let volume = load_fabric(Path::new(&args[1]), &MaterialOverrides::default()).unwrap_or_else(|e| panic!("{}: {e}", args[1]));
    let azimuth: f32 = args[2].parse().expect(usage);
    let polars: Vec<f32> = args[3].split(',').map(|s| s.parse().expect(usage)).collect();
    let spp: u32 = args.get(4).map_or(64, |s| s.parse().expect(usage));
    let medium = reference_medium(&volume, Lookup::Trilinear).expect("the reference medium");
    let kind = if perspective { ViewKind::Perspective } else { ViewKind::Orthographic };
    for (k, &polar) in polars.iter().enumerate() {
        let (t, p) = (polar.to_radians(), azimuth.to_radians());
        let wi = Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
        let pair = Pair { kind: PairKind::Specular, wi, wo: Vec3::new(-wi.x, -wi.y, wi.z) };
        let (e, _) = evaluate_view(&volume, &medium, &model, &pair, kind, model.width(), spp, 1000 + k as u64, 0.0).expect("the view");
        println!(
            "azimuth {azimuth:5.1}° polar {polar:4.1}°: {:5.1}% per 4x4 block, {:5.1}% per pixel, {:5.1}% per 16x16, mean ratio {:.3} (reference noise {:.1}%)",
            100.0 * e.block_error,
            100.0 * e.pixel_error,
            100.0 * e.block16_error,
            e.mean_ratio,
            100.0 * e.reference_noise
        );
    }
}
