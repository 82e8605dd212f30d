//! Weighted non-linear least squares by Levenberg–Marquardt with finite-difference
//! Jacobians (columns evaluated in parallel; the result does not depend on the thread
//! count because each column is computed independently and stored in place).
//!
//! Minimises χ²(θ) = ‖r(θ)‖² where r is the noise-normalised residual vector.
//! Step: (JᵀJ + λ diag JᵀJ) δ = −Jᵀr (Marquardt 1963), projected onto the bounds.

use crate::error::CheckError;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

mod tall;
pub use tall::{gram, mul, r_factor, sub_mul, thin_qr, thin_sv, thin_svd, tr_mul};

/// A residual function of the parameters.
pub type ResidualFn<'a> = dyn Fn(&[f64]) -> Result<Vec<f64>, CheckError> + Sync + 'a;

/// Bounds and scales of the parameters.
#[derive(Debug, Clone)]
pub struct Bounds {
    /// Lower bound of each parameter.
    pub lower: Vec<f64>,
    /// Upper bound of each parameter.
    pub upper: Vec<f64>,
    /// Typical magnitudes: finite-difference steps are 1e-5 of these.
    pub scales: Vec<f64>,
}

/// Result of a fit.
#[derive(Debug, Clone)]
pub struct Fit {
    /// The parameters at the end.
    pub theta: Vec<f64>,
    /// The residual vector there.
    pub residual: Vec<f64>,
    /// `χ² = ‖r‖²` there.
    pub chi2: f64,
    /// The Jacobian `∂r/∂θ` there.
    pub jacobian: DMatrix<f64>,
    /// Iterations used.
    pub iterations: usize,
    /// True when a convergence test was met before the iteration cap.
    pub converged: bool,
}

/// `χ² = ‖r‖²` of a normalised residual vector (docs/conventions.md §8).
pub fn chi2(r: &[f64]) -> f64 {
    r.iter().map(|x| x * x).sum()
}

/// Which finite-difference columns may share an evaluation (Curtis, Powell & Reid
/// 1974): parameters whose declared residual rows are disjoint are perturbed together,
/// and each reads its own rows of the one evaluation. Every other row of its column is
/// zero by declaration, and its own rows are what a separate evaluation gives, bit for
/// bit, when the declaration holds (nothing but the parameter itself changes them).
#[derive(Debug, Clone)]
pub struct Columns {
    /// The residual rows each parameter can change (ascending); `None`: any row.
    rows: Vec<Option<Vec<usize>>>,
    /// The parameters evaluated together, a partition of `0..p`.
    groups: Vec<Vec<usize>>,
}

impl Columns {
    /// Every column its own evaluation.
    pub fn dense(p: usize) -> Columns {
        Columns {
            rows: vec![None; p],
            groups: (0..p).map(|j| vec![j]).collect(),
        }
    }

    /// Columns grouped greedily in parameter order: a parameter with declared rows
    /// joins the first group of declared parameters none of whose rows it shares.
    pub fn grouped(rows: Vec<Option<Vec<usize>>>, n_rows: usize) -> Columns {
        let mut groups: Vec<Vec<usize>> = Vec::new();
        let mut taken: Vec<Vec<bool>> = Vec::new();
        // The groups of declared parameters (indices into `groups`).
        let mut sparse: Vec<usize> = Vec::new();
        for (j, r) in rows.iter().enumerate() {
            let Some(r) = r else {
                groups.push(vec![j]);
                continue;
            };
            let fits = |t: &Vec<bool>| r.iter().all(|&i| !t[i]);
            let k = match sparse.iter().copied().find(|&g| fits(&taken[g])) {
                Some(g) => g,
                None => {
                    groups.push(Vec::new());
                    taken.resize(groups.len(), Vec::new());
                    let g = groups.len() - 1;
                    taken[g] = vec![false; n_rows];
                    sparse.push(g);
                    g
                }
            };
            groups[k].push(j);
            for &i in r {
                taken[k][i] = true;
            }
        }
        Columns { rows, groups }
    }

    /// Model evaluations per Jacobian.
    pub fn evaluations(&self) -> usize {
        self.groups.len()
    }
}

