//! Pipeline tests on synthetic volumes with known answers (testvol.rs).

use std::f32::consts::TAU;

use glam::Vec3;

use super::testvol::{add_fiber, empty, height_field, noise};
use super::*;
use crate::volume::Voxel;

fn extract(vol: &FabricVolume) -> Geometry {
    extract_geometry(vol, &GeometryOptions::default()).unwrap()
}

/// Maps are finite, normals unit, tangents unit and ⟂ normals (1e-5: f32 rounding of a
/// normalize and a projection).
fn check_invariants(g: &Geometry) {
    assert_eq!(g.h0.len(), g.texels());
    assert!(g.h0.iter().chain(&g.h).all(|v| v.is_finite() && *v >= 0.0 && *v <= g.depth as f32 + 1e-4));
    for (n, t) in g.normals.iter().zip(&g.tangents) {
        assert!(n.is_finite() && t.is_finite());
        assert!((n.length() - 1.0).abs() < 1e-5 && (t.length() - 1.0).abs() < 1e-5, "n {n} t {t}");
        assert!(n.dot(*t).abs() < 1e-5, "n {n} t {t}");
        assert!(n.z > 0.0);
    }
    assert!(g.filter_size.iter().all(|s| s.is_finite() && *s >= 0.0));
    assert!(g.fiber_thickness.is_finite() && g.fiber_thickness > 0.0);
    assert!(g.flyaways.voxels.iter().all(|v| v.fiber_diameter.is_finite() && v.density > 0.0));
}

/// A weave-like surface: periods 32 (x) and 24 (y) texels, slopes up to 0.8 voxel per
/// texel, plus ±0.4 voxel of per-column fiber-level noise.
fn sinusoid(dims: [usize; 3], base: f32) -> (FabricVolume, Vec<f32>) {
    let nx = dims[0];
    height_field(
        dims,
        move |x, y| {
            let column = (x.floor() as u64) + nx as u64 * (y.floor() as u64);
            base + 3.0 * (TAU * x / 32.0).sin() + 2.5 * (TAU * y / 24.0).sin() + 0.4 * noise(column, 7)
        },
        |_, _, _| Vec3::X,
    )
}

#[test]
fn sinusoidal_surface_gives_h0_and_the_filter_size() {
    let (vol, truth) = sinusoid([128, 96, 24], 12.0);
    let g = extract(&vol);
    check_invariants(&g);
    // h0 is the column's mean surface height: exact partial-volume coverage, except a
    // top cell filled below the 5% threshold counts as empty (≤ 0.05 voxel), plus f16
    // rounding of densities (≤ 2⁻¹¹ per cell). The issue asks for half a voxel.
    let worst = g.h0.iter().zip(&truth).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
    eprintln!("sinusoid: worst h0 error {worst:.4} voxels, filter size {:?} (periods 32, 24)", g.filter_size);
    assert!(worst <= 0.06, "worst h0 error {worst} voxels");
    assert_eq!(g.hole_columns, 0);
    assert_eq!(g.clipped_columns, 0);
    assert!(g.flyaways.is_empty(), "{} flyaways on a bare surface", g.flyaways.len());
    // The filter size is the period, within one texel (issue); parabolic refinement of
    // a peak averaged over 96 or 128 lines does better.
    assert!(g.filter_auto);
    assert!((g.filter_size[0] - 32.0).abs() < 1.0 && (g.filter_size[1] - 24.0).abs() < 1.0, "filter size {:?}", g.filter_size);
    // h keeps the yarn-scale shape (a 32-texel sinusoid keeps exp(−2π²/36) = 58% of its
    // amplitude at σ = 32/6) and loses the fiber-level noise: h0 − h is mostly noise.
    let detail_rms = (g.h0.iter().zip(&g.h).map(|(a, b)| (a - b).powi(2)).sum::<f32>() / g.texels() as f32).sqrt();
    assert!(detail_rms > 0.1 && detail_rms < 2.0, "detail rms {detail_rms}");
    let [lo, hi] = Geometry::range(&g.h);
    assert!(hi - lo > 3.0 && hi - lo < 11.0, "h range {lo}..{hi}");
}

