//! Where a mip chain's far-view error comes from: the far views of
//! `baker/src/prefilter/far_view.rs` for a model as it is, with its flyaways taken out
//! of every level (truth included), and with its surface made black (the flyaways
//! alone), each with the chain's mean over the truth's (baker/PREFILTER_MEASUREMENTS.md,
//! "Grazing views").
//!
//! `cargo run --release -p fabric-baker --example far_view_parts MODEL.hyb [PIXELS]`;
//! with `LEVELS=1` also each fixed level at 8×8 samples per pixel, `OPACITY=1` the mean
//! flyaway opacity per level (`OPACITY_ONLY=1`: that alone, `OPACITY_POLARS=0,30,…` at those angles), `AS_IS_ONLY=1` the model as it is alone (`CHAIN_ONLY=1`: without the supersampled chains), `FINE=1` with `--coarse-filter fine` (with `SWEEP=1` too, every filter but `bilinear`, `SWEEP_FILTERS=a,b` those; `SPLIT=1`: `split`, `SHADED=1`: `split-shaded`), `AZIMUTH=deg` the far views' azimuth (0: pixel rows along the tile), `PART=surface` or `PART=flyaways` one part alone (`PART=through`: the flyaways black, the surface through and under them) (also with `SWEEP=1`), `SWEEP=1` the distance sweep alone (`SWEEP_AT=0.3,0.4`: steps at those texels per pixel instead;  `SWEEP_SS=1` its three nearest steps with the chain at 1, 2² and 4² samples per pixel; `SWEEP_LEVELS=4,32` at those steps the chain's mean over the truth's, its error at the truth's mean, and each fixed level at 4 × 4 samples per pixel), `IMAGES=DIR` a picture per far view (truth | chain | difference), `NODES=1` the flyaway
//! nodes' responses at 70°; `OPACITY_IMAGES=POLAR` each fixed level's flyaway opacity and
//! colour per pixel against level 0's; `ORACLE=POLAR` each fixed level with its coarse
//! flyaway nodes shaded other ways (with `QUAD=1`, `SPLIT="q,c;…"`, `CHOOSE=1`,
//! `KMEANS=1,2,… [GROUP_CONES=1] [PLAIN=1]`; baker/PREFILTER_MEASUREMENTS.md, "What the
//! coarse flyaways get wrong"); `DEPTHS=POLAR` each coarse level's flyaway weights against
//! its level-0 children's, by depth, by axis against the view and by α ("Where the 70°
//! flyaway error lies").

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
        // `AZIMUTH=deg`: the view's azimuth (0: pixel rows along the tile's axes).
        let camera = match std::env::var("AZIMUTH") {
            Ok(a) => fabric_baker::prefilter::far_view::far_camera_at(model, polar, a.parse().expect("AZIMUTH in degrees"), pixels),
            Err(_) => far_camera(model, polar, pixels),
        };
        let tpp = model.width() as f32 / pixels as f32 / polar.to_radians().cos().max(0.1);
        let f = ((tpp * 4.0 / 16.0).ceil() as u32).clamp(1, 64);
        let big = fabric_runtime::scene::Camera { width: camera.width * f, height: camera.height * f, ..camera };
        let coarse_filter = if std::env::var("SHADED").is_ok() { CoarseFilter::SplitShaded } else if std::env::var("SPLIT").is_ok() { CoarseFilter::Split } else if std::env::var("FINE").is_ok() { CoarseFilter::Fine } else { CoarseFilter::Box };
        let opt = |level, ss| CpuRenderOptions { level, periodic: true, supersampling: ss, coarse_filter, ..Default::default() };
        let truth = render(model, &big, &light, &opt(LevelChoice::Fixed(0), 16)).unwrap().box_downsample(f);
        let chain = render(model, &camera, &light, &opt(LevelChoice::Auto { bias: 0.0 }, 1)).unwrap();
        // `CHAIN_ONLY=1`: the chain at one sample alone (the other columns repeat it).
        let ss = |s: u32| if std::env::var("CHAIN_ONLY").is_ok() { chain.clone() } else { render(model, &camera, &light, &opt(LevelChoice::Auto { bias: 0.0 }, s)).unwrap() };
        let chain_ss = ss(8);
        let chain_2 = ss(2);
        let e = relative_rmse(&chain, &truth).unwrap();
        if let Ok(dir) = std::env::var("IMAGES") {
            // `IMAGES=DIR`: truth, chain and their difference per view, as EXR-free PNGs.
            let tag = format!("{dir}/{}_{pixels}_{polar}", label.trim().replace(' ', "_"));
            let m = mean(&truth) as f32;
            // Side by side, 8× nearest: truth | chain | difference (grey = 0, ±mean = black / white).
            let (w, h, z) = (truth.width, truth.height, 8u32);
            let strip = Image::from_fn(3 * w * z + 2 * z, h * z, |x, y| {
                let (panel, px, py) = (x / (w * z + z), (x % (w * z + z)) / z, y / z);
                if px >= w {
                    return glam::Vec3::ONE;
                }
                let (t, c) = (truth.get(px, py), chain.get(px, py));
                match panel {
                    0 => 0.5 * t / m.max(1e-6),
                    1 => 0.5 * c / m.max(1e-6),
                    _ => glam::Vec3::splat(0.5) + 0.5 * (c - t) / m.max(1e-6),
                }
            });
            strip.write(std::path::Path::new(&format!("{tag}.png")), 1.0).unwrap();
        }
        let e_ss = relative_rmse(&chain_ss, &truth).unwrap();
        let e_2 = relative_rmse(&chain_2, &truth).unwrap();
        println!("{label} {pixels}px polar {polar:>4}: chain {:.1}%  chain 2x2spp {:.1}%  chain 8x8spp {:.1}% (mean {:.3})  mean chain/truth {:.3}", 100.0 * e, 100.0 * e_2, 100.0 * e_ss, mean(&chain_ss) / mean(&truth), mean(&chain) / mean(&truth));
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
            Ok("through") => flyaways_black(&model),
            _ => model,
        };
        if let Ok(list) = std::env::var("SWEEP_LEVELS") {
            sweep_levels(&model, &list);
            return;
        }
        if std::env::var("SWEEP_SS").is_ok() {
            sweep_supersampled(&model);
            return;
        }
        // `FINE=1`: the sweep's eight steps with every `--coarse-filter` but `bilinear`
        // (`SWEEP_FILTERS=split,split-shaded`: those).
        if std::env::var("FINE").is_ok() {
            use fabric_baker::prefilter::far_view::distance_sweep_filtered;
            let names = std::env::var("SWEEP_FILTERS").unwrap_or_else(|_| "fine,box,split,split-shaded".into());
            let sweeps: Vec<(&str, Vec<_>)> = names.split(',').map(|n| (n, distance_sweep_filtered(&model, 32, 8, CoarseFilter::from_name(n).expect("SWEEP_FILTERS: coarse filter names")).expect("the sweep"))).collect();
            for step in 0..sweeps[0].1.len() {
                let columns: Vec<String> = sweeps.iter().map(|(n, s)| format!("({n}) {:.2}%", 100.0 * s[step].chain)).collect();
                println!("sweep {:5.2} texels/px: chain {}", sweeps[0].1[step].texels_per_pixel, columns.join("  "));
            }
            return;
        }
        // `SWEEP_AT=0.3,0.4`: steps at these texels per pixel instead of the sweep's eight.
        let steps = match std::env::var("SWEEP_AT") {
            Ok(list) => list.split(',').map(|t| fabric_baker::prefilter::far_view::sweep_step(&model, 32, t.trim().parse().expect("SWEEP_AT: texels per pixel, comma-separated"))).collect(),
            Err(_) => fabric_baker::prefilter::far_view::distance_sweep(&model, 32, 8),
        };
        for s in steps.expect("the sweep") {
            println!("sweep {:5.2} texels/px: chain {:.2}%  level 0 at 1 spp {:.2}%", s.texels_per_pixel, 100.0 * s.chain, 100.0 * s.level0);
        }
        return;
    }
    if let Ok(polar) = std::env::var("DEPTHS") {
        depth_weights(&model, polar.parse().unwrap());
        return;
    }
    if let Ok(polar) = std::env::var("ORACLE") {
        oracle_images(&model, polar.parse().unwrap());
        return;
    }
    if let Ok(polar) = std::env::var("OPACITY_IMAGES") {
        opacity_images(&model, polar.parse().unwrap());
        return;
    }
    if std::env::var("OPACITY_ONLY").is_ok() {
        // `OPACITY_POLARS=0,30,60`: at those polar angles instead.
        let polars: Vec<f32> = std::env::var("OPACITY_POLARS").map_or(vec![0.0, 45.0, 70.0], |l| l.split(',').map(|v| v.trim().parse().expect("a polar angle")).collect());
        for polar in polars {
            opacity_by_level(&model, polar);
        }
        return;
    }
    if let Ok(part) = std::env::var("PART") {
        // One part alone, as in the sweep: `PART=surface`, `PART=flyaways` or
        // `PART=through` (the flyaways black: the surface through and under them).
        let one = match part.as_str() {
            "surface" => without_flyaways(&model),
            "through" => flyaways_black(&model),
            _ => surface_black(&model),
        };
        views(&one, pixels, &format!("{part:<13}"));
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

/// The flyaways black: the surface as their opacity lets it through (and shadows it).
fn flyaways_black(model: &HybridModel) -> HybridModel {
    let mut dark = model.clone();
    for f in dark.levels.iter_mut().filter_map(|l| l.flyaways.as_mut()) {
        f.table.headers.iter_mut().for_each(|h| h.kd = [0; 3]);
        f.table.lobes.iter_mut().for_each(|l| l.k = [0; 3]);
    }
    dark
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
        l.transmission_visibility = None;
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
    let mut first = None;
    for level in 0..model.levels.len().min(6) {
        let mut sum = 0.0f64;
        for y in 0..n {
            for x in 0..n {
                let ray = camera.ray((x as f32 + 0.5) * 16.0 / n as f32, (y as f32 + 0.5) * 16.0 / n as f32);
                sum += scene.trace_ray(&ray, level).flyaway_opacity as f64;
            }
        }
        let opacity = sum / (n * n) as f64;
        // The exponent on the path that would give level 0's mean transmittance.
        let l0 = *first.get_or_insert(opacity);
        line += &format!(" L{level} {opacity:.3} (g {:.3})", (1.0 - l0).ln() / (1.0 - opacity).ln());
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
            let b = in_fiber_frame(f.table.brdf_in_frame(node.param as usize, fabric_runtime::brdf::cloth_frame(glam::Vec3::Z, glam::Vec3::X)), node.tangent(), wo, model.meta.fiber_lobes);
            let r = texel_response(&b, wi, wo, model.meta.reading, fabric_runtime::brdf::DiffuseLaw::Lambert);
            sum += (r.x + r.y + r.z) as f64 / 3.0;
            lit += (r.max_element() > 0.0) as usize;
        }
        let p = f.table.brdf_in_frame(0, fabric_runtime::brdf::cloth_frame(glam::Vec3::Z, glam::Vec3::X)).params;
        println!("  level {level}: {} nodes, mean response {:.4}, {} lit; entry 0: kd {:.3} a {:.2} eta {:.2} lobes {:?}", f.nodes.len(), sum / f.nodes.len() as f64, lit, p.kd, p.a, p.eta, &p.lobes[..p.lobe_count as usize]);
    }
}

