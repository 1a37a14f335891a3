//! A counter-based random number generator keyed by (seed, stream, sample).
//!
//! Every path owns its own stream, derived by hashing the render seed, the item it
//! belongs to (pixel, texel or measurement pair) and the sample index. Nothing is shared
//! between paths, so an image is bit-identical for any number of threads and any
//! scheduling (docs/DESIGN.md §8, "Determinism").
//!
//! The generator is SplitMix64 (Steele, Lea and Flood 2014): output n of a stream is
//! `mix(key + n·γ)`, γ the golden-ratio increment, `mix` a 64-bit finalizer with full
//! avalanche. Each 64-bit output gives two 24-bit-mantissa floats in [0, 1).

/// Weyl increment of SplitMix64: 2⁶⁴ / φ, odd.
const GOLDEN_GAMMA: u64 = 0x9e37_79b9_7f4a_7c15;

/// The SplitMix64 / Stafford "Mix13" finalizer: a bijection on u64 with full avalanche.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// One path's random stream.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
    /// The second half of the last 64-bit output, not yet used.
    spare: Option<u32>,
}

impl Rng {
    /// The stream for (`seed`, `stream`, `sample`). Distinct triples give independent
    /// streams: the key is a chain of bijective mixes, so two triples collide only if
    /// the 64-bit keys collide.
    pub fn new(seed: u64, stream: u64, sample: u64) -> Rng {
        let k = mix64(seed ^ 0x5851_f42d_4c95_7f2d);
        let k = mix64(k ^ stream.wrapping_mul(GOLDEN_GAMMA));
        let k = mix64(k.wrapping_add(sample).wrapping_mul(0xd134_2543_de82_ef95) ^ (k >> 29));
        Rng { state: k, spare: None }
    }

    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(GOLDEN_GAMMA);
        mix64(self.state)
    }

    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        if let Some(s) = self.spare.take() {
            return s;
        }
        let v = self.next_u64();
        self.spare = Some((v >> 32) as u32);
        v as u32
    }

    /// Uniform in [0, 1), 24 random bits (every value exactly representable in f32).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }

    /// Two uniforms in [0, 1).
    #[inline]
    pub fn next_2d(&mut self) -> (f32, f32) {
        (self.next_f32(), self.next_f32())
    }

    /// An exponential variate with rate 1: −ln(1 − u), finite because u < 1.
    #[inline]
    pub fn next_exp(&mut self) -> f32 {
        -(1.0 - self.next_f32()).ln()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_uniform_and_distinct() {
        // Mean and variance of U[0,1): 1/2 and 1/12; with n = 200k the standard error of
        // the mean is 0.29/√n ≈ 6.5e-4, so 3e-3 is a > 4σ bound.
        let n = 200_000;
        let mut r = Rng::new(7, 3, 11);
        let (mut s, mut s2) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let u = r.next_f32() as f64;
            assert!((0.0..1.0).contains(&u));
            s += u;
            s2 += u * u;
        }
        let mean = s / n as f64;
        let var = s2 / n as f64 - mean * mean;
        assert!((mean - 0.5).abs() < 3e-3, "mean {mean}");
        assert!((var - 1.0 / 12.0).abs() < 2e-3, "variance {var}");
        // Neighbouring keys give unrelated first outputs.
        let a = Rng::new(7, 3, 11).next_u64();
        for (seed, stream, sample) in [(8, 3, 11), (7, 4, 11), (7, 3, 12), (7, 11, 3)] {
            let b = Rng::new(seed, stream, sample).next_u64();
            assert!((a ^ b).count_ones() > 12, "{seed} {stream} {sample}");
        }
        // Same key, same stream.
        assert_eq!(Rng::new(1, 2, 3).next_u64(), Rng::new(1, 2, 3).next_u64());
    }

    #[test]
    fn adjacent_samples_are_uncorrelated() {
        // Correlation of the first uniform of consecutive sample streams of one pixel;
        // for independent streams it is ~N(0, 1/n): 5/√n bounds it.
        let n = 100_000u64;
        let xs: Vec<f64> = (0..n).map(|i| Rng::new(1, 42, i).next_f32() as f64 - 0.5).collect();
        let c: f64 = xs.windows(2).map(|w| w[0] * w[1]).sum::<f64>() / (n as f64 * (1.0 / 12.0));
        assert!(c.abs() < 5.0 / (n as f64).sqrt(), "lag-1 correlation {c}");
    }
}
