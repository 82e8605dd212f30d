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

/// A thin QR factorisation `A = Q R` of a tall real matrix (Householder, faer).
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
            .map(|j| (n..m).map(|i| rhs[(i, j)].powi(2)).sum())
            .collect();
        (Mat::from_fn(n, k, |i, j| rhs[(i, j)]), rss)
    }

    /// `(AᵀA)⁻¹ = R⁻¹R⁻ᵀ`, the unscaled covariance of least-squares coefficients.
    pub fn inverse_gram(&self) -> Mat<f64> {
        let n = self.ncols();
        // Invert the upper-triangular R by back substitution, column by column.
        let mut rinv = Mat::<f64>::zeros(n, n);
        for j in 0..n {
            rinv[(j, j)] = 1.0 / self.qr[(j, j)];
            for i in (0..j).rev() {
                let mut s = 0.0;
                for l in i + 1..=j {
                    s += self.qr[(i, l)] * rinv[(l, j)];
                }
                rinv[(i, j)] = -s / self.qr[(i, i)];
            }
        }
        Mat::from_fn(n, n, |i, j| {
            (i.max(j)..n).map(|l| rinv[(i, l)] * rinv[(j, l)]).sum()
        })
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

/// Solves the small symmetric system `A x = b` (LU with partial pivoting, sequential).
/// Returns `None` when `A` is numerically singular.
pub fn solve_square(a: &Mat<f64>, b: &Mat<f64>) -> Option<Mat<f64>> {
    let n = a.nrows();
    // Gaussian elimination with partial pivoting: the systems here are ≤ ~60 unknowns,
    // and a hand-written kernel keeps the operation order fixed.
    let k = b.ncols();
    let mut m = a.clone();
    let mut x = b.clone();
    let scale = (0..n)
        .flat_map(|i| (0..n).map(move |j| (i, j)))
        .map(|(i, j)| m[(i, j)].abs())
        .fold(0.0f64, f64::max);
    if !(scale > 0.0) || !scale.is_finite() {
        return None;
    }
    for c in 0..n {
        let p = (c..n)
            .max_by(|&i, &j| m[(i, c)].abs().total_cmp(&m[(j, c)].abs()))
            .unwrap();
        if m[(p, c)].abs() <= 1e-14 * scale {
            return None;
        }
        if p != c {
            for j in 0..n {
                let t = m[(c, j)];
                m[(c, j)] = m[(p, j)];
                m[(p, j)] = t;
            }
            for j in 0..k {
                let t = x[(c, j)];
                x[(c, j)] = x[(p, j)];
                x[(p, j)] = t;
            }
        }
        let d = m[(c, c)];
        for i in c + 1..n {
            let f = m[(i, c)] / d;
            if f != 0.0 {
                for j in c..n {
                    m[(i, j)] -= f * m[(c, j)];
                }
                for j in 0..k {
                    x[(i, j)] -= f * x[(c, j)];
                }
            }
        }
    }
    for j in 0..k {
        for i in (0..n).rev() {
            let mut s = x[(i, j)];
            for l in i + 1..n {
                s -= m[(i, l)] * x[(l, j)];
            }
            x[(i, j)] = s / m[(i, i)];
        }
    }
    Some(x)
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
    fn companion_eigenvalues_are_polynomial_roots() {
        // (z - 2)(z^2 + 1) = z^3 - 2 z^2 + z - 2
        let c = [-2.0, 1.0, -2.0];
        let a = Mat::from_fn(3, 3, |i, j| {
            if i == 0 {
                -c[2 - j]
            } else if j + 1 == i {
                1.0
            } else {
                0.0
            }
        });
        let mut ev = eigenvalues(&a).unwrap();
        ev.sort_by(|a, b| a.re.total_cmp(&b.re).then(a.im.total_cmp(&b.im)));
        assert!((ev[0] - c64::new(0.0, -1.0)).norm() < 1e-12);
        assert!((ev[1] - c64::new(0.0, 1.0)).norm() < 1e-12);
        assert!((ev[2] - c64::new(2.0, 0.0)).norm() < 1e-12);
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
