use super::twin::*;
use super::*;

fn silk() -> ClothParams {
    ClothParams::new(
        Vec3::new(0.05, 0.03, 0.02),
        1.46,
        2.0,
        &[ClothLobe { k: Vec3::new(0.8, 0.7, 0.6), beta: 0.08, gamma: 0.6 }, ClothLobe { k: Vec3::splat(0.3), beta: 0.3, gamma: ClothLobe::GAMMA_OFF }],
    )
}

/// Direction at (θ, φ) in frame f.
fn dir(f: &ClothFrame, theta: f32, phi: f32) -> Vec3 {
    f.t * theta.sin() + theta.cos() * (f.n * phi.cos() + f.b * phi.sin())
}

#[test]
fn angles_invert_the_direction_construction() {
    let f = cloth_frame(Vec3::new(0.1, 0.2, 1.0), Vec3::new(1.0, 0.3, 0.0));
    for &(theta, phi) in &[(0.3f32, 0.2f32), (-1.2, 2.9), (0.0, -3.0), (1.5, 0.0)] {
        let a = cloth_angles(&f, dir(&f, theta, phi));
        assert!((a.theta - theta).abs() < 1e-5 && (a.phi - phi).abs() < 1e-4, "{theta},{phi} -> {a:?}");
        assert!((a.cos_phi - phi.cos()).abs() < 1e-5);
    }
    // Along t the projection vanishes: φ = 0 by definition.
    let a = cloth_angles(&f, f.t);
    assert_eq!((a.phi, a.cos_phi), (0.0, 1.0));
    assert!((a.theta - std::f32::consts::FRAC_PI_2).abs() < 1e-6);
}

#[test]
fn peak_value_matches_the_closed_form() {
    // At the mirror configuration θ_o = −θ_i, φ_o = −φ_i: G = 1/(√(2π)β), P = 1 and
    // cos θ_d = cos θ_i, so f_r = k_d + F(η, cos θ_i) cos(φ_i)^a Σ k_j /(√(2π)β_j).
    let p = silk();
    let f = cloth_frame(Vec3::Z, Vec3::X);
    let (ti, pi) = (0.35f64, 0.25f64);
    let wi = dir(&f, ti as f32, pi as f32);
    let wo = dir(&f, -ti as f32, -pi as f32);
    let eta = p.eta as f64;
    let c = ti.cos();
    let ct = (1.0 - (1.0 - c * c) / (eta * eta)).sqrt();
    let rs = (c - eta * ct) / (c + eta * ct);
    let rp = (eta * c - ct) / (eta * c + ct);
    let fres = 0.5 * (rs * rs + rp * rp);
    let shadow = pi.cos().powf(p.a as f64);
    for reading in [BrdfReading::Bounded, BrdfReading::Width, BrdfReading::Held] {
        let got = cloth_brdf(&p, &f, wi, wo, reading);
        for ch in 0..3 {
            let spec: f64 = p.lobes().iter().map(|l| l.k[ch] as f64 / ((2.0 * std::f64::consts::PI).sqrt() * l.beta as f64)).sum();
            let want = p.kd[ch] as f64 + fres * shadow * spec;
            // f32 evaluation of exp/asin near the peak: a few ulps of the ~10 result.
            assert!((got[ch] as f64 - want).abs() < 1e-5 * want, "{reading:?} ch{ch}: {} vs {want}", got[ch]);
        }
    }
}

#[test]
fn gaussian_is_normalized_and_falls_off() {
    for beta in [0.01f32, 0.1, 0.7] {
        // Midpoint rule over ±10β with 4000 steps: error far below 1e-4.
        let n = 4000;
        let h = 20.0 * beta as f64 / n as f64;
        let s: f64 = (0..n).map(|i| cloth_gaussian((-10.0 * beta as f64 + (i as f64 + 0.5) * h) as f32, beta) as f64 * h).sum();
        assert!((s - 1.0).abs() < 1e-4, "β={beta}: ∫G = {s}");
    }
    assert!((cloth_phi_falloff(0.4, 0.4) - (-0.5f32).exp()).abs() < 1e-7);
    assert_eq!(cloth_phi_falloff(3.0, ClothLobe::GAMMA_OFF), 1.0);
    // γ = ∞ is clamped to GAMMA_MAX: off to within 1e-7 for |x| ≤ 2π.
    assert!(cloth_phi_falloff(3.0, f32::INFINITY) > 1.0 - 1e-7);
}

