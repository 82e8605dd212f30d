//! Least squares and small linear solves: thin QR, the Gram/Cholesky path of [`TallLs`],
//! and a pivoted LU for small square systems. Sequential, like every kernel here.

use super::kernels::{dot, gram, mul_add, t_mul};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::qr::no_pivoting::{factor, solve};
use faer::prelude::*;
use faer::{Conj, Par};

/// A thin QR factorisation `A = Q R` of a tall real matrix (Householder, faer).
#[derive(Debug)]
pub struct TallQr {
    qr: Mat<f64>,
    q_coeff: Mat<f64>,
}

impl TallQr {
    /// Factorises `a` (`m ≥ n > 0` rows and columns).
    pub fn new(a: Mat<f64>) -> Self {
        let (m, n) = a.shape();
        assert!(m >= n && n > 0, "TallQr needs a tall matrix, got {m}×{n}");
        let bs = factor::recommended_block_size::<f64>(m, n);
        let mut qr = a;
        let mut q_coeff = Mat::zeros(bs, n);
        let mut buf = MemBuffer::new(factor::qr_in_place_scratch::<f64>(
            m,
            n,
            bs,
            Par::Seq,
            Default::default(),
        ));
        factor::qr_in_place(
            qr.as_mut(),
            q_coeff.as_mut(),
            Par::Seq,
            MemStack::new(&mut buf),
            Default::default(),
        );
        Self { qr, q_coeff }
    }

    /// Number of columns of `A`.
    #[cfg(test)]
    fn ncols(&self) -> usize {
        self.qr.ncols()
    }

    /// Entry `(i, j)` of the triangular factor R (`i ≤ j`).
    pub fn r(&self, i: usize, j: usize) -> f64 {
        if i <= j {
            self.qr[(i, j)]
        } else {
            0.0
        }
    }

    /// Least-squares solution of `A x = b` for every column of `b`; returns
    /// `(x, residual sum of squares per column)`.
    pub fn solve(&self, b: &Mat<f64>) -> (Mat<f64>, Vec<f64>) {
        let (m, n) = self.qr.shape();
        let k = b.ncols();
        let mut rhs = b.clone();
        let bs = self.q_coeff.nrows();
        let mut buf = MemBuffer::new(solve::solve_lstsq_in_place_scratch::<f64>(
            m,
            n,
            bs,
            k,
            Par::Seq,
        ));
        solve::solve_lstsq_in_place_with_conj(
            self.qr.as_ref(),
            self.q_coeff.as_ref(),
            self.qr.as_ref(),
            Conj::No,
            rhs.as_mut(),
            Par::Seq,
            MemStack::new(&mut buf),
        );
        // After applying Qᵀ, rows n.. hold the residual's coordinates.
        let rss = (0..k)
            .map(|j| {
                let c = &rhs.col(j).try_as_col_major().unwrap().as_slice()[n..m];
                dot(c, c)
            })
            .collect();
        (Mat::from_fn(n, k, |i, j| rhs[(i, j)]), rss)
    }

    /// `(AᵀA)⁻¹ = R⁻¹R⁻ᵀ`, the unscaled covariance of least-squares coefficients.
    #[cfg(test)]
    fn inverse_gram(&self) -> Mat<f64> {
        inverse_gram_of(self.ncols(), |i, j| self.qr[(i, j)])
    }
}

/// `(RᵀR)⁻¹ = R⁻¹R⁻ᵀ` for the upper-triangular `n×n` factor with entries `r(i, j)`.
pub fn inverse_gram_of(n: usize, r: impl Fn(usize, usize) -> f64) -> Mat<f64> {
    // Invert the upper-triangular R by back substitution, column by column.
    let mut rinv = Mat::<f64>::zeros(n, n);
    for j in 0..n {
        rinv[(j, j)] = 1.0 / r(j, j);
        for i in (0..j).rev() {
            let mut s = 0.0;
            for l in i + 1..=j {
                s += r(i, l) * rinv[(l, j)];
            }
            rinv[(i, j)] = -s / r(i, i);
        }
    }
    Mat::from_fn(n, n, |i, j| {
        (i.max(j)..n).map(|l| rinv[(i, l)] * rinv[(j, l)]).sum()
    })
}