#[test]
fn filter_size_follows_a_fractional_period() {
    // 6 repeats over 128 texels along x: period 21.33; 4 over 64 along y: 16.
    let (vol, _) = height_field([128, 64, 16], |x, y| 8.0 + 2.0 * (TAU * x * 6.0 / 128.0).sin() + 1.5 * (TAU * y / 16.0).cos(), |_, _, _| Vec3::Y);
    let g = extract(&vol);
    assert!((g.filter_size[0] - 128.0 / 6.0).abs() < 1.0 && (g.filter_size[1] - 16.0).abs() < 1.0, "{:?}", g.filter_size);
    let small = extract_geometry(&vol, &GeometryOptions { filter_rule: FilterRule::Smaller, ..Default::default() }).unwrap();
    assert_eq!(small.filter_size, [g.filter_size[1]; 2]);
}

#[test]
fn unpatterned_surface_gets_the_default_filter_size_and_says_so() {
    // Felt-like: white noise blurred by σ = 3 texels (stationary, no lattice), ±2 voxels,
    // on a small tile where the large-scale swells make bumps of ~0.2 in C.
    let (nx, ny) = (96, 96);
    for seed in [3, 4, 5] {
        let white: Vec<f32> = (0..nx * ny).map(|k| noise(k as u64, seed)).collect();
        let smooth = blur::periodic_gaussian(&white, nx, ny, [3.0, 3.0]);
        let rms = (smooth.iter().map(|v| v * v).sum::<f32>() / smooth.len() as f32).sqrt();
        let (vol, _) = height_field([nx, ny, 20], |x, y| 10.0 + 2.0 * smooth[(x as usize % nx) + nx * (y as usize % ny)] / rms, |_, _, _| Vec3::X);
        let g = extract(&vol);
        check_invariants(&g);
        assert!(!g.filter_auto, "seed {seed}: peaks {:?}", g.autocorrelation_peaks);
        assert_eq!(g.filter_size, [6.0 * g.fiber_thickness; 2]);
        assert!(g.warnings.iter().any(|w| w.contains("no clear autocorrelation peak")), "{:?}", g.warnings);
        // The null standard error matches Bartlett's for this field: Σρ² = πσ_ρ² with
        // σ_ρ = 3√2 gives √(56.5/9216) = 0.078 (±30% for the sampling of the lobes).
        let ac = autocorrelation::autocorrelate(&g.h0, nx, ny).unwrap();
        for sd in ac.null_sd {
            assert!((sd - 0.078).abs() < 0.025, "seed {seed}: null sd {sd}");
        }
    }
}

