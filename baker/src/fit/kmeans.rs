//! k-means clustering of f32 feature vectors: k-means++ seeding and Lloyd iterations.
//!
//! Seeding is k-means++ (Arthur and Vassilvitskii, "k-means++: the advantages of careful
//! seeding", SODA 2007): the first centre is a uniformly random point, each next one is
//! drawn with probability proportional to D², the squared distance to the nearest centre
//! chosen so far. As in scikit-learn, each step draws 2 + ⌊ln k⌋ candidates and keeps the
//! one that lowers the total D² most ("greedy k-means++"), which costs a few passes more
//! and avoids most bad seeds. Lloyd's iterations (Lloyd 1957/1982) then alternate
//! assigning every point to its nearest centre (ties to the lowest index) and moving each
//! centre to the mean of its points, until no assignment changes, the inertia (sum of
//! squared distances) changes by less than `tolerance` relatively, or `max_iterations`.
//! A centre left without points is moved onto the point farthest from its own centre.
//!
//! Determinism: the result depends only on the data, k and the options, never on the
//! number of threads. Points are processed in blocks whose size depends only on n; every
//! per-point value is computed the same way wherever it runs, and every sum over points
//! (centroid sums in f64, inertia, D² totals) is accumulated sequentially within a block
//! and then over blocks in block order.

use rayon::prelude::*;

use crate::reference::rng::Rng;

/// Why a clustering cannot run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum KMeansError {
    #[error("the dimension must be at least 1")]
    ZeroDim,
    #[error("{len} values are not a whole number of {dim}-dimensional points")]
    Length { len: usize, dim: usize },
    #[error("k must be at least 1")]
    ZeroK,
    #[error("k = {k} does not fit the u32 assignment")]
    TooManyClusters { k: usize },
    #[error("{points} points cannot make {k} clusters")]
    TooFewPoints { points: usize, k: usize },
    #[error("data[{index}] is not finite")]
    NonFinite { index: usize },
    #[error("data[{index}] = {value} is larger in magnitude than {MAX_ABS:e}")]
    TooLarge { index: usize, value: f32 },
}

/// The largest |value| accepted, so that squared distances stay finite in f32 for any
/// dimension up to ~10⁷.
pub const MAX_ABS: f32 = 1e15;

/// Options of [`kmeans`].
#[derive(Debug, Clone, PartialEq)]
pub struct KMeansOptions {
    /// Seed of the k-means++ draws.
    pub seed: u64,
    /// Most Lloyd iterations (centre updates) after seeding.
    pub max_iterations: usize,
    /// Stop when |ΔI| ≤ tolerance·I for the inertia I of consecutive iterations.
    pub tolerance: f64,
}

impl Default for KMeansOptions {
    fn default() -> KMeansOptions {
        KMeansOptions { seed: 1, max_iterations: 100, tolerance: 1e-6 }
    }
}

/// A clustering.
#[derive(Debug, Clone, PartialEq)]
pub struct KMeans {
    /// k × dim, row-major.
    pub centres: Vec<f32>,
    /// Per point, the index of its nearest centre (ties to the lowest index).
    pub assignment: Vec<u32>,
    /// Σ over points of the squared distance to the assigned centre.
    pub inertia: f64,
    /// Lloyd iterations run.
    pub iterations: usize,
    /// Per centre, the number of points assigned to it. It is 0 only where fewer than k
    /// distinct points exist (identical centres: the lowest index takes the points) or
    /// the iteration limit stopped a relocation half-way.
    pub sizes: Vec<usize>,
}

/// Minimum points per block; blocks are at most [`MAX_BLOCKS`], so a per-block partial of
/// k × dim f64 sums stays affordable.
const MIN_BLOCK: usize = 1024;
const MAX_BLOCKS: usize = 64;
/// The generator's stream for k-means draws ("kmeans").
const STREAM: u64 = 0x6b6d_6561_6e73;

fn block_len(n: usize) -> usize {
    n.div_ceil(MAX_BLOCKS).max(MIN_BLOCK)
}

