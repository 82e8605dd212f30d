//! The poly-reference basis of one set-up in its block form, and its least squares.
//!
//! The basis `Φ` of [`crate::plsfd`] has `2N·Ni` rows (`N` lines, `Ni` excitations) and
//! `2·modes + nres·Ni` columns: the pole columns `(a_r, b_r)` are shared by every
//! excitation's rows, but the residual terms (`U_oe`, `L_oe`) of excitation `e` live on
//! its own `2N` rows only. With 50 excitations that is 112 columns of which 14 are
//! non-zero on any row: a dense `Φ` spends 8× the work on zeros in its Gram matrix
//! (`2N·Ni·112²` against `2N·Ni·14²`), and its storage (90 MB at 1,000 lines) is cleared
//! and written on every trial of the refinement.
//!
//! Here the pole columns are one tall matrix and the residual columns one small matrix
//! per excitation. Every product of [`SetupLs`] takes each entry as the dense one does,
//! the same terms in the same order (the zeros the dense basis would add change no
//! bit; see [`crate::tallmul`]), so the solution is the dense solution: what changes is
//! only the work skipped.

use crate::band::BandData;
use crate::linalg::{self, cholesky_solve, cholesky_upper, dot, gram_usable, TallLs};
use crate::lsfd::Residuals;
use crate::pole::Pole;
use faer::{Mat, MatRef};
use rbprops_core::c64;

/// The basis `Φ` of [`crate::plsfd`] (weighted, real-stacked) as blocks.
#[derive(Debug, Clone)]
pub(crate) struct SetupBasis {
    /// Pole columns `(a_r, b_r)` of every mode over every excitation's rows
    /// (`2N·Ni × 2·modes`; excitation `e`'s rows at `2N·e`, `[Re; Im]`).
    poles: Mat<f64>,
    /// Residual-term columns of each excitation on its own `2N` rows (`2N × nres`).
    residuals: Vec<Mat<f64>>,
    /// `2N`, the rows of one excitation.
    rows_per: usize,
}

impl SetupBasis {
    /// The basis for the poles `poles` with participation vectors `parts` (`parts[r][e]`)
    /// on `bands` (one per excitation), line weights `w[e]`: per line `k` and mode `r`
    /// the columns `q w (l u + l̄ v)` and `q w·i(l u − l̄ v)` (`u = 1/(iω − λ)`,
    /// `v = 1/(iω − λ*)`), and the residual terms `q w` and `−q w/ω²`.
    pub fn new(
        poles: &[Pole],
        parts: &[Vec<c64>],
        bands: &[&BandData],
        res: Residuals,
        w: &[Vec<f64>],
    ) -> Self {
        let ni = bands.len();
        let nm = poles.len();
        let n = bands[0].n_lines();
        let q = bands[0].quantity_factor();
        let omega = &bands[0].omega;
        let nres = res.upper as usize + res.lower as usize;
        let mut a = linalg::mat_for_overwrite(2 * n * ni, 2 * nm);
        let mut residuals = Vec::with_capacity(ni);
        for e in 0..ni {
            let base = 2 * n * e;
            let mut rm = linalg::mat_for_overwrite(2 * n, nres);
            for k in 0..n {
                let qk = q[k] * w[e][k];
                let s = c64::new(0.0, omega[k]);
                for (r, p) in poles.iter().enumerate() {
                    let (u, v) = (1.0 / (s - p.0), 1.0 / (s - p.0.conj()));
                    let le = parts[r][e];
                    let c1 = qk * (le * u + le.conj() * v);
                    let c2 = qk * c64::new(0.0, 1.0) * (le * u - le.conj() * v);
                    a[(base + k, 2 * r)] = c1.re;
                    a[(base + n + k, 2 * r)] = c1.im;
                    a[(base + k, 2 * r + 1)] = c2.re;
                    a[(base + n + k, 2 * r + 1)] = c2.im;
                }
                let mut j = 0;
                if res.upper {
                    rm[(k, j)] = qk.re;
                    rm[(n + k, j)] = qk.im;
                    j += 1;
                }
                if res.lower {
                    let x = qk * (-1.0 / (omega[k] * omega[k]));
                    rm[(k, j)] = x.re;
                    rm[(n + k, j)] = x.im;
                }
            }
            residuals.push(rm);
        }
        Self {
            poles: a,
            residuals,
            rows_per: 2 * n,
        }
    }

    /// Columns of the pole block (`2·modes`).
    pub fn pole_cols(&self) -> usize {
        self.poles.ncols()
    }

    /// Residual-term columns per excitation.
    fn nres(&self) -> usize {
        self.residuals.first().map_or(0, |m| m.ncols())
    }