#[test]
fn fresnel_limits() {
    let eta = 1.5f32;
    let r0 = ((eta - 1.0) / (eta + 1.0)).powi(2);
    assert!((cloth_fresnel(eta, 1.0) - r0).abs() < 1e-7);
    assert!((cloth_fresnel(eta, 0.0) - 1.0).abs() < 1e-6);
    assert!(cloth_fresnel(1.0, 0.3) < 1e-12, "η = 1: no interface");
    assert_eq!(cloth_fresnel(1.0, 0.0), 0.0);
    // Monotone in the angle of incidence.
    let mut last = 0.0;
    for i in (0..=100).rev() {
        let f = cloth_fresnel(eta, i as f32 / 100.0);
        assert!(f >= last - 1e-7, "{i}: {f} < {last}");
        last = f;
    }
}

#[test]
fn shadowing_zero_to_the_zero_is_one() {
    assert_eq!(cloth_shadowing(0.0, 0.0), 1.0);
    assert_eq!(cloth_shadowing(-0.5, 0.0), 1.0);
    assert_eq!(cloth_shadowing(0.0, 2.0), 0.0);
    assert_eq!(cloth_shadowing(-0.1, 2.0), 0.0);
    assert!((cloth_shadowing(0.5, 2.0) - 0.25).abs() < 1e-7);
    assert_eq!(cloth_shadowing(0.5, 1e30), 0.0);
}

#[test]
fn readings_agree_where_the_falloff_is_one() {
    // φ_i + φ_o = 0 or γ off: P = 1, so β̃ = β and both readings give the same lobe.
    let f = cloth_frame(Vec3::Z, Vec3::Y);
    let p = silk();
    for &(ti, to, pi) in &[(0.2f32, 0.1f32, 0.4f32), (-0.5, 0.7, -1.0)] {
        let (wi, wo) = (dir(&f, ti, pi), dir(&f, to, -pi));
        let a = cloth_brdf(&p, &f, wi, wo, BrdfReading::Bounded);
        let b = cloth_brdf(&p, &f, wi, wo, BrdfReading::Width);
        assert!((a - b).abs().max_element() <= 1e-6 * a.max_element(), "{a} vs {b}");
    }
    // Away from it they differ: the width reading widens nothing, it narrows the lobe
    // in θ (peak up) where P < 1; the bounded one scales it down.
    let (wi, wo) = (dir(&f, 0.2, 0.6), dir(&f, -0.2, 0.6));
    let p1 = ClothParams::new(Vec3::ZERO, 1.5, 0.0, &[ClothLobe { k: Vec3::ONE, beta: 0.1, gamma: 0.5 }]);
    let a = cloth_brdf(&p1, &f, wi, wo, BrdfReading::Bounded);
    let b = cloth_brdf(&p1, &f, wi, wo, BrdfReading::Width);
    assert!(b.x > a.x * 2.0, "{a} vs {b}");
}

