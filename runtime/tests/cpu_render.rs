//! The CPU renderer's images against analytic ones: a flat height field with a constant
//! BRDF under point and directional lights, level choice from the footprint, alpha
//! compositing at coarse levels, periodic tiling, determinism, and bad input.

use fabric_runtime::brdf::{BrdfReading, ClothLobe, ClothParams, cloth_brdf};
use fabric_runtime::cpu::shading::{in_fiber_frame, texel_response};
use fabric_runtime::cpu::render::{FILTER_GRID, FILTER_OFFSET, FINE_GRID_FROM, FINE_GRID_FULL, FINE_TRACE_FROM, FLY_FINE_GRID, FLY_MAX_ANISOTROPY, LEVEL0_GRID_MAX, LEVEL0_REACH, LEVEL0_TAPS_MAX, MAX_ANISOTROPY, MAX_SURFACE_TAPS, SURFACE_GRID, box_grid, fine_grid_spread, fine_grid_traced, fly_box_grid, grid_taps, level0_grid_taps, level0_reach_weight};
use fabric_runtime::cpu::{CoarseFilter, CpuRenderError, CpuRenderOptions, LevelChoice, Scene, ShadowMode, render, render_with_stats};
use fabric_runtime::hybrid::{BrdfTable, FlyawayInput, Surface, Tile, examples, level_dims};
use fabric_runtime::scene::{Camera, Light, Projection};
use glam::{Vec2, Vec3};

fn tile() -> Tile {
    Tile { origin: Vec2::new(-0.5, -0.5), size: Vec2::ONE, top_z: 0.3, height_scale: 0.3, voxel_depth: 0.01 }
}

#[test]
fn flat_surface_matches_the_analytic_image() {
    // Surface at depth 0.1 (z = 0.2), tilted normal map, silk BRDF; point light and a
    // perspective camera, then a directional light and an orthographic one.
    let params = examples::silk_params();
    let (n, t) = (Vec3::new(0.15, -0.1, 1.0), Vec3::new(1.0, 0.3, 0.0));
    let m = examples::uniform_model(32, 32, 1, tile(), |_, _| 0.1, &params, n, t).unwrap();
    let decoded = m.levels[0].texel_brdf(3, 7);
    let frame = decoded.frames[0];
    let cases = [
        (
            Camera { origin: Vec3::new(0.1, -1.2, 1.1), target: Vec3::new(0.0, 0.0, 0.2), up: Vec3::Z, projection: Projection::Perspective { fov_x_deg: 45.0 }, width: 64, height: 48 },
            Light::Point { position: Vec3::new(-0.2, 0.3, 0.9), intensity: Vec3::new(1.0, 0.9, 0.8) },
        ),
        (Camera::orbit_orthographic(35.0, -70.0, Vec3::new(0.0, 0.0, 0.2), 3.0, 1.3, 50, 40), Light::directional(Vec3::new(-0.4, 0.5, 1.0), Vec3::splat(1.5))),
    ];
    for (k, (cam, light)) in cases.iter().enumerate() {
        let opts = CpuRenderOptions { level: LevelChoice::Fixed(0), shadows: ShadowMode::On, ..Default::default() };
        let (image, stats) = render_with_stats(&m, cam, &[*light], &opts).unwrap();
        let mut surface = 0;
        for py in 0..cam.height {
            for px in 0..cam.width {
                let ray = cam.ray(px as f32 + 0.5, py as f32 + 0.5);
                // Exact: the plane z = 0.2, inside the tile, entered through the top.
                let (o, d) = (ray.o.as_dvec3(), ray.d.as_dvec3());
                let t_plane = (0.2 - o.z) / d.z;
                let t_top = (0.3 - o.z) / d.z;
                let p = o + d * t_plane;
                let q = o + d * t_top;
                let inside = |v: glam::DVec3| v.x.abs() <= 0.5 && v.y.abs() <= 0.5;
                let got = image.get(px, py);
                // Rays within 1e-4 of the tile's edge may go either way.
                if (p.x.abs() - 0.5).abs() < 1e-4 || (p.y.abs() - 0.5).abs() < 1e-4 || (q.x.abs() - 0.5).abs() < 1e-4 || (q.y.abs() - 0.5).abs() < 1e-4 {
                    continue;
                }
                if !(d.z < 0.0 && inside(p) && inside(q)) {
                    assert_eq!(got, Vec3::ZERO, "case {k}, pixel ({px}, {py}) should miss the tile");
                    continue;
                }
                let p = p.as_vec3();
                let s = light.sample(p);
                let wo = -ray.d;
                // Eq. 1 with the model's (f16-quantized) parameters and (packed) frame.
                let want = s.irradiance * cloth_brdf(&decoded.params, &frame, s.wi, wo, BrdfReading::Bounded) * frame.n.dot(s.wi).max(0.0);
                // Tolerance: the hit point is exact to f32 rounding (~1e-7 relative);
                // the point light's 1/d² and the lobes turn that into ≲ 1e-5.
                assert!((got - want).abs().max_element() <= 1e-5 * want.max_element().max(1e-4), "case {k}, pixel ({px}, {py}): {got} vs {want}");
                surface += 1;
            }
        }
        assert!(surface > 1000, "case {k}: {surface} surface pixels");
        assert!(stats.surface_pixels >= surface, "{} < {surface}", stats.surface_pixels);
        assert_eq!(stats.step_limited_pixels, 0);
    }
    // Against the unquantized parameters: the f16/octahedral packing costs < 0.5%.
    let f_exact = fabric_runtime::brdf::cloth_frame(n, t);
    let (wi, wo) = (Vec3::new(0.3, 0.2, 0.9).normalize(), Vec3::new(-0.35, -0.2, 0.9).normalize());
    let a = cloth_brdf(&params, &f_exact, wi, wo, BrdfReading::Bounded);
    let b = cloth_brdf(&decoded.params, &frame, wi, wo, BrdfReading::Bounded);
    assert!((a - b).abs().max_element() < 5e-3 * a.max_element(), "{a} vs {b}");
}

/// A model whose level ℓ is pure diffuse with k_d = colour(ℓ): the image says the level.
fn level_coded_model(n: u32, levels: usize) -> fabric_runtime::hybrid::HybridModel {
    let colour = |l: usize| Vec3::new(0.1 + 0.2 * l as f32, 0.5, 0.9 - 0.2 * l as f32);
    let mut m = examples::uniform_model(n, n, levels, Tile { origin: Vec2::ZERO, size: Vec2::ONE, top_z: 0.0, height_scale: 0.1, voxel_depth: 0.01 }, |_, _| 0.05, &ClothParams::new(Vec3::ZERO, 1.5, 0.0, &[ClothLobe { k: Vec3::ZERO, beta: 0.1, gamma: 0.0 }]), Vec3::Z, Vec3::X).unwrap();
    for (l, level) in m.levels.iter_mut().enumerate() {
        let (w, h) = level_dims(n, n, l);
        let mut table = BrdfTable::new();
        let lobes = [(ClothLobe { k: Vec3::ZERO, beta: 0.1, gamma: 0.0 }, Vec3::Z, Vec3::X)];
        for _ in 0..w * h {
            table.push_framed(colour(l), 1.5, 0.0, &lobes);
        }
        level.surface = Surface::PerTexel(table);
    }
    m.validate().unwrap();
    m
}

