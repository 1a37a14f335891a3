//! What a held-out view's error is made of: for each orthographic held-out view of a
//! bake report, the relative RMSE over 4×4 blocks of the model against the reference
//! as is, after the best global scale, after the best shift of the model image by
//! whole pixels (up to ±4), and after both; beside it the reference against itself
//! shifted by one pixel (how sensitive the figure is to misregistration).
//!
//! `cargo run --release -p fabric-baker --example held_out_anatomy MODEL.hyb FABRIC_DIR REPORT.json [SPP]`

use std::path::Path;

use fabric_baker::bake::block_mean;
use fabric_baker::evaluate::{ViewKind, reference_medium, view};
use fabric_baker::fit::directions::{Pair, PairKind};
use fabric_baker::reference::{Lookup, RenderSettings};
use fabric_baker::volume::{MaterialOverrides, load_fabric};
use fabric_runtime::cpu::{CpuRenderOptions, render};
use fabric_runtime::hybrid::format;
use fabric_runtime::image::Image;
use glam::Vec3;

/// ‖s·A(x + d) − B(x)‖ / ‖B‖ over 4×4 blocks of the interior (a 4-pixel border left out).
fn err(a: &Image, b: &Image, d: (i32, i32), s: f32) -> f64 {
    let shifted = Image::from_fn(a.width, a.height, |x, y| {
        let (sx, sy) = ((x as i32 + d.0).clamp(0, a.width as i32 - 1), (y as i32 + d.1).clamp(0, a.height as i32 - 1));
        a.get(sx as u32, sy as u32) * s
    });
    let crop = |i: &Image| Image::from_fn(i.width - 8, i.height - 8, |x, y| i.get(x + 4, y + 4));
    let (ba, bb) = (block_mean(&crop(&shifted), 4), block_mean(&crop(b), 4));
    let (mut n, mut r) = (0f64, 0f64);
    for (p, q) in ba.pixels.iter().zip(&bb.pixels) {
        n += (*p - *q).as_dvec3().length_squared();
        r += q.as_dvec3().length_squared();
    }
    (n / r).sqrt()
}

fn best_scale(a: &Image, b: &Image) -> f32 {
    let (mut ab, mut aa) = (0f64, 0f64);
    for (p, q) in a.pixels.iter().zip(&b.pixels) {
        ab += p.as_dvec3().dot(q.as_dvec3());
        aa += p.as_dvec3().length_squared();
    }
    (ab / aa.max(1e-30)) as f32
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let model = format::read_file(Path::new(&args[1])).expect("read the model");
    let volume = load_fabric(Path::new(&args[2]), &MaterialOverrides::default()).expect("read the fabric");
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&args[3]).expect("read the report")).expect("parse the report");
    let spp: u32 = args.get(4).map(|s| s.parse().expect("SPP")).unwrap_or(32);
    let medium = reference_medium(&volume, Lookup::Trilinear).expect("medium");
    println!("view | as is | scaled (s) | shifted (dx,dy) | both | ref vs ref shifted 1 px x / y");
    for (k, v) in report["held_out"].as_array().expect("held_out views").iter().enumerate() {
        if v["kind"] != "orthographic" {
            continue;
        }
        let vec = |x: &serde_json::Value| Vec3::new(x[0].as_f64().unwrap() as f32, x[1].as_f64().unwrap() as f32, x[2].as_f64().unwrap() as f32);
        let pair = Pair { kind: PairKind::Stratified, wi: vec(&v["pair"]["wi"]), wo: vec(&v["pair"]["wo"]) };
        let (camera, light) = view(&volume, &pair, ViewKind::Orthographic, model.width());
        let (reference, _) = fabric_baker::reference::render(&medium, &camera, &(&light).into(), &RenderSettings { spp, seed: 7, ..Default::default() }, None).expect("reference");
        let m = render(&model, &camera, &[light], &CpuRenderOptions { periodic: true, supersampling: 4, ..Default::default() }).expect("model");
        let s = best_scale(&m, &reference);
        let mut best = ((0, 0), f64::MAX);
        let mut best_both = f64::MAX;
        for dy in -4..=4 {
            for dx in -4..=4 {
                let e = err(&m, &reference, (dx, dy), 1.0);
                if e < best.1 {
                    best = ((dx, dy), e);
                }
                best_both = best_both.min(err(&m, &reference, (dx, dy), best_scale(&m, &reference)));
            }
        }
        println!(
            "{k} | {:.1}% | {:.1}% ({s:.3}) | {:.1}% ({},{}) | {:.1}% | {:.1}% / {:.1}%",
            100.0 * err(&m, &reference, (0, 0), 1.0),
            100.0 * err(&m, &reference, (0, 0), s),
            100.0 * best.1,
            best.0.0,
            best.0.1,
            100.0 * best_both,
            100.0 * err(&reference, &reference, (1, 0), 1.0),
            100.0 * err(&reference, &reference, (0, 1), 1.0),
        );
    }
}
