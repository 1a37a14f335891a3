//! The visibility gradient of a level-0 texel (format 1.12,
//! `brdf::cloth_visibility_gradient`), fitted with the texel's linear parameters.
//!
//! A texel's response is its BRDF times
//! ```text
//! M(ω_i, ω_o) = max(1 + g_o·(ω_o,x, ω_o,y) + g_i·(ω_i,x, ω_i,y), 0)
//! ```
//! in tile space. At one texel per fibre, what the volume shows along the ray that the
//! model says meets texel j depends on the side it comes from: a texel on a yarn's flank
//! is seen more, and lit more, from that flank's side, by neighbours the smooth height
//! field does not cast. The per-texel BRDF's cosines and lobes are even in those
//! directions' slant across the tile, and M is their first-order odd part.
//!
//! The fit alternates, from the texel's refinement without a gradient: for fixed k_d,
//! k_j, M's four coefficients are linear least squares (each sample's row is the
//! predicted radiance times the directions' x and y, over the three channels; a ridge
//! towards g = 0); for fixed g, k_d and k_j are `refine_texel` on the samples scaled by
//! M. Each round lowers or keeps the texel's residual up to the ridges.
//! baker/FIT_MEASUREMENTS.md, "The visibility gradient", measures what it buys.

use fabric_runtime::brdf::{BrdfReading, ClothParams, GRADIENT_MAX, cloth_visibility_gradient};
use glam::Vec3;

use super::cluster_fit::{LobeTarget, predict_lobes, refine_texel};

/// How the gradient is fitted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GradientOptions {
    /// Ridge towards g = 0, relative to the mean diagonal of the normal equations.
    pub ridge: f64,
    /// Alternations of (g for fixed k, k for fixed g).
    pub rounds: usize,
}

impl Default for GradientOptions {
    fn default() -> Self {
        GradientOptions { ridge: 0.05, rounds: 4 }
    }
}

/// `t` with its whole response scaled by `m` (every factor of `cluster_fit::basis` is
/// linear in `cos_i` and `kd_cos`).
fn scaled(mut t: LobeTarget, m: f32) -> LobeTarget {
    for g in t.geos.iter_mut() {
        g.cos_i *= m;
        g.kd_cos *= m;
    }
    t
}

/// The gradient's features of a pair: (ω_o,x, ω_o,y, ω_i,x, ω_i,y).
fn features(wi: Vec3, wo: Vec3) -> [f64; 4] {
    [wo.x as f64, wo.y as f64, wi.x as f64, wi.y as f64]
}

/// The least-squares g for fixed BRDF `p` over `samples` (their pairs `dirs`), with a
/// ridge of `ridge` · (mean diagonal) towards 0; zero where the system is degenerate.
fn solve_gradient(samples: &[LobeTarget], dirs: &[(Vec3, Vec3)], p: &ClothParams, ridge: f64, reading: BrdfReading) -> [f32; 4] {
    gradient_least_squares(samples.iter().zip(dirs).map(|(t, &(wi, wo))| (predict_lobes(p, t, reading), t.radiance, wi, wo)), ridge)
}

/// The g that best scales `predicted` into `target` over rows (predicted, target, ω_i,
/// ω_o): least squares of target − predicted = predicted · (g · features) over the three
/// channels, with a ridge of `ridge` · (mean diagonal) towards 0; zero where the system
/// is degenerate. Also the coarse levels' fit (`prefilter`).
pub fn gradient_least_squares(rows: impl Iterator<Item = (Vec3, Vec3, Vec3, Vec3)>, ridge: f64) -> [f32; 4] {
    let mut a = [[0f64; 4]; 4];
    let mut b = [0f64; 4];
    for (predicted, target, wi, wo) in rows {
        let f = features(wi, wo);
        let r = predicted.as_dvec3();
        let y = target.as_dvec3() - r;
        for ch in 0..3 {
            for u in 0..4 {
                b[u] += y[ch] * r[ch] * f[u];
                for v in 0..4 {
                    a[u][v] += r[ch] * r[ch] * f[u] * f[v];
                }
            }
        }
    }
    let trace = (0..4).map(|u| a[u][u]).sum::<f64>() / 4.0;
    if !(trace > 0.0 && trace.is_finite()) {
        return [0.0; 4];
    }
    for (u, row) in a.iter_mut().enumerate() {
        row[u] += ridge.max(1e-9) * trace;
    }
    let Some(x) = solve4(a, b) else { return [0.0; 4] };
    x.map(|v| if v.is_finite() { (v as f32).clamp(-GRADIENT_MAX, GRADIENT_MAX) } else { 0.0 })
}