#[test]
fn level_follows_the_pixel_footprint() {
    let n = 64;
    let m = level_coded_model(n, 5);
    let light = [Light::directional(Vec3::Z, Vec3::ONE)];
    // Straight down over the unit tile: footprint ρ = (1 / pixels) / (1 / 64) texels.
    for (pixels, bias, want) in [(64u32, 0.0f32, 0usize), (32, 0.0, 1), (16, 0.0, 2), (8, 0.0, 3), (4, 0.0, 4), (2, 0.0, 4), (64, 1.0, 1), (32, -1.0, 0), (45, 0.0, 1), (23, 0.0, 1), (22, 0.0, 2)] {
        let cam = Camera { origin: Vec3::new(0.5, 0.5, 2.0), target: Vec3::new(0.5, 0.5, 0.0), up: Vec3::Y, projection: Projection::Orthographic { extent: 1.0 }, width: pixels, height: pixels };
        let opts = CpuRenderOptions { level: LevelChoice::Nearest { bias }, ..Default::default() };
        let (image, stats) = render_with_stats(&m, &cam, &light, &opts).unwrap();
        // ρ = 64/pixels: level ⌊log2 ρ + bias + ½⌋ (45 px: ρ = 1.42, log2 = 0.51 → 1;
        // 23 px: 2.78 → 1.48 → 1; 22 px: 2.91 → 1.54 → 2).
        assert_eq!(stats.level_pixels[want], (pixels * pixels) as u64, "{pixels} px, bias {bias}: {:?}", stats.level_pixels);
        let expect = Vec3::new(0.1 + 0.2 * want as f32, 0.5, 0.9 - 0.2 * want as f32);
        assert!((image.get(pixels / 2, pixels / 2) - expect).abs().max_element() < 1e-3, "{pixels} px: {}", image.get(pixels / 2, pixels / 2));
        // Auto: level 0 alone through its grid up to LEVEL0_REACH texels, blended into
        // level 1 until the box grid's level reaches 1, then the box grid's levels
        // ⌊λ⌋ and ⌊λ⌋ + 1 by λ − ⌊λ⌋ (λ − log2 G for a round footprint, clamped to the chain).
        let (image, _) = render_with_stats(&m, &cam, &light, &CpuRenderOptions { level: LevelChoice::Auto { bias }, ..Default::default() }).unwrap();
        let rho = 64.0 / pixels as f32;
        let lambda = rho.log2() + FILTER_OFFSET + bias;
        let lambda = match box_grid(rho, rho, 1, lambda, bias, SURFACE_GRID) {
            None => 0.0,
            Some(g) => {
                // The reach is a footprint's size, in FILTER_GRID lookups whatever the surface's grid.
                let reach = level0_reach_weight((rho / FILTER_GRID as f32).log2() + FILTER_OFFSET + bias);
                if reach < 1.0 { reach } else { g.lambda }
            }
        }
        .min(4.0);
        let expect = Vec3::new(0.1 + 0.2 * lambda, 0.5, 0.9 - 0.2 * lambda);
        assert!((image.get(pixels / 2, pixels / 2) - expect).abs().max_element() < 1e-3, "{pixels} px, λ {lambda}: {}", image.get(pixels / 2, pixels / 2));
    }
    // Fixed levels override the footprint; a level past the chain is an error.
    let cam = Camera { origin: Vec3::new(0.5, 0.5, 2.0), target: Vec3::new(0.5, 0.5, 0.0), up: Vec3::Y, projection: Projection::Orthographic { extent: 1.0 }, width: 8, height: 8 };
    let scene = Scene::new(&m, &cam, &light, CpuRenderOptions { level: LevelChoice::Fixed(2), ..Default::default() }).unwrap();
    assert_eq!(scene.trace_pixel(4, 4).level, Some(2));
    assert!(matches!(render(&m, &cam, &light, &CpuRenderOptions { level: LevelChoice::Fixed(5), ..Default::default() }), Err(CpuRenderError::Level { level: 5, count: 5 })));
    // A perspective view of a receding plane walks down the chain toward the horizon.
    let cam = Camera { origin: Vec3::new(0.5, -0.3, 0.4), target: Vec3::new(0.5, 0.6, 0.0), up: Vec3::Z, projection: Projection::Perspective { fov_x_deg: 50.0 }, width: 40, height: 40 };
    let (_, stats) = render_with_stats(&m, &cam, &light, &CpuRenderOptions { periodic: true, ..Default::default() }).unwrap();
    assert!(stats.level_pixels.iter().filter(|&&c| c > 0).count() >= 3, "{:?}", stats.level_pixels);
}

