//! Analytic and statistical checks of the whole path tracer: closed-form single
//! scattering from a homogeneous slab, a white furnace, reciprocity, 1/√spp
//! convergence, determinism across thread counts, and the voxel mask.
//!
//! Every Monte Carlo comparison bounds the error by a multiple of the standard error
//! measured from the samples themselves (per-texel means are independent), so the
//! tolerances say what bounds them.

use fabric_runtime::image::Image;
use fabric_runtime::scene::{Camera, Light, Projection, direction_from_angles};
use glam::Vec3;

use super::integrator::{Lighting, PathSettings, PathStats, radiance};
use super::measure::MeasureScene;
use super::medium::{Lookup, MediumOptions};
use super::render::{RenderSettings, render};
use super::rng::Rng;
use super::sggx::Sggx;
use super::tracking::{GridRay, TracedMedium};
use crate::volume::{Aabb, FabricVolume, MaterialParams, Voxel};

/// Mean and standard error of the mean over all pixel-channel means of an image whose
/// pixels are independent estimates.
pub(super) fn mean_and_stderr(img: &Image) -> (f64, f64) {
    let v: Vec<f64> = img.pixels.iter().map(|p| (p.x + p.y + p.z) as f64 / 3.0).collect();
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

pub(super) fn homogeneous(dims: [usize; 3], thickness: f32, rho: f32, scale: f32, albedo: f32, fiber: Vec3, roughness: f32) -> FabricVolume {
    let mut v = FabricVolume::new(dims, Aabb::new(Vec3::ZERO, Vec3::new(1.0, 1.0, thickness)), MaterialParams { density_scale: scale, roughness });
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                v.set(x, y, z, Voxel::pack(rho, Vec3::splat(albedo), fiber));
            }
        }
    }
    v
}

/// Heterogeneous, anisotropic: random densities (30% empty), random fibers lying
/// mostly in the sheet's plane, albedo `albedo`.
pub(super) fn random_fabric(dims: [usize; 3], thickness: f32, scale: f32, albedo: Vec3, seed: u64) -> FabricVolume {
    let mut v = FabricVolume::new(dims, Aabb::new(Vec3::ZERO, Vec3::new(1.0, 1.0, thickness)), MaterialParams { density_scale: scale, roughness: 0.3 });
    let mut rng = Rng::new(seed, 0, 0);
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                let rho = if rng.next_f32() < 0.3 { 0.0 } else { 0.5 + 1.5 * rng.next_f32() };
                let dir = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, 0.3 * (rng.next_f32() - 0.5));
                v.set(x, y, z, Voxel::pack(rho, albedo, dir));
            }
        }
    }
    v
}

/// Single scattering from a homogeneous slab of thickness H, σ_t(ω) = k·σ(ω) with
/// k = scale·ρ, albedo α, unit irradiance from ω_i, seen from ω_o. With
/// a = k·σ(ω)/|μ| per direction and σ_s(ω_i)·f_p(ω_i → ω_o) = α·k·D(ω_h)/4:
///   reflection:   L = α k D(ω_h) / (4 μ_o) · (1 − e^{−H(a_i + a_o)}) / (a_i + a_o)
///   transmission: L = α k D(ω_h) / (4 |μ_o|) · (e^{−H a_o} − e^{−H a_i}) / (a_i − a_o)
pub(super) fn single_scattering(s: &Sggx, k: f64, albedo: f64, h: f64, wi: Vec3, wo: Vec3) -> f64 {
    let d = s.ndf((wi + wo).normalize()) as f64;
    let (mu_i, mu_o) = (wi.z as f64, wo.z as f64);
    let a_i = k * s.projected_area(wi) as f64 / mu_i;
    let a_o = k * s.projected_area(wo) as f64 / mu_o.abs();
    let front = albedo * k * d / (4.0 * mu_o.abs());
    if mu_o > 0.0 {
        front * (1.0 - (-h * (a_i + a_o)).exp()) / (a_i + a_o)
    } else if (a_i - a_o).abs() < 1e-9 {
        front * h * (-h * a_i).exp()
    } else {
        front * ((-h * a_o).exp() - (-h * a_i).exp()) / (a_i - a_o)
    }
}

