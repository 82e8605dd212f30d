//! Weighted non-linear least squares by Levenberg–Marquardt with finite-difference
//! Jacobians (columns evaluated in parallel; the result does not depend on the thread
//! count because each column is computed independently and stored in place).
//!
//! Minimises χ²(θ) = ‖r(θ)‖² where r is the noise-normalised residual vector.
//! Step: (JᵀJ + λ diag JᵀJ) δ = −Jᵀr (Marquardt 1963), projected onto the bounds.

use crate::error::CheckError;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

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

/// Rows per block of [`thin_qr`]: a block of a 54 000 × 60 Jacobian (1 024 × 60 × 8
/// bytes = 0.5 MB) is factorised within the L2 cache.
const QR_BLOCK: usize = 1024;

/// Thin QR `A = Q R` (Q n × p with orthonormal columns, R p × p upper triangular) of a
/// tall matrix (n ≥ p), by row blocks (TSQR, Demmel, Grigori, Hoemmen & Langou 2012):
/// each block of `QR_BLOCK` rows (the last takes the remainder) factorised by
/// Householder reflections, the blocks' stacked R factorised again, and each block of Q
/// the product of its own Q and its slice of the second one.
///
/// Why: nalgebra's SVD of the check's Jacobians (54 000 rows × 20–60 columns, 9–27 MB)
/// bidiagonalises the whole matrix with one pass per reflection beyond the cache and
/// accumulates U there too; the screening took two per step (the span of the current
/// model and the chord solver) and the gauge checks one per refit. Here the passes stay in
/// cache, the blocks run in parallel, and the SVD is of the p × p factor R: A = (Q U_R) S
/// V_Rᵀ has A's singular values (to rounding). Householder QR is backward stable block by
/// block (columnwise), so this is as accurate as one Householder QR; the blocks are fixed
/// and each computed in one piece, so the result does not depend on the thread count.
pub fn thin_qr(a: &DMatrix<f64>) -> (DMatrix<f64>, DMatrix<f64>) {
    let (n, p) = a.shape();
    assert!(n >= p, "thin QR of a wide matrix ({n} × {p})");
    let block = QR_BLOCK.max(p);
    let nb = (n / block).max(1);
    if nb == 1 {
        let qr = a.clone().qr();
        return (qr.q(), qr.r());
    }
    let ranges: Vec<(usize, usize)> = (0..nb)
        .map(|i| (i * block, if i + 1 == nb { n } else { (i + 1) * block }))
        .collect();
    let parts: Vec<(DMatrix<f64>, DMatrix<f64>)> = ranges
        .par_iter()
        .map(|&(s, e)| {
            let qr = a.rows(s, e - s).into_owned().qr();
            (qr.q(), qr.r())
        })
        .collect();
    let mut stacked = DMatrix::zeros(nb * p, p);
    for (i, (_, r)) in parts.iter().enumerate() {
        stacked.rows_mut(i * p, p).copy_from(r);
    }
    let top = stacked.qr();
    let (qt, r) = (top.q(), top.r());
    let blocks: Vec<DMatrix<f64>> = parts
        .par_iter()
        .enumerate()
        .map(|(i, (qi, _))| qi * qt.rows(i * p, p))
        .collect();
    let mut q = DMatrix::zeros(n, p);
    for (&(s, e), b) in ranges.iter().zip(blocks) {
        q.rows_mut(s, e - s).copy_from(&b);
    }
    (q, r)
}

/// The thin SVD `A = U S Vᵀ` of a tall matrix (n ≥ p) through [`thin_qr`]: the SVD of
/// R (p × p), with U = Q U_R. Singular values in decreasing order (nalgebra's `svd`).
/// A wide or empty matrix takes nalgebra's SVD directly.
pub fn thin_svd(a: &DMatrix<f64>) -> nalgebra::SVD<f64, nalgebra::Dyn, nalgebra::Dyn> {
    if a.ncols() == 0 || a.nrows() < a.ncols() {
        return a.clone().svd(true, true);
    }
    let (q, r) = thin_qr(a);
    let mut svd = r.svd(true, true);
    svd.u = svd.u.map(|u| q * u);
    svd
}

/// Rows per block of [`gram`]: a block of a 54 000 × 40 Jacobian's columns (40 × 256 × 8
/// bytes = 80 kB) stays in cache while every column pair is accumulated over it.
const GRAM_BLOCK: usize = 256;

