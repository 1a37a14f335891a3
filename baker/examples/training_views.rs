//! The held-out measurement taken at training pairs: how far the whole model (flyaways
//! in, rendered by the CPU renderer) is from the whole volume where the fit saw the
//! light and viewer, against the bake's training figure (surface alone, through the probe).
//!
//! `cargo run --release -p fabric-baker --example training_views MODEL.hyb FABRIC_DIR [PAIRS] [SPP]`

use std::path::Path;

use fabric_baker::evaluate::{ViewKind, evaluate_view, reference_medium};
use fabric_baker::fit::directions::{PairOptions, training_pairs};
use fabric_baker::reference::Lookup;
use fabric_baker::volume::{MaterialOverrides, load_fabric};
use fabric_runtime::hybrid::format;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let model = format::read_file(Path::new(&args[1])).expect("read the model");
    let volume = load_fabric(Path::new(&args[2]), &MaterialOverrides::default()).expect("read the fabric");
    let count: usize = args.get(3).map_or(40, |s| s.parse().expect("pairs"));
    let spp: u32 = args.get(4).map_or(32, |s| s.parse().expect("spp"));
    let medium = reference_medium(&volume, Lookup::Trilinear).expect("medium");
    let pairs = training_pairs(&PairOptions { count, ..Default::default() });
    let mut no_fly = model.clone();
    for l in no_fly.levels.iter_mut() {
        l.flyaways = None;
    }
    let step = std::env::var("STEP").ok().and_then(|s| s.parse().ok()).unwrap_or(5usize);
    for (k, p) in pairs.iter().enumerate().step_by(step) {
        let (e, _) = evaluate_view(&volume, &medium, &model, p, ViewKind::Orthographic, model.width(), spp, 7 + k as u64, 0.0).expect("view");
        let (f, _) = evaluate_view(&volume, &medium, &no_fly, p, ViewKind::Orthographic, model.width(), spp, 7 + k as u64, 0.0).expect("view");
        let ang = |w: glam::Vec3| (w.z.acos().to_degrees(), w.y.atan2(w.x).to_degrees());
        println!(
            "pair {k:2} {:?} wi ({:4.1},{:6.1}) wo ({:4.1},{:6.1}): block {:5.1}% px {:5.1}% b16 {:5.1}% ratio {:.3} noise {:.1}% | no flyaways: block {:5.1}% ratio {:.3}",
            p.kind,
            ang(p.wi).0,
            ang(p.wi).1,
            ang(p.wo).0,
            ang(p.wo).1,
            100.0 * e.block_error,
            100.0 * e.pixel_error,
            100.0 * e.block16_error,
            e.mean_ratio,
            100.0 * e.reference_noise,
            100.0 * f.block_error,
            f.mean_ratio
        );
    }
}
