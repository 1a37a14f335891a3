//! Nelder–Mead downhill simplex minimization of a function of a few variables.
//!
//! The method of Nelder and Mead ("A simplex method for function minimization", The
//! Computer Journal 7, 1965) in the precise form of Lagarias, Reeds, Wright and Wright
//! ("Convergence properties of the Nelder–Mead simplex method in low dimensions", SIAM
//! J. Optim. 9, 1998): reflection ρ = 1, expansion χ = 2, contraction γ = 1/2, shrink
//! σ = 1/2, outside and inside contractions, and their tie-breaking (a new vertex goes
//! after the old ones of equal value). Above 4 dimensions the adaptive coefficients of
//! Gao and Han ("Implementing the Nelder–Mead simplex algorithm with adaptive
//! parameters", Comput. Optim. Appl. 51, 2012) are used instead: χ = 1 + 2/n,
//! γ = 3/4 − 1/(2n), σ = 1 − 1/n, which keep the simplex from degenerating.
//!
//! A value that is NaN or infinite counts as +∞, so a caller rejects a point (outside
//! its bounds, say) by returning ∞; a point with a non-finite coordinate is not passed
//! to the function at all. Everything is deterministic.

/// Why a minimization cannot run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimplexError {
    #[error("the starting point is empty")]
    Empty,
    #[error("the step has {got} entries, the starting point {expected}")]
    StepLength { expected: usize, got: usize },
    #[error("step[{index}] = {value} is zero or not finite")]
    BadStep { index: usize, value: f64 },
    #[error("x0[{index}] = {value} is not finite")]
    NonFiniteStart { index: usize, value: f64 },
    #[error("{what} = {value} is negative or not finite")]
    BadTolerance { what: &'static str, value: f64 },
    #[error("no finite function value in {evals} evaluations")]
    NoFiniteValue { evals: usize },
}

/// Stopping rules.
#[derive(Debug, Clone, PartialEq)]
pub struct NelderMead {
    /// Most function evaluations per run; the initial simplex (n + 1 of them) is
    /// evaluated even if this is smaller.
    pub max_evals: usize,
    /// Converged when the spread of the vertex values is ≤ f_tol·(|f_best| + 1e-30) …
    pub f_tol: f64,
    /// … and the simplex is within x_tol of its best vertex in every coordinate.
    pub x_tol: f64,
}

impl Default for NelderMead {
    fn default() -> NelderMead {
        NelderMead { max_evals: 2000, f_tol: 1e-10, x_tol: 1e-8 }
    }
}

/// The result of a minimization.
#[derive(Debug, Clone, PartialEq)]
pub struct Minimum {
    /// The best point found.
    pub x: Vec<f64>,
    /// f(x), finite.
    pub f: f64,
    /// Function evaluations used.
    pub evals: usize,
    /// Whether both tolerances were met (otherwise the evaluations ran out).
    pub converged: bool,
}

/// Minimizes `f` from `x0` with the initial simplex x0, x0 + step_i·e_i.
pub fn nelder_mead(mut f: impl FnMut(&[f64]) -> f64, x0: &[f64], step: &[f64], opts: &NelderMead) -> Result<Minimum, SimplexError> {
    validate(x0, step, opts)?;
    run(&mut f, x0, step, opts)
}

/// Nelder–Mead restarted from the best point with a fresh simplex of the original `step`
/// until a restart improves f by less than f_tol·(|f| + 1e-30), at most `max_restarts`
/// times. A collapsed simplex (a common failure of the method) is re-expanded this way.
///
/// Each run gets `opts.max_evals`; `evals` in the result is the total, `converged` that
/// of the last run.
pub fn nelder_mead_restarts(mut f: impl FnMut(&[f64]) -> f64, x0: &[f64], step: &[f64], opts: &NelderMead, max_restarts: usize) -> Result<Minimum, SimplexError> {
    validate(x0, step, opts)?;
    let mut best = run(&mut f, x0, step, opts)?;
    for _ in 0..max_restarts {
        let next = run(&mut f, &best.x, step, opts)?;
        let evals = best.evals + next.evals;
        let improvement = best.f - next.f;
        let small = improvement <= opts.f_tol * (best.f.abs() + 1e-30);
        if next.f < best.f {
            best = Minimum { evals, ..next };
        } else {
            best.evals = evals;
            best.converged = next.converged;
        }
        if small {
            break;
        }
    }
    Ok(best)
}

