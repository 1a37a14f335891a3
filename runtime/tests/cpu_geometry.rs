//! The CPU renderer's geometry against exact answers: the height-field march (parallax
//! and occlusion) against independent ray–surface intersections, shadow rays against
//! brute force, and a single flyaway voxel against an exact ray–box test.

use fabric_runtime::brdf::{ClothParams, cloth_fiber_frame};
use fabric_runtime::cpu::shading::texel_response;
use fabric_runtime::cpu::{CpuRenderOptions, LevelChoice, Scene, ShadowMode};
use fabric_runtime::hybrid::{FlyawayInput, HybridModel, Tile, examples};
use fabric_runtime::scene::{Camera, Light, Projection, Ray};
use glam::{Vec2, Vec3};

fn tile(height_scale: f32) -> Tile {
    Tile { origin: Vec2::ZERO, size: Vec2::ONE, top_z: 1.0, height_scale, voxel_depth: 0.05 }
}

fn diffuse() -> ClothParams {
    ClothParams::new(Vec3::splat(0.5), 1.5, 0.0, &[])
}

/// The surface depth at (x, y) from the model's samples, written independently of the
/// renderer: bilinear between texel centres, clamped or wrapped (HYBRID_FORMAT.md §5.2).
fn bilinear_depth(m: &HybridModel, x: f32, y: f32, periodic: bool) -> f64 {
    let (w, h) = (m.width() as i64, m.height_px() as i64);
    let u = (x as f64 - m.tile.origin.x as f64) / (m.tile.size.x as f64 / w as f64) - 0.5;
    let v = (y as f64 - m.tile.origin.y as f64) / (m.tile.size.y as f64 / h as f64) - 0.5;
    let (fu, fv) = (u.floor(), v.floor());
    let (s, t) = (u - fu, v - fv);
    let at = |i: i64, j: i64| {
        let (i, j) = if periodic { (i.rem_euclid(w), j.rem_euclid(h)) } else { (i.clamp(0, w - 1), j.clamp(0, h - 1)) };
        m.depth(i as u32, j as u32) as f64
    };
    let (i, j) = (fu as i64, fv as i64);
    (at(i, j) * (1.0 - s) + at(i + 1, j) * s) * (1.0 - t) + (at(i, j + 1) * (1.0 - s) + at(i + 1, j + 1) * s) * t
}

/// First t ≥ t0 where the ray is below the surface, by marching in steps of `step` and
/// bisecting (f64), or None before `t1` / leaving a clamped tile.
fn brute_force_hit(m: &HybridModel, ray: &Ray, t0: f64, t1: f64, step: f64, periodic: bool) -> Option<f64> {
    let g = |t: f64| {
        let p = ray.o.as_dvec3() + ray.d.as_dvec3() * t;
        (m.tile.top_z as f64 - p.z) - bilinear_depth(m, p.x as f32, p.y as f32, periodic)
    };
    let inside = |t: f64| {
        let p = ray.o.as_dvec3() + ray.d.as_dvec3() * t;
        periodic || (p.x >= 0.0 && p.x <= 1.0 && p.y >= 0.0 && p.y <= 1.0)
    };
    let mut a = t0;
    if g(a) >= 0.0 {
        return Some(a);
    }
    while a < t1 {
        let b = (a + step).min(t1);
        if !inside(b) {
            return None;
        }
        if g(b) >= 0.0 {
            let (mut lo, mut hi) = (a, b);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if g(mid) >= 0.0 { hi = mid } else { lo = mid }
            }
            return Some(hi);
        }
        a = b;
    }
    None
}

/// Whether the ray is above the surface somewhere in [t0, t1] (inside the tile).
fn emerges(m: &HybridModel, ray: &Ray, t0: f64, t1: f64, periodic: bool) -> bool {
    let mut t = t0;
    while t < t1 {
        let p = ray.o.as_dvec3() + ray.d.as_dvec3() * t;
        if !periodic && (p.x < 0.0 || p.x > 1.0 || p.y < 0.0 || p.y > 1.0) {
            return false;
        }
        if (m.tile.top_z as f64 - p.z) < bilinear_depth(m, p.x as f32, p.y as f32, periodic) {
            return true;
        }
        t += 1e-3;
    }
    false
}

fn options(periodic: bool) -> CpuRenderOptions {
    CpuRenderOptions { periodic, level: LevelChoice::Fixed(0), shadows: ShadowMode::Off, ..Default::default() }
}

