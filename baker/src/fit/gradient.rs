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
//!
//! With [`GradientOptions::curvature`] (format 1.15, the default) M also has an even
//! second-order part, q · e(ω_i, ω_o) with e = `brdf::cloth_curvature_terms` (six terms,
//! each unchanged when ω_i and ω_o trade places), fitted with g in the same least
//! squares (ten unknowns): the lobes' form ties a yarn's highlight seen along its fibres
//! to the one seen across them, and the data does not (baker/FIT_MEASUREMENTS.md, "The
//! visibility curvature").

use fabric_runtime::brdf::{BrdfReading, CURVATURE_MAX, ClothParams, GRADIENT_MAX, cloth_curvature_terms, cloth_visibility};
use glam::Vec3;

use super::cluster_fit::{LobeTarget, predict_lobes, refine_texel};

/// How the gradient is fitted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GradientOptions {
    /// Ridge towards g = 0, relative to the mean diagonal of the normal equations.
    pub ridge: f64,
    /// Alternations of (g for fixed k, k for fixed g).
    pub rounds: usize,
    /// Fit the even second-order part q too (format 1.15).
    pub curvature: bool,
    /// Ridge towards q = 0, as `ridge` (the same trace).
    pub curvature_ridge: f64,
}

impl Default for GradientOptions {
    fn default() -> Self {
        GradientOptions { ridge: 0.05, rounds: 4, curvature: true, curvature_ridge: 0.05 }
    }
}

/// A texel's visibility: the gradient g and the curvature q (zero without one).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Visibility {
    pub g: [f32; 4],
    pub q: [f32; 6],
}