#[test]
fn the_held_reading_is_the_width_reading_until_it_would_rise_past_its_bound() {
    let lobe = ClothLobe { k: Vec3::ONE, beta: 0.2, gamma: 0.5 };
    let peak = cloth_gaussian(0.0, lobe.beta);
    // Where P ≥ 1/HELD_RISE the two readings are one lobe, at every θ.
    for phi_sum in [0.0f32, 0.3, -0.6, 0.5 * (2.0 * HELD_RISE.ln()).sqrt()] {
        assert!(cloth_phi_falloff(phi_sum, lobe.gamma) >= 1.0 / HELD_RISE - 1e-6);
        for theta_sum in [0.0f32, 0.01, -0.05, 0.3] {
            let (w, h) = (cloth_lobe_shape(theta_sum, phi_sum, lobe.beta, lobe.gamma, BrdfReading::Width), cloth_lobe_shape(theta_sum, phi_sum, lobe.beta, lobe.gamma, BrdfReading::Held));
            assert!((w - h).abs() <= 1e-5 * w.max(1e-6), "φ {phi_sum} θ {theta_sum}: {w} vs {h}");
        }
    }
    // Past it the width reading becomes a needle (its peak 1/(√(2π)·max(βP, BETA_MIN)),
    // 400 at φ_i + φ_o = π here); the held one keeps the same width and stops at
    // HELD_RISE times the lobe's peak.
    for phi_sum in [1.0f32, 2.0, std::f32::consts::PI] {
        let (w, h) = (cloth_lobe_shape(0.0, phi_sum, lobe.beta, lobe.gamma, BrdfReading::Width), cloth_lobe_shape(0.0, phi_sum, lobe.beta, lobe.gamma, BrdfReading::Held));
        assert!((h - HELD_RISE * peak).abs() <= 1e-4 * h && w > h, "φ {phi_sum}: width {w}, held {h}, peak {peak}");
        // The same θ profile: their ratio is one constant across θ.
        let width = (lobe.beta * cloth_phi_falloff(phi_sum, lobe.gamma)).max(BETA_MIN);
        let ratio = |t: f32| cloth_lobe_shape(t, phi_sum, lobe.beta, lobe.gamma, BrdfReading::Held) / cloth_lobe_shape(t, phi_sum, lobe.beta, lobe.gamma, BrdfReading::Width);
        assert!((ratio(0.5 * width) - h / w).abs() <= 1e-4 * (h / w), "φ {phi_sum}");
    }
    assert!(cloth_lobe_shape(0.0, std::f32::consts::PI, lobe.beta, lobe.gamma, BrdfReading::Width) > 300.0);
    // On the held third of 200 000 random and extreme inputs no lobe passes
    // HELD_RISE · k · G(0; β) (Fresnel and shadowing are at most 1; the cosine too).
    for (i, input) in generate_inputs(200_000, 0x4e1d).iter().enumerate().filter(|(_, x)| x.reading() == BrdfReading::Held) {
        let p = input.params();
        let l = &p.lobes[0];
        let bound = HELD_RISE * l.k.max(Vec3::ZERO).min(Vec3::splat(K_MAX)).max_element() * cloth_gaussian(0.0, l.beta.max(BETA_MIN).min(BETA_MAX)) * 1.0001;
        let out = input.evaluate();
        for v in out.lobe0.iter().take(3) {
            assert!(*v <= bound.max(1e-30), "input {i}: lobe 0 {v} > {bound}: {input:?}");
        }
    }
}

#[test]
fn reciprocal_without_shadowing_and_even_in_the_tangent_sign() {
    let mut rng = SplitMix64(7);
    for _ in 0..2000 {
        let (n, t) = (rng.unit_vector(), rng.unit_vector());
        let (wi, wo) = (rng.unit_vector(), rng.unit_vector());
        let mut p = silk();
        let f = cloth_frame(n, t);
        let g = cloth_frame(n, -t);
        for reading in [BrdfReading::Bounded, BrdfReading::Width, BrdfReading::Held] {
            // t ≡ −t: tangents are axes.
            let x = cloth_brdf(&p, &f, wi, wo, reading);
            let y = cloth_brdf(&p, &g, wi, wo, reading);
            assert!((x - y).abs().max_element() <= 1e-5 * x.max_element().max(1e-3), "{x} vs {y}");
            // a = 0: every factor is symmetric in (ω_i, ω_o).
            p.a = 0.0;
            let x = cloth_brdf(&p, &f, wi, wo, reading);
            let y = cloth_brdf(&p, &f, wo, wi, reading);
            assert!((x - y).abs().max_element() <= 1e-5 * x.max_element().max(1e-3), "{x} vs {y}");
        }
    }
}

#[test]
fn frames_are_orthonormal_even_when_degenerate() {
    let mut rng = SplitMix64(11);
    let mut cases = vec![(Vec3::ZERO, Vec3::ZERO), (Vec3::Z, Vec3::Z), (Vec3::Z, -Vec3::Z), (-Vec3::Z, Vec3::ZERO), (Vec3::new(0.0, 0.0, -0.0), Vec3::X)];
    for _ in 0..1000 {
        let n = rng.unit_vector() * rng.log_range(1e-12, 1e12);
        let t = if rng.next_f32() < 0.2 { n * rng.range(-3.0, 3.0) + rng.unit_vector() * 1e-9 } else { rng.unit_vector() * rng.log_range(1e-12, 1e12) };
        cases.push((n, t));
    }
    for (n, t) in cases {
        let f = cloth_frame(n, t);
        for v in [f.n, f.t, f.b] {
            assert!(v.is_finite() && (v.length() - 1.0).abs() < 1e-5, "{n} {t} -> {f:?}");
        }
        assert!(f.n.dot(f.t).abs() < 1e-5 && f.n.dot(f.b).abs() < 1e-5 && f.t.dot(f.b).abs() < 1e-5, "{n} {t} -> {f:?}");
    }
    assert_eq!(cloth_frame(Vec3::ZERO, Vec3::X).n, Vec3::Z);
    assert_eq!(cloth_frame(Vec3::Z, Vec3::Z).t, cloth_reference_tangent(Vec3::Z));
}

