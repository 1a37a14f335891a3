//! Energy of the fitted reflection lobes: a lobe may not reflect more than it receives.
//!
//! Why: the NNLS of the lobes' k (Algorithm 1, §5.3.3) is bounded only by `K_MAX`. A lobe
//! that is sharp (small β) and points where no training pair looks is held by the tail of
//! its Gaussian alone, and the solve can give it any k. Measured on a 33×17×9 satin baked
//! with 8 pairs: a cluster lobe of k = 14 472, β = 0.031 reflected about a thousand times
//! the light it received at held-out pairs, and the held-out views came out 40 to 5 800
//! times too bright (baker/FIT_MEASUREMENTS.md, "Energy of the lobes").
//!
//! The bound: the directional albedo of lobe j, A_j(ω_o) = ∫ f_j(ω_i, ω_o) (n·ω_i)⁺ dω_i
//! over the sphere (the runtime's own `cloth_lobe`, never a copy), is linear in k_j, so
//! Â_j = max over ω_o of A_j per unit k depends on the lobe's shape (β, γ, η, a) alone,
//! not on its frame: the tile's hemisphere only takes from it. A texel whose lobes give
//! Σ_j k_j Â_j > [`LOBE_ALBEDO_MAX`] in any channel has its lobes' k scaled down to it
//! ([`cap_lobes`]). The diffuse term is left out: under the Lommel–Seeliger law a fitted
//! k_d reflects more than a physical albedo allows toward grazing views by design
//! (`runtime/src/brdf`, `cloth_diffuse_cosine`), and the NNLS sees k_d at every pair.

use fabric_runtime::brdf::{BETA_MIN, BrdfReading, ClothLobe, ClothParams, cloth_frame, cloth_lobe, cloth_phi_falloff};
use glam::Vec3;

/// The largest albedo the lobes of one texel may have together, per channel.
pub const LOBE_ALBEDO_MAX: f32 = 1.0;

/// Polar angles of ω_o at which the albedo is taken (its sign does not matter: the lobe
/// is symmetric under θ → −θ for both directions at once).
const VIEW_POLAR_DEG: [f32; 6] = [0.0, 15.0, 30.0, 45.0, 60.0, 75.0];
/// Azimuths of ω_o about the fibre axis (symmetric under φ → −φ).
const VIEW_AZIMUTH_DEG: [f32; 7] = [0.0, 30.0, 60.0, 90.0, 120.0, 150.0, 180.0];

/// Quadrature nodes of a periodic or bounded interval: `uniform` evenly spaced plus
/// `dense` over `centre` ± 6 `width` (clipped, or wrapped when periodic), sorted, with
/// trapezoid weights. The dense nodes follow a lobe's peak, which a uniform grid misses
/// when β or γ is a few degrees.
fn nodes(lo: f32, hi: f32, periodic: bool, centre: f32, width: f32, uniform: usize, dense: usize) -> Vec<(f32, f32)> {
    let span = hi - lo;
    let mut x: Vec<f32> = (0..=uniform).map(|i| lo + span * i as f32 / uniform as f32).collect();
    if periodic {
        x.pop();
    }
    let reach = 6.0 * width;
    if reach < 0.5 * span {
        for i in 0..dense {
            let mut v = centre - reach + 2.0 * reach * (i as f32 + 0.5) / dense as f32;
            if periodic {
                v = lo + (v - lo).rem_euclid(span);
            }
            if (lo..=hi).contains(&v) {
                x.push(v);
            }
        }
    }
    x.sort_by(f32::total_cmp);
    x.dedup();
    let n = x.len();
    (0..n)
        .map(|i| {
            let (prev, next) = if periodic {
                (if i == 0 { x[n - 1] - span } else { x[i - 1] }, if i + 1 == n { x[0] + span } else { x[i + 1] })
            } else {
                (if i == 0 { x[0] } else { x[i - 1] }, if i + 1 == n { x[n - 1] } else { x[i + 1] })
            };
            (x[i], 0.5 * (next - prev))
        })
        .collect()
}

