//! The baker's probe (`cpu::probe`) sees what the CPU renderer shows: the same surface
//! hit, the texel under it, the same light visibility, and `measure_image` equals the
//! renderer's radiance along the same rays.

use fabric_runtime::cpu::probe::measure_image;
use fabric_runtime::cpu::{CpuRenderOptions, Scene, ShadowMode};
use fabric_runtime::hybrid::examples::synthetic_model;
use fabric_runtime::scene::{Light, Ray};
use glam::Vec3;

#[test]
fn the_probe_hits_the_texel_the_renderer_shows() {
    let model = synthetic_model(32, 7);
    let wi = Vec3::new(0.9, -0.3, 0.08).normalize();
    let lights = [Light::directional(wi, Vec3::ONE)];
    let options = CpuRenderOptions { periodic: true, shadows: ShadowMode::On, ..Default::default() };
    let scene = Scene::for_rays(&model, &lights, options.clone()).unwrap();
    let (o, s) = (model.tile.origin, model.tile.size);
    let mut hits = 0;
    let mut shadowed = 0;
    for k in 0..2000u32 {
        // Oblique rays from the top plane, as the measurement traces them.
        let (u, v) = ((k % 47) as f32 / 47.0, (k % 53) as f32 / 53.0);
        let d = Vec3::new(0.6 * ((k % 7) as f32 - 3.0) / 3.0, 0.5 * ((k % 5) as f32 - 2.0) / 2.0, -1.0).normalize();
        let ray = Ray::new(Vec3::new(o.x + u * s.x, o.y + v * s.y, model.tile.top_z), d);
        let trace = scene.trace_ray(&ray, 0);
        let probe = scene.probe_ray(&ray, 0, true);
        assert_eq!(probe.surface.map(|h| h.point), trace.surface_t.map(|t| ray.at(t)), "ray {k}");
        if let Some(h) = probe.surface {
            hits += 1;
            let p = ray.at(trace.surface_t.unwrap());
            assert_eq!(h.texel, scene.texel_at(p, 0));
            let (blocked, _) = scene.tracer.occluded(p, wi, f32::INFINITY, options.max_steps);
            assert_eq!(h.visibility, if blocked { 0.0 } else { 1.0 });
            shadowed += blocked as u32;
        }
    }
    assert_eq!(hits, 2000, "a periodic tile is always hit");
    assert!(shadowed > 0, "the test should see some shadowed hits");
}

#[test]
fn measure_image_is_the_renderers_radiance_along_the_given_rays() {
    let model = synthetic_model(16, 3);
    let wi = Vec3::new(-0.2, 0.4, 0.8).normalize();
    let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
    let (o, texel, top) = (model.tile.origin, model.texel_size(), model.tile.top_z);
    let ray = |x: u32, y: u32, s: u32| Ray::new(Vec3::new(o.x + (x as f32 + 0.25 + 0.5 * s as f32) * texel.x, o.y + (y as f32 + 0.5) * texel.y, top), -wo);
    let options = CpuRenderOptions::default();
    let image = measure_image(&model, &options, wi, 0, 2, &ray).unwrap();
    let lights = [Light::directional(wi, Vec3::ONE)];
    let scene = Scene::for_rays(&model, &lights, CpuRenderOptions { periodic: true, ..options.clone() }).unwrap();
    for (x, y) in [(0, 0), (5, 9), (15, 15)] {
        let want = 0.5 * (scene.trace_ray(&ray(x, y, 0), 0).radiance + scene.trace_ray(&ray(x, y, 1), 0).radiance);
        assert_eq!(image.get(x, y), want);
    }
    assert!(image.mean() > 0.0);
    assert!(measure_image(&model, &options, wi, 0, 0, &ray).is_err());
    assert!(measure_image(&model, &options, wi, 9, 1, &ray).is_err());
}

