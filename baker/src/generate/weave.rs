//! Woven structure: which yarn lies on top at each crossing, and the yarn centrelines
//! that follow from it (warp along y, weft along x, z up).
//!
//! A yarn's centreline sits at ±A around the fabric's mid-plane at each crossing
//! (+A where it passes over), and moves between neighbouring crossings along a half
//! cosine, z(f) = z₀ + (z₁ − z₀)·(1 − cos πf)/2: C¹, flat along floats, periodic
//! because the pattern period divides the number of yarns per tile.

use glam::Vec3;

use super::params::{PatternKind, WovenParams};

/// The interlacing pattern.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Weave {
    pub kind: PatternKind,
    pub repeat: u32,
    pub over: u32,
    pub step: u32,
}

impl Weave {
    pub fn from_params(p: &WovenParams) -> Weave {
        Weave { kind: p.pattern, repeat: p.repeat, over: p.over, step: p.step }
    }

    /// Yarns per pattern period (in both directions).
    pub fn period(&self) -> u32 {
        match self.kind {
            PatternKind::Plain => 2,
            PatternKind::Twill | PatternKind::Satin => self.repeat,
        }
    }

    /// Whether warp `i` passes over weft `j`.
    pub fn warp_over(&self, i: u32, j: u32) -> bool {
        let n = self.period() as i64;
        let phase = (j as i64 - (self.step as i64) * (i as i64)).rem_euclid(n);
        match self.kind {
            PatternKind::Plain => (i + j).is_multiple_of(2),
            PatternKind::Twill => phase < self.over as i64,
            PatternKind::Satin => phase != 0,
        }
    }
}

/// Which way a yarn runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    /// Warp: along +y.
    Y,
    /// Weft: along +x.
    X,
}

/// A right-handed frame along a yarn: `t` tangent, `b` sideways (horizontal), `n`
/// "up" (b × n = t).
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub pos: Vec3,
    pub t: Vec3,
    pub b: Vec3,
    pub n: Vec3,
}

/// The centreline of one yarn over one tile period, in mm.
#[derive(Clone, Debug)]
pub struct YarnPath {
    pub axis: Axis,
    /// Position across the yarn (x for warps, y for wefts).
    pub offset: f32,
    pub z_mid: f32,
    pub amplitude: f32,
    /// Distance between the crossing yarns (they cross at (j + ½)·spacing).
    pub crossing_spacing: f32,
    /// +1 where this yarn is on top at crossing j, −1 below.
    pub sides: Vec<f32>,
    /// Tile length along the yarn (= sides.len() · crossing_spacing).
    pub length: f32,
}

impl YarnPath {
    /// Height and its derivative along the yarn at parameter `s` (mm along the axis).
    pub fn height(&self, s: f32) -> (f32, f32) {
        let n = self.sides.len() as i64;
        let u = s / self.crossing_spacing - 0.5;
        let j0 = u.floor();
        let f = u - j0;
        let j0 = j0 as i64;
        let s0 = self.sides[j0.rem_euclid(n) as usize];
        let s1 = self.sides[(j0 + 1).rem_euclid(n) as usize];
        let w = 0.5 * (1.0 - (std::f32::consts::PI * f).cos());
        let dw = 0.5 * std::f32::consts::PI * (std::f32::consts::PI * f).sin() / self.crossing_spacing;
        (self.z_mid + self.amplitude * (s0 + (s1 - s0) * w), self.amplitude * (s1 - s0) * dw)
    }

    /// The frame at parameter `s` (unwrapped: s beyond the tile continues periodically).
    pub fn frame(&self, s: f32) -> Frame {
        let (z, dz) = self.height(s);
        let (pos, t) = match self.axis {
            Axis::Y => (Vec3::new(self.offset, s, z), Vec3::new(0.0, 1.0, dz).normalize()),
            Axis::X => (Vec3::new(s, self.offset, z), Vec3::new(1.0, 0.0, dz).normalize()),
        };
        // t is never vertical (|dz| is bounded), so Z × t is a valid sideways axis.
        let b = Vec3::Z.cross(t).normalize();
        let n = t.cross(b);
        Frame { pos, t, b, n }
    }
}

