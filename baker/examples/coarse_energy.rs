//! The lobes' albedo bound Σ_j k_j Â_j (`fit::energy`) per level of a model: the bake
//! bounds level 0 and the flyaway entries, not the coarse levels, whose lobes the
//! prefilter fits to their footprints' (baker/FIT_MEASUREMENTS.md, "Energy of the
//! lobes"). Prints, per level, the texels measured (an even stride of at most `SAMPLES`,
//! default 400), the median, the 99th percentile, the worst, and how many exceed 1.
//!
//! `cargo run --release -p fabric-baker --example coarse_energy MODEL.hyb`

use std::collections::HashMap;

use fabric_baker::fit::energy::{LOBE_ALBEDO_MAX, unit_lobe_albedo};
use fabric_runtime::brdf::ClothParams;
use fabric_runtime::hybrid::{Surface, format};
use rayon::prelude::*;

/// Σ_j k_j Â_j, largest channel; Â_j cached by the lobe's shape (β, γ, η, a).
fn albedo(p: &ClothParams, cache: &HashMap<[u32; 4], f32>) -> f32 {
    p.lobes().iter().map(|l| l.k.max(glam::Vec3::ZERO) * cache[&key(l.beta, l.gamma, p.eta, p.a)]).fold(glam::Vec3::ZERO, |s, v| s + v).max_element()
}

fn key(beta: f32, gamma: f32, eta: f32, a: f32) -> [u32; 4] {
    [beta.to_bits(), gamma.to_bits(), eta.to_bits(), a.to_bits()]
}

fn main() {
    let path = std::env::args().nth(1).expect("usage: coarse_energy MODEL.hyb");
    let samples: usize = std::env::var("SAMPLES").ok().and_then(|s| s.parse().ok()).unwrap_or(400);
    let model = format::read_file(std::path::Path::new(&path)).expect("read the model");
    let reading = model.meta.reading;
    println!("level  texels measured  median  p99    worst   above {LOBE_ALBEDO_MAX}");
    for (l, level) in model.levels.iter().enumerate() {
        let params: Vec<ClothParams> = match &level.surface {
            Surface::Clustered { table, .. } => (0..table.headers.len()).map(|i| table.brdf_framed(i).params).collect(),
            Surface::PerTexel(table) => {
                let n = table.headers.len();
                let stride = n.div_ceil(samples.max(1)).max(1);
                (0..n).step_by(stride).map(|i| table.brdf_framed(i).params).collect()
            }
        };
        let mut shapes: Vec<[u32; 4]> = params.iter().flat_map(|p| p.lobes().iter().map(move |lb| key(lb.beta, lb.gamma, p.eta, p.a))).collect();
        shapes.sort();
        shapes.dedup();
        let cache: HashMap<[u32; 4], f32> = shapes
            .par_iter()
            .map(|k| {
                let lobe = fabric_runtime::brdf::ClothLobe { k: glam::Vec3::ONE, beta: f32::from_bits(k[0]), gamma: f32::from_bits(k[1]) };
                (*k, unit_lobe_albedo(&lobe, f32::from_bits(k[2]), f32::from_bits(k[3]), reading))
            })
            .collect();
        let mut a: Vec<f32> = params.iter().map(|p| albedo(p, &cache)).collect();
        a.sort_by(f32::total_cmp);
        let q = |f: f64| a[((a.len() - 1) as f64 * f).round() as usize];
        println!("{l:>5}  {:>15}  {:.3}  {:.3}  {:.3}  {}", a.len(), q(0.5), q(0.99), q(1.0), a.iter().filter(|v| **v > LOBE_ALBEDO_MAX).count());
    }
}