fn camera_from(theta_deg: f32, phi_deg: f32, size: u32) -> Camera {
    let dir = fabric_runtime::scene::direction_from_angles(theta_deg, phi_deg);
    let up = if theta_deg < 1.0 { Vec3::Y } else { Vec3::Z };
    Camera { origin: Vec3::new(0.5, 0.5, 0.8) + 3.0 * dir, target: Vec3::new(0.5, 0.5, 0.8), up, projection: Projection::Perspective { fov_x_deg: 28.0 }, width: size, height: size }
}

#[test]
fn tilted_plane_hits_match_the_exact_ray_plane_intersection() {
    // depth = 0.1 + 0.3·x: bilinear interpolation reproduces a linear function exactly
    // between the outermost texel centres; outside them (half a texel) it is clamped flat.
    let n = 20;
    let m = examples::uniform_model(n, n, 1, tile(0.5), |x, _| 0.1 + 0.3 * x, &diffuse(), Vec3::Z, Vec3::X).unwrap();
    let lights = [Light::directional(Vec3::Z, Vec3::ONE)];
    let half = 0.5 / n as f32;
    let mut checked = 0;
    for (theta, phi) in [(0.0, 0.0), (35.0, 20.0), (60.0, 180.0), (75.0, -90.0)] {
        let cam = camera_from(theta, phi, 40);
        let scene = Scene::new(&m, &cam, &lights, options(false)).unwrap();
        for py in 0..40 {
            for px in 0..40 {
                let ray = cam.ray(px as f32 + 0.5, py as f32 + 0.5);
                let got = scene.trace_ray(&ray, 0).surface_t;
                // Exact: o.z + t·d.z = 1 − (0.1 + 0.3·(o.x + t·d.x)) (heights are stored
                // as unorm16 of the height scale: exact to 0.5/65535 = 7.6e-6).
                let (o, d) = (ray.o.as_dvec3(), ray.d.as_dvec3());
                let t = (0.9 - 0.3 * o.x - o.z) / (d.z + 0.3 * d.x);
                let p = o + d * t;
                if p.x < half as f64 + 1e-3 || p.x > 1.0 - half as f64 - 1e-3 || p.y < 1e-3 || p.y > 1.0 - 1e-3 {
                    continue;
                }
                // Rays enter through the tile's top face only (as the GPU's top mesh).
                let entry = o + d * ((1.0 - o.z) / d.z);
                if entry.x < 1e-3 || entry.x > 1.0 - 1e-3 || entry.y < 1e-3 || entry.y > 1.0 - 1e-3 {
                    let outside = entry.x < -1e-3 || entry.x > 1.0 + 1e-3 || entry.y < -1e-3 || entry.y > 1.0 + 1e-3;
                    assert!(!outside || got.is_none(), "view ({theta}, {phi}) pixel ({px}, {py}): entered outside the tile at {entry:?} and hit");
                    continue;
                }
                let got = got.unwrap_or_else(|| panic!("view ({theta}, {phi}) pixel ({px}, {py}): missed the plane at t = {t}"));
                // Tolerance: unorm16 depth quantization (7.6e-6 in depth) over the ray's
                // sine against the plane, plus f32 rounding of t ≈ 3.
                let tol = 7.6e-6 / (d.z + 0.3 * d.x).abs() + 2e-6 * t;
                assert!((got as f64 - t).abs() <= tol, "view ({theta}, {phi}) pixel ({px}, {py}): t = {got}, exact {t}");
                checked += 1;
            }
        }
    }
    assert!(checked > 1000, "{checked} rays checked");
}

/// A bumpy height field: depth = 0.25 + 0.2·sin(2π·2x)·cos(2π·y), periodic in the tile.
fn bumps(n: u32) -> HybridModel {
    let depth = |x: f32, y: f32| 0.25 + 0.2 * (std::f32::consts::TAU * 2.0 * x).sin() * (std::f32::consts::TAU * y).cos();
    examples::uniform_model(n, n, 1, tile(0.5), depth, &diffuse(), Vec3::Z, Vec3::X).unwrap()
}

