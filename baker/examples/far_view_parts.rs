//! Where a mip chain's far-view error comes from: the far views of
//! `baker/src/prefilter/far_view.rs` for a model as it is, with its flyaways taken out
//! of every level (truth included), and with its surface made black (the flyaways
//! alone), each with the chain's mean over the truth's (baker/PREFILTER_MEASUREMENTS.md,
//! "Grazing views").
//!
//! `cargo run --release -p fabric-baker --example far_view_parts MODEL.hyb [PIXELS]`;
//! with `LEVELS=1` also each fixed level at 8×8 samples per pixel, `OPACITY=1` the mean
//! flyaway opacity per level (`OPACITY_ONLY=1`: that alone), `AS_IS_ONLY=1` the model as it is alone, `FINE=1` with `--coarse-filter fine`, `SWEEP=1` the distance sweep alone (`PART=surface` or `PART=flyaways` for one part; `SWEEP_SS=1` its three nearest steps with the chain at 1, 2² and 4² samples per pixel), `NODES=1` the flyaway
//! nodes' responses at 70°.

use fabric_baker::prefilter::far_view::{far_camera, far_light};
use fabric_runtime::cpu::{CoarseFilter, CpuRenderOptions, LevelChoice, render};
use fabric_runtime::hybrid::{HybridModel, format};
use fabric_runtime::image::Image;
use fabric_runtime::metrics::relative_rmse;

fn mean(im: &Image) -> f64 {
    im.mean()
}

