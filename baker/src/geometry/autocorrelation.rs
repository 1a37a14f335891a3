//! The filter size from the autocorrelations of the height map (paper §5.2, Eq. 4,
//! after Kang et al.):
//!
//! ```text
//! C0[x] := Σ_{i,j} h[i, j] h[i − x, j],   C1[y] := Σ_{i,j} h[i, j] h[i, j − y]
//! ```
//!
//! with h periodic. By the Wiener–Khinchin theorem C0 is the inverse FFT along x of the
//! row power spectra summed over rows (and C1 likewise along y), O(n log n) per row.
//! We subtract h's mean first and divide by `C[0]`: that adds a constant and scales, so
//! the peaks stay where Eq. 4 puts them, and the curves become correlation coefficients
//! in [−1, 1] that thresholds can be stated in.
//!
//! For a patterned fabric C peaks at multiples of the smallest repeating structure (a
//! yarn); the first peak of each is the filter size along that axis.
//!
//! "Robustly in the presence of noise": a random (felt-like) height map also has bumps
//! in C, from its large-scale swells, and on a small tile they reach 0.2. A peak counts
//! only when (a) it is a real feature of the curve (topographic prominence) and (b) the
//! repetition it stands for is significant against the null hypothesis "h0 is a
//! stationary random field with this correlation" ([`first_peak`]): by Bartlett's formula
//! the sampling error of C at a lag beyond the correlation length has variance
//! ≈ (1/N) Σ_{u,v} ρ(u, v)², which we estimate from the central lobes (lags before the
//! first zero crossing) of the 1D autocorrelations, taking ρ as separable. A weave's
//! height is largely additive, a profile f(x) (column means) plus a profile g(y) (row
//! means), whose correlations never decay along the other axis, which would make the
//! lobes endless. So h = f + g + r is split, and the noise of C0 is that of the random
//! part r (Bartlett, 2D, scaled by r's share of h's variance) plus that of f, a single
//! realization of nx samples (Bartlett, 1D, scaled by f's share); C1 likewise with g. A
//! periodic profile's lobe ends within a quarter period, so it adds little; a random
//! one (silk's irregular weft profile, a felt's) adds its full sampling noise.

use rustfft::FftPlanner;
use rustfft::num_complex::Complex;

use super::GeometryError;

/// The normalized autocorrelations of a map: C0 along x (length nx), C1 along y (length ny).
#[derive(Clone, Debug, PartialEq)]
pub struct Autocorrelation {
    pub c0: Vec<f32>,
    pub c1: Vec<f32>,
    /// Standard error of C0 and C1 at lags beyond the correlation length, were h0 free
    /// of periodic patterns (module docs).
    pub null_sd: [f32; 2],
}

/// How the two first peaks become the filter size [x, y].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FilterRule {
    /// Each axis its own peak (the paper's Table 1 lists x / y sizes); an axis without a
    /// peak takes the other's.
    #[default]
    PerAxis,
    /// Both axes the smaller peak (the paper's text: "set our filter size to the smaller
    /// of the two").
    Smaller,
}

/// Settings of the robust first-peak search.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PeakSearch {
    /// A peak must rise this far above the deeper of the two valleys that separate it
    /// from higher ground (its topographic prominence), as a fraction of C's range over
    /// lags ≥ `min_lag`. Fiber-level noise and the sampling noise of a random (felt-like)
    /// map give wiggles of a few percent; a weave's yarn peak stands out by tens of
    /// percent. Default 0.15.
    pub min_prominence: f32,
    /// Smallest lag that can be a pattern period, in texels (default 2: below that it
    /// is fiber-level noise, not a yarn).
    pub min_lag: usize,
    /// A peak's periodic contrast must be at least this many null standard errors
    /// ([`first_peak`], [`Autocorrelation::null_sd`]). Default 4: ~10⁻⁴ false alarms
    /// over the dozen independent lags of a tile.
    pub min_significance: f32,
}

impl Default for PeakSearch {
    fn default() -> Self {
        PeakSearch { min_prominence: 0.15, min_lag: 2, min_significance: 4.0 }
    }
}

impl PeakSearch {
    pub(crate) fn validate(&self) -> Result<(), GeometryError> {
        if !(self.min_prominence.is_finite() && self.min_prominence > 0.0 && self.min_prominence < 1.0) {
            return Err(GeometryError::BadOption { name: "min_prominence", value: self.min_prominence.to_string(), reason: "must be in (0, 1)" });
        }
        if !(self.min_significance.is_finite() && self.min_significance >= 0.0) {
            return Err(GeometryError::BadOption { name: "min_significance", value: self.min_significance.to_string(), reason: "must be ≥ 0" });
        }
        if self.min_lag < 1 {
            return Err(GeometryError::BadOption { name: "min_lag", value: self.min_lag.to_string(), reason: "must be at least 1 texel" });
        }
        Ok(())
    }
}

