//! How far a model's level-0 texels rise above the sheet at directions no pair measured:
//! every texel's response (`cpu::shading::texel_response`, no visibility) at 40 000
//! direction pairs, ω_i and ω_o each from a spiral of 400 directions up to 70° from the
//! normal (ω_i every fourth); per pair the brightest texel against the sheet's 99th
//! percentile, and the brightest response of all with its texel's lobes. A lobe the fit
//! never saw near its top shows here as a needle (baker/FIT_MEASUREMENTS.md, "The held
//! reading").
//!
//! With `--against FABRIC_DIR` before a model, the pairs where the model rises highest
//! are also rendered (orthographic, texel-ordered, the bake's held-out measurement) from
//! the volume and from the whole model, so a needle can be told from a glint the
//! truth has too: the brightest pixel and the 99.9th percentile of each, and the error.
//!
//! `--level N` reads level N of the mip chain instead (its texels' BRDFs, no rendering):
//! whether the chain's coarse fits bring needles back.
//!
//! `cargo run --release -p fabric-baker --example lobe_peaks [--level N] [--against DIR] MODEL.hyb...`

use std::path::Path;

use fabric_baker::evaluate::{ViewKind, evaluate_view, reference_medium};
use fabric_baker::fit::directions::{Pair, PairKind};
use fabric_baker::reference::Lookup;
use fabric_baker::volume::{MaterialOverrides, load_fabric};
use fabric_runtime::brdf::{cloth_angles, cloth_lobe_shape};
use fabric_runtime::image::Image;
use fabric_runtime::cpu::shading::texel_response;
use fabric_runtime::hybrid::format;
use glam::Vec3;
use rayon::prelude::*;

