//! Non-negative least squares: minimize ‖A x − b‖² subject to x ≥ 0.
//!
//! The active-set algorithm of Lawson and Hanson ("Solving Least Squares Problems",
//! 1974, ch. 23, algorithm NNLS). Variables are split into a passive set P (free, x > 0)
//! and a zero set Z (x = 0, held at the bound). Each outer iteration moves into P the
//! variable of Z whose gradient w = Aᵀ(b − A x) is largest, solves the unconstrained
//! least-squares problem on P, and, while that solution has non-positive entries, steps
//! from x towards it as far as feasibility allows and drops the variables that hit zero.
//! It ends when no variable of Z has a positive gradient: the Kuhn–Tucker conditions.
//!
//! Two front ends share the active-set driver and differ in how they solve the
//! subproblem on P:
//! - [`nnls`] takes A and b and solves each subproblem by Householder QR of the passive
//!   columns, as Lawson and Hanson do (accurate for ill-conditioned A).
//! - [`nnls_gram`] takes only AᵀA, Aᵀb and bᵀb and solves each subproblem by Cholesky
//!   of the passive block of AᵀA. It is the hot path of the BRDF fit (many tiny problems,
//!   n = 2..9), so it allocates only a few vectors of length n and n².
//!
//! Dependent columns (an all-zero column, a duplicate, one in the span of the passive
//! ones) are rejected when they would enter P, as in Lawson and Hanson's step 6; if
//! round-off makes a passive column look dependent later, the subproblem drops it
//! (its entry is 0, which the feasibility step then removes from P), so every answer
//! is finite with x ≥ 0.

/// Why an NNLS problem cannot be solved.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NnlsError {
    #[error("{what} has {got} entries, expected {expected}")]
    Shape { what: &'static str, expected: usize, got: usize },
    #[error("{what}[{index}] is not finite")]
    NonFinite { what: &'static str, index: usize },
    #[error("upper[{index}] = {value}: an upper bound must be ≥ 0 (infinity for none)")]
    BadBound { index: usize, value: f64 },
}

/// A solution of an NNLS problem.
#[derive(Debug, Clone, PartialEq)]
pub struct Nnls {
    /// The minimizer, every entry ≥ 0.
    pub x: Vec<f64>,
    /// ‖A x − b‖², ≥ 0 (clamped at 0 where round-off would make it negative).
    pub residual2: f64,
    /// Outer iterations (variables moved into the passive set).
    pub iterations: usize,
}

/// A column whose component orthogonal to the passive columns is below this fraction of
/// its norm counts as dependent (QR: the ratio itself; Cholesky: its square, since the
/// Gram matrix squares the condition number).
const DEPENDENT_QR: f64 = 1e-10;
const DEPENDENT_GRAM: f64 = 1e-12;

/// Solves min ‖A x − b‖² s.t. x ≥ 0 for a row-major `rows × cols` matrix `a`.
///
/// `residual2` is computed from A x − b directly. `cols = 0` gives an empty x.
pub fn nnls(a: &[f64], rows: usize, cols: usize, b: &[f64]) -> Result<Nnls, NnlsError> {
    check_shape("A", a.len(), rows.saturating_mul(cols))?;
    check_shape("b", b.len(), rows)?;
    check_finite("A", a)?;
    check_finite("b", b)?;
    let mut sub = Dense::new(a, rows, cols, b);
    let (x, iterations) = active_set(&mut sub);
    let residual2: f64 = (0..rows)
        .map(|r| {
            let ax: f64 = a[r * cols..(r + 1) * cols].iter().zip(&x).map(|(a, x)| a * x).sum();
            (ax - b[r]) * (ax - b[r])
        })
        .sum();
    Ok(Nnls { x, residual2: finite_nonneg(residual2), iterations })
}

/// The same problem given only the Gram matrix `ata` = AᵀA (`n × n`, row-major,
/// symmetric positive semi-definite), `atb` = Aᵀb and `btb` = bᵀb.
///
/// `residual2` = bᵀb − 2 xᵀAᵀb + xᵀAᵀA x, clamped at 0: it loses the digits that
/// cancel, so it is accurate to about ε·bᵀb, not relative to a tiny residual.
pub fn nnls_gram(ata: &[f64], atb: &[f64], btb: f64, n: usize) -> Result<Nnls, NnlsError> {
    check_shape("AᵀA", ata.len(), n.saturating_mul(n))?;
    check_shape("Aᵀb", atb.len(), n)?;
    check_finite("AᵀA", ata)?;
    check_finite("Aᵀb", atb)?;
    check_finite("bᵀb", &[btb])?;
    let mut sub = Gram::new(ata, atb, n);
    let (x, iterations) = active_set(&mut sub);
    let mut quad = 0.0;
    for i in 0..n {
        let gx: f64 = ata[i * n..(i + 1) * n].iter().zip(&x).map(|(g, x)| g * x).sum();
        quad += x[i] * (gx - 2.0 * atb[i]);
    }
    Ok(Nnls { x, residual2: finite_nonneg(btb + quad), iterations })
}

/// [`nnls_gram`] with upper bounds: min ‖A x − b‖² subject to 0 ≤ x ≤ `upper`
/// (`f64::INFINITY` for none). Each round solves the NNLS of the variables not yet held,
/// then holds at its bound the one that exceeds it most (relative to the bound) and
/// moves its columns to the right-hand side: at most n + 1 solves. A held variable is
/// not released again, so this is the exact optimum only when no held variable would
/// rather sit below its bound once the others are held — true of the BRDF fit's few,
/// positively correlated columns, and the result is feasible in every case.
pub fn nnls_gram_capped(ata: &[f64], atb: &[f64], btb: f64, n: usize, upper: &[f64]) -> Result<Nnls, NnlsError> {
    check_shape("upper", upper.len(), n)?;
    if let Some(index) = upper.iter().position(|u| !(*u >= 0.0)) {
        return Err(NnlsError::BadBound { index, value: upper[index] });
    }
    let mut held: Vec<Option<f64>> = vec![None; n];
    let mut iterations = 0;
    loop {
        let free: Vec<usize> = (0..n).filter(|&i| held[i].is_none()).collect();
        let m = free.len();
        // The reduced problem: b' = b − A_h u_h, so A_fᵀb' = A_fᵀb − A_fᵀA_h u_h and
        // b'ᵀb' = bᵀb − 2 u_hᵀA_hᵀb + u_hᵀA_hᵀA_h u_h.
        let u = |i: usize| held[i].unwrap_or(0.0);
        let mut sub_ata = vec![0.0; m * m];
        let mut sub_atb = vec![0.0; m];
        for (r, &i) in free.iter().enumerate() {
            for (c, &j) in free.iter().enumerate() {
                sub_ata[r * m + c] = ata[i * n + j];
            }
            sub_atb[r] = atb[i] - (0..n).map(|j| ata[i * n + j] * u(j)).sum::<f64>();
        }
        let mut sub_btb = btb;
        for i in 0..n {
            sub_btb += u(i) * ((0..n).map(|j| ata[i * n + j] * u(j)).sum::<f64>() - 2.0 * atb[i]);
        }
        let sol = nnls_gram(&sub_ata, &sub_atb, finite_nonneg(sub_btb), m)?;
        iterations += sol.iterations;
        let mut x: Vec<f64> = (0..n).map(u).collect();
        for (r, &i) in free.iter().enumerate() {
            x[i] = sol.x[r];
        }
        let worst = free.iter().copied().filter(|&i| x[i] > upper[i]).max_by(|&a, &b| (x[a] / upper[a]).total_cmp(&(x[b] / upper[b])));
        match worst {
            Some(i) => held[i] = Some(upper[i]),
            None => return Ok(Nnls { x, residual2: sol.residual2, iterations }),
        }
    }
}

fn check_shape(what: &'static str, got: usize, expected: usize) -> Result<(), NnlsError> {
    if got == expected { Ok(()) } else { Err(NnlsError::Shape { what, expected, got }) }
}

fn check_finite(what: &'static str, v: &[f64]) -> Result<(), NnlsError> {
    match v.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(NnlsError::NonFinite { what, index }),
        None => Ok(()),
    }
}