#[test]
fn single_scattering_matches_the_closed_form() {
    // τ along the normal = scale·ρ·H·σ(z) ≤ 0.5: thin, but every term of the closed
    // form matters. ρ = 1.5 is exact in f16. ~200k paths per configuration give a
    // standard error below 0.5%, so a 2% bias fails at 4σ.
    let (rho, thickness, albedo) = (1.5f32, 0.25f32, 0.7f32);
    let scale = 0.5 / (rho * thickness);
    let k = (scale * rho) as f64;
    let cases = [(Vec3::Y, 1.0f32), (Vec3::X, 0.5), (Vec3::new(1.0, 1.0, 0.3).normalize(), 0.3)];
    let pairs = [
        (direction_from_angles(30.0, 0.0), direction_from_angles(45.0, 120.0)),
        (direction_from_angles(40.0, 0.0), direction_from_angles(40.0, 180.0)), // mirror
        (direction_from_angles(60.0, 90.0), direction_from_angles(20.0, -30.0)),
        (direction_from_angles(30.0, 10.0), direction_from_angles(140.0, 200.0)), // transmission
    ];
    for (ci, (fiber, roughness)) in cases.into_iter().enumerate() {
        let v = homogeneous([16, 16, 4], thickness, rho, scale, albedo, fiber, roughness);
        let s = Sggx::fiber(v.voxel(0, 0, 0).orientation(), roughness);
        let lookups: &[Lookup] = if ci == 2 { &[Lookup::Trilinear, Lookup::Nearest] } else { &[Lookup::Trilinear] };
        for &lookup in lookups {
            let mut scene = MeasureScene::new(&v, lookup, None, None).unwrap();
            scene.path = PathSettings { max_depth: Some(2), rr_depth: 5 };
            for (pi, &(wi, wo)) in pairs.iter().enumerate() {
                let (img, _) = scene.render_image(wi, wo, 768, 17 + pi as u64).unwrap();
                let (mean, se) = mean_and_stderr(&img);
                let exact = single_scattering(&s, k, albedo as f64, thickness as f64, wi, wo);
                assert!(se < 0.005 * exact, "case {ci} pair {pi}: too noisy to be a test ({se} vs {exact})");
                assert!((mean - exact).abs() < 4.0 * se, "case {ci} {lookup:?} pair {pi}: {mean} ± {se} vs closed form {exact}");
            }
        }
    }
}