#[test]
fn flyaway_strands_above_a_body_are_all_found_and_nothing_else() {
    let dims = [64, 64, 32];
    let (mut vol, truth) = height_field(dims, |x, y| 10.0 + 0.8 * (TAU * x / 32.0).sin() * (TAU * y / 64.0).cos(), |_, _, _| Vec3::X);
    let body: Vec<bool> = vol.voxels().iter().map(|v| !v.is_empty()).collect();
    // Strands of diameter 2: along x, along y, diagonal (all wrapping the tile), and a
    // finite one rising at 25°; at least 3 voxels apart wherever they pass over each
    // other (touching strands would be two fibers thick: a surface, by definition).
    let r = 1.0;
    let mut strands = Vec::new();
    strands.extend(add_fiber(&mut vol, Vec3::new(0.0, 20.3, 17.2), Vec3::X, r, f32::INFINITY));
    strands.extend(add_fiber(&mut vol, Vec3::new(52.6, 0.0, 22.5), Vec3::Y, r, f32::INFINITY));
    strands.extend(add_fiber(&mut vol, Vec3::new(0.0, 0.0, 29.0), Vec3::new(1.0, 1.0, 0.0), r, f32::INFINITY));
    let rise = Vec3::new(25f32.to_radians().cos(), 0.0, 25f32.to_radians().sin());
    strands.extend(add_fiber(&mut vol, Vec3::new(30.0, 45.0, 20.0), rise, r, 12.0));

    let g = extract(&vol);
    check_invariants(&g);
    let mask = g.flyaway_mask();
    assert_eq!(mask.count(), g.flyaways.len());
    // The mask in the reference renderer's form, and the stricter above-surface mask:
    // V ⊂ above surface, and no non-empty body voxel is above the surface (only the
    // body's sub-threshold partial cells, which count as empty).
    let bools = mask.to_bools();
    let above = g.above_surface_mask();
    assert_eq!(bools.iter().filter(|&&b| b).count(), g.flyaways.len());
    assert!(bools.iter().zip(&above).all(|(&v, &a)| !v || a));
    for (k, (&b, &a)) in body.iter().zip(&above).enumerate() {
        assert!(!(b && a) || vol.voxels()[k].density() <= g.density.threshold, "body voxel {k} above the surface");
    }
    let thr = g.density.threshold;
    // Every strand voxel above the threshold is in V.
    for &([x, y, z], _) in &strands {
        if vol.voxel(x, y, z).density() > thr {
            assert!(mask.contains(x, y, z), "strand voxel ({x}, {y}, {z}) missed");
        }
    }
    // No body voxel is in V, and V holds nothing but strands.
    for (k, &b) in body.iter().enumerate() {
        let (x, y, z) = (k % 64, (k / 64) % 64, k / 4096);
        if b {
            assert!(!mask.contains(x, y, z), "body voxel ({x}, {y}, {z}) classified as flyaway");
        }
    }
    assert!(g.flyaways.voxels.iter().all(|v| !body[v.x as usize + 64 * (v.y as usize + 64 * v.z as usize)]));
    // The surface under the strands is the body's (bound as in the sinusoid test).
    let worst = g.h0.iter().zip(&truth).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
    assert!(worst <= 0.06, "worst h0 error {worst}");
    // Fiber thickness and per-voxel diameters measure the strands' 2 voxels: the
    // cross-section estimate is within 3% on a clean cylinder (flyaways.rs); crossings
    // and the strands' ends add a tail that the mode and median ignore.
    assert!(g.fiber_thickness_auto && (g.fiber_thickness - 2.0).abs() < 0.3, "fiber thickness {}", g.fiber_thickness);
    let mut d: Vec<f32> = g.flyaways.voxels.iter().map(|v| v.fiber_diameter).collect();
    d.sort_by(f32::total_cmp);
    let median = d[d.len() / 2];
    eprintln!("strands (d = 2): fiber thickness {:.3}, median flyaway diameter {median:.3}, {} flyaway voxels", g.fiber_thickness, g.flyaways.len());
    assert!((median - 2.0).abs() < 0.3, "median flyaway diameter {median}");
    // Each flyaway voxel keeps its strand's orientation (axes: compare |cos|).
    for v in &g.flyaways.voxels {
        let want = [Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0).normalize(), rise];
        assert!(want.iter().any(|w| v.orientation.dot(*w).abs() > 0.9999), "{:?}", v.orientation);
    }
}

#[test]
fn tangents_follow_a_known_orientation_field_regardless_of_fiber_sign() {
    // Fiber axis rotating with x and tilting with y; the sign flips from voxel to voxel.
    let dims = [64, 48, 16];
    let axis = |x: usize, y: usize| {
        let a = TAU * x as f32 / 64.0;
        Vec3::new(a.cos(), a.sin(), 0.4 * (TAU * y as f32 / 48.0).sin()).normalize()
    };
    let (vol, _) = height_field(dims, |x, y| 8.0 + 1.5 * (TAU * x / 16.0).sin() + (TAU * y / 12.0).cos(), |x, y, z| {
        let s = if noise((x + 64 * (y + 48 * z)) as u64, 11) > 0.0 { 1.0 } else { -1.0 };
        axis(x, y) * s
    });
    let g = extract(&vol);
    check_invariants(&g);
    assert_eq!(g.tangent_fallback_texels, 0);
    // Octahedral coding of ω_f is within 0.05°, so t matches the projected axis to 0.1°.
    let mut worst = 0.0f32;
    for j in 0..48 {
        for i in 0..64 {
            let n = g.normals[i + 64 * j];
            let want = tangents::tangent_from_axis(axis(i, j), n).unwrap();
            worst = worst.max(g.tangents[i + 64 * j].angle_between(want));
        }
    }
    eprintln!("orientation field: worst tangent error {:.4}°", worst.to_degrees());
    assert!(worst.to_degrees() < 0.1, "worst tangent error {}°", worst.to_degrees());
}

#[test]
fn empty_volume_is_rejected() {
    let err = extract_geometry(&empty([8, 8, 8]), &GeometryOptions::default()).unwrap_err();
    assert!(matches!(err, GeometryError::EmptyVolume { .. }), "{err}");
    assert!(err.to_string().contains("empty"), "{err}");
}

