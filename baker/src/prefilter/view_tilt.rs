//! The view tilt of coarse texels (the renderers' side and the reason:
//! `fabric_runtime::brdf::visible_normal`; measured in baker/PREFILTER_MEASUREMENTS.md,
//! "Grazing views").
//!
//! For each of [`TILT_DIRECTIONS`] view directions ω_k (polar angles
//! [`TILT_POLARS`], [`TILT_AZIMUTHS`] azimuths each, the rings offset by half a step),
//! rays leave the top plane over every level-0 texel (a [`TILT_RAYS`]² grid per texel)
//! toward −ω_k and meet the unfiltered height field, on the periodic tile when the model
//! is rendered so. Each hit adds its level-0 texel's lobe-0 normal to the coarse texel
//! under the hit, at every level: the sum h_k is the direction of the normals a distant
//! pixel sees there. Per coarse texel and slope component the fit is then the weighted
//! least squares
//!
//! ```text
//! σ(h_k) ≈ a + B u(ω_k),   σ(n) = n.xy / n.z,   u(ω) = ω.xy / √ω.z
//! ```
//!
//! with weights m/(m + 4) (m the hits) and a small ridge on B; the intercept a (the
//! normal of a view from above) is dropped, since renderers tilt from the texel's own
//! lobe-0 normal. A texel no ray meets keeps B = 0. The visibility's slope c is the
//! least-squares fit of m_k / E − 1 ≈ c · u(ω_k), E = the hits a view from above gives
//! (the rays started over the texel's footprint): every ray meets the periodic sheet
//! somewhere, so the hit density m/E is 1 on average, and exactly 1 from above. (A fit
//! of ln(m/E) was tried first: zero-hit views drove its exponential to 2× the density's
//! spread and a mean of 2 at 70°.)
//!
//! Turning every frame by the mean visible normal is not the mean over the visible
//! normals (on the aggregate it left twill 4% dark), so once a level's lobes are fitted
//! each texel's B is refined ([`VisibleHits::fit_level`]): Nelder–Mead from the
//! normal-based B on the relative error of the texel's tilted luminance response against
//! the hit-weighted mean of its footprint's level-0 responses, over the same views and
//! [`refine_lights`]. Per coarse texel the sums are folded from the level below, so the
//! level-0 responses are evaluated once.

use glam::{Mat3, Vec2, Vec3};
use rayon::prelude::*;

use fabric_runtime::brdf::BrdfReading;
use fabric_runtime::brdf::visible_normal::{ViewTilt, tilt_frames, view_tilt_basis};
use fabric_runtime::cpu::heightfield::{HeightTracer, HfTrace};
use fabric_runtime::cpu::shading::texel_response;
use fabric_runtime::hybrid::{HybridModel, Level, PackedViewTilt, level_dims};

use fabric_runtime::scene::{Ray, direction_from_angles};

use crate::fit::simplex::{NelderMead, nelder_mead};

/// Polar angles of the view directions (degrees).
pub const TILT_POLARS: [f32; 4] = [30.0, 50.0, 65.0, 75.0];
/// Azimuths per polar angle.
pub const TILT_AZIMUTHS: usize = 8;
/// View directions in all.
pub const TILT_DIRECTIONS: usize = TILT_POLARS.len() * TILT_AZIMUTHS;
/// Rays per level-0 texel axis and direction.
pub const TILT_RAYS: u32 = 2;
/// Ridge on B, relative to the summed weight.
const RIDGE: f32 = 1e-3;
/// Height-field steps per ray.
const STEPS: u32 = 4096;

/// The view directions of the fit.
pub fn tilt_directions() -> Vec<Vec3> {
    let mut out = Vec::with_capacity(TILT_DIRECTIONS);
    for (ring, &polar) in TILT_POLARS.iter().enumerate() {
        for a in 0..TILT_AZIMUTHS {
            let az = (a as f32 + 0.5 * (ring % 2) as f32) * 360.0 / TILT_AZIMUTHS as f32;
            out.push(direction_from_angles(polar, az));
        }
    }
    out
}