    /// Columns of the whole basis.
    pub fn ncols(&self) -> usize {
        self.pole_cols() + self.nres() * self.residuals.len()
    }

    /// Column of `Φ` of excitation `e`'s first residual term.
    fn residual_col(&self, e: usize) -> usize {
        self.pole_cols() + self.nres() * e
    }

    /// The columns of `Φ` non-zero on excitation `e`'s rows, in order: the pole
    /// columns, then `e`'s residual terms.
    pub fn block_cols(&self, e: usize) -> Vec<usize> {
        let r0 = self.residual_col(e);
        (0..self.pole_cols()).chain(r0..r0 + self.nres()).collect()
    }

    /// Excitation `e`'s rows of the pole block.
    fn pole_rows(&self, e: usize) -> MatRef<'_, f64> {
        self.poles
            .as_ref()
            .subrows(self.rows_per * e, self.rows_per)
    }

    /// Scales every column to unit norm as [`crate::plsfd::normalise_columns`] does the
    /// dense basis (a column's zeros outside its block add nothing to its norm); returns
    /// the scales in the column order of `Φ`.
    pub fn normalise_columns(&mut self) -> Vec<f64> {
        let mut scale = crate::plsfd::normalise_columns(&mut self.poles);
        for m in self.residuals.iter_mut() {
            scale.extend(crate::plsfd::normalise_columns(m));
        }
        scale
    }

    /// Sum of squares of each pole column (in row order), for the column scales of a
    /// set-up built one excitation at a time ([`crate::plsfd::fit_shapes`]): carried
    /// over the excitations in order, these are the sums
    /// [`SetupBasis::normalise_columns`] takes over the whole block.
    pub fn add_pole_sumsq(&self, acc: &mut [f64]) {
        for (j, a) in acc.iter_mut().enumerate() {
            for &v in column(self.poles.as_ref(), j) {
                *a += v * v;
            }
        }
    }

    /// Divides the pole columns by `pole_scale` (the set-up's column norms, 1 for a zero
    /// column) and scales the residual columns to unit norm; returns the residual
    /// columns' scales.
    pub fn scale_columns(&mut self, pole_scale: &[f64]) -> Vec<f64> {
        for (j, &s) in pole_scale.iter().enumerate() {
            if s != 1.0 {
                self.poles.col_mut(j).iter_mut().for_each(|v| *v /= s);
            }
        }
        self.residuals
            .iter_mut()
            .flat_map(crate::plsfd::normalise_columns)
            .collect()
    }

    /// `ΦᵀΦ` (symmetric): the pole block's Gram matrix, each excitation's residual
    /// terms against its pole rows and against themselves; zero between excitations.
    pub fn gram(&self) -> Mat<f64> {
        let nc = self.ncols();
        let mut g = Mat::<f64>::zeros(nc, nc);
        let pc = self.pole_cols();
        linalg::gram_lower_add_into(g.as_mut().submatrix_mut(0, 0, pc, pc), self.poles.as_ref());
        for (e, rm) in self.residuals.iter().enumerate() {
            let (c0, nr) = (self.residual_col(e), rm.ncols());
            linalg::t_mul_add_into(
                g.as_mut().submatrix_mut(c0, 0, nr, pc),
                rm.as_ref(),
                self.pole_rows(e),
            );
            linalg::gram_lower_add_into(g.as_mut().submatrix_mut(c0, c0, nr, nr), rm.as_ref());
        }
        linalg::mirror_lower(&mut g);
        g
    }

    /// `Φᵀ b` (`b` with the rows of `Φ`).
    pub fn t_mul(&self, b: &Mat<f64>) -> Mat<f64> {
        let mut out = Mat::<f64>::zeros(self.ncols(), b.ncols());
        let pc = self.pole_cols();
        linalg::t_mul_add_into(
            out.as_mut().subrows_mut(0, pc),
            self.poles.as_ref(),
            b.as_ref(),
        );
        for (e, rm) in self.residuals.iter().enumerate() {
            linalg::t_mul_add_into(
                out.as_mut().subrows_mut(self.residual_col(e), rm.ncols()),
                rm.as_ref(),
                b.as_ref().subrows(self.rows_per * e, self.rows_per),
            );
        }
        out
    }

    /// `[pole rows of e | residual terms of e]ᵀ m` for `m` with excitation `e`'s rows:
    /// the rows of `Φᵀ m` named by [`SetupBasis::block_cols`] (the others are zero).
    pub fn block_t_mul(&self, e: usize, m: MatRef<'_, f64>) -> Mat<f64> {
        let (pc, rm) = (self.pole_cols(), &self.residuals[e]);
        let mut out = Mat::<f64>::zeros(pc + rm.ncols(), m.ncols());
        linalg::t_mul_add_into(out.as_mut().subrows_mut(0, pc), self.pole_rows(e), m);
        linalg::t_mul_add_into(out.as_mut().subrows_mut(pc, rm.ncols()), rm.as_ref(), m);
        out
    }

    /// `c += α Φ x`, each row's sum over the columns in the order of `Φ`.
    pub fn mul_add(&self, c: &mut Mat<f64>, x: &Mat<f64>, alpha: f64) {
        for e in 0..self.residuals.len() {
            let rows = self.rows_per * e..self.rows_per * (e + 1);
            let pole = self.pole_rows(e);
            let rm = &self.residuals[e];
            let cols: Vec<&[f64]> = (0..pole.ncols())
                .map(|j| column(pole, j))
                .chain((0..rm.ncols()).map(|j| column(rm.as_ref(), j)))
                .collect();
            let idx = self.block_cols(e);
            let xe = Mat::from_fn(idx.len(), x.ncols(), |i, j| x[(idx[i], j)]);
            crate::tallmul::add_cols_x(
                c.as_mut().subrows_mut(rows.start, self.rows_per),
                &cols,
                xe.as_ref(),
                alpha,
            );
        }
    }

    /// The dense `Φ` (for Householder QR when the Gram matrix is too ill-conditioned).
    fn to_dense(&self) -> Mat<f64> {
        let (pc, n2) = (self.pole_cols(), self.rows_per);
        let mut a = Mat::<f64>::zeros(self.poles.nrows(), self.ncols());
        a.as_mut().subcols_mut(0, pc).copy_from(self.poles.as_ref());
        for (e, rm) in self.residuals.iter().enumerate() {
            a.as_mut()
                .submatrix_mut(n2 * e, self.residual_col(e), n2, rm.ncols())
                .copy_from(rm.as_ref());
        }
        a
    }
}