/// Solves the 4×4 system a x = b (symmetric, positive definite with the ridge);
/// `None` where it is singular.
fn solve4(a: [[f64; 4]; 4], b: [f64; 4]) -> Option<[f64; 4]> {
    let m = glam::DMat4::from_cols_array_2d(&a);
    let det = m.determinant();
    (det.is_finite() && det > 0.0).then(|| (m.inverse() * glam::DVec4::from_array(b)).to_array())
}

/// Refines one texel's linear parameters together with its visibility gradient (module
/// docs): `samples` with their pairs `dirs` (tile space), the non-linear parameters
/// kept from `cluster`, `ridge` as `refine_texel`'s. Returns the BRDF and g.
pub fn refine_texel_with_gradient(samples: &[LobeTarget], dirs: &[(Vec3, Vec3)], cluster: &ClothParams, ridge: f64, o: &GradientOptions, reading: BrdfReading) -> (ClothParams, [f32; 4]) {
    let plain = refine_texel(samples, cluster, ridge, reading);
    refine_gradient_from(plain, samples, dirs, cluster, ridge, o, reading)
}

/// [`refine_texel_with_gradient`] from `plain`, the texel's refinement without a
/// gradient (`refine_texel` on the same samples), which the caller already has.
pub fn refine_gradient_from(plain: ClothParams, samples: &[LobeTarget], dirs: &[(Vec3, Vec3)], cluster: &ClothParams, ridge: f64, o: &GradientOptions, reading: BrdfReading) -> (ClothParams, [f32; 4]) {
    let mut p = plain;
    let mut g = [0.0f32; 4];
    if samples.is_empty() {
        return (p, g);
    }
    for _ in 0..o.rounds {
        g = solve_gradient(samples, dirs, &p, o.ridge, reading);
        let scaled: Vec<LobeTarget> = samples.iter().zip(dirs).map(|(t, &(wi, wo))| scaled(*t, cloth_visibility_gradient(g, wi, wo))).collect();
        p = refine_texel(&scaled, cluster, ridge, reading);
    }
    (p, g)
}