#[test]
fn finite_and_non_negative_on_a_million_random_and_extreme_inputs() {
    let inputs = generate_inputs(1_000_000, 0xb1d);
    let mut max_seen = 0.0f32;
    for (i, input) in inputs.iter().enumerate() {
        let out = input.evaluate();
        for v in out.brdf.iter().chain(&out.lobe0).chain(&out.fiber).chain(&out.cylinder) {
            assert!(v.is_finite() && *v >= 0.0, "input {i}: {input:?} -> {out:?}");
            max_seen = max_seen.max(*v);
        }
    }
    // Bounded by K_MAX·(1 + 8/(√(2π)·BETA_MIN)): no overflow possible.
    assert!(max_seen < 3e8, "{max_seen}");
}

#[test]
fn nan_parameters_are_absorbed_in_rust() {
    let nan = f32::NAN;
    let p = ClothParams::new(Vec3::splat(nan), nan, nan, &[ClothLobe { k: Vec3::splat(nan), beta: nan, gamma: nan }]);
    let v = cloth_brdf(&p, &cloth_frame(Vec3::Z, Vec3::X), Vec3::Z, Vec3::Z, BrdfReading::Bounded);
    assert!(v.is_finite() && v.min_element() >= 0.0, "{v}");
    // A NaN normal fails the length test and falls back to +Z.
    let f = cloth_frame(Vec3::splat(nan), Vec3::X);
    assert_eq!((f.n, f.t), (Vec3::Z, Vec3::X));
}

#[test]
fn brdf_test_vectors_are_current() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shaders/brdf_test_vectors.json");
    let fresh = test_vector_file();
    if std::env::var_os("FABRIC_BLESS").is_some() {
        std::fs::write(&path, fresh.to_json()).unwrap();
    }
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e} (write it with FABRIC_BLESS=1)", path.display()));
    let stored: TestVectorFile = serde_json::from_str(&text).unwrap();
    assert_eq!(stored.vectors.len(), fresh.vectors.len());
    for (i, (s, f)) in stored.vectors.iter().zip(&fresh.vectors).enumerate() {
        // Inputs are stored exactly (shortest round-trip decimal); outputs to 1e-6
        // relative, the slack a different libm's exp/asin/atan2 may need.
        assert_eq!((s.n, s.t, s.wi, s.wo, s.kd, s.eta, s.a, &s.reading, &s.lobes), (f.n, f.t, f.wi, f.wo, f.kd, f.eta, f.a, &f.reading, &f.lobes), "row {i}");
        for (x, y) in s.brdf.iter().chain(&s.lobe0).chain(&s.fiber).chain(&s.cylinder).zip(f.brdf.iter().chain(&f.lobe0).chain(&f.fiber).chain(&f.cylinder)) {
            assert!((x - y).abs() <= 1e-6 * y.abs().max(1e-6), "row {i}: stored {x}, now {y}");
        }
    }
    assert_eq!(stored.shading.len(), fresh.shading.len());
    for (i, (s, f)) in stored.shading.iter().zip(&fresh.shading).enumerate() {
        // The stored inputs evaluate to the stored outputs, and the table is the generator's.
        assert_eq!((s.n, s.t, s.wi, s.wo, s.g, s.q, s.openness), (f.n, f.t, f.wi, f.wo, f.g, f.q, f.openness), "shading row {i}");
        assert_eq!((s.kdt, s.kt, s.beta_t, s.gamma_t, s.tau), (f.kdt, f.kt, f.beta_t, f.gamma_t, f.tau), "shading row {i}");
        for (x, y) in s.outputs().iter().zip(s.reevaluate().outputs()) {
            assert!(x.is_finite() && (x - y).abs() <= 1e-6 * y.abs().max(1e-6), "shading row {i}: stored {x}, now {y}");
        }
    }
}