/// The normal matrix `JᵀJ`, bit-identical to nalgebra's `j.tr_mul(j)` but computed in one
/// pass over `J` instead of one pass per entry.
///
/// Why: `tr_mul` takes each entry as a separate dot product of two whole columns. For the
/// check's Jacobians (2N ≈ 54 000 rows × 20–60 parameters, 17 MB) the p² column reads go
/// to main memory, and the LM fits spent most of their time there. Here the rows are
/// walked in cache-sized blocks and every pair (i ≤ j) is accumulated over a block
/// before the next is read.
///
/// Bit-identity (so fits and reports do not move): nalgebra's dot product sums rows
/// k ≡ m (mod 8) into accumulator m over the rows below the last multiple of 8, then
/// forms `((((0 + (a₀+a₄)) + (a₁+a₅)) + (a₂+a₆)) + (a₃+a₇))` and adds the remaining rows
/// one by one. The same accumulators receive the same products in the same order here
/// (blocks are multiples of 8 rows and are visited in order), and `x·y = y·x` exactly, so
/// the lower triangle is the upper one mirrored.
pub fn gram(j: &DMatrix<f64>) -> DMatrix<f64> {
    blocked_tr_mul(j, j, true)
}

/// `AᵀB`, bit-identical to nalgebra's `a.tr_mul(b)`, in one cache-blocked pass (see
/// [`gram`]): the projections of candidate Jacobians onto the current model's span.
pub fn tr_mul(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    blocked_tr_mul(a, b, false)
}

/// `AᵀB` by 8-accumulator dot products over row blocks ([`gram`]); with `symmetric`
/// (A = B) only the pairs i ≤ j are summed and mirrored.
fn blocked_tr_mul(a: &DMatrix<f64>, b: &DMatrix<f64>, symmetric: bool) -> DMatrix<f64> {
    assert_eq!(a.nrows(), b.nrows(), "AᵀB: row counts differ");
    let (n, pa, pb) = (a.nrows(), a.ncols(), b.ncols());
    let n8 = n - n % 8;
    fn col(m: &DMatrix<f64>, c: usize) -> &[f64] {
        let n = m.nrows();
        &m.as_slice()[c * n..(c + 1) * n]
    }
    let first = |i: usize| if symmetric { i } else { 0 };
    let mut acc = vec![[0.0f64; 8]; pa * pb];
    let st_a = block_states(a, n8);
    let st_b = if symmetric {
        st_a.clone()
    } else {
        block_states(b, n8)
    };
    let nb = n8.div_ceil(GRAM_BLOCK);
    let mut start = 0;
    while start < n8 {
        let end = (start + GRAM_BLOCK).min(n8);
        let blk = start / GRAM_BLOCK;
        for i in 0..pa {
            let sa = st_a[i * nb + blk];
            let skip = |j: usize| adds_nothing(sa, st_b[j * nb + blk]);
            let ca = &col(a, i)[start..end];
            let mut j = first(i);
            // Two columns of B per pass over A's column: each x is loaded once for two
            // products, and each accumulator still receives its own products in order.
            while j + 1 < pb {
                if skip(j) && skip(j + 1) {
                    j += 2;
                    continue;
                }
                let (cb0, cb1) = (&col(b, j)[start..end], &col(b, j + 1)[start..end]);
                let (mut s0, mut s1) = (acc[i * pb + j], acc[i * pb + j + 1]);
                for ((x, y0), y1) in ca
                    .chunks_exact(8)
                    .zip(cb0.chunks_exact(8))
                    .zip(cb1.chunks_exact(8))
                {
                    for m in 0..8 {
                        s0[m] += x[m] * y0[m];
                        s1[m] += x[m] * y1[m];
                    }
                }
                (acc[i * pb + j], acc[i * pb + j + 1]) = (s0, s1);
                j += 2;
            }
            if j < pb && !skip(j) {
                let cb = &col(b, j)[start..end];
                let mut s = acc[i * pb + j];
                for (x, y) in ca.chunks_exact(8).zip(cb.chunks_exact(8)) {
                    for m in 0..8 {
                        s[m] += x[m] * y[m];
                    }
                }
                acc[i * pb + j] = s;
            }
        }
        start = end;
    }
    let mut out = DMatrix::zeros(pa, pb);
    for i in 0..pa {
        for j in first(i)..pb {
            let s = &acc[i * pb + j];
            let mut res = 0.0;
            res += s[0] + s[4];
            res += s[1] + s[5];
            res += s[2] + s[6];
            res += s[3] + s[7];
            let (ca, cb) = (col(a, i), col(b, j));
            for k in n8..n {
                res += ca[k] * cb[k];
            }
            out[(i, j)] = res;
            if symmetric {
                out[(j, i)] = res;
            }
        }
    }
    out
}