#[test]
fn white_furnace_conserves_energy() {
    // Albedo 1, infinite periodic sheet: everything that enters leaves, either
    // scattered (∫ L |μ_o| dω_o over both hemispheres, estimated with cosine-weighted
    // ω_o: π·E[L]) or unscattered (μ_i·T̄ along −ω_i). Sum = μ_i (unit irradiance
    // perpendicular to the beam). Tolerance: 4 standard errors.
    let v = random_fabric([8, 8, 6], 0.5, 6.0, Vec3::ONE, 3);
    let scene = MeasureScene::new(&v, Lookup::Trilinear, None, None).unwrap();
    let medium = scene.medium();
    let wi = direction_from_angles(35.0, 20.0);
    let light = Light::directional(wi, Vec3::ONE);
    let settings = PathSettings::default();
    let n = 40_000u64;
    let mut stats = PathStats::default();
    let (mut sum, mut sum2) = (0.0f64, 0.0f64);
    for i in 0..n {
        let mut rng = Rng::new(8, 0, i);
        let (u1, u2) = rng.next_2d();
        let (r, phi) = (u1.sqrt(), core::f32::consts::TAU * u2);
        let mut wo = Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt().max(1e-3));
        if i % 2 == 1 {
            wo.z = -wo.z;
        }
        let (tx, ty) = ((rng.next_f32() * 8.0) as usize, (rng.next_f32() * 8.0) as usize);
        let (u, w) = rng.next_2d();
        let (o, d) = scene.sample_ray(tx.min(7), ty.min(7), u, w, wo.normalize());
        // Each hemisphere gets half the samples: π·E[L] per hemisphere = 2π·E[L] overall.
        let x = 2.0 * core::f64::consts::PI * radiance(medium, &Lighting::from(&light), &settings, o, d, &mut rng, &mut stats).x as f64;
        sum += x;
        sum2 += x * x;
    }
    let scattered = sum / n as f64;
    let se_scattered = ((sum2 / n as f64 - scattered * scattered) / n as f64).sqrt();
    // Unscattered: transmittance through the sheet along −ω_i from random top points.
    let m = 20_000u64;
    let (mut tsum, mut tsum2) = (0.0f64, 0.0f64);
    for i in 0..m {
        let mut rng = Rng::new(9, 0, i);
        let p = Vec3::new(rng.next_f32(), rng.next_f32(), 0.5);
        let ray = GridRay::new(&medium.medium, p, -wi);
        let t = medium.transmittance(&ray, 0.0, f32::INFINITY, &mut rng).0 as f64;
        tsum += t;
        tsum2 += t * t;
    }
    let t_mean = tsum / m as f64;
    let se_t = ((tsum2 / m as f64 - t_mean * t_mean) / m as f64).sqrt();
    let mu_i = wi.z as f64;
    let total = (scattered + mu_i * t_mean) / mu_i;
    let se = (se_scattered * se_scattered + (mu_i * se_t).powi(2)).sqrt() / mu_i;
    assert!(t_mean < 0.3, "the sheet must scatter most light to be a test: T̄ = {t_mean}");
    assert!(stats.scatterings as f64 / n as f64 > 3.0, "multiple scattering must matter");
    assert!(se < 0.01, "too noisy: {se}");
    assert!((total - 1.0).abs() < 4.0 * se, "R + T = {total} ± {se} (scattered {scattered}, direct {t_mean})");
}

#[test]
fn measured_reflectance_is_reciprocal() {
    // The tile-averaged BRDF f = L/(E·μ_i) of the periodic sheet is symmetric:
    // L(ω_i → ω_o)/μ_i = L(ω_o → ω_i)/μ_o, with full multiple scattering.
    let v = random_fabric([16, 16, 8], 0.5, 4.0, Vec3::new(0.9, 0.7, 0.5), 21);
    let scene = MeasureScene::new(&v, Lookup::Trilinear, None, None).unwrap();
    for (k, (a, b)) in [(direction_from_angles(30.0, 20.0), direction_from_angles(65.0, 200.0)), (direction_from_angles(50.0, 0.0), direction_from_angles(45.0, 170.0))].into_iter().enumerate() {
        let (ia, _) = scene.render_image(a, b, 64, 100 + k as u64).unwrap();
        let (ib, _) = scene.render_image(b, a, 64, 200 + k as u64).unwrap();
        let ((ma, sa), (mb, sb)) = (mean_and_stderr(&ia), mean_and_stderr(&ib));
        let (fa, fb) = (ma / a.z as f64, mb / b.z as f64);
        let se = ((sa / a.z as f64).powi(2) + (sb / b.z as f64).powi(2)).sqrt();
        assert!(se < 0.02 * fa, "too noisy: {se} vs {fa}");
        assert!((fa - fb).abs() < 4.0 * se, "pair {k}: f(ω_i, ω_o) = {fa}, f(ω_o, ω_i) = {fb}, σ = {se}");
    }
}