impl Visibility {
    /// M(ω_i, ω_o) (`brdf::cloth_visibility`).
    pub fn at(&self, wi: Vec3, wo: Vec3) -> f32 {
        cloth_visibility(self.g, self.q, wi, wo)
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

/// The least-squares visibility for fixed BRDF `p` over `samples` (their pairs `dirs`):
/// g, and q too where `curvature`; a ridge of `ridge` · (mean diagonal) towards 0; zero
/// where the system is degenerate.
fn solve_visibility(samples: &[LobeTarget], dirs: &[(Vec3, Vec3)], p: &ClothParams, o: &GradientOptions, reading: BrdfReading) -> Visibility {
    let rows = samples.iter().zip(dirs).map(|(t, &(wi, wo))| (predict_lobes(p, t, reading), t.radiance, wi, wo));
    if o.curvature { visibility_least_squares(rows, o.ridge, o.curvature_ridge) } else { Visibility { g: gradient_least_squares(rows, o.ridge), q: [0.0; 6] } }
}

/// The g and q that best scale `predicted` into `target` over rows (predicted, target,
/// ω_i, ω_o), as [`gradient_least_squares`] with the six curvature terms beside the
/// gradient's four (ten unknowns; ridges `ridge` on g and `curvature_ridge` on q, each
/// relative to the mean diagonal).
pub fn visibility_least_squares(rows: impl Iterator<Item = (Vec3, Vec3, Vec3, Vec3)>, ridge: f64, curvature_ridge: f64) -> Visibility {
    const N: usize = 10;
    let mut a = [[0f64; N]; N];
    let mut b = [0f64; N];
    for (predicted, target, wi, wo) in rows {
        let (l, e) = (features(wi, wo), cloth_curvature_terms(wi, wo));
        let f = [l[0], l[1], l[2], l[3], e[0] as f64, e[1] as f64, e[2] as f64, e[3] as f64, e[4] as f64, e[5] as f64];
        let r = predicted.as_dvec3();
        let y = target.as_dvec3() - r;
        for ch in 0..3 {
            for u in 0..N {
                b[u] += y[ch] * r[ch] * f[u];
                for v in u..N {
                    a[u][v] += r[ch] * r[ch] * f[u] * f[v];
                }
            }
        }
    }
    for u in 0..N {
        for v in 0..u {
            a[u][v] = a[v][u];
        }
    }
    let trace = (0..N).map(|u| a[u][u]).sum::<f64>() / N as f64;
    if !(trace > 0.0 && trace.is_finite()) {
        return Visibility::default();
    }
    for (u, row) in a.iter_mut().enumerate() {
        row[u] += if u < 4 { ridge } else { curvature_ridge }.max(1e-9) * trace;
    }
    let Some(x) = cholesky_solve(a, b) else { return Visibility::default() };
    let c = |v: f64, max: f32| if v.is_finite() { (v as f32).clamp(-max, max) } else { 0.0 };
    Visibility { g: std::array::from_fn(|u| c(x[u], GRADIENT_MAX)), q: std::array::from_fn(|u| c(x[4 + u], CURVATURE_MAX)) }
}

/// Solves a x = b for symmetric positive definite `a` (Cholesky); `None` where a pivot
/// is not positive or the result is not finite.
fn cholesky_solve<const N: usize>(a: [[f64; N]; N], b: [f64; N]) -> Option<[f64; N]> {
    let mut l = [[0f64; N]; N];
    for i in 0..N {
        for j in 0..=i {
            let s = a[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>();
            if i == j {
                if !(s > 0.0 && s.is_finite()) {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    let mut y = [0f64; N];
    for i in 0..N {
        y[i] = (b[i] - (0..i).map(|k| l[i][k] * y[k]).sum::<f64>()) / l[i][i];
    }
    let mut x = [0f64; N];
    for i in (0..N).rev() {
        x[i] = (y[i] - (i + 1..N).map(|k| l[k][i] * x[k]).sum::<f64>()) / l[i][i];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
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

/// Refines one texel's linear parameters together with its visibility (module docs):
/// `samples` with their pairs `dirs` (tile space), the non-linear parameters kept from
/// `cluster`, `ridge` as `refine_texel`'s. Returns the BRDF and the visibility.
pub fn refine_texel_with_gradient(samples: &[LobeTarget], dirs: &[(Vec3, Vec3)], cluster: &ClothParams, ridge: f64, o: &GradientOptions, reading: BrdfReading) -> (ClothParams, Visibility) {
    let plain = refine_texel(samples, cluster, ridge, reading);
    refine_gradient_from(plain, samples, dirs, cluster, ridge, o, reading)
}

/// [`refine_texel_with_gradient`] from `plain`, the texel's refinement without a
/// gradient (`refine_texel` on the same samples), which the caller already has.
pub fn refine_gradient_from(plain: ClothParams, samples: &[LobeTarget], dirs: &[(Vec3, Vec3)], cluster: &ClothParams, ridge: f64, o: &GradientOptions, reading: BrdfReading) -> (ClothParams, Visibility) {
    let mut p = plain;
    let mut v = Visibility::default();
    if samples.is_empty() {
        return (p, v);
    }
    for _ in 0..o.rounds {
        v = solve_visibility(samples, dirs, &p, o, reading);
        let scaled: Vec<LobeTarget> = samples.iter().zip(dirs).map(|(t, &(wi, wo))| scaled(*t, v.at(wi, wo))).collect();
        p = refine_texel(&scaled, cluster, ridge, reading);
    }
    (p, v)
}

/// A sample's factors with the texel's visibility `v` applied: what the renderer shades.
pub fn with_gradient(t: LobeTarget, v: &Visibility, wi: Vec3, wo: Vec3) -> LobeTarget {
    scaled(t, v.at(wi, wo))
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

    /// Samples of `p` in a tilted frame, times M(g, q), with relative noise `noise`.
    fn synthetic(p: &ClothParams, v: Visibility, count: usize, noise: f32, seed: u64) -> (Vec<LobeTarget>, Vec<(Vec3, Vec3)>) {
        let frame = cloth_frame(Vec3::new(0.2, -0.1, 1.0).normalize(), Vec3::X);
        let mut rng = Rng::new(seed, 0x6772, 0);
        let (mut out, mut dirs) = (Vec::new(), Vec::new());
        for _ in 0..count {
            let (wi, wo) = (hemi(&mut rng), hemi(&mut rng));
            let t = LobeTarget::in_frames(&[frame], wi, wo, 1.0, Vec3::ZERO, DiffuseLaw::LommelSeeliger);
            let clean = predict_lobes(p, &t, BrdfReading::Width) * v.at(wi, wo);
            let n = 1.0 + noise * (2.0 * rng.next_f32() - 1.0);
            out.push(LobeTarget { radiance: clean * n, ..t });
            dirs.push((wi, wo));
        }
        (out, dirs)
    }

    fn truth() -> ClothParams {
        ClothParams::new(Vec3::new(0.3, 0.2, 0.1), 1.46, 0.5, &[ClothLobe { k: Vec3::splat(0.4), beta: 0.3, gamma: 0.0 }])
    }

    fn gradient_only(g: [f32; 4]) -> Visibility {
        Visibility { g, q: [0.0; 6] }
    }

    #[test]
    fn a_known_gradient_is_recovered_with_or_without_the_curvature() {
        let p = truth();
        let g = [0.4, -0.3, -0.25, 0.5];
        let (samples, dirs) = synthetic(&p, gradient_only(g), 400, 0.0, 1);
        // The cluster's k's start off by a factor of two; the shape is right.
        let mut start = p;
        start.kd *= 2.0;
        start.lobes[0].k *= 0.5;
        for curvature in [false, true] {
            let (fit, got) = refine_texel_with_gradient(&samples, &dirs, &start, 1e-6, &GradientOptions { ridge: 1e-6, rounds: 12, curvature, curvature_ridge: 1e-6 }, BrdfReading::Width);
            // The even terms trade a little with k_d and k_j (both even in the slant; q_xx +
            // q_yy with 2 − μ_i² − μ_o² most), so the alternation from k's off by two ends
            // further from the truth with them.
            let (tol, tol_kd) = if curvature { (0.08, 0.03) } else { (0.02, 0.01) };
            for u in 0..4 {
                assert!((got.g[u] - g[u]).abs() < tol, "curvature {curvature}: g[{u}] = {} against {}", got.g[u], g[u]);
            }
            assert!(got.q.iter().all(|v| v.abs() < tol), "curvature {curvature}: q = {:?} where the data has none", got.q);
            assert!((fit.kd - p.kd).abs().max_element() < tol_kd, "curvature {curvature}: k_d {} against {}", fit.kd, p.kd);
        }
    }

    #[test]
    fn a_known_curvature_is_recovered_and_lowers_the_residual() {
        let p = truth();
        let truth_v = Visibility { g: [0.2, -0.1, 0.15, 0.3], q: [0.3, -0.2, 0.15, -0.25, 0.2, 0.1] };
        let (samples, dirs) = synthetic(&p, truth_v, 600, 0.0, 5);
        let (_, got) = refine_texel_with_gradient(&samples, &dirs, &p, 1e-6, &GradientOptions { ridge: 1e-6, rounds: 12, curvature: true, curvature_ridge: 1e-6 }, BrdfReading::Width);
        for u in 0..6 {
            assert!((got.q[u] - truth_v.q[u]).abs() < 0.03, "q[{u}] = {} against {}", got.q[u], truth_v.q[u]);
        }
        for u in 0..4 {
            assert!((got.g[u] - truth_v.g[u]).abs() < 0.03, "g[{u}] = {} against {}", got.g[u], truth_v.g[u]);
        }
        // With noise and the default ridge: the fit with the curvature is closer than the
        // gradient's alone.
        let residual = |q: &ClothParams, v: &Visibility, s: &[LobeTarget], d: &[(Vec3, Vec3)]| -> f64 {
            s.iter().zip(d).map(|(t, &(wi, wo))| (predict_lobes(q, &with_gradient(*t, v, wi, wo), BrdfReading::Width) - t.radiance).length_squared() as f64).sum()
        };
        let (s, d) = synthetic(&p, truth_v, 400, 0.05, 6);
        let (a, va) = refine_texel_with_gradient(&s, &d, &p, 0.05, &GradientOptions { curvature: false, ..Default::default() }, BrdfReading::Width);
        let (b, vb) = refine_texel_with_gradient(&s, &d, &p, 0.05, &GradientOptions::default(), BrdfReading::Width);
        assert_eq!(va.q, [0.0; 6], "no curvature when it is off");
        assert!(residual(&b, &vb, &s, &d) < 0.8 * residual(&a, &va, &s, &d));
    }

    #[test]
    fn the_gradient_lowers_the_residual_and_stays_near_zero_without_one() {
        let p = truth();
        let residual = |q: &ClothParams, v: &Visibility, s: &[LobeTarget], d: &[(Vec3, Vec3)]| -> f64 {
            s.iter().zip(d).map(|(t, &(wi, wo))| (predict_lobes(q, &with_gradient(*t, v, wi, wo), BrdfReading::Width) - t.radiance).length_squared() as f64).sum()
        };
        // With a gradient in the data: the fit with one is better than without.
        let (s, d) = synthetic(&p, gradient_only([0.5, 0.0, 0.0, -0.5]), 300, 0.05, 2);
        let plain = refine_texel(&s, &p, 0.05, BrdfReading::Width);
        let (q, v) = refine_texel_with_gradient(&s, &d, &p, 0.05, &GradientOptions::default(), BrdfReading::Width);
        assert!(residual(&q, &v, &s, &d) < 0.5 * residual(&plain, &Visibility::default(), &s, &d));
        // Without one (noise only): g and q stay small.
        let (s, d) = synthetic(&p, Visibility::default(), 300, 0.05, 3);
        let (_, v) = refine_texel_with_gradient(&s, &d, &p, 0.05, &GradientOptions::default(), BrdfReading::Width);
        assert!(v.g.iter().chain(&v.q).all(|x| x.abs() < 0.05), "{v:?}");
    }

    #[test]
    fn degenerate_samples_give_no_gradient() {
        let p = truth();
        let (none, _) = refine_texel_with_gradient(&[], &[], &p, 0.05, &GradientOptions::default(), BrdfReading::Width);
        assert_eq!(none, p);
        // Black targets of a black texel: no information, g = q = 0, finite.
        let black = ClothParams::new(Vec3::ZERO, 1.46, 0.5, &[]);
        let (s, d) = synthetic(&black, Visibility { g: [0.3; 4], q: [0.2; 6] }, 50, 0.0, 4);
        let (q, v) = refine_texel_with_gradient(&s, &d, &black, 0.05, &GradientOptions::default(), BrdfReading::Width);
        assert_eq!(v, Visibility::default());
        assert!(q.kd.is_finite());
    }
}