/// The sweep's camera at `texels` level-0 texels per pixel (as `far_view::sweep_step`)
/// and its truth: level 0 at 16 × 16 samples per pixel of an image enlarged to at least
/// 4 × 4 samples per texel, box-downsampled.
fn sweep_truth(model: &HybridModel, texels: f32) -> (fabric_runtime::scene::Camera, Image) {
    use fabric_runtime::scene::{Camera, Projection, direction_from_angles};
    use glam::Vec3;
    let b = model.bounds();
    let centre = Vec3::new(0.5 * (b.min.x + b.max.x), 0.5 * (b.min.y + b.max.y), model.tile.top_z);
    let (fov, pixels) = (40f32, 32u32);
    let pixel_at = 2.0 * (0.5 * fov).to_radians().tan() / pixels as f32;
    let d = texels * model.texel_size().x / pixel_at;
    let dir = direction_from_angles(45.0, fabric_baker::prefilter::far_view::VIEW_AZIMUTH);
    let camera = Camera { origin: centre + d * dir, target: centre, up: Vec3::Z, projection: Projection::Perspective { fov_x_deg: fov }, width: pixels, height: pixels };
    let f = ((1.6 * texels * std::f32::consts::SQRT_2 * 4.0 / 16.0).ceil() as u32).clamp(1, 64);
    let big = Camera { width: pixels * f, height: pixels * f, ..camera };
    let opt = CpuRenderOptions { level: LevelChoice::Fixed(0), periodic: true, supersampling: 16, ..Default::default() };
    (camera, render(model, &big, &[far_light()], &opt).unwrap().box_downsample(f))
}