#[test]
fn shading_vectors_cover_every_branch() {
    let rows = shading_vectors();
    // Visibility clamped to 0 somewhere, above 1 somewhere; curvature changes it.
    assert!(rows.iter().any(|r| r.visibility == 0.0) && rows.iter().any(|r| r.visibility > 1.0));
    assert!(rows.iter().filter(|r| (r.visibility - r.visibility_gradient).abs() > 1e-3).count() > rows.len() / 2);
    // Transmission only across the sheet, and there it is nonzero somewhere.
    for r in &rows {
        let across = r.wi[2] * r.wo[2] < 0.0;
        assert!(across || r.transmission == [0.0; 3], "{r:?}");
    }
    assert!(rows.iter().filter(|r| r.transmission[0] > 0.0).count() >= 5);
    // The transmission visibility (format 1.16): clamped to 0 somewhere, above 1 somewhere
    // across the sheet.
    let across = |r: &&super::twin::ShadingVector| r.wi[2] * r.wo[2] < 0.0;
    assert!(rows.iter().filter(across).any(|r| r.transmission_visibility == 0.0) && rows.iter().filter(across).any(|r| r.transmission_visibility > 1.0));
    // Lommel–Seeliger differs from Lambert, openness spans (0, 1).
    assert!(rows.iter().any(|r| r.diffuse_cosine[1] > 1.5 * r.diffuse_cosine[0] && r.diffuse_cosine[0] > 0.0));
    assert!(rows.iter().any(|r| r.openness_value > 0.1) && rows.iter().any(|r| r.openness_value > 0.0 && r.openness_value < 0.01));
}

#[test]
fn fiber_frame_sees_the_fiber_side_on() {
    let mut rng = SplitMix64(13);
    for _ in 0..1000 {
        let (fiber, wo) = (rng.unit_vector() * rng.range(0.1, 10.0), rng.unit_vector());
        let f = cloth_fiber_frame(fiber, wo);
        assert!(f.t.cross(fiber).length() < 1e-5 * fiber.length(), "t is the fiber axis");
        assert!(f.n.dot(f.t).abs() < 1e-5 && (f.n.length() - 1.0).abs() < 1e-5);
        // n is wo's component perpendicular to t: wo lies in the (n, t) plane, n·wo ≥ 0.
        assert!(wo.dot(f.b).abs() < 1e-5 && wo.dot(f.n) >= 0.0);
    }
    let f = cloth_fiber_frame(Vec3::Z, Vec3::Z);
    assert_eq!((f.t, f.n), (Vec3::Z, cloth_reference_tangent(Vec3::Z)));
    assert_eq!(cloth_fiber_frame(Vec3::ZERO, Vec3::Z).t, Vec3::X);
}

#[test]
fn a_cylinders_lobe_is_the_facing_lobe_where_light_and_viewer_share_the_azimuth() {
    // φ_i = 0 about the fibre: the half-angle is 0, and cloth_lobe · n·ω_i is the same
    // lobe (γ off, so the falloff at φ_i + φ_o = 0 is 1 in both).
    let mut rng = SplitMix64(21);
    for _ in 0..500 {
        let fiber = rng.unit_vector();
        let wo = rng.unit_vector();
        let f = cloth_fiber_frame(fiber, wo);
        // ω_i in the (n, t) plane on the viewer's side, at a random longitudinal angle.
        let th = rng.range(-1.4, 1.4);
        let wi = f.t * th.sin() + f.n * th.cos();
        let lobe = ClothLobe { k: Vec3::new(0.7, 0.5, 0.3), beta: rng.range(0.02, 0.8), gamma: 0.0 };
        for reading in [BrdfReading::Bounded, BrdfReading::Width, BrdfReading::Held] {
            let (eta, a) = (rng.range(1.0, 2.0), rng.range(0.0, 3.0));
            let facing = cloth_lobe(&lobe, eta, a, &f, wi, wo, reading) * f.n.dot(wi).max(0.0);
            let cylinder = cloth_cylinder_lobe(&lobe, eta, a, &f, wi, wo, reading);
            assert!((facing - cylinder).abs().max_element() <= 1e-4 * facing.max_element().max(1e-3), "{facing} vs {cylinder}");
        }
    }
}