/// The box filter's grid (render.rs, `box_grid`): each axis keeps the pixel's variance
/// P²/12 (grid s²(G² − 1)/12 plus a lookup's T²/4), never reads level 0 through the
/// grid, and grows out of the one-lookup rule continuously.
#[test]
fn the_box_grid_keeps_the_pixels_variance_and_grows_continuously() {
    assert!(FILTER_GRID >= 2 && SURFACE_GRID >= 2, "the grids are on");
    let variance = |span: f32, taps: u32, level: f32| {
        let s = span / taps as f32;
        s * s * (taps * taps - 1) as f32 / 12.0 + (2.0 * level).exp2() / 4.0
    };
    let mut grids = 0;
    for (major, minor) in [(8.0f32, 8.0f32), (12.0, 5.0), (40.0, 5.0), (100.0, 11.0), (6.0, 4.0), (3.0, 3.0), (1.0, 0.5), (16.0, 1.0)] {
        for bias in [0.0f32, 0.5, -0.5] {
            let n = ((major / minor - 1e-3).ceil() as u32).clamp(1, MAX_ANISOTROPY);
            let lambda = (major / n as f32).log2() + FILTER_OFFSET + bias;
            assert!(box_grid(major, minor, n, lambda, bias, 1).is_none(), "the bilinear filter reads no grid");
            let Some(g) = box_grid(major, minor, n, lambda, bias, FILTER_GRID) else {
                assert!(lambda <= 1.0, "{major}×{minor}: λ {lambda} reads no grid");
                continue;
            };
            grids += 1;
            assert!(g.lambda >= 1.0 && g.lambda <= lambda, "{major}×{minor}: {g:?}");
            assert!(g.taps_major >= 1 && g.taps_major <= MAX_ANISOTROPY.max(n) && g.taps_minor <= FILTER_GRID, "{g:?}");
            let scale = (2.0 * bias).exp2();
            for (p, span, taps) in [(major, g.span_major, g.taps_major), (minor, g.span_minor, g.taps_minor)] {
                let want = p * p * scale / 12.0;
                let got = variance(span, taps, g.lambda);
                // Where level 1's own lookup is wider than the pixel, no spread: the
                // lookup's width alone.
                if span > 0.0 {
                    assert!((got - want).abs() <= 1e-3 * want, "{major}×{minor}, bias {bias}: variance {got} against the box's {want} ({g:?})");
                } else {
                    assert!(got >= want * (1.0 - 1e-3), "{major}×{minor}: {got} < {want}");
                }
            }
        }
    }
    assert!(grids >= 12, "{grids} footprints read a grid");
    // Continuity at λ = 1: just past it the grid's spread is (nearly) nothing.
    let edge = (1.0 - FILTER_OFFSET).exp2();
    let g = box_grid(edge * 1.001, edge * 1.001, 1, 1.0 + 1.001f32.log2(), 0.0, FILTER_GRID).unwrap();
    assert!(g.span_major < 0.2 && g.span_minor < 0.2 && g.lambda == 1.0, "{g:?}");
    assert!(box_grid(edge, edge, 1, 1.0, 0.0, FILTER_GRID).is_none());
    // The flyaways' grid: one ray up to a footprint of a quarter texel, then G × G rays
    // one level finer (never below level 0) spreading to the whole footprint at half a
    // texel, as level 0's grid of the surface; continuous in distance.
    let fly = |lambda: f32, n: u32, grid: u32| {
        let g = fly_box_grid(lambda.exp2(), n, 0.0, grid);
        (g.lambda, g.spread, g.taps_major, g.taps_minor)
    };
    let close = |a: (f32, f32, u32, u32), b: (f32, f32, u32, u32)| (a.0 - b.0).abs() < 1e-5 && (a.1 - b.1).abs() < 1e-5 && (a.2, a.3) == (b.2, b.3);
    let (quarter, three_eighths) = (0.25f32.log2(), 0.375f32.log2());
    for (lambda, want) in [(-3.0f32, (0.0f32, 0.0f32, 1, 1)), (quarter, (0.0, 0.0, 1, 1)), (three_eighths, (0.0, 0.5, 2, 2)), (-1.0, (0.0, 1.0, 2, 2)), (0.5, (0.0, 1.0, 2, 2)), (1.25, (0.25, 1.0, 2, 2)), (2.0, (1.0, 1.0, 2, 2)), (3.5, (2.5, 1.0, 2, 2))] {
        assert!(close(fly(lambda, 1, FILTER_GRID), want), "λ {lambda}: {:?}", fly(lambda, 1, FILTER_GRID));
        assert!(close(fly(lambda, 1, 1), (lambda, 0.0, 1, 1)));
    }
    // Just past a quarter texel the rays spread over (nearly) nothing: the one ray's image.
    let g = fly_box_grid(0.25 * 1.001, 1, 0.0, FILTER_GRID);
    assert!(g.spread < 0.01 && g.lambda == 0.0, "{g:?}");
    // A footprint N times longer than wide: min(N, 2)·G rays along it, G across, at the
    // level of the surface's N·G lookups (at most 8), major/(N·G), never below 0; the
    // spread from major/N.
    assert_eq!(FLY_MAX_ANISOTROPY, 2);
    for (lambda, n, want) in [(4.5f32, 3u32, (4.5 - 1.0 - 3f32.log2(), 1.0, 4, 2)), (4.5, 5, (1.5, 1.0, 4, 2)), (2.5, 4, (0.0, 1.0, 4, 2)), (1.5, 2, (0.0, 1.0, 4, 2)), (0.75f32.log2(), 2, (0.0, 0.5, 4, 2))] {
        assert!(close(fly(lambda, n, FILTER_GRID), want), "λ {lambda}, N {n}: {:?}", fly(lambda, n, FILTER_GRID));
    }
    // Level 0 is read through a grid of its nearest texels, spread from nothing at a
    // minor axis of a quarter texel to the footprint at half a texel, and where it is
    // past λ = 0 at least from nothing at λ = 0 to the footprint at λ = ½; under a
    // quarter texel the hit's texel alone (close-ups as they were).
    assert_eq!((FINE_GRID_FROM, FINE_GRID_FULL), (0.25, 0.5));
    for (minor, want) in [(0.0f32, 0.0f32), (0.25, 0.0), (0.3, 0.2), (0.375, 0.5), (0.5, 1.0), (0.9, 1.0), (3.0, 1.0)] {
        assert!((fine_grid_spread(minor) - want).abs() < 1e-6, "{minor}: {}", fine_grid_spread(minor));
    }
    let model = examples::synthetic_model(64, 7);
    let scene = Scene::for_rays(&model, &[], CpuRenderOptions { periodic: true, ..Default::default() }).unwrap();
    let t = model.texel_size().x;
    // Its lookups are traced once it spans half a texel along either axis; a close-up's
    // narrower grid reads beside the hit.
    assert_eq!(FINE_TRACE_FROM, 0.5);
    let inv = model.inv_texel_size();
    for (a, b, want) in [(0.3f32, 0.2f32, false), (0.49, 0.1, false), (0.51, 0.1, true), (0.1, 0.6, true), (0.0, 0.0, false)] {
        let axes = (Vec2::new(a * t, 0.0).rotate(Vec2::from_angle(0.3)), Vec2::new(0.0, b * t));
        assert_eq!(fine_grid_traced(axes, inv), want, "a grid of {a} × {b} texels");
    }
    let mix_at = |texels: f32| scene.level_mix_axes(Some((Vec2::new(texels * t, 0.0), Vec2::new(0.0, texels * t))));
    let lambda_of = |texels: f32| texels.log2() + FILTER_OFFSET;
    for texels in [0.1f32, 0.25, 0.3, 0.4, 0.5, 0.8, 1.0, 1.2, 1.5, 1.8, 2.0, 2.5, 3.0, 3.4] {
        let m = mix_at(texels);
        let lambda = lambda_of(texels);
        if texels <= FINE_GRID_FROM {
            assert_eq!((m.lo, m.weight, m.fine_taps), (0, 0.0, (1, 1)), "{texels} texels");
            continue;
        }
        let across = (texels.ceil() as u32).clamp(SURFACE_GRID, LEVEL0_GRID_MAX);
        assert_eq!((m.lo, m.hi, m.weight, m.fine_taps), (0, 0, 0.0, (across, across)), "{texels} texels: level 0 alone");
        let spread = (2.0 * lambda).clamp(0.0, 1.0).max(fine_grid_spread(texels));
        assert!((m.fine_axes.0.length() - spread * texels * t).abs() < 1e-4 * t && (m.fine_axes.1.length() - spread * texels * t).abs() < 1e-4 * t, "{texels} texels: {m:?}");
    }
    // A long footprint (1.5 × 3.4 texels, λ < 0): along its major axis the grid spans
    // the minor axis's width in texels, not the whole footprint, with N·G lookups (N = 3,
    // G = 3: 9 × 3, within LEVEL0_TAPS_MAX).
    let m = scene.level_mix_axes(Some((Vec2::new(3.4 * t, 0.0), Vec2::new(0.0, 1.5 * t))));
    assert_eq!((m.lo, m.hi, m.fine_taps), (0, 0, (9, SURFACE_GRID)), "{m:?}");
    assert!((m.fine_axes.0.length() - 1.5 * t).abs() < 1e-4 * t && (m.fine_axes.1.length() - 1.5 * t).abs() < 1e-4 * t, "{m:?}");
    // Continuous across λ = 0 (1.73 texels) and at a quarter texel.
    let spread_of = |texels: f32| mix_at(texels).fine_axes.0.length() / (texels * t);
    let l0 = 2f32.powf(-FILTER_OFFSET);
    assert!((spread_of(l0 * 0.999) - spread_of(l0 * 1.001)).abs() < 0.01, "{} / {}", spread_of(l0 * 0.999), spread_of(l0 * 1.001));
    assert!(spread_of(FINE_GRID_FROM * 1.001) < 0.01);
    // Level 0's grid: about one lookup per texel across, G to four, N times as many
    // along a long footprint, at most 32 (a grazing footprint four texels across keeps
    // 8 along); a coarse grid at most 8 × 3; the GPU's arrays hold the larger.
    assert_eq!((LEVEL0_REACH, LEVEL0_GRID_MAX, LEVEL0_TAPS_MAX, SURFACE_GRID, MAX_SURFACE_TAPS), (4.0, 4, 32, 3, 32));
    assert!(MAX_SURFACE_TAPS >= MAX_ANISOTROPY * SURFACE_GRID && MAX_SURFACE_TAPS >= LEVEL0_TAPS_MAX);
    for (grid, minor, n, want) in [(2, 0.3f32, 1u32, (2u32, 2u32)), (2, 1.5, 1, (2, 2)), (2, 2.0, 3, (6, 2)), (2, 2.5, 1, (3, 3)), (2, 3.0, 2, (6, 3)), (2, 3.0, 4, (10, 3)), (2, 3.4, 1, (4, 4)), (2, 4.0, 2, (8, 4)), (2, 4.0, 3, (8, 4)), (2, 10.0, 1, (4, 4)), (2, 2.0, 8, (16, 2)), (2, 0.0, 1, (2, 2)), (2, f32::NAN, 1, (2, 2)), (3, 0.3, 1, (3, 3)), (3, 1.5, 2, (6, 3)), (3, 1.5, 3, (9, 3)), (3, 1.5, 8, (10, 3)), (3, 3.4, 1, (4, 4)), (3, 3.5, 3, (8, 4)), (3, 0.0, 1, (3, 3))] {
        let got = level0_grid_taps(minor, n, grid);
        assert_eq!(got, want, "{minor} texels, N {n}, G {grid}");
        assert!(got.0 * got.1 <= LEVEL0_TAPS_MAX);
    }
    // Up to G texels across it is G × N·G: the box grid's while that is within the box
    // grid's cap of MAX_ANISOTROPY along.
    for n in 1..=8 {
        assert_eq!(level0_grid_taps(1.9, n, FILTER_GRID), (n * FILTER_GRID, FILTER_GRID));
        if n * FILTER_GRID <= MAX_ANISOTROPY {
            assert_eq!(level0_grid_taps(1.9, n, FILTER_GRID), (grid_taps(n, FILTER_GRID), FILTER_GRID));
        }
    }
    // Past λ = 1 (3.46 texels) level 0 is still read alone, over the whole footprint,
    // up to LEVEL0_REACH; level 1's box grid is blended in from there until its level
    // reaches 1 (6.93 texels), continuously, and reads alone beyond.
    let m = mix_at(3.9);
    assert_eq!((m.lo, m.hi, m.weight, m.fine_taps), (0, 1, 0.0, (4, 4)), "{m:?}");
    assert!((m.fine_axes.0.length() - 3.9 * t).abs() < 1e-4 * t && (m.fine_axes.1.length() - 3.9 * t).abs() < 1e-4 * t, "{m:?}");
    assert!((spread_of(3.46) - spread_of(3.47)).abs() < 1e-3 && mix_at(3.46).fine_taps == mix_at(3.47).fine_taps);
    let weight_at = |texels: f32| mix_at(texels).weight;
    assert!(weight_at(LEVEL0_REACH * 1.001) < 0.01 && weight_at(LEVEL0_REACH * 0.999) == 0.0);
    let full = 2.0 * (1.0 - FILTER_OFFSET).exp2();
    assert!(weight_at(full * 0.999) > 0.99 && (mix_at(full * 0.999).lo, mix_at(full * 1.001).lo) == (0, 1), "{:?}", mix_at(full * 1.001));
    assert_eq!(mix_at(full * 1.001).fine_taps, (1, 1), "past the reach the coarse grid reads the footprint alone");
    let mut last = 0.0;
    for k in 0..=20 {
        let texels = LEVEL0_REACH + (full - LEVEL0_REACH) * k as f32 / 20.0;
        let m = mix_at(texels);
        assert!(m.weight >= last - 1e-6 && m.weight <= 1.0, "{texels} texels: {m:?}");
        last = m.weight;
        if texels < full * 0.999 {
            // Level 1 through the box grid at level 1.
            let g = box_grid(texels, texels, 1, lambda_of(texels), 0.0, SURFACE_GRID).unwrap();
            assert_eq!((m.lo, m.hi, m.taps, m.taps_minor), (0, 1, g.taps_major, g.taps_minor), "{texels} texels");
            assert!((m.axis.length() - g.span_major * t).abs() < 1e-4 * t, "{texels} texels");
        }
    }
    assert!((level0_reach_weight(f32::NAN), level0_reach_weight(-9.0), level0_reach_weight(9.0)) == (1.0, 0.0, 1.0));
    // A model without a chain (`fabric bake --no-prefilter`) reads level 0 through its
    // grid at every distance, not one texel.
    let mut bare = model.clone();
    bare.levels.truncate(1);
    bare.meta.fit_error.truncate(1);
    let lone = Scene::for_rays(&bare, &[], CpuRenderOptions { periodic: true, ..Default::default() }).unwrap();
    for texels in [3.0f32, 5.0, 10.0, 40.0] {
        let m = lone.level_mix_axes(Some((Vec2::new(texels * t, 0.0), Vec2::new(0.0, texels * t))));
        assert!((m.lo, m.hi, m.weight, m.fine_taps) == (0, 0, 0.0, level0_grid_taps(texels, 1, SURFACE_GRID)) && (m.fine_axes.0.length() - texels * t).abs() < 1e-4 * texels * t, "{texels} texels: {m:?}");
    }
    // The bilinear filter (no grid) blends levels 0 and 1 by λ, as Vulkan's linear mips.
    let bilinear = Scene::for_rays(&model, &[], CpuRenderOptions { periodic: true, coarse_filter: CoarseFilter::Bilinear, ..Default::default() }).unwrap();
    let m = bilinear.level_mix_axes(Some((Vec2::new(3.0 * t, 0.0), Vec2::new(0.0, 3.0 * t))));
    assert!((m.lo, m.hi, m.fine_taps) == (0, 1, (1, 1)) && (m.weight - lambda_of(3.0)).abs() < 1e-5, "{m:?}");
    // The fine grid (`CoarseFilter::Fine`): G = 4 rays per axis through voxels a quarter
    // of a round footprint (two levels finer), N·G along a long one as the surface's
    // lookups (at most 8), never below level 0.
    assert_eq!(CoarseFilter::Fine.fly_grid(), FLY_FINE_GRID);
    assert_eq!((CoarseFilter::Box.fly_grid(), CoarseFilter::Bilinear.fly_grid()), (FILTER_GRID, 1));
    assert_eq!(CoarseFilter::Fine.grid(), CoarseFilter::Box.grid(), "the surface's grid is the box filter's");
    for (lambda, n, want) in [(3.5f32, 1u32, (1.5f32, 1.0f32, 4, 4)), (2.0, 1, (0.0, 1.0, 4, 4)), (2.5, 1, (0.5, 1.0, 4, 4)), (1.5, 1, (0.0, 1.0, 4, 4)), (4.5, 3, (1.5, 1.0, 8, 4)), (5.0, 1, (3.0, 1.0, 4, 4))] {
        assert!(close(fly(lambda, n, FLY_FINE_GRID), want), "fine, λ {lambda}, N {n}: {:?}", fly(lambda, n, FLY_FINE_GRID));
    }
    for grid in [FILTER_GRID, FLY_FINE_GRID] {
        for n in [1u32, 2, 3, 8] {
            let step = |l: f32| fly(l + 1e-4, n, grid).0 - fly(l - 1e-4, n, grid).0;
            let spread = |l: f32| fly(l + 1e-4, n, grid).1 - fly(l - 1e-4, n, grid).1;
            // A quarter texel across (where the grid grows out of the one ray) at N · ¼.
            let entry = (0.25 * n as f32).log2();
            for l in [entry, 1.0f32, 2.0, 2.5, 3.0, 4.0] {
                assert!(step(l).abs() < 1e-3 && spread(l).abs() < 1e-3, "G {grid}, N {n}: a jump at λ {l}");
            }
        }
    }
}

