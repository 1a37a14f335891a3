//! Why coarse levels are too bright at grazing views: over the whole tile seen
//! orthographically from polar θ (azimuth 30°, light at 40°/210° as in the far views),
//! traced on level 0 without flyaways, it compares
//!   truth   = ⟨V f_j⟩ over the hits (j the hit texel, V the light's visibility),
//!   ⟨V⟩ ⟨f_j⟩_hits (the hits' BRDFs, decorrelated from the shadowing),
//!   ⟨V⟩ f̄      (f̄ the plain mean over all texels: what a coarse level stands for).
//!
//! `cargo run --release -p fabric-baker --example grazing_parts MODEL.hyb`

use fabric_baker::prefilter::far_view::{VIEW_AZIMUTH, far_light};
use fabric_runtime::cpu::shading::texel_response;
use fabric_runtime::cpu::{CpuRenderOptions, Scene};
use fabric_runtime::hybrid::format;
use fabric_runtime::scene::{Ray, direction_from_angles};
use glam::Vec3;

fn lum(v: Vec3) -> f64 {
    (v.x + v.y + v.z) as f64 / 3.0
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let model = format::read_file(std::path::Path::new(&args[1])).expect("read the model");
    let mut model = model;
    for l in model.levels.iter_mut() {
        l.flyaways = None;
    }
    let light = [far_light()];
    let wi = light[0].sample(Vec3::ZERO).wi;
    let scene = Scene::for_rays(&model, &light, CpuRenderOptions { periodic: true, ..Default::default() }).unwrap();
    let (w, h) = (model.width(), model.height_px());
    let l0 = &model.levels[0];
    let reading = model.meta.reading;
    let n = 384u32;
    for polar in [0.0f32, 45.0, 60.0, 70.0] {
        let wo = direction_from_angles(polar, VIEW_AZIMUTH);
        let mut plain = 0.0;
        for j in 0..h {
            for i in 0..w {
                plain += lum(texel_response(&l0.texel_brdf(i, j), wi, wo, reading, model.meta.diffuse));
            }
        }
        plain /= (w * h) as f64;
        let (mut truth, mut v_sum, mut f_sum, mut count, mut cos_hit) = (0.0, 0.0, 0.0, 0.0, 0.0);
        let b = model.bounds();
        for y in 0..n {
            for x in 0..n {
                let p = Vec3::new(b.min.x + (x as f32 + 0.5) / n as f32 * (b.max.x - b.min.x), b.min.y + (y as f32 + 0.5) / n as f32 * (b.max.y - b.min.y), model.tile.top_z + 1e-4);
                let ray = Ray::new(p, -wo);
                let trace = scene.probe_ray(&ray, 0, false);
                let Some(hit) = trace.surface else { continue };
                let brdf = l0.texel_brdf(hit.texel.0, hit.texel.1);
                let f = lum(texel_response(&brdf, wi, wo, reading, model.meta.diffuse));
                truth += hit.visibility as f64 * f;
                v_sum += hit.visibility as f64;
                f_sum += f;
                cos_hit += brdf.frames[0].n.dot(wi) as f64;
                count += 1.0;
            }
        }
        // The hits' mean normal, the projected-area estimate of it, and f̄ with every
        // frame turned by the rotation that takes the plain mean normal to the hits'.
        let mut n_hits = Vec3::ZERO;
        let mut n_plain = Vec3::ZERO;
        let mut n_proj = Vec3::ZERO;
        for j in 0..h {
            for i in 0..w {
                let nn = l0.texel_brdf(i, j).frames[0].n;
                n_plain += nn;
                n_proj += nn * (nn.dot(wo).max(0.0) / nn.z.max(1e-3));
            }
        }
        for y in 0..n {
            for x in 0..n {
                let p = Vec3::new(b.min.x + (x as f32 + 0.5) / n as f32 * (b.max.x - b.min.x), b.min.y + (y as f32 + 0.5) / n as f32 * (b.max.y - b.min.y), model.tile.top_z + 1e-4);
                if let Some(hit) = scene.probe_ray(&Ray::new(p, -wo), 0, false).surface {
                    n_hits += l0.texel_brdf(hit.texel.0, hit.texel.1).frames[0].n;
                }
            }
        }
        let (n_plain, n_hits, n_proj) = (n_plain.normalize(), n_hits.normalize(), n_proj.normalize());
        let rot = glam::Quat::from_rotation_arc(n_plain, n_hits);
        let mut tilted = 0.0;
        for j in 0..h {
            for i in 0..w {
                let mut brdf = l0.texel_brdf(i, j);
                for fr in brdf.frames.iter_mut() {
                    fr.n = rot * fr.n;
                    fr.t = rot * fr.t;
                }
                tilted += lum(texel_response(&brdf, wi, wo, reading, model.meta.diffuse));
            }
        }
        tilted /= (w * h) as f64;
        println!("  normals: plain {n_plain:.3}  hits {n_hits:.3}  projected-area {n_proj:.3}");
        let (t, v, fh) = (truth / count, v_sum / count, f_sum / count);
        println!("  <V> fbar tilted to the hits' normal: {:.3} of the truth", v * tilted / t);
        if polar == 70.0 {
            visibility_check(&model, wo, &scene);
        }
        println!("polar {polar:>4}: truth {t:.4}  <V> {v:.3}  <V><f>hits {:.4} ({:.3})  <V> fbar {:.4} ({:.3})  <n0.wi>hits {:.3}", v * fh, v * fh / t, v * plain, v * plain / t, cos_hit / count);
    }
}

/// Per coarse level at the far view's 70°: the mean of the stored v(ω_o) over texels
/// (1 if v is a density), and the hit density's own contrast against v's.
#[allow(dead_code)]
pub fn visibility_check(model: &fabric_runtime::hybrid::HybridModel, wo: Vec3, scene: &Scene) {
    use fabric_runtime::brdf::visible_normal::view_visibility;
    let b = model.bounds();
    let n = 512u32;
    for (level, l) in model.levels.iter().enumerate().skip(1).take(4) {
        let Some(t) = &l.view_tilt else { continue };
        let mut hits = vec![0u32; t.len()];
        for y in 0..n {
            for x in 0..n {
                let p = Vec3::new(b.min.x + (x as f32 + 0.5) / n as f32 * (b.max.x - b.min.x), b.min.y + (y as f32 + 0.5) / n as f32 * (b.max.y - b.min.y), model.tile.top_z + 1e-4);
                if let Some(hit) = scene.probe_ray(&Ray::new(p, -wo), level, false).surface {
                    hits[(hit.texel.1 * l.width + hit.texel.0) as usize] += 1;
                }
            }
        }
        let expected = (n * n) as f64 / t.len() as f64;
        let v: Vec<f64> = t.iter().map(|r| view_visibility(&r.decode(), wo) as f64).collect();
        let d: Vec<f64> = hits.iter().map(|&h| h as f64 / expected).collect();
        let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len() as f64;
        let var = |x: &[f64]| { let m = mean(x); x.iter().map(|a| (a - m) * (a - m)).sum::<f64>() / x.len() as f64 };
        let cov = { let (mv, md) = (mean(&v), mean(&d)); v.iter().zip(&d).map(|(a, b)| (a - mv) * (b - md)).sum::<f64>() / v.len() as f64 };
        println!("  level {level}: mean v {:.3}  sd v {:.3}  sd density {:.3}  corr {:.3}", mean(&v), var(&v).sqrt(), var(&d).sqrt(), cov / (var(&v) * var(&d)).sqrt());
    }
}
