//! Checks of environment lighting in the path tracer: a white furnace under a constant
//! map, single scattering under the built-in sky against the closed form integrated over
//! the map (both MIS strategies matter there), and the directional-light limit of a tiny
//! bright patch. Tolerances are multiples of the measured standard error.

use fabric_runtime::scene::{EnvMap, EnvMapOptions, Light, Sky, direction_from_angles};
use glam::{DVec3, Vec3};

use super::integrator::{Lighting, PathSettings, PathStats, radiance};
use super::measure::MeasureScene;
use super::medium::Lookup;
use super::rng::Rng;
use super::sggx::Sggx;
use super::validation::{homogeneous, random_fabric, single_scattering};
use crate::volume::FabricVolume;

/// Mean and standard error of the mean channel of `n` paths leaving random points of
/// the periodic sheet toward `wo`.
fn sheet_radiance(v: &FabricVolume, lighting: &Lighting<'_>, path: PathSettings, wo: Vec3, n: u64, seed: u64) -> (f64, f64, PathStats) {
    let scene = MeasureScene::new(v, Lookup::Trilinear, None, None).unwrap();
    let [w, h, _] = v.dims();
    let mut stats = PathStats::default();
    let (mut sum, mut sum2) = (0.0f64, 0.0f64);
    for i in 0..n {
        let mut rng = Rng::new(seed, 0, i);
        let (tx, ty) = ((rng.next_f32() * w as f32) as usize, (rng.next_f32() * h as f32) as usize);
        let (u, s) = rng.next_2d();
        let (o, d) = scene.sample_ray(tx.min(w - 1), ty.min(h - 1), u, s, wo);
        let l = radiance(scene.medium(), lighting, &path, o, d, &mut rng, &mut stats);
        let x = (l.x + l.y + l.z) as f64 / 3.0;
        sum += x;
        sum2 += x * x;
    }
    let mean = sum / n as f64;
    (mean, ((sum2 / n as f64 - mean * mean) / n as f64).sqrt(), stats)
}

#[test]
fn white_furnace_under_a_constant_environment() {
    // Albedo 1 everywhere and L = 0.5 from every direction: every path, scattered or
    // not, sees exactly 0.5 in expectation, from above and from below the sheet.
    let v = random_fabric([8, 8, 6], 0.5, 6.0, Vec3::ONE, 3);
    let env = EnvMap::constant(Vec3::splat(0.5)).unwrap();
    let lighting = Lighting::env(&env);
    for (k, wo) in [direction_from_angles(20.0, 30.0), direction_from_angles(75.0, -100.0), direction_from_angles(130.0, 200.0)].into_iter().enumerate() {
        let (mean, se, stats) = sheet_radiance(&v, &lighting, PathSettings::default(), wo, 20_000, 40 + k as u64);
        assert!(stats.scatterings as f64 / stats.paths as f64 > 2.0, "view {k}: multiple scattering must matter");
        assert!(se < 0.004, "view {k}: too noisy to be a test ({se})");
        assert!((mean - 0.5).abs() < 4.0 * se, "view {k}: furnace gives {mean} ± {se}, expected 0.5");
    }
}

/// z-mirror of a direction.
fn flip(w: Vec3) -> Vec3 {
    Vec3::new(w.x, w.y, -w.z)
}