/// Clusters the `n = data.len() / dim` points of `data` (row-major `n × dim`) into `k`.
pub fn kmeans(data: &[f32], dim: usize, k: usize, options: &KMeansOptions) -> Result<KMeans, KMeansError> {
    if dim == 0 {
        return Err(KMeansError::ZeroDim);
    }
    if !data.len().is_multiple_of(dim) {
        return Err(KMeansError::Length { len: data.len(), dim });
    }
    if k == 0 {
        return Err(KMeansError::ZeroK);
    }
    if k > u32::MAX as usize {
        return Err(KMeansError::TooManyClusters { k });
    }
    let n = data.len() / dim;
    if n < k {
        return Err(KMeansError::TooFewPoints { points: n, k });
    }
    if let Some(index) = data.par_iter().position_first(|v| !v.is_finite() || v.abs() > MAX_ABS) {
        let value = data[index];
        return Err(if value.is_finite() { KMeansError::TooLarge { index, value } } else { KMeansError::NonFinite { index } });
    }

    let mut centres = seed(data, dim, k, options.seed);
    let mut assignment = vec![u32::MAX; n];
    // Per point, its squared distance to its centre.
    let mut dist = vec![0f32; n];
    let mut step = assign(data, dim, &centres, &mut assignment, &mut dist);
    let mut iterations = 0;
    while iterations < options.max_iterations {
        update(data, dim, &mut centres, &mut step, &mut assignment, &mut dist);
        iterations += 1;
        let previous = step.inertia;
        step = assign(data, dim, &centres, &mut assignment, &mut dist);
        // An empty cluster that a relocation can fill keeps the iterations going.
        if step.counts.contains(&0) && step.max_dist > 0.0 {
            continue;
        }
        if step.changed == 0 || (previous - step.inertia).abs() <= options.tolerance * previous {
            break;
        }
    }
    Ok(KMeans { centres, assignment, inertia: step.inertia, iterations, sizes: step.counts })
}

/// For each centre, the index of the point of its cluster nearest to it (ties to the
/// lowest index): the cluster's representative. A centre without points gets the
/// nearest point overall. Empty if `result` does not fit `data` and `dim`.
pub fn representatives(data: &[f32], dim: usize, result: &KMeans) -> Vec<usize> {
    if dim == 0 || !data.len().is_multiple_of(dim) || !result.centres.len().is_multiple_of(dim) {
        return Vec::new();
    }
    let (n, k) = (data.len() / dim, result.centres.len() / dim);
    if n == 0 || result.assignment.len() != n {
        return Vec::new();
    }
    let bl = block_len(n);
    let lanes = CentreLanes::new(&result.centres, dim);
    // Per block and centre: (nearest member, nearest point overall), as (distance, index).
    // Minimum by (distance, index) is order independent, so the combination is exact.
    let none = (f32::INFINITY, usize::MAX);
    let partials: Vec<Vec<[(f32, usize); 2]>> = data
        .par_chunks(bl * dim)
        .zip(result.assignment.par_chunks(bl))
        .enumerate()
        .map(|(b, (points, labels))| {
            let mut best = vec![[none; 2]; k];
            let mut d_all = vec![0f32; lanes.padded()];
            for (i, (x, &label)) in points.chunks_exact(dim).zip(labels).enumerate() {
                let index = b * bl + i;
                lanes.distances(x, &mut d_all);
                for (c, &d) in d_all[..k].iter().enumerate() {
                    let slot = &mut best[c];
                    if (d, index) < slot[1] {
                        slot[1] = (d, index);
                    }
                    if label as usize == c && (d, index) < slot[0] {
                        slot[0] = (d, index);
                    }
                }
            }
            best
        })
        .collect();
    (0..k)
        .map(|c| {
            let (mut member, mut any) = (none, none);
            for p in &partials {
                member = if p[c][0] < member { p[c][0] } else { member };
                any = if p[c][1] < any { p[c][1] } else { any };
            }
            if member.1 != usize::MAX { member.1 } else { any.1 }
        })
        .collect()
}