/// The sweep's three nearest steps with the chain at 1, 2 and 4² samples per pixel:
/// whether what is left there is aliasing (falls with samples) or bias (does not).
fn sweep_supersampled(model: &HybridModel) {
    let light = [far_light()];
    for texels in [0.5f32, 0.91, 1.64] {
        let (camera, truth) = sweep_truth(model, texels);
        let opt = |level, ss| CpuRenderOptions { level, periodic: true, supersampling: ss, ..Default::default() };
        let mut line = format!("{texels:.2} texels/px:");
        for ss in [1u32, 2, 4] {
            let chain = render(model, &camera, &light, &opt(LevelChoice::Auto { bias: 0.0 }, ss)).unwrap();
            let l0 = render(model, &camera, &light, &opt(LevelChoice::Fixed(0), ss)).unwrap();
            line += &format!("  {ss}x{ss}: chain {:.2}% level0 {:.2}% (chain mean/truth {:.3})", 100.0 * relative_rmse(&chain, &truth).unwrap(), 100.0 * relative_rmse(&l0, &truth).unwrap(), mean(&chain) / mean(&truth));
        }
        println!("{line}");
    }
}

/// Per pixel of the 16 px far view at `polar`, each fixed level's mean flyaway opacity
/// and mean flyaway radiance per unit opacity (the surface black), against level 0's at
/// 32 × 32 rays per pixel: whether a level's error is *where* its flyaways hide or *what
/// colour* they are.
pub fn opacity_images(model: &HybridModel, polar: f32) {
    use fabric_runtime::cpu::Scene;
    let dark = surface_black(model);
    let camera = far_camera(&dark, polar, 16);
    let light = [far_light()];
    let options = CpuRenderOptions { periodic: true, ..Default::default() };
    let scene = Scene::new(&dark, &camera, &light, options).unwrap();
    let per_pixel = |level: usize, n: u32| -> Vec<(f64, f64)> {
        let mut out = Vec::new();
        for py in 0..16 {
            for px in 0..16 {
                let (mut o, mut r) = (0.0f64, 0.0f64);
                for sy in 0..n {
                    for sx in 0..n {
                        let ray = camera.ray(px as f32 + (sx as f32 + 0.5) / n as f32, py as f32 + (sy as f32 + 0.5) / n as f32);
                        let t = scene.trace_ray(&ray, level);
                        o += t.flyaway_opacity as f64;
                        r += (t.radiance.x + t.radiance.y + t.radiance.z) as f64 / 3.0;
                    }
                }
                out.push((o / (n * n) as f64, r / (n * n) as f64));
            }
        }
        out
    };
    let truth = per_pixel(0, 32);
    let rel = |a: &[f64], b: &[f64]| (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / b.iter().map(|y| y * y).sum::<f64>()).sqrt();
    for level in 0..model.levels.len().min(6) {
        let im = per_pixel(level, 8);
        let (o, r): (Vec<f64>, Vec<f64>) = im.iter().copied().unzip();
        let (to, tr): (Vec<f64>, Vec<f64>) = truth.iter().copied().unzip();
        let c: Vec<f64> = im.iter().map(|(o, r)| r / o.max(1e-6)).collect();
        let tc: Vec<f64> = truth.iter().map(|(o, r)| r / o.max(1e-6)).collect();
        // The radiance if each pixel had the truth's opacity and its own colour.
        let swap: Vec<f64> = c.iter().zip(&to).map(|(c, o)| c * o).collect();
        let m = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        println!("  {polar}° level {level}: radiance {:.1}% (mean {:.3}), opacity {:.1}% (mean {:.3}), colour {:.1}% (mean {:.3}), own colour at the truth's opacity {:.1}%", 100.0 * rel(&r, &tr), m(&r) / m(&tr), 100.0 * rel(&o, &to), m(&o) / m(&to), 100.0 * rel(&c, &tc), m(&c) / m(&tc), 100.0 * rel(&swap, &tr));
    }
}

/// The far view at `polar` of the model with its surface black (its flyaways alone), with
/// the far light's direction and the view's.
fn flyaway_probe_view(model: &HybridModel, polar: f32) -> (HybridModel, fabric_runtime::scene::Camera, glam::Vec3, glam::Vec3) {
    let dark = surface_black(model);
    let camera = far_camera(&dark, polar, 16);
    let wi = far_light().sample(glam::Vec3::ZERO).wi;
    let wo = -camera.ray(8.0, 8.0).d;
    (dark, camera, wi, wo)
}

/// Flyaway node `index`'s mean luminance response under the far light, seen from `wo`:
/// its axes' responses weighted as the renderer weights them.
fn node_response(model: &HybridModel, f: &fabric_runtime::hybrid::Flyaways, index: usize, wi: glam::Vec3, wo: glam::Vec3) -> f64 {
    use fabric_runtime::brdf::{DiffuseLaw, cloth_frame};
    use fabric_runtime::cpu::shading::{in_fiber_frame, texel_response};
    let node = &f.nodes[index];
    let base = f.table.brdf_in_frame(node.param as usize, cloth_frame(glam::Vec3::Z, glam::Vec3::X));
    let axes = f.node_axes(index);
    (0..8).map(|k| axes.weights[k] as f64 * { let r = texel_response(&in_fiber_frame(base, axes.axes[k], wo, model.meta.fiber_lobes), wi, wo, model.meta.reading, DiffuseLaw::Lambert); (r.x + r.y + r.z) as f64 / 3.0 }).sum()
}