/// Forward-difference Jacobian ∂r/∂θ (step 1e-7 of the scale; backward where the
/// forward evaluation fails, e.g. at a bound). Forward differences halve the cost; their
/// relative error (~1e-7) is far below what standard errors and score tests need.
pub fn jacobian(
    f: &ResidualFn,
    theta: &[f64],
    scales: &[f64],
    r0: &[f64],
) -> Result<DMatrix<f64>, CheckError> {
    jacobian_with(f, theta, scales, r0, false)
}

/// [`jacobian`] with the columns of `columns`' groups evaluated together (the same
/// matrix, fewer evaluations); `r0` is the residual at `theta`.
pub fn jacobian_grouped(
    f: &ResidualFn,
    theta: &[f64],
    scales: &[f64],
    r0: &[f64],
    columns: &Columns,
) -> Result<DMatrix<f64>, CheckError> {
    jacobian_grouped_from(f, theta, scales, r0, None, columns)
}

/// [`jacobian_grouped`] against a reference residual `r0` other than the residual at
/// `theta` (a score test's current model, which lacks the candidate at its neutral
/// point): the residual at `theta` is evaluated once more and a column's rows outside its parameter's reach are `(r(θ) − r0)/h`, what the
/// column's own step leaves them, so the matrix is still [`jacobian`]'s.
pub fn jacobian_grouped_against(
    f: &ResidualFn,
    theta: &[f64],
    scales: &[f64],
    r0: &[f64],
    columns: &Columns,
) -> Result<DMatrix<f64>, CheckError> {
    if columns.groups.iter().all(|g| g.len() == 1) {
        return jacobian_grouped_from(f, theta, scales, r0, None, columns);
    }
    match f(theta) {
        Ok(at) => jacobian_grouped_from(f, theta, scales, r0, Some(&at), columns),
        Err(_) => jacobian_with(f, theta, scales, r0, false),
    }
}

fn jacobian_grouped_from(
    f: &ResidualFn,
    theta: &[f64],
    scales: &[f64],
    r0: &[f64],
    at_theta: Option<&[f64]>,
    columns: &Columns,
) -> Result<DMatrix<f64>, CheckError> {
    let mut jm = DMatrix::zeros(r0.len(), theta.len());
    jacobian_into(f, theta, scales, r0, at_theta, columns, &mut jm)?;
    Ok(jm)
}

/// [`jacobian_grouped`] written over `jm` (n × p), which need not be zero: an LM fit
/// reuses its matrix, and each column is written in place, without a column vector and a
/// copy per parameter or a fresh 20 MB matrix per iteration.
fn jacobian_into(
    f: &ResidualFn,
    theta: &[f64],
    scales: &[f64],
    r0: &[f64],
    at_theta: Option<&[f64]>,
    columns: &Columns,
    jm: &mut DMatrix<f64>,
) -> Result<(), CheckError> {
    let _t = crate::prof::span(crate::prof::JACOBIAN);
    assert_eq!(columns.rows.len(), theta.len(), "one row set per parameter");
    let n = r0.len();
    assert_eq!(jm.shape(), (n, theta.len()), "Jacobian shape");
    if n == 0 {
        return Ok(());
    }
    let step = |j: usize| 1e-7f64 * scales[j].abs().max(1e-12);
    let mut slots: Vec<Option<&mut [f64]>> = jm.as_mut_slice().chunks_mut(n).map(Some).collect();
    let work: Vec<(&Vec<usize>, Vec<&mut [f64]>)> = columns
        .groups
        .iter()
        .map(|g| {
            let outs = g
                .iter()
                .map(|&j| slots[j].take().expect("a partition"))
                .collect();
            (g, outs)
        })
        .collect();
    let errors: Vec<(usize, CheckError)> = work
        .into_par_iter()
        .flat_map_iter(|(g, mut outs)| {
            if g.len() > 1 {
                let mut tp = theta.to_vec();
                for &j in g {
                    tp[j] = theta[j] + step(j);
                }
                if let Ok(p) = f(&tp) {
                    for (&j, c) in g.iter().zip(outs.iter_mut()) {
                        let h = step(j);
                        match at_theta {
                            Some(at) => c
                                .iter_mut()
                                .zip(at.iter().zip(r0))
                                .for_each(|(c, (a, b))| *c = (a - b) / h),
                            None => c.fill(0.0),
                        }
                        for &i in columns.rows[j].as_deref().expect("grouped rows") {
                            c[i] = (p[i] - r0[i]) / h;
                        }
                    }
                    return Vec::new();
                }
            }
            // A parameter of its own, or a group whose joint step failed: one by one.
            g.iter()
                .zip(outs)
                .filter_map(|(&j, c)| {
                    column_into(f, theta, scales, r0, false, j, c)
                        .err()
                        .map(|e| (j, e))
                })
                .collect()
        })
        .collect();
    // The error of the first failing column, as when the columns were taken in order.
    match errors.into_iter().min_by_key(|(j, _)| *j) {
        Some((_, e)) => Err(e),
        None => Ok(()),
    }
}