/// Centres laid out for [`CentreLanes::distances`]: groups of [`LANES`] centres, each
/// group dim × LANES (coordinate d of centre g·LANES + l at (g·dim + d)·LANES + l), the
/// last group padded with zeros.
struct CentreLanes {
    values: Vec<f32>,
    dim: usize,
}

const LANES: usize = 8;

impl CentreLanes {
    fn new(centres: &[f32], dim: usize) -> CentreLanes {
        let k = centres.len() / dim;
        let groups = k.div_ceil(LANES);
        let mut values = vec![0f32; groups * dim * LANES];
        for (c, centre) in centres.chunks_exact(dim).enumerate() {
            let (g, l) = (c / LANES, c % LANES);
            for (d, &v) in centre.iter().enumerate() {
                values[(g * dim + d) * LANES + l] = v;
            }
        }
        CentreLanes { values, dim }
    }

    /// k rounded up to a multiple of [`LANES`]: the length `distances` writes.
    fn padded(&self) -> usize {
        self.values.len() / self.dim
    }

    /// Squared distances from `x` to every centre (and to the zero padding after them),
    /// vectorized across centres: each is Σ_d (x_d − c_d)² summed in order of d, so the
    /// value of a (point, centre) pair never depends on where it is computed.
    #[inline]
    fn distances(&self, x: &[f32], out: &mut [f32]) {
        for (group, o) in self.values.chunks_exact(self.dim * LANES).zip(out.chunks_exact_mut(LANES)) {
            let mut acc = [0f32; LANES];
            for (c, &xd) in group.chunks_exact(LANES).zip(x) {
                for l in 0..LANES {
                    let e = xd - c[l];
                    acc[l] += e * e;
                }
            }
            o.copy_from_slice(&acc);
        }
    }
}

/// Squared Euclidean distance in f32, in 8 independent lanes (a fixed order the compiler
/// can vectorize, the same on every thread). Used by the seeding, which compares one
/// candidate with every point; its rounding differs from [`CentreLanes::distances`].
#[inline]
fn dist2(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0f32; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let mut tail = 0f32;
    for (x, y) in ca.remainder().iter().zip(cb.remainder()) {
        tail += (x - y) * (x - y);
    }
    for (x, y) in ca.zip(cb) {
        for l in 0..8 {
            let d = x[l] - y[l];
            acc[l] += d * d;
        }
    }
    ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7])) + tail
}

/// Uniform in [0, 1) with 53 bits.
fn uniform(rng: &mut Rng) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// Greedy k-means++: k distinct data points as long as k distinct points exist.
fn seed(data: &[f32], dim: usize, k: usize, seed: u64) -> Vec<f32> {
    let n = data.len() / dim;
    let bl = block_len(n);
    let mut rng = Rng::new(seed, STREAM, 0);
    let point = |i: usize| &data[i * dim..(i + 1) * dim];
    let mut centres = Vec::with_capacity(k * dim);
    let first = ((rng.next_u64() as u128 * n as u128) >> 64) as usize;
    centres.extend_from_slice(point(first));
    // closest[i] = D²(i); block_sums[b] = Σ of block b, summed in order. Adding a centre
    // lowers each D² to the distance to it where that is closer.
    let add_centre = |closest: &mut [f32], chosen: usize| -> Vec<f64> {
        closest
            .par_chunks_mut(bl)
            .zip(data.par_chunks(bl * dim))
            .map(|(cl, points)| {
                let mut s = 0f64;
                for (c, x) in cl.iter_mut().zip(points.chunks_exact(dim)) {
                    *c = c.min(dist2(x, point(chosen)));
                    s += *c as f64;
                }
                s
            })
            .collect()
    };
    let mut closest = vec![f32::INFINITY; n];
    let mut block_sums = add_centre(&mut closest, first);
    let trials = 2 + (k as f64).ln().floor() as usize;
    let mut candidates = Vec::with_capacity(trials);
    for _ in 1..k {
        let potential: f64 = block_sums.iter().sum();
        candidates.clear();
        for _ in 0..trials {
            let target = uniform(&mut rng) * potential;
            candidates.push(if potential > 0.0 {
                sample(&closest, &block_sums, bl, target)
            } else {
                // Every point sits on a centre (fewer distinct points than k).
                ((rng.next_u64() as u128 * n as u128) >> 64) as usize
            });
        }
        // The candidate that leaves the smallest total D², all candidates in one pass.
        let candidate_points: Vec<f32> = candidates.iter().flat_map(|&c| point(c).iter().copied()).collect();
        let lanes = CentreLanes::new(&candidate_points, dim);
        let candidate_sums: Vec<Vec<f64>> = closest
            .par_chunks(bl)
            .zip(data.par_chunks(bl * dim))
            .map(|(cl, points)| {
                let mut s = vec![0f64; trials];
                let mut d = vec![0f32; lanes.padded()];
                for (&c, x) in cl.iter().zip(points.chunks_exact(dim)) {
                    lanes.distances(x, &mut d);
                    for (s, &d) in s.iter_mut().zip(&d[..trials]) {
                        *s += d.min(c) as f64;
                    }
                }
                s
            })
            .collect();
        let mut best = 0;
        let mut best_sum = f64::INFINITY;
        for t in 0..trials {
            let total: f64 = candidate_sums.iter().map(|s| s[t]).sum();
            if total < best_sum {
                best_sum = total;
                best = t;
            }
        }
        let chosen = candidates[best];
        centres.extend_from_slice(point(chosen));
        block_sums = add_centre(&mut closest, chosen);
    }
    centres
}