#[test]
fn coarse_flyaway_voxels_are_alpha_composited_by_path_length() {
    // Level 1 of a 16² model: texels of 1/8, voxel depth s₁ = 2 · 0.01. One voxel with
    // α = 0.5 over a flat surface; opacity 1 − (1 − α)^(ℓ/s), s = (Δx₁Δy₁s₁)^(1/3).
    let m0 = level_coded_model(16, 3);
    let mut m = m0.clone();
    let fly = ClothParams::new(Vec3::new(0.9, 0.1, 0.1), 1.5, 0.0, &[]);
    examples::add_flyaways(&mut m, 1, &[(3, 4, FlyawayInput { depth: 1, alpha: 0.5, tangent: Vec3::X, param: 0 })], &fly).unwrap();
    let light = Light::directional(Vec3::new(0.2, 0.1, 1.0), Vec3::ONE);
    let (s1, dx1) = (0.02f32, 0.125f32);
    let edge = (dx1 * dx1 * s1).cbrt();
    let (lo, hi) = (Vec3::new(0.375, 0.5, -0.04), Vec3::new(0.5, 0.625, -0.02));
    let alpha = m.levels[1].flyaways.as_ref().unwrap().nodes[0].alpha();
    // The same voxel with a path gain (format 1.9) of 1.3 − 0.01·θ: the exponent scaled.
    let mut mg = m.clone();
    mg.levels[1].flyaways.as_mut().unwrap().path_gain = Some(fabric_runtime::hybrid::PathGain(std::array::from_fn(|k| 1.3 - 0.1 * k as f32)));
    mg.validate().unwrap();
    let mut checked = 0;
    for (theta, phi) in [(0.0f32, 0.0f32), (50.0, 10.0), (70.0, 135.0)] {
        let dir = fabric_runtime::scene::direction_from_angles(theta, phi);
        let cam = Camera { origin: Vec3::new(0.44, 0.56, -0.03) + 2.0 * dir, target: Vec3::new(0.44, 0.56, -0.03), up: if theta == 0.0 { Vec3::Y } else { Vec3::Z }, projection: Projection::Orthographic { extent: 0.3 }, width: 48, height: 48 };
        let opts = CpuRenderOptions { level: LevelChoice::Fixed(1), ..Default::default() };
        let lights = [light];
        let scene = Scene::new(&m, &cam, &lights, opts.clone()).unwrap();
        let plain = Scene::new(&m0, &cam, &lights, opts.clone()).unwrap();
        let gained = Scene::new(&mg, &cam, &lights, opts).unwrap();
        let gain = 1.3 - 0.01 * theta;
        for py in 0..48 {
            for px in 0..48 {
                let ray = cam.ray(px as f32 + 0.5, py as f32 + 0.5);
                let (o, d) = (ray.o, ray.d);
                let (mut t0, mut t1) = (f32::NEG_INFINITY, f32::INFINITY);
                for a in 0..3 {
                    if d[a].abs() > 1e-9 {
                        let (ta, tb) = ((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]);
                        t0 = t0.max(ta.min(tb));
                        t1 = t1.min(ta.max(tb));
                    } else if o[a] < lo[a] || o[a] > hi[a] {
                        t0 = f32::INFINITY;
                    }
                }
                let path = (t1 - t0).max(0.0);
                let got = scene.trace_ray(&ray, 1);
                let behind = plain.trace_ray(&ray, 1).radiance;
                if path < 1e-4 {
                    if t1 < t0 - 1e-4 {
                        assert!((got.radiance - behind).abs().max_element() < 1e-6, "pixel ({px}, {py}) misses the voxel");
                    }
                    continue;
                }
                let opacity = 1.0 - (1.0 - alpha).powf(path / edge);
                let wo = -d;
                let b = in_fiber_frame(m.levels[1].flyaways.as_ref().unwrap().table.brdf_in_frame(0, fabric_runtime::brdf::cloth_frame(Vec3::Z, Vec3::X)), Vec3::X, wo, m.meta.fiber_lobes);
                let s = light.sample(Vec3::ZERO);
                let l_fly = s.irradiance * texel_response(&b, s.wi, wo, BrdfReading::Bounded, fabric_runtime::brdf::DiffuseLaw::Lambert);
                let want = opacity * l_fly + (1.0 - opacity) * behind;
                // Path lengths agree to f32 rounding of the box crossings (~1e-6 of 0.02).
                assert!((got.flyaway_opacity - opacity).abs() < 2e-4, "view ({theta}, {phi}) pixel ({px}, {py}): opacity {} vs {opacity} (path {path})", got.flyaway_opacity);
                assert!((got.radiance - want).abs().max_element() < 2e-4, "view ({theta}, {phi}) pixel ({px}, {py}): {} vs {want}", got.radiance);
                let with_gain = 1.0 - (1.0 - alpha).powf(gain * path / edge);
                let g = gained.trace_ray(&ray, 1).flyaway_opacity;
                assert!((g - with_gain).abs() < 2e-4, "view ({theta}, {phi}) pixel ({px}, {py}), gain {gain}: opacity {g} vs {with_gain}");
                checked += 1;
            }
        }
    }
    assert!(checked > 300, "{checked} pixels through the voxel");
    // Straight down the path is s₁: opacity = 1 − ½^(s₁/edge), edge = (0.125²·0.02)^(1/3)
    // = 0.06786, so 1 − ½^0.29472 = 0.18477 (worked by hand): what the renderer gives a
    // ray down the voxel's middle (α is stored as unorm16 of 0.5, exact to 1e-5).
    let cam = Camera { origin: Vec3::new(0.44, 0.56, 2.0), target: Vec3::new(0.44, 0.56, 0.0), up: Vec3::Y, projection: Projection::Orthographic { extent: 0.3 }, width: 8, height: 8 };
    let lights = [light];
    let scene = Scene::new(&m, &cam, &lights, CpuRenderOptions { level: LevelChoice::Fixed(1), ..Default::default() }).unwrap();
    let down = scene.trace_ray(&fabric_runtime::scene::Ray::new(Vec3::new(0.4375, 0.5625, 1.0), -Vec3::Z), 1);
    assert!((down.flyaway_opacity - 0.18477).abs() < 1e-4, "straight down: opacity {}", down.flyaway_opacity);
    assert!((1.0 - 0.5f32.powf(s1 / edge) - 0.18477).abs() < 1e-4, "the hand-worked edge");
}