/// A row block of a column with only zeros ([`block_states`]).
const ZERO: u8 = 0;
/// A row block of a column with a non-finite entry.
const NON_FINITE: u8 = 2;

/// The state of each column of `m` in each [`GRAM_BLOCK`] of its first `n8` rows
/// (`[column × block]`): [`ZERO`], finite with a non-zero (1) or [`NON_FINITE`].
///
/// Why: a pair of column blocks one of which is zero and the other finite adds only
/// products ±0 to the accumulators of [`blocked_tr_mul`], which leave them as they are
/// (an accumulator starts at +0, and a sum is −0 only when both terms are), so the pair
/// is skipped bit-identically. Grouped finite-difference columns (an elastic mode's
/// residues, a channel's gain) are zero outside their FRFs. (0 · ∞ is no zero: such a
/// pair is summed.)
fn block_states(m: &DMatrix<f64>, n8: usize) -> Vec<u8> {
    let n = m.nrows();
    (0..m.ncols())
        .flat_map(|c| {
            let col = &m.as_slice()[c * n..c * n + n8];
            col.chunks(GRAM_BLOCK).map(|b| {
                // x · 0 is ±0 for a finite x and NaN otherwise; both tests by lanes.
                let (mut fin, mut nz) = ([0.0f64; 8], [false; 8]);
                for ch in b.chunks_exact(8) {
                    for k in 0..8 {
                        fin[k] += ch[k] * 0.0;
                        nz[k] |= ch[k] != 0.0;
                    }
                }
                if fin.iter().any(|f| f.is_nan()) {
                    NON_FINITE
                } else if nz.iter().any(|z| *z) {
                    1
                } else {
                    ZERO
                }
            })
        })
        .collect()
}