/// The first point whose running D² sum exceeds `target` (< the total): a D² draw. The
/// chosen point always has D² > 0, since the running sum only grows at such points.
fn sample(closest: &[f32], block_sums: &[f64], bl: usize, target: f64) -> usize {
    let mut acc = 0.0;
    let mut last_positive = None;
    for (b, &s) in block_sums.iter().enumerate() {
        if s > 0.0 {
            last_positive = Some(b);
        }
        if acc + s > target {
            let mut run = acc;
            let mut last = None;
            for (i, &d) in closest[b * bl..(b * bl + bl).min(closest.len())].iter().enumerate() {
                if d > 0.0 {
                    run += d as f64;
                    last = Some(b * bl + i);
                    if run > target {
                        return b * bl + i;
                    }
                }
            }
            // Round-off: the block's running sum fell short of its total.
            if let Some(i) = last {
                return i;
            }
        }
        acc += s;
    }
    // Round-off at the very end: the last point with D² > 0.
    let b = last_positive.unwrap_or(0);
    let start = b * bl;
    let end = (start + bl).min(closest.len());
    (start..end).rev().find(|&i| closest[i] > 0.0).unwrap_or(start)
}

/// The outcome of an assignment pass.
struct Step {
    /// k × dim sums of the points of each centre.
    sums: Vec<f64>,
    counts: Vec<usize>,
    inertia: f64,
    /// Points whose centre changed.
    changed: usize,
    /// The largest distance of a point to its centre.
    max_dist: f32,
}