/// Clamps at 0 and maps a (theoretically impossible) overflow to f64::MAX.
fn finite_nonneg(v: f64) -> f64 {
    if v.is_nan() || v < 0.0 { 0.0 } else { v.min(f64::MAX) }
}

/// The two operations the active-set driver needs from a problem representation.
trait Subproblem {
    fn n(&self) -> usize;
    /// Writes w = Aᵀ(b − A x) and returns a round-off bound for its entries: a variable
    /// only enters P if its gradient exceeds it.
    fn gradient(&mut self, x: &[f64], w: &mut [f64]) -> f64;
    /// The least-squares solution restricted to the columns `p` (in that order), written
    /// to `s[..p.len()]`; a dependent column gets 0.
    fn solve(&mut self, p: &[usize], s: &mut [f64]);
}

#[derive(Clone, Copy, PartialEq)]
enum State {
    Zero,
    Passive,
    /// In Z and not to be tried again until x changes: it was rejected as dependent, or
    /// its positive gradient was round-off (its subproblem entry came out ≤ 0).
    Blocked,
}

/// Lawson–Hanson NNLS on any subproblem representation. Returns x (≥ 0) and the number
/// of outer iterations; stops at 3n + 30 of them with the current feasible x.
fn active_set<S: Subproblem>(sub: &mut S) -> (Vec<f64>, usize) {
    let n = sub.n();
    let mut x = vec![0.0; n];
    let mut w = vec![0.0; n];
    let mut s = vec![0.0; n];
    let mut passive: Vec<usize> = Vec::with_capacity(n);
    let mut state = vec![State::Zero; n];
    let max_outer = 3 * n + 30;
    let mut iterations = 0;
    let mut tol = sub.gradient(&x, &mut w);
    'outer: while iterations < max_outer {
        // The variable of Z with the largest positive gradient enters P.
        let mut entering = None;
        let mut best = tol;
        for i in 0..n {
            if state[i] == State::Zero && w[i] > best {
                best = w[i];
                entering = Some(i);
            }
        }
        let Some(j) = entering else { break };
        iterations += 1;
        passive.push(j);
        state[j] = State::Passive;
        let mut first = true;
        loop {
            let m = passive.len();
            sub.solve(&passive, &mut s[..m]);
            if first && s[m - 1] <= 0.0 {
                // With w_j > 0 the new entry is positive in exact arithmetic: j is
                // dependent on P or its gradient was round-off. Leave x as it was.
                passive.pop();
                state[j] = State::Blocked;
                continue 'outer;
            }
            first = false;
            if s[..m].iter().all(|&v| v > 0.0) {
                for (k, &i) in passive.iter().enumerate() {
                    x[i] = s[k];
                }
                break;
            }
            // Step from x towards s as far as x stays ≥ 0; α ∈ [0, 1] because every
            // passive x_i > 0 here (the entering one has s > 0 so it is not a limit).
            let mut alpha = f64::INFINITY;
            let mut limit = 0;
            for (k, &i) in passive.iter().enumerate() {
                if s[k] <= 0.0 {
                    let a = x[i] / (x[i] - s[k]);
                    if a < alpha {
                        alpha = a;
                        limit = k;
                    }
                }
            }
            for (k, &i) in passive.iter().enumerate() {
                x[i] += alpha * (s[k] - x[i]);
            }
            // The limiting variable leaves P exactly at 0 (guaranteeing progress), and
            // so does any other that round-off left at or below 0.
            x[passive[limit]] = 0.0;
            passive.retain(|&i| {
                if x[i] > 0.0 {
                    true
                } else {
                    x[i] = 0.0;
                    state[i] = State::Zero;
                    false
                }
            });
            if passive.is_empty() {
                break;
            }
        }
        // x changed, so earlier rejections may no longer apply.
        for st in state.iter_mut() {
            if *st == State::Blocked {
                *st = State::Zero;
            }
        }
        tol = sub.gradient(&x, &mut w);
    }
    for v in x.iter_mut() {
        *v = v.max(0.0);
    }
    (x, iterations)
}

