//! How much the model's level-0 flyaways let through against the volume they came from:
//! per polar angle, the mean transmittance of the model's level-0 flyaway voxels
//! (1 − (1 − α)^(ℓ/s), `cpu::flyaways`) along rays from the top plane to the model's
//! surface, against the reference medium's (ratio tracking through the same voxels
//! alone, every other voxel removed, SGGX projected areas) along the same segments.
//!
//! `cargo run --release -p fabric-baker --example flyaway_transmittance MODEL.hyb FABRIC_DIR`

use std::path::Path;

use fabric_baker::reference::medium::{EmptyOrientation, MediumOptions};
use fabric_baker::reference::rng::Rng;
use fabric_baker::reference::tracking::{GridRay, TracedMedium};
use fabric_baker::volume::{MaterialOverrides, load_fabric};
use fabric_runtime::cpu::flyaways::{FlyawayGrid, visit_flyaways};
use fabric_runtime::cpu::heightfield::{HeightTracer, HfTrace};
use fabric_runtime::hybrid::format;
use fabric_runtime::scene::{Ray, direction_from_angles};
use glam::Vec2;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let model = format::read_file(Path::new(&args[1])).expect("read the model");
    let volume = load_fabric(Path::new(&args[2]), &MaterialOverrides::default()).expect("read the fabric");
    let f = model.levels[0].flyaways.as_ref().expect("level 0 has flyaways");
    // Keep only the voxels the model's level 0 holds as flyaways.
    let removed = fabric_baker::prefilter::path_gain::all_but_level0_flyaways(&model, volume.dims());
    let lookup = std::env::var("LOOKUP").map_or(fabric_baker::reference::medium::Lookup::Trilinear, |v| if v == "nearest" { fabric_baker::reference::medium::Lookup::Nearest } else { fabric_baker::reference::medium::Lookup::Trilinear });
    let medium = TracedMedium::new(&volume, MediumOptions { lookup, empty_orientation: EmptyOrientation::Isotropic, periodic: true, mask: Some(&removed) }).expect("the medium");
    let tracer = HeightTracer::new(&model, true);
    let grid = FlyawayGrid::new(&model, 0, true);
    let n = 128u32;
    println!("polar | model T | volume T | model/volume | g that would match");
    for polar in [0.0f32, 20.0, 40.0, 55.0, 65.0, 75.0] {
        let (mut tm, mut tv, mut count) = (Vec::new(), 0.0f64, 0usize);
        for a in 0..4 {
            let wo = direction_from_angles(polar, 22.5 + 45.0 * a as f32);
            for j in 0..n {
                for i in 0..n {
                    let mut rng = Rng::new(7, a as u64, (j * n + i) as u64);
                    let (u, v) = rng.next_2d();
                    let start = model.tile.origin + Vec2::new((i as f32 + u) / n as f32, (j as f32 + v) / n as f32) * model.tile.size;
                    let ray = Ray::new(start.extend(model.tile.top_z), -wo);
                    let mut steps = 0;
                    let HfTrace::Hit(t_end) = tracer.trace(&ray, 0.0, f32::MAX, 0.0, 4096, &mut steps) else { continue };
                    tm.push(visit_flyaways(f, &grid, &ray, 0.0, t_end, 1 << 16, |_, _, _, _| {}).transmittance);
                    let g = GridRay::new(&medium.medium, ray.o, ray.d);
                    tv += medium.transmittance(&g, 0.0, t_end, &mut rng).0 as f64;
                    count += 1;
                }
            }
        }
        let mean_m = tm.iter().map(|&t| t as f64).sum::<f64>() / count as f64;
        let mean_v = tv / count as f64;
        let g = fabric_baker::prefilter::path_gain::solve_gain(&tm, mean_v);
        println!("{polar:5.0} | {mean_m:.4} | {mean_v:.4} | {:.3} | {g:.3}", mean_m / mean_v);
    }
}