/// Upper-triangular Cholesky factor `R` (`RᵀR = G`) of the symmetric matrix `g`, or
/// `None` when `g` is not positive definite to working precision.
pub fn cholesky_upper(g: &Mat<f64>) -> Option<Mat<f64>> {
    let n = g.nrows();
    let mut r = Mat::<f64>::zeros(n, n);
    for j in 0..n {
        for i in 0..j {
            let mut v = g[(i, j)];
            for l in 0..i {
                v -= r[(l, i)] * r[(l, j)];
            }
            r[(i, j)] = v / r[(i, i)];
        }
        let mut d = g[(j, j)];
        for l in 0..j {
            d -= r[(l, j)] * r[(l, j)];
        }
        if !d.is_finite() || d <= 0.0 {
            return None;
        }
        r[(j, j)] = d.sqrt();
    }
    Some(r)
}

/// Whether the Cholesky factor `r` of the Gram matrix of a normalised basis serves for
/// least squares (see [`TallLs`]): `None` below [`TallLs::GRAM_LIMIT`], else whether a
/// refinement step is needed (below [`TallLs::REFINE_BELOW`]).
pub fn gram_usable(r: &Mat<f64>) -> Option<bool> {
    let rd: Vec<f64> = (0..r.nrows()).map(|i| r[(i, i)]).collect();
    let lo = rd.iter().cloned().fold(f64::INFINITY, f64::min);
    let hi = rd.iter().cloned().fold(0.0, f64::max);
    (lo > TallLs::GRAM_LIMIT * hi).then_some(lo < TallLs::REFINE_BELOW * hi)
}

/// `(RᵀR)⁻¹ c` for every column of `c`, `R` upper triangular.
pub fn cholesky_solve(r: &Mat<f64>, c: &mut Mat<f64>) {
    let n = r.nrows();
    for j in 0..c.ncols() {
        for i in 0..n {
            let mut v = c[(i, j)];
            for l in 0..i {
                v -= r[(l, i)] * c[(l, j)];
            }
            c[(i, j)] = v / r[(i, i)];
        }
        for i in (0..n).rev() {
            let mut v = c[(i, j)];
            for l in i + 1..n {
                v -= r[(i, l)] * c[(l, j)];
            }
            c[(i, j)] = v / r[(i, i)];
        }
    }
}

/// Least squares `min ‖A x − b‖` on a tall matrix with normalised columns, for many
/// right-hand sides.
///
/// While the columns are well conditioned (smallest/largest diagonal of R above
/// [`TallLs::GRAM_LIMIT`]), R is the Cholesky factor of the Gram matrix `AᵀA` (one
/// matrix product); below [`TallLs::REFINE_BELOW`] the solution takes one step of
/// iterative refinement on the residual (corrected semi-normal equations, Björck 1987),
/// as accurate as Householder QR at that conditioning. Every pass over the tall data is
/// a matrix product, 2–4× cheaper than applying Householder reflections. Otherwise it is
/// [`TallQr`].
#[derive(Debug)]
pub struct TallLs {
    a: Mat<f64>,
    kind: LsKind,
}

#[derive(Debug)]
enum LsKind {
    /// Upper-triangular Cholesky factor of `AᵀA`, and whether a refinement step is
    /// needed (see [`TallLs::REFINE_BELOW`]).
    Gram(Mat<f64>, bool),
    Qr(TallQr),
}

impl TallLs {
    /// Below this ratio of the smallest to the largest diagonal entry of R (condition
    /// number above ~10⁴, 10⁸ for the Gram matrix), Householder QR is used.
    pub const GRAM_LIMIT: f64 = 1e-4;
    /// Above this ratio (condition number below ~100) the semi-normal solution is
    /// already accurate to `κ²ε ≲ 10⁻¹²` relative and the refinement step is skipped.
    pub const REFINE_BELOW: f64 = 1e-2;

