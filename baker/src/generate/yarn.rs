//! The procedural yarn of Zhao, Luan and Bala 2016 ("Fitting procedural yarn models
//! for realistic cloth rendering", §3–4): fibers twisted into plies, plies twisted
//! into a yarn, with fiber migration and flyaway fibers of the hair and loop kinds.
//!
//! Cross-section coordinates are relative to an undeformed yarn of radius 1: ply k's
//! centre sits at R_pc·(cos φ_k, sin φ_k), φ_k = 2πk/K + 2π·ply_twist·s, and a fiber
//! of the ply sits at (in the ply's radial/tangential basis)
//!
//! ```text
//!   R_p · R(s) · (e_N cos θ(s), e_B sin θ(s)),    θ(s) = θ_i + 2π·fiber_twist·s,
//!   R(s) = R_min·r_i + (R_max − R_min)·r_i·(cos ψ(s) + 1)/2            (Zhao Eq. 2)
//! ```
//!
//! with ψ the migration phase. The cross-section is then flattened to the woven yarn's
//! width × thickness. Whatever lies beyond the ply's edge (R > 1: loops, hairs) is
//! added unflattened, at the ply's mean radius in mm, so flyaways stick out by their
//! true length instead of being squashed with the yarn.

use std::f32::consts::{E, PI, TAU};

use glam::{Vec2, Vec3};

use super::params::{FlyawayParams, YarnParams};
use super::random::{Rng, hash3, stream};
use super::weave::YarnPath;

/// A yarn model resolved for one tile: lengths in mm, rates rounded to whole periods
/// per tile so every fiber is periodic.
#[derive(Clone, Debug)]
pub struct YarnModel {
    pub plies: u32,
    /// Ply radius R_p and ply-centre distance R_pc, relative to the yarn radius.
    pub ply_radius: f32,
    pub ply_center: f32,
    pub ellipse: [f32; 2],
    /// Half width and half thickness of the flattened yarn (mm).
    pub half_size: Vec2,
    /// A ply's mean radius in mm (for what sticks out beyond it).
    pub ply_radius_mm: f32,
    /// Radians per mm along the yarn.
    pub ply_rate: f32,
    pub fiber_rate: f32,
    pub migration_rate: f32,
    /// Whole migration cycles per tile (0: no migration).
    pub migration_cycles: u32,
    pub migration: [f32; 2],
    pub fibers_per_ply: u32,
    pub flyaways: FlyawayParams,
    pub density: [f32; 2],
}

/// Rounds a rate (turns per mm) to whole turns over `length`.
fn periodic_rate(turns_per_mm: f32, length: f32) -> f32 {
    TAU * (turns_per_mm * length).round() / length
}

impl YarnModel {
    /// `width`, `thickness`: the flattened yarn's size (mm); `length`: the tile length
    /// along the yarn; `fiber_radius` in mm.
    pub fn new(p: &YarnParams, width: f32, thickness: f32, length: f32, fiber_radius: f32) -> YarnModel {
        let k = p.plies;
        // Plies pressed together in a woven yarn fill its cross-section: their ellipses'
        // areas add up to the yarn's, K·π·R_p²·e_N·e_B = π, with R_pc + R_p = 1 so the
        // outermost fibers reach the yarn's edge. (Loose round plies would touch at
        // R_p = R_pc·sin(π/K) and leave a third to half of the yarn empty.)
        let (ply_radius, ply_center) = if k == 1 {
            (1.0, 0.0)
        } else {
            let rp = (1.0 / (k as f32 * p.ply_ellipse[0] * p.ply_ellipse[1])).sqrt().min(1.0);
            (rp, 1.0 - rp)
        };
        let half_size = Vec2::new(0.5 * width, 0.5 * thickness);
        let ply_area = PI * ply_radius * ply_radius * p.ply_ellipse[0] * p.ply_ellipse[1] * half_size.x * half_size.y;
        let fibers_per_ply = p.fibers_per_ply.unwrap_or_else(|| ((p.packing * ply_area / (PI * fiber_radius * fiber_radius)).round() as u32).max(1));
        let migration_cycles = if p.migration_period > 0.0 { ((length / p.migration_period).round() as u32).max(1) } else { 0 };
        YarnModel {
            plies: k,
            ply_radius,
            ply_center,
            ellipse: p.ply_ellipse,
            half_size,
            ply_radius_mm: ply_radius * (half_size.x * half_size.y).sqrt(),
            ply_rate: periodic_rate(p.ply_twist, length),
            fiber_rate: periodic_rate(p.fiber_twist, length),
            migration_rate: TAU * migration_cycles as f32 / length,
            migration_cycles,
            migration: [p.migration_rmin, p.migration_rmax],
            fibers_per_ply,
            flyaways: p.flyaways.clone(),
            density: [p.density_epsilon, p.density_beta],
        }
    }