/// Normal equations of one coarse texel: Σ w x xᵀ and Σ w σ x, x = (1, u).
#[derive(Clone, Copy)]
struct Normal {
    g: Mat3,
    rx: Vec3,
    ry: Vec3,
    weight: f32,
    /// Σ u uᵀ and Σ u (m/E − 1) of the visibility fit.
    gu: glam::Mat2,
    ru: Vec2,
    views: f32,
}

impl Default for Normal {
    // Not derived: glam's matrices default to the identity.
    fn default() -> Normal {
        Normal { g: Mat3::ZERO, rx: Vec3::ZERO, ry: Vec3::ZERO, weight: 0.0, gu: glam::Mat2::ZERO, ru: Vec2::ZERO, views: 0.0 }
    }
}

impl Normal {
    fn solve_visibility(&self) -> [f32; 2] {
        if self.views <= 0.0 {
            return [0.0; 2];
        }
        let g = self.gu + glam::Mat2::from_diagonal(Vec2::splat(RIDGE * self.views));
        if g.determinant().abs() < 1e-12 {
            return [0.0; 2];
        }
        let c = g.inverse() * self.ru;
        if c.is_finite() { c.to_array() } else { [0.0; 2] }
    }

    fn solve(&self) -> [f32; 4] {
        if self.weight <= 0.0 {
            return [0.0; 4];
        }
        let ridge = RIDGE * self.weight;
        let g = self.g + Mat3::from_diagonal(Vec3::new(0.0, ridge, ridge));
        if g.determinant().abs() < 1e-12 * self.weight.powi(3) {
            return [0.0; 4];
        }
        let inv = g.inverse();
        let (cx, cy) = (inv * self.rx, inv * self.ry);
        let b = [cx.y, cx.z, cy.y, cy.z];
        if b.iter().all(|v| v.is_finite()) { b } else { [0.0; 4] }
    }
}

/// The lights of the response refinement for view ω_o: [`REFINE_POLARS`] ×
/// [`REFINE_AZIMUTHS`] fixed directions and the mirror of ω_o.
pub fn refine_lights(wo: Vec3) -> Vec<Vec3> {
    let mut out = Vec::with_capacity(REFINE_POLARS.len() * REFINE_AZIMUTHS + 1);
    for (ring, &polar) in REFINE_POLARS.iter().enumerate() {
        for a in 0..REFINE_AZIMUTHS {
            let az = (a as f32 + 0.5 * (ring % 2) as f32) * 360.0 / REFINE_AZIMUTHS as f32 + 15.0;
            out.push(direction_from_angles(polar, az));
        }
    }
    out.push(Vec3::new(-wo.x, -wo.y, wo.z));
    out
}

/// Polar angles of the refinement's fixed lights (degrees).
pub const REFINE_POLARS: [f32; 3] = [25.0, 50.0, 70.0];
/// Azimuths per polar angle.
pub const REFINE_AZIMUTHS: usize = 4;
/// Nelder–Mead evaluations of a texel's refinement.
const REFINE_EVALS: usize = 40;

/// What the distant views see of level 0: per view direction, the hits on each
/// level-0 texel, and per coarse level the normal-based fit (the refinement's start).
pub struct VisibleHits {
    directions: Vec<Vec3>,
    /// hits[k][j]: rays of direction k that meet level-0 texel j.
    hits: Vec<Vec<u32>>,
    initial: Vec<Vec<ViewTilt>>,
    /// Per level ≥ 1 after [`VisibleHits::fit_level`] ran for the level below: Σ m_kj
    /// lum f_j at each (texel, direction, light) and Σ m_kj at each (texel, direction).
    finer: Option<(usize, Vec<f32>, Vec<f32>)>,
}

/// A level's fitted tilts and how much the response refinement gained.
pub struct LevelTilts {
    pub records: Vec<PackedViewTilt>,
    /// Mean relative error of the texels' tilted responses against what the views see,
    /// without a tilt and with it.
    pub error_untilted: f64,
    pub error_tilted: f64,
}