/// The 70°-style split of [`opacity_images`] with each coarse node shaded three ways:
/// as the renderer does (its cone of axes, re-marched here), and as the oracle, the
/// α-weighted mean response of the level-0 nodes of its cell: whether the node's
/// shading or where the nodes are is what a level's flyaways get wrong.
pub fn oracle_images(model: &HybridModel, polar: f32) {
    use fabric_runtime::brdf::{DiffuseLaw, cloth_frame};
    use fabric_runtime::cpu::Scene;
    use fabric_runtime::cpu::flyaways::{FlyawayGrid, visit_flyaways};
    use fabric_runtime::cpu::shading::{in_fiber_frame, texel_response};
    use glam::Vec3;
    let (dark, camera, wi, wo) = flyaway_probe_view(model, polar);
    let light = [far_light()];
    let scene = Scene::new(&dark, &camera, &light, CpuRenderOptions { periodic: true, ..Default::default() }).unwrap();
    let response = |f: &fabric_runtime::hybrid::Flyaways, index: usize| node_response(model, f, index, wi, wo);
    let f0 = model.levels[0].flyaways.as_ref().unwrap();
    let w0 = model.width();
    let per_pixel = |level: usize, n: u32, shade: &dyn Fn(usize) -> f64| -> Vec<f64> {
        let f = model.levels[level].flyaways.as_ref().unwrap();
        let grid = FlyawayGrid::new(model, level, true);
        let mut out = Vec::new();
        for py in 0..16 {
            for px in 0..16 {
                let mut r = 0.0f64;
                for sy in 0..n {
                    for sx in 0..n {
                        let ray = camera.ray(px as f32 + (sx as f32 + 0.5) / n as f32, py as f32 + (sy as f32 + 0.5) / n as f32);
                        let Some(t_top) = scene.enter_top(&ray) else { continue };
                        let t = scene.trace_ray(&ray, level);
                        let t_end = t.surface_t.unwrap_or(t_top + model.tile.height_scale / -ray.d.z);
                        visit_flyaways(f, &grid, &ray, t_top, t_end, 1 << 20, |index, _, _, w| r += w as f64 * shade(index));
                    }
                }
                out.push(r / (n * n) as f64);
            }
        }
        out
    };
    let truth = per_pixel(0, 32, &|i| response(f0, i));
    // How much each level-0 node is seen along this view's rays (its visit weights).
    let seen = {
        let grid = FlyawayGrid::new(model, 0, true);
        let mut seen = vec![0.0f64; f0.nodes.len()];
        let n = 64u32;
        for y in 0..16 * n {
            for x in 0..16 * n {
                let ray = camera.ray((x as f32 + 0.5) / n as f32, (y as f32 + 0.5) / n as f32);
                let Some(t_top) = scene.enter_top(&ray) else { continue };
                let t = scene.trace_ray(&ray, 0);
                let t_end = t.surface_t.unwrap_or(t_top + model.tile.height_scale / -ray.d.z);
                visit_flyaways(f0, &grid, &ray, t_top, t_end, 1 << 20, |index, _, _, w| seen[index] += w as f64);
            }
        }
        seen
    };
    let rel = |a: &[f64], b: &[f64]| (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / b.iter().map(|y| y * y).sum::<f64>()).sqrt();
    let m = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    for level in 1..model.levels.len().min(6) {
        let f = model.levels[level].flyaways.as_ref().unwrap();
        let lw = model.levels[level].width;
        let mut cell = std::collections::HashMap::new();
        for j in 0..model.height_px() {
            for i in 0..w0 {
                for (index, node) in f0.list((j * w0 + i) as usize).with_index() {
                    let e = cell.entry((i >> level, j >> level, node.depth as u32 >> level)).or_insert((0.0f64, 0.0f64));
                    e.0 += node.alpha() as f64 * response(f0, index);
                    e.1 += node.alpha() as f64;
                }
            }
        }
        let mut oracle = vec![0.0f64; f.nodes.len()];
        for j in 0..model.levels[level].height {
            for i in 0..lw {
                for (index, node) in f.list((j * lw + i) as usize).with_index() {
                    let (s, a) = cell.get(&(i, j, node.depth as u32)).copied().unwrap_or_default();
                    oracle[index] = s / a.max(1e-12);
                }
            }
        }
        let own = per_pixel(level, 8, &|i| response(f, i));
        let orc = per_pixel(level, 8, &|i| oracle[i]);
        let mut cell = std::collections::HashMap::new();
        for j in 0..model.height_px() {
            for i in 0..w0 {
                for (index, node) in f0.list((j * w0 + i) as usize).with_index() {
                    let e = cell.entry((i >> level, j >> level, node.depth as u32 >> level)).or_insert((0.0f64, 0.0f64));
                    e.0 += seen[index] * response(f0, index);
                    e.1 += seen[index];
                }
            }
        }
        let mut exposed = oracle.clone();
        for j in 0..model.levels[level].height {
            for i in 0..lw {
                for (index, node) in f.list((j * lw + i) as usize).with_index() {
                    if let Some(&(s, a)) = cell.get(&(i, j, node.depth as u32)).filter(|e| e.1 > 0.0) {
                        exposed[index] = s / a;
                    }
                }
            }
        }
        let exp = per_pixel(level, 8, &|i| exposed[i]);
        // Which part of the node's shading is off: its axes (the cone) or its BRDF (the
        // dominant cluster). V2: the cone with its children's clusters; V3: the children's
        // axes with the node's cluster.
        let shade_with = |table: &fabric_runtime::hybrid::BrdfTable, param: usize, axes: &fabric_runtime::brdf::axis_spread::SpreadAxes| -> f64 {
            let base = table.brdf_in_frame(param, cloth_frame(Vec3::Z, Vec3::X));
            (0..8).filter(|&k| axes.weights[k] > 0.0).map(|k| axes.weights[k] as f64 * { let r = texel_response(&in_fiber_frame(base, axes.axes[k], wo, model.meta.fiber_lobes), wi, wo, model.meta.reading, DiffuseLaw::Lambert); (r.x + r.y + r.z) as f64 / 3.0 }).sum()
        };
        let mut kids: std::collections::HashMap<(u32, u32, u32), Vec<usize>> = std::collections::HashMap::new();
        // Each level-0 node's weight as the baker counts it (prefilter/flyaways.rs: what a
        // ray down its column meets of it, under the cell's voxels over it); `PLAIN=1`: α.
        let mut kid_w = vec![0.0f32; f0.nodes.len()];
        let s0 = model.voxel_depth(0);
        for j in 0..model.height_px() {
            for i in 0..w0 {
                let surface = model.depth(i, j);
                let mut over: std::collections::HashMap<u32, f32> = std::collections::HashMap::new();
                for (index, node) in f0.list((j * w0 + i) as usize).with_index() {
                    kids.entry((i >> level, j >> level, node.depth as u32 >> level)).or_default().push(index);
                    let free = ((surface - node.depth as f32 * s0) / s0).clamp(0.0, 1.0);
                    let a = if free <= 0.0 { 0.0 } else { 1.0 - (1.0 - node.alpha().clamp(0.0, 1.0)).powf(free) };
                    let t = over.entry(node.depth as u32 >> level).or_insert(1.0);
                    kid_w[index] = if std::env::var("PLAIN").is_ok() { node.alpha() } else { a * *t };
                    *t *= 1.0 - a;
                }
            }
        }
        let (mut v2, mut v3) = (oracle.clone(), oracle.clone());
        for j in 0..model.levels[level].height {
            for i in 0..lw {
                for (index, node) in f.list((j * lw + i) as usize).with_index() {
                    let Some(ch) = kids.get(&(i, j, node.depth as u32)) else { continue };
                    let axes = f.node_axes(index);
                    let (mut a2, mut a3, mut w) = (0.0, 0.0, 0.0);
                    for &c in ch {
                        let a = f0.nodes[c].alpha() as f64;
                        a2 += a * shade_with(&f0.table, f0.nodes[c].param as usize, &axes);
                        a3 += a * shade_with(&f.table, node.param as usize, &f0.node_axes(c));
                        w += a;
                    }
                    v2[index] = a2 / w;
                    v3[index] = a3 / w;
                }
            }
        }
        let i2 = per_pixel(level, 8, &|i| v2[i]);
        let i3 = per_pixel(level, 8, &|i| v3[i]);
        if let Ok(grid) = std::env::var("SPLIT") {
            // The cone's spread shrunk to q of it, each lobe widened by c·(1 − q) of it.
            for qc in grid.split(';') {
                let v: Vec<f32> = qc.split(',').map(|x| x.parse().unwrap()).collect();
                let (q, c) = (v[0], v[1]);
                let mut split = oracle.clone();
                for (index, node) in f.nodes.iter().enumerate() {
                    let Some(rec) = f.spreads.as_ref().map(|s| s[index]) else { continue };
                    let (l2, l3) = rec.lambdas();
                    let axes = fabric_runtime::brdf::axis_spread::spread_axes(node.tangent(), rec.roll(), q * l2, q * l3);
                    let mut base = f.table.brdf_in_frame(node.param as usize, cloth_frame(Vec3::Z, Vec3::X));
                    let widen = c * (1.0 - q) * (l2 + l3).min(1.0);
                    for lobe in base.params.lobes[..base.params.lobe_count as usize].iter_mut() {
                        lobe.beta = (lobe.beta * lobe.beta + widen).sqrt();
                    }
                    split[index] = (0..8).filter(|&k| axes.weights[k] > 0.0).map(|k| axes.weights[k] as f64 * { let r = texel_response(&in_fiber_frame(base, axes.axes[k], wo, model.meta.fiber_lobes), wi, wo, model.meta.reading, DiffuseLaw::Lambert); (r.x + r.y + r.z) as f64 / 3.0 }).sum();
                }
                let im = per_pixel(level, 8, &|i| split[i]);
                println!("      q {q} c {c}: {:.1}% (mean {:.3})", 100.0 * rel(&im, &truth), m(&im) / m(&truth));
            }
        }
        if std::env::var("QUAD").is_ok() {
            // Other axis sets with the same tensor: the cube's corners of T^½ (four axes
            // √λ₁e₁ ± √λ₂e₂ ± √λ₃e₃), and cone and corners together (eight).
            for set in ["corners", "both"] {
                let mut v = oracle.clone();
                for (index, node) in f.nodes.iter().enumerate() {
                    let Some(rec) = f.spreads.as_ref().map(|s| s[index]) else { continue };
                    let (l2, l3) = rec.lambdas();
                    let spread = (l2 + l3).min(1.0);
                    let e1 = node.tangent();
                    let (r, qv) = fabric_runtime::brdf::axis_spread::spread_basis(e1);
                    let e2 = r * rec.roll().cos() + qv * rec.roll().sin();
                    let e3 = e1.cross(e2);
                    let (a1, a2, a3) = ((1.0 - spread).max(0.0).sqrt(), l2.sqrt(), l3.sqrt());
                    let corners = [e1 * a1 + e2 * a2 + e3 * a3, e1 * a1 + e2 * a2 - e3 * a3, e1 * a1 - e2 * a2 + e3 * a3, e1 * a1 - e2 * a2 - e3 * a3];
                    let base = f.table.brdf_in_frame(node.param as usize, cloth_frame(Vec3::Z, Vec3::X));
                    let resp = |a: Vec3| { let r = texel_response(&in_fiber_frame(base, a.normalize(), wo, model.meta.fiber_lobes), wi, wo, model.meta.reading, DiffuseLaw::Lambert); (r.x + r.y + r.z) as f64 / 3.0 };
                    let c: f64 = corners.iter().map(|&a| 0.25 * resp(a)).sum();
                    v[index] = if set == "corners" { c } else { 0.5 * c + 0.5 * shade_with(&f.table, node.param as usize, &f.node_axes(index)) };
                }
                let im = per_pixel(level, 8, &|i| v[i]);
                println!("      {set}: {:.1}% (mean {:.3})", 100.0 * rel(&im, &truth), m(&im) / m(&truth));
            }
        }
        if let Ok(ks) = std::env::var("KMEANS") {
            // The children's axes in k groups (k-means on axes, |a·c|), each group shaded
            // with its principal axis: what a bimodal cell (warp and weft) needs and a
            // tensor cannot say.
            for k in ks.split(',').map(|x| x.parse::<usize>().unwrap()) {
                let mut v = oracle.clone();
                for j in 0..model.levels[level].height {
                    for i in 0..lw {
                        for (index, node) in f.list((j * lw + i) as usize).with_index() {
                            let Some(ch) = kids.get(&(i, j, node.depth as u32)) else { continue };
                            let ax: Vec<(Vec3, f32)> = ch.iter().map(|&c| (f0.nodes[c].tangent().normalize(), kid_w[c])).filter(|x| x.1 > 0.0).collect();
                            if ax.is_empty() { continue; }
                            let mut centres = vec![node.tangent().normalize()];
                            while centres.len() < k.min(ax.len()) {
                                let far = ax.iter().min_by(|a, b| { let s = |x: &Vec3| centres.iter().map(|c| c.dot(*x).abs()).fold(0.0f32, f32::max); s(&a.0).partial_cmp(&s(&b.0)).unwrap() }).unwrap().0;
                                centres.push(far);
                            }
                            let mut weights = vec![0.0f32; centres.len()];
                            for _ in 0..8 {
                                let mut tensors = vec![glam::Mat3::ZERO; centres.len()];
                                weights.iter_mut().for_each(|w| *w = 0.0);
                                for (a, w) in &ax {
                                    let best = (0..centres.len()).max_by(|&x, &y| centres[x].dot(*a).abs().partial_cmp(&centres[y].dot(*a).abs()).unwrap()).unwrap();
                                    tensors[best] += glam::Mat3::from_cols(*a * a.x, *a * a.y, *a * a.z) * *w;
                                    weights[best] += *w;
                                }
                                for c in 0..centres.len() {
                                    if weights[c] > 0.0 {
                                        if let Some(a) = fabric_baker::geometry::tangents::principal_axis(tensors[c]) { centres[c] = a; }
                                    }
                                }
                            }
                            let total: f32 = weights.iter().sum();
                            let base = f.table.brdf_in_frame(node.param as usize, cloth_frame(Vec3::Z, Vec3::X));
                            if std::env::var("GROUP_CONES").is_ok() {
                                // Each group as the cone of its own tensor.
                                let mut tensors = vec![glam::Mat3::ZERO; centres.len()];
                                for (a, w) in &ax {
                                    let best = (0..centres.len()).max_by(|&x, &y| centres[x].dot(*a).abs().partial_cmp(&centres[y].dot(*a).abs()).unwrap()).unwrap();
                                    tensors[best] += glam::Mat3::from_cols(*a * a.x, *a * a.y, *a * a.z) * *w;
                                }
                                let mut sum = 0.0f64;
                                for (c, t) in tensors.iter().enumerate() {
                                    if weights[c] <= 0.0 { continue; }
                                    let t = *t * (1.0 / weights[c]);
                                    let e1 = centres[c];
                                    let (r, q) = fabric_runtime::brdf::axis_spread::spread_basis(e1);
                                    let (m00, m01, m11) = (r.dot(t * r), r.dot(t * q), q.dot(t * q));
                                    let theta = 0.5 * (2.0 * m01).atan2(m00 - m11);
                                    let half = ((m00 - m11) * (m00 - m11) * 0.25 + m01 * m01).sqrt();
                                    let (l2, l3) = ((0.5 * (m00 + m11) + half).max(0.0), (0.5 * (m00 + m11) - half).max(0.0));
                                    let (e1, l2, l3) = if c > 0 && std::env::var("B_CIRC").is_ok() {
                                        // The second group as 4 bytes would keep it: its axis at 8 bits per
                                        // octahedral coordinate, a circular cone.
                                        let o = fabric_runtime::hybrid::packing::octahedral_encode(e1);
                                        let dec = fabric_runtime::hybrid::packing::octahedral_decode([(o[0] & 0xff00) | 0x80, (o[1] & 0xff00) | 0x80]);
                                        (dec, 0.5 * (l2 + l3), 0.5 * (l2 + l3))
                                    } else { (e1, l2, l3) };
                                    let axes = fabric_runtime::brdf::axis_spread::spread_axes(e1, theta, l2, l3);
                                    sum += (weights[c] / total) as f64 * (0..8).filter(|&k| axes.weights[k] > 0.0).map(|k| axes.weights[k] as f64 * { let r = texel_response(&in_fiber_frame(base, axes.axes[k], wo, model.meta.fiber_lobes), wi, wo, model.meta.reading, DiffuseLaw::Lambert); (r.x + r.y + r.z) as f64 / 3.0 }).sum::<f64>();
                                }
                                v[index] = sum;
                                continue;
                            }
                            v[index] = centres.iter().zip(&weights).map(|(c, w)| (*w / total) as f64 * { let r = texel_response(&in_fiber_frame(base, *c, wo, model.meta.fiber_lobes), wi, wo, model.meta.reading, DiffuseLaw::Lambert); (r.x + r.y + r.z) as f64 / 3.0 }).sum();
                        }
                    }
                }
                let im = per_pixel(level, 8, &|i| v[i]);
                println!("      {k} axis groups: {:.1}% (mean {:.3})", 100.0 * rel(&im, &truth), m(&im) / m(&truth));
            }
        }
        if std::env::var("CHOOSE").is_ok() {
            // Per node, the cone or the three eigen-axes weighted by λ (the same tensor),
            // whichever is nearer the children's mean response over random direction pairs.
            let pairs: Vec<(Vec3, Vec3)> = (0..64u32).map(|k| {
                let h = |x: u32| ((x.wrapping_mul(2654435761) ^ (x >> 13)).wrapping_mul(2246822519) >> 8) as f32 / (1u32 << 24) as f32;
                let d = |a: f32, b: f32| { let z = a.max(0.05); let r = (1.0 - z * z).sqrt(); Vec3::new(r * (std::f32::consts::TAU * b).cos(), r * (std::f32::consts::TAU * b).sin(), z) };
                (d(h(4 * k), h(4 * k + 1)), d(h(4 * k + 2), h(4 * k + 3)))
            }).collect();
            let resp_at = |table: &fabric_runtime::hybrid::BrdfTable, param: usize, a: Vec3, wi: Vec3, wo: Vec3| -> f64 {
                let base = table.brdf_in_frame(param, cloth_frame(Vec3::Z, Vec3::X));
                let r = texel_response(&in_fiber_frame(base, a, wo, model.meta.fiber_lobes), wi, wo, model.meta.reading, DiffuseLaw::Lambert);
                (r.x + r.y + r.z) as f64 / 3.0
            };
            let mut v = oracle.clone();
            let (mut chose_eigen, mut n) = (0, 0);
            for j in 0..model.levels[level].height {
                for i in 0..lw {
                    for (index, node) in f.list((j * lw + i) as usize).with_index() {
                        let Some(ch) = kids.get(&(i, j, node.depth as u32)) else { continue };
                        let Some(rec) = f.spreads.as_ref().map(|s| s[index]) else { continue };
                        let (l2, l3) = rec.lambdas();
                        let e1 = node.tangent();
                        let (r, qv) = fabric_runtime::brdf::axis_spread::spread_basis(e1);
                        let e2 = r * rec.roll().cos() + qv * rec.roll().sin();
                        let e3 = e1.cross(e2);
                        let eigen = [(e1, 1.0 - l2 - l3), (e2, l2), (e3, l3)];
                        let cone = f.node_axes(index);
                        let (mut err_cone, mut err_eigen) = (0.0, 0.0);
                        for &(pi, po) in &pairs {
                            let w: f64 = ch.iter().map(|&c| f0.nodes[c].alpha() as f64).sum();
                            let truth: f64 = ch.iter().map(|&c| f0.nodes[c].alpha() as f64 * resp_at(&f0.table, f0.nodes[c].param as usize, f0.nodes[c].tangent(), pi, po)).sum::<f64>() / w;
                            let c: f64 = (0..8).filter(|&k| cone.weights[k] > 0.0).map(|k| cone.weights[k] as f64 * resp_at(&f.table, node.param as usize, cone.axes[k], pi, po)).sum();
                            let e: f64 = eigen.iter().filter(|x| x.1 > 0.0).map(|&(a, l)| l as f64 * resp_at(&f.table, node.param as usize, a, pi, po)).sum();
                            err_cone += (c - truth).powi(2);
                            err_eigen += (e - truth).powi(2);
                        }
                        n += 1;
                        v[index] = if err_eigen < err_cone {
                            chose_eigen += 1;
                            eigen.iter().filter(|x| x.1 > 0.0).map(|&(a, l)| l as f64 * resp_at(&f.table, node.param as usize, a, wi, wo)).sum()
                        } else {
                            (0..8).filter(|&k| cone.weights[k] > 0.0).map(|k| cone.weights[k] as f64 * resp_at(&f.table, node.param as usize, cone.axes[k], wi, wo)).sum()
                        };
                    }
                }
            }
            let im = per_pixel(level, 8, &|i| v[i]);
            println!("      cone or eigen-axes per node ({chose_eigen} of {n} eigen): {:.1}% (mean {:.3})", 100.0 * rel(&im, &truth), m(&im) / m(&truth));
        }
        println!("      cone with the children's clusters {:.1}% (mean {:.3}); children's axes with the node's cluster {:.1}% (mean {:.3})", 100.0 * rel(&i2, &truth), m(&i2) / m(&truth), 100.0 * rel(&i3, &truth), m(&i3) / m(&truth));
        println!("  {polar}° level {level}: as shaded {:.1}% (mean {:.3}), oracle node colour {:.1}% (mean {:.3}), as seen at this view {:.1}% (mean {:.3})", 100.0 * rel(&own, &truth), m(&own) / m(&truth), 100.0 * rel(&orc, &truth), m(&orc) / m(&truth), 100.0 * rel(&exp, &truth), m(&exp) / m(&truth));
    }
}