fn views(model: &HybridModel, pixels: u32, label: &str) {
    let light = [far_light()];
    for polar in [0.0f32, 45.0, 70.0] {
        let camera = far_camera(model, polar, pixels);
        let tpp = model.width() as f32 / pixels as f32 / polar.to_radians().cos().max(0.1);
        let f = ((tpp * 4.0 / 16.0).ceil() as u32).clamp(1, 64);
        let big = fabric_runtime::scene::Camera { width: camera.width * f, height: camera.height * f, ..camera };
        let coarse_filter = if std::env::var("FINE").is_ok() { CoarseFilter::Fine } else { CoarseFilter::Box };
        let opt = |level, ss| CpuRenderOptions { level, periodic: true, supersampling: ss, coarse_filter, ..Default::default() };
        let truth = render(model, &big, &light, &opt(LevelChoice::Fixed(0), 16)).unwrap().box_downsample(f);
        let chain = render(model, &camera, &light, &opt(LevelChoice::Auto { bias: 0.0 }, 1)).unwrap();
        let chain_ss = render(model, &camera, &light, &opt(LevelChoice::Auto { bias: 0.0 }, 8)).unwrap();
        let e = relative_rmse(&chain, &truth).unwrap();
        let e_ss = relative_rmse(&chain_ss, &truth).unwrap();
        println!("{label} {pixels}px polar {polar:>4}: chain {:.1}%  chain 8x8spp {:.1}% (mean {:.3})  mean chain/truth {:.3}", 100.0 * e, 100.0 * e_ss, mean(&chain_ss) / mean(&truth), mean(&chain) / mean(&truth));
        if std::env::var("LEVELS").is_ok() {
            for level in 0..model.levels.len().min(6) {
                let im = render(model, &camera, &light, &opt(LevelChoice::Fixed(level as u32), 8)).unwrap();
                println!("    level {level} at 8x8 spp: {:.1}%  mean/truth {:.3}", 100.0 * relative_rmse(&im, &truth).unwrap(), mean(&im) / mean(&truth));
            }
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let model = format::read_file(std::path::Path::new(&args[1])).expect("read the model");
    let pixels = args.get(2).map_or(16, |s| s.parse().unwrap());
    if std::env::var("SWEEP").is_ok() {
        // `PART=surface`: flyaways out of every level, truth included; `PART=flyaways`:
        // the surface black.
        let model = match std::env::var("PART").as_deref() {
            Ok("surface") => without_flyaways(&model),
            Ok("flyaways") => surface_black(&model),
            _ => model,
        };
        if std::env::var("SWEEP_SS").is_ok() {
            sweep_supersampled(&model);
            return;
        }
        for s in fabric_baker::prefilter::far_view::distance_sweep(&model, 32, 8).expect("the sweep") {
            println!("sweep {:5.2} texels/px: chain {:.2}%  level 0 at 1 spp {:.2}%", s.texels_per_pixel, 100.0 * s.chain, 100.0 * s.level0);
        }
        return;
    }
    if std::env::var("OPACITY_ONLY").is_ok() {
        for polar in [0.0, 45.0, 70.0] {
            opacity_by_level(&model, polar);
        }
        return;
    }
    views(&model, pixels, "as it is     ");
    if std::env::var("AS_IS_ONLY").is_ok() {
        return;
    }
    views(&without_flyaways(&model), pixels, "no flyaways  ");
    views(&surface_black(&model), pixels, "flyaways only");
    if std::env::var("NODES").is_ok() {
        node_responses(&model);
    }
    if std::env::var("OPACITY").is_ok() {
        for polar in [0.0, 45.0, 70.0] {
            opacity_by_level(&model, polar);
        }
    }
}

fn without_flyaways(model: &HybridModel) -> HybridModel {
    let mut bare = model.clone();
    for l in bare.levels.iter_mut() {
        l.flyaways = None;
    }
    bare
}

/// The surface black: what the flyaways alone bring.
fn surface_black(model: &HybridModel) -> HybridModel {
    let mut dark = model.clone();
    for l in dark.levels.iter_mut() {
        let table = match &mut l.surface {
            fabric_runtime::hybrid::Surface::PerTexel(t) => t,
            fabric_runtime::hybrid::Surface::Clustered { table, .. } => table,
        };
        table.headers.iter_mut().for_each(|h| h.kd = [0; 3]);
        table.lobes.iter_mut().for_each(|l| l.k = [0; 3]);
        l.transmission = None;
    }
    dark
}

/// Mean flyaway opacity seen along the far view's rays, per fixed level.
pub fn opacity_by_level(model: &HybridModel, polar: f32) {
    use fabric_runtime::cpu::Scene;
    let camera = far_camera(model, polar, 16);
    let light = [far_light()];
    let options = CpuRenderOptions { periodic: true, ..Default::default() };
    let scene = Scene::new(model, &camera, &light, options).unwrap();
    let n = 128u32;
    let mut line = format!("  opacity at {polar}°:");
    for level in 0..model.levels.len().min(6) {
        let mut sum = 0.0f64;
        for y in 0..n {
            for x in 0..n {
                let ray = camera.ray((x as f32 + 0.5) * 16.0 / n as f32, (y as f32 + 0.5) * 16.0 / n as f32);
                sum += scene.trace_ray(&ray, level).flyaway_opacity as f64;
            }
        }
        line += &format!(" L{level} {:.3}", sum / (n * n) as f64);
    }
    println!("{line}");
}

/// The flyaway nodes' responses at the far view's 70° and light, per level.
pub fn node_responses(model: &HybridModel) {
    use fabric_runtime::cpu::shading::{in_fiber_frame, texel_response};
    let wo = fabric_runtime::scene::direction_from_angles(70.0, fabric_baker::prefilter::far_view::VIEW_AZIMUTH);
    let wi = far_light().sample(glam::Vec3::ZERO).wi;
    for (level, l) in model.levels.iter().enumerate().take(6) {
        let Some(f) = &l.flyaways else { continue };
        let (mut sum, mut lit) = (0.0f64, 0usize);
        for node in &f.nodes {
            let b = in_fiber_frame(f.table.brdf_in_frame(node.param as usize, fabric_runtime::brdf::cloth_frame(glam::Vec3::Z, glam::Vec3::X)), node.tangent(), wo);
            let r = texel_response(&b, wi, wo, model.meta.reading, fabric_runtime::brdf::DiffuseLaw::Lambert);
            sum += (r.x + r.y + r.z) as f64 / 3.0;
            lit += (r.max_element() > 0.0) as usize;
        }
        let p = f.table.brdf_in_frame(0, fabric_runtime::brdf::cloth_frame(glam::Vec3::Z, glam::Vec3::X)).params;
        println!("  level {level}: {} nodes, mean response {:.4}, {} lit; entry 0: kd {:.3} a {:.2} eta {:.2} lobes {:?}", f.nodes.len(), sum / f.nodes.len() as f64, lit, p.kd, p.a, p.eta, &p.lobes[..p.lobe_count as usize]);
    }
}

/// The sweep's three nearest steps with the chain at 1, 2 and 4² samples per pixel:
/// whether what is left there is aliasing (falls with samples) or bias (does not).
fn sweep_supersampled(model: &HybridModel) {
    use fabric_runtime::scene::{Camera, Projection, direction_from_angles};
    use glam::Vec3;
    let b = model.bounds();
    let centre = Vec3::new(0.5 * (b.min.x + b.max.x), 0.5 * (b.min.y + b.max.y), model.tile.top_z);
    let (fov, pixels) = (40f32, 32u32);
    let pixel_at = 2.0 * (0.5 * fov).to_radians().tan() / pixels as f32;
    let light = [far_light()];
    for texels in [0.5f32, 0.91, 1.64] {
        let d = texels * model.texel_size().x / pixel_at;
        let dir = direction_from_angles(45.0, fabric_baker::prefilter::far_view::VIEW_AZIMUTH);
        let camera = Camera { origin: centre + d * dir, target: centre, up: Vec3::Z, projection: Projection::Perspective { fov_x_deg: fov }, width: pixels, height: pixels };
        let f = ((1.6 * texels * std::f32::consts::SQRT_2 * 4.0 / 16.0).ceil() as u32).clamp(1, 64);
        let big = Camera { width: pixels * f, height: pixels * f, ..camera };
        let opt = |level, ss| CpuRenderOptions { level, periodic: true, supersampling: ss, ..Default::default() };
        let truth = render(model, &big, &light, &opt(LevelChoice::Fixed(0), 16)).unwrap().box_downsample(f);
        let mut line = format!("{texels:.2} texels/px:");
        for ss in [1u32, 2, 4] {
            let chain = render(model, &camera, &light, &opt(LevelChoice::Auto { bias: 0.0 }, ss)).unwrap();
            let l0 = render(model, &camera, &light, &opt(LevelChoice::Fixed(0), ss)).unwrap();
            line += &format!("  {ss}x{ss}: chain {:.2}% level0 {:.2}% (chain mean/truth {:.3})", 100.0 * relative_rmse(&chain, &truth).unwrap(), 100.0 * relative_rmse(&l0, &truth).unwrap(), mean(&chain) / mean(&truth));
        }
        println!("{line}");
    }
}