/// Traces the views of every level-0 texel and fits levels 1..`count` from the normals.
pub fn trace_visible_hits(model: &HybridModel, count: usize, periodic: bool) -> VisibleHits {
    let (w0, h0) = (model.width(), model.height_px());
    let l0 = &model.levels[0];
    let normals: Vec<Vec3> = (0..w0 * h0).map(|k| l0.texel_brdf(k % w0, k / w0).frames[0].n).collect();
    let tracer = HeightTracer::new(model, periodic);
    let texel = model.texel_size();
    let origin = model.tile.origin;
    let top = model.tile.top_z;
    let directions = tilt_directions();
    let mut acc: Vec<Vec<Normal>> = (0..count).map(|l| vec![Normal::default(); { let (w, h) = level_dims(w0, h0, l); (w * h) as usize }]).collect();
    let mut all_hits = Vec::with_capacity(directions.len());
    for &wo in &directions {
        // The level-0 texel each ray meets, row by row in parallel, summed in row order
        // (the same sums on any number of threads).
        let rows: Vec<Vec<u32>> = (0..h0)
            .into_par_iter()
            .map(|j| {
                let mut met = Vec::with_capacity((w0 * TILT_RAYS * TILT_RAYS) as usize);
                for i in 0..w0 {
                    for s in 0..TILT_RAYS * TILT_RAYS {
                        let (a, b) = ((s % TILT_RAYS) as f32 + 0.5, (s / TILT_RAYS) as f32 + 0.5);
                        let start = origin + Vec2::new(i as f32 + a / TILT_RAYS as f32, j as f32 + b / TILT_RAYS as f32) * texel;
                        let ray = Ray::new(start.extend(top), -wo);
                        let mut steps = 0;
                        if let HfTrace::Hit(t) = tracer.trace(&ray, 0.0, f32::MAX, 0.0, STEPS, &mut steps) {
                            let q = ((ray.at(t).truncate() - origin) / texel).floor();
                            let (qi, qj) = (q.x as i64, q.y as i64);
                            let (qi, qj) = if periodic { (qi.rem_euclid(w0 as i64), qj.rem_euclid(h0 as i64)) } else { (qi.clamp(0, w0 as i64 - 1), qj.clamp(0, h0 as i64 - 1)) };
                            met.push(qj as u32 * w0 + qi as u32);
                        }
                    }
                }
                met
            })
            .collect();
        let mut sums = vec![(Vec3::ZERO, 0u32); (w0 * h0) as usize];
        for &k in rows.iter().flatten() {
            sums[k as usize].0 += normals[k as usize];
            sums[k as usize].1 += 1;
        }
        let u = view_tilt_basis(wo);
        let x = Vec3::new(1.0, u.x, u.y);
        let xxt = Mat3::from_cols(x * x.x, x * x.y, x * x.z);
        for (level, eqs) in acc.iter_mut().enumerate().skip(1) {
            let (lw, lh) = level_dims(w0, h0, level);
            let mut cell = vec![(Vec3::ZERO, 0u32); (lw * lh) as usize];
            for j in 0..h0 {
                for i in 0..w0 {
                    let (n, c) = sums[(j * w0 + i) as usize];
                    let slot = &mut cell[((j >> level) * lw + (i >> level)) as usize];
                    slot.0 += n;
                    slot.1 += c;
                }
            }
            for (k, (e, &(_, m))) in eqs.iter_mut().zip(&cell).enumerate() {
                let (ci, cj) = (k as u32 % lw, k as u32 / lw);
                let expected = (TILT_RAYS * TILT_RAYS * super::extent(ci, level, w0) * super::extent(cj, level, h0)) as f32;
                let excess = m as f32 / expected - 1.0;
                e.gu += glam::Mat2::from_cols(u * u.x, u * u.y);
                e.ru += u * excess;
                e.views += 1.0;
            }
            for (e, (h, c)) in eqs.iter_mut().zip(cell) {
                if c == 0 || h.z <= 1e-3 * c as f32 {
                    continue;
                }
                let w = c as f32 / (c as f32 + 4.0);
                let sigma = Vec2::new(h.x, h.y) / h.z;
                e.g += xxt * w;
                e.rx += x * (w * sigma.x);
                e.ry += x * (w * sigma.y);
                e.weight += w;
            }
        }
        all_hits.push(sums.into_iter().map(|s| s.1).collect());
    }
    let initial = acc.into_iter().map(|eqs| eqs.iter().map(|e| ViewTilt { b: e.solve(), c: e.solve_visibility() }).collect()).collect();
    VisibleHits { directions, hits: all_hits, initial, finer: None }
}