/// Whether the pair of column blocks in states `x` and `y` adds nothing ([`block_states`]).
fn adds_nothing(x: u8, y: u8) -> bool {
    (x == ZERO && y != NON_FINITE) || (y == ZERO && x != NON_FINITE)
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
    let mut r = f(&theta).map_err(|e| CheckError::Fit {
        stage: stage.into(),
        problem: format!("cannot evaluate the starting model: {e}"),
    })?;
    let mut c2 = chi2(&r);
    let rel_tol = converged_rel(r.len());
    let mut jm = jacobian_grouped(f, &theta, &bounds.scales, &r, columns)?;
    let mut lambda = 1e-3;
    let mut converged = false;
    // `jm` is the Jacobian at the current θ (no step accepted since it was taken).
    let mut jm_current = max_iter == 0;
    let mut it = 0;
    while it < max_iter {
        it += 1;
        let algebra = crate::prof::span(crate::prof::LM_ALGEBRA);
        let a = gram(&jm);
        let g = jm.tr_mul(&DVector::from_column_slice(&r));
        drop(algebra);
        let dmax = a.diagonal().max().max(f64::MIN_POSITIVE);
        let a_diag: Vec<f64> = a.diagonal().iter().map(|d| d.max(1e-12 * dmax)).collect();
        let mut improved = false;
        let mut stalled = false;
        // Only the first step tried at this θ may end the fit by its prediction: after a
        // rejected step λ grows, and a shorter, more damped step predicts less whatever
        // is left to gain (on exact data that stopped baseline fits far from the floor).
        let mut first_try = true;
        while lambda < 1e12 {
            let mut m = a.clone();
            for i in 0..m.nrows() {
                m[(i, i)] += lambda * a[(i, i)].max(1e-12 * dmax);
            }
            // Active set: a parameter at a bound whose step points outward is frozen and
            // the step re-solved for the others (a clamped step is often no descent).
            let mut frozen = vec![false; theta.len()];
            let mut delta = DVector::zeros(theta.len());
            let mut solved = false;
            // The factorisation of the free parameters' damped normal matrix.
            let mut factor = None;
            for _ in 0..=theta.len() {
                let free: Vec<usize> = (0..theta.len()).filter(|&i| !frozen[i]).collect();
                let mf = DMatrix::from_fn(free.len(), free.len(), |r, c| m[(free[r], free[c])]);
                let gf = DVector::from_iterator(free.len(), free.iter().map(|&i| -g[i]));
                let Some(ch) = mf.cholesky() else {
                    break;
                };
                let df = ch.solve(&gf);
                factor = Some((ch, free.clone()));
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
                    solved = true;
                    break;
                }
            }
            if !solved {
                first_try = false;
                lambda *= 10.0;
                continue;
            }
            if first_try && step_would_converge(&g, &a, &delta, c2, rel_tol) {
                stalled = true;
                break;
            }
            first_try = false;
            if refit && it > ACCELERATE_AFTER {
                let (ch, free) = factor.as_ref().expect("solved");
                match geodesic_acceleration(f, &theta, &r, &jm, &delta, ch, free, bounds) {
                    Some(a)
                        if 2.0 * scaled_norm(&a, &a_diag)
                            <= GEODESIC_RATIO * scaled_norm(&delta, &a_diag) =>
                    {
                        delta += 0.5 * a;
                    }
                    // The path bends faster than the step could follow: a shorter step.
                    _ => {
                        lambda *= 10.0;
                        continue;
                    }
                }
            }
            let mut t2: Vec<f64> = theta.iter().zip(delta.iter()).map(|(t, d)| t + d).collect();
            clamp(&mut t2, bounds);
            match f(&t2) {
                Ok(r2) => {
                    let c2n = chi2(&r2);
                    if c2n.is_finite() && c2n < c2 {
                        let rel = (c2 - c2n) / c2.max(f64::MIN_POSITIVE);
                        let step = t2
                            .iter()
                            .zip(&theta)
                            .zip(&bounds.scales)
                            .map(|((a, b), s)| ((a - b) / s.abs().max(1e-12)).abs())
                            .fold(0.0, f64::max);
                        theta = t2;
                        r = r2;
                        c2 = c2n;
                        lambda = (lambda / 10.0).max(1e-12);
                        improved = true;
                        if rel < rel_tol || step < CONVERGED_STEP {
                            converged = true;
                        }
                        break;
                    }
                    lambda *= 10.0;
                }
                Err(_) => lambda *= 10.0,
            }
        }
        if stalled || !improved {
            // The next step would end the fit by the convergence test below, or no
            // descent direction is left at any damping: a minimum (to working
            // precision). θ and r did not move since `jm` was taken, so it is already
            // the Jacobian at the solution (the same forward differences, bit for bit).
            converged = true;
            jm_current = true;
            break;
        }
        if converged {
            break;
        }
        jacobian_into(f, &theta, &bounds.scales, &r, None, columns, &mut jm)?;
    }
    // The Jacobian at the solution, for standard errors and score tests: the last one
    // taken when no step was accepted after it (`max_iter` = 0 or no descent left),
    // otherwise one more.
    if !jm_current {
        jacobian_into(f, &theta, &bounds.scales, &r, None, columns, &mut jm)?;
    }
    Ok(Fit {
        theta,
        residual: r,
        chi2: c2,
        jacobian: jm,
        iterations: it,
        converged,
    })
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

    /// `gram` is nalgebra's `tr_mul` bit for bit: row counts below, at and across the
    /// 8-row unrolling and the block size, values of mixed sign and magnitude (so that
    /// any change of summation order would show in the last bits).
    #[test]
    fn gram_and_tr_mul_are_nalgebras_bit_for_bit() {
        let mut state = 0x2545f4914f6cdd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for (n, p) in [
            (0, 3),
            (1, 1),
            (7, 2),
            (8, 3),
            (13, 4),
            (255, 5),
            (256, 6),
            (777, 9),
            (2 * GRAM_BLOCK + 11, 17),
        ] {
            let mut j = DMatrix::from_fn(n, p, |_, c| next() * 10f64.powi(c as i32 % 7 - 3));
            // Zero runs as grouped finite differences leave them (whole blocks, a column
            // zero but in one row, an all-zero column), where the blocks are skipped.
            for c in (1..p).step_by(2) {
                for r in 0..n {
                    if !(r / (GRAM_BLOCK / 2) + c).is_multiple_of(3) && (c % 4 != 1 || r != n / 2) {
                        j[(r, c)] = if r.is_multiple_of(2) { 0.0 } else { -0.0 };
                    }
                }
            }
            let want = j.tr_mul(&j);
            let got = gram(&j);
            for (g, w) in got.iter().zip(want.iter()) {
                assert_eq!(g.to_bits(), w.to_bits(), "n = {n}, p = {p}: {g} vs {w}");
            }
            let k = DMatrix::from_fn(n, p / 2 + 1, |_, c| next() * 10f64.powi(3 - c as i32 % 5));
            let want = j.tr_mul(&k);
            let got = tr_mul(&j, &k);
            assert_eq!(got.shape(), want.shape());
            for (g, w) in got.iter().zip(want.iter()) {
                assert_eq!(
                    g.to_bits(),
                    w.to_bits(),
                    "JᵀK, n = {n}, p = {p}: {g} vs {w}"
                );
            }
        }
    }

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

    /// The blocked thin QR and SVD against nalgebra's on a tall matrix of five blocks and
    /// a remainder, columns scaled over 12 decades, one nearly a combination of two
    /// others (condition ~1e8): A = QR and QᵀQ = I to 1e-14, the singular values to
    /// 1e-13 of the largest (Householder rounding, ~n^½ ε), U's span the same where the
    /// singular values are apart; the same bits on one and two threads.
    #[test]
    fn thin_qr_and_svd_match_a_dense_factorisation() {
        let mut state = 0x9e3779b97f4a7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let (n, p) = (5 * QR_BLOCK + 77, 9);
        let mut a = DMatrix::from_fn(n, p, |_, _| next());
        for r in 0..n {
            a[(r, 4)] = a[(r, 1)] - 2.0 * a[(r, 2)] + 1e-8 * a[(r, 4)];
        }
        for c in 0..p {
            a.column_mut(c)
                .scale_mut(10f64.powi(2 * (c as i32 % 7) - 6));
        }
        let (q, r) = thin_qr(&a);
        assert_eq!((q.shape(), r.shape()), ((n, p), (p, p)));
        for c in 0..p {
            let err = (&q * r.column(c) - a.column(c)).norm();
            assert!(err <= 1e-14 * a.column(c).norm(), "column {c}: {err:e}");
            for k in 0..c {
                assert_eq!(r[(c, k)], 0.0, "R is upper triangular");
            }
        }
        let eye = q.tr_mul(&q) - DMatrix::identity(p, p);
        assert!(eye.amax() < 1e-14, "QᵀQ − I: {:e}", eye.amax());
        // Singular values and left vectors of equally scaled columns.
        let mut b = a.clone();
        for c in 0..p {
            let norm = b.column(c).norm();
            b.column_mut(c).scale_mut(1.0 / norm);
        }
        let (want, got) = (b.clone().svd(true, true), thin_svd(&b));
        let smax = want.singular_values[0];
        for (g, w) in got.singular_values.iter().zip(want.singular_values.iter()) {
            assert!((g - w).abs() <= 1e-13 * smax, "{g:e} vs {w:e}");
        }
        let (uw, ug) = (want.u.as_ref().unwrap(), got.u.as_ref().unwrap());
        for k in 0..p - 1 {
            // |u_kᵀ u'_k| = 1 up to the rounding over the gap to the neighbours.
            let dot = uw.column(k).dot(&ug.column(k)).abs();
            assert!((dot - 1.0).abs() < 1e-10, "u_{k}: {dot}");
        }
        let solve = |svd: &nalgebra::SVD<f64, nalgebra::Dyn, nalgebra::Dyn>| {
            svd.solve(&b.column(0).into_owned(), 1e-10).unwrap()
        };
        let (xw, xg) = (solve(&want), solve(&got));
        assert!((&xw - &xg).norm() < 1e-8 * xw.norm(), "{xw} vs {xg}");
        let on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| thin_qr(&a))
        };
        let ((q1, r1), (q2, r2)) = (on(1), on(2));
        assert!(q1
            .iter()
            .zip(q2.iter())
            .all(|(x, y)| x.to_bits() == y.to_bits()));
        assert!(r1
            .iter()
            .zip(r2.iter())
            .all(|(x, y)| x.to_bits() == y.to_bits()));
    }

    /// A zero block against an infinite entry is summed, as nalgebra does (0 · ∞ is NaN).
    #[test]
    fn gram_sums_a_zero_block_against_an_infinite_entry() {
        let mut j = DMatrix::from_fn(600, 3, |r, c| (r + 3 * c) as f64 * 0.01 + 1.0);
        for r in 0..GRAM_BLOCK {
            j[(r, 0)] = 0.0;
        }
        j[(5, 1)] = f64::INFINITY;
        let (want, got) = (j.tr_mul(&j), gram(&j));
        for (g, w) in got.iter().zip(want.iter()) {
            assert!(
                g.to_bits() == w.to_bits() || (g.is_nan() && w.is_nan()),
                "{g} vs {w}"
            );
        }
        assert!(got[(0, 1)].is_nan());
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
