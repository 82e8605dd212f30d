//! Covariance of the real modal constants that `modal-fit` returns for one excitation,
//! linearised about the noiseless FRFs.
//!
//! # The fit being linearised (`rbprops_modal`, default method)
//! Per excitation, in the measured quantity (`q(ω) = (iω)^k`), every channel `i` follows
//!
//! ```text
//!   M_il = q_l [ Σ_r ( R_ir u_rl + R̄_ir v_rl ) + U_i + L_i/(iω_l)² ],
//!   u_rl = 1/(iω_l − λ_r),  v_rl = 1/(iω_l − λ̄_r)
//! ```
//!
//! (`L_i` only when the band starts above 0 Hz). The pipeline
//! 1. refines the poles `λ` jointly with the residues by least squares on the *focus
//!    lines* `F` (`BandData::focus_indices`: ±20 half-bandwidths of each pole, 4 lines per
//!    half-bandwidth, a 256-line skeleton), each channel scaled to unit RMS over `F`
//!    (`ρ_i`) and each line weighted by `w^F_l` (`lsfd::line_weights`);
//! 2. fits the residues and residual terms on every line `B` for those poles, line
//!    weights `w^B_l`;
//! 3. reports the real modal constants `a_ir = Re(2iω_d,r R_ir)` (rotated by the mode's
//!    principal angle, which is 0 for the real modes of a proportionally damped body,
//!    so to first order `da = Re dA`).
//!
//! # Linearisation
//! With noise `ε_il` (`Var Re = Var Im = σ²_il/2`, `σ² = a²|H|² + b²`,
//! docs/conventions.md §8), real-stacked rows and the weighted quantities
//! `X̃_i = ρ_i W_F X_F`, `J̃_i = ρ_i W_F J_λi,F` (residue basis, pole derivatives):
//!
//! ```text
//!   step 1:  P_i = J̃_i − X̃_i (X̃_iᵀX̃_i)⁻¹ X̃_iᵀ J̃_i,   S = Σ_i P_iᵀP_i,
//!            dλ = S⁻¹ Σ_i P_iᵀ ε̃_i,             Cov dλ = S⁻¹ (Σ_i P_iᵀ D̃_i P_i) S⁻¹
//!   step 2:  G = (X̂ᵀX̂)⁻¹X̂ᵀ (X̂ = W_B X_B),   da_i = E ε̂_i + K_i dλ,
//!            E = C_a G,   K_i = C_λi − E Ĵ_i
//! ```
//!
//! where `C_a`, `C_λi` are the derivatives of `a_ir = −2 ω_d,r Im R_ir` with respect to
//! the residue and pole parameters. Then
//!
//! ```text
//!   Cov(a_i, a_j) = δ_ij E V̂_i Eᵀ + H_i S⁻¹K_jᵀ + K_i S⁻¹H_jᵀ + K_i Cov(dλ) K_jᵀ,
//!   H_i = Σ_{rows of F} E[:, row] P_i[row, :] w^B ρ_i w^F σ²/2
//! ```
//!
//! (`H_i S⁻¹` is the covariance of channel i's step-2 noise with the poles). Every
//! term is O(lines × parameters²) per channel.

use crate::model::{PlanModel, SetupModes};
use nalgebra::DMatrix;
use nalgebra::RowVector6;
use rbprops_core::{c64, Vec6};
use rbprops_modal::band::BandData;
use rbprops_modal::Pole;

/// Focus half-widths, lines per half-width and skeleton of `modal-fit`'s refinement
/// (`rbprops_modal` fit.rs: `FOCUS_HALF_WIDTHS`, 4.0, `SKELETON_LINES`).
const FOCUS: (f64, f64, usize) = (20.0, 4.0, 256);

/// What one excitation contributes: its true real modal constants, their covariance and
/// its Norm Indicator at each mode.
#[derive(Debug, Clone)]
pub struct ExcitationCovariance {
    /// `a[r][i] = (s_iᵀφ_r)(fᵀφ_r)` (1/kg), mode by mode, channel by channel.
    pub constants: Vec<Vec<f64>>,
    /// Covariance of the estimated constants, index `r·n_channels + i`.
    pub cov: DMatrix<f64>,
    /// `Σ_i |H_i(ω_r)|²` in the measured quantity: the square of the Norm Indicator
    /// (paper Eq. 12) at each mode's natural frequency.
    pub ni: Vec<f64>,
}