#[test]
fn bumpy_surface_hits_match_brute_force_with_parallax_and_occlusion() {
    let m = bumps(24);
    let lights = [Light::directional(Vec3::Z, Vec3::ONE)];
    for periodic in [false, true] {
        let (mut checked, mut occluded, mut worst) = (0, 0, 0.0f64);
        for (theta, phi) in [(10.0, 30.0), (55.0, 0.0), (70.0, 100.0), (78.0, 200.0)] {
            let cam = camera_from(theta, phi, 32);
            let scene = Scene::new(&m, &cam, &lights, options(periodic)).unwrap();
            for py in 0..32 {
                for px in 0..32 {
                    let ray = cam.ray(px as f32 + 0.37, py as f32 + 0.61);
                    let Some(t_top) = scene.enter_top(&ray) else { continue };
                    let got = scene.trace_ray(&ray, 0).surface_t.map(|t| t as f64);
                    let t_end = t_top as f64 + 0.5 / -(ray.d.z as f64);
                    // Steps of 2e-4 tile widths: 1/200 of a texel.
                    let want = brute_force_hit(&m, &ray, t_top as f64, t_end, 2e-4, periodic);
                    match (got, want) {
                        (Some(a), Some(b)) => {
                            worst = worst.max((a - b).abs());
                            // f32 ray parameters: a few ulps of t (t reaches 140 on the
                            // periodic horizon), and the bisection's 2⁻²⁰ of a leaf.
                            assert!((a - b).abs() < 1e-5 + 5e-7 * b, "periodic {periodic}, view ({theta}, {phi}), pixel ({px}, {py}): {a} vs {b}");
                            // Occlusion: past the hit the ray comes out above the surface
                            // again, i.e. the hit is on a crest hiding what lies behind it.
                            occluded += emerges(&m, &ray, b + 1e-3, t_end, periodic) as u32;
                        }
                        (None, None) => {}
                        (a, b) => panic!("periodic {periodic}, view ({theta}, {phi}), pixel ({px}, {py}): renderer {a:?}, brute force {b:?} at {:?}, entry {:?}", b.map(|t| ray.at(t as f32)), ray.at(t_top)),
                    }
                    checked += 1;
                }
            }
        }
        println!("periodic {periodic}: {checked} rays, worst |Δt| {worst:.1e}, {occluded} hits hide surface behind them");
        assert!(checked > 900 && occluded > 50, "{checked} rays, {occluded} occluding hits");
    }
}

#[test]
fn periodic_rays_cross_many_repeats_at_grazing_angles() {
    let m = bumps(16);
    let lights = [Light::directional(Vec3::Z, Vec3::ONE)];
    let cam = camera_from(86.0, 33.0, 24);
    let scene = Scene::new(&m, &cam, &lights, options(true)).unwrap();
    let mut hits = 0;
    for py in 0..24 {
        for px in 0..24 {
            let ray = cam.ray(px as f32 + 0.5, py as f32 + 0.5);
            let Some(t_top) = scene.enter_top(&ray) else { continue };
            let got = scene.trace_ray(&ray, 0);
            assert!(!got.step_limited, "pixel ({px}, {py})");
            let want = brute_force_hit(&m, &ray, t_top as f64, t_top as f64 + 0.5 / -(ray.d.z as f64), 2e-4, true);
            match (got.surface_t, want) {
                (Some(a), Some(b)) => assert!((a as f64 - b).abs() < 5e-5, "pixel ({px}, {py}): {a} vs {b}"),
                (a, b) => panic!("pixel ({px}, {py}): {a:?} vs {b:?}"),
            }
            hits += 1;
        }
    }
    assert!(hits > 100);
}