#[test]
fn the_volumetric_flag_scales_surface_hits_by_the_factor_and_round_trips() {
    use fabric_runtime::brdf::{ClothLobe, ClothParams};
    use fabric_runtime::cpu::shading::volume_factor;
    use fabric_runtime::hybrid::{Tile, examples::uniform_model, format};
    let tile = Tile { origin: glam::Vec2::ZERO, size: glam::Vec2::ONE, top_z: 0.2, height_scale: 0.2, voxel_depth: 0.0125 };
    let params = ClothParams::new(Vec3::splat(0.3), 1.5, 1.0, &[ClothLobe { k: Vec3::splat(0.5), beta: 0.3, gamma: 1.0 }]);
    let mut model = uniform_model(8, 8, 1, tile, |_, _| 0.1, &params, Vec3::Z, Vec3::X).unwrap();
    let wi = Vec3::new(0.6, 0.1, 0.5).normalize();
    let wo = Vec3::new(-0.3, 0.4, 0.7).normalize();
    let ray = |x: u32, y: u32, _s: u32| Ray::new(Vec3::new((x as f32 + 0.5) / 8.0, (y as f32 + 0.5) / 8.0, 0.2), -wo);
    let plain = measure_image(&model, &CpuRenderOptions::default(), wi, 0, 1, &ray).unwrap();
    model.meta.volumetric = true;
    let scaled = measure_image(&model, &CpuRenderOptions::default(), wi, 0, 1, &ray).unwrap();
    let f = volume_factor(wi, wo);
    assert!(f > 1.0 && f < 2.0, "{f}");
    for (a, b) in plain.pixels.iter().zip(&scaled.pixels) {
        assert!(a.max_element() > 0.0);
        assert!((*b - *a * f).abs().max_element() <= 1e-6 * b.max_element(), "{a} · {f} vs {b}");
    }
    // The flag survives the file; 1.0 readers would reject it as an unknown flag.
    let bytes = format::to_bytes(&model).unwrap();
    assert!(format::read(&bytes).unwrap().meta.volumetric);
    // Normal incidence and view: the factor is 1; it is capped at grazing.
    assert_eq!(volume_factor(Vec3::Z, Vec3::Z), 1.0);
    assert_eq!(volume_factor(Vec3::X, -Vec3::Z), 20.0);
}

#[test]
fn the_lommel_seeliger_flag_scales_the_diffuse_term_alone_and_round_trips() {
    use fabric_runtime::brdf::{ClothLobe, ClothParams, DiffuseLaw};
    use fabric_runtime::hybrid::{Tile, examples::uniform_model, format};
    let tile = Tile { origin: glam::Vec2::ZERO, size: glam::Vec2::ONE, top_z: 0.2, height_scale: 0.2, voxel_depth: 0.0125 };
    let lobe = ClothLobe { k: Vec3::splat(0.5), beta: 0.3, gamma: 1.0 };
    let wi = Vec3::new(0.6, 0.1, 0.5).normalize();
    let wo = Vec3::new(-0.3, 0.4, 0.7).normalize();
    let ray = |x: u32, y: u32, _s: u32| Ray::new(Vec3::new((x as f32 + 0.5) / 8.0, (y as f32 + 0.5) / 8.0, 0.2), -wo);
    let image = |kd: f32, law: DiffuseLaw| {
        let mut m = uniform_model(8, 8, 1, tile, |_, _| 0.1, &ClothParams::new(Vec3::splat(kd), 1.5, 1.0, &[lobe]), Vec3::Z, Vec3::X).unwrap();
        m.meta.diffuse = law;
        (measure_image(&m, &CpuRenderOptions::default(), wi, 0, 1, &ray).unwrap(), m)
    };
    // The lobes alone do not change; the diffuse part scales by 2 / (μ_i + μ_o).
    let (lobes_l, _) = image(0.0, DiffuseLaw::Lambert);
    let (lobes_ls, _) = image(0.0, DiffuseLaw::LommelSeeliger);
    let (full_l, _) = image(0.3, DiffuseLaw::Lambert);
    let (full_ls, model) = image(0.3, DiffuseLaw::LommelSeeliger);
    let f = 2.0 / (wi.z + wo.z);
    assert!(f > 1.0 && f < 2.0, "{f}");
    for k in 0..full_l.pixels.len() {
        assert_eq!(lobes_l.pixels[k], lobes_ls.pixels[k]);
        let (d_l, d_ls) = (full_l.pixels[k] - lobes_l.pixels[k], full_ls.pixels[k] - lobes_ls.pixels[k]);
        assert!(d_l.max_element() > 0.0);
        assert!((d_ls - d_l * f).abs().max_element() <= 1e-5 * d_ls.max_element(), "{d_l} · {f} vs {d_ls}");
    }
    // The flag survives the file (bit 3 of MODEL flags; hybrid_format.rs tests the bits).
    let bytes = format::to_bytes(&model).unwrap();
    assert_eq!(format::read(&bytes).unwrap().meta.diffuse, DiffuseLaw::LommelSeeliger);
    assert_eq!(format::read(&format::to_bytes(&image(0.3, DiffuseLaw::Lambert).1).unwrap()).unwrap().meta.diffuse, DiffuseLaw::Lambert);
}