/// Linearised covariance of the real modal constants of one excitation (module docs).
pub fn excitation_covariance(
    model: &PlanModel,
    setup: &SetupModes,
    rows: &[RowVector6<f64>],
    column: &Vec6,
) -> ExcitationCovariance {
    let modes = &setup.modes;
    let nm = modes.len();
    let nc = rows.len();
    let omega = &model.omega;
    let nl = omega.len();
    let poles: Vec<c64> = modes
        .iter()
        .map(|m| {
            let w = m.omega();
            let z = m.damping_ratio;
            c64::new(-z * w, w * (1.0 - z * z).sqrt())
        })
        .collect();
    let participation: Vec<f64> = modes.iter().map(|m| column.dot(&m.shape)).collect();
    let constants: Vec<Vec<f64>> = (0..nm)
        .map(|r| {
            rows.iter()
                .map(|s| (s * modes[r].shape)[0] * participation[r])
                .collect()
        })
        .collect();
    // R = A/(2iω_d), purely imaginary for a real mode.
    let residue: Vec<Vec<c64>> = (0..nc)
        .map(|i| {
            (0..nm)
                .map(|r| c64::new(constants[r][i], 0.0) / c64::new(0.0, 2.0 * poles[r].im))
                .collect()
        })
        .collect();
    let q: Vec<c64> = omega
        .iter()
        .map(|&w| model.quantity.from_receptance_factor(w))
        .collect();
    let recips = |r: usize, l: usize| {
        let iw = c64::new(0.0, omega[l]);
        (1.0 / (iw - poles[r]), 1.0 / (iw - poles[r].conj()))
    };
    // Noiseless FRFs [channel][line] in the measured quantity.
    let h: Vec<Vec<c64>> = (0..nc)
        .map(|i| {
            (0..nl)
                .map(|l| {
                    let mut s = c64::new(0.0, 0.0);
                    for r in 0..nm {
                        let (u, v) = recips(r, l);
                        s += residue[i][r] * u + residue[i][r].conj() * v;
                    }
                    q[l] * s
                })
                .collect()
        })
        .collect();
    let ni: Vec<f64> = modes
        .iter()
        .map(|m| {
            let w = m.omega();
            let iw = c64::new(0.0, w);
            let qq = model.quantity.from_receptance_factor(w);
            (0..nc)
                .map(|i| {
                    let mut s = c64::new(0.0, 0.0);
                    for r in 0..nm {
                        s += residue[i][r] / (iw - poles[r])
                            + residue[i][r].conj() / (iw - poles[r].conj());
                    }
                    (qq * s).norm_sqr()
                })
                .sum()
        })
        .collect();
    let n_res = 1 + model.lower_residual as usize;
    let np = 2 * nm + n_res;
    let nlam = 2 * nm;
    // Residue-basis columns at line l (complex): Re R_r, Im R_r, U, L.
    let basis = |l: usize| -> Vec<c64> {
        let mut b = Vec::with_capacity(np);
        for r in 0..nm {
            let (u, v) = recips(r, l);
            b.push(q[l] * (u + v));
            b.push(q[l] * c64::new(0.0, 1.0) * (u - v));
        }
        b.push(q[l]);
        if model.lower_residual {
            b.push(-q[l] / (omega[l] * omega[l]));
        }
        b
    };
    // Pole-derivative columns of channel i at line l: Re λ_r, Im λ_r.
    let pole_cols = |i: usize, l: usize| -> Vec<c64> {
        let mut b = Vec::with_capacity(nlam);
        for r in 0..nm {
            let (u, v) = recips(r, l);
            let (a, b_) = (residue[i][r] * u * u, residue[i][r].conj() * v * v);
            b.push(q[l] * (a + b_));
            b.push(q[l] * c64::new(0.0, 1.0) * (a - b_));
        }
        b
    };
    let var = |i: usize, l: usize| model.noise.variance(h[i][l]);

    // ---- step 1: poles on the focus lines.
    let band = BandData {
        quantity: model.quantity,
        frequency_hz: omega
            .iter()
            .map(|w| w / (2.0 * std::f64::consts::PI))
            .collect(),
        omega: omega.clone(),
        channels: Vec::new(),
        first_line: 0,
        line_quality: None,
    };
    let pole_list: Vec<Pole> = poles.iter().map(|p| Pole(*p)).collect();
    let focus = band.focus_indices(&pole_list, FOCUS.0, FOCUS.1, FOCUS.2);
    let nf = focus.len();
    // The fit weighs lines and scales channels by the *measured* FRFs, whose expected
    // power is |H|² + σ² (not |H|²): where the noise floor dominates (near 0 Hz in
    // mobility, between modes of a weak channel) the noiseless |H| would give those
    // lines weights the pipeline never uses. A real magnitude stands for each line.
    let level: Vec<Vec<c64>> = (0..nc)
        .map(|i| {
            (0..nl)
                .map(|l| c64::new((h[i][l].norm_sqr() + var(i, l)).sqrt(), 0.0))
                .collect()
        })
        .collect();
    let hf: Vec<Vec<c64>> = level
        .iter()
        .map(|c| focus.iter().map(|&l| c[l]).collect())
        .collect();
    let wf = rbprops_modal::lsfd::line_weights(&hf);
    let rho: Vec<f64> = hf
        .iter()
        .map(|c| {
            let ms = c.iter().map(|z| z.norm_sqr()).sum::<f64>() / nf as f64;
            if ms > 0.0 {
                1.0 / ms.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    let xf_unit = stacked(nf, np, |k| basis(focus[k]), |k| wf[k]);
    let mut s_mat = DMatrix::<f64>::zeros(nlam, nlam);
    let mut m_mat = DMatrix::<f64>::zeros(nlam, nlam);
    let mut p_all: Vec<DMatrix<f64>> = Vec::with_capacity(nc);
    let bf = xf_unit.transpose() * &xf_unit;
    let bf_inv = pinv_sym(&bf);
    for i in 0..nc {
        if rho[i] == 0.0 {
            // A channel that does not respond carries no information on the poles.
            p_all.push(DMatrix::zeros(2 * nf, nlam));
            continue;
        }
        let jf = stacked(nf, nlam, |k| pole_cols(i, focus[k]), |k| rho[i] * wf[k]);
        let xf = &xf_unit * rho[i];
        let c = xf.transpose() * &jf;
        let p = &jf - &xf * (&bf_inv / (rho[i] * rho[i])) * c;
        s_mat += p.transpose() * &p;
        let mut pd = p.clone();
        for k in 0..nf {
            let d = rho[i] * rho[i] * wf[k] * wf[k] * var(i, focus[k]) / 2.0;
            for row in [2 * k, 2 * k + 1] {
                for col in 0..nlam {
                    pd[(row, col)] *= d;
                }
            }
        }
        m_mat += p.transpose() * pd;
        p_all.push(p);
    }
    let s_inv = pinv_sym(&s_mat);
    let cov_lambda = &s_inv * m_mat * &s_inv;

    // ---- step 2: residues on every line for the poles.
    let wb = rbprops_modal::lsfd::line_weights(&level);
    let xb = stacked(nl, np, basis, |l| wb[l]);
    let g = pinv_sym(&(xb.transpose() * &xb)) * xb.transpose();
    let mut c_a = DMatrix::<f64>::zeros(nm, np);
    for r in 0..nm {
        c_a[(r, 2 * r + 1)] = -2.0 * poles[r].im;
    }
    let e = &c_a * g; // nm × 2L
    let mut k_all = Vec::with_capacity(nc);
    let mut h_all = Vec::with_capacity(nc);
    let mut ev_all = Vec::with_capacity(nc);
    for i in 0..nc {
        let jb = stacked(nl, nlam, |l| pole_cols(i, l), |l| wb[l]);
        let mut c_l = DMatrix::<f64>::zeros(nm, nlam);
        for r in 0..nm {
            c_l[(r, 2 * r + 1)] = -2.0 * residue[i][r].im;
        }
        k_all.push(c_l - &e * jb);
        // E V̂_i Eᵀ
        let mut ev = DMatrix::<f64>::zeros(nm, nm);
        let mut scaled = e.clone();
        for l in 0..nl {
            let d = (wb[l] * wb[l] * var(i, l) / 2.0).sqrt();
            for row in [2 * l, 2 * l + 1] {
                for r in 0..nm {
                    scaled[(r, row)] *= d;
                }
            }
        }
        ev.gemm(1.0, &scaled, &scaled.transpose(), 0.0);
        ev_all.push(ev);
        // H_i = Σ_F E[:, row] P_i[row, :] w^B ρ w^F σ²/2
        let mut hi = DMatrix::<f64>::zeros(nm, nlam);
        let p = &p_all[i];
        for (k, &l) in focus.iter().enumerate() {
            let d = wb[l] * rho[i] * wf[k] * var(i, l) / 2.0;
            for (rowb, rowf) in [(2 * l, 2 * k), (2 * l + 1, 2 * k + 1)] {
                for r in 0..nm {
                    let er = e[(r, rowb)] * d;
                    if er != 0.0 {
                        for col in 0..nlam {
                            hi[(r, col)] += er * p[(rowf, col)];
                        }
                    }
                }
            }
        }
        h_all.push(hi * &s_inv);
    }
    let n = nm * nc;
    let mut cov = DMatrix::<f64>::zeros(n, n);
    for i in 0..nc {
        for j in 0..nc {
            let mut blk = &h_all[i] * k_all[j].transpose()
                + &k_all[i] * h_all[j].transpose()
                + &k_all[i] * &cov_lambda * k_all[j].transpose();
            if i == j {
                blk += &ev_all[i];
            }
            for r in 0..nm {
                for t in 0..nm {
                    cov[(r * nc + i, t * nc + j)] = blk[(r, t)];
                }
            }
        }
    }
    // Symmetrise (rounding).
    let cov = (&cov + cov.transpose()) * 0.5;
    ExcitationCovariance { constants, cov, ni }
}

/// Real-stacked weighted design matrix: line k gives rows `2k` (real parts) and `2k + 1`
/// (imaginary parts) of `weight(k) · cols(k)`.
fn stacked(
    n: usize,
    ncol: usize,
    cols: impl Fn(usize) -> Vec<c64>,
    weight: impl Fn(usize) -> f64,
) -> DMatrix<f64> {
    let mut m = DMatrix::<f64>::zeros(2 * n, ncol);
    for k in 0..n {
        let w = weight(k);
        for (c, z) in cols(k).into_iter().enumerate() {
            m[(2 * k, c)] = w * z.re;
            m[(2 * k + 1, c)] = w * z.im;
        }
    }
    m
}

/// Pseudo-inverse of a symmetric positive semi-definite matrix, eigenvalues below
/// `1e-12 · λ_max` treated as 0 (a parameter the data do not determine — e.g. the pole
/// of a mode this excitation does not excite — gets no variance and passes none on).
pub(crate) fn pinv_sym(a: &DMatrix<f64>) -> DMatrix<f64> {
    let n = a.nrows();
    // Equilibrate: the parameters differ in scale by many decades.
    let d: Vec<f64> = (0..n)
        .map(|k| {
            let v = a[(k, k)];
            if v > 0.0 {
                1.0 / v.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    let mut s = a.clone();
    for r in 0..n {
        for c in 0..n {
            s[(r, c)] *= d[r] * d[c];
        }
    }
    let eig = s.symmetric_eigen();
    let max = eig.eigenvalues.amax();
    let mut inv = DMatrix::<f64>::zeros(n, n);
    for k in 0..n {
        let l = eig.eigenvalues[k];
        if l > 1e-12 * max {
            let v = eig.eigenvectors.column(k);
            inv += (v * v.transpose()) / l;
        }
    }
    for r in 0..n {
        for c in 0..n {
            inv[(r, c)] *= d[r] * d[c];
        }
    }
    inv
}