#[test]
fn a_fibre_across_a_mirror_view_shines_as_a_cylinder_and_not_as_a_facing_surface() {
    // A fibre along x, light and viewer in the y–z plane on either side at 55°: the
    // cone condition holds (θ_i + θ_o = 0) and the cylinder's normal at the top
    // reflects the light to the viewer. The frame facing the viewer turns the light
    // 110° away from its normal: nothing.
    let lobe = ClothLobe { k: Vec3::ONE, beta: 0.1, gamma: 0.5 };
    let t = 55f32.to_radians();
    let (wi, wo) = (Vec3::new(0.0, t.sin(), t.cos()), Vec3::new(0.0, -t.sin(), t.cos()));
    let f = cloth_fiber_frame(Vec3::X, wo);
    for reading in [BrdfReading::Bounded, BrdfReading::Width, BrdfReading::Held] {
        assert_eq!(cloth_lobe(&lobe, 1.5, 1.0, &f, wi, wo, reading) * f.n.dot(wi).max(0.0), Vec3::ZERO);
        let c = (0.5 * 110f32.to_radians()).cos();
        let want = cloth_gaussian(0.0, 0.1) * cloth_fresnel(1.5, 1.0) * c * c;
        let got = cloth_cylinder_lobe(&lobe, 1.5, 1.0, &f, wi, wo, reading);
        assert!((got.x - want).abs() <= 1e-4 * want, "{reading:?}: {got} vs {want}");
    }
}

#[test]
fn a_cylinders_lobe_is_even_in_the_azimuth_and_dark_only_straight_behind() {
    let lobe = ClothLobe { k: Vec3::ONE, beta: 0.3, gamma: 0.2 };
    let wo = Vec3::new(0.0, -0.6, 0.8);
    let f = cloth_fiber_frame(Vec3::X, wo);
    let mut last = f32::INFINITY;
    for k in 0..=36 {
        let phi = std::f32::consts::PI * k as f32 / 36.0;
        let side = |s: f32| f.t * 0.2 + (f.n * phi.cos() + f.b * (s * phi.sin())) * (1.0f32 - 0.04).sqrt();
        let (plus, minus) = (cloth_cylinder_lobe(&lobe, 1.4, 0.5, &f, side(1.0), wo, BrdfReading::Width), cloth_cylinder_lobe(&lobe, 1.4, 0.5, &f, side(-1.0), wo, BrdfReading::Width));
        assert!((plus - minus).abs().max_element() <= 1e-5 * plus.max_element().max(1e-6), "φ {phi}: {plus} vs {minus}");
        assert!(plus.x <= last * (1.0 + 1e-5), "φ {phi}: not falling toward straight behind");
        if k < 36 {
            assert!(plus.x > 0.0, "φ {phi}: dark");
        }
        last = plus.x;
    }
    assert!(last <= 1e-6, "straight behind: {last}");
}

#[test]
fn twin_arctangent_is_accurate_everywhere() {
    let mut worst = 0.0f64;
    let n = 20_000;
    for k in 0..=n {
        let a = -std::f64::consts::PI + 2.0 * std::f64::consts::PI * k as f64 / n as f64;
        for r in [1e-20f64, 1e-3, 1.0, 7.5, 1e20] {
            let (y, x) = ((a.sin() * r) as f32, (a.cos() * r) as f32);
            let want = (y as f64).atan2(x as f64);
            let got = cloth_atan2(y, x) as f64;
            // Compare on the circle (π and −π are one angle).
            let d = (got - want).abs().min(2.0 * std::f64::consts::PI - (got - want).abs());
            worst = worst.max(d / want.abs().max(1e-3));
        }
    }
    assert!(worst < 5e-7, "worst relative error {worst:.2e}");
    assert_eq!(cloth_atan2(0.0, 0.0), 0.0);
    assert_eq!(cloth_atan2(0.0, 1.0), 0.0);
    assert!((cloth_atan2(1.0, 0.0) - std::f32::consts::FRAC_PI_2).abs() < 1e-7);
    assert!((cloth_atan2(0.0, -1.0) - std::f32::consts::PI).abs() < 1e-7);
}

fn transmission() -> ClothTransmission {
    ClothTransmission { kd: Vec3::new(0.05, 0.04, 0.03), lobe: ClothLobe { k: Vec3::new(0.3, 0.2, 0.1), beta: 0.25, gamma: 1.0 }, tau: 0.7, gap: Default::default(), grad: [0.4, -0.3, 0.5, 0.2], curv: [0.2, -0.3, 0.1, 0.4, -0.2, 0.1] }
}