/// A_j(ω_o) per unit k (the green channel of k = 1): ∫ f_j (n·ω_i)⁺ dω_i over the sphere
/// in the lobe's frame, ω_o at longitudinal angle `theta_o` and azimuth `phi_o`.
/// dω = cos θ_i dθ_i dφ_i.
pub fn lobe_albedo_at(lobe: &ClothLobe, eta: f32, a: f32, theta_o: f32, phi_o: f32, reading: BrdfReading) -> f32 {
    let f = cloth_frame(Vec3::Z, Vec3::X);
    let unit = ClothLobe { k: Vec3::ONE, ..*lobe };
    let dir = |theta: f32, phi: f32| f.t * theta.sin() + (f.n * phi.cos() + f.b * phi.sin()) * theta.cos();
    let wo = dir(theta_o, phi_o);
    let pi = std::f32::consts::PI;
    let gamma = if lobe.gamma > 0.0 { lobe.gamma } else { f32::INFINITY };
    let mut sum = 0.0f64;
    // The peak lies at θ_i = −θ_o, φ_i = −φ_o (θ_i + θ_o = 0, φ_i + φ_o = 0).
    for (phi_i, w_phi) in nodes(-pi, pi, true, -phi_o, gamma, 96, 32) {
        // The θ width at this φ (node placement only): the width and held readings
        // narrow the Gaussian by P(φ_i + φ_o).
        let width = match reading {
            BrdfReading::Bounded => lobe.beta,
            BrdfReading::Width | BrdfReading::Held => lobe.beta * cloth_phi_falloff(phi_i + phi_o, lobe.gamma),
        }
        .max(BETA_MIN);
        for (theta_i, w_theta) in nodes(-0.5 * pi, 0.5 * pi, false, -theta_o, width, 64, 32) {
            let wi = dir(theta_i, phi_i);
            let cos_i = f.n.dot(wi);
            if cos_i <= 0.0 {
                continue;
            }
            let r = cloth_lobe(&unit, eta, a, &f, wi, wo, reading).y * cos_i * theta_i.cos();
            sum += (r * w_theta * w_phi) as f64;
        }
    }
    sum as f32
}

/// Â_j: the worst of [`lobe_albedo_at`] over the views of [`VIEW_POLAR_DEG`] ×
/// [`VIEW_AZIMUTH_DEG`].
pub fn unit_lobe_albedo(lobe: &ClothLobe, eta: f32, a: f32, reading: BrdfReading) -> f32 {
    let mut worst = 0f32;
    for polar in VIEW_POLAR_DEG {
        for azimuth in VIEW_AZIMUTH_DEG {
            worst = worst.max(lobe_albedo_at(lobe, eta, a, polar.to_radians(), azimuth.to_radians(), reading));
        }
    }
    worst
}

/// Â_j of every lobe of `p`.
pub fn unit_albedos(p: &ClothParams, reading: BrdfReading) -> Vec<f32> {
    p.lobes().iter().map(|l| unit_lobe_albedo(l, p.eta, p.a, reading)).collect()
}

/// The lobes' albedo bound Σ_j k_j Â_j, the largest channel's, for lobes of the shapes
/// whose Â_j are `unit`.
pub fn lobe_albedo(p: &ClothParams, unit: &[f32]) -> f32 {
    p.lobes().iter().zip(unit).fold(Vec3::ZERO, |s, (l, &u)| s + l.k.max(Vec3::ZERO) * u).max_element()
}