#[test]
fn error_falls_as_one_over_sqrt_spp() {
    // Two independent renders at N spp differ by a zero-mean error with variance
    // 2σ²/N: the RMS difference must fall with slope −1/2 in log-log over N = 1…64.
    // The estimated slope's spread with 256 texels is ≈ 0.02; bound ±0.08.
    let v = random_fabric([16, 16, 8], 0.5, 4.0, Vec3::splat(0.8), 5);
    let scene = MeasureScene::new(&v, Lookup::Trilinear, None, None).unwrap();
    let (wi, wo) = (direction_from_angles(30.0, 0.0), direction_from_angles(20.0, 150.0));
    let spps = [1u32, 4, 16, 64];
    let rms: Vec<f64> = spps
        .iter()
        .map(|&n| {
            let a = scene.render_image(wi, wo, n, 1000 + n as u64).unwrap().0;
            let b = scene.render_image(wi, wo, n, 2000 + n as u64).unwrap().0;
            let ss: f64 = a.pixels.iter().zip(&b.pixels).map(|(p, q)| (*p - *q).length_squared() as f64).sum();
            (ss / a.pixels.len() as f64).sqrt()
        })
        .collect();
    let xs: Vec<f64> = spps.iter().map(|&n| (n as f64).ln()).collect();
    let ys: Vec<f64> = rms.iter().map(|r| r.ln()).collect();
    let (mx, my) = (xs.iter().sum::<f64>() / 4.0, ys.iter().sum::<f64>() / 4.0);
    let slope = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum::<f64>() / xs.iter().map(|x| (x - mx) * (x - mx)).sum::<f64>();
    assert!(rms[3] > 0.0);
    assert!((slope + 0.5).abs() < 0.08, "slope {slope}, RMS differences {rms:?}");
}

#[test]
fn output_is_identical_for_any_thread_count() {
    let v = random_fabric([8, 8, 6], 0.5, 4.0, Vec3::new(0.9, 0.6, 0.3), 9);
    let traced = TracedMedium::new(&v, MediumOptions::default()).unwrap();
    let camera = Camera { origin: Vec3::new(0.5, -1.5, 1.2), target: Vec3::new(0.5, 0.5, 0.25), up: Vec3::Z, projection: Projection::Perspective { fov_x_deg: 40.0 }, width: 24, height: 16 };
    let light = Light::Point { position: Vec3::new(1.0, -0.5, 1.5), intensity: Vec3::splat(3.0) };
    let settings = RenderSettings { spp: 4, seed: 3, path: PathSettings::default() };
    let scene = MeasureScene::new(&v, Lookup::Trilinear, None, None).unwrap();
    let pairs = [(direction_from_angles(30.0, 0.0), direction_from_angles(10.0, 90.0)), (direction_from_angles(70.0, 45.0), direction_from_angles(50.0, 225.0))];
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let (img, stats) = render(&traced, &camera, &Lighting::from(&light), &settings, None).unwrap();
            let (texel, _) = scene.measure_texel((3, 5), &pairs, 300, 4).unwrap();
            let (m, _) = scene.render_image(pairs[0].0, pairs[0].1, 3, 4).unwrap();
            (img, stats.paths, texel, m)
        })
    };
    let (a, b) = (run(1), run(2));
    assert!(a.0.mean() > 0.0 && a.2.iter().all(|v| v.x > 0.0));
    assert_eq!(a, b);
}

#[test]
fn mask_is_the_same_as_removing_the_voxels() {
    let v = random_fabric([8, 8, 6], 0.5, 4.0, Vec3::splat(0.8), 12);
    // Remove the top two layers, once by mask and once by zeroing ρ in a copy (keeping
    // α and ω_f, which still enter interpolation in both).
    let mut mask = vec![false; v.voxels().len()];
    let mut cut = v.clone();
    for z in 4..6 {
        for y in 0..8 {
            for x in 0..8 {
                mask[v.index(x, y, z)] = true;
                let old = *v.voxel(x, y, z);
                cut.set(x, y, z, Voxel { density: 0, ..old });
            }
        }
    }
    let (wi, wo) = (direction_from_angles(30.0, 0.0), direction_from_angles(20.0, 150.0));
    let masked = MeasureScene::new(&v, Lookup::Trilinear, None, Some(&mask)).unwrap().render_image(wi, wo, 8, 1).unwrap().0;
    let removed = MeasureScene::new(&cut, Lookup::Trilinear, None, None).unwrap().render_image(wi, wo, 8, 1).unwrap().0;
    let full = MeasureScene::new(&v, Lookup::Trilinear, None, None).unwrap().render_image(wi, wo, 8, 1).unwrap().0;
    assert_eq!(masked, removed);
    assert_ne!(masked, full);
    let all = vec![true; v.voxels().len()];
    let empty = MeasureScene::new(&v, Lookup::Trilinear, None, Some(&all)).unwrap().render_image(wi, wo, 4, 1).unwrap().0;
    assert!(empty.pixels.iter().all(|p| *p == Vec3::ZERO));
}