#[test]
fn periodic_tiles_repeat_and_clamped_tiles_end() {
    let m = examples::sample_model();
    let light = [Light::directional(Vec3::new(0.3, 0.2, 1.0), Vec3::ONE)];
    // Straight down over two tile widths (2.4 × 2.0), pixel grid aligned with the tiles:
    // 48 px per tile width in x (1.2), 40 px per tile height in y (1.0).
    let cam = Camera { origin: Vec3::new(0.6, 0.5, 2.0), target: Vec3::new(0.6, 0.5, 0.0), up: Vec3::Y, projection: Projection::Orthographic { extent: 2.4 }, width: 96, height: 80 };
    let opts = CpuRenderOptions { level: LevelChoice::Fixed(0), periodic: true, shadows: ShadowMode::On, ..Default::default() };
    let image = render(&m, &cam, &light, &opts).unwrap();
    let mut worst = 0.0f32;
    for y in 0..40 {
        for x in 0..48 {
            let a = image.get(x, y);
            for (dx, dy) in [(48, 0), (0, 40), (48, 40)] {
                worst = worst.max((a - image.get(x + dx, y + dy)).abs().max_element() / a.max_element().max(1e-3));
            }
        }
    }
    // Positions one period apart differ by f32 rounding only (flyaway crossings, hits).
    assert!(worst < 1e-3, "periodic repeats differ by {worst}");
    let clamped = render(&m, &cam, &light, &CpuRenderOptions { periodic: false, ..opts }).unwrap();
    // The tile covers x ∈ [−0.6, 0.6], y ∈ [−0.5, 0.5]: the upper-right quadrant of
    // this view (x > 0.6 or y > 0.5 on screen) is background.
    assert_eq!(clamped.get(80, 10), Vec3::ZERO);
    assert!(clamped.get(20, 60).max_element() > 0.0);
}

