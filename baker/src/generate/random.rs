//! Counter-based random streams: every random choice of the generator is keyed by
//! (seed, stream, item), so the output does not depend on the order in which threads
//! run, or on how many there are.
//!
//! The mixer is SplitMix64's finalizer (Steele, Lea and Flood 2014), which passes
//! BigCrush as a counter-based generator; a stream is SplitMix64 started from the hash
//! of its key.

/// Streams: one per kind of random choice, so adding draws to one kind never shifts
/// another.
pub mod stream {
    pub const FIBER: u64 = 1;
    pub const HAIR: u64 = 2;
    pub const LOOP: u64 = 3;
    pub const FELT: u64 = 4;
    pub const FELT_HAIR: u64 = 5;
    pub const FELT_LOOP: u64 = 6;
    pub const YARN: u64 = 7;
}

/// The baker's one SplitMix64 finalizer (the reference path tracer's streams use it too).
pub use crate::reference::rng::mix64;

/// A hash of a key: deterministic, well mixed.
#[inline]
pub fn hash3(a: u64, b: u64, c: u64) -> u64 {
    mix64(mix64(mix64(a ^ 0x9e37_79b9_7f4a_7c15).wrapping_add(b)).wrapping_add(c))
}

/// A stream of random numbers for one item.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
}

impl Rng {
    pub fn new(seed: u64, stream: u64, item: u64) -> Rng {
        Rng { state: hash3(seed, stream, item) }
    }

    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        mix64(self.state)
    }

    /// Uniform in [0, 1).
    #[inline]
    pub fn uniform(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }

    /// Uniform in [a, b).
    #[inline]
    pub fn range(&mut self, a: f32, b: f32) -> f32 {
        a + (b - a) * self.uniform()
    }

    /// Standard normal (Box–Muller; one of the pair is dropped for simplicity).
    pub fn normal(&mut self) -> f32 {
        let u1 = 1.0 - self.uniform(); // (0, 1]
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
    }

    /// A count with mean `mean`: floor(mean) plus one with probability frac(mean).
    pub fn count(&mut self, mean: f32) -> usize {
        let m = mean.max(0.0);
        m.floor() as usize + usize::from(self.uniform() < m.fract())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_uniform_independent_and_reproducible() {
        let mut a = Rng::new(1, stream::FIBER, 0);
        let mut b = Rng::new(1, stream::FIBER, 0);
        let xs: Vec<f32> = (0..100_000).map(|_| a.uniform()).collect();
        assert!(xs.iter().zip((0..).map(|_| b.uniform())).all(|(x, y)| *x == y));
        // Mean and variance of U(0,1): 1/2 and 1/12; with n = 1e5 the standard errors are
        // 9e-4 and 2.6e-4, so 5σ bounds.
        let n = xs.len() as f64;
        let mean = xs.iter().map(|&x| x as f64).sum::<f64>() / n;
        let var = xs.iter().map(|&x| (x as f64 - mean).powi(2)).sum::<f64>() / n;
        assert!((mean - 0.5).abs() < 5.0 * 9.2e-4, "{mean}");
        assert!((var - 1.0 / 12.0).abs() < 5.0 * 2.7e-4, "{var}");
        // Neighbouring items are uncorrelated (lag correlation of first draws).
        let firsts: Vec<f64> = (0..20_000).map(|i| Rng::new(1, stream::FIBER, i).uniform() as f64 - 0.5).collect();
        let corr = firsts.windows(2).map(|w| w[0] * w[1]).sum::<f64>() / (firsts.len() as f64 / 12.0);
        assert!(corr.abs() < 5.0 / (20_000f64).sqrt(), "{corr}");
        let mut r = Rng::new(9, stream::HAIR, 3);
        let normals: Vec<f32> = (0..50_000).map(|_| r.normal()).collect();
        let m = normals.iter().sum::<f32>() / 5e4;
        let v = normals.iter().map(|x| (x - m).powi(2)).sum::<f32>() / 5e4;
        assert!(m.abs() < 0.025 && (v - 1.0).abs() < 0.04, "normal mean {m} var {v}");
    }
}