#[test]
fn transmission_is_reciprocal_and_peaks_straight_through() {
    let mut rng = super::twin::SplitMix64(11);
    let t = transmission();
    let unit = |rng: &mut super::twin::SplitMix64, lo: f32, hi: f32| {
        let z = rng.range(lo, hi);
        let p = rng.range(0.0, std::f32::consts::TAU);
        let s = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(s * p.cos(), s * p.sin(), z)
    };
    for _ in 0..2000 {
        let f = cloth_frame(Vec3::new(rng.range(-0.5, 0.5), rng.range(-0.5, 0.5), 1.0), Vec3::new(1.0, rng.range(-1.0, 1.0), 0.0));
        let (below, above) = (unit(&mut rng, -1.0, -0.02), unit(&mut rng, 0.02, 1.0));
        let a = cloth_transmission(&t, &f, below, above);
        let b = cloth_transmission(&t, &f, above, below);
        assert!(a.is_finite() && a.min_element() >= 0.0);
        assert!((a - b).abs().max_element() <= 1e-6 * a.max_element().max(1e-6), "not reciprocal: {a} vs {b}");
        // Same side: nothing through.
        assert_eq!(cloth_transmission(&t, &f, above, above), Vec3::ZERO);
        assert_eq!(cloth_transmission(&t, &f, below, -above), Vec3::ZERO);
    }
    // With n = z, the lobe peaks at ω_o = −ω_i: straight through beats every tilt of it.
    let f = cloth_frame(Vec3::Z, Vec3::X);
    let t0 = ClothTransmission { tau: 0.0, grad: [0.0; 4], curv: [0.0; 6], ..t };
    let wi = Vec3::new(0.3, 0.2, -0.9).normalize();
    let peak = cloth_transmission(&t0, &f, wi, -wi).x;
    for k in 0..16 {
        let a = k as f32 * std::f32::consts::TAU / 16.0;
        let wo = (-wi + 0.15 * Vec3::new(a.cos(), a.sin(), 0.0)).normalize();
        assert!(cloth_transmission(&t0, &f, wi, wo).x < peak);
    }
    // The attenuation: 1 at normal incidence and view, falling with the slant, and
    // exp(−τ·(1/μ − 1)) with one side normal.
    assert_eq!(cloth_transmission_attenuation(0.7, -1.0, 1.0), 1.0);
    let mu = 0.5f32;
    assert!((cloth_transmission_attenuation(0.7, -mu, 1.0) - (-0.7f32 * (1.0 / mu - 1.0)).exp()).abs() < 1e-6);
    assert!(cloth_transmission_attenuation(0.7, -0.2, 0.3) < cloth_transmission_attenuation(0.7, -0.5, 0.3));
    // Extreme inputs stay finite (grazing, τ out of range, NaN τ absorbed).
    for tau in [-1.0, 0.0, 1e9, f32::NAN] {
        let v = cloth_transmission(&ClothTransmission { tau, ..t }, &f, Vec3::new(1.0, 0.0, -1e-7).normalize(), Vec3::new(0.0, 1.0, 1e-7).normalize());
        assert!(v.is_finite() && v.min_element() >= 0.0, "τ {tau}: {v}");
    }
    // The response carries the tile's cosine |ω_i.z|.
    let r = cloth_transmission_response(&t, &f, wi, -wi);
    assert!((r - cloth_transmission(&t, &f, wi, -wi) * 0.9f32.min(-wi.z).max(-wi.z)).abs().max_element() < 1e-6);
}