/// Finite-difference Jacobian, central or forward (half the cost; used while iterating,
/// where the step direction need not be exact).
pub fn jacobian_with(
    f: &ResidualFn,
    theta: &[f64],
    scales: &[f64],
    r0: &[f64],
    central: bool,
) -> Result<DMatrix<f64>, CheckError> {
    let _t = crate::prof::span(crate::prof::JACOBIAN);
    let n = r0.len();
    let mut jm = DMatrix::zeros(n, theta.len());
    if n == 0 {
        return Ok(jm);
    }
    let errors: Vec<(usize, CheckError)> = jm
        .as_mut_slice()
        .par_chunks_mut(n)
        .enumerate()
        .filter_map(|(j, c)| {
            column_into(f, theta, scales, r0, central, j, c)
                .err()
                .map(|e| (j, e))
        })
        .collect();
    match errors.into_iter().next() {
        Some((_, e)) => Err(e),
        None => Ok(jm),
    }
}

/// Column j of [`jacobian_with`], written to `out`.
fn column_into(
    f: &ResidualFn,
    theta: &[f64],
    scales: &[f64],
    r0: &[f64],
    central: bool,
    j: usize,
    out: &mut [f64],
) -> Result<(), CheckError> {
    let h = if central { 1e-5 } else { 1e-7f64 } * scales[j].abs().max(1e-12);
    let mut write = |a: &[f64], b: &[f64], d: f64| {
        out.iter_mut()
            .zip(a.iter().zip(b))
            .for_each(|(o, (a, b))| *o = (a - b) / d);
    };
    let mut tp = theta.to_vec();
    if !central {
        if let Ok(p) = f(&tp
            .iter()
            .enumerate()
            .map(|(i, t)| if i == j { t + h } else { *t })
            .collect::<Vec<_>>())
        {
            write(&p, r0, h);
            return Ok(());
        }
    }
    tp[j] += h;
    let mut tm = theta.to_vec();
    tm[j] -= h;
    match (f(&tp), f(&tm)) {
        (Ok(p), Ok(m)) => write(&p, &m, 2.0 * h),
        (Ok(p), Err(_)) => write(&p, r0, h),
        (Err(_), Ok(m)) => write(r0, &m, h),
        (Err(e), Err(_)) => return Err(e),
    }
    Ok(())
}

fn clamp(theta: &mut [f64], b: &Bounds) {
    for (t, (lo, hi)) in theta.iter_mut().zip(b.lower.iter().zip(&b.upper)) {
        *t = t.clamp(*lo, *hi);
    }
}

/// Relative χ² decrease of a step below which a fit has converged (see
/// [`converged_rel`]).
const CONVERGED_REL: f64 = 1e-6;

/// The relative χ² decrease below which a fit of `n_rows` residual rows has converged:
/// [`CONVERGED_REL`], and for very large recordings at most a tenth of χ²'s share per
/// row (ν ≈ rows: a tenth of one degree of freedom's expected contribution).
///
/// Why this tolerance: what a fit's χ² feeds are likelihood-ratio, BIC and Wald tests
/// whose thresholds are 10 or more units of χ²/ν, and comparisons of refits whose Δχ²
/// differ by far more; at the bench's 54 000 rows 1e-6 of χ² is 0.05 units of χ²/ν.
/// A tighter tolerance (1e-7) only added iterations of a refit crawling along a valley
/// towards a bound (an elastic mode's damping running to zero: 0.2 of χ² per
/// iteration for ten iterations), each costing a Jacobian.
fn converged_rel(n_rows: usize) -> f64 {
    CONVERGED_REL.min(0.1 / n_rows.max(1) as f64)
}
/// Largest scaled parameter change of a step below which a fit has converged.
const CONVERGED_STEP: f64 = 1e-9;