    /// Prepares the solve of `min ‖a x − b‖`: Cholesky of the Gram matrix when well conditioned, else Householder QR.
    pub fn new(a: Mat<f64>) -> Self {
        let (m, n) = a.shape();
        assert!(m >= n && n > 0, "TallLs needs a tall matrix, got {m}×{n}");
        let g = gram(&a);
        if let Some(r) = cholesky_upper(&g) {
            if let Some(refine) = gram_usable(&r) {
                return Self {
                    a,
                    kind: LsKind::Gram(r, refine),
                };
            }
        }
        let qr = TallQr::new(a.clone());
        Self {
            a,
            kind: LsKind::Qr(qr),
        }
    }

    /// Number of columns of `A`.
    pub fn ncols(&self) -> usize {
        self.a.ncols()
    }

    /// The matrix A.
    pub fn matrix(&self) -> &Mat<f64> {
        &self.a
    }

    /// The matrix A back, for reuse as the storage of another matrix of its shape.
    pub fn into_matrix(self) -> Mat<f64> {
        self.a
    }

    /// Entry `(i, j)` of the triangular factor R (`i ≤ j`; up to the signs of its rows,
    /// the same R for both methods).
    pub fn r(&self, i: usize, j: usize) -> f64 {
        match &self.kind {
            LsKind::Gram(r, _) => {
                if i <= j {
                    r[(i, j)]
                } else {
                    0.0
                }
            }
            LsKind::Qr(qr) => qr.r(i, j),
        }
    }

    /// |diagonal of R|: its smallest/largest ratio bounds the conditioning of the basis.
    pub fn r_diag(&self) -> Vec<f64> {
        (0..self.ncols()).map(|i| self.r(i, i).abs()).collect()
    }

    /// `(RᵀR)⁻¹ c` for every column of `c` (the Gram kind only).
    fn gram_solve(&self, c: &mut Mat<f64>) {
        if let LsKind::Gram(r, _) = &self.kind {
            cholesky_solve(r, c);
        }
    }

    /// As [`TallLs::solve`], the residuals overwriting `b` (no copy of the data).
    pub fn solve_into(&self, b: Mat<f64>) -> (Mat<f64>, Mat<f64>, Vec<f64>) {
        let mut resid = b;
        let x = match &self.kind {
            LsKind::Gram(_, refine) => {
                let mut x = t_mul(&self.a, &resid);
                self.gram_solve(&mut x);
                mul_add(&mut resid, &self.a, &x, -1.0);
                if *refine {
                    // One refinement step: x += (AᵀA)⁻¹Aᵀr, r −= A·dx.
                    let mut dx = t_mul(&self.a, &resid);
                    self.gram_solve(&mut dx);
                    mul_add(&mut resid, &self.a, &dx, -1.0);
                    x + dx
                } else {
                    x
                }
            }
            LsKind::Qr(qr) => {
                let (x, _) = qr.solve(&resid);
                mul_add(&mut resid, &self.a, &x, -1.0);
                x
            }
        };
        let rss = (0..resid.ncols())
            .map(|j| {
                let c = resid.col(j).try_as_col_major().unwrap().as_slice();
                dot(c, c)
            })
            .collect();
        (x, resid, rss)
    }

    /// `(AᵀA)⁻¹ = R⁻¹R⁻ᵀ`, the unscaled covariance of least-squares coefficients.
    pub fn inverse_gram(&self) -> Mat<f64> {
        inverse_gram_of(self.ncols(), |i, j| self.r(i, j))
    }
}

/// Solves the small symmetric system `A x = b` (LU with partial pivoting, sequential).
/// Returns `None` when `A` is numerically singular.
pub fn solve_square(a: &Mat<f64>, b: &Mat<f64>) -> Option<Mat<f64>> {
    let (n, k) = (a.nrows(), b.ncols());
    let m: Vec<f64> = (0..n * n).map(|i| a[(i / n, i % n)]).collect();
    let x: Vec<f64> = (0..n * k).map(|i| b[(i / k, i % k)]).collect();
    let x = solve_rows(m, x, n, k)?;
    Some(Mat::from_fn(n, k, |i, j| x[i * k + j]))
}