/// A sample's factors with the texel's gradient `g` applied: what the renderer shades.
pub fn with_gradient(t: LobeTarget, g: [f32; 4], wi: Vec3, wo: Vec3) -> LobeTarget {
    scaled(t, cloth_visibility_gradient(g, wi, wo))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::rng::Rng;
    use fabric_runtime::brdf::{ClothLobe, DiffuseLaw, cloth_frame};

    fn hemi(rng: &mut Rng) -> Vec3 {
        let (u, v) = (rng.next_f32(), rng.next_f32());
        let z = 0.15 + 0.85 * u;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = std::f32::consts::TAU * v;
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    /// Samples of `p` in a tilted frame, times M(g), with relative noise `noise`.
    fn synthetic(p: &ClothParams, g: [f32; 4], count: usize, noise: f32, seed: u64) -> (Vec<LobeTarget>, Vec<(Vec3, Vec3)>) {
        let frame = cloth_frame(Vec3::new(0.2, -0.1, 1.0).normalize(), Vec3::X);
        let mut rng = Rng::new(seed, 0x6772, 0);
        let (mut out, mut dirs) = (Vec::new(), Vec::new());
        for _ in 0..count {
            let (wi, wo) = (hemi(&mut rng), hemi(&mut rng));
            let t = LobeTarget::in_frames(&[frame], wi, wo, 1.0, Vec3::ZERO, DiffuseLaw::LommelSeeliger);
            let clean = predict_lobes(p, &t, BrdfReading::Width) * cloth_visibility_gradient(g, wi, wo);
            let n = 1.0 + noise * (2.0 * rng.next_f32() - 1.0);
            out.push(LobeTarget { radiance: clean * n, ..t });
            dirs.push((wi, wo));
        }
        (out, dirs)
    }

    fn truth() -> ClothParams {
        ClothParams::new(Vec3::new(0.3, 0.2, 0.1), 1.46, 0.5, &[ClothLobe { k: Vec3::splat(0.4), beta: 0.3, gamma: 0.0 }])
    }

    #[test]
    fn a_known_gradient_is_recovered() {
        let p = truth();
        let g = [0.4, -0.3, -0.25, 0.5];
        let (samples, dirs) = synthetic(&p, g, 400, 0.0, 1);
        // The cluster's k's start off by a factor of two; the shape is right.
        let mut start = p;
        start.kd *= 2.0;
        start.lobes[0].k *= 0.5;
        let (fit, got) = refine_texel_with_gradient(&samples, &dirs, &start, 1e-6, &GradientOptions { ridge: 1e-6, rounds: 12 }, BrdfReading::Width);
        for u in 0..4 {
            assert!((got[u] - g[u]).abs() < 0.02, "g[{u}] = {} against {}", got[u], g[u]);
        }
        assert!((fit.kd - p.kd).abs().max_element() < 0.01, "k_d {} against {}", fit.kd, p.kd);
    }

    #[test]
    fn the_gradient_lowers_the_residual_and_stays_near_zero_without_one() {
        let p = truth();
        let residual = |q: &ClothParams, g: [f32; 4], s: &[LobeTarget], d: &[(Vec3, Vec3)]| -> f64 {
            s.iter().zip(d).map(|(t, &(wi, wo))| (predict_lobes(q, &with_gradient(*t, g, wi, wo), BrdfReading::Width) - t.radiance).length_squared() as f64).sum()
        };
        // With a gradient in the data: the fit with one is better than without.
        let (s, d) = synthetic(&p, [0.5, 0.0, 0.0, -0.5], 300, 0.05, 2);
        let plain = refine_texel(&s, &p, 0.05, BrdfReading::Width);
        let (q, g) = refine_texel_with_gradient(&s, &d, &p, 0.05, &GradientOptions::default(), BrdfReading::Width);
        assert!(residual(&q, g, &s, &d) < 0.5 * residual(&plain, [0.0; 4], &s, &d));
        // Without one (noise only): g stays small.
        let (s, d) = synthetic(&p, [0.0; 4], 300, 0.05, 3);
        let (_, g) = refine_texel_with_gradient(&s, &d, &p, 0.05, &GradientOptions::default(), BrdfReading::Width);
        assert!(g.iter().all(|v| v.abs() < 0.05), "{g:?}");
    }

    #[test]
    fn degenerate_samples_give_no_gradient() {
        let p = truth();
        let (none, _) = refine_texel_with_gradient(&[], &[], &p, 0.05, &GradientOptions::default(), BrdfReading::Width);
        assert_eq!(none, p);
        // Black targets of a black texel: no information, g = 0, finite.
        let (s, d) = synthetic(&ClothParams::new(Vec3::ZERO, 1.46, 0.5, &[]), [0.3; 4], 50, 0.0, 4);
        let (q, g) = refine_texel_with_gradient(&s, &d, &ClothParams::new(Vec3::ZERO, 1.46, 0.5, &[]), 0.05, &GradientOptions::default(), BrdfReading::Width);
        assert_eq!(g, [0.0; 4]);
        assert!(q.kd.is_finite());
    }
}