/// A and b: Householder QR of the passive columns.
struct Dense<'a> {
    a: &'a [f64],
    rows: usize,
    cols: usize,
    b: &'a [f64],
    col_norm: Vec<f64>,
    b_norm: f64,
    /// rows × |P|, column-major: the passive columns, overwritten by R and the reflectors.
    qr: Vec<f64>,
    qtb: Vec<f64>,
    residual: Vec<f64>,
}

impl<'a> Dense<'a> {
    fn new(a: &'a [f64], rows: usize, cols: usize, b: &'a [f64]) -> Dense<'a> {
        let col_norm = (0..cols).map(|j| (0..rows).map(|r| a[r * cols + j] * a[r * cols + j]).sum::<f64>().sqrt()).collect();
        let b_norm = b.iter().map(|v| v * v).sum::<f64>().sqrt();
        Dense { a, rows, cols, b, col_norm, b_norm, qr: Vec::new(), qtb: vec![0.0; rows], residual: vec![0.0; rows] }
    }
}

impl Subproblem for Dense<'_> {
    fn n(&self) -> usize {
        self.cols
    }

    fn gradient(&mut self, x: &[f64], w: &mut [f64]) -> f64 {
        let (rows, cols) = (self.rows, self.cols);
        for r in 0..rows {
            let row = &self.a[r * cols..(r + 1) * cols];
            self.residual[r] = self.b[r] - row.iter().zip(x).map(|(a, x)| a * x).sum::<f64>();
        }
        for (j, wj) in w.iter_mut().enumerate() {
            *wj = (0..rows).map(|r| self.a[r * cols + j] * self.residual[r]).sum();
        }
        // |error of w_j| ≲ (rows + n)·ε·‖a_j‖·(‖b‖ + Σ‖a_i‖x_i).
        let ax_bound: f64 = x.iter().zip(&self.col_norm).map(|(x, c)| x * c).sum();
        let max_norm = self.col_norm.iter().fold(0.0f64, |m, &c| m.max(c));
        10.0 * f64::EPSILON * (rows + cols) as f64 * max_norm * (self.b_norm + ax_bound)
    }

    fn solve(&mut self, p: &[usize], s: &mut [f64]) {
        let (rows, cols, m) = (self.rows, self.cols, p.len());
        self.qr.clear();
        for &j in p {
            self.qr.extend((0..rows).map(|r| self.a[r * cols + j]));
        }
        self.qtb.copy_from_slice(self.b);
        // pivots[k] = (row of R_kk, R_kk, β of its reflector), None for a dropped column.
        let mut pivots: Vec<Option<(usize, f64, f64)>> = Vec::with_capacity(m);
        let mut next_row = 0;
        for (k, &j) in p.iter().enumerate() {
            // Apply the earlier reflectors to column k.
            for (i, piv) in pivots.iter().enumerate() {
                if let Some((r0, _, beta)) = *piv {
                    let (left, right) = self.qr.split_at_mut(k * rows);
                    let v = &left[i * rows + r0..(i + 1) * rows];
                    let c = &mut right[r0..rows];
                    let dot: f64 = v.iter().zip(c.iter()).map(|(v, c)| v * c).sum();
                    for (c, v) in c.iter_mut().zip(v) {
                        *c -= beta * dot * v;
                    }
                }
            }
            let col = &mut self.qr[k * rows..(k + 1) * rows];
            let norm = if next_row < rows { col[next_row..].iter().map(|v| v * v).sum::<f64>().sqrt() } else { 0.0 };
            if !norm.is_finite() || norm <= DEPENDENT_QR * self.col_norm[j] {
                pivots.push(None);
                continue;
            }
            // Householder vector v = x − α e₁ with α = −sign(x₀)‖x‖ (no cancellation).
            let alpha = if col[next_row] > 0.0 { -norm } else { norm };
            col[next_row] -= alpha;
            let v2: f64 = col[next_row..].iter().map(|v| v * v).sum();
            let beta = 2.0 / v2;
            let v = &col[next_row..];
            let dot: f64 = v.iter().zip(&self.qtb[next_row..]).map(|(v, c)| v * c).sum();
            for (c, v) in self.qtb[next_row..].iter_mut().zip(v) {
                *c -= beta * dot * v;
            }
            pivots.push(Some((next_row, alpha, beta)));
            next_row += 1;
        }
        // Back substitution R s = Qᵀb over the independent columns; R[r_k, c] sits in
        // column c at row r_k (above that column's own reflector).
        for k in (0..m).rev() {
            s[k] = 0.0;
            if let Some((r0, rkk, _)) = pivots[k] {
                let mut v = self.qtb[r0];
                for c in k + 1..m {
                    if pivots[c].is_some() {
                        v -= self.qr[c * rows + r0] * s[c];
                    }
                }
                let sk = v / rkk;
                s[k] = if sk.is_finite() { sk } else { 0.0 };
            }
        }
    }
}

