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
/// the product of its own Q and its slice of the second one. The factorisations are
/// faer's blocked Householder QR, sequential within a block: nalgebra's (one reflection
/// at a time, Q formed from the identity by p more passes) took 13 % of the six-effects
/// bench's CPU time.
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
    let ranges: Vec<(usize, usize)> = (0..nb)
        .map(|i| (i * block, if i + 1 == nb { n } else { (i + 1) * block }))
        .collect();
    let parts: Vec<(faer::Mat<f64>, faer::Mat<f64>)> = ranges
        .par_iter()
        .map(|&(s, e)| householder_qr(faer::Mat::from_fn(e - s, p, |i, k| a[(s + i, k)])))
        .collect();
    if nb == 1 {
        let (q, r) = &parts[0];
        return (to_nalgebra(q), to_nalgebra(r));
    }
    let (qt, r) = householder_qr(faer::Mat::from_fn(nb * p, p, |i, k| {
        parts[i / p].1[(i % p, k)]
    }));
    let blocks: Vec<faer::Mat<f64>> = parts
        .par_iter()
        .enumerate()
        .map(|(i, (qi, _))| {
            let mut b = faer::Mat::<f64>::zeros(qi.nrows(), p);
            faer::linalg::matmul::matmul(
                b.as_mut(),
                faer::Accum::Replace,
                qi.as_ref(),
                qt.get(i * p..(i + 1) * p, ..),
                1.0,
                faer::Par::Seq,
            );
            b
        })
        .collect();
    let mut q = DMatrix::zeros(n, p);
    for (&(s, _), b) in ranges.iter().zip(&blocks) {
        for k in 0..p {
            for i in 0..b.nrows() {
                q[(s + i, k)] = b[(i, k)];
            }
        }
    }
    (q, to_nalgebra(&r))
}