/// Whether the step `delta`, solved from the damped normal equations at θ, would end
/// the fit by the convergence test once taken: its decrease of χ² predicted by the
/// linearised residual, `−2gᵀδ − δᵀAδ` (g = Jᵀr, A = JᵀJ), is below `rel_tol` of χ²
/// ([`converged_rel`]). Such a step is not taken: it would cost a model evaluation and
/// a Jacobian at a point whose χ² differs from θ's by less than the fit resolves, and
/// θ's Jacobian is already at hand.
///
/// The other convergence test, a scaled parameter change below `CONVERGED_STEP`, is
/// left to the step taken: a tiny step along a very sensitive direction can still carry
/// all of χ² (on exact data a baseline fit once stopped at χ²/ν 7.9 instead of 5e-4).
fn step_would_converge(
    g: &DVector<f64>,
    a: &DMatrix<f64>,
    delta: &DVector<f64>,
    c2: f64,
    rel_tol: f64,
) -> bool {
    let predicted = -2.0 * g.dot(delta) - (a * delta).dot(delta);
    predicted < rel_tol * c2.max(f64::MIN_POSITIVE)
}

/// Iterations of a refit after which its steps take geodesic acceleration (see
/// [`fit_grouped`]). Most refits of the bench's recordings converge in 2 to 6; those
/// that go on are elastic modes running off along a curved valley (9, 14 and 42
/// iterations), the last of which was each step's slowest refit.
const ACCELERATE_AFTER: usize = 8;

/// Largest ratio `2‖a‖/‖v‖` (D-norms, D the normal matrix's diagonal) of the geodesic
/// acceleration `a` to the velocity `v` for which a step `v + a/2` is tried
/// (Transtrum & Sethna 2012 recommend 0.75).
const GEODESIC_RATIO: f64 = 0.75;

/// `√(Σ d_i x_i²)`.
fn scaled_norm(x: &DVector<f64>, d: &[f64]) -> f64 {
    x.iter().zip(d).map(|(x, d)| d * x * x).sum::<f64>().sqrt()
}

/// The geodesic acceleration of a Levenberg–Marquardt step `v` (Transtrum & Sethna
/// 2012, eq. 13–15): the residual's second directional derivative along v by a finite
/// difference, `r_vv ≈ (2/h) ((r(θ + h v) − r(θ))/h − J v)` with h = 0.1, and `a` the
/// damped normal equations' solution for it, `(JᵀJ + λD) a = −Jᵀ r_vv`, over the free
/// parameters `free` (`ch` their factorisation). `None` when θ + h v cannot be
/// evaluated.
#[allow(clippy::too_many_arguments)]
fn geodesic_acceleration(
    f: &ResidualFn,
    theta: &[f64],
    r: &[f64],
    jm: &DMatrix<f64>,
    v: &DVector<f64>,
    ch: &nalgebra::Cholesky<f64, nalgebra::Dyn>,
    free: &[usize],
    bounds: &Bounds,
) -> Option<DVector<f64>> {
    const H: f64 = 0.1;
    let mut tp: Vec<f64> = theta.iter().zip(v.iter()).map(|(t, d)| t + H * d).collect();
    clamp(&mut tp, bounds);
    let rp = f(&tp).ok()?;
    let jv = jm * v;
    let rvv = DVector::from_iterator(
        r.len(),
        rp.iter()
            .zip(r)
            .zip(jv.iter())
            .map(|((p, r), jv)| (2.0 / H) * ((p - r) / H - jv)),
    );
    let gv = jm.tr_mul(&rvv);
    let af = ch.solve(&DVector::from_iterator(
        free.len(),
        free.iter().map(|&i| -gv[i]),
    ));
    let mut a = DVector::zeros(theta.len());
    for (k, &i) in free.iter().enumerate() {
        a[i] = af[k];
    }
    Some(a).filter(|a| a.iter().all(|x| x.is_finite()))
}

/// Levenberg–Marquardt from `theta0`.
pub fn fit(
    stage: &str,
    f: &ResidualFn,
    theta0: &[f64],
    bounds: &Bounds,
    max_iter: usize,
) -> Result<Fit, CheckError> {
    fit_grouped(
        stage,
        f,
        theta0,
        bounds,
        max_iter,
        &Columns::dense(theta0.len()),
    )
}