/// AᵀA, Aᵀb: Cholesky of the passive block.
struct Gram<'a> {
    ata: &'a [f64],
    atb: &'a [f64],
    n: usize,
    /// |P| × |P| row-major lower factor (row stride n).
    l: Vec<f64>,
    y: Vec<f64>,
    dropped: Vec<bool>,
}

impl<'a> Gram<'a> {
    fn new(ata: &'a [f64], atb: &'a [f64], n: usize) -> Gram<'a> {
        Gram { ata, atb, n, l: vec![0.0; n * n], y: vec![0.0; n], dropped: vec![false; n] }
    }
}

impl Subproblem for Gram<'_> {
    fn n(&self) -> usize {
        self.n
    }

    fn gradient(&mut self, x: &[f64], w: &mut [f64]) -> f64 {
        let n = self.n;
        let mut scale = 0.0f64;
        for ((wi, row), &atb) in w.iter_mut().zip(self.ata.chunks_exact(n.max(1))).zip(self.atb) {
            let gx: f64 = row.iter().zip(x).map(|(g, x)| g * x).sum();
            let mag: f64 = row.iter().zip(x).map(|(g, x)| (g * x).abs()).sum();
            *wi = atb - gx;
            scale = scale.max(atb.abs() + mag);
        }
        // |error of w_i| ≲ (n + 1)·ε·(|Aᵀb|_i + Σ_j |G_ij x_j|).
        10.0 * f64::EPSILON * (n + 1) as f64 * scale
    }

    fn solve(&mut self, p: &[usize], s: &mut [f64]) {
        let (n, m) = (self.n, p.len());
        let (g, l) = (self.ata, &mut self.l);
        // Cholesky G_PP = L Lᵀ row by row; a pivot that is not a clear fraction of its
        // diagonal means that column is (numerically) in the span of the earlier ones:
        // drop it (its row and column of L are zero, its entry of s is 0).
        for k in 0..m {
            let gk = p[k];
            let diag = g[gk * n + gk];
            let mut d = diag;
            for i in 0..k {
                let mut v = 0.0;
                if !self.dropped[i] {
                    v = g[gk * n + p[i]];
                    for t in 0..i {
                        v -= l[k * n + t] * l[i * n + t];
                    }
                    v /= l[i * n + i];
                    d -= v * v;
                }
                l[k * n + i] = v;
            }
            let ok = diag > 0.0 && d > DEPENDENT_GRAM * diag && d.is_finite();
            self.dropped[k] = !ok;
            if ok {
                l[k * n + k] = d.sqrt();
            } else {
                l[k * n..k * n + k + 1].fill(0.0);
            }
        }
        // L y = (Aᵀb)_P, then Lᵀ s = y.
        for k in 0..m {
            self.y[k] = 0.0;
            if !self.dropped[k] {
                let mut v = self.atb[p[k]];
                for i in 0..k {
                    v -= l[k * n + i] * self.y[i];
                }
                self.y[k] = v / l[k * n + k];
            }
        }
        for k in (0..m).rev() {
            s[k] = 0.0;
            if !self.dropped[k] {
                let mut v = self.y[k];
                for i in k + 1..m {
                    v -= l[i * n + k] * s[i];
                }
                let sk = v / l[k * n + k];
                s[k] = if sk.is_finite() { sk } else { 0.0 };
            }
        }
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)] // the checks index x, w and the expected values together
mod tests {
    use super::*;

