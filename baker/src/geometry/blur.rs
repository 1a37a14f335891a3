//! Anisotropic periodic Gaussian blur: h = G_σ ⊛ h0 (paper §5.2), σ = (σx, σy) in texels.
//!
//! Separable and exact for a periodic map: each row (then column) is multiplied in the
//! Fourier domain by the Gaussian's transform exp(−2π²σ²(k/n)²), k the signed frequency
//! index. That is the convolution with the Gaussian wrapped around the period, with no
//! truncation of its tails and the mean kept exactly (k = 0 is multiplied by 1).

use rayon::prelude::*;
use rustfft::FftPlanner;
use rustfft::num_complex::Complex;

/// Blurs the periodic `nx × ny` map (x fastest) with σ = `sigma` [x, y] texels.
pub fn periodic_gaussian(map: &[f32], nx: usize, ny: usize, sigma: [f32; 2]) -> Vec<f32> {
    let mut data: Vec<f64> = map.iter().map(|&v| v as f64).collect();
    blur_lines(&mut data, nx, sigma[0] as f64);
    let mut transposed: Vec<f64> = (0..nx * ny).map(|k| data[(k / ny) + nx * (k % ny)]).collect();
    blur_lines(&mut transposed, ny, sigma[1] as f64);
    (0..nx * ny).map(|k| transposed[(k / nx) + ny * (k % nx)] as f32).collect()
}

/// Blurs every line of length `n` in place.
fn blur_lines(data: &mut [f64], n: usize, sigma: f64) {
    if !(sigma > 0.0) || n < 2 {
        return;
    }
    let mut planner = FftPlanner::<f64>::new();
    let forward = planner.plan_fft_forward(n);
    let inverse = planner.plan_fft_inverse(n);
    let gain: Vec<f64> = (0..n)
        .map(|k| {
            let f = if k <= n / 2 { k as f64 } else { k as f64 - n as f64 } / n as f64;
            (-2.0 * std::f64::consts::PI * std::f64::consts::PI * sigma * sigma * f * f).exp() / n as f64
        })
        .collect();
    data.par_chunks_mut(n * 16).for_each(|chunk| {
        let mut buf = vec![Complex::new(0.0, 0.0); n];
        let mut scratch = vec![Complex::new(0.0, 0.0); forward.get_inplace_scratch_len().max(inverse.get_inplace_scratch_len())];
        for line in chunk.chunks_mut(n) {
            buf.iter_mut().zip(line.iter()).for_each(|(b, &v)| *b = Complex::new(v, 0.0));
            forward.process_with_scratch(&mut buf, &mut scratch);
            buf.iter_mut().zip(&gain).for_each(|(b, g)| *b *= g);
            inverse.process_with_scratch(&mut buf, &mut scratch);
            line.iter_mut().zip(&buf).for_each(|(v, b)| *v = b.re);
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    #[test]
    fn sinusoids_are_attenuated_by_the_gaussian_transfer_function() {
        // A sinusoid of period P through a Gaussian of width σ keeps exp(−2π²σ²/P²) of
        // its amplitude; exact for periods that divide the map, to f32 rounding.
        let (nx, ny) = (64, 32);
        let (px, py) = (16.0, 8.0);
        let (sx, sy) = (3.0f32, 1.0f32);
        let h: Vec<f32> = (0..nx * ny).map(|k| (5.0 + (TAU * (k % nx) as f64 / px).sin() + (TAU * (k / nx) as f64 / py).cos()) as f32).collect();
        let b = periodic_gaussian(&h, nx, ny, [sx, sy]);
        let ax = (-2.0 * std::f64::consts::PI.powi(2) * (sx as f64 / px).powi(2)).exp();
        let ay = (-2.0 * std::f64::consts::PI.powi(2) * (sy as f64 / py).powi(2)).exp();
        for (k, &got) in b.iter().enumerate() {
            let want = 5.0 + ax * (TAU * (k % nx) as f64 / px).sin() + ay * (TAU * (k / nx) as f64 / py).cos();
            assert!((got as f64 - want).abs() < 1e-5, "texel {k}: {got} vs {want}");
        }
    }

    #[test]
    fn zero_width_is_the_identity_and_the_mean_is_kept() {
        let h: Vec<f32> = (0..48).map(|k| ((k * 37) % 11) as f32).collect();
        assert_eq!(periodic_gaussian(&h, 8, 6, [0.0, 0.0]), h);
        let b = periodic_gaussian(&h, 8, 6, [2.5, 40.0]);
        let mean = |v: &[f32]| v.iter().map(|&x| x as f64).sum::<f64>() / v.len() as f64;
        assert!((mean(&b) - mean(&h)).abs() < 1e-5);
    }
}