/// A periodic tile whose size a coarse level's 2^ℓ does not divide (20 texels: levels 3
/// and 4 are 3 and 2 texels wide, 24 and 32 level-0 texels' worth) repeats at every
/// level: the level's grid is not allowed to drift by a texel per repeat. Measured on a
/// 63² twill before the rule: the distance sweep's far steps 7.3–10.8% off, 4.0–8.3%
/// after, as its 64² twin (baker/PREFILTER_MEASUREMENTS.md, "Tiles of any size").
#[test]
fn periodic_tiles_of_any_size_repeat_at_every_level() {
    let m = examples::synthetic_model(20, 3);
    assert_eq!(m.levels.len(), 5);
    let light = [Light::directional(Vec3::new(0.3, 0.2, 1.0), Vec3::ONE)];
    let cam = Camera { origin: Vec3::new(0.5, 0.5, 2.0), target: Vec3::new(0.5, 0.5, 0.0), up: Vec3::Y, projection: Projection::Orthographic { extent: 1.0 }, width: 8, height: 8 };
    let opts = CpuRenderOptions { periodic: true, ..Default::default() };
    let scene = Scene::new(&m, &cam, &light, opts.clone()).unwrap();
    for level in 0..m.levels.len() {
        for (i, j) in [(0.013f32, 0.5f32), (0.31, 0.77), (0.5, 0.02), (0.97, 0.96), (0.7, 0.3)] {
            let p = Vec3::new(i, j, 0.05);
            let here = scene.bilinear_texels(p, level);
            for k in [1.0f32, 2.0, 5.0, -3.0] {
                let there = scene.bilinear_texels(p + Vec3::new(k * m.tile.size.x, -k * m.tile.size.y, 0.0), level);
                for ((a, wa), (b, wb)) in here.iter().zip(&there) {
                    assert!(a == b && (wa - wb).abs() < 1e-3, "level {level} at ({i}, {j}), {k} tiles on: {wa} against {wb}");
                }
            }
        }
    }
    // Whole frames at the coarse levels: two tile widths, 48 px each, repeat.
    let cam = Camera { origin: Vec3::new(1.0, 1.0, 2.0), target: Vec3::new(1.0, 1.0, 0.0), up: Vec3::Y, projection: Projection::Orthographic { extent: 2.0 }, width: 96, height: 96 };
    for level in [3, 4] {
        let image = render(&m, &cam, &light, &CpuRenderOptions { level: LevelChoice::Fixed(level), ..opts.clone() }).unwrap();
        let mut worst = 0.0f32;
        for y in 0..48 {
            for x in 0..48 {
                let a = image.get(x, y);
                worst = worst.max((a - image.get(x + 48, y + 48)).abs().max_element() / a.max_element().max(1e-3));
            }
        }
        assert!(worst < 1e-3, "level {level}: repeats differ by {worst}");
    }
}

#[test]
fn renders_are_bit_identical_for_any_thread_count() {
    let m = examples::sample_model();
    let cam = Camera { origin: Vec3::new(0.3, -1.5, 1.2), target: Vec3::new(0.0, 0.0, 0.1), up: Vec3::Z, projection: Projection::Perspective { fov_x_deg: 50.0 }, width: 64, height: 48 };
    let lights = [Light::Point { position: Vec3::new(0.5, -0.5, 1.0), intensity: Vec3::splat(2.0) }, Light::directional(Vec3::new(-0.3, 0.1, 0.5), Vec3::splat(0.5))];
    let opts = CpuRenderOptions { periodic: true, shadows: ShadowMode::On, supersampling: 2, ..Default::default() };
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap().install(|| render(&m, &cam, &lights, &opts).unwrap());
    let three = rayon::ThreadPoolBuilder::new().num_threads(3).build().unwrap().install(|| render(&m, &cam, &lights, &opts).unwrap());
    assert_eq!(one, three);
    assert!(one.mean() > 0.0);
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let m = examples::sample_model();
    let cam = Camera { origin: Vec3::new(0.0, 0.0, 2.0), target: Vec3::ZERO, up: Vec3::Y, projection: Projection::Orthographic { extent: 1.0 }, width: 8, height: 8 };
    let light = [Light::directional(Vec3::Z, Vec3::ONE)];
    let ok = CpuRenderOptions::default();
    assert!(matches!(render(&m, &Camera { up: Vec3::Z, ..cam }, &light, &ok), Err(CpuRenderError::Camera(_))));
    assert!(matches!(render(&m, &cam, &[Light::directional(Vec3::ZERO, Vec3::ONE)], &ok), Err(CpuRenderError::Light(_))));
    assert!(matches!(render(&m, &cam, &light, &CpuRenderOptions { supersampling: 0, ..ok.clone() }), Err(CpuRenderError::Options(_))));
    assert!(matches!(render(&m, &cam, &light, &CpuRenderOptions { level: LevelChoice::Auto { bias: f32::NAN }, ..ok.clone() }), Err(CpuRenderError::Options(_))));
    let mut broken = m.clone();
    broken.tile.height_scale = -1.0;
    assert!(matches!(render(&broken, &cam, &light, &ok), Err(CpuRenderError::Model(_))));
    // No lights: black, not an error.
    assert_eq!(render(&m, &cam, &[], &ok).unwrap().mean(), 0.0);
}

#[test]
fn extreme_but_valid_models_render_finite() {
    // Parameters at the ends of their ranges (huge k, narrowest β, γ on and off, a = 1e4,
    // η = 4) under grazing and overhead lights, from grazing and overhead views.
    let params = ClothParams::new(
        Vec3::splat(65504.0),
        4.0,
        1e4,
        &[ClothLobe { k: Vec3::splat(65504.0), beta: 1e-3, gamma: 1e-3 }, ClothLobe { k: Vec3::ZERO, beta: 1e4, gamma: 0.0 }, ClothLobe { k: Vec3::splat(1.0), beta: 0.001, gamma: 1e4 }],
    );
    let depth = |x: f32, y: f32| 0.15 + 0.14 * (40.0 * x).sin() * (37.0 * y).cos();
    let mut m = examples::uniform_model(16, 16, 5, tile(), depth, &params, Vec3::new(0.0, 0.0, -1.0), Vec3::Z).unwrap();
    examples::add_flyaways(&mut m, 0, &[(1, 1, FlyawayInput { depth: 0, alpha: 1.0, tangent: Vec3::Z, param: 0 })], &params).unwrap();
    for (theta, phi) in [(0.0f32, 0.0f32), (89.0, 45.0)] {
        let cam = Camera::orbit_orthographic(theta, phi, Vec3::new(0.0, 0.0, 0.3), 3.0, 1.5, 24, 24);
        let lights = [Light::directional(fabric_runtime::scene::direction_from_angles(89.9, 10.0), Vec3::splat(1e3)), Light::Point { position: Vec3::new(0.0, 0.0, 0.3), intensity: Vec3::ONE }];
        for periodic in [false, true] {
            let opts = CpuRenderOptions { periodic, shadows: ShadowMode::On, max_steps: 64, ..Default::default() };
            let image = render(&m, &cam, &lights, &opts).unwrap();
            assert!(image.first_non_finite().is_none());
            assert!(image.pixels.iter().all(|p| p.min_element() >= 0.0));
        }
    }
}