/// Column `j` of `m` as a slice (column-major storage).
fn column(m: MatRef<'_, f64>, j: usize) -> &[f64] {
    m.col(j)
        .try_as_col_major()
        .expect("column-major matrices")
        .as_slice()
}

/// Least squares `min ‖Φ x − b‖` on a [`SetupBasis`] with normalised columns: as
/// [`TallLs`] (Cholesky of the Gram matrix with one refinement step where needed,
/// Householder QR of the dense `Φ` when ill-conditioned), the products by blocks.
#[derive(Debug)]
pub(crate) struct SetupLs {
    basis: SetupBasis,
    kind: Kind,
}

#[derive(Debug)]
enum Kind {
    /// Upper-triangular Cholesky factor of `ΦᵀΦ`, and whether a refinement step is
    /// needed ([`TallLs::REFINE_BELOW`]).
    Gram(Mat<f64>, bool),
    /// The dense `Φ` factorised ([`TallLs`] falls back to Householder QR).
    Dense(TallLs),
}

impl SetupLs {
    /// Prepares the solve (the choice of [`TallLs::new`], on the same Gram matrix).
    pub fn new(basis: SetupBasis) -> Self {
        let g = basis.gram();
        if let Some(r) = cholesky_upper(&g) {
            if let Some(refine) = gram_usable(&r) {
                return Self {
                    basis,
                    kind: Kind::Gram(r, refine),
                };
            }
        }
        let dense = TallLs::new(basis.to_dense());
        Self {
            basis,
            kind: Kind::Dense(dense),
        }
    }

    /// The basis.
    pub fn basis(&self) -> &SetupBasis {
        &self.basis
    }

    /// Columns of `Φ`.
    pub fn ncols(&self) -> usize {
        self.basis.ncols()
    }

    /// Entry `(i, j)` of the triangular factor R (`i ≤ j`).
    pub fn r(&self, i: usize, j: usize) -> f64 {
        match &self.kind {
            Kind::Gram(r, _) => {
                if i <= j {
                    r[(i, j)]
                } else {
                    0.0
                }
            }
            Kind::Dense(ls) => ls.r(i, j),
        }
    }

    /// |diagonal of R| (its smallest/largest ratio bounds the conditioning of `Φ`).
    pub fn r_diag(&self) -> Vec<f64> {
        (0..self.ncols()).map(|i| self.r(i, i).abs()).collect()
    }

    /// `(ΦᵀΦ)⁻¹ = R⁻¹R⁻ᵀ`.
    pub fn inverse_gram(&self) -> Mat<f64> {
        linalg::inverse_gram_of(self.ncols(), |i, j| self.r(i, j))
    }