/// `SWEEP_LEVELS=9.8,32`: at those sweep steps, the chain and each fixed level at 4 × 4
/// samples per pixel against the truth, with their means over the truth's: whether a
/// step's error is a level's bias or its filtering.
fn sweep_levels(model: &HybridModel, list: &str) {
    let light = [far_light()];
    for texels in list.split(',').map(|t| t.trim().parse::<f32>().unwrap()) {
        let (camera, truth) = sweep_truth(model, texels);
        let opt = |level, ss| CpuRenderOptions { level, periodic: true, supersampling: ss, ..Default::default() };
        let chain = render(model, &camera, &light, &opt(LevelChoice::Auto { bias: 0.0 }, 1)).unwrap();
        let k = (mean(&truth) / mean(&chain)) as f32;
        let scaled = Image::from_fn(chain.width, chain.height, |x, y| k * chain.get(x, y));
        println!("{texels:.2} texels/px: chain {:.2}% (mean {:.3}; {:.2}% at the truth's mean)", 100.0 * relative_rmse(&chain, &truth).unwrap(), mean(&chain) / mean(&truth), 100.0 * relative_rmse(&scaled, &truth).unwrap());
        for level in 1..model.levels.len().min(7) {
            let im = render(model, &camera, &light, &opt(LevelChoice::Fixed(level as u32), 4)).unwrap();
            println!("    level {level} at 4x4 spp: {:.2}% (mean {:.3})", 100.0 * relative_rmse(&im, &truth).unwrap(), mean(&im) / mean(&truth));
        }
    }
}