#[test]
fn fully_solid_block_is_a_flat_surface_at_the_top_with_a_warning() {
    let (vol, _) = height_field([16, 16, 8], |_, _| 100.0, |_, _, _| Vec3::Y);
    let g = extract(&vol);
    check_invariants(&g);
    assert!(g.h0.iter().chain(&g.h).all(|&h| (h - 8.0).abs() < 1e-5));
    assert_eq!(g.clipped_columns, 256);
    assert!(g.warnings.iter().any(|w| w.contains("cut off at the top")), "{:?}", g.warnings);
    assert!(g.warnings.iter().any(|w| w.contains("h0 is flat")), "{:?}", g.warnings);
    assert!(g.normals.iter().all(|n| *n == Vec3::Z));
    assert!(g.tangents.iter().all(|t| t.abs_diff_eq(Vec3::Y, 1e-4)));
    assert!(g.flyaways.is_empty());
}

#[test]
fn one_voxel_layer_is_rejected_unless_the_fiber_thickness_allows_it() {
    let (vol, _) = height_field([16, 16, 8], |_, _| 4.0, |_, _, _| Vec3::X);
    // Keep only cell z = 3: a layer one voxel thick.
    let mut layer = empty([16, 16, 8]);
    for j in 0..16 {
        for i in 0..16 {
            layer.set(i, j, 3, *vol.voxel(i, j, 3));
        }
    }
    let err = extract_geometry(&layer, &GeometryOptions::default()).unwrap_err();
    assert!(matches!(err, GeometryError::NoSurface { .. }), "{err}");
    assert!(err.to_string().contains("fiber thickness"), "{err}");
    let g = extract_geometry(&layer, &GeometryOptions { fiber_thickness: Some(0.5), ..Default::default() }).unwrap();
    check_invariants(&g);
    assert!(g.h0.iter().all(|&h| (h - 4.0).abs() < 1e-5));
}

#[test]
fn volume_filled_to_the_top_row_is_handled_and_reported() {
    // The sinusoid pokes through the top face on its crests.
    let (vol, truth) = sinusoid([64, 48, 14], 11.0);
    let g = extract(&vol);
    check_invariants(&g);
    assert!(g.clipped_columns > 0 && g.clipped_columns < 64 * 48);
    assert!(g.warnings.iter().any(|w| w.contains("cut off at the top")));
    // Where the surface is inside the volume h0 is as accurate as ever; where it is
    // cut off it sits at the top face (the truth clamped to nz).
    let worst = g.h0.iter().zip(&truth).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
    assert!(worst <= 0.06, "worst h0 error {worst}");
    assert!(Geometry::range(&g.h0)[1] <= 14.0);
}

#[test]
fn isolated_fibers_without_a_body_are_rejected() {
    // Two crossing fibers of diameter 2 and nothing else. Too few of them lie above
    // another run to measure the thickness, so it is given, as a user would.
    let mut vol = empty([32, 32, 16]);
    add_fiber(&mut vol, Vec3::new(0.0, 10.5, 8.0), Vec3::X, 1.0, f32::INFINITY);
    add_fiber(&mut vol, Vec3::new(20.5, 0.0, 4.0), Vec3::Y, 1.0, f32::INFINITY);
    let err = extract_geometry(&vol, &GeometryOptions { fiber_thickness: Some(2.0), ..Default::default() }).unwrap_err();
    assert!(matches!(err, GeometryError::NoSurface { .. }), "{err}");
}