    /// SplitMix64 uniforms in [−1, 1).
    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            z ^= z >> 31;
            (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        }
    }

    fn gram(a: &[f64], rows: usize, cols: usize, b: &[f64]) -> (Vec<f64>, Vec<f64>, f64) {
        let mut ata = vec![0.0; cols * cols];
        let mut atb = vec![0.0; cols];
        for r in 0..rows {
            for i in 0..cols {
                atb[i] += a[r * cols + i] * b[r];
                for j in 0..cols {
                    ata[i * cols + j] += a[r * cols + i] * a[r * cols + j];
                }
            }
        }
        (ata, atb, b.iter().map(|v| v * v).sum())
    }

    fn gradient(a: &[f64], rows: usize, cols: usize, b: &[f64], x: &[f64]) -> Vec<f64> {
        let r: Vec<f64> = (0..rows).map(|i| b[i] - (0..cols).map(|j| a[i * cols + j] * x[j]).sum::<f64>()).collect();
        (0..cols).map(|j| (0..rows).map(|i| a[i * cols + j] * r[i]).sum()).collect()
    }

    /// Kuhn–Tucker conditions: w_i ≤ tol where x_i = 0, |w_i| ≤ tol where x_i > 0.
    fn assert_kkt(a: &[f64], rows: usize, cols: usize, b: &[f64], x: &[f64], tol: f64) {
        let w = gradient(a, rows, cols, b, x);
        for i in 0..cols {
            assert!(x[i] >= 0.0 && x[i].is_finite(), "x[{i}] = {}", x[i]);
            if x[i] == 0.0 {
                assert!(w[i] <= tol, "w[{i}] = {} at the bound (x = {x:?}, w = {w:?})", w[i]);
            } else {
                assert!(w[i].abs() <= tol, "w[{i}] = {} for a free variable (x = {x:?}, w = {w:?})", w[i]);
            }
        }
    }

    fn random_problem(rng: &mut Lcg, rows: usize, cols: usize) -> (Vec<f64>, Vec<f64>) {
        let a: Vec<f64> = (0..rows * cols).map(|_| rng.next()).collect();
        let b: Vec<f64> = (0..rows).map(|_| rng.next()).collect();
        (a, b)
    }

    #[test]
    #[allow(clippy::approx_constant)] // 0.7071 is MATLAB's datum, not 1/√2
    fn textbook_problem_with_an_active_constraint() {
        // MATLAB's lsqnonneg example: the unconstrained solution has x₁ < 0, the NNLS
        // solution is x = (0, c₂·d / c₂·c₂) ≈ (0, 0.6929), ‖Cx − d‖² ≈ 0.8315.
        let c = [0.0372, 0.2869, 0.6861, 0.7071, 0.6233, 0.6245, 0.6344, 0.6170];
        let d = [0.8587, 0.1781, 0.0747, 0.8405];
        let r = nnls(&c, 4, 2, &d).unwrap();
        let c2: Vec<f64> = (0..4).map(|i| c[2 * i + 1]).collect();
        let x2 = c2.iter().zip(&d).map(|(a, b)| a * b).sum::<f64>() / c2.iter().map(|a| a * a).sum::<f64>();
        assert_eq!(r.x[0], 0.0);
        assert!((r.x[1] - x2).abs() < 1e-12, "{:?}", r.x);
        assert!((r.x[1] - 0.6929).abs() < 1e-4);
        assert!((r.residual2 - 0.8315).abs() < 1e-4, "{}", r.residual2);
        assert_kkt(&c, 4, 2, &d, &r.x, 1e-12);
        // The same through the Gram matrix.
        let (ata, atb, btb) = gram(&c, 4, 2, &d);
        let g = nnls_gram(&ata, &atb, btb, 2).unwrap();
        assert_eq!(g.x[0], 0.0);
        assert!((g.x[1] - x2).abs() < 1e-12);
        assert!((g.residual2 - r.residual2).abs() < 1e-12);
    }

    #[test]
    fn upper_bounds_hold_and_cost_no_more_than_clamping() {
        // On the identity each variable is its own problem: clipped at both ends.
        let id = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let c = nnls_gram_capped(&id, &[1.0, -2.0, 3.0], 14.0, 3, &[0.5, 1.0, 10.0]).unwrap();
        assert_eq!(c.x, vec![0.5, 0.0, 3.0]);
        assert!((c.residual2 - 4.25).abs() < 1e-12, "{}", c.residual2);
        // No bound is no change.
        let mut rng = Lcg(11);
        for trial in 0..200 {
            let (rows, cols) = (16, 1 + trial % 5);
            // Positive columns, as the BRDF's basis functions are.
            let a: Vec<f64> = (0..rows * cols).map(|_| rng.next().abs() + 0.01).collect();
            let b: Vec<f64> = (0..rows).map(|_| 2.0 * rng.next().abs()).collect();
            let (ata, atb, btb) = gram(&a, rows, cols, &b);
            let free = nnls_gram(&ata, &atb, btb, cols).unwrap();
            assert_eq!(nnls_gram_capped(&ata, &atb, btb, cols, &vec![f64::INFINITY; cols]).unwrap().x, free.x);
            let upper: Vec<f64> = free.x.iter().map(|x| x * (0.2 + 0.9 * rng.next().abs())).collect();
            let capped = nnls_gram_capped(&ata, &atb, btb, cols, &upper).unwrap();
            let clamped: Vec<f64> = free.x.iter().zip(&upper).map(|(x, u)| x.min(*u)).collect();
            let residual = |x: &[f64]| (0..rows).map(|r| ((0..cols).map(|j| a[r * cols + j] * x[j]).sum::<f64>() - b[r]).powi(2)).sum::<f64>();
            for j in 0..cols {
                assert!(capped.x[j] >= 0.0 && capped.x[j] <= upper[j], "trial {trial}: x {:?}, upper {upper:?}", capped.x);
            }
            assert!((capped.residual2 - residual(&capped.x)).abs() <= 1e-9 * (1.0 + btb), "trial {trial}: {} against {}", capped.residual2, residual(&capped.x));
            assert!(capped.residual2 <= residual(&clamped) + 1e-9 * (1.0 + btb), "trial {trial}: capped {} against clamped {}", capped.residual2, residual(&clamped));
            // Kuhn–Tucker with both bounds: at 0 the gradient w = Aᵀ(b − Ax) points down,
            // at the cap up, and it vanishes between.
            let w = gradient(&a, rows, cols, &b, &capped.x);
            for j in 0..cols {
                let tol = 1e-8 * (1.0 + btb);
                if upper[j] == 0.0 {
                    assert_eq!(capped.x[j], 0.0);
                } else if capped.x[j] == 0.0 {
                    assert!(w[j] <= tol, "trial {trial}: w {w:?} x {:?}", capped.x);
                } else if capped.x[j] == upper[j] {
                    assert!(w[j] >= -tol, "trial {trial}: w {w:?} x {:?} upper {upper:?}", capped.x);
                } else {
                    assert!(w[j].abs() <= tol, "trial {trial}: w {w:?} x {:?}", capped.x);
                }
            }
        }
        assert_eq!(nnls_gram_capped(&id, &[1.0, 2.0, 3.0], 14.0, 3, &[1.0, -1.0, 1.0]).unwrap_err(), NnlsError::BadBound { index: 1, value: -1.0 });
        assert!(matches!(nnls_gram_capped(&id, &[1.0, 2.0, 3.0], 14.0, 3, &[1.0, f64::NAN, 1.0]), Err(NnlsError::BadBound { index: 1, .. })));
        assert!(nnls_gram_capped(&id, &[1.0, 2.0, 3.0], 14.0, 3, &[1.0]).is_err());
    }

    #[test]
    fn identity_clips_negative_entries() {
        let a = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let b = [1.0, -2.0, 3.0];
        let r = nnls(&a, 3, 3, &b).unwrap();
        assert_eq!(r.x, vec![1.0, 0.0, 3.0]);
        assert!((r.residual2 - 4.0).abs() < 1e-12);
        let g = nnls_gram(&a, &b, 14.0, 3).unwrap();
        assert_eq!(g.x, vec![1.0, 0.0, 3.0]);
        assert!((g.residual2 - 4.0).abs() < 1e-12);
    }

    #[test]
    fn unconstrained_case_is_least_squares() {
        // b = A x* + noise with x* well inside the positive orthant: NNLS = least squares,
        // whose gradient vanishes everywhere.
        let mut rng = Lcg(3);
        let (rows, cols) = (12, 4);
        let a: Vec<f64> = (0..rows * cols).map(|_| rng.next()).collect();
        let xs = [1.0, 2.0, 0.5, 3.0];
        let b: Vec<f64> = (0..rows).map(|i| (0..cols).map(|j| a[i * cols + j] * xs[j]).sum::<f64>() + 1e-3 * rng.next()).collect();
        let r = nnls(&a, rows, cols, &b).unwrap();
        assert!(r.x.iter().all(|&v| v > 0.0));
        let w = gradient(&a, rows, cols, &b, &r.x);
        assert!(w.iter().all(|w| w.abs() < 1e-12), "{w:?}");
        for j in 0..cols {
            assert!((r.x[j] - xs[j]).abs() < 1e-2);
        }
        // Exact data: exact recovery.
        let b: Vec<f64> = (0..rows).map(|i| (0..cols).map(|j| a[i * cols + j] * xs[j]).sum()).collect();
        let r = nnls(&a, rows, cols, &b).unwrap();
        for j in 0..cols {
            assert!((r.x[j] - xs[j]).abs() < 1e-12, "{:?}", r.x);
        }
        assert!(r.residual2 < 1e-24);
        let (ata, atb, btb) = gram(&a, rows, cols, &b);
        let g = nnls_gram(&ata, &atb, btb, cols).unwrap();
        for j in 0..cols {
            assert!((g.x[j] - xs[j]).abs() < 1e-10, "{:?}", g.x);
        }
        assert!(g.residual2 < 1e-12 * btb, "{} vs bᵀb {btb}", g.residual2);
    }

    #[test]
    fn all_negative_solution_gives_zero() {
        // b = −A·(1, 2, 3) with A ≥ 0: every gradient Aᵀb is negative, x = 0.
        let a = [1.0, 0.5, 0.2, 0.3, 1.0, 0.1, 0.2, 0.4, 1.0, 0.6, 0.6, 0.6];
        let b: Vec<f64> = (0..4).map(|i| -(a[3 * i] + 2.0 * a[3 * i + 1] + 3.0 * a[3 * i + 2])).collect();
        let r = nnls(&a, 4, 3, &b).unwrap();
        assert_eq!(r.x, vec![0.0; 3]);
        assert_eq!(r.iterations, 0);
        let b2: f64 = b.iter().map(|v| v * v).sum();
        assert!((r.residual2 - b2).abs() < 1e-12);
        let (ata, atb, btb) = gram(&a, 4, 3, &b);
        let g = nnls_gram(&ata, &atb, btb, 3).unwrap();
        assert_eq!(g.x, vec![0.0; 3]);
        assert_eq!(g.residual2, btb);
    }

    #[test]
    fn gram_agrees_with_dense_on_random_problems() {
        let mut rng = Lcg(11);
        for trial in 0..300 {
            let cols = 1 + trial % 9;
            let rows = cols + (trial % 7) * 3 + 1;
            let (a, b) = random_problem(&mut rng, rows, cols);
            let r = nnls(&a, rows, cols, &b).unwrap();
            let (ata, atb, btb) = gram(&a, rows, cols, &b);
            let g = nnls_gram(&ata, &atb, btb, cols).unwrap();
            for j in 0..cols {
                assert!((r.x[j] - g.x[j]).abs() < 1e-8 * (1.0 + r.x[j].abs()), "trial {trial}: {:?} vs {:?}", r.x, g.x);
            }
            assert!((r.residual2 - g.residual2).abs() < 1e-9 * (1.0 + btb), "trial {trial}");
        }
    }

    #[test]
    fn kkt_conditions_hold_on_random_problems() {
        let mut rng = Lcg(5);
        for trial in 0..300 {
            let cols = 1 + trial % 12;
            // Include under-determined problems (rows < cols).
            let rows = 1 + (trial * 7) % 20;
            let (a, b) = random_problem(&mut rng, rows, cols);
            let r = nnls(&a, rows, cols, &b).unwrap();
            assert_kkt(&a, rows, cols, &b, &r.x, 1e-9);
            assert!(r.iterations <= 3 * cols + 30);
            let (ata, atb, btb) = gram(&a, rows, cols, &b);
            let g = nnls_gram(&ata, &atb, btb, cols).unwrap();
            assert_kkt(&a, rows, cols, &b, &g.x, 1e-7);
            assert!(g.residual2 >= 0.0 && g.residual2 <= btb + 1e-12);
        }
    }

    #[test]
    fn rank_deficient_and_duplicate_columns() {
        // Columns: c0, c0 again, 0, c0 + c3, c3 (so c3 is also dependent on the rest).
        let mut rng = Lcg(9);
        let rows = 8;
        let c0: Vec<f64> = (0..rows).map(|_| rng.next()).collect();
        let c3: Vec<f64> = (0..rows).map(|_| rng.next()).collect();
        let cols = 5;
        let mut a = vec![0.0; rows * cols];
        for r in 0..rows {
            a[r * cols] = c0[r];
            a[r * cols + 1] = c0[r];
            a[r * cols + 3] = c0[r] + c3[r];
            a[r * cols + 4] = c3[r];
        }
        for seed in 0..20 {
            let mut rng = Lcg(100 + seed);
            let b: Vec<f64> = (0..rows).map(|_| rng.next()).collect();
            let r = nnls(&a, rows, cols, &b).unwrap();
            assert_kkt(&a, rows, cols, &b, &r.x, 1e-9);
            assert_eq!(r.x[2], 0.0);
            let (ata, atb, btb) = gram(&a, rows, cols, &b);
            let g = nnls_gram(&ata, &atb, btb, cols).unwrap();
            assert_kkt(&a, rows, cols, &b, &g.x, 1e-7);
            assert!((g.residual2 - r.residual2).abs() < 1e-9, "{} vs {}", g.residual2, r.residual2);
        }
        // An all-zero matrix.
        let z = nnls(&[0.0; 6], 3, 2, &[1.0, 2.0, 3.0]).unwrap();
        assert_eq!(z.x, vec![0.0, 0.0]);
        assert!((z.residual2 - 14.0).abs() < 1e-12);
        let zg = nnls_gram(&[0.0; 4], &[0.0; 2], 14.0, 2).unwrap();
        assert_eq!(zg.x, vec![0.0, 0.0]);
        assert_eq!(zg.residual2, 14.0);
        // Exactly duplicated columns with a positive target: the weight is split, the
        // sum is the single-column answer.
        let a = [1.0, 1.0, 2.0, 2.0];
        let g = nnls(&a, 2, 2, &[1.0, 2.0]).unwrap();
        assert!((g.x[0] + g.x[1] - 1.0).abs() < 1e-12 && g.residual2 < 1e-24, "{g:?}");
        let gg = nnls_gram(&[5.0, 5.0, 5.0, 5.0], &[5.0, 5.0], 5.0, 2).unwrap();
        assert!((gg.x[0] + gg.x[1] - 1.0).abs() < 1e-12 && gg.residual2 < 1e-12, "{gg:?}");
    }

    #[test]
    fn degenerate_sizes() {
        let r = nnls(&[], 0, 3, &[]).unwrap();
        assert_eq!(r.x, vec![0.0; 3]);
        assert_eq!(r.residual2, 0.0);
        let r = nnls(&[], 2, 0, &[3.0, 4.0]).unwrap();
        assert!(r.x.is_empty());
        assert_eq!(r.residual2, 25.0);
        let g = nnls_gram(&[], &[], 2.0, 0).unwrap();
        assert!(g.x.is_empty());
        assert_eq!(g.residual2, 2.0);
        // A 1 × 1 problem both ways.
        assert_eq!(nnls(&[2.0], 1, 1, &[3.0]).unwrap().x, vec![1.5]);
        assert_eq!(nnls(&[2.0], 1, 1, &[-3.0]).unwrap().x, vec![0.0]);
    }

    #[test]
    fn bad_input_is_an_error() {
        assert_eq!(nnls(&[1.0; 5], 2, 3, &[1.0, 2.0]), Err(NnlsError::Shape { what: "A", expected: 6, got: 5 }));
        assert_eq!(nnls(&[1.0; 6], 2, 3, &[1.0]), Err(NnlsError::Shape { what: "b", expected: 2, got: 1 }));
        assert_eq!(nnls(&[1.0, f64::NAN], 1, 2, &[1.0]), Err(NnlsError::NonFinite { what: "A", index: 1 }));
        assert_eq!(nnls(&[1.0, 1.0], 1, 2, &[f64::INFINITY]), Err(NnlsError::NonFinite { what: "b", index: 0 }));
        assert!(nnls(&[], usize::MAX, 2, &[]).is_err());
        assert_eq!(nnls_gram(&[1.0; 3], &[1.0; 2], 1.0, 2), Err(NnlsError::Shape { what: "AᵀA", expected: 4, got: 3 }));
        assert_eq!(nnls_gram(&[1.0; 4], &[1.0; 3], 1.0, 2), Err(NnlsError::Shape { what: "Aᵀb", expected: 2, got: 3 }));
        assert_eq!(nnls_gram(&[1.0; 4], &[1.0, f64::NAN], 1.0, 2), Err(NnlsError::NonFinite { what: "Aᵀb", index: 1 }));
        assert_eq!(nnls_gram(&[1.0; 4], &[1.0; 2], f64::NAN, 2), Err(NnlsError::NonFinite { what: "bᵀb", index: 0 }));
        // Not PSD (negative diagonal) or asymmetric: no panic, a feasible answer.
        let g = nnls_gram(&[-1.0, 3.0, 0.0, 1.0], &[1.0, 1.0], 1.0, 2).unwrap();
        assert!(g.x.iter().all(|v| *v >= 0.0 && v.is_finite()) && g.residual2.is_finite());
    }

    #[test]
    fn badly_scaled_columns() {
        // Columns differing by 10⁶ in scale: the solution is scale-equivariant.
        let mut rng = Lcg(21);
        let (rows, cols) = (10, 4);
        let (a, b) = random_problem(&mut rng, rows, cols);
        let scales = [1e-3, 1.0, 1e3, 1.0];
        let scaled: Vec<f64> = a.iter().enumerate().map(|(i, v)| v * scales[i % cols]).collect();
        let r = nnls(&a, rows, cols, &b).unwrap();
        let s = nnls(&scaled, rows, cols, &b).unwrap();
        for j in 0..cols {
            assert!((s.x[j] * scales[j] - r.x[j]).abs() < 1e-9 * (1.0 + r.x[j]), "{:?} vs {:?}", s.x, r.x);
        }
        let (ata, atb, btb) = gram(&scaled, rows, cols, &b);
        let g = nnls_gram(&ata, &atb, btb, cols).unwrap();
        for j in 0..cols {
            assert!((g.x[j] * scales[j] - r.x[j]).abs() < 1e-6 * (1.0 + r.x[j]), "{:?} vs {:?}", g.x, r.x);
        }
    }
}