fn main() {
    let spiral: Vec<Vec3> = (0..400)
        .map(|k| {
            let z = 1.0 - (k as f32 + 0.5) / 400.0 * (1.0 - 70f32.to_radians().cos());
            let (r, phi) = ((1.0 - z * z).sqrt(), k as f32 * 2.399_963);
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect();
    let pairs: Vec<(Vec3, Vec3)> = spiral.iter().step_by(4).flat_map(|&wi| spiral.iter().map(move |&wo| (wi, wo))).collect();
    let mut against: Option<String> = None;
    let mut level_index = 0usize;
    let mut args = std::env::args().skip(1);
    while let Some(path) = args.next() {
        if path == "--against" {
            against = Some(args.next().expect("--against takes a fabric directory"));
            continue;
        }
        if path == "--level" {
            level_index = args.next().and_then(|s| s.parse().ok()).expect("--level takes a level number");
            continue;
        }
        let model = format::read_file(Path::new(&path)).expect("read the model");
        let Some(level) = model.levels.get(level_index) else {
            eprintln!("{path}: no level {level_index} ({} levels)", model.levels.len());
            continue;
        };
        let brdfs: Vec<_> = (0..level.height).flat_map(|j| (0..level.width).map(move |i| (i, j))).map(|(i, j)| level.texel_brdf(i, j)).collect();
        let (reading, diffuse) = (model.meta.reading, model.meta.diffuse);
        // Per pair: (brightest / p99, brightest, its texel).
        let per_pair: Vec<(f32, f32, usize)> = pairs
            .par_iter()
            .map(|&(wi, wo)| {
                let r: Vec<f32> = brdfs.iter().map(|b| texel_response(b, wi, wo, reading, diffuse).length()).collect();
                let mut sorted = r.clone();
                sorted.sort_by(|a, b| a.total_cmp(b));
                let p99 = sorted[sorted.len() * 99 / 100].max(1e-6);
                let (t, top) = r.iter().enumerate().fold((0, 0.0f32), |best, (t, &v)| if v > best.1 { (t, v) } else { best });
                (top / p99, top, t)
            })
            .collect();
        let mut ratios: Vec<f32> = per_pair.iter().map(|p| p.0).collect();
        ratios.sort_by(|a, b| a.total_cmp(b));
        let n = ratios.len();
        let (k, &(_, top, t)) = per_pair.iter().enumerate().max_by(|a, b| a.1.1.total_cmp(&b.1.1)).expect("pairs");
        println!(
            "{path} level {level_index} ({} reading): brightest texel / the sheet's 99th percentile over {n} pairs: median {:.2}, 99th percentile {:.1}, most {:.0}; pairs above 10x: {}",
            reading.name(),
            ratios[n / 2],
            ratios[n * 99 / 100],
            ratios[n - 1],
            ratios.iter().filter(|r| **r > 10.0).count()
        );
        let (wi, wo) = pairs[k];
        let b = &brdfs[t];
        println!("  brightest response {top:.2} (texel {t}, ω_i {wi:.2}, ω_o {wo:.2}); its lobes:");
        for (l, f) in b.params.lobes().iter().zip(&b.frames) {
            let (ai, ao) = (cloth_angles(f, wi), cloth_angles(f, wo));
            println!(
                "    k {:.2} β {:.3} γ {:.3}: θ_i + θ_o {:.3}, φ_i + φ_o {:.2}, S {:.1} (its peak G(0; β) {:.1})",
                l.k,
                l.beta,
                l.gamma,
                ai.theta + ao.theta,
                ai.phi + ao.phi,
                cloth_lobe_shape(ai.theta + ao.theta, ai.phi + ao.phi, l.beta, l.gamma, reading),
                fabric_runtime::brdf::cloth_gaussian(0.0, l.beta)
            );
        }
        if let (Some(dir), 0) = (&against, level_index) {
            render_worst(dir, &model, &pairs, &per_pair);
        }
    }
}

/// The model's six highest pairs (by brightest response, at least 20° apart in ω_i or
/// ω_o) rendered from the volume and the model, 64 spp.
fn render_worst(dir: &str, model: &fabric_runtime::hybrid::HybridModel, pairs: &[(Vec3, Vec3)], per_pair: &[(f32, f32, usize)]) {
    let volume = load_fabric(Path::new(dir), &MaterialOverrides::default()).expect("read the fabric");
    let medium = reference_medium(&volume, Lookup::Trilinear).expect("medium");
    let mut order: Vec<usize> = (0..pairs.len()).collect();
    order.sort_by(|a, b| per_pair[*b].1.total_cmp(&per_pair[*a].1));
    let far = 20f32.to_radians().cos();
    let mut chosen: Vec<usize> = Vec::new();
    for k in order {
        let (wi, wo) = pairs[k];
        if chosen.iter().all(|&c| pairs[c].0.dot(wi) < far || pairs[c].1.dot(wo) < far) {
            chosen.push(k);
        }
        if chosen.len() == 6 {
            break;
        }
    }
    let stats = |im: &Image| {
        let mut v: Vec<f32> = im.pixels.iter().map(|p| (p.x + p.y + p.z) / 3.0).collect();
        v.sort_by(|a, b| a.total_cmp(b));
        (v[v.len() - 1], v[v.len() * 999 / 1000])
    };
    for k in chosen {
        let (wi, wo) = pairs[k];
        let pair = Pair { wi, wo, kind: PairKind::Stratified };
        let (e, images) = evaluate_view(&volume, &medium, model, &pair, ViewKind::Orthographic, model.width(), 64, 11 + k as u64, 0.0).expect("view");
        let ((rmax, r999), (mmax, m999)) = (stats(&images.reference), stats(&images.model));
        println!(
            "  pair ω_i {wi:.2} ω_o {wo:.2} (texel response {:.2}): truth max {rmax:.3}, 99.9% {r999:.3}; model max {mmax:.3}, 99.9% {m999:.3}; 4x4 {:.1}%, px {:.1}%, mean ratio {:.3}",
            per_pair[k].1,
            100.0 * e.block_error,
            100.0 * e.pixel_error,
            e.mean_ratio
        );
    }
}