/// [`fit`] with the Jacobians' columns evaluated in `columns`' groups.
pub fn fit_grouped(
    stage: &str,
    f: &ResidualFn,
    theta0: &[f64],
    bounds: &Bounds,
    max_iter: usize,
    columns: &Columns,
) -> Result<Fit, CheckError> {
    let _t = crate::prof::span(if stage == "baseline" {
        crate::prof::FIT_BASELINE
    } else if stage.starts_with("refit") {
        crate::prof::FIT_REFIT
    } else {
        crate::prof::FIT_OTHER
    });
    // A refit starts from a screening's point, often far from its optimum, and an
    // effect's parameters can run off along a curved valley towards a limit (an
    // elastic mode leaving the band with residues growing as its frequency squared, so
    // that it becomes a residual flexibility): there straight Gauss–Newton steps
    // overshoot and the fit crawls (71 iterations of 1e-4 relative each). A refit still
    // descending after `ACCELERATE_AFTER` iterations follows the valley's bend by
    // geodesic acceleration (Transtrum & Sethna 2012) from then on; shorter fits take
    // the plain steps, unchanged.
    let refit = stage.starts_with("refit");
    let mut theta = theta0.to_vec();
    clamp(&mut theta, bounds);
    let r = f(&theta).map_err(|e| CheckError::Fit {
        stage: stage.into(),
        problem: format!("cannot evaluate the starting model: {e}"),
    })?;
    let mut at = State {
        c2: chi2(&r),
        theta,
        r,
        lambda: 1e-3,
    };
    let rel_tol = converged_rel(at.r.len());
    let mut jm = jacobian_grouped(f, &at.theta, &bounds.scales, &at.r, columns)?;
    let mut converged = false;
    // `jm` is the Jacobian at the current θ (no step accepted since it was taken).
    let mut jm_current = max_iter == 0;
    let mut it = 0;
    while it < max_iter {
        it += 1;
        let accelerate = refit && it > ACCELERATE_AFTER;
        match at.iterate(f, &jm, bounds, rel_tol, accelerate) {
            Iteration::AtMinimum => {
                // θ and r did not move since `jm` was taken, so it is already the
                // Jacobian at the solution (the same forward differences, bit for bit).
                converged = true;
                jm_current = true;
                break;
            }
            Iteration::Moved { converged: true } => {
                converged = true;
                break;
            }
            Iteration::Moved { converged: false } => {}
        }
        jacobian_into(f, &at.theta, &bounds.scales, &at.r, None, columns, &mut jm)?;
    }
    // The Jacobian at the solution, for standard errors and score tests: the last one
    // taken when no step was accepted after it (`max_iter` = 0 or no descent left),
    // otherwise one more.
    if !jm_current {
        jacobian_into(f, &at.theta, &bounds.scales, &at.r, None, columns, &mut jm)?;
    }
    Ok(Fit {
        theta: at.theta,
        residual: at.r,
        chi2: at.c2,
        jacobian: jm,
        iterations: it,
        converged,
    })
}

/// Where a Levenberg–Marquardt fit stands: θ, its residual and χ², and the damping λ.
struct State {
    theta: Vec<f64>,
    r: Vec<f64>,
    c2: f64,
    lambda: f64,
}

/// What one iteration of [`State::iterate`] did.
enum Iteration {
    /// A step was taken; `converged` when it met the convergence test.
    Moved { converged: bool },
    /// No step taken: the next would end the fit by the convergence test, or no descent
    /// direction is left at any damping (a minimum to working precision).
    AtMinimum,
}

/// A step solved from the damped normal equations over the free parameters, with the
/// factorisation of their damped normal matrix (for the geodesic acceleration).
struct DampedStep {
    delta: DVector<f64>,
    factor: nalgebra::Cholesky<f64, nalgebra::Dyn>,
    free: Vec<usize>,
}

