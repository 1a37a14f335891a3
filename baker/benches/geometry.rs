//! Stage times of geometry extraction (`fabric_baker::geometry`) on the generator's
//! presets, printed, not asserted.
//!
//! `cargo bench -p fabric-baker --bench geometry [-- SIZE... PRESET...]`, SIZE like
//! 256x256x48 (default: 256x256x48 and 1024x1024x128), PRESET among plain, twill,
//! satin, silk, felt (default: all). Generation (seed 1) is not part of the timings.

use std::time::Instant;

use fabric_baker::generate::{Preset, generate};
use fabric_baker::geometry::{Geometry, GeometryOptions, extract_geometry};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with('-')).collect();
    let mut sizes: Vec<[usize; 3]> = args
        .iter()
        .filter_map(|a| {
            let v: Vec<usize> = a.split('x').filter_map(|p| p.parse().ok()).collect();
            (v.len() == 3).then(|| [v[0], v[1], v[2]])
        })
        .collect();
    if sizes.is_empty() {
        sizes = vec![[256, 256, 48], [1024, 1024, 128]];
    }
    let mut presets: Vec<Preset> = args.iter().filter_map(|a| a.parse().ok()).collect();
    if presets.is_empty() {
        presets = Preset::ALL.to_vec();
    }
    println!("rayon threads: {}", rayon::current_num_threads());
    for dims in sizes {
        println!("\n{}x{}x{}", dims[0], dims[1], dims[2]);
        for &preset in &presets {
            let t = Instant::now();
            let vol = match generate(&preset.params(), dims, 1) {
                Ok(v) => v,
                Err(e) => {
                    println!("  {}: cannot generate: {e}", preset.name());
                    continue;
                }
            };
            let generated = t.elapsed().as_secs_f64();
            let t = Instant::now();
            let g = match extract_geometry(&vol, &GeometryOptions::default()) {
                Ok(g) => g,
                Err(e) => {
                    println!("  {}: extraction failed: {e}", preset.name());
                    continue;
                }
            };
            let total = t.elapsed().as_secs_f64();
            let stages: Vec<String> = g.stage_times.iter().map(|s| format!("{} {:.3}", s.stage, s.seconds)).collect();
            println!("  {:<6} extraction {total:.2} s (generation {generated:.1} s): {}", preset.name(), stages.join(", "));
            let [lo, hi] = Geometry::range(&g.h0);
            println!(
                "         filter {:.1} x {:.1} ({}), fiber {:.2} vox ({}), V {} voxels ({:.2}% of the volume), holes {}, filled {}, h0 [{lo:.1}, {hi:.1}]",
                g.filter_size[0],
                g.filter_size[1],
                if g.filter_auto { "auto" } else { "fixed" },
                g.fiber_thickness,
                if g.fiber_thickness_auto { "estimated" } else { "default" },
                g.flyaways.len(),
                100.0 * g.flyaways.len() as f64 / (dims[0] * dims[1] * dims[2]) as f64,
                g.hole_columns,
                g.filled_columns,
            );
        }
    }
}