/// The transmission's visibility (format 1.16): the reflection's visibility with the
/// viewer's side above and the light's below, the same whichever of ω_i, ω_o is the
/// light; 1 for g = q = 0 and along ±ẑ; a factor of the whole term.
#[test]
fn the_transmission_visibility_reads_each_side_of_the_sheet() {
    let mut rng = super::twin::SplitMix64(29);
    let t = transmission();
    let f = cloth_frame(Vec3::new(0.1, -0.2, 1.0), Vec3::X);
    for _ in 0..2000 {
        let g: [f32; 4] = std::array::from_fn(|_| rng.range(-3.0, 3.0));
        let q: [f32; 6] = std::array::from_fn(|_| rng.range(-3.0, 3.0));
        let above = (rng.unit_vector() * Vec3::new(1.0, 1.0, 0.0) + Vec3::Z * rng.range(0.02, 1.0)).normalize();
        let below = (rng.unit_vector() * Vec3::new(1.0, 1.0, 0.0) - Vec3::Z * rng.range(0.02, 1.0)).normalize();
        let m = cloth_transmission_visibility(g, q, below, above);
        assert_eq!(m, cloth_transmission_visibility(g, q, above, below), "reciprocal");
        assert_eq!(m, cloth_visibility(g, q, below, above), "g_u on the side above, g_l below");
        assert_eq!(cloth_transmission_visibility(g, [0.0; 6], below, above), cloth_visibility_gradient(g, below, above));
        assert!(m.is_finite() && m >= 0.0);
        assert_eq!(cloth_transmission_visibility([0.0; 4], [0.0; 6], below, above), 1.0);
        // The term scales by M_t: against the same term without it.
        let plain = cloth_transmission(&ClothTransmission { grad: [0.0; 4], curv: [0.0; 6], ..t }, &f, below, above);
        let seen = cloth_transmission(&ClothTransmission { grad: g, curv: q, ..t }, &f, below, above);
        assert!((seen - plain * m).abs().max_element() <= 1e-5 * plain.max_element().max(1e-6), "{seen} vs {plain} × {m}");
    }
    assert_eq!(cloth_transmission_visibility([1.0, -1.0, 2.0, 0.5], [0.5, 0.4, -0.3, 0.2, 0.1, 0.7], -Vec3::Z, Vec3::Z), 1.0);
    // Past their clamp (±2) the coefficients act as ±2; far past, the factor is 0.
    let (above, below) = (Vec3::new(0.6, 0.0, 0.8), Vec3::new(-0.6, 0.0, -0.8));
    assert_eq!(cloth_transmission_visibility([9.0, 0.0, 0.0, 0.0], [0.0; 6], below, above), cloth_transmission_visibility([2.0, 0.0, 0.0, 0.0], [0.0; 6], below, above));
    assert_eq!(cloth_transmission_visibility([-2.0, 0.0, 2.0, 0.0], [0.0; 6], below, above), 0.0);
    // The even part: straight through along x (u_x = −l_x) against along y.
    let (ax, bx) = (Vec3::new(0.6, 0.0, 0.8), Vec3::new(-0.6, 0.0, -0.8));
    let q = [-0.5, 0.0, 0.0, 0.0, 0.0, 0.0];
    assert!((cloth_transmission_visibility([0.0; 4], q, bx, ax) - (1.0 - 0.5 * 0.72)).abs() < 1e-6);
    assert_eq!(cloth_transmission_visibility([0.0; 4], q, Vec3::new(0.0, -0.6, -0.8), Vec3::new(0.0, 0.6, 0.8)), 1.0);
}

/// The openness (format 1.10): o straight down, closing with the slant at a rate its
/// azimuth terms set, an axis's (ω and −ω alike), finite for any record.
#[test]
fn openness_closes_with_the_slant_and_by_azimuth() {
    let g = ClothOpenness { o: 0.3, q: 2.0, aniso: [1.0, 0.0] };
    assert_eq!(cloth_openness(&g, Vec3::Z), 0.3);
    let (along_x, along_y) = (Vec3::new(1.0, 0.0, 1.0).normalize(), Vec3::new(0.0, 1.0, 1.0).normalize());
    let slant = 2f32.sqrt() - 1.0;
    assert!((cloth_openness(&g, along_x) - 0.3 * (-2.0 * 2.0 * slant).exp()).abs() < 1e-6, "rate 2 along x");
    assert!((cloth_openness(&g, along_y) - 0.3).abs() < 1e-6, "rate 0 along y: a slit seen along its length");
    assert_eq!(cloth_azimuth_axis(along_x), cloth_azimuth_axis(Vec3::new(-1.0, 0.0, 1.0).normalize()));
    assert_eq!(cloth_azimuth_axis(Vec3::Z), [0.0, 0.0]);
    let iso = ClothOpenness { aniso: [0.0; 2], ..g };
    assert!(cloth_openness(&iso, along_x) > cloth_openness(&iso, Vec3::new(2.0, 0.0, 1.0).normalize()));
    for bad in [ClothOpenness { o: f32::NAN, q: f32::NAN, aniso: [f32::NAN; 2] }, ClothOpenness { o: 5.0, q: -1.0, aniso: [9.0, -9.0] }] {
        for w in [Vec3::Z, along_x, Vec3::new(1.0, 0.0, 1e-9)] {
            let v = cloth_openness(&bad, w);
            assert!(v.is_finite() && (0.0..=1.0).contains(&v), "{bad:?} {w}: {v}");
        }
    }
}