/// Assigns every point to its nearest centre, recording its squared distance.
fn assign(data: &[f32], dim: usize, centres: &[f32], assignment: &mut [u32], dist: &mut [f32]) -> Step {
    let k = centres.len() / dim;
    let bl = block_len(assignment.len());
    let lanes = CentreLanes::new(centres, dim);
    let partials: Vec<Step> = data
        .par_chunks(bl * dim)
        .zip(assignment.par_chunks_mut(bl))
        .zip(dist.par_chunks_mut(bl))
        .map(|((points, labels), dists)| {
            let mut s = Step { sums: vec![0.0; k * dim], counts: vec![0; k], inertia: 0.0, changed: 0, max_dist: 0.0 };
            let mut d_all = vec![0f32; lanes.padded()];
            for ((x, label), d_out) in points.chunks_exact(dim).zip(labels.iter_mut()).zip(dists.iter_mut()) {
                lanes.distances(x, &mut d_all);
                let mut best = f32::INFINITY;
                let mut bi = 0;
                // Strict <: ties go to the lowest index.
                for (c, &d) in d_all[..k].iter().enumerate() {
                    if d < best {
                        best = d;
                        bi = c;
                    }
                }
                if *label != bi as u32 {
                    s.changed += 1;
                    *label = bi as u32;
                }
                *d_out = best;
                s.inertia += best as f64;
                s.max_dist = s.max_dist.max(best);
                s.counts[bi] += 1;
                for (acc, &v) in s.sums[bi * dim..(bi + 1) * dim].iter_mut().zip(x) {
                    *acc += v as f64;
                }
            }
            s
        })
        .collect();
    let mut total = Step { sums: vec![0.0; k * dim], counts: vec![0; k], inertia: 0.0, changed: 0, max_dist: 0.0 };
    for p in partials {
        for (a, v) in total.sums.iter_mut().zip(&p.sums) {
            *a += v;
        }
        for (a, v) in total.counts.iter_mut().zip(&p.counts) {
            *a += v;
        }
        total.inertia += p.inertia;
        total.changed += p.changed;
        total.max_dist = total.max_dist.max(p.max_dist);
    }
    total
}