/// C0 and C1 of the periodic `nx × ny` map `h` (x fastest), normalized to `C[0] = 1`.
/// `None` when h is flat (no variation to correlate).
pub fn autocorrelate(h: &[f32], nx: usize, ny: usize) -> Option<Autocorrelation> {
    let mean = h.iter().map(|&v| v as f64).sum::<f64>() / h.len() as f64;
    let centered: Vec<f64> = h.iter().map(|&v| v as f64 - mean).collect();
    let transposed: Vec<f64> = (0..nx * ny).map(|k| centered[(k / ny) + nx * (k % ny)]).collect();
    let c0 = line_autocorrelation(&centered, nx, ny);
    let c1 = line_autocorrelation(&transposed, ny, nx);
    // Flat within f32 rounding of the heights: nothing to correlate.
    let scale = mean.abs().max(1.0);
    if !(c0[0] > (1e-6 * scale).powi(2) * (nx * ny) as f64) {
        return None;
    }
    let norm = |c: Vec<f64>| -> Vec<f32> {
        let c00 = c[0];
        c.into_iter().map(|v| (v / c00).clamp(-1.0, 1.0) as f32).collect()
    };
    let total_energy = c0[0];
    let (c0, c1) = (norm(c0), norm(c1));
    // The null's random field: h minus its row and column mean profiles (module docs).
    let row_mean: Vec<f64> = (0..ny).map(|j| centered[j * nx..(j + 1) * nx].iter().sum::<f64>() / nx as f64).collect();
    let col_mean: Vec<f64> = (0..nx).map(|i| (0..ny).map(|j| centered[i + nx * j]).sum::<f64>() / ny as f64).collect();
    let residual: Vec<f64> = (0..nx * ny).map(|k| centered[k] - row_mean[k / nx] - col_mean[k % nx]).collect();
    let residual_t: Vec<f64> = (0..nx * ny).map(|k| residual[(k / ny) + nx * (k % ny)]).collect();
    let (r0, r1) = (line_autocorrelation(&residual, nx, ny), line_autocorrelation(&residual_t, ny, nx));
    let residual_var = if r0[0] > 1e-12 * total_energy { (r0[0] / total_energy).powi(2) * lobe_energy(&norm(r0)) * lobe_energy(&norm(r1)) / (nx * ny) as f64 } else { 0.0 };
    // A profile is one realization along its axis: its own sampling noise enters the
    // autocorrelation along that axis (and only a constant along the other).
    let profile_var = |p: &[f64], copies: usize| -> f64 {
        let a = line_autocorrelation(p, p.len(), 1);
        if a[0] > 1e-12 * total_energy { (a[0] * copies as f64 / total_energy).powi(2) * lobe_energy(&norm(a)) / p.len() as f64 } else { 0.0 }
    };
    let null_sd = [(residual_var + profile_var(&col_mean, ny)).sqrt() as f32, (residual_var + profile_var(&row_mean, nx)).sqrt() as f32];
    Some(Autocorrelation { c0, c1, null_sd })
}

/// Σ C(u)² over the central lobe −z < u < z, z the first lag with C ≤ 0.
fn lobe_energy(c: &[f32]) -> f64 {
    let z = c.iter().position(|&v| v <= 0.0).unwrap_or(c.len() / 2 + 1).min(c.len() / 2 + 1);
    1.0 + 2.0 * c[1..z.max(1)].iter().map(|&v| (v as f64).powi(2)).sum::<f64>()
}

/// Σ over `lines` lines of length `n` of each line's circular autocorrelation, via the
/// summed power spectrum. Lines are summed in fixed chunks, in order: deterministic.
fn line_autocorrelation(data: &[f64], n: usize, lines: usize) -> Vec<f64> {
    use rayon::prelude::*;
    let mut planner = FftPlanner::<f64>::new();
    let forward = planner.plan_fft_forward(n);
    let inverse = planner.plan_fft_inverse(n);
    const CHUNK: usize = 16;
    let partial: Vec<Vec<f64>> = data
        .par_chunks(n * CHUNK)
        .map(|chunk| {
            let mut power = vec![0f64; n];
            let mut buf = vec![Complex::new(0.0, 0.0); n];
            let mut scratch = vec![Complex::new(0.0, 0.0); forward.get_inplace_scratch_len()];
            for line in chunk.chunks(n) {
                buf.iter_mut().zip(line).for_each(|(b, &v)| *b = Complex::new(v, 0.0));
                forward.process_with_scratch(&mut buf, &mut scratch);
                power.iter_mut().zip(&buf).for_each(|(p, b)| *p += b.norm_sqr());
            }
            power
        })
        .collect();
    debug_assert_eq!(partial.len(), lines.div_ceil(CHUNK));
    let mut spectrum = vec![Complex::new(0.0, 0.0); n];
    for p in &partial {
        spectrum.iter_mut().zip(p).for_each(|(s, &v)| s.re += v);
    }
    inverse.process(&mut spectrum);
    spectrum.iter().map(|c| c.re / n as f64).collect()
}