#[test]
fn supersampled_far_views_converge_on_the_supersampled_level_0() {
    // A far view of the synthetic chain, 8 level-0 texels per pixel, against level 0 at
    // 16 × 16 samples per pixel. Each of s × s samples filters its own sub-pixel, so more
    // samples come closer; when each filtered the whole pixel, 8 × 8 samples blurred the
    // pixel's box over the sample grid and were further off than one (satin's 16 px far
    // view at 45°: 14.1% against 9.7%).
    let m = examples::synthetic_model(64, 7);
    let b = m.bounds();
    let top = Vec3::new(b.center().x, b.center().y, b.max.z);
    let cam = Camera::orbit_orthographic(45.0, 30.0, top, 4.0 * b.size().length(), 2.0 * b.size().x, 16, 16);
    let light = [Light::directional(fabric_runtime::scene::direction_from_angles(40.0, 210.0), Vec3::ONE)];
    let opts = |level, s| CpuRenderOptions { level, periodic: true, supersampling: s, ..Default::default() };
    let truth = render(&m, &Camera { width: 16 * 8, height: 16 * 8, ..cam }, &light, &opts(LevelChoice::Fixed(0), 2)).unwrap().box_downsample(8);
    let e = |s| fabric_runtime::metrics::relative_rmse(&render(&m, &cam, &light, &opts(LevelChoice::Auto { bias: 0.0 }, s)).unwrap(), &truth).unwrap();
    let (e1, e2, e8) = (e(1), e(2), e(8));
    println!("far view, chain against supersampled level 0: 1 spp {:.2}%, 2x2 {:.2}%, 8x8 {:.2}%", 100.0 * e1, 100.0 * e2, 100.0 * e8);
    // 8 × 8 samples come within 2% (1.4% measured, the truth's own 16 × 16 samples per
    // pixel near its floor), well under the 2 × 2's (2.6%; 3.1% with level 0's grid
    // capped at 16 lookups, when the bound was half of it).
    assert!(e2 < e1 && e8 < 0.6 * e2 && e8 < 0.02, "no convergence: {e1} / {e2} / {e8}");
}

#[test]
fn a_flyaway_grid_cell_holds_its_own_ray_and_lookups_keep_the_mean_transmittance() {
    use fabric_runtime::cpu::render::{fly_cell, lookup_transmittances, tap_offset};
    // Each ray's own offset lies in its own cell, for skewed and degenerate axes alike;
    // points beyond the grid fall in its edge cells.
    for (a, b) in [(Vec2::new(0.3, 0.0), Vec2::new(0.0, 0.1)), (Vec2::new(0.2, 0.15), Vec2::new(-0.05, 0.12)), (Vec2::new(0.1, 0.0), Vec2::ZERO), (Vec2::ZERO, Vec2::new(0.0, 0.4))] {
        for (ta, tb) in [(1u32, 1u32), (4, 2), (8, 4), (2, 1)] {
            for k in 0..ta * tb {
                let o = tap_offset(a, ta, b, tb, k);
                // With an empty axis, rays along it coincide: any of them will do.
                let got = fly_cell(o, a, ta, b, tb);
                assert!(got < ta * tb && (tap_offset(a, ta, b, tb, got) - o).length() < 1e-6, "axes {a} {b}, {ta}x{tb}, ray {k}: cell {got}");
                if a != Vec2::ZERO && b != Vec2::ZERO {
                    assert_eq!(got, k, "axes {a} {b}, {ta}x{tb}");
                }
            }
            assert!(fly_cell(a * 3.0 + b * 3.0, a, ta, b, tb) < ta * tb);
        }
    }
    assert_eq!(fly_cell(Vec2::new(10.0, 10.0), Vec2::X, 4, Vec2::Y, 2), 7);
    assert_eq!(fly_cell(Vec2::new(-10.0, -10.0), Vec2::X, 4, Vec2::Y, 2), 0);
    // Lookups behind the rays' gaps weigh more, their mean stays the pixel's.
    let (fa, fb) = (Vec2::new(0.4, 0.0), Vec2::new(0.0, 0.2));
    // The 2×2 lookups at x = ±0.1 fall in the rays' cells 1 and 3 (and 5, 7 across).
    let fly_t = [0.0, 1.0, 0.0, 0.2, 0.0, 1.0, 0.0, 0.2];
    let mean_t = fly_t.iter().sum::<f32>() / 8.0;
    let offsets: Vec<Vec2> = (0..4).map(|k| tap_offset(Vec2::new(0.4, 0.0), 2, Vec2::new(0.0, 0.2), 2, k)).collect();
    let t = lookup_transmittances(&offsets, &fly_t, (fa, fb), (4, 2), mean_t);
    assert!((t.iter().sum::<f32>() / 4.0 - mean_t).abs() < 1e-6, "{t:?}");
    assert!(t[0] > t[1] && t[2] > t[3], "the lookups over the open rays weigh more: {t:?}");
    assert!((t[0] - 0.5).abs() < 1e-6 && (t[1] - 0.1).abs() < 1e-6, "{t:?}");
    // Uniform flyaways, or none let through: the mean in front of every lookup.
    assert!(lookup_transmittances(&offsets, &[0.3; 8], (fa, fb), (4, 2), 0.3).iter().all(|x| (x - 0.3).abs() < 1e-6));
    assert!(lookup_transmittances(&offsets, &[0.0; 8], (fa, fb), (4, 2), 0.2).iter().all(|&x| x == 0.2));
}

#[test]
fn the_split_filters_change_only_the_flyaways_of_views_with_a_flyaway_grid() {
    // `CoarseFilter::Split`: the box grid's rays shaded, a 4 × 4 grid one level finer
    // marched unshaded for the coverage (render.rs, FlyCover) where the box grid's rays
    // march a coarse level; `SplitShaded`: that grid shaded too, its light the
    // flyaways'. A close-up (no flyaway grid), a view whose flyaway rays march level 0
    // and a model without flyaways draw the box filter's image bit for bit; a far view
    // of flyaways does not, and the two split filters draw different ones.
    let model = examples::synthetic_model(32, 3);
    let lights = [Light::directional(Vec3::new(-0.3, 0.2, 1.0), Vec3::ONE)];
    let opts = |coarse_filter| CpuRenderOptions { periodic: true, coarse_filter, ..Default::default() };
    let centre = Vec3::new(0.5, 0.5, 0.0);
    // 0.2 texels per pixel (under FINE_GRID_FROM: one flyaway ray) and 6.
    let near = Camera::orbit_orthographic(30.0, 30.0, centre, 40.0, 0.15, 24, 24);
    let far = Camera::orbit_orthographic(30.0, 30.0, centre, 40.0, 6.0, 32, 32);
    let at = |m: &fabric_runtime::hybrid::HybridModel, cam: &Camera, f| render(m, cam, &lights, &opts(f)).unwrap();
    let mut bare = model.clone();
    bare.levels.iter_mut().for_each(|l| l.flyaways = None);
    let mut images = Vec::new();
    for split in [CoarseFilter::Split, CoarseFilter::SplitShaded] {
        assert_eq!(at(&model, &near, split).pixels, at(&model, &near, CoarseFilter::Box).pixels);
    // About one texel per pixel: the flyaways' grid spreads, but its rays march level 0,
    // whose voxels a finer grid would only supersample: no coverage grid, the box's image.
        let mid = Camera::orbit_orthographic(30.0, 30.0, centre, 40.0, 1.0, 32, 32);
        let m = Scene::new(&model, &mid, &lights, opts(split)).unwrap().level_mix(16.5, 16.5, model.tile.top_z);
        assert!(m.fly_taps.0 * m.fly_taps.1 > 1 && m.fly == (0, 0, 0.0) && m.cover.is_none(), "{m:?}");
        assert_eq!(at(&model, &mid, split).pixels, at(&model, &mid, CoarseFilter::Box).pixels);
        let scene = Scene::new(&model, &far, &lights, opts(split)).unwrap();
        let m = scene.level_mix(16.5, 16.5, model.tile.top_z);
        let cover = m.cover.expect("a far view has a coverage grid");
        assert!(cover.taps.0 * cover.taps.1 == 4 * m.fly_taps.0 * m.fly_taps.1 && cover.fly.0 <= m.fly.0, "{m:?}");
        assert!(Scene::new(&model, &far, &lights, opts(CoarseFilter::Box)).unwrap().level_mix(16.5, 16.5, model.tile.top_z).cover.is_none());
        let (image, boxed) = (at(&model, &far, split), at(&model, &far, CoarseFilter::Box));
        assert!(image.pixels.iter().all(|p| p.is_finite()));
        assert!(image.pixels != boxed.pixels, "{split:?}: the flyaways came from the box grid");
        assert_eq!(at(&bare, &far, split).pixels, at(&bare, &far, CoarseFilter::Box).pixels);
        images.push(image);
    }
    assert!(images[0].pixels != images[1].pixels, "the shaded coverage grid changed nothing");
    // They differ in the flyaways' light alone: with black fibres (k_d and every k zero,
    // f16 bits 0) the coverage and the surface through it are the same image.
    let mut dark = model.clone();
    for level in dark.levels.iter_mut() {
        if let Some(f) = level.flyaways.as_mut() {
            f.table.headers.iter_mut().for_each(|h| h.kd = [0; 3]);
            f.table.lobes.iter_mut().for_each(|l| l.k = [0; 3]);
        }
    }
    let split_dark = at(&dark, &far, CoarseFilter::Split);
    let shaded_dark = at(&dark, &far, CoarseFilter::SplitShaded);
    assert_eq!(split_dark.pixels, shaded_dark.pixels, "black flyaways: the coverage and the surface are the same in both");
    // `SplitShaded` shades the lights along the finer grid and an environment's SG part
    // along the box grid, spread as `Split` spreads it: lit by the SG part alone (the
    // sky prefiltered whole, no lights) the two are one image, and with a light they are
    // not.
    use fabric_runtime::scene::{EnvMapOptions, PrefilteredEnv, Sky};
    let sky = Sky::default().env_map(EnvMapOptions::default()).unwrap();
    let env = fabric_runtime::cpu::EnvLight::new(PrefilteredEnv::new(&sky));
    let under = |f, lights: &[Light]| render(&model, &far, lights, &CpuRenderOptions { env: Some(env.clone()), ..opts(f) }).unwrap();
    let (split_sky, shaded_sky) = (under(CoarseFilter::Split, &[]), under(CoarseFilter::SplitShaded, &[]));
    assert!(split_sky.mean() > 1e-4);
    assert_eq!(split_sky.pixels, shaded_sky.pixels, "the environment's SG part is spread alike");
    assert!(under(CoarseFilter::Split, &lights).pixels != under(CoarseFilter::SplitShaded, &lights).pixels);
}