/// Yarn counts per tile: a multiple of `lcm(period, colours)` closest to
/// `extent / spacing`, at least one such multiple.
pub fn yarn_count(extent: f32, spacing: f32, period: u32, colors: usize) -> u32 {
    let unit = lcm(period, colors as u32).max(1);
    let repeats = (extent / (spacing * unit as f32)).round().max(1.0);
    repeats as u32 * unit
}

fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 { a } else { gcd(b, a % b) }
}

fn lcm(a: u32, b: u32) -> u32 {
    if a == 0 || b == 0 { a.max(b) } else { a / gcd(a, b) * b }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn weave(kind: PatternKind, repeat: u32, over: u32, step: u32) -> Weave {
        Weave { kind, repeat, over, step }
    }

    #[test]
    fn patterns_have_the_textbook_float_structure() {
        let plain = weave(PatternKind::Plain, 2, 1, 1);
        for i in 0..4 {
            for j in 0..4 {
                assert_eq!(plain.warp_over(i, j), plain.warp_over(i + 2, j) && !plain.warp_over(i + 1, j));
            }
        }
        // 2/2 twill: each warp over 2 of 4; the pattern shifts by one per warp (diagonal).
        let twill = weave(PatternKind::Twill, 4, 2, 1);
        for i in 0..8 {
            assert_eq!((0..4).filter(|&j| twill.warp_over(i, j)).count(), 2);
            for j in 0..8 {
                assert_eq!(twill.warp_over(i, j), twill.warp_over(i + 1, j + 1));
            }
        }
        // 5-harness satin: one interlacing per warp and per weft in each period.
        let satin = weave(PatternKind::Satin, 5, 1, 2);
        for k in 0..5 {
            assert_eq!((0..5).filter(|&j| !satin.warp_over(k, j)).count(), 1);
            assert_eq!((0..5).filter(|&i| !satin.warp_over(i, k)).count(), 1);
        }
        // Interlacing points of neighbouring warps never touch (that is what makes satin smooth).
        for i in 0..5 {
            let j = (0..5).find(|&j| !satin.warp_over(i, j)).unwrap();
            assert!(satin.warp_over(i + 1, j) && satin.warp_over(i + 1, (j + 1) % 5) && satin.warp_over(i + 1, (j + 4) % 5));
        }
    }

    #[test]
    fn centrelines_are_periodic_and_smooth() {
        let path = YarnPath { axis: Axis::Y, offset: 0.1, z_mid: 1.0, amplitude: 0.2, crossing_spacing: 0.25, sides: vec![1.0, 1.0, -1.0, 1.0, -1.0], length: 1.25 };
        for k in 0..200 {
            let s = k as f32 * 0.013;
            let (z, dz) = path.height(s);
            let (z2, dz2) = path.height(s + path.length);
            assert!((z - z2).abs() < 1e-5 && (dz - dz2).abs() < 1e-3);
            // Derivative matches a central difference (C¹). Bound: the second derivative
            // (≤ A·π²/s_c² = 31.6) may jump at a crossing, costing ≤ 31.6·e/2 = 3.2e-3, plus
            // f32 rounding of z ≈ 1 over 2e (≈ 6e-4).
            let e = 2e-4;
            let num = (path.height(s + e).0 - path.height(s - e).0) / (2.0 * e);
            assert!((num - dz).abs() < 4e-3, "s {s}: {num} vs {dz}");
            let f = path.frame(s);
            assert!((f.b.cross(f.n) - f.t).length() < 1e-5 && f.n.z > 0.0 && f.b.z.abs() < 1e-6);
        }
        assert_eq!(path.height(0.125).0, 1.2); // over at crossing 0
        assert_eq!(path.height(0.625).0, 0.8); // under at crossing 2
        assert_eq!(yarn_count(1.0, 0.14, 4, 1), 8);
        assert_eq!(yarn_count(1.0, 0.14, 5, 2), 10);
        assert_eq!(yarn_count(0.1, 0.14, 4, 3), 12);
    }
}