/// Smallest periodic contrast of a peak, as a fraction of C's range ([`first_peak`]).
const MIN_CONTRAST: f32 = 0.05;

/// The first robust peak of a normalized periodic autocorrelation `c` (`c[0] = 1`), in
/// texels with sub-texel precision, or `None` for unpatterned input. `null_sd` is the
/// standard error of C under the random-field null hypothesis (module docs).
///
/// Searches lags P in [min_lag, n/2] (C is symmetric, `C[x] = C[n − x]`) for a local
/// maximum with C > 0 that passes two tests:
/// - it is a feature of the curve: its prominence (as in topography: height above the
///   higher of the lowest points on the way to higher ground on either side) is at least
///   `min_prominence` of C's range over [min_lag, n − min_lag];
/// - it is a repetition beyond chance: a period P makes C high at every multiple m·P and
///   low halfway between, so the mean contrast K = mean_m [C(m·P) − C((m − ½)·P)] over
///   the M multiples within n/2 is compared with its standard error under the null,
///   √2·null_sd/√M, and must reach `min_significance` of it. Using every multiple is what
///   separates a weave (a dozen peaks in a row) from a random bump on a small tile (one);
///   using contrasts, not values, keeps C that never decays (stripes along the other
///   axis hold it high at every lag) from passing. The contrast must also reach
///   MIN_CONTRAST of the range, so that in a map with no random part (null_sd = 0) a
///   rounding wiggle is no pattern. (Not more: a twill's yarn period along the twill's
///   steps shows as a partial repeat, contrast 0.14 of the range at 1024², 10σ.)
///
/// The location is refined by a parabola through the maximum and its two neighbours.
pub fn first_peak(c: &[f32], null_sd: f32, search: &PeakSearch) -> Option<f32> {
    let n = c.len();
    if n < 2 * search.min_lag.max(1) + 1 {
        return None;
    }
    let at = |k: isize| c[k.rem_euclid(n as isize) as usize];
    // C at a fractional lag, linearly interpolated, periodic.
    let lerp = |x: f64| {
        let k = x.floor();
        let f = (x - k) as f32;
        at(k as isize) * (1.0 - f) + at(k as isize + 1) * f
    };
    let tail = &c[search.min_lag..=n - search.min_lag];
    let hi = tail.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let lo = c.iter().copied().fold(f32::INFINITY, f32::min);
    let range = hi - lo;
    if !(range > 1e-6) {
        return None;
    }
    for x in search.min_lag..=n / 2 {
        let v = c[x];
        // Plateaus: a run of equal values counts once, at its first lag.
        if !(v > 0.0 && v > at(x as isize - 1) && v >= at(x as isize + 1)) {
            continue;
        }
        // Left: C[0] = 1 is the global maximum, so the left base is min C[0..x].
        let left_base = c[..x].iter().copied().fold(f32::INFINITY, f32::min);
        // Right: walk until C rises above v (C[n] = C[0] guarantees it ends).
        let mut right_base = v;
        for k in x + 1..=n {
            let w = at(k as isize);
            if w > v {
                break;
            }
            right_base = right_base.min(w);
        }
        let prominence = v - left_base.max(right_base);
        if prominence < search.min_prominence * range {
            continue;
        }
        let (l, r) = (at(x as isize - 1) as f64, at(x as isize + 1) as f64);
        let denom = l - 2.0 * v as f64 + r;
        let offset = if denom < 0.0 { (0.5 * (l - r) / denom).clamp(-0.5, 0.5) } else { 0.0 };
        let period = x as f64 + offset;
        let multiples = ((n / 2) as f64 / period).floor().max(1.0) as usize;
        let contrast = (1..=multiples).map(|m| lerp(m as f64 * period) - lerp((m as f64 - 0.5) * period)).sum::<f32>() / multiples as f32;
        let standard_error = std::f32::consts::SQRT_2 * null_sd / (multiples as f32).sqrt();
        if contrast >= search.min_significance * standard_error && contrast >= MIN_CONTRAST * range {
            return Some(period as f32);
        }
    }
    None
}

