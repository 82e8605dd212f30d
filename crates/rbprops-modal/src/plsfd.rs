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
use crate::setup_bands::Bands;
use crate::ModalError;
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
    /// Smallest / largest |diagonal of R| of the normalised basis.
    pub basis_conditioning: f64,
    /// What [`ShapeFit::synthesised`] needs to make one excitation's fitted FRFs again.
    model: FittedModel,
}

/// The fitted coefficients of the normalised basis and what the basis is made from.
#[derive(Debug, Clone)]
struct FittedModel {
    poles: Vec<Pole>,
    parts: Vec<Vec<c64>>,
    res: Residuals,
    /// Column scales of `Φ` (pole columns, then each excitation's residual terms).
    scale: Vec<f64>,
    /// Coefficients of the normalised `Φ`, one column per output.
    x: Mat<f64>,
}

/// Fits the mode shapes of every output of `bands` (one per excitation, same axis and
/// outputs) for the poles `poles` with participation vectors `parts` (`parts[r][e]`).
///
/// The least squares `min ‖Φ x − b‖` ([`SetupLs`]: normal equations, one refinement
/// step where needed) made one excitation at a time: the basis and the data of an
/// excitation are its own `2N` rows, so `ΦᵀΦ` and `Φᵀb` are sums over the excitations,
/// and the residuals are made again per excitation. What is held is a matrix of the
/// basis's columns squared, never the `2N·Ni`-row basis or data (issue 41: the shape
/// fit of 192 excitations × 1,601 lines held 150 MB). A Gram matrix too ill-conditioned
/// for that falls back to Householder QR of the whole basis ([`SetupLs`]).
pub(crate) fn fit_shapes(
    poles: &[Pole],
    parts: &[Vec<c64>],
    bands: &dyn Bands,
    res: Residuals,
) -> Result<ShapeFit, ModalError> {
    let ni = bands.len();
    let first = bands.band(0)?;
    let (n, no) = (first.n_lines(), first.channels.len());
    drop(first);
    // Excitation e's basis block (normalised with the set-up's pole-column scales when
    // given), its weighted data and the residual columns' scales.
    let block = |e: usize, pole_scale: Option<&[f64]>| -> Result<_, ModalError> {
        let band = bands.band(e)?;
        let w = [line_weights(&band.channels)];
        let pe: Vec<Vec<c64>> = parts.iter().map(|l| vec![l[e]]).collect();
        let mut b = SetupBasis::new(poles, &pe, &[band.as_ref()], res, &w);
        let rs = pole_scale.map(|s| b.scale_columns(s)).unwrap_or_default();
        let data = pole_scale.map(|_| stacked_data(&[band.as_ref()], &w));
        Ok((b, data, rs))
    };
    // The pole columns' norms over every excitation's rows.
    let pc = 2 * poles.len();
    let mut sumsq = vec![0.0; pc];
    for e in 0..ni {
        block(e, None)?.0.add_pole_sumsq(&mut sumsq);
    }
    let pole_scale: Vec<f64> = sumsq
        .iter()
        .map(|&s| if s > 0.0 { s.sqrt() } else { 1.0 })
        .collect();
    let nres = res.upper as usize + res.lower as usize;
    let ncol = pc + nres * ni;
    let (mut g, mut atb) = (Mat::<f64>::zeros(ncol, ncol), Mat::<f64>::zeros(ncol, no));
    let mut scale = pole_scale.clone();
    for e in 0..ni {
        let (b, data, rs) = block(e, Some(&pole_scale))?;
        scale.extend(rs);
        add_block(&mut g, &b.gram(), pc, e, nres);
        add_block(
            &mut atb,
            &b.t_mul(&data.expect("data with scales")),
            pc,
            e,
            nres,
        );
    }
    let gram = crate::linalg::cholesky_upper(&g)
        .and_then(|r| crate::linalg::gram_usable(&r).map(|refine| (r, refine)));
    let Some((r, refine)) = gram else {
        return fit_shapes_whole(poles, parts, bands, res);
    };
    // `Φᵀ(b − Φx)`, and the residual sums of squares per output into `rss`.
    let residual_pass = |x: &Mat<f64>, rss: &mut [f64]| -> Result<Mat<f64>, ModalError> {
        let mut t = Mat::<f64>::zeros(ncol, no);
        for e in 0..ni {
            let (b, data, _) = block(e, Some(&pole_scale))?;
            let mut resid = data.expect("data with scales");
            b.mul_add(&mut resid, &rows_of(x, pc, e, nres), -1.0);
            add_block(&mut t, &b.t_mul(&resid), pc, e, nres);
            for (o, s) in rss.iter_mut().enumerate() {
                let c = resid
                    .col(o)
                    .try_as_col_major()
                    .expect("column-major")
                    .as_slice();
                *s += crate::linalg::dot(c, c);
            }
        }
        Ok(t)
    };
    let mut x = atb;
    crate::linalg::cholesky_solve(&r, &mut x);
    let mut rss = vec![0.0; no];
    if refine {
        // One refinement step: x += (ΦᵀΦ)⁻¹Φᵀr (as `SetupLs`).
        let mut dx = residual_pass(&x, &mut rss)?;
        crate::linalg::cholesky_solve(&r, &mut dx);
        x += dx;
        rss.iter_mut().for_each(|s| *s = 0.0);
    }
    residual_pass(&x, &mut rss)?;
    let ginv = crate::linalg::inverse_gram_of(ncol, |i, j| if i <= j { r[(i, j)] } else { 0.0 });
    let rd: Vec<f64> = (0..ncol).map(|i| r[(i, i)].abs()).collect();
    let model = FittedModel {
        poles: poles.to_vec(),
        parts: parts.to_vec(),
        res,
        scale,
        x,
    };
    Ok(shape_fit(model, (&ginv, &rd, &rss), 2 * n * ni, ni))
}