#[test]
fn single_scattering_under_the_sky_matches_the_closed_form() {
    // A thin homogeneous slab with in-plane fibers (S even in z, so light from below is
    // the mirror case of light from above), max_depth = 2: the radiance toward ω_o is
    //   ∫ L(ω_i) SS(ω_i, ω_o) dω_i  +  L(−ω_o) e^{−H a_o}   (the unscattered background),
    // integrated by quadrature over the map, 4×4 points per texel. The sky's sun is a
    // small bright disk and its sky is dim and broad: map sampling wins for the first,
    // phase sampling for sharp fibers; a wrong MIS weight biases one of them.
    let (rho, thickness, albedo) = (1.5f32, 0.25f32, 0.8f32);
    let scale = 0.5 / (rho * thickness);
    let k = (scale * rho) as f64;
    let sky = Sky { width: 256, height: 128, sun_radius_deg: 4.0, ..Sky::default() };
    let env = sky.env_map(EnvMapOptions { scale: 1.0, rotate_deg: 25.0 }).unwrap();
    let lighting = Lighting::env(&env);
    let (w, h) = (env.width() as usize, env.height() as usize);
    for (ci, roughness) in [0.5f32, 0.15].into_iter().enumerate() {
        let v = homogeneous([16, 16, 4], thickness, rho, scale, albedo, Vec3::X, roughness);
        let s = Sggx::fiber(v.voxel(0, 0, 0).orientation(), roughness);
        for (vi, wo) in [direction_from_angles(0.0, 0.0), direction_from_angles(40.0, 120.0), direction_from_angles(35.0, 120.0 + 180.0), direction_from_angles(150.0, 60.0)].into_iter().enumerate() {
            let ss = |wi: Vec3| if wi.z > 0.0 { single_scattering(&s, k, albedo as f64, thickness as f64, wi, wo) } else if wi.z < 0.0 { single_scattering(&s, k, albedo as f64, thickness as f64, flip(wi), flip(wo)) } else { 0.0 };
            let mut exact = DVec3::ZERO;
            let sub = 4;
            for y in 0..h {
                for x in 0..w {
                    let texel = env.texel(x as u32, y as u32).as_dvec3();
                    let mut acc = 0.0;
                    for j in 0..sub {
                        // Equal solid angle per sub-row: uniform in cos θ.
                        let (c0, c1) = ((std::f64::consts::PI * y as f64 / h as f64).cos(), (std::f64::consts::PI * (y + 1) as f64 / h as f64).cos());
                        let ct = c0 + (j as f64 + 0.5) / sub as f64 * (c1 - c0);
                        let vv = (ct.acos() / std::f64::consts::PI) as f32;
                        for i in 0..sub {
                            let u = (x as f32 + (i as f32 + 0.5) / sub as f32) / w as f32;
                            acc += ss(env.direction(u, vv));
                        }
                    }
                    let omega = fabric_runtime::scene::envmap::row_solid_angle(y, h, w);
                    exact += texel * acc / (sub * sub) as f64 * omega;
                }
            }
            let a_o = k * s.projected_area(wo) as f64 / (wo.z as f64).abs();
            exact += env.eval(-wo).as_dvec3() * (-(thickness as f64) * a_o).exp();
            let exact = (exact.x + exact.y + exact.z) / 3.0;
            let path = PathSettings { max_depth: Some(2), rr_depth: 5 };
            let (mean, se, _) = sheet_radiance(&v, &lighting, path, wo, 120_000, 70 + vi as u64);
            assert!(se < 0.006 * exact, "case {ci} view {vi}: too noisy to be a test ({se} vs {exact})");
            assert!((mean - exact).abs() < 4.0 * se, "case {ci} (σ = {roughness}) view {vi}: {mean} ± {se} vs closed form {exact}");
        }
    }
}

#[test]
fn a_tiny_bright_patch_acts_as_a_directional_light() {
    // A black sky with a 0.4°-radius sun of irradiance E against a directional light of
    // irradiance E from the sun's centre, full multiple scattering. The patch's angular
    // size moves the image by O(0.4°) of lobe width: ≤ 1% on a rough fabric.
    let v = random_fabric([8, 8, 6], 0.5, 4.0, Vec3::new(0.9, 0.7, 0.5), 21);
    let sun_dir = direction_from_angles(40.0, -60.0);
    let sky = Sky { sun_dir, sun_irradiance: Vec3::new(1.0, 0.8, 0.6), sun_radius_deg: 0.4, zenith: Vec3::ZERO, horizon: Vec3::ZERO, ground: Vec3::ZERO, width: 2048, height: 1024 };
    let env = sky.env_map(EnvMapOptions::default()).unwrap();
    let light = Light::directional(sun_dir, sky.sun_irradiance);
    for (k, wo) in [direction_from_angles(30.0, 100.0), direction_from_angles(60.0, 120.0), direction_from_angles(140.0, 0.0)].into_iter().enumerate() {
        let (a, sa, _) = sheet_radiance(&v, &Lighting::env(&env), PathSettings::default(), wo, 30_000, 90 + k as u64);
        let (b, sb, _) = sheet_radiance(&v, &Lighting::from(&light), PathSettings::default(), wo, 30_000, 190 + k as u64);
        let se = (sa * sa + sb * sb).sqrt();
        assert!(se < 0.01 * b, "view {k}: too noisy ({se} vs {b})");
        assert!((a - b).abs() < 4.0 * se + 0.01 * b, "view {k}: patch {a} ± {sa} vs directional {b} ± {sb}");
    }
}
