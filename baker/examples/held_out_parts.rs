//! What a baked model's held-out views are made of: for each orthographic held-out view
//! of a bake report, the model's mean radiance as baked, without the height field's
//! shadowing, without flyaways, and split into its diffuse and lobe parts, against the
//! reference's mean (from the report's mean ratio), with the fraction of near-black
//! pixels (below 5% of the reference's mean).
//!
//! `cargo run --release -p fabric-baker --example held_out_parts MODEL.hyb FABRIC_DIR REPORT.json`

use std::path::Path;

use fabric_baker::evaluate::{ViewKind, view};
use fabric_baker::fit::directions::{Pair, PairKind};
use fabric_baker::volume::{MaterialOverrides, load_fabric};
use fabric_runtime::brdf::cloth_angles;
use fabric_runtime::cpu::shading::texel_response;
use fabric_runtime::cpu::{CpuRenderOptions, Scene, ShadowMode, render};
use fabric_runtime::hybrid::{HybridModel, Surface, format};
use fabric_runtime::image::Image;
use glam::Vec3;

fn lum(v: Vec3) -> f64 {
    (v.x + v.y + v.z) as f64 / 3.0
}

fn mean(i: &Image) -> f64 {
    i.pixels.iter().map(|p| lum(*p)).sum::<f64>() / i.pixels.len() as f64
}

/// The model with its level-0 diffuse terms (or lobes) scaled by `kd` (`k`).
fn scaled(model: &HybridModel, kd: f32, k: f32) -> HybridModel {
    let mut m = model.clone();
    let (Surface::PerTexel(t) | Surface::Clustered { table: t, .. }) = &mut m.levels[0].surface;
    {
        for h in t.headers.iter_mut() {
            h.kd = (h.kd() * kd).to_array().map(|v| half::f16::from_f32(v).to_bits());
        }
        for l in t.lobes.iter_mut() {
            let mut lobe = l.lobe();
            lobe.k *= k;
            let frame = l.frame();
            *l = fabric_runtime::hybrid::PackedLobe::new(&lobe, Some((frame.n, frame.t)));
        }
    }
    m
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let model = format::read_file(Path::new(&args[1])).expect("read the model");
    let volume = load_fabric(Path::new(&args[2]), &MaterialOverrides::default()).expect("read the fabric");
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&args[3]).expect("read the report")).expect("parse the report");
    let views = report["held_out"].as_array().expect("held_out views");
    let diffuse = scaled(&model, 1.0, 0.0);
    let lobes = scaled(&model, 0.0, 1.0);
    let mut no_fly = model.clone();
    for l in no_fly.levels.iter_mut() {
        l.flyaways = None;
    }
    println!("view  wi(θ,φ)  wo(θ,φ)  | reference | as baked  no shadows  no flyaways | diffuse  lobes | black px");
    for (k, v) in views.iter().enumerate() {
        if v["kind"] != "orthographic" {
            continue;
        }
        let vec = |x: &serde_json::Value| Vec3::new(x[0].as_f64().unwrap() as f32, x[1].as_f64().unwrap() as f32, x[2].as_f64().unwrap() as f32);
        let pair = Pair { kind: PairKind::Stratified, wi: vec(&v["pair"]["wi"]), wo: vec(&v["pair"]["wo"]) };
        let (camera, light) = view(&volume, &pair, ViewKind::Orthographic, model.width());
        let options = CpuRenderOptions { periodic: true, supersampling: 4, ..Default::default() };
        let draw = |m: &HybridModel, o: &CpuRenderOptions| render(m, &camera, &[light], o).expect("render");
        let base = draw(&model, &options);
        let reference = mean(&base) / v["mean_ratio"].as_f64().unwrap();
        let unshadowed = draw(&model, &CpuRenderOptions { shadows: ShadowMode::Off, ..options.clone() });
        let black = base.pixels.iter().filter(|p| lum(**p) < 0.05 * reference).count() as f64 / base.pixels.len() as f64;
        let angles = |w: Vec3| (w.z.acos().to_degrees(), w.y.atan2(w.x).to_degrees());
        let (ti, pi) = angles(pair.wi);
        let (to, po) = angles(pair.wo);
        println!(
            "{k}  ({ti:4.1},{pi:6.1}) ({to:4.1},{po:6.1}) | {reference:.4} | {:.3}  {:.3}  {:.3} | {:.3}  {:.3} | {:.1}%",
            mean(&base) / reference,
            mean(&unshadowed) / reference,
            mean(&draw(&no_fly, &options)) / reference,
            mean(&draw(&diffuse, &options)) / reference,
            mean(&draw(&lobes, &options)) / reference,
            100.0 * black
        );
        // Why pixels are dark: at each pixel centre's hit, split by cause.
        let lights = [light];
        let scene = Scene::for_rays(&no_fly, &lights, CpuRenderOptions { periodic: true, ..Default::default() }).expect("scene");
        let (mut n, mut shadowed, mut facing_away, mut lobe_miss, mut lit_sum) = (0usize, 0usize, 0usize, 0usize, 0f64);
        let mut thetas: Vec<f32> = Vec::new();
        for py in 0..camera.height {
            for px in 0..camera.width {
                let ray = camera.ray(px as f32 + 0.5, py as f32 + 0.5);
                let Some(hit) = scene.probe_ray(&ray, 0, false).surface else { continue };
                n += 1;
                let b = no_fly.levels[0].texel_brdf(hit.texel.0, hit.texel.1);
                let wo = -ray.d;
                let f = texel_response(&b, pair.wi, wo, no_fly.meta.reading, no_fly.meta.diffuse);
                lit_sum += lum(f * hit.visibility);
                if lum(f * hit.visibility) >= 0.05 * reference {
                    continue;
                }
                if hit.visibility < 0.5 {
                    shadowed += 1;
                } else if b.frames[0].n.dot(pair.wi) <= 0.05 {
                    facing_away += 1;
                } else {
                    lobe_miss += 1;
                    let ai = cloth_angles(&b.frames[0], pair.wi);
                    let ao = cloth_angles(&b.frames[0], wo);
                    thetas.push((ai.theta + ao.theta).abs().to_degrees());
                }
            }
        }
        thetas.sort_by(f32::total_cmp);
        let q = |f: f32| thetas.get((f * thetas.len() as f32) as usize).copied().unwrap_or(0.0);
        let pct = |c: usize| 100.0 * c as f64 / n.max(1) as f64;
        println!(
            "     dark hits (centre rays, no flyaways; mean {:.3} of reference): shadowed {:.1}%, facing away {:.1}%, lobe missed {:.1}% (|θ_i+θ_o| median {:.1}°, p90 {:.1}°)",
            lit_sum / n.max(1) as f64 / reference,
            pct(shadowed),
            pct(facing_away),
            pct(lobe_miss),
            q(0.5),
            q(0.9)
        );
    }
}