/// Moves each centre to the mean of its points. An empty cluster first takes the point
/// farthest from its own centre (ties to the lowest index) out of a cluster that keeps at
/// least one point; if every point sits on its centre the empty centre stays put.
fn update(data: &[f32], dim: usize, centres: &mut [f32], step: &mut Step, assignment: &mut [u32], dist: &mut [f32]) {
    let k = step.counts.len();
    for c in 0..k {
        if step.counts[c] != 0 {
            continue;
        }
        let mut far: Option<(f32, usize)> = None;
        for (i, &d) in dist.iter().enumerate() {
            if d > 0.0 && step.counts[assignment[i] as usize] > 1 && far.is_none_or(|(fd, _)| d > fd) {
                far = Some((d, i));
            }
        }
        let Some((_, p)) = far else { break };
        let x = &data[p * dim..(p + 1) * dim];
        let old = assignment[p] as usize;
        for (s, &v) in step.sums[old * dim..(old + 1) * dim].iter_mut().zip(x) {
            *s -= v as f64;
        }
        step.counts[old] -= 1;
        for (s, &v) in step.sums[c * dim..(c + 1) * dim].iter_mut().zip(x) {
            *s = v as f64;
        }
        step.counts[c] = 1;
        assignment[p] = c as u32;
        // It now sits on its centre, so it is not taken twice.
        dist[p] = 0.0;
    }
    for c in 0..k {
        if step.counts[c] > 0 {
            let inv = 1.0 / step.counts[c] as f64;
            for (out, s) in centres[c * dim..(c + 1) * dim].iter_mut().zip(&step.sums[c * dim..(c + 1) * dim]) {
                *out = (s * inv) as f32;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Approximately normal variates (sum of 4 uniforms, variance 1).
    fn gauss(rng: &mut Rng) -> f32 {
        (rng.next_f32() + rng.next_f32() + rng.next_f32() + rng.next_f32() - 2.0) * 3f32.sqrt()
    }

    /// `blobs` well-separated clusters of `per` points in `dim` dimensions, spread `sd`,
    /// points interleaved (label i % blobs); returns the data and the true labels.
    fn blobs(blobs: usize, per: usize, dim: usize, sd: f32, seed: u64) -> (Vec<f32>, Vec<usize>) {
        let mut rng = Rng::new(seed, 1, 0);
        let means: Vec<f32> = (0..blobs * dim).map(|_| rng.next_f32() * 100.0 - 50.0).collect();
        let mut data = Vec::with_capacity(blobs * per * dim);
        let mut labels = Vec::with_capacity(blobs * per);
        for i in 0..blobs * per {
            let b = i % blobs;
            labels.push(b);
            for d in 0..dim {
                data.push(means[b * dim + d] + sd * gauss(&mut rng));
            }
        }
        (data, labels)
    }

    /// Whether `a` equals `truth` up to a relabeling (a bijection of the labels).
    fn same_partition(a: &[u32], truth: &[usize], k: usize) -> bool {
        let mut map = vec![None; k];
        let mut used = vec![false; k];
        for (&x, &t) in a.iter().zip(truth) {
            match map[t] {
                None => {
                    if used[x as usize] {
                        return false;
                    }
                    used[x as usize] = true;
                    map[t] = Some(x);
                }
                Some(m) if m != x => return false,
                _ => {}
            }
        }
        true
    }

    /// Squared distances from `x` to each centre, as the assignment computes them.
    fn distances(x: &[f32], centres: &[f32], dim: usize) -> Vec<f32> {
        let lanes = CentreLanes::new(centres, dim);
        let mut d = vec![0f32; lanes.padded()];
        lanes.distances(x, &mut d);
        d.truncate(centres.len() / dim);
        d
    }

    #[test]
    fn distance_kernels_agree() {
        // Against a plain f64 sum, for dimensions around the lane width and k not a
        // multiple of it.
        let mut rng = Rng::new(3, 0, 0);
        for dim in [1, 3, 7, 8, 9, 16, 17, 60] {
            let centres: Vec<f32> = (0..11 * dim).map(|_| rng.next_f32() * 4.0 - 2.0).collect();
            let x: Vec<f32> = (0..dim).map(|_| rng.next_f32()).collect();
            let d = distances(&x, &centres, dim);
            assert_eq!(d.len(), 11);
            for (c, centre) in centres.chunks_exact(dim).enumerate() {
                let exact: f64 = x.iter().zip(centre).map(|(a, b)| (*a as f64 - *b as f64).powi(2)).sum();
                assert!((d[c] as f64 - exact).abs() <= 1e-5 * exact, "dim {dim} centre {c}");
                assert!((dist2(&x, centre) as f64 - exact).abs() <= 1e-5 * exact);
            }
        }
    }

    fn check_valid(data: &[f32], dim: usize, r: &KMeans) {
        let k = r.centres.len() / dim;
        assert_eq!(r.sizes.len(), k);
        assert_eq!(r.sizes.iter().sum::<usize>(), r.assignment.len());
        let mut inertia = 0f64;
        for (i, x) in data.chunks_exact(dim).enumerate() {
            let d = distances(x, &r.centres, dim);
            let a = r.assignment[i] as usize;
            assert!(d.iter().enumerate().all(|(c, &dc)| dc > d[a] || (dc == d[a] && c >= a)), "point {i} not at its nearest centre");
            inertia += d[a] as f64;
        }
        assert!((inertia - r.inertia).abs() <= 1e-9 * (1.0 + inertia));
        assert!(r.centres.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn well_separated_blobs_are_recovered() {
        let (data, truth) = blobs(5, 200, 8, 1.0, 3);
        for seed in 1..6 {
            let r = kmeans(&data, 8, 5, &KMeansOptions { seed, ..KMeansOptions::default() }).unwrap();
            assert!(same_partition(&r.assignment, &truth, 5), "seed {seed}");
            assert_eq!(r.sizes, vec![200; 5]);
            check_valid(&data, 8, &r);
            // The representatives belong to their own clusters.
            let reps = representatives(&data, 8, &r);
            assert_eq!(reps.len(), 5);
            for (c, &p) in reps.iter().enumerate() {
                assert_eq!(r.assignment[p] as usize, c);
                // And nothing in the cluster is nearer.
                let dp = distances(&data[p * 8..p * 8 + 8], &r.centres, 8)[c];
                for (i, x) in data.chunks_exact(8).enumerate() {
                    if r.assignment[i] as usize == c {
                        assert!(distances(x, &r.centres, 8)[c] >= dp);
                    }
                }
            }
        }
    }

    #[test]
    fn deterministic_across_seeds_and_thread_counts() {
        let (data, _) = blobs(12, 2000, 20, 8.0, 7);
        let run = |threads: usize, seed: u64| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| kmeans(&data, 20, 16, &KMeansOptions { seed, max_iterations: 30, ..KMeansOptions::default() }).unwrap())
        };
        let bits = |r: &KMeans| (r.centres.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), r.inertia.to_bits());
        for seed in [1, 2] {
            let a = run(1, seed);
            let b = run(2, seed);
            let c = run(3, seed);
            assert_eq!(a.assignment, b.assignment);
            assert_eq!(bits(&a), bits(&b));
            assert_eq!(a.iterations, b.iterations);
            assert_eq!(a.assignment, c.assignment);
            assert_eq!(bits(&a), bits(&c));
            let reps = |threads: usize| rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(|| representatives(&data, 20, &a));
            assert_eq!(reps(1), reps(2));
            // Same seed, same answer, run again.
            assert_eq!(bits(&a), bits(&run(2, seed)));
            check_valid(&data, 20, &a);
        }
        // Different seeds seed differently.
        assert_ne!(bits(&run(2, 1)).0, bits(&run(2, 99)).0);
    }

    #[test]
    fn k_equal_to_n_gives_zero_inertia() {
        let mut rng = Rng::new(5, 0, 0);
        let data: Vec<f32> = (0..50 * 3).map(|_| rng.next_f32()).collect();
        let r = kmeans(&data, 3, 50, &KMeansOptions::default()).unwrap();
        assert_eq!(r.inertia, 0.0);
        assert_eq!(r.sizes, vec![1; 50]);
        let mut a = r.assignment.clone();
        a.sort();
        assert_eq!(a, (0..50).collect::<Vec<u32>>());
        let reps = representatives(&data, 3, &r);
        for (c, &p) in reps.iter().enumerate() {
            assert_eq!(r.assignment[p] as usize, c);
        }
    }

    #[test]
    fn duplicate_points() {
        // Three distinct values, each many times, k = 3: one cluster each, zero inertia.
        let values = [[0.0f32, 0.0], [5.0, 1.0], [-3.0, 7.0]];
        let data: Vec<f32> = (0..300).flat_map(|i| values[(i * 7) % 3]).collect();
        let r = kmeans(&data, 2, 3, &KMeansOptions::default()).unwrap();
        assert_eq!(r.inertia, 0.0);
        assert_eq!(r.sizes, vec![100; 3]);
        check_valid(&data, 2, &r);
        // Fewer distinct points than k: identical centres are allowed, assignments stay
        // valid (lowest index of equal centres), some clusters are empty.
        let r = kmeans(&data, 2, 5, &KMeansOptions::default()).unwrap();
        assert_eq!(r.inertia, 0.0);
        check_valid(&data, 2, &r);
        assert_eq!(r.sizes.iter().filter(|&&s| s > 0).count(), 3);
        let reps = representatives(&data, 2, &r);
        assert_eq!(reps.len(), 5);
        for (c, &p) in reps.iter().enumerate() {
            assert_eq!(&data[p * 2..p * 2 + 2], &r.centres[c * 2..c * 2 + 2]);
        }
        // All points identical.
        let same = vec![1.5f32; 40];
        let r = kmeans(&same, 4, 3, &KMeansOptions::default()).unwrap();
        assert_eq!(r.inertia, 0.0);
        assert_eq!(r.sizes, vec![10, 0, 0]);
        assert_eq!(r.centres, vec![1.5; 12]);
    }

    #[test]
    fn empty_clusters_are_refilled() {
        // Two tight groups far apart plus one far outlier; k = 3 must give the outlier its
        // own cluster whatever the seed.
        let mut data = Vec::new();
        for i in 0..100 {
            data.extend_from_slice(&[(i % 10) as f32 * 0.01, 0.0]);
            data.extend_from_slice(&[10.0 + (i % 10) as f32 * 0.01, 0.0]);
        }
        data.extend_from_slice(&[1000.0, 1000.0]);
        for seed in 0..10 {
            let r = kmeans(&data, 2, 3, &KMeansOptions { seed, ..KMeansOptions::default() }).unwrap();
            assert!(r.sizes.iter().all(|&s| s > 0), "seed {seed}: {:?}", r.sizes);
            assert!(r.sizes.contains(&1));
            check_valid(&data, 2, &r);
        }
        // Direct: a centre far from everything loses all its points, then gets one back.
        let data: Vec<f32> = (0..40).map(|i| (i / 2) as f32).collect(); // 20 points in 2-D
        let mut centres = vec![0.0, 0.0, 1e6, 1e6];
        let mut assignment = vec![u32::MAX; 20];
        let mut dist = vec![0.0; 20];
        let mut step = assign(&data, 2, &centres, &mut assignment, &mut dist);
        assert_eq!(step.counts, vec![20, 0]);
        update(&data, 2, &mut centres, &mut step, &mut assignment, &mut dist);
        assert_eq!(step.counts, vec![19, 1]);
        assert_eq!(&centres[2..], &data[38..40]);
    }

    #[test]
    fn bad_input_is_an_error() {
        let o = KMeansOptions::default();
        assert_eq!(kmeans(&[1.0; 6], 0, 1, &o), Err(KMeansError::ZeroDim));
        assert_eq!(kmeans(&[1.0; 7], 2, 1, &o), Err(KMeansError::Length { len: 7, dim: 2 }));
        assert_eq!(kmeans(&[1.0; 6], 2, 0, &o), Err(KMeansError::ZeroK));
        assert_eq!(kmeans(&[1.0; 6], 2, 4, &o), Err(KMeansError::TooFewPoints { points: 3, k: 4 }));
        assert_eq!(kmeans(&[], 2, 1, &o), Err(KMeansError::TooFewPoints { points: 0, k: 1 }));
        assert_eq!(kmeans(&[1.0, 2.0, f32::NAN, 0.0], 2, 1, &o), Err(KMeansError::NonFinite { index: 2 }));
        assert_eq!(kmeans(&[1.0, f32::NEG_INFINITY], 1, 1, &o), Err(KMeansError::NonFinite { index: 1 }));
        assert_eq!(kmeans(&[1.0, 1e30], 1, 1, &o), Err(KMeansError::TooLarge { index: 1, value: 1e30 }));
        // Mismatched result: no panic.
        let r = kmeans(&[1.0, 2.0, 3.0, 4.0], 2, 1, &o).unwrap();
        assert!(representatives(&[1.0, 2.0, 3.0], 2, &r).is_empty());
        assert!(representatives(&[1.0; 6], 2, &r).is_empty());
        assert!(representatives(&[1.0; 4], 0, &r).is_empty());
        assert_eq!(representatives(&[1.0, 2.0, 3.0, 4.0], 2, &r).len(), 1);
        // Zero iterations: the seeding, assigned.
        let (data, _) = blobs(3, 50, 4, 0.5, 1);
        let r = kmeans(&data, 4, 3, &KMeansOptions { max_iterations: 0, ..o }).unwrap();
        assert_eq!(r.iterations, 0);
        check_valid(&data, 4, &r);
    }

    #[test]
    fn scale_smoke_test() {
        // 200 000 points in 16-D, 32 blobs of varying spread: finishes, stays valid.
        let (n, dim, k) = (200_000, 16, 32);
        let (data, _) = blobs(k, n / k, dim, 6.0, 11);
        let r = kmeans(&data, dim, k, &KMeansOptions { max_iterations: 30, ..KMeansOptions::default() }).unwrap();
        assert_eq!(r.assignment.len(), n);
        assert!(r.sizes.iter().all(|&s| s > 0));
        assert_eq!(r.sizes.iter().sum::<usize>(), n);
        assert!(r.inertia.is_finite() && r.inertia > 0.0);
        // Mean squared distance near the blobs' variance (16 × 6²), far below spread-out.
        let per_point = r.inertia / n as f64;
        assert!(per_point < 2.0 * (dim as f64) * 36.0, "{per_point}");
        let reps = representatives(&data, dim, &r);
        assert!(reps.iter().enumerate().all(|(c, &p)| r.assignment[p] as usize == c));
    }
}