    /// World position of a point of ply `ply` at parameter `s`, ply-relative radius
    /// `r` (1 = the ply's edge) and angle `theta` in the ply's frame.
    pub fn point(&self, path: &YarnPath, ply: u32, s: f32, r: f32, theta: f32) -> Vec3 {
        let phi = TAU * ply as f32 / self.plies as f32 + self.ply_rate * s;
        let (sp, cp) = phi.sin_cos();
        let (e_r, e_t) = (Vec2::new(cp, sp), Vec2::new(-sp, cp));
        let (st, ct) = theta.sin_cos();
        let dir = e_r * (self.ellipse[0] * ct) + e_t * (self.ellipse[1] * st);
        let inside = r.min(1.0);
        let q = e_r * self.ply_center + dir * (self.ply_radius * inside);
        let mut uv = q * self.half_size;
        if r > 1.0 {
            let out = (dir * self.half_size).normalize_or_zero();
            uv += out * ((r - 1.0) * self.ply_radius_mm);
        }
        let f = path.frame(s);
        f.pos + f.b * uv.x + f.n * uv.y
    }

    /// The fibers of one ply, drawn by rejection from Zhao's density (Eq. 1).
    pub fn sample_fibers(&self, rng: &mut Rng) -> Vec<FiberSeed> {
        let [eps, beta] = self.density;
        let p = |r: f32| (1.0 - 2.0 * eps) * ((E - r.exp()) / (E - 1.0)).max(0.0).powf(beta) + eps;
        let mut out = Vec::with_capacity(self.fibers_per_ply as usize);
        while out.len() < self.fibers_per_ply as usize {
            let v = Vec2::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
            let r = v.length();
            if r >= 1.0 || rng.uniform() >= p(r) {
                continue;
            }
            out.push(FiberSeed { radius: r, theta: v.y.atan2(v.x), migration_phase: rng.range(0.0, TAU) });
        }
        out
    }

    /// Ply-relative radius of a fiber at `s`, with loops (Zhao §4.2: a loop is a
    /// migration cycle whose R_max is raised to `loop_rmax`).
    pub fn fiber_radius(&self, f: &FiberSeed, s: f32, loop_key: (u64, u64)) -> f32 {
        let [rmin, rmax] = self.migration;
        if self.migration_cycles == 0 {
            return f.radius;
        }
        let psi = self.migration_rate * s + f.migration_phase;
        let c = 0.5 * (psi.cos() + 1.0);
        let base = rmin * f.radius;
        let fl = &self.flyaways;
        if fl.loop_probability > 0.0 {
            // Cycles run trough to trough; index them periodically over the tile.
            let cycle = ((psi + PI) / TAU).floor() as i64;
            let cycle = cycle.rem_euclid(self.migration_cycles as i64) as u64;
            let h = hash3(loop_key.0, loop_key.1, stream::LOOP.wrapping_mul(0x1000_0000) ^ cycle);
            if ((h >> 40) as f32 / (1u64 << 24) as f32) < fl.loop_probability {
                return base + (fl.loop_rmax - base) * c;
            }
        }
        base + (rmax - rmin) * f.radius * c
    }

    /// Fiber angle in the ply frame at `s`.
    pub fn fiber_angle(&self, f: &FiberSeed, s: f32) -> f32 {
        f.theta + self.fiber_rate * s
    }

    /// Hair flyaways of one ply over a tile of length `length` (Zhao §4.2): each runs
    /// from a root inside the ply to a tip beyond it, interpolating radius, azimuth and
    /// position along the yarn.
    pub fn sample_hairs(&self, length: f32, rng: &mut Rng) -> Vec<HairSeed> {
        let fl = &self.flyaways;
        let n = rng.count(fl.hair_density * length);
        (0..n)
            .map(|_| {
                let s0 = rng.range(0.0, length);
                let span = fl.hair_zspan * rng.range(0.5, 1.0) * if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
                let r0 = fl.hair_rmin * rng.range(0.9, 1.0);
                let r1 = r0 + fl.hair_rspan * rng.range(0.3, 1.0);
                let t0 = rng.range(0.0, TAU);
                let t1 = t0 + fl.hair_theta_span * rng.range(-0.5, 0.5);
                HairSeed { s: [s0, s0 + span], r: [r0, r1], theta: [t0, t1] }
            })
            .collect()
    }
}

