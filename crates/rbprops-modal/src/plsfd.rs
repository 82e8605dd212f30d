//! Poly-reference LSFD: mode shapes `ψ_r` for known poles `λ_r` and participation
//! vectors `l_r` over every excitation of a set-up at once.
//!
//! Model of output `o` and excitation `e` in the measured quantity (`q(ω) = (iω)^k`):
//!
//! ```text
//!   H_oe(ω) = q(ω) [ Σ_r ( ψ_ro l_re/(iω−λ_r) + conj(ψ_ro l_re)/(iω−λ_r*) ) + U_oe + L_oe/(iω)² ]
//! ```
//!
//! so the residue of mode `r` seen by excitation `e` is `R_roe = ψ_ro l_re` (the rank-one
//! residue matrix `ψ_r l_rᵀ`). With `ψ = a + ib` the pole columns are
//! `a (l u + l̄ v) + b i(l u − l̄ v)`, `u = 1/(iω − λ)`, `v = 1/(iω − λ*)`, stacked over
//! the excitations; the residual terms are per excitation. Every output shares the
//! basis (one QR for all). Two poles at the same place with independent participation
//! vectors give independent columns: a repeated root is separable here, where a
//! single-reference fit sees one column.

mod setup_basis;

pub(crate) use setup_basis::{SetupBasis, SetupLs};

use crate::band::BandData;
use crate::lsfd::{line_weights, Residuals};
use crate::pole::Pole;
use faer::Mat;
use rbprops_core::c64;

/// Result of [`fit_shapes`].
#[derive(Debug, Clone)]
pub struct ShapeFit {
    /// `ψ_ro` per mode and output (pole–residue units with `l_r` as given).
    pub shapes: Vec<Vec<c64>>,
    /// Per excitation: residues `R_roe = ψ_ro l_re` `[e][r][o]` and their standard errors.
    pub residues: Vec<Vec<Vec<c64>>>,
    /// Standard errors of `residues`, same layout.
    pub residue_std: Vec<Vec<Vec<f64>>>,
    /// Per excitation, fitted FRFs `[e][o][line]` in the measured quantity.
    pub synthesised: Vec<Vec<Vec<c64>>>,
    /// Smallest / largest |diagonal of R| of the normalised basis.
    pub basis_conditioning: f64,
}

/// Fits the mode shapes of every output of `bands` (one per excitation, same axis and
/// outputs) for the poles `poles` with participation vectors `parts` (`parts[r][e]`).
pub fn fit_shapes(
    poles: &[Pole],
    parts: &[Vec<c64>],
    bands: &[&BandData],
    res: Residuals,
) -> ShapeFit {
    let ni = bands.len();
    let nm = poles.len();
    let n = bands[0].n_lines();
    let no = bands[0].channels.len();
    let w = line_weights_per_excitation(bands);
    let mut a = SetupBasis::new(poles, parts, bands, res, &w);
    let (rows, ncol) = (2 * n * ni, a.ncols());
    let scale = a.normalise_columns();
    let b = stacked_data(bands, &w);
    let ls = SetupLs::new(a);
    let (x, resid, rss) = ls.solve_into(b);
    let ginv = ls.inverse_gram();
    let rd = ls.r_diag();
    let basis_conditioning =
        rd.iter().cloned().fold(f64::INFINITY, f64::min) / rd.iter().cloned().fold(0.0, f64::max);
    // The basis (`2N·Ni × 2·modes`, larger than the data) is done with: let go before
    // the fitted FRFs are made (issue 41: 219 → 166 MB at 192 excitations × 1,601 lines).
    drop(ls);
    let dof = rows.saturating_sub(ncol).max(1) as f64;
    let mut shapes = vec![vec![c64::new(0.0, 0.0); no]; nm];
    let mut shape_std = vec![vec![0.0; no]; nm];
    for o in 0..no {
        let s2 = rss[o] / dof;
        for r in 0..nm {
            let (ia, ib) = (2 * r, 2 * r + 1);
            shapes[r][o] = c64::new(x[(ia, o)] / scale[ia], x[(ib, o)] / scale[ib]);
            let va = s2 * ginv[(ia, ia)] / (scale[ia] * scale[ia]);
            let vb = s2 * ginv[(ib, ib)] / (scale[ib] * scale[ib]);
            shape_std[r][o] = ((va + vb) / 2.0).sqrt();
        }
    }
    let residues = (0..ni)
        .map(|e| {
            (0..nm)
                .map(|r| shapes[r].iter().map(|s| s * parts[r][e]).collect())
                .collect()
        })
        .collect();
    let residue_std = (0..ni)
        .map(|e| {
            (0..nm)
                .map(|r| {
                    shape_std[r]
                        .iter()
                        .map(|s| s * parts[r][e].norm())
                        .collect()
                })
                .collect()
        })
        .collect();
    let synthesised = bands
        .iter()
        .enumerate()
        .map(|(e, band)| {
            let base = 2 * n * e;
            band.channels
                .iter()
                .enumerate()
                .map(|(o, h)| {
                    (0..n)
                        .map(|k| {
                            let r = c64::new(resid[(base + k, o)], resid[(base + n + k, o)]);
                            h[k] - r / w[e][k]
                        })
                        .collect()
                })
                .collect()
        })
        .collect();
    ShapeFit {
        shapes,
        residues,
        residue_std,
        synthesised,
        basis_conditioning,
    }
}

/// The line weights of every excitation's channels ([`line_weights`]), `[e][line]`.
pub(crate) fn line_weights_per_excitation(bands: &[&BandData]) -> Vec<Vec<f64>> {
    bands.iter().map(|b| line_weights(&b.channels)).collect()
}

/// Scales the columns of `a` to unit norm (the pole columns and the residual terms
/// differ by orders of magnitude); returns the scales (1 for a zero column).
pub(crate) fn normalise_columns(a: &mut Mat<f64>) -> Vec<f64> {
    let (rows, ncol) = a.shape();
    let mut scale = vec![1.0; ncol];
    for (j, sc) in scale.iter_mut().enumerate() {
        let s = (0..rows).map(|i| a[(i, j)] * a[(i, j)]).sum::<f64>().sqrt();
        if s > 0.0 {
            *sc = s;
            for i in 0..rows {
                a[(i, j)] /= s;
            }
        }
    }
    scale
}

/// The weighted data real-stacked as the rows of [`SetupBasis`], one column per output.
pub(crate) fn stacked_data(bands: &[&BandData], w: &[Vec<f64>]) -> Mat<f64> {
    let n = bands[0].n_lines();
    let no = bands[0].channels.len();
    let mut b = Mat::<f64>::zeros(2 * n * bands.len(), no);
    for (e, band) in bands.iter().enumerate() {
        let base = 2 * n * e;
        for (o, h) in band.channels.iter().enumerate() {
            for k in 0..n {
                let z = h[k] * w[e][k];
                b[(base + k, o)] = z.re;
                b[(base + n + k, o)] = z.im;
            }
        }
    }
    b
}
