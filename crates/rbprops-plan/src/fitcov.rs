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

/// Linearised covariance of the real modal constants of one excitation (module docs):
/// the fit's line weights and channel scales from these channels themselves.
pub fn excitation_covariance(
    model: &PlanModel,
    setup: &SetupModes,
    rows: &[RowVector6<f64>],
    column: &Vec6,
) -> ExcitationCovariance {
    let basis = ExcitationBasis::new(model, setup, column, rows);
    let terms: Vec<ChannelTerms> = rows.iter().map(|r| basis.channel(r)).collect();
    let refs: Vec<&ChannelTerms> = terms.iter().collect();
    combine(&refs)
}

/// What every channel of one excitation's fit shares: the poles, the focus lines, the
/// line weights (`lsfd::line_weights` of the measured FRFs of the channels given to
/// [`ExcitationBasis::new`]) and the residue step's solution operator.
///
/// The weights couple the channels; everything else of the linearisation is a sum over
/// channels ([`ChannelTerms`], [`combine`]). Holding the weights of one layout while
/// trying another channel set (the planner's sensor exchanges) makes each candidate
/// channel's terms computable once and reusable.
pub struct ExcitationBasis<'a> {
    model: &'a PlanModel,
    modes: &'a [rbprops_core::modal::RigidMode],
    poles: Vec<c64>,
    participation: Vec<f64>,
    q: Vec<c64>,
    focus: Vec<usize>,
    wf: Vec<f64>,
    wb: Vec<f64>,
    xf_unit: DMatrix<f64>,
    bf_inv: DMatrix<f64>,
    /// `E = C_a G` (nm × 2L).
    e: DMatrix<f64>,
}

/// One channel's share of one excitation's linearised fit (module docs): its true
/// constants, `P_iᵀP_i`, `P_iᵀD̃_iP_i`, `K_i`, `H_i` (before `S⁻¹`), `E V̂_i Eᵀ` and
/// `|H_i(ω_r)|²`.
#[derive(Debug, Clone)]
pub struct ChannelTerms {
    constants: Vec<f64>,
    ptp: DMatrix<f64>,
    ptdp: DMatrix<f64>,
    k: DMatrix<f64>,
    h: DMatrix<f64>,
    ev: DMatrix<f64>,
    ni: Vec<f64>,
}

impl<'a> ExcitationBasis<'a> {
    /// The basis of the hit with force column `column`, its weights from the measured
    /// FRFs of `weight_rows`' channels.
    pub fn new(
        model: &'a PlanModel,
        setup: &'a SetupModes,
        column: &Vec6,
        weight_rows: &[RowVector6<f64>],
    ) -> Self {
        let modes = &setup.modes[..];
        let nm = modes.len();
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
        let q: Vec<c64> = omega
            .iter()
            .map(|&w| model.quantity.from_receptance_factor(w))
            .collect();
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
        let mut b = Self {
            model,
            modes,
            poles,
            participation,
            q,
            focus,
            wf: Vec::new(),
            wb: Vec::new(),
            xf_unit: DMatrix::zeros(0, 0),
            bf_inv: DMatrix::zeros(0, 0),
            e: DMatrix::zeros(0, 0),
        };
        // The fit weighs lines by the *measured* FRFs, whose expected power is
        // |H|² + σ² (not |H|²): where the noise floor dominates (near 0 Hz in mobility,
        // between modes of a weak channel) the noiseless |H| would give those lines
        // weights the pipeline never uses. A real magnitude stands for each line.
        let level: Vec<Vec<c64>> = weight_rows
            .iter()
            .map(|row| {
                let res = b.residues(row);
                (0..nl)
                    .map(|l| {
                        let h = b.frf(&res, l);
                        c64::new((h.norm_sqr() + model.noise.variance(h)).sqrt(), 0.0)
                    })
                    .collect()
            })
            .collect();
        let hf: Vec<Vec<c64>> = level
            .iter()
            .map(|c| b.focus.iter().map(|&l| c[l]).collect())
            .collect();
        b.wf = rbprops_modal::lsfd::line_weights(&hf);
        b.wb = rbprops_modal::lsfd::line_weights(&level);
        let np = b.n_params();
        let nf = b.focus.len();
        b.xf_unit = stacked(nf, np, |k| b.basis_cols(b.focus[k]), |k| b.wf[k]);
        b.bf_inv = pinv_sym(&(b.xf_unit.transpose() * &b.xf_unit));
        let xb = stacked(nl, np, |l| b.basis_cols(l), |l| b.wb[l]);
        let g = pinv_sym(&(xb.transpose() * &xb)) * xb.transpose();
        let mut c_a = DMatrix::<f64>::zeros(nm, np);
        for r in 0..nm {
            c_a[(r, 2 * r + 1)] = -2.0 * b.poles[r].im;
        }
        b.e = c_a * g;
        b
    }