#[test]
fn tiny_volumes_and_bad_options_are_rejected_with_names() {
    let (vol, _) = height_field([3, 8, 4], |_, _| 2.0, |_, _, _| Vec3::X);
    assert!(matches!(extract(&vol_ok()).dims, [8, 8]));
    let err = extract_geometry(&vol, &GeometryOptions::default()).unwrap_err();
    assert!(matches!(err, GeometryError::TooSmall { .. }), "{err}");
    let cases: [(GeometryOptions, &str); 5] = [
        (GeometryOptions { fiber_thickness: Some(f32::NAN), ..Default::default() }, "fiber_thickness"),
        (GeometryOptions { density_threshold: DensityThreshold::Relative(1.5), ..Default::default() }, "density_threshold"),
        (GeometryOptions { filter_size: Some([-1.0, 2.0]), ..Default::default() }, "filter_size"),
        (GeometryOptions { tangent_depth: 0, ..Default::default() }, "tangent_depth"),
        (GeometryOptions { peak_search: PeakSearch { min_prominence: 0.0, ..Default::default() }, ..Default::default() }, "min_prominence"),
    ];
    for (o, name) in cases {
        let err = extract_geometry(&vol_ok(), &o).unwrap_err();
        assert!(matches!(err, GeometryError::BadOption { .. }) && err.to_string().contains(name), "{err}");
    }
    // An absolute threshold above every density leaves nothing: empty, with numbers.
    let err = extract_geometry(&vol_ok(), &GeometryOptions { density_threshold: DensityThreshold::Absolute(5.0), ..Default::default() }).unwrap_err();
    assert!(matches!(err, GeometryError::EmptyVolume { threshold: 5.0, .. }), "{err}");
}

fn vol_ok() -> FabricVolume {
    height_field([8, 8, 6], |x, _| 3.0 + (TAU * x / 8.0).sin(), |_, _, _| Vec3::X).0
}

#[test]
fn extraction_is_bit_identical_for_any_thread_count() {
    let (mut vol, _) = sinusoid([64, 48, 24], 10.0);
    add_fiber(&mut vol, Vec3::new(0.0, 20.3, 20.0), Vec3::X, 1.0, f32::INFINITY);
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let mut g = pool.install(|| extract(&vol));
        g.stage_times.clear();
        g
    };
    let (a, b) = (run(1), run(3));
    assert!(!a.flyaways.is_empty());
    assert!(a == b, "results differ between 1 and 3 threads");
}