/// Where a coarse level's flyaway weights go against level 0's: each coarse node's visit
/// weight along this view's rays against the summed weight of its level-0 children, by
/// depth, with the children's seen-weighted colour (`DEPTHS=POLAR`).
pub fn depth_weights(model: &HybridModel, polar: f32) {
    use fabric_runtime::cpu::Scene;
    use fabric_runtime::cpu::flyaways::{FlyawayGrid, visit_flyaways};
    let (dark, camera, wi, wo) = flyaway_probe_view(model, polar);
    let light = [far_light()];
    let scene = Scene::new(&dark, &camera, &light, CpuRenderOptions { periodic: true, ..Default::default() }).unwrap();
    let f0 = model.levels[0].flyaways.as_ref().unwrap();
    let response = |index: usize| node_response(model, f0, index, wi, wo);
    let seen_at = |level: usize, n: u32| -> Vec<f64> {
        let f = model.levels[level].flyaways.as_ref().unwrap();
        let grid = FlyawayGrid::new(model, level, true);
        let mut seen = vec![0.0f64; f.nodes.len()];
        for y in 0..16 * n {
            for x in 0..16 * n {
                let ray = camera.ray((x as f32 + 0.5) / n as f32, (y as f32 + 0.5) / n as f32);
                let Some(t_top) = scene.enter_top(&ray) else { continue };
                let t = scene.trace_ray(&ray, level);
                let t_end = t.surface_t.unwrap_or(t_top + model.tile.height_scale / -ray.d.z);
                visit_flyaways(f, &grid, &ray, t_top, t_end, 1 << 20, |index, _, _, w| seen[index] += w as f64 / (n * n) as f64);
            }
        }
        seen
    };
    let seen0 = seen_at(0, 32);
    let w0 = model.width();
    let colour: Vec<f64> = (0..f0.nodes.len()).map(response).collect();
    for level in 1..model.levels.len().min(4) {
        let f = model.levels[level].flyaways.as_ref().unwrap();
        let lw = model.levels[level].width;
        let mut index_of = std::collections::HashMap::new();
        for j in 0..model.levels[level].height {
            for i in 0..lw {
                for (index, node) in f.list((j * lw + i) as usize).with_index() {
                    index_of.insert((i, j, node.depth as u32), index);
                }
            }
        }
        // Per coarse node: the children's seen weight and seen-weighted colour sum, and
        // the same split by whether the child lies in the upper or lower half of its cell.
        let mut wt = vec![0.0f64; f.nodes.len()];
        let mut ct = vec![0.0f64; f.nodes.len()];
        let mut upper = [0.0f64; 2];
        let mut upper_c = [0.0f64; 2];
        let mut orphan = 0.0;
        for j in 0..model.height_px() {
            for i in 0..w0 {
                for (index, node) in f0.list((j * w0 + i) as usize).with_index() {
                    let key = (i >> level, j >> level, node.depth as u32 >> level);
                    let Some(&c) = index_of.get(&key) else { orphan += seen0[index]; continue };
                    wt[c] += seen0[index];
                    ct[c] += seen0[index] * colour[index];
                    let half = usize::from(((node.depth as u32) & ((1 << level) - 1)) >= (1 << (level - 1)));
                    upper[half] += seen0[index];
                    upper_c[half] += seen0[index] * colour[index];
                }
            }
        }
        let wc = seen_at(level, 8);
        let e: Vec<f64> = (0..f.nodes.len()).map(|k| if wt[k] > 0.0 { ct[k] / wt[k] } else { 0.0 }).collect();
        let sum = |v: &[f64]| v.iter().sum::<f64>();
        let (st, sc) = (sum(&wt), sum(&wc));
        let img_t: f64 = (0..f.nodes.len()).map(|k| e[k] * wt[k]).sum();
        let img_c: f64 = (0..f.nodes.len()).map(|k| e[k] * wc[k]).sum();
        let unseen: f64 = (0..f.nodes.len()).filter(|&k| wt[k] == 0.0).map(|k| wc[k]).sum();
        println!("{polar}° level {level}: opacity coarse/truth {:.3} (orphan children {:.4}, coarse weight on nodes whose children go unseen {:.1}%), exposed-colour image coarse/truth {:.3}", sc / st, orphan / st, 100.0 * unseen / sc, img_c / img_t);
        println!("    children in the upper / lower half of their cell: weight {:.1}% / {:.1}%, colour {:.4} / {:.4}", 100.0 * upper[0] / (upper[0] + upper[1]), 100.0 * upper[1] / (upper[0] + upper[1]), upper_c[0] / upper[0].max(1e-12), upper_c[1] / upper[1].max(1e-12));
        // By depth at this level.
        let mut by_depth: std::collections::BTreeMap<u16, [f64; 4]> = std::collections::BTreeMap::new();
        for (k, node) in f.nodes.iter().enumerate() {
            let b = by_depth.entry(node.depth).or_default();
            b[0] += wt[k];
            b[1] += wc[k];
            b[2] += e[k] * wt[k];
            b[3] += e[k] * wc[k];
        }
        for (d, b) in by_depth {
            if b[0] + b[1] < 1e-4 * (st + sc) {
                continue;
            }
            println!("    depth {d:3}: truth weight {:6.2}%  coarse {:6.2}%  colour (truth-weighted) {:.4}  (coarse-weighted) {:.4}", 100.0 * b[0] / st, 100.0 * b[1] / sc, b[2] / b[0].max(1e-12), b[3] / b[1].max(1e-12));
        }
        // By the node's axis against the view: |t·ω_o| in fifths.
        let mut by_axis = [[0.0f64; 4]; 5];
        for (k, node) in f.nodes.iter().enumerate() {
            let b = &mut by_axis[((node.tangent().dot(wo).abs() * 5.0) as usize).min(4)];
            b[0] += wt[k];
            b[1] += wc[k];
            b[2] += e[k] * wt[k];
            b[3] += node.alpha() as f64 * wt[k];
        }
        for (a, b) in by_axis.iter().enumerate() {
            println!("    |t·wo| {:.1}–{:.1}: truth weight {:6.2}%  coarse {:6.2}%  ratio {:.3}  colour {:.4}  alpha {:.3}", a as f32 / 5.0, (a + 1) as f32 / 5.0, 100.0 * b[0] / st, 100.0 * b[1] / sc, (b[1] / sc) / (b[0] / st).max(1e-12), b[2] / b[0].max(1e-12), b[3] / b[0].max(1e-12));
        }
        // By α in fifths.
        let mut by_alpha = [[0.0f64; 3]; 5];
        for (k, node) in f.nodes.iter().enumerate() {
            let b = &mut by_alpha[((node.alpha() * 5.0) as usize).min(4)];
            b[0] += wt[k];
            b[1] += wc[k];
            b[2] += e[k] * wt[k];
        }
        for (a, b) in by_alpha.iter().enumerate() {
            println!("    alpha {:.1}–{:.1}: truth weight {:6.2}%  coarse {:6.2}%  ratio {:.3}  colour {:.4}", a as f32 / 5.0, (a + 1) as f32 / 5.0, 100.0 * b[0] / st, 100.0 * b[1] / sc, (b[1] / sc) / (b[0] / st).max(1e-12), b[2] / b[0].max(1e-12));
        }
        // By colour: quartiles of the exposed colour among seen nodes.
        let mut order: Vec<usize> = (0..f.nodes.len()).filter(|&k| wt[k] > 0.0).collect();
        order.sort_by(|&a, &b| e[a].total_cmp(&e[b]));
        let q = order.len() / 4;
        for part in 0..4 {
            let ks = &order[part * q..if part == 3 { order.len() } else { (part + 1) * q }];
            let (a, b): (f64, f64) = ks.iter().fold((0.0, 0.0), |s, &k| (s.0 + wt[k], s.1 + wc[k]));
            println!("    colour quartile {part}: truth weight {:6.2}%  coarse {:6.2}%  ratio {:.3}", 100.0 * a / st, 100.0 * b / sc, (b / sc) / (a / st).max(1e-12));
        }
    }
}