    fn n_params(&self) -> usize {
        2 * self.modes.len() + 1 + self.model.lower_residual as usize
    }

    fn recips(&self, r: usize, l: usize) -> (c64, c64) {
        let iw = c64::new(0.0, self.model.omega[l]);
        (
            1.0 / (iw - self.poles[r]),
            1.0 / (iw - self.poles[r].conj()),
        )
    }

    /// `R = A/(2iω_d)` of a channel, purely imaginary for a real mode.
    fn residues(&self, row: &RowVector6<f64>) -> Vec<c64> {
        (0..self.modes.len())
            .map(|r| {
                let a = (row * self.modes[r].shape)[0] * self.participation[r];
                c64::new(a, 0.0) / c64::new(0.0, 2.0 * self.poles[r].im)
            })
            .collect()
    }

    /// The noiseless FRF of a channel at line `l`, in the measured quantity.
    fn frf(&self, res: &[c64], l: usize) -> c64 {
        let mut s = c64::new(0.0, 0.0);
        for (r, rr) in res.iter().enumerate() {
            let (u, v) = self.recips(r, l);
            s += rr * u + rr.conj() * v;
        }
        self.q[l] * s
    }

    /// Residue-basis columns at line `l` (complex): Re R_r, Im R_r, U, L.
    fn basis_cols(&self, l: usize) -> Vec<c64> {
        let q = self.q[l];
        let mut b = Vec::with_capacity(self.n_params());
        for r in 0..self.modes.len() {
            let (u, v) = self.recips(r, l);
            b.push(q * (u + v));
            b.push(q * c64::new(0.0, 1.0) * (u - v));
        }
        b.push(q);
        if self.model.lower_residual {
            let w = self.model.omega[l];
            b.push(-q / (w * w));
        }
        b
    }

    /// Pole-derivative columns of a channel at line `l`: Re λ_r, Im λ_r.
    fn pole_cols(&self, res: &[c64], l: usize) -> Vec<c64> {
        let q = self.q[l];
        let mut b = Vec::with_capacity(2 * self.modes.len());
        for (r, rr) in res.iter().enumerate() {
            let (u, v) = self.recips(r, l);
            let (a, b_) = (rr * u * u, rr.conj() * v * v);
            b.push(q * (a + b_));
            b.push(q * c64::new(0.0, 1.0) * (a - b_));
        }
        b
    }