fn validate(x0: &[f64], step: &[f64], opts: &NelderMead) -> Result<(), SimplexError> {
    if x0.is_empty() {
        return Err(SimplexError::Empty);
    }
    if step.len() != x0.len() {
        return Err(SimplexError::StepLength { expected: x0.len(), got: step.len() });
    }
    if let Some(index) = x0.iter().position(|v| !v.is_finite()) {
        return Err(SimplexError::NonFiniteStart { index, value: x0[index] });
    }
    if let Some(index) = step.iter().position(|v| !v.is_finite() || *v == 0.0) {
        return Err(SimplexError::BadStep { index, value: step[index] });
    }
    for (what, value) in [("f_tol", opts.f_tol), ("x_tol", opts.x_tol)] {
        if !(value >= 0.0 && value.is_finite()) {
            return Err(SimplexError::BadTolerance { what, value });
        }
    }
    Ok(())
}

/// The function with the evaluation count and the +∞ convention.
struct Objective<'f, F: FnMut(&[f64]) -> f64> {
    f: &'f mut F,
    evals: usize,
}

impl<F: FnMut(&[f64]) -> f64> Objective<'_, F> {
    fn eval(&mut self, x: &[f64]) -> f64 {
        self.evals += 1;
        if x.iter().any(|v| !v.is_finite()) {
            return f64::INFINITY;
        }
        let v = (self.f)(x);
        if v.is_finite() { v } else { f64::INFINITY }
    }
}