rbprops_core::avx_fn! {
    /// [`solve_square`] on row-major storage: `m` is `A` (`n×n`), `x` is `B` (`n×k`),
    /// both consumed; returns `X = A⁻¹B` row-major.
    ///
    /// Gaussian elimination with partial pivoting: the systems here are ≤ ~60 unknowns,
    /// and a hand-written kernel over plain slices keeps the operation order fixed.
    pub fn solve_rows(m: Vec<f64>, x: Vec<f64>, n: usize, k: usize) -> Option<Vec<f64>> {
        let (mut m, mut x) = (m, x);
        let scale = m.iter().map(|v| v.abs()).fold(0.0f64, f64::max);
        if !(scale > 0.0) || !scale.is_finite() {
            return None;
        }
        for c in 0..n {
            let p = (c..n)
                .max_by(|&i, &j| m[i * n + c].abs().total_cmp(&m[j * n + c].abs()))
                .unwrap();
            if m[p * n + c].abs() <= 1e-14 * scale {
                return None;
            }
            if p != c {
                swap_rows(&mut m, n, c, p);
                swap_rows(&mut x, k, c, p);
            }
            let (top, below) = m.split_at_mut((c + 1) * n);
            let (xtop, xbelow) = x.split_at_mut((c + 1) * k);
            let (pivot_row, xpivot) = (&top[c * n..], &xtop[c * k..]);
            let d = pivot_row[c];
            for (row, xrow) in below.chunks_exact_mut(n).zip(xbelow.chunks_exact_mut(k)) {
                let f = row[c] / d;
                if f != 0.0 {
                    for (v, u) in row[c..].iter_mut().zip(&pivot_row[c..]) {
                        *v -= f * u;
                    }
                    for (v, u) in xrow.iter_mut().zip(xpivot) {
                        *v -= f * u;
                    }
                }
            }
        }
        for j in 0..k {
            for i in (0..n).rev() {
                let mut s = x[i * k + j];
                for l in i + 1..n {
                    s -= m[i * n + l] * x[l * k + j];
                }
                x[i * k + j] = s / m[i * n + i];
            }
        }
        Some(x)
    }
}

/// Swaps rows `a` and `b` of the row-major matrix `m` with `w` columns.
fn swap_rows(m: &mut [f64], w: usize, a: usize, b: usize) {
    let (lo, hi) = (a.min(b), a.max(b));
    let (head, tail) = m.split_at_mut(hi * w);
    head[lo * w..(lo + 1) * w].swap_with_slice(&mut tail[..w]);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lstsq_recovers_exact_coefficients_and_rss() {
        let a = Mat::from_fn(7, 3, |i, j| ((i + 1) as f64).powi(j as i32));
        let x = [0.5, -2.0, 0.25];
        let b = Mat::from_fn(7, 1, |i, _| (0..3).map(|j| a[(i, j)] * x[j]).sum());
        let (sol, rss) = TallQr::new(a.clone()).solve(&b);
        for j in 0..3 {
            assert!((sol[(j, 0)] - x[j]).abs() < 1e-12);
        }
        assert!(rss[0] < 1e-20);
        let g = TallQr::new(a.clone()).inverse_gram();
        let ata = a.transpose() * &a;
        let id = &ata * &g;
        for i in 0..3 {
            for j in 0..3 {
                let e = if i == j { 1.0 } else { 0.0 };
                assert!((id[(i, j)] - e).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn square_solve_and_singular_detection() {
        let a = Mat::from_fn(3, 3, |i, j| if i == j { 2.0 } else { 0.5 });
        let b = Mat::from_fn(3, 1, |i, _| i as f64);
        let x = solve_square(&a, &b).unwrap();
        let r = &a * &x - &b;
        assert!((0..3).all(|i| r[(i, 0)].abs() < 1e-14));
        let s = Mat::from_fn(2, 2, |_, _| 1.0);
        assert!(solve_square(&s, &Mat::from_fn(2, 1, |_, _| 1.0)).is_none());
    }
}