/// `p` with its lobes' k scaled so that [`lobe_albedo`] is at most [`LOBE_ALBEDO_MAX`]
/// (k_d, β, γ, η and a untouched), and its albedo before (above the bound: scaled).
pub fn cap_lobes(p: &ClothParams, unit: &[f32]) -> (ClothParams, f32) {
    let albedo = lobe_albedo(p, unit);
    if !(albedo > LOBE_ALBEDO_MAX) {
        return (*p, albedo);
    }
    let s = LOBE_ALBEDO_MAX / albedo;
    let mut out = *p;
    for lobe in out.lobes.iter_mut().take(p.lobe_count as usize) {
        lobe.k *= s;
    }
    (out, albedo)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force: a fine uniform grid in (θ_i, φ_i).
    fn brute(lobe: &ClothLobe, eta: f32, a: f32, theta_o: f32, phi_o: f32, reading: BrdfReading, (n, m): (usize, usize)) -> f32 {
        let f = cloth_frame(Vec3::Z, Vec3::X);
        let unit = ClothLobe { k: Vec3::ONE, ..*lobe };
        let dir = |theta: f32, phi: f32| f.t * theta.sin() + (f.n * phi.cos() + f.b * phi.sin()) * theta.cos();
        let wo = dir(theta_o, phi_o);
        let pi = std::f64::consts::PI;
        let (dt, dp) = (pi / n as f64, 2.0 * pi / m as f64);
        let mut sum = 0.0f64;
        for a_ in 0..n {
            let theta = (-0.5 * pi + (a_ as f64 + 0.5) * dt) as f32;
            for b_ in 0..m {
                let phi = (-pi + (b_ as f64 + 0.5) * dp) as f32;
                let wi = dir(theta, phi);
                let cos_i = f.n.dot(wi);
                if cos_i > 0.0 {
                    sum += (cloth_lobe(&unit, eta, a, &f, wi, wo, reading).y * cos_i * theta.cos()) as f64 * dt * dp;
                }
            }
        }
        sum as f32
    }

    #[test]
    fn the_quadrature_agrees_with_a_dense_grid_for_broad_and_sharp_lobes() {
        for reading in [BrdfReading::Bounded, BrdfReading::Width, BrdfReading::Held] {
            // The brute force resolves the θ width with about ten cells across it (under the
            // width reading it narrows to β·P(φ_i + φ_o), hence the finer θ), and γ in φ.
            for (beta, gamma, n) in [(0.3f32, 1.5f32, (300usize, 600usize)), (0.03, 0.5, (6000, 400)), (0.02, 3.0, (3000, 400))] {
                let lobe = ClothLobe { k: Vec3::ONE, beta, gamma };
                for (theta_o, phi_o) in [(0.0f32, 0.0f32), (0.6, 0.4), (1.1, 2.5)] {
                    let q = lobe_albedo_at(&lobe, 1.5, 0.5, theta_o, phi_o, reading);
                    let b = brute(&lobe, 1.5, 0.5, theta_o, phi_o, reading, n);
                    assert!((q - b).abs() <= 0.01 * b.max(1e-3), "{reading:?} β {beta} γ {gamma} at ({theta_o}, {phi_o}): {q} against {b}");
                }
            }
        }
    }

    #[test]
    fn the_albedo_is_linear_in_k_and_a_bright_lobe_is_scaled_to_the_bound() {
        let sharp = ClothLobe { k: Vec3::new(14472.0, 0.0, 0.0), beta: 0.031, gamma: 0.546 };
        let broad = ClothLobe { k: Vec3::new(0.5, 0.4, 0.3), beta: 0.4, gamma: 1.2 };
        let p = ClothParams::new(Vec3::splat(0.05), 1.5, 0.45, &[sharp, broad]);
        let unit = unit_albedos(&p, BrdfReading::Width);
        assert!(unit.iter().all(|u| u.is_finite() && *u > 0.0), "{unit:?}");
        let before = lobe_albedo(&p, &unit);
        assert!(before > 100.0, "the fitted lobe of the satin reflected far more than it received: {before}");
        let (capped, found) = cap_lobes(&p, &unit);
        assert_eq!(found, before);
        assert!((lobe_albedo(&capped, &unit) - LOBE_ALBEDO_MAX).abs() < 1e-4, "{}", lobe_albedo(&capped, &unit));
        let s = LOBE_ALBEDO_MAX / before;
        // Shape and diffuse unchanged; every lobe scaled alike.
        assert_eq!(capped.kd, p.kd);
        for (c, o) in capped.lobes().iter().zip(p.lobes()) {
            assert_eq!((c.beta, c.gamma), (o.beta, o.gamma));
            assert!((c.k - o.k * s).abs().max_element() <= 1e-6 * o.k.max_element());
        }
        // A lobe within the bound is left bit for bit.
        let dim = ClothParams::new(Vec3::splat(0.05), 1.5, 0.45, &[broad]);
        let unit_dim = unit_albedos(&dim, BrdfReading::Width);
        let dim_albedo = lobe_albedo(&dim, &unit_dim);
        assert!(dim_albedo < LOBE_ALBEDO_MAX);
        assert_eq!(cap_lobes(&dim, &unit_dim), (dim, dim_albedo));
    }
}
