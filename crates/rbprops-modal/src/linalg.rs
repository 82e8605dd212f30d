//! Thin wrappers over faer's dense kernels, always run sequentially (`Par::Seq`).
//!
//! Why sequential: excitations are already fitted in parallel with rayon, and faer's
//! own parallel kernels would make the floating-point reduction order depend on the
//! thread count. Running each small problem on one thread keeps every result
//! bit-identical whatever the pool size.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::qr::no_pivoting::{factor, solve};
use faer::prelude::*;
use faer::{Conj, Par};
use rbprops_core::c64;

crate::simd::avx_fn! {
/// `Σ a_i b_i` over the common length, with eight independent partial sums combined in a
/// fixed tree at the end.
///
/// Why: a plain running sum is one long chain of dependent additions (latency-bound,
/// never vectorised, since floating-point addition is not associative); eight chains
/// vectorise and pipeline. The order is fixed by the data length alone, so results stay
/// bit-identical for any thread count.
#[inline]
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0f64; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .fold(0.0, |s, (x, y)| s + x * y);
    for (x, y) in ca.zip(cb) {
        for i in 0..8 {
            acc[i] += x[i] * y[i];
        }
    }
    ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7])) + tail
}
}

/// `Σ_i (t_i.0 + t_i.1)` with `t_i = term(a_i, b_i)`, in the eight-way partial sums of
/// [`dot`] (four complex lanes, the two parts apart), combined in the same fixed tree.
#[inline(always)]
fn complex_sum8(a: &[c64], b: &[c64], term: impl Fn(c64, c64) -> (f64, f64)) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0f64; 8];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .fold(0.0, |s, (x, y)| {
            let (p, q) = term(*x, *y);
            s + (p + q)
        });
    for (x, y) in ca.zip(cb) {
        for i in 0..4 {
            let (p, q) = term(x[i], y[i]);
            acc[2 * i] += p;
            acc[2 * i + 1] += q;
        }
    }
    ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7])) + tail
}

/// `Re Σ conj(a_i) b_i`: the real inner product of real-stacked complex vectors, with the
/// same eight-way partial sums as [`dot`].
#[inline]
pub fn cdot(a: &[c64], b: &[c64]) -> f64 {
    complex_sum8(a, b, |x, y| (x.re * y.re, x.im * y.im))
}

/// `Σ |a_i − b_i|²` with the eight-way partial sums of [`cdot`].
#[inline]
pub fn cdist_sqr(a: &[c64], b: &[c64]) -> f64 {
    complex_sum8(a, b, |x, y| {
        let (dr, di) = (x.re - y.re, x.im - y.im);
        (dr * dr, di * di)
    })
}

/// A thin QR factorisation `A = Q R` of a tall real matrix (Householder, faer).
#[derive(Debug)]
pub struct TallQr {
    qr: Mat<f64>,
    q_coeff: Mat<f64>,
}

impl TallQr {
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

    pub fn ncols(&self) -> usize {
        self.qr.ncols()
    }