impl VisibleHits {
    /// The tilts of coarse level `level` (whose lobes are fitted: `coarse`), each texel's
    /// B refined from the normal-based fit by Nelder–Mead on the relative error of its
    /// tilted luminance response against the hit-weighted mean of its footprint's
    /// level-0 responses, over the views ω_k (weighted by the texel's hit density) and
    /// [`refine_lights`]; the start is kept where it is not beaten. Levels must come in
    /// order 1, 2, … (each folds the sums of the one below).
    pub fn fit_level(&mut self, model: &HybridModel, level: usize, coarse: &Level, reading: BrdfReading) -> LevelTilts {
        let (w0, h0) = (model.width(), model.height_px());
        let (lw, lh) = (coarse.width, coarse.height);
        let nd = self.directions.len();
        let lights: Vec<Vec<Vec3>> = self.directions.iter().map(|&wo| refine_lights(wo)).collect();
        let nl = lights[0].len();
        let lum = |v: Vec3| (v.x + v.y + v.z) / 3.0;
        // Σ m lum f per (texel, direction, light) and Σ m per (texel, direction) at this level.
        let (sums, mass): (Vec<f32>, Vec<f32>) = match self.finer.take() {
            Some((finer_level, fs, fm)) if finer_level + 1 == level => {
                let fw = level_dims(w0, h0, finer_level).0;
                let fh = level_dims(w0, h0, finer_level).1;
                let mut s = vec![0f32; (lw * lh) as usize * nd * nl];
                let mut m = vec![0f32; (lw * lh) as usize * nd];
                for cj in 0..fh {
                    for ci in 0..fw {
                        let (from, to) = ((cj * fw + ci) as usize, ((cj / 2) * lw + ci / 2) as usize);
                        for (a, b) in s[to * nd * nl..][..nd * nl].iter_mut().zip(&fs[from * nd * nl..][..nd * nl]) {
                            *a += b;
                        }
                        for (a, b) in m[to * nd..][..nd].iter_mut().zip(&fm[from * nd..][..nd]) {
                            *a += b;
                        }
                    }
                }
                (s, m)
            }
            _ => {
                let l0 = &model.levels[0];
                let hits = &self.hits;
                let dirs = &self.directions;
                let per_texel: Vec<(Vec<f32>, Vec<f32>)> = (0..lw * lh)
                    .into_par_iter()
                    .map(|c| {
                        let (ci, cj) = (c % lw, c / lw);
                        let mut s = vec![0f32; nd * nl];
                        let mut m = vec![0f32; nd];
                        for j in (cj << level)..((cj + 1) << level).min(h0) {
                            for i in (ci << level)..((ci + 1) << level).min(w0) {
                                let index = (j * w0 + i) as usize;
                                let b = l0.texel_brdf(i, j);
                                for k in 0..nd {
                                    let hk = hits[k][index];
                                    if hk == 0 {
                                        continue;
                                    }
                                    m[k] += hk as f32;
                                    for (q, &wi) in lights[k].iter().enumerate() {
                                        s[k * nl + q] += hk as f32 * lum(texel_response(&b, wi, dirs[k], reading, model.meta.diffuse));
                                    }
                                }
                            }
                        }
                        (s, m)
                    })
                    .collect();
                let (mut s, mut m) = (Vec::with_capacity((lw * lh) as usize * nd * nl), Vec::with_capacity((lw * lh) as usize * nd));
                for (a, b) in per_texel {
                    s.extend(a);
                    m.extend(b);
                }
                (s, m)
            }
        };
        let initial = &self.initial[level];
        let dirs = &self.directions;
        let fits: Vec<(ViewTilt, f64, f64)> = (0..lw * lh)
            .into_par_iter()
            .map(|c| {
                let (ci, cj) = (c % lw, c / lw);
                let c = c as usize;
                let base = coarse.texel_brdf(ci, cj);
                let expected = (TILT_RAYS * TILT_RAYS * super::extent(ci, level, w0) * super::extent(cj, level, h0)) as f32;
                let start = initial[c];
                let n = (base.params.lobe_count as usize).clamp(1, fabric_runtime::brdf::MAX_LOBES);
                let error = |b: [f32; 4]| -> f64 {
                    let (mut e2, mut t2) = (0f64, 0f64);
                    for k in 0..nd {
                        let mk = mass[c * nd + k];
                        if mk <= 0.0 {
                            continue;
                        }
                        let weight = (mk / expected) as f64;
                        let mut tilted = base;
                        tilt_frames(&mut tilted.frames[..n], &ViewTilt { b, c: [0.0; 2] }, dirs[k]);
                        for (q, &wi) in lights[k].iter().enumerate() {
                            let target = (sums[(c * nd + k) * nl + q] / mk) as f64;
                            let model = lum(texel_response(&tilted, wi, dirs[k], reading, model.meta.diffuse)) as f64;
                            e2 += weight * (model - target) * (model - target);
                            t2 += weight * target * target;
                        }
                    }
                    if t2 > 0.0 { (e2 / t2).sqrt() } else { 0.0 }
                };
                let untilted = error([0.0; 4]);
                let mut best = (start.b, error(start.b));
                if untilted < best.1 {
                    best = ([0.0; 4], untilted);
                }
                let opts = NelderMead { max_evals: REFINE_EVALS, f_tol: 1e-4, x_tol: 1e-3 };
                let x0: Vec<f64> = best.0.iter().map(|&v| v as f64).collect();
                if let Ok(m) = nelder_mead(|x| error([x[0] as f32, x[1] as f32, x[2] as f32, x[3] as f32]), &x0, &[0.1; 4], &opts)
                    && m.f < best.1
                {
                    best = ([m.x[0] as f32, m.x[1] as f32, m.x[2] as f32, m.x[3] as f32], m.f);
                }
                (ViewTilt { b: best.0, c: start.c }, untilted, best.1)
            })
            .collect();
        let count = fits.len().max(1) as f64;
        let error_untilted = fits.iter().map(|f| f.1).sum::<f64>() / count;
        let error_tilted = fits.iter().map(|f| f.2).sum::<f64>() / count;
        self.finer = Some((level, sums, mass));
        LevelTilts { records: fits.iter().map(|f| PackedViewTilt::new(&f.0)).collect(), error_untilted, error_tilted }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_directions_cover_every_azimuth_of_each_ring() {
        let d = tilt_directions();
        assert_eq!(d.len(), TILT_DIRECTIONS);
        for ring in d.chunks(TILT_AZIMUTHS) {
            let sum: Vec3 = ring.iter().copied().sum();
            assert!(sum.truncate().length() < 1e-4, "{sum}");
        }
    }

    #[test]
    fn the_solve_recovers_a_known_matrix() {
        let b = [0.3f32, -0.05, 0.1, 0.2];
        let a = Vec2::new(0.02, -0.01);
        let mut e = Normal::default();
        for wo in tilt_directions() {
            let u = view_tilt_basis(wo);
            let sigma = a + Vec2::new(b[0] * u.x + b[1] * u.y, b[2] * u.x + b[3] * u.y);
            let x = Vec3::new(1.0, u.x, u.y);
            e.g += Mat3::from_cols(x * x.x, x * x.y, x * x.z);
            e.rx += x * sigma.x;
            e.ry += x * sigma.y;
            e.weight += 1.0;
        }
        let got = e.solve();
        for (g, w) in got.iter().zip(b) {
            assert!((g - w).abs() < 3e-3, "{got:?} vs {b:?}");
        }
        assert_eq!(Normal::default().solve(), [0.0; 4]);
        assert_eq!(Normal::default().solve_visibility(), [0.0; 2]);
    }
}