#[test]
fn files_round_trip_and_previews_are_written() {
    let (mut vol, _) = sinusoid([48, 48, 24], 10.0);
    add_fiber(&mut vol, Vec3::new(0.0, 20.3, 20.0), Vec3::X, 1.0, f32::INFINITY);
    let g = extract(&vol);
    let dir = std::env::temp_dir().join(format!("fabric-geometry-{}", std::process::id()));
    let report = g.write_dir(&dir, GeometryOptions::default().sigma_per_filter_size).unwrap();
    assert_eq!(report.flyaway_voxels, g.flyaways.len());
    let back = Geometry::read_dir(&dir).unwrap();
    assert!(back == g, "read back differs");
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("geometry.json")).unwrap()).unwrap();
    for key in ["filter_size", "fiber_thickness", "flyaway_voxels", "height_range", "stage_times"] {
        assert!(json.get(key).is_some(), "geometry.json lacks {key}");
    }
    let written = preview::write_previews(&g, &dir).unwrap();
    for p in &written {
        let img = image::open(p).unwrap();
        assert!(img.width() > 0, "{}", p.display());
    }
    assert_eq!(written.len(), 7);
    // A damaged data file is named in the error.
    std::fs::write(dir.join("h.exr"), b"not an exr").unwrap();
    let err = Geometry::read_dir(&dir).unwrap_err();
    assert!(err.to_string().contains("h.exr"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn voxel_is_empty_agrees_with_zero_coverage() {
    // The scan treats ρ ≤ threshold as empty; an explicit zero voxel is empty at any
    // threshold (guards the f16 sign bit).
    let d = DensityScale { solid: 1.0, threshold: 0.0 };
    assert_eq!(d.coverage(Voxel::EMPTY.density()), 0.0);
    assert_eq!(d.coverage(Voxel::pack(-0.0, Vec3::ONE, Vec3::X).density()), 0.0);
}

#[test]
fn progress_reports_every_stage_and_reaches_each_total() {
    use std::sync::Mutex;
    #[derive(Default)]
    struct Counter {
        log: Mutex<Vec<(String, u64, u64)>>, // stage, total, done
    }
    impl Progress for Counter {
        fn begin(&self, stage: &str, total: u64) {
            self.log.lock().unwrap().push((stage.to_string(), total, 0));
        }
        fn advance(&self, n: u64) {
            if let Some(last) = self.log.lock().unwrap().last_mut() {
                last.2 += n;
            }
        }
    }
    let (mut vol, _) = sinusoid([48, 40, 24], 10.0);
    add_fiber(&mut vol, Vec3::new(0.0, 20.3, 20.0), Vec3::X, 1.0, f32::INFINITY);
    let counter = Counter::default();
    extract_geometry_with(&vol, &GeometryOptions::default(), &counter).unwrap();
    let log = counter.log.into_inner().unwrap();
    let stages: Vec<&str> = log.iter().map(|l| l.0.as_str()).collect();
    assert_eq!(
        stages,
        [Stage::DensityScale, Stage::FiberThickness, Stage::HeightMap, Stage::Flyaways, Stage::Autocorrelation, Stage::Blur, Stage::Normals, Stage::Tangents].map(Stage::name)
    );
    for (stage, total, done) in log {
        assert_eq!(total, done, "{stage:?}");
    }
}

#[test]
fn columns_without_a_thick_run_take_the_surface_of_their_neighbours_or_are_holes() {
    // A flat body of height 10 with three bands of columns along y:
    // x in 20..24: only a one-voxel layer at z = 9 (a yarn edge thinned to one fiber);
    // x in 40..44: nothing at all (a gap through the fabric);
    // x in 50..54: nothing but one voxel high up at z = 18 (a flyaway over the gap).
    let (mut vol, _) = height_field([64, 32, 24], |_, _| 10.0, |_, _, _| Vec3::Y);
    for y in 0..32 {
        for x in (20..24).chain(40..44).chain(50..54) {
            for z in 0..24 {
                vol.set(x, y, z, Voxel::EMPTY);
            }
        }
        for x in 20..24 {
            vol.set(x, y, 9, Voxel::pack(1.0, Vec3::splat(0.8), Vec3::Y));
        }
        for x in 50..54 {
            vol.set(x, y, 18, Voxel::pack(1.0, Vec3::splat(0.8), Vec3::Y));
        }
    }
    let g = extract_geometry(&vol, &GeometryOptions { fiber_thickness: Some(2.0), ..Default::default() }).unwrap();
    check_invariants(&g);
    assert_eq!(g.filled_columns, 4 * 32);
    assert_eq!(g.hole_columns, 8 * 32);
    for y in 0..32 {
        for x in 0..64 {
            let (h0, top) = (g.h0[x + 64 * y], g.surface_top(x, y));
            match x {
                // The thin layer is the surface at the neighbours' level: top face of cell 9.
                20..24 => assert!(top == Some(9) && (h0 - 10.0).abs() < 1e-5, "({x}, {y}): {h0} {top:?}"),
                40..44 | 50..54 => assert!(top.is_none() && h0 == 0.0, "({x}, {y}): {h0} {top:?}"),
                _ => assert!(top == Some(9) && (h0 - 10.0).abs() < 1e-5, "({x}, {y}): {h0} {top:?}"),
            }
        }
    }
    // V is exactly the voxel over the gap in each column of the last band.
    assert_eq!(g.flyaways.len(), 4 * 32);
    assert!(g.flyaways.voxels.iter().all(|v| v.z == 18 && (50..54).contains(&v.x)));
}

#[test]
fn every_generator_preset_gives_valid_maps() {
    use crate::generate::{Preset, generate};
    for preset in Preset::ALL {
        let vol = generate(&preset.params(), [96, 96, 24], 1).unwrap();
        let g = extract(&vol);
        check_invariants(&g);
        let name = preset.name();
        // The geometry is a surface with a thin layer above: V is a small part of the
        // fabric (2–7% of all voxels on these presets, 1 in 6 non-empty at most) and
        // holes through it are rare (< 1% of columns on these presets).
        let non_empty = vol.voxels().iter().filter(|v| v.density() > g.density.threshold).count();
        assert!(g.flyaways.len() * 6 < non_empty, "{name}: {} flyaway voxels of {non_empty}", g.flyaways.len());
        assert!(g.hole_columns * 50 < g.texels(), "{name}: {} holes", g.hole_columns);
        // Fibers span 1–4 voxels at this resolution (generate/presets.rs).
        assert!((0.8..5.0).contains(&g.fiber_thickness), "{name}: fiber thickness {}", g.fiber_thickness);
        // Weaves show their yarn period; the felt has none.
        match preset {
            Preset::Plain | Preset::Twill => assert!(g.filter_auto, "{name}: peaks {:?}", g.autocorrelation_peaks),
            Preset::Felt => assert!(!g.filter_auto, "{name}: peaks {:?}", g.autocorrelation_peaks),
            _ => {}
        }
    }
}
