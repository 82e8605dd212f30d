//! The eigen-solver: eigenvalues of small real matrices, and polynomial roots as the
//! eigenvalues of balanced companion matrices by the Francis double-shift QR iteration.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::prelude::*;
use faer::Par;
use rbprops_core::c64;

/// Eigenvalues of a small real square matrix (companion matrices of pole polynomials).
pub fn eigenvalues(a: &Mat<f64>) -> Option<Vec<c64>> {
    let (re, im, _) = real_evd(a, false)?;
    Some(
        re.iter()
            .zip(&im)
            .map(|(&r, &i)| c64::new(r, i))
            .filter(|z| z.re.is_finite() && z.im.is_finite())
            .collect(),
    )
}

/// Eigenvalues (real and imaginary parts, faer's order) and real right eigenvectors of a
/// real square matrix: a complex pair's eigenvalue `re[j] ± i·im[j]` has the vector
/// `u[:, j] ± i·u[:, j+1]` (LAPACK's convention). `None` when the solver fails.
pub fn eigen_with_vectors(a: &Mat<f64>) -> Option<(Vec<f64>, Vec<f64>, Mat<f64>)> {
    let (re, im, u) = real_evd(a, true)?;
    Some((re, im, u?))
}

/// faer's real non-symmetric eigen-decomposition, sequential, right vectors on request.
fn real_evd(a: &Mat<f64>, vectors: bool) -> Option<(Vec<f64>, Vec<f64>, Option<Mat<f64>>)> {
    use faer::linalg::evd::ComputeEigenvectors;
    let n = a.nrows();
    let mut re = faer::diag::Diag::<f64>::zeros(n);
    let mut im = faer::diag::Diag::<f64>::zeros(n);
    let mut u = vectors.then(|| Mat::<f64>::zeros(n, n));
    if n > 0 {
        let right = if vectors {
            ComputeEigenvectors::Yes
        } else {
            ComputeEigenvectors::No
        };
        let mut buf = MemBuffer::new(faer::linalg::evd::evd_scratch::<f64>(
            n,
            ComputeEigenvectors::No,
            right,
            Par::Seq,
            Default::default(),
        ));
        faer::linalg::evd::evd_real(
            a.as_ref(),
            re.as_mut(),
            im.as_mut(),
            None,
            u.as_mut().map(|u| u.as_mut()),
            Par::Seq,
            MemStack::new(&mut buf),
            Default::default(),
        )
        .ok()?;
    }
    let v = |d: &faer::diag::Diag<f64>| (0..n).map(|i| d[i]).collect();
    Some((v(&re), v(&im), u))
}

/// Eigenvalues (ascending) and orthonormal eigenvectors (columns) of a real symmetric
/// matrix, from its lower triangle. `None` when the solver fails (non-finite entries).
pub fn symmetric_eigen(a: &Mat<f64>) -> Option<(Vec<f64>, Mat<f64>)> {
    use faer::linalg::evd::ComputeEigenvectors;
    let n = a.nrows();
    let mut vals = faer::diag::Diag::<f64>::zeros(n);
    let mut vecs = Mat::<f64>::zeros(n, n);
    let mut buf = MemBuffer::new(faer::linalg::evd::self_adjoint_evd_scratch::<f64>(
        n,
        ComputeEigenvectors::Yes,
        Par::Seq,
        Default::default(),
    ));
    faer::linalg::evd::self_adjoint_evd(
        a.as_ref(),
        vals.as_mut(),
        Some(vecs.as_mut()),
        Par::Seq,
        MemStack::new(&mut buf),
        Default::default(),
    )
    .ok()?;
    Some(((0..n).map(|i| vals[i]).collect(), vecs))
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
///
/// The EISPACK `hqr` scheme (Wilkinson & Reinsch, Handbook II/14), in its steps: the
/// deflation point ([`deflation_point`]), a 1×1 or 2×2 block's eigenvalues
/// ([`block_eigenvalues`]), the start of the double-shift bulge
/// ([`double_shift_start`]) and its chase down the active block ([`chase_bulge`]).
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
            let l = deflation_point(a, n, h, anorm);
            if l + 1 >= h {
                // A 1×1 or 2×2 block split off: its eigenvalues.
                hi -= block_eigenvalues(a, n, h, l == h, shift_acc, &mut out) as isize;
                break;
            }
            let mut x = a[at(h, h)];
            let mut y = a[at(h - 1, h - 1)];
            let mut w = a[at(h, h - 1)] * a[at(h - 1, h)];
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
            let (m, pqr) = double_shift_start(a, n, (l, h), (x, y, w));
            chase_bulge(a, n, (l, m, h), pqr);
        }
    }
    Some(out)
}

/// The lowest row `l ≤ h` of the active block whose subdiagonal `a[l][l−1]` is
/// negligible against its diagonal neighbours (set to zero), or 0.
#[inline(always)]
fn deflation_point(a: &mut [f64], n: usize, h: usize, anorm: f64) -> usize {
    let at = |i: usize, j: usize| i * n + j;
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
    l
}

/// The eigenvalues of the block ending at row `h` that split off, plus the accumulated
/// exceptional shifts: one (`single`, `a[h][h]`) or the two of the trailing 2×2 block
/// (a real pair or a complex-conjugate pair), written into `out`. Returns how many.
#[inline(always)]
fn block_eigenvalues(
    a: &[f64],
    n: usize,
    h: usize,
    single: bool,
    shift_acc: f64,
    out: &mut [c64],
) -> usize {
    let at = |i: usize, j: usize| i * n + j;
    let mut x = a[at(h, h)];
    if single {
        out[h] = c64::new(x + shift_acc, 0.0);
        return 1;
    }
    let y = a[at(h - 1, h - 1)];
    let w = a[at(h, h - 1)] * a[at(h - 1, h)];
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
    2
}

/// Start of the double-shift bulge for the shifts given by `(x, y, w)` (trailing
/// diagonal entries and the product of the trailing off-diagonal pair): the highest row
/// `m ≥ l` where two consecutive subdiagonals are small enough for the bulge to start,
/// the first column `(p, q, r)` of `(H − σ₁)(H − σ₂)` there (scaled), and the entries
/// below the bulge cleared.
#[inline(always)]
fn double_shift_start(
    a: &mut [f64],
    n: usize,
    (l, h): (usize, usize),
    (x, y, w): (f64, f64, f64),
) -> (usize, (f64, f64, f64)) {
    let at = |i: usize, j: usize| i * n + j;
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
    (m, (p, q, r))
}

/// Chases the bulge started at row `m` (first reflector from `(p, q, r)`) down the
/// active block `l..=h` with 3×3 Householder reflections (2×2 at the last row).
#[inline(always)]
fn chase_bulge(
    a: &mut [f64],
    n: usize,
    (l, m, h): (usize, usize, usize),
    (mut p, mut q, mut r): (f64, f64, f64),
) {
    let at = |i: usize, j: usize| i * n + j;
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

#[cfg(test)]
mod tests {
    use super::*;
    use rbprops_testkit::synthetic::poly_from_roots;

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
        let mut g = rbprops_testkit::Lcg::new(12345);
        let mut rnd = || g.unit() * 2.0 - 1.0;
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
}