/// A ray a hundredth of a degree above the horizon of a periodic sheet crosses thousands
/// of repeats above the crests: its march starts at the shallowest depth, and after
/// `SKIM_TILES` repeats below it takes the next one's flat top, so it ends within a bounded
/// number of steps on the sheet's crest plane instead of running out of them (at 89.99°
/// over a felt, lavapipe drew 160×90 in 15 s before, 2.3 s after; 57 ms at 85°).
#[test]
fn rays_at_the_horizon_end_on_the_crests_within_a_bounded_march() {
    use fabric_runtime::cpu::heightfield::SKIM_TILES;
    // A flat sheet with one spike per repeat: a ray just below the spike's depth meets one
    // only where it happens to pass over one, so it skims repeat after repeat.
    let spike = |x: f32, y: f32| if (x - 0.53).abs() < 0.04 && (y - 0.47).abs() < 0.04 { 0.05 } else { 0.3 };
    let m = examples::uniform_model(16, 16, 1, tile(0.5), spike, &diffuse(), Vec3::Z, Vec3::X).unwrap();
    let lights = [Light::directional(Vec3::Z, Vec3::ONE)];
    let (shallowest, deepest) = (0.05f32, 0.3f32);
    // Parallel rays, every one at 89.99°.
    let cam = Camera::orbit_orthographic(89.99, 33.0, Vec3::new(0.5, 0.5, m.tile.top_z), 4.0, 1.0, 24, 24);
    let scene = Scene::new(&m, &cam, &lights, options(true)).unwrap();
    let (mut hits, mut most) = (0, 0);
    for py in 0..24 {
        for px in 0..24 {
            let ray = cam.ray(px as f32 + 0.5, py as f32 + 0.5);
            let Some(t_top) = scene.enter_top(&ray) else { continue };
            let got = scene.trace_ray(&ray, 0);
            assert!(!got.step_limited, "pixel ({px}, {py}): {} steps", got.steps);
            most = most.max(got.steps);
            // A repeat below its root bound costs a descent of a few steps (112 at most
            // here; 582 without the rule, where STEPS_PER_FLOOR ended the skim).
            assert!(got.steps <= (SKIM_TILES + 4) * 8, "pixel ({px}, {py}): {} steps", got.steps);
            let t = got.surface_t.unwrap_or_else(|| panic!("pixel ({px}, {py}) missed the sheet"));
            let depth = m.tile.top_z - ray.at(t).z;
            assert!(t > t_top && depth >= shallowest - 1e-3 && depth <= deepest + 1e-3, "pixel ({px}, {py}): depth {depth}");
            hits += 1;
        }
    }
    eprintln!("{hits} hits, most steps {most}");
    assert!(hits > 250, "{hits}");
}

#[test]
fn shadow_rays_match_brute_force() {
    let m = bumps(24);
    // A low sun: much of the relief is in shadow.
    let wi = fabric_runtime::scene::direction_from_angles(68.0, 20.0);
    let scene_cam = camera_from(0.0, 0.0, 8);
    let lights = [Light::directional(wi, Vec3::ONE)];
    let scene = Scene::new(&m, &scene_cam, &lights, options(true)).unwrap();
    let (mut shadowed, mut total, mut disagree) = (0, 0, 0);
    for j in 0..60 {
        for i in 0..60 {
            let (x, y) = ((i as f32 + 0.31) / 60.0, (j as f32 + 0.77) / 60.0);
            let p = Vec3::new(x, y, 1.0 - scene.tracer.depth_at(x, y));
            let (blocked, limited) = scene.tracer.occluded(p, wi, f32::INFINITY, 4096);
            assert!(!limited);
            // Brute force from a hair above the surface along wi, to the top plane.
            let ray = Ray::new(p, wi);
            let t_top = (1.0 - p.z as f64) / wi.z as f64;
            let want = brute_force_hit(&m, &ray, 2e-3, t_top, 1e-4, true).is_some();
            total += 1;
            shadowed += want as u32;
            disagree += (blocked != want) as u32;
        }
    }
    println!("{shadowed} of {total} points shadowed; {disagree} disagree with brute force");
    assert!(shadowed > 400 && shadowed < 3200, "a real mix of light and shadow: {shadowed}");
    // Disagreements only where the shadow ray grazes the relief within the offsets
    // (1e-3 texel start, 1e-4 texel bias vs 2e-3 start here): a handful at most.
    assert!(disagree <= 5, "{disagree} disagreements");
}