impl State {
    /// One iteration from θ with `jm` the Jacobian there: damped steps at growing λ
    /// until one lowers χ² (then λ shrinks), or none is left to take.
    fn iterate(
        &mut self,
        f: &ResidualFn,
        jm: &DMatrix<f64>,
        bounds: &Bounds,
        rel_tol: f64,
        accelerate: bool,
    ) -> Iteration {
        let algebra = crate::prof::span(crate::prof::LM_ALGEBRA);
        let a = gram(jm);
        let g = jm.tr_mul(&DVector::from_column_slice(&self.r));
        drop(algebra);
        let dmax = a.diagonal().max().max(f64::MIN_POSITIVE);
        let a_diag: Vec<f64> = a.diagonal().iter().map(|d| d.max(1e-12 * dmax)).collect();
        // Only the first step tried at this θ may end the fit by its prediction: after a
        // rejected step λ grows, and a shorter, more damped step predicts less whatever
        // is left to gain (on exact data that stopped baseline fits far from the floor).
        let mut first_try = true;
        while self.lambda < 1e12 {
            let Some(step) = damped_step(&a, &g, self.lambda, dmax, &self.theta, bounds) else {
                first_try = false;
                self.lambda *= 10.0;
                continue;
            };
            let mut delta = step.delta;
            if first_try && step_would_converge(&g, &a, &delta, self.c2, rel_tol) {
                return Iteration::AtMinimum;
            }
            first_try = false;
            if accelerate {
                let (ch, free) = (&step.factor, &step.free);
                match geodesic_acceleration(f, &self.theta, &self.r, jm, &delta, ch, free, bounds) {
                    Some(acc)
                        if 2.0 * scaled_norm(&acc, &a_diag)
                            <= GEODESIC_RATIO * scaled_norm(&delta, &a_diag) =>
                    {
                        delta += 0.5 * acc;
                    }
                    // The path bends faster than the step could follow: a shorter step.
                    _ => {
                        self.lambda *= 10.0;
                        continue;
                    }
                }
            }
            if let Some(converged) = self.try_move(f, &delta, bounds, rel_tol) {
                self.lambda = (self.lambda / 10.0).max(1e-12);
                return Iteration::Moved { converged };
            }
            self.lambda *= 10.0;
        }
        Iteration::AtMinimum
    }

    /// Moves to θ + δ (clamped to the bounds) when χ² is finite and lower there; then
    /// whether the move meets the convergence test (relative decrease below `rel_tol`
    /// or largest scaled parameter change below `CONVERGED_STEP`). `None`: not moved.
    fn try_move(
        &mut self,
        f: &ResidualFn,
        delta: &DVector<f64>,
        bounds: &Bounds,
        rel_tol: f64,
    ) -> Option<bool> {
        let mut t2: Vec<f64> = self
            .theta
            .iter()
            .zip(delta.iter())
            .map(|(t, d)| t + d)
            .collect();
        clamp(&mut t2, bounds);
        let r2 = f(&t2).ok()?;
        let c2n = chi2(&r2);
        if !(c2n.is_finite() && c2n < self.c2) {
            return None;
        }
        let rel = (self.c2 - c2n) / self.c2.max(f64::MIN_POSITIVE);
        let step = t2
            .iter()
            .zip(&self.theta)
            .zip(&bounds.scales)
            .map(|((a, b), s)| ((a - b) / s.abs().max(1e-12)).abs())
            .fold(0.0, f64::max);
        self.theta = t2;
        self.r = r2;
        self.c2 = c2n;
        Some(rel < rel_tol || step < CONVERGED_STEP)
    }
}

/// The step of the damped normal equations `(A + λ diag A) δ = −g` at θ, with an active
/// set: a parameter at a bound whose step points outward is frozen and the step re-solved
/// for the others (a clamped step is often no descent). `None` when the free parameters'
/// damped matrix is not positive definite or the active set does not settle.
fn damped_step(
    a: &DMatrix<f64>,
    g: &DVector<f64>,
    lambda: f64,
    dmax: f64,
    theta: &[f64],
    bounds: &Bounds,
) -> Option<DampedStep> {
    let mut m = a.clone();
    for i in 0..m.nrows() {
        m[(i, i)] += lambda * a[(i, i)].max(1e-12 * dmax);
    }
    let mut frozen = vec![false; theta.len()];
    let mut delta = DVector::zeros(theta.len());
    for _ in 0..=theta.len() {
        let free: Vec<usize> = (0..theta.len()).filter(|&i| !frozen[i]).collect();
        let mf = DMatrix::from_fn(free.len(), free.len(), |r, c| m[(free[r], free[c])]);
        let gf = DVector::from_iterator(free.len(), free.iter().map(|&i| -g[i]));
        let ch = mf.cholesky()?;
        let df = ch.solve(&gf);
        delta.fill(0.0);
        for (k, &i) in free.iter().enumerate() {
            delta[i] = df[k];
        }
        let mut again = false;
        for &i in &free {
            let at_lo = theta[i] <= bounds.lower[i] && delta[i] < 0.0;
            let at_hi = theta[i] >= bounds.upper[i] && delta[i] > 0.0;
            if at_lo || at_hi {
                frozen[i] = true;
                again = true;
            }
        }
        if !again {
            return Some(DampedStep {
                delta,
                factor: ch,
                free,
            });
        }
    }
    None
}

