//! Factorisations and products of the fits' tall Jacobians (2N ≈ 54 000 rows × 20–60
//! parameters): thin QR and SVD by row blocks, and `JᵀJ`, `AᵀB` in one cache-blocked pass,
//! each equal to nalgebra's to rounding or bit for bit (said per function) and
//! independent of the thread count.

use nalgebra::DMatrix;
use rayon::prelude::*;

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

/// Rows per block of [`r_factor`]: 2 048 × 60 × 8 bytes ≈ 1 MB, factorised within the L2
/// cache.
const R_BLOCK: usize = 2048;

/// The triangular factor R (p × p, upper) of the thin QR of the matrix whose k-th column
/// is column `cols[k]` of `a` divided by `scale[k]` (n ≥ p rows), without Q: each block
/// of `R_BLOCK` rows (the last takes the remainder) factorised by Householder (faer), in
/// parallel, and their stacked R factorised again (TSQR, as [`thin_qr`]).
///
/// Why: a statistic that needs only `‖(I − P_B) v‖` for B and v among the columns needs R
/// alone (docs/physics.md, M6e); forming Q, as [`thin_qr`] and [`thin_svd`] do, costs
/// more than the factorisation and holds another n × p matrix. The blocks are fixed and
/// each factorised sequentially: the same R whatever the thread count.
pub fn r_factor(a: &DMatrix<f64>, cols: &[usize], scale: &[f64]) -> DMatrix<f64> {
    let (n, p) = (a.nrows(), cols.len());
    assert!(n >= p && p > 0, "R factor of a {n} × {p} matrix");
    let block = R_BLOCK.max(p);
    let nb = (n / block).max(1);
    let stacked: Vec<faer::Mat<f64>> = (0..nb)
        .into_par_iter()
        .map(|i| {
            let (s, e) = (i * block, if i + 1 == nb { n } else { (i + 1) * block });
            let mut m = faer::Mat::<f64>::zeros(e - s, p);
            for (k, (&c, &sc)) in cols.iter().zip(scale).enumerate() {
                for (dst, src) in m
                    .col_mut(k)
                    .iter_mut()
                    .zip(a.column(c).rows(s, e - s).iter())
                {
                    *dst = src / sc;
                }
            }
            householder_r(m)
        })
        .collect();
    let r = if nb == 1 {
        stacked.into_iter().next().expect("one block")
    } else {
        householder_r(faer::Mat::from_fn(nb * p, p, |i, k| {
            stacked[i / p][(i % p, k)]
        }))
    };
    DMatrix::from_fn(p, p, |i, k| r[(i, k)])
}

/// The upper triangular R (p × p) of the Householder QR of `m` (rows ≥ p), sequential.
fn householder_r(mut m: faer::Mat<f64>) -> faer::Mat<f64> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::qr::no_pivoting::factor;
    let (n, p) = m.shape();
    let bs = factor::recommended_block_size::<f64>(n, p);
    let mut coeff = faer::Mat::<f64>::zeros(bs, p);
    let mut buf = MemBuffer::new(factor::qr_in_place_scratch::<f64>(
        n,
        p,
        bs,
        faer::Par::Seq,
        Default::default(),
    ));
    factor::qr_in_place(
        m.as_mut(),
        coeff.as_mut(),
        faer::Par::Seq,
        MemStack::new(&mut buf),
        Default::default(),
    );
    faer::Mat::from_fn(p, p, |i, k| if i <= k { m[(i, k)] } else { 0.0 })
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

#[cfg(test)]
mod tests {
    use super::*;

    /// `r_factor` over several row blocks (and a remainder) is the R of one Householder QR
    /// of the selected, scaled columns: rows equal up to their sign, to 1e-12 of R's
    /// largest entry.
    #[test]
    fn r_factor_by_blocks_is_the_r_of_one_qr() {
        let mut g = rbprops_testkit::Lcg::new(41);
        let a = DMatrix::from_fn(3 * R_BLOCK + 517, 6, |_, _| g.centred());
        let (cols, scale) = ([4, 0, 2, 5], [2.0, 0.5, 1.0, 3.0]);
        let r = r_factor(&a, &cols, &scale);
        let mut sel = a.select_columns(&cols);
        for (k, s) in scale.iter().enumerate() {
            sel.column_mut(k).unscale_mut(*s);
        }
        let expected = sel.qr().r();
        let tol = 1e-12 * expected.amax();
        for i in 0..4 {
            let sign = (r[(i, i)] * expected[(i, i)]).signum();
            for k in 0..4 {
                let d = (r[(i, k)] - sign * expected[(i, k)]).abs();
                assert!(d < tol, "R[{i},{k}] {} vs {}", r[(i, k)], expected[(i, k)]);
            }
        }
    }

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
}