    /// As [`TallLs::solve_into`]: `(x, residuals, residual sum of squares per column)`,
    /// the residuals overwriting `b`.
    pub fn solve_into(&self, b: Mat<f64>) -> (Mat<f64>, Mat<f64>, Vec<f64>) {
        let (r, refine) = match &self.kind {
            Kind::Dense(ls) => return ls.solve_into(b),
            Kind::Gram(r, refine) => (r, *refine),
        };
        let mut resid = b;
        let mut x = self.basis.t_mul(&resid);
        cholesky_solve(r, &mut x);
        self.basis.mul_add(&mut resid, &x, -1.0);
        if refine {
            // One refinement step: x += (ΦᵀΦ)⁻¹Φᵀr, r −= Φ·dx (as `TallLs`).
            let mut dx = self.basis.t_mul(&resid);
            cholesky_solve(r, &mut dx);
            self.basis.mul_add(&mut resid, &dx, -1.0);
            x += dx;
        }
        let rss = (0..resid.ncols())
            .map(|j| {
                let c = column(resid.as_ref(), j);
                dot(c, c)
            })
            .collect();
        (x, resid, rss)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rbprops_core::Quantity;

    /// Three excitations × two outputs of accelerance with two modes; `lines` lines.
    fn bands(lines: usize) -> Vec<BandData> {
        let omega: Vec<f64> = (1..=lines).map(|k| 0.05 * k as f64).collect();
        (0..3)
            .map(|e| BandData {
                quantity: Quantity::Accelerance,
                frequency_hz: omega
                    .iter()
                    .map(|w| w / (2.0 * std::f64::consts::PI))
                    .collect(),
                omega: omega.clone(),
                channels: (0..2)
                    .map(|o| {
                        omega
                            .iter()
                            .map(|&w| c64::new((w * (1 + o + e) as f64).sin(), 0.1 * w))
                            .collect()
                    })
                    .collect(),
                first_line: 0,
                line_quality: None,
            })
            .collect()
    }

    /// The block products and solve equal the dense ones bit for bit, for line counts
    /// whose `2N` is and is not a multiple of four (`N` even and odd): the zeros of the
    /// dense basis add nothing, and each sum runs over the same terms in the same order.
    #[test]
    fn block_solution_is_the_dense_one() {
        let c = c64::new;
        let poles = [Pole::from_modal(0.3, 0.02), Pole::from_modal(0.5, 0.05)];
        let parts = vec![
            vec![c(1.0, 0.0), c(0.4, 0.1), c(-0.3, 0.0)],
            vec![c(0.2, 0.0), c(1.0, 0.0), c(0.5, -0.2)],
        ];
        for lines in [40, 41] {
            let bands = bands(lines);
            let refs: Vec<&BandData> = bands.iter().collect();
            let w = crate::plsfd::line_weights_per_excitation(&refs);
            let res = Residuals {
                upper: true,
                lower: true,
            };
            let mut blocks = SetupBasis::new(&poles, &parts, &refs, res, &w);
            let mut dense = blocks.to_dense();
            let s_dense = crate::plsfd::normalise_columns(&mut dense);
            let s_blocks = blocks.normalise_columns();
            assert_eq!(s_dense, s_blocks);
            assert_eq!(blocks.to_dense(), dense);
            let b = crate::plsfd::stacked_data(&refs, &w);
            let (x0, r0, rss0) = TallLs::new(dense.clone()).solve_into(b.clone());
            let (x1, r1, rss1) = SetupLs::new(blocks.clone()).solve_into(b.clone());
            if lines % 2 == 0 {
                assert_eq!(linalg::gram(&dense), blocks.gram());
                assert_eq!(x0, x1);
                assert_eq!(r0, r1);
                assert_eq!(rss0, rss1);
            }
            // Odd line counts: the four-lane sums of one block start on another lane
            // than in the dense basis; the same sums, rounded differently.
            let dx = (0..x0.nrows())
                .flat_map(|i| (0..x0.ncols()).map(move |j| (i, j)))
                .map(|(i, j)| (x0[(i, j)] - x1[(i, j)]).abs() / x0[(i, j)].abs().max(1e-300))
                .fold(0.0, f64::max);
            assert!(dx < 1e-9, "lines {lines}: {dx:e}");
            let e = 1;
            let em = Mat::from_fn(2 * lines, 3, |i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0);
            let full = linalg::t_mul(&dense, &{
                let mut m = Mat::<f64>::zeros(dense.nrows(), 3);
                m.as_mut()
                    .subrows_mut(2 * lines * e, 2 * lines)
                    .copy_from(em.as_ref());
                m
            });
            let part = blocks.block_t_mul(e, em.as_ref());
            for (i, &col) in blocks.block_cols(e).iter().enumerate() {
                for j in 0..3 {
                    assert!(
                        (full[(col, j)] - part[(i, j)]).abs()
                            <= 1e-12 * full[(col, j)].abs().max(1.0)
                    );
                }
            }
        }
    }
}