/// (JᵀJ)⁺ by symmetric eigen-decomposition, dropping directions with eigenvalue below
/// 1e-12 of the largest (unidentifiable combinations get no variance, and are reported
/// by the caller as such).
pub fn covariance(jm: &DMatrix<f64>) -> DMatrix<f64> {
    // Column scaling first, so parameters of very different units do not hide each other.
    let p = jm.ncols();
    let norms: Vec<f64> = (0..p)
        .map(|j| jm.column(j).norm().max(f64::MIN_POSITIVE))
        .collect();
    let mut js = jm.clone();
    for j in 0..p {
        js.column_mut(j).scale_mut(1.0 / norms[j]);
    }
    let a = gram(&js);
    let eig = a.symmetric_eigen();
    let emax = eig.eigenvalues.max().max(f64::MIN_POSITIVE);
    let mut inv = DMatrix::zeros(p, p);
    for k in 0..p {
        let l = eig.eigenvalues[k];
        if l > 1e-12 * emax {
            let v = eig.eigenvectors.column(k);
            inv += (v * v.transpose()) / l;
        }
    }
    for i in 0..p {
        for j in 0..p {
            inv[(i, j)] /= norms[i] * norms[j];
        }
    }
    inv
}

#[cfg(test)]
mod tests {
    use super::*;
    /// Grouped columns are the dense Jacobian bit for bit, in fewer evaluations: three
    /// parameters each scaling its own block of rows (declared, disjoint) share one
    /// evaluation, a fourth reaching every row has its own.
    #[test]
    fn grouped_columns_are_the_dense_jacobian_in_fewer_evaluations() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        let calls = AtomicUsize::new(0);
        let xs: Vec<f64> = (0..12).map(|i| 0.3 + i as f64 * 0.17).collect();
        let f = |t: &[f64]| -> Result<Vec<f64>, CheckError> {
            calls.fetch_add(1, Ordering::Relaxed);
            Ok(xs
                .iter()
                .enumerate()
                .map(|(i, x)| (t[i / 4] * x).sin() * (t[3] * x).exp() - 0.1 * x)
                .collect())
        };
        let theta = [0.7, -1.3, 2.1, 0.4];
        let scales = [1.0, 0.5, 2.0, 0.1];
        let r0 = f(&theta).unwrap();
        let dense = jacobian(&f, &theta, &scales, &r0).unwrap();
        let rows = (0..3)
            .map(|g| Some((4 * g..4 * g + 4).collect()))
            .chain([None])
            .collect();
        let columns = Columns::grouped(rows, 12);
        assert_eq!(columns.evaluations(), 2);
        calls.store(0, Ordering::Relaxed);
        let grouped = jacobian_grouped(&f, &theta, &scales, &r0, &columns).unwrap();
        assert_eq!(calls.load(Ordering::Relaxed), 2);
        for (g, d) in grouped.iter().zip(dense.iter()) {
            assert_eq!(g.to_bits(), d.to_bits(), "{g} vs {d}");
        }
        // Against a reference other than the residual at θ: still the dense matrix.
        let r_ref: Vec<f64> = r0
            .iter()
            .enumerate()
            .map(|(i, r)| r + 1e-3 * i as f64)
            .collect();
        let dense = jacobian(&f, &theta, &scales, &r_ref).unwrap();
        calls.store(0, Ordering::Relaxed);
        let against = jacobian_grouped_against(&f, &theta, &scales, &r_ref, &columns).unwrap();
        assert_eq!(calls.load(Ordering::Relaxed), 3);
        for (g, d) in against.iter().zip(dense.iter()) {
            assert_eq!(g.to_bits(), d.to_bits(), "{g} vs {d}");
        }
        // Overlapping declarations are not grouped.
        let overlapping = Columns::grouped(vec![Some(vec![0, 1]), Some(vec![1, 2])], 3);
        assert_eq!(overlapping.evaluations(), 2);
    }

    /// A pole fitted to a smooth term runs off towards infinity with its residue growing
    /// as its frequency squared (`A/(w² − x²) → A/w²`): the plain steps crawl along that
    /// curved valley, the refit's take geodesic acceleration after `ACCELERATE_AFTER`
    /// iterations and get further in the same budget (χ² 7.6e-6 against 2.1e-5 after 16
    /// iterations, the pole 1.24 times as far out). A fit that converges before then
    /// is the plain one bit for bit.
    #[test]
    fn a_refit_crawling_along_a_curved_valley_is_accelerated() {
        let xs: Vec<f64> = (0..40).map(|i| i as f64 * 0.05).collect();
        let f = |t: &[f64]| -> Result<Vec<f64>, CheckError> {
            Ok(xs
                .iter()
                .map(|x| t[1] / (t[0] * t[0] - x * x) - (1.0 + 0.02 * x * x) + t[2])
                .collect())
        };
        let b = Bounds {
            lower: vec![2.5, f64::NEG_INFINITY, f64::NEG_INFINITY],
            upper: vec![f64::INFINITY; 3],
            scales: vec![0.01, 0.01, 0.01],
        };
        let start = [3.0, 9.0, 0.0];
        let n = 2 * ACCELERATE_AFTER;
        let plain = fit("test", &f, &start, &b, n).unwrap();
        let refit = fit("refit test", &f, &start, &b, n).unwrap();
        assert!(plain.iterations > ACCELERATE_AFTER, "{}", plain.iterations);
        assert!(
            refit.chi2 < 0.5 * plain.chi2,
            "accelerated χ² {:e} vs plain {:e}",
            refit.chi2,
            plain.chi2
        );
        assert!(
            refit.theta[0] > 1.2 * plain.theta[0],
            "{:?} vs {:?}",
            refit.theta,
            plain.theta
        );
        // Converged before the acceleration starts: the same fit.
        let short = |stage: &str| fit(stage, &f, &start, &b, ACCELERATE_AFTER).unwrap();
        let (p, r) = (short("test"), short("refit test"));
        assert_eq!(p.chi2.to_bits(), r.chi2.to_bits());
        assert!(p
            .theta
            .iter()
            .zip(&r.theta)
            .all(|(x, y)| x.to_bits() == y.to_bits()));
    }

    /// A last step that is tiny in scaled units but carries all of χ² (a very sensitive
    /// direction, as exact data give) is taken, not predicted away.
    #[test]
    fn a_tiny_step_carrying_all_of_chi2_is_taken() {
        let f = |t: &[f64]| -> Result<Vec<f64>, CheckError> {
            Ok(vec![1e12 * (t[0] - 1.0), t[1] - 2.0])
        };
        let b = Bounds {
            lower: vec![f64::NEG_INFINITY; 2],
            upper: vec![f64::INFINITY; 2],
            scales: vec![1.0, 1.0],
        };
        // The first step lands within the finite-difference slope's error, ~1e-11 off
        // (χ² ~ 100); the next is below `CONVERGED_STEP` in size and ends the fit once
        // taken, at the rounding of θ near 1 (χ² ~ 1e-4).
        let fit = fit("test", &f, &[1.0 + 1e-8, 2.0], &b, 20).unwrap();
        assert!(fit.chi2 < 1.0, "χ² {:e} at {:?}", fit.chi2, fit.theta);
    }

    #[test]
    fn fits_an_exponential_exactly() {
        // y = a e^{-b x}: noise-free data, the fit recovers (a, b) to 1e-9.
        let xs: Vec<f64> = (0..50).map(|i| i as f64 * 0.1).collect();
        let f = |t: &[f64]| -> Result<Vec<f64>, CheckError> {
            Ok(xs
                .iter()
                .map(|x| t[0] * (-t[1] * x).exp() - 2.5 * (-0.7 * x).exp())
                .collect())
        };
        let b = Bounds {
            lower: vec![f64::NEG_INFINITY; 2],
            upper: vec![f64::INFINITY; 2],
            scales: vec![1.0; 2],
        };
        let fit = fit("test", &f, &[1.0, 0.1], &b, 100).unwrap();
        assert!(
            (fit.theta[0] - 2.5).abs() < 1e-9 && (fit.theta[1] - 0.7).abs() < 1e-9,
            "{:?}",
            fit.theta
        );
        assert!(fit.converged);
    }
}