#[test]
fn measurement_rays_pass_through_the_surface_point() {
    let v = random_fabric([8, 4, 6], 0.5, 4.0, Vec3::splat(0.8), 1);
    let heights: Vec<f32> = (0..32).map(|i| 0.3 + 0.005 * i as f32).collect();
    let scene = MeasureScene::new(&v, Lookup::Trilinear, Some(&heights), None).unwrap();
    for wo in [direction_from_angles(0.0, 0.0), direction_from_angles(70.0, 30.0), direction_from_angles(120.0, 200.0)] {
        let (o, d) = scene.sample_ray(5, 2, 0.25, 0.75, wo);
        assert!(d.abs_diff_eq(-wo, 1e-6));
        // Start on the slab face on ω_o's side, inside the base tile.
        assert!((o.z - if wo.z > 0.0 { 0.5 } else { 0.0 }).abs() < 1e-5 && (0.0..1.0).contains(&o.x) && (0.0..1.0).contains(&o.y), "{o}");
        // Following the ray to the surface height lands on the jittered point, modulo
        // whole tiles.
        let s = o + d * ((heights[5 + 8 * 2] - o.z) / d.z);
        let (fx, fy) = ((s.x - 5.25 / 8.0).rem_euclid(1.0), (s.y - 2.75 / 4.0).rem_euclid(1.0));
        assert!(fx.min(1.0 - fx) < 1e-5 && fy.min(1.0 - fy) < 1e-5, "{s}");
    }
    assert!(MeasureScene::new(&v, Lookup::Trilinear, Some(&heights[1..]), None).is_err());
    assert!(scene.render_image(Vec3::Z, Vec3::new(1.0, 0.0, 1e-4), 1, 0).is_err());
    assert!(scene.render_image(Vec3::ZERO, Vec3::Z, 1, 0).is_err());
    assert!(scene.measure_texel((8, 0), &[(Vec3::Z, Vec3::Z)], 1, 0).is_err());
}

/// The memory bound: a 1024×1024×128 fabric renders within 24 GiB. Ignored by
/// default (it allocates ~2.2 GB); run with
/// `cargo test --release -p fabric-baker large_fabric -- --ignored --nocapture`.
#[test]
#[ignore]
fn large_fabric_renders_within_memory_budget() {
    let dims = [1024usize, 1024, 128];
    let mut v = FabricVolume::new(dims, Aabb::new(Vec3::ZERO, Vec3::new(4.0, 4.0, 0.5)), MaterialParams { density_scale: 200.0, roughness: 0.3 });
    // Two layers of yarns: warp along x in z ∈ [40, 70), weft along y in z ∈ [70, 100).
    for z in 40..100 {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                let (along, across) = if z < 70 { (Vec3::X, y) } else { (Vec3::Y, x) };
                if across % 16 < 12 {
                    v.set(x, y, z, Voxel::pack(1.0, Vec3::splat(0.8), along));
                }
            }
        }
    }
    let traced = TracedMedium::new(&v, MediumOptions { periodic: true, ..Default::default() }).unwrap();
    let camera = Camera::orbit_orthographic(30.0, 20.0, Vec3::new(2.0, 2.0, 0.5), 4.0, 4.0, 64, 64);
    let (img, stats) = render(&traced, &camera, &Lighting::from(&Light::directional(direction_from_angles(40.0, -60.0), Vec3::ONE)), &RenderSettings { spp: 2, ..Default::default() }, None).unwrap();
    let peak = crate::memory::peak_rss_bytes().expect("the peak RSS (VmHWM in /proc/self/status)");
    eprintln!("1024x1024x128: packed volume {:.2} GB, peak RSS {:.2} GB, {:.0} paths/s, mean {}", v.memory_bytes() as f64 / 1e9, peak as f64 / 1e9, stats.paths_per_second(), img.mean());
    assert!(img.mean() > 0.0 && img.first_non_finite().is_none());
    assert!(peak < 24 * (1 << 30), "peak RSS {peak} bytes exceeds 24 GiB");
}