    /// Diagonal of R: its smallest/largest ratio bounds the conditioning of the basis.
    pub fn r_diag(&self) -> Vec<f64> {
        (0..self.ncols()).map(|i| self.qr[(i, i)].abs()).collect()
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
    pub fn inverse_gram(&self) -> Mat<f64> {
        inverse_gram_of(self.ncols(), |i, j| self.qr[(i, j)])
    }
}

/// An `m×n` matrix whose every entry the caller writes before reading any.
///
/// Zero-filled by `Mat::zeros`, which in faer 0.24 compiles to one `memset` per matrix:
/// cheaper than the zeroed `Vec` copied into a `Mat` used before (two passes over the
/// storage; −0.16M instructions per excitation). Where a tall matrix is needed again
/// and again, its storage is reused instead (see `lsfd::Spares`).
pub fn mat_for_overwrite(m: usize, n: usize) -> Mat<f64> {
    Mat::zeros(m, n)
}

/// `aᵀ · b` (see [`crate::tallmul`]: inner products of columns in a fixed order,
/// independent of the thread count).
pub fn t_mul(a: &Mat<f64>, b: &Mat<f64>) -> Mat<f64> {
    let mut out = Mat::<f64>::zeros(a.ncols(), b.ncols());
    crate::tallmul::at_b(a.as_ref(), b.as_ref(), out.as_mut(), 1.0, false);
    out
}

/// The Gram matrix `aᵀ · a`: its lower triangle (see [`gram_lower_add`]), mirrored into
/// the upper one.
///
/// Why: a Gram matrix is symmetric, so the full product computes nearly half of it
/// twice.
pub fn gram(a: &Mat<f64>) -> Mat<f64> {
    let n = a.ncols();
    let mut g = Mat::<f64>::zeros(n, n);
    gram_lower_add(&mut g, a.as_ref());
    mirror_lower(&mut g);
    g
}

/// `g += aᵀ · a` on the lower triangle of `g` only (diagonal included; sequential).
pub fn gram_lower_add(g: &mut Mat<f64>, a: MatRef<'_, f64>) {
    crate::tallmul::gram_lower_add(a, g.as_mut());
}

/// Copies the lower triangle of the square `g` onto its upper one (symmetric `g`).
pub fn mirror_lower(g: &mut Mat<f64>) {
    for j in 0..g.ncols() {
        for i in 0..j {
            g[(i, j)] = g[(j, i)];
        }
    }
}

/// `dst += alpha · aᵀ · b` (sequential).
pub fn t_mul_add(dst: &mut Mat<f64>, a: MatRef<'_, f64>, b: MatRef<'_, f64>, alpha: f64) {
    crate::tallmul::at_b(a, b, dst.as_mut(), alpha, true);
}

/// `dst += alpha · a · b` into a view, `a` tall (sequential).
pub fn mul_add_into(dst: MatMut<'_, f64>, a: MatRef<'_, f64>, b: MatRef<'_, f64>, alpha: f64) {
    crate::tallmul::add_a_x(dst, a, b, alpha);
}

/// `dst += alpha · a · b`, `a` tall (sequential).
fn mul_add(dst: &mut Mat<f64>, a: &Mat<f64>, b: &Mat<f64>, alpha: f64) {
    crate::tallmul::add_a_x(dst.as_mut(), a.as_ref(), b.as_ref(), alpha);
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

    /// Least-squares solution for every column of `b`: `(x, residuals b − Ax, residual
    /// sum of squares per column)`.
    pub fn solve(&self, b: &Mat<f64>) -> (Mat<f64>, Mat<f64>, Vec<f64>) {
        self.solve_into(b.clone())
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

/// Eigenvalues of a small real square matrix (companion matrices of pole polynomials).
pub fn eigenvalues(a: &Mat<f64>) -> Option<Vec<c64>> {
    let n = a.nrows();
    if n == 0 {
        return Some(Vec::new());
    }
    let mut re = faer::diag::Diag::<f64>::zeros(n);
    let mut im = faer::diag::Diag::<f64>::zeros(n);
    let mut buf = MemBuffer::new(faer::linalg::evd::evd_scratch::<f64>(
        n,
        faer::linalg::evd::ComputeEigenvectors::No,
        faer::linalg::evd::ComputeEigenvectors::No,
        Par::Seq,
        Default::default(),
    ));
    faer::linalg::evd::evd_real(
        a.as_ref(),
        re.as_mut(),
        im.as_mut(),
        None,
        None,
        Par::Seq,
        MemStack::new(&mut buf),
        Default::default(),
    )
    .ok()?;
    Some(
        (0..n)
            .map(|i| c64::new(re[i], im[i]))
            .filter(|z| z.re.is_finite() && z.im.is_finite())
            .collect(),
    )
}

/// Roots of the monic real polynomial `z^n + c_{n−1} z^{n−1} + … + c_0` (`coef[j] = c_j`,
/// `j < n`) as the eigenvalues of its companion matrix: balanced (Parlett–Reinsch,
/// powers of 2, so exact), then the Francis double-shift QR iteration on the upper
/// Hessenberg form (Wilkinson, *The Algebraic Eigenvalue Problem*, §8.36; EISPACK `hqr`).
///
/// Why not [`eigenvalues`]: the companion matrix is already Hessenberg and at most
/// ~60×60, so faer's general path (Hessenberg reduction, blocked multishift QR, scratch
/// allocation) costs 2–3× more per call, and the stabilisation sweep solves one per
/// model order. Falls back to [`eigenvalues`] if the iteration does not converge.
pub fn polynomial_roots(coef: &[f64]) -> Option<Vec<c64>> {
    let n = coef.len();
    if n == 0 {
        return Some(Vec::new());
    }
    // Frobenius companion: first row −c_{n−1} … −c_0, ones on the subdiagonal.
    let mut a = vec![0.0f64; n * n];
    for j in 0..n {
        a[j] = -coef[n - 1 - j];
    }
    for i in 1..n {
        a[i * n + i - 1] = 1.0;
    }
    if a.iter().any(|x| !x.is_finite()) {
        return None;
    }
    balance(&mut a, n);
    match hessenberg_qr(&mut a, n) {
        Some(r) => Some(r),
        None => eigenvalues(&companion(coef)),
    }
}

/// The Frobenius companion matrix of the monic polynomial with coefficients `coef`
/// (`c_0..c_{n−1}`): first row `−c_{n−1} … −c_0`, ones on the subdiagonal.
pub fn companion(coef: &[f64]) -> Mat<f64> {
    let n = coef.len();
    Mat::from_fn(n, n, |i, j| {
        if i == 0 {
            -coef[n - 1 - j]
        } else if j + 1 == i {
            1.0
        } else {
            0.0
        }
    })
}

/// Parlett–Reinsch balancing `A ← D⁻¹AD` with `D` a diagonal of powers of 2, until
/// every row and column pair has comparable norms (row-major `n×n`).
fn balance(a: &mut [f64], n: usize) {
    loop {
        let mut done = true;
        for i in 0..n {
            let (mut c, mut r) = (0.0f64, 0.0f64);
            for j in 0..n {
                if j != i {
                    c += a[j * n + i].abs();
                    r += a[i * n + j].abs();
                }
            }
            if c == 0.0 || r == 0.0 {
                continue;
            }
            let s = c + r;
            let mut f = 1.0;
            let (lo, hi) = (r / 2.0, r * 2.0);
            while c < lo {
                f *= 2.0;
                c *= 4.0;
            }
            while c > hi {
                f /= 2.0;
                c /= 4.0;
            }
            if (c + r) / f < 0.95 * s {
                done = false;
                for j in 0..n {
                    a[i * n + j] /= f;
                    a[j * n + i] *= f;
                }
            }
        }
        if done {
            return;
        }
    }
}

/// Eigenvalues of the upper Hessenberg row-major `n×n` matrix `a` (destroyed) by the
/// Francis double-shift QR iteration with deflation on negligible subdiagonals and
/// exceptional shifts after 10 and 20 stalled iterations. `None` after 30 iterations
/// on one eigenvalue.
fn hessenberg_qr(a: &mut [f64], n: usize) -> Option<Vec<c64>> {
    let at = |i: usize, j: usize| i * n + j;
    let mut out = vec![c64::new(0.0, 0.0); n];
    let anorm: f64 = (0..n)
        .flat_map(|i| (i.saturating_sub(1)..n).map(move |j| (i, j)))
        .map(|(i, j)| a[at(i, j)].abs())
        .sum();
    let mut shift_acc = 0.0;
    let mut hi = n as isize - 1;
    while hi >= 0 {
        let h = hi as usize;
        let mut its = 0;
        loop {
            // Deflation point: the lowest l with a negligible subdiagonal a[l][l−1].
            let mut l = h;
            while l >= 1 {
                let mut s = a[at(l - 1, l - 1)].abs() + a[at(l, l)].abs();
                if s == 0.0 {
                    s = anorm;
                }
                if a[at(l, l - 1)].abs() + s == s {
                    a[at(l, l - 1)] = 0.0;
                    break;
                }
                l -= 1;
            }
            let mut x = a[at(h, h)];
            if l == h {
                out[h] = c64::new(x + shift_acc, 0.0);
                hi -= 1;
                break;
            }
            let mut y = a[at(h - 1, h - 1)];
            let mut w = a[at(h, h - 1)] * a[at(h - 1, h)];
            if l + 1 == h {
                // A 2×2 block: a real pair or a complex-conjugate pair.
                let p = 0.5 * (y - x);
                let q = p * p + w;
                let z = q.abs().sqrt();
                x += shift_acc;
                if q >= 0.0 {
                    let z = p + z.copysign(p);
                    out[h - 1] = c64::new(x + z, 0.0);
                    out[h] = c64::new(if z != 0.0 { x - w / z } else { x + z }, 0.0);
                } else {
                    out[h - 1] = c64::new(x + p, -z);
                    out[h] = c64::new(x + p, z);
                }
                hi -= 2;
                break;
            }
            if its == 30 {
                return None;
            }
            if its == 10 || its == 20 {
                // Exceptional shift to break a cycle.
                shift_acc += x;
                for i in 0..=h {
                    a[at(i, i)] -= x;
                }
                let s = a[at(h, h - 1)].abs() + a[at(h - 1, h - 2)].abs();
                x = 0.75 * s;
                y = x;
                w = -0.4375 * s * s;
            }
            its += 1;
            // Start of the double-shift bulge: two consecutive small subdiagonals.
            let mut m = h - 2;
            let (mut p, mut q, mut r);
            loop {
                let z = a[at(m, m)];
                let rr = x - z;
                let ss = y - z;
                p = (rr * ss - w) / a[at(m + 1, m)] + a[at(m, m + 1)];
                q = a[at(m + 1, m + 1)] - z - rr - ss;
                r = a[at(m + 2, m + 1)];
                let s = p.abs() + q.abs() + r.abs();
                p /= s;
                q /= s;
                r /= s;
                if m == l {
                    break;
                }
                let u = a[at(m, m - 1)].abs() * (q.abs() + r.abs());
                let v = p.abs() * (a[at(m - 1, m - 1)].abs() + z.abs() + a[at(m + 1, m + 1)].abs());
                if u + v == v {
                    break;
                }
                m -= 1;
            }
            for i in m + 2..=h {
                a[at(i, i - 2)] = 0.0;
                if i != m + 2 {
                    a[at(i, i - 3)] = 0.0;
                }
            }
            // Chase the bulge with 3×3 Householder reflections, rows/columns l..=h.
            let mut xk = 0.0;
            for k in m..h {
                if k != m {
                    p = a[at(k, k - 1)];
                    q = a[at(k + 1, k - 1)];
                    r = if k + 1 != h { a[at(k + 2, k - 1)] } else { 0.0 };
                    xk = p.abs() + q.abs() + r.abs();
                    if xk != 0.0 {
                        p /= xk;
                        q /= xk;
                        r /= xk;
                    }
                }
                let s = (p * p + q * q + r * r).sqrt().copysign(p);
                if s == 0.0 {
                    continue;
                }
                if k == m {
                    if l != m {
                        a[at(k, k - 1)] = -a[at(k, k - 1)];
                    }
                } else {
                    a[at(k, k - 1)] = -s * xk;
                }
                p += s;
                let (hx, hy, hz) = (p / s, q / s, r / s);
                let (q2, r2) = (q / p, r / p);
                let three = k + 1 != h;
                // Rows k, k+1 (and k+2), columns k..=h: contiguous slices, so the
                // update runs without index checks (same operations, same order).
                let (row0, rest) = a[k * n..].split_at_mut(n);
                let (row1, rest) = rest.split_at_mut(n);
                let (x0, x1) = (&mut row0[k..=h], &mut row1[k..=h]);
                if three {
                    let x2 = &mut rest[k..=h];
                    for ((a0, a1), a2) in x0.iter_mut().zip(x1.iter_mut()).zip(x2.iter_mut()) {
                        let t = *a0 + q2 * *a1 + r2 * *a2;
                        *a2 -= t * hz;
                        *a1 -= t * hy;
                        *a0 -= t * hx;
                    }
                } else {
                    for (a0, a1) in x0.iter_mut().zip(x1.iter_mut()) {
                        let t = *a0 + q2 * *a1;
                        *a1 -= t * hy;
                        *a0 -= t * hx;
                    }
                }
                // Rows l..=min(h, k+3), columns k, k+1 (and k+2).
                let rows = a[l * n..(h.min(k + 3) + 1) * n].chunks_exact_mut(n);
                if three {
                    for row in rows {
                        let c = &mut row[k..k + 3];
                        let t = hx * c[0] + hy * c[1] + hz * c[2];
                        c[2] -= t * r2;
                        c[1] -= t * q2;
                        c[0] -= t;
                    }
                } else {
                    for row in rows {
                        let c = &mut row[k..k + 2];
                        let t = hx * c[0] + hy * c[1];
                        c[1] -= t * q2;
                        c[0] -= t;
                    }
                }
            }
        }
    }
    Some(out)
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

crate::simd::avx_fn! {
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
    use crate::testdata::poly_from_roots;

    /// The complex sums against their definitions, for every leftover length.
    #[test]
    fn complex_sums_match_their_definitions() {
        for n in 0..12 {
            let a: Vec<c64> = (0..n)
                .map(|i| c64::new(0.3 * i as f64 - 1.0, 0.7 - 0.1 * i as f64))
                .collect();
            let b: Vec<c64> = (0..n)
                .map(|i| c64::new(1.0 / (i + 1) as f64, 0.2 * i as f64))
                .collect();
            let dot_def: f64 = a.iter().zip(&b).map(|(x, y)| (x.conj() * y).re).sum();
            let dist_def: f64 = a.iter().zip(&b).map(|(x, y)| (x - y).norm_sqr()).sum();
            assert!((cdot(&a, &b) - dot_def).abs() <= 1e-13, "cdot, n = {n}");
            assert!(
                (cdist_sqr(&a, &b) - dist_def).abs() <= 1e-13,
                "cdist_sqr, n = {n}"
            );
        }
    }

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
    fn companion_eigenvalues_are_polynomial_roots() {
        // (z - 2)(z^2 + 1) = z^3 - 2 z^2 + z - 2
        let a = companion(&[-2.0, 1.0, -2.0]);
        let mut ev = eigenvalues(&a).unwrap();
        ev.sort_by(|a, b| a.re.total_cmp(&b.re).then(a.im.total_cmp(&b.im)));
        assert!((ev[0] - c64::new(0.0, -1.0)).norm() < 1e-12);
        assert!((ev[1] - c64::new(0.0, 1.0)).norm() < 1e-12);
        assert!((ev[2] - c64::new(2.0, 0.0)).norm() < 1e-12);
    }

    fn sorted(mut v: Vec<c64>) -> Vec<c64> {
        v.sort_by(|a, b| a.re.total_cmp(&b.re).then(a.im.total_cmp(&b.im)));
        v
    }

    #[test]
    fn polynomial_roots_recover_known_roots() {
        // Pole-like roots on and near the unit circle, conjugate pairs, and real roots.
        let mut roots = Vec::new();
        for k in 0..8 {
            let z = c64::from_polar(0.999 - 0.01 * k as f64, 0.05 + 0.3 * k as f64);
            roots.push(z);
            roots.push(z.conj());
        }
        roots.extend([c64::new(0.5, 0.0), c64::new(-0.8, 0.0), c64::new(2.5, 0.0)]);
        let got = sorted(polynomial_roots(&poly_from_roots(&roots)).unwrap());
        let want = sorted(roots);
        for (g, w) in got.iter().zip(&want) {
            assert!((g - w).norm() < 1e-9, "{g} vs {w}");
        }
    }

    #[test]
    fn polynomial_roots_agree_with_the_general_eigen_solver() {
        // Pseudo-random degree 2..40 polynomials: same spectrum as faer's real EVD of
        // the unbalanced companion matrix (to the conditioning of the roots).
        let mut seed = 12345u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        for n in 2..=40 {
            let c: Vec<f64> = (0..n).map(|_| rnd()).collect();
            let m = companion(&c);
            let a = sorted(polynomial_roots(&c).unwrap());
            let b = sorted(eigenvalues(&m).unwrap());
            assert_eq!(a.len(), n);
            // Residual test, robust to ordering ties: every root nearly zeroes p.
            for z in &a {
                let mut p = c64::new(1.0, 0.0);
                for j in (0..n).rev() {
                    p = p * z + c[j];
                }
                let scale: f64 = (0..=n).map(|j| z.norm().powi(j as i32)).sum();
                assert!(p.norm() < 1e-11 * scale, "n={n}: |p({z})| = {}", p.norm());
            }
            let sa: c64 = a.iter().sum();
            let sb: c64 = b.iter().sum();
            assert!(
                (sa - sb).norm() < 1e-9 * (1.0 + sb.norm()),
                "n={n}: {sa} vs {sb}"
            );
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