    /// One channel's terms (module docs), the weights held.
    pub fn channel(&self, row: &RowVector6<f64>) -> ChannelTerms {
        let model = self.model;
        let nm = self.modes.len();
        let nlam = 2 * nm;
        let nl = model.omega.len();
        let nf = self.focus.len();
        let res = self.residues(row);
        let constants: Vec<f64> = (0..nm)
            .map(|r| (row * self.modes[r].shape)[0] * self.participation[r])
            .collect();
        let h: Vec<c64> = (0..nl).map(|l| self.frf(&res, l)).collect();
        let var: Vec<f64> = h.iter().map(|z| model.noise.variance(*z)).collect();
        let ni: Vec<f64> = self
            .modes
            .iter()
            .map(|m| {
                let w = m.omega();
                let iw = c64::new(0.0, w);
                let mut s = c64::new(0.0, 0.0);
                for (r, rr) in res.iter().enumerate() {
                    s += rr / (iw - self.poles[r]) + rr.conj() / (iw - self.poles[r].conj());
                }
                (model.quantity.from_receptance_factor(w) * s).norm_sqr()
            })
            .collect();
        // Step 1: this channel's share of the pole information, scaled to unit RMS over
        // the focus lines (of its measured FRF).
        let ms = self
            .focus
            .iter()
            .map(|&l| h[l].norm_sqr() + var[l])
            .sum::<f64>()
            / nf as f64;
        let rho = if ms > 0.0 { 1.0 / ms.sqrt() } else { 0.0 };
        let mut ptp = DMatrix::<f64>::zeros(nlam, nlam);
        let mut ptdp = DMatrix::<f64>::zeros(nlam, nlam);
        let mut p = DMatrix::<f64>::zeros(2 * nf, nlam);
        if rho > 0.0 {
            // A channel that does not respond carries no information on the poles.
            let jf = stacked(
                nf,
                nlam,
                |k| self.pole_cols(&res, self.focus[k]),
                |k| rho * self.wf[k],
            );
            let c = self.xf_unit.transpose() * &jf;
            p = &jf - &self.xf_unit * (&self.bf_inv * c);
            ptp = p.transpose() * &p;
            let mut pd = p.clone();
            for k in 0..nf {
                let d = rho * rho * self.wf[k] * self.wf[k] * var[self.focus[k]] / 2.0;
                for row in [2 * k, 2 * k + 1] {
                    for col in 0..nlam {
                        pd[(row, col)] *= d;
                    }
                }
            }
            ptdp = p.transpose() * pd;
        }
        // Step 2: residues on every line for the poles.
        let jb = stacked(nl, nlam, |l| self.pole_cols(&res, l), |l| self.wb[l]);
        let mut c_l = DMatrix::<f64>::zeros(nm, nlam);
        for r in 0..nm {
            c_l[(r, 2 * r + 1)] = -2.0 * res[r].im;
        }
        let k = c_l - &self.e * jb;
        // E V̂_i Eᵀ
        let mut scaled = self.e.clone();
        for l in 0..nl {
            let d = (self.wb[l] * self.wb[l] * var[l] / 2.0).sqrt();
            for row in [2 * l, 2 * l + 1] {
                for r in 0..nm {
                    scaled[(r, row)] *= d;
                }
            }
        }
        let ev = &scaled * scaled.transpose();
        // H_i = Σ_F E[:, row] P_i[row, :] w^B ρ w^F σ²/2
        let mut hi = DMatrix::<f64>::zeros(nm, nlam);
        if rho > 0.0 {
            for (kf, &l) in self.focus.iter().enumerate() {
                let d = self.wb[l] * rho * self.wf[kf] * var[l] / 2.0;
                for (rowb, rowf) in [(2 * l, 2 * kf), (2 * l + 1, 2 * kf + 1)] {
                    for r in 0..nm {
                        let er = self.e[(r, rowb)] * d;
                        if er != 0.0 {
                            for col in 0..nlam {
                                hi[(r, col)] += er * p[(rowf, col)];
                            }
                        }
                    }
                }
            }
        }
        ChannelTerms {
            constants,
            ptp,
            ptdp,
            k,
            h: hi,
            ev,
            ni,
        }
    }
}

/// The covariance of one excitation's constants from its channels' terms (module docs):
/// `S = Σ P_iᵀP_i`, `Cov dλ = S⁻¹(Σ P_iᵀD̃_iP_i)S⁻¹`, then the blocks
/// `δ_ij E V̂_i Eᵀ + H_i S⁻¹K_jᵀ + K_i S⁻¹H_jᵀ + K_i Cov(dλ) K_jᵀ`.
pub fn combine(terms: &[&ChannelTerms]) -> ExcitationCovariance {
    let nc = terms.len();
    let nm = terms.first().map_or(0, |t| t.constants.len());
    let nlam = 2 * nm;
    let mut s_mat = DMatrix::<f64>::zeros(nlam, nlam);
    let mut m_mat = DMatrix::<f64>::zeros(nlam, nlam);
    for t in terms {
        s_mat += &t.ptp;
        m_mat += &t.ptdp;
    }
    let s_inv = pinv_sym(&s_mat);
    let cov_lambda = &s_inv * m_mat * &s_inv;
    let hs: Vec<DMatrix<f64>> = terms.iter().map(|t| &t.h * &s_inv).collect();
    let kc: Vec<DMatrix<f64>> = terms.iter().map(|t| &t.k * &cov_lambda).collect();
    let n = nm * nc;
    let mut cov = DMatrix::<f64>::zeros(n, n);
    for i in 0..nc {
        for j in 0..nc {
            let kj = terms[j].k.transpose();
            let mut blk = &hs[i] * &kj + &kc[i] * &kj + &terms[i].k * hs[j].transpose();
            if i == j {
                blk += &terms[i].ev;
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
    ExcitationCovariance {
        constants: (0..nm)
            .map(|r| terms.iter().map(|t| t.constants[r]).collect())
            .collect(),
        cov,
        ni: (0..nm)
            .map(|r| terms.iter().map(|t| t.ni[r]).sum())
            .collect(),
    }
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