/// A fiber's place in its ply: normalized radius r_i, angle θ_i, migration phase.
#[derive(Clone, Copy, Debug)]
pub struct FiberSeed {
    pub radius: f32,
    pub theta: f32,
    pub migration_phase: f32,
}

/// A hair flyaway: (start, end) of its position along the yarn, radius and angle.
#[derive(Clone, Copy, Debug)]
pub struct HairSeed {
    pub s: [f32; 2],
    pub r: [f32; 2],
    pub theta: [f32; 2],
}

/// Samples a closed fiber along the whole tile: points at s = 0, Δs, …, L (the last
/// equals the first shifted by one tile, so the polyline tiles seamlessly).
pub fn fiber_polyline(model: &YarnModel, path: &YarnPath, ply: u32, f: &FiberSeed, loop_key: (u64, u64), step: f32) -> Vec<Vec3> {
    // Speed bound of s ↦ position: 1 along the axis plus the twist and migration
    // motions, so segments stay ≤ `step` long.
    let max_r = model.migration[1].max(model.flyaways.loop_rmax).max(1.0);
    let reach = model.half_size.max_element() + max_r * model.ply_radius_mm;
    let speed = 1.0 + reach * (model.ply_rate.abs() + model.fiber_rate.abs() + model.migration_rate) + 2.0 * path.amplitude / path.crossing_spacing;
    let n = ((path.length * speed / step).ceil() as usize).max(8);
    let fine = (0..=n).map(|i| {
        let s = path.length * i as f32 / n as f32;
        model.point(path, ply, s, model.fiber_radius(f, s, loop_key), model.fiber_angle(f, s))
    });
    decimate(fine, step)
}

/// Keeps a point once it is `step` away from the last one kept (and always the last
/// point): the speed bound above is loose, and segments of about `step` are what the
/// voxelizer wants. Each kept chord is ≤ 2·step and spans a fine polyline whose
/// curvature radius is many steps, so the chord error stays far below a voxel.
fn decimate(points: impl Iterator<Item = Vec3>, step: f32) -> Vec<Vec3> {
    let mut out: Vec<Vec3> = Vec::new();
    let mut pending = None;
    for p in points {
        match out.last() {
            Some(&last) if (p - last).length() < step => pending = Some(p),
            _ => {
                out.push(p);
                pending = None;
            }
        }
    }
    out.extend(pending);
    out
}