fn to_nalgebra(m: &faer::Mat<f64>) -> DMatrix<f64> {
    DMatrix::from_fn(m.nrows(), m.ncols(), |i, k| m[(i, k)])
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

/// The singular values and right singular vectors (`Vᵀ`; no U) of a tall matrix (n ≥ p)
/// from its R factor alone ([`r_factor`]): A = Q R and R = U_R S Vᵀ give A = (Q U_R) S
/// Vᵀ, so A's S and V are R's (to rounding). A wide or empty matrix takes nalgebra's
/// SVD directly.
///
/// Why: the score test needs U only through `Uᵀr` and the kept directions' basis, both
/// `A V S⁻¹` over singular values far from zero; forming Q and U (two n × p passes and
/// an n × p × p product) cost more than the factorisation.
pub fn thin_sv(a: &DMatrix<f64>) -> nalgebra::SVD<f64, nalgebra::Dyn, nalgebra::Dyn> {
    if a.ncols() == 0 || a.nrows() < a.ncols() {
        return a.clone().svd(false, true);
    }
    let cols: Vec<usize> = (0..a.ncols()).collect();
    r_factor(a, &cols, &vec![1.0; a.ncols()]).svd(false, true)
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
fn householder_r(m: faer::Mat<f64>) -> faer::Mat<f64> {
    householder_factor(m, false).1
}

/// The thin Householder QR of `m` (rows ≥ p), sequential: Q (rows × p, orthonormal
/// columns) and R (p × p, upper triangular).
fn householder_qr(m: faer::Mat<f64>) -> (faer::Mat<f64>, faer::Mat<f64>) {
    let (q, r) = householder_factor(m, true);
    (q.expect("Q asked for"), r)
}

/// faer's blocked Householder QR of `m` in place, sequential (so the same whatever the
/// thread count): R, and with `want_q` the thin Q, the reflections applied to the first
/// p columns of the identity.
fn householder_factor(
    mut m: faer::Mat<f64>,
    want_q: bool,
) -> (Option<faer::Mat<f64>>, faer::Mat<f64>) {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::householder;
    use faer::linalg::qr::no_pivoting::factor;
    let (n, p) = m.shape();
    let bs = factor::recommended_block_size::<f64>(n, p);
    let mut coeff = faer::Mat::<f64>::zeros(bs, p);
    let mut buf = MemBuffer::new(
        factor::qr_in_place_scratch::<f64>(n, p, bs, faer::Par::Seq, Default::default()).or(
            householder::apply_block_householder_sequence_on_the_left_in_place_scratch::<f64>(
                n, bs, p,
            ),
        ),
    );
    factor::qr_in_place(
        m.as_mut(),
        coeff.as_mut(),
        faer::Par::Seq,
        MemStack::new(&mut buf),
        Default::default(),
    );
    let r = faer::Mat::from_fn(p, p, |i, k| if i <= k { m[(i, k)] } else { 0.0 });
    let q = want_q.then(|| {
        let mut q = faer::Mat::<f64>::identity(n, p);
        householder::apply_block_householder_sequence_on_the_left_in_place_with_conj(
            m.as_ref(),
            coeff.as_ref(),
            faer::Conj::No,
            q.as_mut(),
            faer::Par::Seq,
            MemStack::new(&mut buf),
        );
        q
    });
    (q, r)
}

/// Rows per block of [`tr_mul`]: large enough that faer's product runs at its speed
/// (4 096 rows were as fast as one product over all 108 000), small enough that the
/// blocks share two threads evenly.
const PRODUCT_BLOCK: usize = 4096;

/// The normal matrix `JᵀJ` ([`tr_mul`] of `J` with itself), exactly symmetric (the upper
/// triangle mirrored).
pub fn gram(j: &DMatrix<f64>) -> DMatrix<f64> {
    let mut g = tr_mul(j, j);
    for c in 0..g.ncols() {
        for r in c + 1..g.nrows() {
            g[(r, c)] = g[(c, r)];
        }
    }
    g
}

/// `C − A B` in place of `C` (A tall), by faer's matrix product (sequential, so the same
/// whatever the thread count): the check's projections `J − Q (QᵀJ)`, whose n × p × k
/// product nalgebra's (matrixmultiply) took at half faer's speed, with a copy for the
/// difference.
pub fn sub_mul(c: &mut DMatrix<f64>, a: &DMatrix<f64>, b: &DMatrix<f64>) {
    assert_eq!(
        (c.nrows(), c.ncols(), a.ncols()),
        (a.nrows(), b.ncols(), b.nrows()),
        "C − AB: shapes differ"
    );
    product_into(c, faer::Accum::Add, a, b, -1.0);
}

/// `A B` (A tall) by faer's matrix product, sequential as in [`sub_mul`].
pub fn mul(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    assert_eq!(a.ncols(), b.nrows(), "AB: shapes differ");
    let mut c = DMatrix::zeros(a.nrows(), b.ncols());
    product_into(&mut c, faer::Accum::Replace, a, b, 1.0);
    c
}

/// `C = α A B` (`Replace`) or `C += α A B` (`Add`) by faer over the nalgebra matrices'
/// storage, sequential.
fn product_into(
    c: &mut DMatrix<f64>,
    accum: faer::Accum,
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    alpha: f64,
) {
    let (n, k, m) = (a.nrows(), a.ncols(), b.ncols());
    faer::linalg::matmul::matmul(
        faer::MatMut::from_column_major_slice_mut(c.as_mut_slice(), n, m),
        accum,
        faer::MatRef::from_column_major_slice(a.as_slice(), n, k),
        faer::MatRef::from_column_major_slice(b.as_slice(), k, m),
        alpha,
        faer::Par::Seq,
    );
}

/// `AᵀB` by row blocks of [`PRODUCT_BLOCK`]: each block's product by faer (sequential),
/// read in place from both matrices, and the blocks' products summed in order. Equal
/// to nalgebra's `a.tr_mul(b)` to rounding (each entry a dot product, `|error| ≤ n ε
/// ‖aᵢ‖ ‖bⱼ‖`), and the same bits whatever the thread count (the blocks are fixed and
/// summed in order). Every entry takes part, so a non-finite one makes its row's
/// products NaN or ∞ as nalgebra's would.
///
/// Why: nalgebra takes each entry as a separate dot product of two whole columns, from
/// memory for the check's Jacobians and bases (108 000 rows × 20–150 columns, 17–130
/// MB); a matrix product keeps a block in cache for all its pairs. Skipping the columns
/// that are zero in a block (grouped finite-difference columns) was measured slower
/// than taking them: the scan for zeros and non-finite entries and the gather of the
/// rest cost more than the flops saved (a projection's `RᵀQ` of 16 residuals on a
/// 100-column basis: 55 ms skipping, 11 ms in place; a 150-column Jacobian with 60
/// grouped columns: 110 ms, 90 ms; one thread).
pub fn tr_mul(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    assert_eq!(a.nrows(), b.nrows(), "AᵀB: row counts differ");
    let n = a.nrows();
    let partial: Vec<faer::Mat<f64>> = (0..n.div_ceil(PRODUCT_BLOCK))
        .into_par_iter()
        .map(|k| {
            let rows = k * PRODUCT_BLOCK..((k + 1) * PRODUCT_BLOCK).min(n);
            let mut prod = faer::Mat::<f64>::zeros(a.ncols(), b.ncols());
            faer::linalg::matmul::matmul(
                prod.as_mut(),
                faer::Accum::Replace,
                row_block(a, &rows).transpose(),
                row_block(b, &rows),
                1.0,
                faer::Par::Seq,
            );
            prod
        })
        .collect();
    let mut out = DMatrix::zeros(a.ncols(), b.ncols());
    for p in &partial {
        for j in 0..out.ncols() {
            for i in 0..out.nrows() {
                out[(i, j)] += p[(i, j)];
            }
        }
    }
    out
}

/// Rows `rows` of every column of `m`, in place (column stride: `m`'s row count).
fn row_block<'m>(m: &'m DMatrix<f64>, rows: &std::ops::Range<usize>) -> faer::MatRef<'m, f64> {
    faer::MatRef::from_column_major_slice_with_stride(
        &m.as_slice()[rows.start.min(m.as_slice().len())..],
        rows.len(),
        m.ncols(),
        m.nrows(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Uniform draws on [−½, ½) from a xorshift generator started at `state`.
    fn xorshift(mut state: u64) -> impl FnMut() -> f64 {
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
    }

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

    /// Columns whose plain sum of squares over- or underflows (entries near 1e±170) and
    /// an all-zero column: `R(A D) = R(A) D` for a positive diagonal D, so each column of
    /// R is the unscaled one's times its scale, to 1e-12 of that column's largest entry;
    /// the zero column's R column zero.
    #[test]
    fn r_factor_keeps_columns_beyond_the_plain_sum_of_squares() {
        let mut g = rbprops_testkit::Lcg::new(7);
        let mut a = DMatrix::from_fn(2 * R_BLOCK + 33, 4, |_, _| g.centred());
        a.column_mut(2).fill(0.0);
        let cols = [0, 1, 2, 3];
        let plain = r_factor(&a, &cols, &[1.0; 4]);
        let d = [1e170, 1e-170, 1.0, 1.0];
        let scaled = r_factor(&a, &cols, &d.map(|x| 1.0 / x));
        for k in 0..4 {
            let want = plain.column(k) * d[k];
            let tol = 1e-12 * want.amax();
            for i in 0..=k {
                let sign = (scaled[(i, i)] * plain[(i, i)]).signum();
                let sign = if sign == 0.0 { 1.0 } else { sign };
                let diff = (scaled[(i, k)] - sign * want[i]).abs();
                assert!(
                    diff <= tol,
                    "R[{i},{k}] {:e} vs {:e}",
                    scaled[(i, k)],
                    want[i]
                );
            }
        }
        assert!(scaled.column(2).iter().all(|&x| x == 0.0));
    }

    /// `gram` and `tr_mul` are nalgebra's `tr_mul` to rounding: every entry within the
    /// dot product's error bound `n ε ‖aᵢ‖ ‖bⱼ‖` of both (twice it between them), for row
    /// counts below, at and across the block size, values of mixed sign and magnitude, and
    /// zero runs (whole blocks, a column zero but in one row, an all-zero column: the
    /// block boundaries and signed zeros a product must keep); `gram` exactly
    /// symmetric; the same bits on one and two threads.
    #[test]
    fn gram_and_tr_mul_are_nalgebras_to_rounding() {
        let mut next = xorshift(0x2545f4914f6cdd1du64);
        let close =
            |got: &DMatrix<f64>, want: &DMatrix<f64>, a: &DMatrix<f64>, b: &DMatrix<f64>| {
                assert_eq!(got.shape(), want.shape());
                let n = a.nrows().max(1) as f64;
                for i in 0..got.nrows() {
                    for j in 0..got.ncols() {
                        let bound =
                            2.0 * n * f64::EPSILON * a.column(i).norm() * b.column(j).norm();
                        let (g, w) = (got[(i, j)], want[(i, j)]);
                        assert!((g - w).abs() <= bound, "({i}, {j}) of {n} rows: {g} vs {w}");
                    }
                }
            };
        for (n, p) in [
            (0, 3),
            (1, 1),
            (7, 2),
            (8, 3),
            (13, 4),
            (255, 5),
            (PRODUCT_BLOCK, 6),
            (777, 9),
            (2 * PRODUCT_BLOCK + 11, 17),
        ] {
            let mut j = DMatrix::from_fn(n, p, |_, c| next() * 10f64.powi(c as i32 % 7 - 3));
            for c in (1..p).step_by(2) {
                for r in 0..n {
                    if !(r / (PRODUCT_BLOCK / 2) + c).is_multiple_of(3)
                        && (c % 4 != 1 || r != n / 2)
                    {
                        j[(r, c)] = if r.is_multiple_of(2) { 0.0 } else { -0.0 };
                    }
                }
            }
            let got = gram(&j);
            close(&got, &j.tr_mul(&j), &j, &j);
            assert_eq!(got, got.transpose(), "n = {n}, p = {p}: not symmetric");
            let k = DMatrix::from_fn(n, p / 2 + 1, |_, c| next() * 10f64.powi(3 - c as i32 % 5));
            close(&tr_mul(&j, &k), &j.tr_mul(&k), &j, &k);
            let on = |threads: usize| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                pool.install(|| (gram(&j), tr_mul(&j, &k)))
            };
            let (one, two) = (on(1), on(2));
            let bits = |m: &DMatrix<f64>| m.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&one.0), bits(&two.0));
            assert_eq!(bits(&one.1), bits(&two.1));
        }
    }

    /// The blocked thin QR and SVD against nalgebra's on a tall matrix of five blocks and
    /// a remainder, columns scaled over 12 decades, one nearly a combination of two
    /// others (condition ~1e8): A = QR and QᵀQ = I to 1e-14, the singular values to
    /// 1e-13 of the largest (Householder rounding, ~n^½ ε), U's span the same where the
    /// singular values are apart; the same bits on one and two threads.
    #[test]
    fn thin_qr_and_svd_match_a_dense_factorisation() {
        let mut next = xorshift(0x9e3779b97f4a7c15u64);
        // Several blocks, and one block alone (its Q and R are the answer).
        for (n, p) in [(5 * QR_BLOCK + 77, 9), (QR_BLOCK / 2 + 3, 9)] {
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
            // b x = b₀ is solved exactly by e₀; a backward-stable solve is off by about
            // κ(b)·ε (κ ≈ 1e8 here, from the nearly dependent column 4), both of them.
            let kappa = smax / want.singular_values[p - 1];
            let e0 = nalgebra::DVector::from_fn(p, |i, _| if i == 0 { 1.0 } else { 0.0 });
            for x in [solve(&want), solve(&got)] {
                let err = (&x - &e0).norm();
                assert!(err < 100.0 * kappa * f64::EPSILON, "{err:e} (κ {kappa:e})");
            }
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
    }

    /// `thin_sv` has `thin_svd`'s singular values and right vectors (to rounding; a
    /// nearly dependent column, so that the smallest is 1e-8 of the largest), no U; and
    /// `sub_mul`, `mul` are nalgebra's `C − A B`, `A B` within the dot product's error
    /// bound `k ε Σ|aᵢₗ bₗⱼ|` (twice it between them).
    #[test]
    fn thin_sv_and_products_match_nalgebra() {
        let mut next = xorshift(0x51ed270b27e3a7d5u64);
        let (n, p) = (3 * R_BLOCK + 45, 8);
        let mut a = DMatrix::from_fn(n, p, |_, _| next());
        for r in 0..n {
            a[(r, 5)] = a[(r, 0)] + 1e-8 * a[(r, 5)];
        }
        let (want, got) = (thin_svd(&a), thin_sv(&a));
        assert!(got.u.is_none());
        let smax = want.singular_values[0];
        assert!(want.singular_values[p - 1] < 1e-7 * smax);
        for (g, w) in got.singular_values.iter().zip(want.singular_values.iter()) {
            assert!((g - w).abs() <= 1e-13 * smax, "{g:e} vs {w:e}");
        }
        let (vw, vg) = (want.v_t.unwrap(), got.v_t.unwrap());
        for k in 0..p - 1 {
            let dot = vw.row(k).dot(&vg.row(k)).abs();
            assert!((dot - 1.0).abs() < 1e-10, "v_{k}: {dot}");
        }
        let b = DMatrix::from_fn(p, 3, |_, _| next() * 1e3);
        let c0 = DMatrix::from_fn(n, 3, |_, _| next());
        let mut c = c0.clone();
        sub_mul(&mut c, &a, &b);
        let (want_c, want_ab) = (&c0 - &a * &b, &a * &b);
        let ab = mul(&a, &b);
        let abs_ab = a.abs() * b.abs();
        let tol = 2.0 * (p + 1) as f64 * f64::EPSILON;
        for i in 0..n {
            for j in 0..3 {
                let m = abs_ab[(i, j)] + c0[(i, j)].abs();
                assert!(
                    (c[(i, j)] - want_c[(i, j)]).abs() <= tol * m,
                    "C − AB ({i}, {j})"
                );
                assert!(
                    (ab[(i, j)] - want_ab[(i, j)]).abs() <= tol * abs_ab[(i, j)],
                    "AB ({i}, {j})"
                );
            }
        }
    }

    /// A zero block against an infinite entry is summed, as nalgebra does (0 · ∞ is NaN):
    /// the entries NaN and infinite where nalgebra's are, the others equal to rounding.
    #[test]
    fn gram_sums_a_zero_block_against_an_infinite_entry() {
        // Column 0 zero over the first block, against the ∞ of column 1 there.
        let mut j = DMatrix::from_fn(PRODUCT_BLOCK + 600, 3, |r, c| {
            (r + 3 * c) as f64 * 0.01 + 1.0
        });
        for r in 0..PRODUCT_BLOCK {
            j[(r, 0)] = 0.0;
        }
        j[(5, 1)] = f64::INFINITY;
        let (want, got) = (j.tr_mul(&j), gram(&j));
        for (g, w) in got.iter().zip(want.iter()) {
            assert!(
                (g.is_nan() && w.is_nan())
                    || (g.is_infinite() && g == w)
                    || (g - w).abs() <= 1e-12 * w.abs(),
                "{g} vs {w}"
            );
        }
        assert!(got[(0, 1)].is_nan());
    }
}