/// `rows` (`pole columns + nres·Ni` rows) += excitation `e`'s block (`pc + nres` rows:
/// its pole rows, then its residual terms); for a square `rows`, the columns alike.
fn add_block(rows: &mut Mat<f64>, blk: &Mat<f64>, pc: usize, e: usize, nres: usize) {
    let idx = |i: usize| if i < pc { i } else { pc + nres * e + (i - pc) };
    let square = rows.ncols() == rows.nrows();
    for j in 0..blk.ncols() {
        let jj = if square { idx(j) } else { j };
        for i in 0..blk.nrows() {
            rows[(idx(i), jj)] += blk[(i, j)];
        }
    }
}

/// Excitation `e`'s rows of the coefficients `x` (its block's columns of `Φ`).
fn rows_of(x: &Mat<f64>, pc: usize, e: usize, nres: usize) -> Mat<f64> {
    Mat::from_fn(pc + nres, x.ncols(), |i, j| {
        x[(if i < pc { i } else { pc + nres * e + (i - pc) }, j)]
    })
}

/// [`fit_shapes`] on the whole basis at once (Householder QR of the dense basis), for a
/// Gram matrix too ill-conditioned to solve: every band held.
pub(crate) fn fit_shapes_whole(
    poles: &[Pole],
    parts: &[Vec<c64>],
    bands: &dyn Bands,
    res: Residuals,
) -> Result<ShapeFit, ModalError> {
    let held: Vec<std::borrow::Cow<'_, BandData>> = (0..bands.len())
        .map(|e| bands.band(e))
        .collect::<Result<_, _>>()?;
    let bands: Vec<&BandData> = held.iter().map(|b| b.as_ref()).collect();
    let w = line_weights_per_excitation(&bands);
    let mut a = SetupBasis::new(poles, parts, &bands, res, &w);
    let scale = a.normalise_columns();
    let b = stacked_data(&bands, &w);
    let ls = SetupLs::new(a);
    let (x, _, rss) = ls.solve_into(b);
    let ginv = ls.inverse_gram();
    let rd = ls.r_diag();
    let rows = 2 * bands[0].n_lines() * bands.len();
    let model = FittedModel {
        poles: poles.to_vec(),
        parts: parts.to_vec(),
        res,
        scale,
        x,
    };
    Ok(shape_fit(model, (&ginv, &rd, &rss), rows, bands.len()))
}

/// Shapes, residues and their standard errors from the fitted model, `(ΦᵀΦ)⁻¹`, the
/// diagonal of R and the residual sums of squares, with the rows of `Φ` and the number
/// of excitations.
fn shape_fit(
    model: FittedModel,
    (ginv, rd, rss): (&Mat<f64>, &[f64], &[f64]),
    rows: usize,
    ni: usize,
) -> ShapeFit {
    let (nm, no) = (model.poles.len(), model.x.ncols());
    let (x, scale, parts) = (&model.x, &model.scale, &model.parts);
    let basis_conditioning =
        rd.iter().cloned().fold(f64::INFINITY, f64::min) / rd.iter().cloned().fold(0.0, f64::max);
    let dof = rows.saturating_sub(x.nrows()).max(1) as f64;
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
    ShapeFit {
        shapes,
        residues,
        residue_std,
        basis_conditioning,
        model,
    }
}

impl ShapeFit {
    /// The fitted FRFs `[o][line]` of excitation `e` (its band `band`, as fitted), in the
    /// measured quantity: the data less the weighted residual, made again from the
    /// fitted coefficients one excitation at a time.
    pub fn synthesised(&self, e: usize, band: &BandData) -> Vec<Vec<c64>> {
        let m = &self.model;
        let (pc, n) = (2 * m.poles.len(), band.n_lines());
        let nres = m.res.upper as usize + m.res.lower as usize;
        let w = vec![line_weights(&band.channels)];
        let pe: Vec<Vec<c64>> = m.parts.iter().map(|l| vec![l[e]]).collect();
        let mut b = SetupBasis::new(&m.poles, &pe, &[band], m.res, &w);
        b.scale_columns(&m.scale[..pc]);
        let mut resid = stacked_data(&[band], &w);
        b.mul_add(&mut resid, &rows_of(&m.x, pc, e, nres), -1.0);
        band.channels
            .iter()
            .enumerate()
            .map(|(o, h)| {
                (0..n)
                    .map(|k| h[k] - c64::new(resid[(k, o)], resid[(n + k, o)]) / w[0][k])
                    .collect()
            })
            .collect()
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