/// The filter size [x, y] from the first peaks of C0 and C1, or `None` when neither has
/// one.
pub fn filter_size(peaks: [Option<f32>; 2], rule: FilterRule) -> Option<[f32; 2]> {
    match (peaks, rule) {
        ([None, None], _) => None,
        ([Some(a), None], _) | ([None, Some(a)], _) => Some([a, a]),
        ([Some(a), Some(b)], FilterRule::PerAxis) => Some([a, b]),
        ([Some(a), Some(b)], FilterRule::Smaller) => Some([a.min(b); 2]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Direct O(n²) evaluation of Eq. 4 (after centering and normalizing).
    fn eq4_direct(h: &[f32], nx: usize, ny: usize) -> (Vec<f64>, Vec<f64>) {
        let mean = h.iter().map(|&v| v as f64).sum::<f64>() / h.len() as f64;
        let at = |i: isize, j: isize| h[i.rem_euclid(nx as isize) as usize + nx * j.rem_euclid(ny as isize) as usize] as f64 - mean;
        let c0: Vec<f64> = (0..nx as isize).map(|x| (0..ny as isize).flat_map(|j| (0..nx as isize).map(move |i| (i, j))).map(|(i, j)| at(i, j) * at(i - x, j)).sum()).collect();
        let c1: Vec<f64> = (0..ny as isize).map(|y| (0..ny as isize).flat_map(|j| (0..nx as isize).map(move |i| (i, j))).map(|(i, j)| at(i, j) * at(i, j - y)).sum()).collect();
        (c0.iter().map(|v| v / c0[0]).collect(), c1.iter().map(|v| v / c1[0]).collect())
    }

    #[test]
    fn fft_autocorrelation_equals_eq4() {
        let (nx, ny) = (24, 10);
        let h: Vec<f32> = (0..nx * ny).map(|k| ((k * 7919) % 97) as f32 * 0.1 + (k % nx) as f32 * 0.05).collect();
        let ac = autocorrelate(&h, nx, ny).unwrap();
        let (c0, c1) = eq4_direct(&h, nx, ny);
        // f32 storage of normalized values: 1e-6 absolute.
        for (a, b) in ac.c0.iter().zip(&c0).chain(ac.c1.iter().zip(&c1)) {
            assert!((*a as f64 - b).abs() < 1e-6, "{a} vs {b}");
        }
    }

    #[test]
    fn flat_map_has_no_autocorrelation() {
        assert!(autocorrelate(&[7.5; 64], 8, 8).is_none());
    }

    #[test]
    fn peak_of_a_cosine_is_its_period_and_noise_wiggles_are_not_peaks() {
        let s = PeakSearch::default();
        // Fractional period 128/6: parabolic refinement lands within 0.1 texel.
        let c: Vec<f32> = (0..128).map(|x| (std::f32::consts::TAU * x as f32 * 6.0 / 128.0).cos()).collect();
        let p = first_peak(&c, 0.01, &s).unwrap();
        assert!((p - 128.0 / 6.0).abs() < 0.1, "{p}");
        // Decaying correlation with ±2% wiggles: no peak.
        let c: Vec<f32> = (0..128)
            .map(|x| {
                let d = x.min(128 - x) as f32;
                (-d / 6.0).exp() + if x == 0 { 0.0 } else { 0.02 * (d * 1.7).sin() }
            })
            .collect();
        assert_eq!(first_peak(&c, 0.01, &s), None);
        // A period of 32 (two repeats within n/2, contrast 1.2) is significant when the
        // null standard error is 0.1 (threshold 4·√2·0.1/√2 = 0.4), not when it is 0.35.
        let c: Vec<f32> = (0..128).map(|x| 0.6 * (std::f32::consts::TAU * x as f32 * 4.0 / 128.0).cos() + if x == 0 { 0.4 } else { 0.0 }).collect();
        assert!((first_peak(&c, 0.1, &s).unwrap() - 32.0).abs() < 0.1);
        assert_eq!(first_peak(&c, 0.35, &s), None);
        // A single bump at n/2 (one "repeat") on a decayed curve needs its value alone to
        // stand out: 0.2 is not enough against 0.08 (4·√2·0.08 = 0.45).
        let c: Vec<f32> = (0..96).map(|x| {
            let d = x.min(96 - x) as f32;
            (-d / 4.0).exp() + 0.2 * (-((d - 48.0) / 6.0).powi(2)).exp()
        }).collect();
        assert_eq!(first_peak(&c, 0.08, &s), None);
        assert!(first_peak(&c, 0.02, &s).is_some());
    }

    #[test]
    fn filter_rules() {
        assert_eq!(filter_size([Some(10.0), Some(20.0)], FilterRule::PerAxis), Some([10.0, 20.0]));
        assert_eq!(filter_size([Some(10.0), Some(20.0)], FilterRule::Smaller), Some([10.0, 10.0]));
        assert_eq!(filter_size([None, Some(20.0)], FilterRule::PerAxis), Some([20.0, 20.0]));
        assert_eq!(filter_size([None, None], FilterRule::Smaller), None);
    }
}