/// Samples a hair from root to tip.
pub fn hair_polyline(model: &YarnModel, path: &YarnPath, ply: u32, h: &HairSeed, step: f32) -> Vec<Vec3> {
    let len = (h.s[1] - h.s[0]).abs() + (h.r[1] - h.r[0]) * model.ply_radius_mm + (h.theta[1] - h.theta[0]).abs() * model.ply_radius_mm * h.r[1];
    let n = ((len / step).ceil() as usize).max(2);
    (0..=n)
        .map(|i| {
            let a = i as f32 / n as f32;
            let lerp = |v: [f32; 2]| v[0] + (v[1] - v[0]) * a;
            model.point(path, ply, lerp(h.s), lerp(h.r), lerp(h.theta))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate::presets::Preset;
    use crate::generate::weave::Axis;

    fn straight(length: f32) -> YarnPath {
        YarnPath { axis: Axis::Y, offset: 0.0, z_mid: 0.0, amplitude: 0.0, crossing_spacing: length / 4.0, sides: vec![1.0; 4], length }
    }

    fn yarn_params() -> YarnParams {
        match Preset::Twill.params().fabric {
            super::super::params::FabricParams::Woven(w) => w.yarn,
            _ => unreachable!(),
        }
    }

    #[test]
    fn fiber_distribution_follows_zhao_eq1() {
        // Sample many fibers; the radial histogram, divided by the disk's 2πr, must follow
        // p(R) up to normalization. Bins of 0.1; n = 200k gives ≤ 3 % noise per bin.
        let mut p = yarn_params();
        p.fibers_per_ply = Some(200_000);
        (p.density_epsilon, p.density_beta) = (0.1, 2.0);
        let m = YarnModel::new(&p, 0.2, 0.1, 1.0, 0.006);
        let fibers = m.sample_fibers(&mut Rng::new(1, 0, 0));
        let mut hist = [0f64; 10];
        for f in &fibers {
            hist[(f.radius * 10.0) as usize] += 1.0;
        }
        let pdf = |r: f32| 0.8 * ((E - r.exp()) / (E - 1.0)).powf(2.0) + 0.1;
        let ratio: Vec<f64> = (0..10).map(|i| hist[i] / (((i as f64 + 0.5) / 10.0) * pdf((i as f32 + 0.5) / 10.0) as f64)).collect();
        let mean = ratio.iter().sum::<f64>() / 10.0;
        for (i, r) in ratio.iter().enumerate() {
            // Bin-centre evaluation of a curved density: ≤ 4 % bias in the outer bins.
            assert!((r / mean - 1.0).abs() < 0.07, "bin {i}: {}", r / mean);
        }
    }

    #[test]
    fn fibers_are_periodic_twisted_and_stay_in_the_yarn() {
        let p = yarn_params();
        let (w, t, len) = (0.14, 0.063, 1.2);
        let m = YarnModel::new(&p, w, t, len, 0.006);
        let path = straight(len);
        let seeds = m.sample_fibers(&mut Rng::new(3, 0, 0));
        let mut no_loop = m.clone();
        no_loop.flyaways.loop_probability = 0.0;
        for (k, f) in seeds.iter().enumerate() {
            let line = fiber_polyline(&no_loop, &path, 0, f, (3, k as u64), 0.005);
            let (first, last) = (line[0], *line.last().unwrap());
            assert!((last - first - Vec3::new(0.0, len, 0.0)).length() < 1e-4, "fiber {k} is not periodic");
            for q in &line {
                // Inside the flattened yarn's bounding ellipse (ply ellipse may overhang a bit).
                let e = (q.x / (0.5 * w * 1.3)).powi(2) + (q.z / (0.5 * t * 1.3)).powi(2);
                assert!(e <= 1.0, "fiber {k} leaves the yarn: {q}");
            }
            for seg in line.windows(2) {
                assert!((seg[1] - seg[0]).length() <= 2.0 * 0.005, "segment longer than twice the step");
            }
            // Segments are about one step long: the count matches the arc length.
            let arc: f32 = line.windows(2).map(|w| (w[1] - w[0]).length()).sum();
            assert!(line.len() as f32 >= arc / 0.0101 && (line.len() as f32) <= arc / 0.005 + 2.0, "{} points for arc {arc}", line.len());
        }
        // Twist: the ply centre turns ply_twist·L whole times over the tile.
        assert!((m.ply_rate * len / TAU - (p.ply_twist * len).round()).abs() < 1e-4);
    }

    #[test]
    fn loops_and_hairs_leave_the_ply() {
        let mut p = yarn_params();
        p.flyaways.loop_probability = 1.0;
        p.flyaways.loop_rmax = 2.5;
        let m = YarnModel::new(&p, 0.14, 0.063, 1.2, 0.006);
        let path = straight(1.2);
        let f = FiberSeed { radius: 0.5, theta: 0.0, migration_phase: 0.0 };
        // At a migration peak the loop reaches loop_rmax.
        assert!((m.fiber_radius(&f, 0.0, (1, 1)) - 2.5).abs() < 1e-5);
        let hairs = m.sample_hairs(10.0, &mut Rng::new(5, 0, 0));
        let expected = p.flyaways.hair_density * 10.0;
        assert!((hairs.len() as f32 - expected).abs() <= 1.0, "{} hairs for a mean of {expected}", hairs.len());
        for h in &hairs {
            let line = hair_polyline(&m, &path, 0, h, 0.005);
            let tip = *line.last().unwrap();
            let centre = path.frame(h.s[1]).pos;
            // The tip sticks out beyond the ply by (r1 − 1)·R_p(mm), unflattened.
            assert!((tip - centre).length() > 0.5 * m.ply_radius_mm * (h.r[1] - 1.0).max(0.0), "hair tip too close");
        }
    }
}