#[test]
fn a_single_flyaway_voxel_in_front_of_the_surface() {
    // Flat surface at depth 0.4; one voxel in column (4, 5) (x ∈ [0.4, 0.5],
    // y ∈ [0.5, 0.6]) at depth index 2 (depth [0.1, 0.15] ↔ z ∈ [0.85, 0.9]).
    let surface = ClothParams::new(Vec3::new(0.2, 0.3, 0.4), 1.5, 0.0, &[]);
    let mut m = examples::uniform_model(10, 10, 1, tile(0.5), |_, _| 0.4, &surface, Vec3::Z, Vec3::X).unwrap();
    let fiber = Vec3::new(1.0, 0.4, 0.2);
    let fly_params = examples::silk_params();
    examples::add_flyaways(&mut m, 0, &[(4, 5, FlyawayInput { depth: 2, alpha: 1.0, tangent: fiber, param: 0 })], &fly_params).unwrap();
    let light = Light::directional(Vec3::new(0.3, -0.2, 1.0), Vec3::splat(2.0));
    let lights = [light];
    let decoded_fly = m.levels[0].flyaways.as_ref().unwrap().table.brdf_in_frame(0, fabric_runtime::brdf::cloth_frame(Vec3::Z, Vec3::X));
    let fiber_q = m.levels[0].flyaways.as_ref().unwrap().nodes[0].tangent();
    let decoded_surface = m.levels[0].texel_brdf(0, 0);
    let (lo, hi) = (Vec3::new(0.4, 0.5, 0.85), Vec3::new(0.5, 0.6, 0.9));
    let (mut on_voxel, mut on_surface) = (0, 0);
    for (theta, phi) in [(0.0, 0.0), (40.0, 30.0), (65.0, 250.0)] {
        let dir = fabric_runtime::scene::direction_from_angles(theta, phi);
        let cam = Camera { origin: Vec3::new(0.45, 0.55, 0.6) + 2.0 * dir, target: Vec3::new(0.45, 0.55, 0.6), up: if theta == 0.0 { Vec3::Y } else { Vec3::Z }, projection: Projection::Orthographic { extent: 0.4 }, width: 64, height: 64 };
        let scene = Scene::new(&m, &cam, &lights, options(false)).unwrap();
        for py in 0..64 {
            for px in 0..64 {
                let ray = cam.ray(px as f32 + 0.5, py as f32 + 0.5);
                let got = scene.trace_ray(&ray, 0);
                // Exact ray–box slab test (f64), skipping rays within 1e-5 of an edge.
                let (o, d) = (ray.o.as_dvec3(), ray.d.as_dvec3());
                let (mut t0, mut t1, mut margin) = (f64::NEG_INFINITY, f64::INFINITY, f64::INFINITY);
                for a in 0..3 {
                    if d[a].abs() < 1e-12 {
                        if o[a] < lo[a] as f64 || o[a] > hi[a] as f64 {
                            t0 = f64::INFINITY;
                        }
                        continue;
                    }
                    let (ta, tb) = ((lo[a] as f64 - o[a]) / d[a], (hi[a] as f64 - o[a]) / d[a]);
                    t0 = t0.max(ta.min(tb));
                    t1 = t1.min(ta.max(tb));
                }
                if t1 >= t0 {
                    let p = o + d * (0.5 * (t0 + t1));
                    for a in 0..3 {
                        margin = margin.min((p[a] - lo[a] as f64).abs()).min((p[a] - hi[a] as f64).abs());
                    }
                }
                if (t1 - t0).abs() < 1e-5 || (t1 > t0 && margin < 1e-5) {
                    continue;
                }
                let wo = -ray.d;
                let s = light.sample(Vec3::ZERO);
                if t1 > t0 {
                    let frame_b = fabric_runtime::cpu::shading::in_fiber_frame(decoded_fly, fiber_q, wo, m.meta.fiber_lobes);
                    let want = s.irradiance * texel_response(&frame_b, s.wi, wo, fabric_runtime::brdf::BrdfReading::Bounded, fabric_runtime::brdf::DiffuseLaw::Lambert);
                    assert!((got.radiance - want).abs().max_element() <= 1e-5 * want.max_element().max(1e-3), "view ({theta}, {phi}) pixel ({px}, {py}): {} vs flyaway {want}", got.radiance);
                    assert_eq!(got.flyaway_opacity, 1.0);
                    // The fiber frame's t is the fiber axis.
                    assert!(cloth_fiber_frame(fiber_q, wo).t.cross(fiber).length() < 1e-3);
                    on_voxel += 1;
                } else if got.surface_t.is_some() {
                    let want = s.irradiance * texel_response(&decoded_surface, s.wi, wo, fabric_runtime::brdf::BrdfReading::Bounded, fabric_runtime::brdf::DiffuseLaw::Lambert);
                    assert!((got.radiance - want).abs().max_element() <= 1e-5 * want.max_element(), "view ({theta}, {phi}) pixel ({px}, {py}): {} vs surface {want}", got.radiance);
                    assert_eq!(got.flyaway_opacity, 0.0);
                    on_surface += 1;
                }
            }
        }
    }
    assert!(on_voxel > 150 && on_surface > 3000, "{on_voxel} voxel pixels, {on_surface} surface pixels");
}
