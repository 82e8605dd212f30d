//! Dense kernels: inner products with a fixed reduction order and the matrix products
//! the least-squares solvers are built on.
//!
//! Why sequential: excitations are already fitted in parallel with rayon, and faer's
//! own parallel kernels would make the floating-point reduction order depend on the
//! thread count. Running each small problem on one thread keeps every result
//! bit-identical whatever the pool size.

use faer::prelude::*;
use rbprops_core::c64;

rbprops_core::avx_fn! {
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
    gram_lower_add_into(g.as_mut(), a);
}

/// [`gram_lower_add`] into a view (a diagonal block of a larger Gram matrix).
pub fn gram_lower_add_into(g: MatMut<'_, f64>, a: MatRef<'_, f64>) {
    crate::tallmul::gram_lower_add(a, g);
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

/// `dst += aᵀ · b` into a view (sequential).
pub fn t_mul_add_into(dst: MatMut<'_, f64>, a: MatRef<'_, f64>, b: MatRef<'_, f64>) {
    crate::tallmul::at_b(a, b, dst, 1.0, true);
}

/// `dst += alpha · a · b` into a view, `a` tall (sequential).
pub fn mul_add_into(dst: MatMut<'_, f64>, a: MatRef<'_, f64>, b: MatRef<'_, f64>, alpha: f64) {
    crate::tallmul::add_a_x(dst, a, b, alpha);
}

/// `dst += alpha · a · b`, `a` tall (sequential).
pub(crate) fn mul_add(dst: &mut Mat<f64>, a: &Mat<f64>, b: &Mat<f64>, alpha: f64) {
    crate::tallmul::add_a_x(dst.as_mut(), a.as_ref(), b.as_ref(), alpha);
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