/// Format 1.13's flyaway shadow: a surface hit's light passes through the flyaways
/// between it and the top plane, (1 − α)^(ℓ/s) per voxel over the path ℓ toward the
/// light, the environment's straight up; the flyaways' own light and everything else are
/// unchanged, and without the model's flag, shadows, or for a light below, nothing is.
#[test]
fn flyaways_shadow_the_surface_by_their_transmittance_toward_the_light() {
    use fabric_runtime::scene::{Ray, direction_from_angles};
    // 8² texels of 1/8 over a flat surface at depth 0.2 (z = 0.1); every column holds a
    // voxel of α = 0.5 at depth index 2, [0.02, 0.03] below the top plane (z 0.27–0.28).
    let params = ClothParams::new(Vec3::new(0.5, 0.4, 0.3), 1.5, 0.0, &[ClothLobe { k: Vec3::splat(0.3), beta: 0.3, gamma: ClothLobe::GAMMA_OFF }]);
    let plain = examples::uniform_model(8, 8, 1, tile(), |_, _| 0.2, &params, Vec3::Z, Vec3::X).unwrap();
    let voxels: Vec<_> = (0..64u32).map(|k| (k % 8, k / 8, FlyawayInput { depth: 2, alpha: 0.5, tangent: Vec3::X, param: 0 })).collect();
    let mut off = plain.clone();
    examples::add_flyaways(&mut off, 0, &voxels, &params).unwrap();
    let mut on = off.clone();
    on.meta.flyaway_shadow = true;
    let alpha = on.levels[0].flyaways.as_ref().unwrap().nodes[0].alpha();
    let edge = (0.125f32 * 0.125 * 0.01).cbrt();
    let p = Vec3::new(0.06, -0.13, 0.1);
    let opts = CpuRenderOptions { periodic: true, shadows: ShadowMode::On, ..Default::default() };
    for theta in [0.0f32, 35.0, 62.0] {
        let wi = direction_from_angles(theta, 40.0);
        let lights = [Light::directional(wi, Vec3::ONE)];
        let scene = Scene::for_rays(&on, &lights, opts.clone()).unwrap();
        let want = (1.0 - alpha).powf(0.01 / wi.z / edge);
        let (got, limited) = scene.flyaway_shadow(0, p, wi, f32::INFINITY);
        assert!((got - want).abs() < 1e-4 && !limited, "θ = {theta}: transmittance toward the light {got} vs {want}");
        // The probe (what the bake fits with) sees the same.
        let down = Ray::new(Vec3::new(p.x, p.y, 1.0), -Vec3::Z);
        let hit = scene.probe_ray(&down, 0, true).surface.unwrap();
        assert!((hit.visibility - want).abs() < 1e-4, "θ = {theta}: probe visibility {}", hit.visibility);
        assert_eq!(scene.probe_ray(&down, 0, false).surface.unwrap().visibility, 1.0, "a probe without flyaways");
        // In the image: only the surface's light changes, by that factor, behind what the
        // view's flyaways let through. A ray down a column: flyaways' radiance + T·surface.
        let (a, b, bare) = (scene.trace_ray(&down, 0), Scene::for_rays(&off, &lights, opts.clone()).unwrap().trace_ray(&down, 0), Scene::for_rays(&plain, &lights, opts.clone()).unwrap().trace_ray(&down, 0));
        let t_view = 1.0 - b.flyaway_opacity;
        assert!(t_view > 0.1 && t_view < 0.95, "the view crosses the voxel: {t_view}");
        let delta = (a.radiance - b.radiance) - t_view * (want - 1.0) * bare.radiance;
        assert!(delta.abs().max_element() < 1e-5, "θ = {theta}: {} vs {} ({delta})", a.radiance, b.radiance);
        // Without the flag, without flyaways rendered, or for a light below: nothing. Without
        // the height field's shadow rays (the bake's default), the same shadow.
        assert_eq!(Scene::for_rays(&off, &lights, opts.clone()).unwrap().flyaway_shadow(0, p, wi, f32::INFINITY).0, 1.0);
        assert_eq!(Scene::for_rays(&on, &lights, CpuRenderOptions { flyaways: false, ..opts.clone() }).unwrap().flyaway_shadow(0, p, wi, f32::INFINITY).0, 1.0);
        assert_eq!(scene.flyaway_shadow(0, p, -wi, f32::INFINITY).0, 1.0);
        assert_eq!(Scene::for_rays(&on, &lights, CpuRenderOptions { shadows: ShadowMode::Off, ..opts.clone() }).unwrap().flyaway_shadow(0, p, wi, f32::INFINITY), (got, limited));
    }
    // A point light within the layer's reach: the path stops at the light (below the voxel).
    let scene = Scene::for_rays(&on, &[], opts.clone()).unwrap();
    assert_eq!(scene.flyaway_shadow(0, p, Vec3::Z, 0.1).0, 1.0, "a light below the voxel");
    // The environment's: straight up.
    let sky = scene.flyaway_sky(0, p);
    assert!((sky - (1.0 - alpha).powf(0.01 / edge)).abs() < 1e-4, "sky {sky}");
    assert_eq!(Scene::for_rays(&off, &[], opts).unwrap().flyaway_sky(0, p), 1.0);
}