fn run<F: FnMut(&[f64]) -> f64>(f: &mut F, x0: &[f64], step: &[f64], opts: &NelderMead) -> Result<Minimum, SimplexError> {
    let n = x0.len();
    let (rho, chi, gamma, sigma) = if n > 4 {
        let nf = n as f64;
        (1.0, 1.0 + 2.0 / nf, 0.75 - 0.5 / nf, 1.0 - 1.0 / nf)
    } else {
        (1.0, 2.0, 0.5, 0.5)
    };
    let mut obj = Objective { f, evals: 0 };
    // Vertices with their values, kept sorted best first.
    let mut simplex: Vec<(f64, Vec<f64>)> = Vec::with_capacity(n + 1);
    simplex.push((obj.eval(x0), x0.to_vec()));
    for i in 0..n {
        let mut v = x0.to_vec();
        v[i] += step[i];
        simplex.push((obj.eval(&v), v));
    }
    // Stable: a vertex of equal value keeps its place, new vertices come last (Lagarias).
    simplex.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut centroid = vec![0.0; n];
    let mut trial = vec![0.0; n];
    let mut trial2 = vec![0.0; n];
    let mut converged = false;
    loop {
        if has_converged(&simplex, opts) {
            converged = true;
            break;
        }
        if obj.evals >= opts.max_evals {
            break;
        }
        centroid.fill(0.0);
        for (_, v) in &simplex[..n] {
            for (c, x) in centroid.iter_mut().zip(v) {
                *c += x;
            }
        }
        for c in centroid.iter_mut() {
            *c /= n as f64;
        }
        let (f_best, f_second_worst, f_worst) = (simplex[0].0, simplex[n - 1].0, simplex[n].0);
        // x̄ + t·(x̄ − x_worst): reflection t = ρ, expansion ρχ, outside contraction ργ,
        // inside contraction −γ.
        let along = |t: f64, out: &mut [f64], centroid: &[f64], worst: &[f64]| {
            for ((o, c), w) in out.iter_mut().zip(centroid).zip(worst) {
                *o = c + t * (c - w);
            }
        };
        along(rho, &mut trial, &centroid, &simplex[n].1);
        let fr = obj.eval(&trial);
        let mut accepted: Option<f64> = None;
        if f_best <= fr && fr < f_second_worst {
            accepted = Some(fr);
        } else if fr < f_best {
            along(rho * chi, &mut trial2, &centroid, &simplex[n].1);
            let fe = obj.eval(&trial2);
            if fe < fr {
                std::mem::swap(&mut trial, &mut trial2);
                accepted = Some(fe);
            } else {
                accepted = Some(fr);
            }
        } else if fr < f_worst {
            along(rho * gamma, &mut trial2, &centroid, &simplex[n].1);
            let fc = obj.eval(&trial2);
            if fc <= fr {
                std::mem::swap(&mut trial, &mut trial2);
                accepted = Some(fc);
            }
        } else {
            along(-gamma, &mut trial2, &centroid, &simplex[n].1);
            let fcc = obj.eval(&trial2);
            if fcc < f_worst {
                std::mem::swap(&mut trial, &mut trial2);
                accepted = Some(fcc);
            }
        }
        match accepted {
            Some(fv) => {
                simplex[n].0 = fv;
                simplex[n].1.copy_from_slice(&trial);
            }
            None => {
                // Shrink towards the best vertex; stop part-way if evaluations run out
                // (the vertices already moved keep their new values).
                let best = simplex[0].1.clone();
                for (fv, v) in simplex[1..].iter_mut() {
                    if obj.evals >= opts.max_evals {
                        break;
                    }
                    for (x, b) in v.iter_mut().zip(&best) {
                        *x = b + sigma * (*x - b);
                    }
                    *fv = obj.eval(v);
                }
            }
        }
        simplex.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    let (f, x) = simplex.swap_remove(0);
    if !f.is_finite() {
        return Err(SimplexError::NoFiniteValue { evals: obj.evals });
    }
    Ok(Minimum { x, f, evals: obj.evals, converged })
}

fn has_converged(simplex: &[(f64, Vec<f64>)], opts: &NelderMead) -> bool {
    let (f_best, f_worst) = (simplex[0].0, simplex[simplex.len() - 1].0);
    // An infinite vertex value never counts as converged (and ∞ − ∞ is not computed).
    if !f_worst.is_finite() {
        return false;
    }
    if f_worst - f_best > opts.f_tol * (f_best.abs() + 1e-30) {
        return false;
    }
    let best = &simplex[0].1;
    simplex[1..].iter().all(|(_, v)| v.iter().zip(best).all(|(x, b)| (x - b).abs() <= opts.x_tol))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rosenbrock(x: &[f64]) -> f64 {
        100.0 * (x[1] - x[0] * x[0]).powi(2) + (1.0 - x[0]).powi(2)
    }

    #[test]
    fn rosenbrock_from_the_classic_start() {
        let m = nelder_mead(rosenbrock, &[-1.2, 1.0], &[0.1, 0.1], &NelderMead::default()).unwrap();
        assert!(m.converged, "{m:?}");
        assert!((m.x[0] - 1.0).abs() < 1e-4 && (m.x[1] - 1.0).abs() < 1e-4, "{m:?}");
        assert!(m.f < 1e-8);
        assert!(m.evals <= 2000);
        let r = nelder_mead_restarts(rosenbrock, &[-1.2, 1.0], &[0.1, 0.1], &NelderMead::default(), 5).unwrap();
        assert!((r.x[0] - 1.0).abs() < 1e-5 && (r.x[1] - 1.0).abs() < 1e-5, "{r:?}");
        assert!(r.f <= m.f);
        assert!(r.evals > m.evals);
    }

    #[test]
    fn quadratic_in_four_dimensions() {
        // Σ d_i (x_i − c_i)² + a coupling term; minimum at c, value 3.
        let c = [1.0, -2.0, 0.5, 3.0];
        let d = [1.0, 4.0, 0.25, 2.0];
        let f = |x: &[f64]| {
            let mut s = 3.0;
            for i in 0..4 {
                s += d[i] * (x[i] - c[i]).powi(2);
            }
            s + 0.5 * (x[0] - c[0]) * (x[1] - c[1])
        };
        let opts = NelderMead { max_evals: 5000, ..NelderMead::default() };
        let m = nelder_mead_restarts(f, &[0.0; 4], &[0.5; 4], &opts, 3).unwrap();
        assert!(m.x.iter().zip(&c).all(|(x, c)| (x - c).abs() < 1e-4), "{m:?}");
        assert!((m.f - 3.0).abs() < 1e-9);
    }

    #[test]
    fn quadratic_in_eight_dimensions_uses_adaptive_coefficients() {
        let f = |x: &[f64]| x.iter().enumerate().map(|(i, v)| (i + 1) as f64 * (v - 0.1 * i as f64).powi(2)).sum::<f64>();
        let opts = NelderMead { max_evals: 20000, ..NelderMead::default() };
        let m = nelder_mead_restarts(f, &[1.0; 8], &[0.3; 8], &opts, 5).unwrap();
        for i in 0..8 {
            assert!((m.x[i] - 0.1 * i as f64).abs() < 1e-3, "{m:?}");
        }
    }

    #[test]
    fn infinite_outside_a_box_converges_inside() {
        // The unconstrained minimum (2, 2) is outside [−1, 1]²; the constrained one is
        // the corner (1, 1).
        let f = |x: &[f64]| if x.iter().all(|v| v.abs() <= 1.0) { (x[0] - 2.0).powi(2) + (x[1] - 2.0).powi(2) } else { f64::INFINITY };
        let m = nelder_mead_restarts(f, &[0.0, 0.0], &[0.5, 0.5], &NelderMead::default(), 5).unwrap();
        assert!(m.x.iter().all(|v| v.abs() <= 1.0), "{m:?}");
        assert!((m.x[0] - 1.0).abs() < 1e-3 && (m.x[1] - 1.0).abs() < 1e-3, "{m:?}");
        assert!(m.f.is_finite());
        // A start whose value is infinite is fine as long as some vertex is finite.
        let m = nelder_mead(f, &[1.5, 0.0], &[-1.0, 0.5], &NelderMead::default()).unwrap();
        assert!(m.x.iter().all(|v| v.abs() <= 1.0) && m.f.is_finite(), "{m:?}");
    }

    #[test]
    fn nan_regions_count_as_infinity() {
        // NaN for x < 0 (a log of a negative number); minimum at x = e⁻¹ of x·ln x.
        let f = |x: &[f64]| x[0] * x[0].ln() + (x[1] - 1.0).powi(2);
        let m = nelder_mead_restarts(f, &[0.05, 0.0], &[-0.2, 0.5], &NelderMead::default(), 3).unwrap();
        assert!((m.x[0] - (-1.0f64).exp()).abs() < 1e-4, "{m:?}");
        assert!((m.x[1] - 1.0).abs() < 1e-4);
        assert!(m.f.is_finite());
        // Everything NaN: an error, not a NaN result.
        let r = nelder_mead(|_| f64::NAN, &[0.0], &[1.0], &NelderMead { max_evals: 50, ..NelderMead::default() });
        assert_eq!(r, Err(SimplexError::NoFiniteValue { evals: 50 }));
    }

    #[test]
    fn unbounded_below_stays_finite() {
        // f = −x runs off to −∞; the points overflow at some stage and count as ∞, so the
        // result is a finite point with a finite value.
        let m = nelder_mead(|x: &[f64]| -x[0], &[0.0], &[1.0], &NelderMead { max_evals: 5000, ..NelderMead::default() }).unwrap();
        assert!(m.x[0].is_finite() && m.f.is_finite(), "{m:?}");
        assert!(!m.converged);
        assert_eq!(m.evals, 5000);
    }

    #[test]
    fn deterministic() {
        let f = |x: &[f64]| (x[0] - 0.3).powi(2) + (x[1] + x[0]).powi(4) + (x[2] * 2.0).sin().abs();
        let a = nelder_mead_restarts(f, &[1.0, 1.0, 1.0], &[0.2, 0.2, 0.2], &NelderMead::default(), 4).unwrap();
        let b = nelder_mead_restarts(f, &[1.0, 1.0, 1.0], &[0.2, 0.2, 0.2], &NelderMead::default(), 4).unwrap();
        assert_eq!(a.evals, b.evals);
        assert_eq!(a.f.to_bits(), b.f.to_bits());
        for (x, y) in a.x.iter().zip(&b.x) {
            assert_eq!(x.to_bits(), y.to_bits());
        }
    }

    #[test]
    fn evaluation_budget_is_respected() {
        let mut count = 0;
        let opts = NelderMead { max_evals: 37, f_tol: 0.0, x_tol: 0.0 };
        let m = nelder_mead(
            |x: &[f64]| {
                count += 1;
                rosenbrock(x)
            },
            &[-1.2, 1.0],
            &[0.1, 0.1],
            &opts,
        )
        .unwrap();
        assert_eq!(m.evals, 37);
        assert_eq!(count, 37);
        assert!(!m.converged);
        // Smaller than the initial simplex: that is still evaluated.
        let m = nelder_mead(rosenbrock, &[-1.2, 1.0], &[0.1, 0.1], &NelderMead { max_evals: 1, ..opts }).unwrap();
        assert_eq!(m.evals, 3);
    }

    #[test]
    fn bad_input_is_an_error() {
        let o = NelderMead::default();
        assert_eq!(nelder_mead(rosenbrock, &[], &[], &o), Err(SimplexError::Empty));
        assert_eq!(nelder_mead(rosenbrock, &[0.0, 0.0], &[1.0], &o), Err(SimplexError::StepLength { expected: 2, got: 1 }));
        assert_eq!(nelder_mead(rosenbrock, &[0.0, 0.0], &[1.0, 0.0], &o), Err(SimplexError::BadStep { index: 1, value: 0.0 }));
        assert!(matches!(nelder_mead(rosenbrock, &[0.0, 0.0], &[f64::NAN, 1.0], &o), Err(SimplexError::BadStep { index: 0, .. })));
        assert!(matches!(nelder_mead(rosenbrock, &[0.0, f64::INFINITY], &[1.0, 1.0], &o), Err(SimplexError::NonFiniteStart { index: 1, .. })));
        let bad = NelderMead { f_tol: -1.0, ..o.clone() };
        assert!(matches!(nelder_mead(rosenbrock, &[0.0, 0.0], &[1.0, 1.0], &bad), Err(SimplexError::BadTolerance { what: "f_tol", .. })));
        let bad = NelderMead { x_tol: f64::NAN, ..o.clone() };
        assert!(matches!(nelder_mead_restarts(rosenbrock, &[0.0, 0.0], &[1.0, 1.0], &bad, 2), Err(SimplexError::BadTolerance { what: "x_tol", .. })));
    }
}
