//! Residues by least squares in the frequency domain (LSFD) once the poles are known,
//! and joint refinement of the poles (variable projection).
//!
//! Model of one channel in the measured quantity (`q(ω) = (iω)^k`, k = 0, 1, 2 for
//! receptance, mobility, accelerance):
//!
//! ```text
//!   H(ω) = q(ω) [ Σ_r ( R_r/(iω−λ_r) + R_r*/(iω−λ_r*) ) + U + L/(iω)² ]
//! ```
//!
//! with `R_r = a_r + i b_r` complex and the residual terms `U` (upper: modes above the
//! band, a constant receptance) and `L` (lower: modes below the band, a mass line) real.
//! Conjugate symmetry is enforced by solving for the real unknowns `(a_r, b_r, U, L)`
//! on the real-stacked equations `[Re; Im]`. All channels share the basis, so one QR
//! factorisation serves them all.

use crate::band::BandData;
use crate::linalg::{self, TallQr};
use crate::pole::Pole;
use faer::Mat;
use rbprops_core::c64;

/// Which residual terms the model carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Residuals {
    pub upper: bool,
    pub lower: bool,
}

impl Residuals {
    /// Upper always (when enabled); lower only when the band starts above 0 Hz, where
    /// `1/(iω)²` is finite.
    pub fn for_band(enabled: bool, band: &BandData) -> Self {
        Self {
            upper: enabled,
            lower: enabled && band.omega[0] > 0.0,
        }
    }
    fn count(self) -> usize {
        self.upper as usize + self.lower as usize
    }
}

/// Complex basis columns (before real stacking), each already multiplied by `q(ω)`.
fn basis_columns(poles: &[Pole], band: &BandData, res: Residuals) -> Vec<Vec<c64>> {
    let q = band.quantity_factor();
    let mut cols = Vec::with_capacity(2 * poles.len() + res.count());
    for p in poles {
        let mut c1 = Vec::with_capacity(band.n_lines());
        let mut c2 = Vec::with_capacity(band.n_lines());
        for (k, &w) in band.omega.iter().enumerate() {
            let s = c64::new(0.0, w);
            let u = 1.0 / (s - p.0);
            let v = 1.0 / (s - p.0.conj());
            c1.push(q[k] * (u + v));
            c2.push(q[k] * c64::new(0.0, 1.0) * (u - v));
        }
        cols.push(c1);
        cols.push(c2);
    }
    if res.upper {
        cols.push(q.clone());
    }
    if res.lower {
        cols.push(
            band.omega
                .iter()
                .zip(&q)
                .map(|(w, qk)| qk * (-1.0 / (w * w)))
                .collect(),
        );
    }
    cols
}

/// Real-stacked, column-normalised design matrix; returns it with the column scales.
fn stack(cols: &[Vec<c64>]) -> (Mat<f64>, Vec<f64>) {
    let n = cols[0].len();
    let scale: Vec<f64> = cols
        .iter()
        .map(|c| {
            let s = c.iter().map(|z| z.norm_sqr()).sum::<f64>().sqrt();
            if s > 0.0 {
                s
            } else {
                1.0
            }
        })
        .collect();
    let a = Mat::from_fn(2 * n, cols.len(), |i, j| {
        let z = cols[j][i % n];
        (if i < n { z.re } else { z.im }) / scale[j]
    });
    (a, scale)
}

fn stack_data(chans: &[Vec<c64>]) -> Mat<f64> {
    let n = chans[0].len();
    Mat::from_fn(2 * n, chans.len(), |i, j| {
        let z = chans[j][i % n];
        if i < n {
            z.re
        } else {
            z.im
        }
    })
}

/// Residues of one set of channels for fixed poles.
#[derive(Debug, Clone)]
pub struct ResidueFit {
    /// `R` per mode and channel (pole–residue form, receptance units m/N·rad/s).
    pub residues: Vec<Vec<c64>>,
    /// Standard error of Re R and Im R (root-mean of the two variances), per mode and channel.
    pub residue_std: Vec<Vec<f64>>,
    pub upper: Vec<f64>,
    pub lower: Vec<f64>,
    /// Residual sum of squares per channel (measured quantity units²).
    pub rss: Vec<f64>,
    /// Ratio of the smallest to the largest diagonal entry of R (QR) of the normalised
    /// basis: near 0 means two poles' columns are nearly collinear (inseparable modes).
    pub basis_conditioning: f64,
}

/// LSFD: residues (and residual terms) for every channel given the poles.
pub fn fit_residues(
    poles: &[Pole],
    band: &BandData,
    chans: &[Vec<c64>],
    res: Residuals,
) -> ResidueFit {
    let cols = basis_columns(poles, band, res);
    let (a, scale) = stack(&cols);
    let rows = a.nrows();
    let p = a.ncols();
    let qr = TallQr::new(a);
    let (x, rss) = qr.solve(&stack_data(chans));
    let ginv = qr.inverse_gram();
    let rd = qr.r_diag();
    let basis_conditioning =
        rd.iter().cloned().fold(f64::INFINITY, f64::min) / rd.iter().cloned().fold(0.0, f64::max);
    let dof = (rows.saturating_sub(p)).max(1) as f64;
    let nm = poles.len();
    let no = chans.len();
    let mut residues = vec![vec![c64::new(0.0, 0.0); no]; nm];
    let mut residue_std = vec![vec![0.0; no]; nm];
    for o in 0..no {
        let s2 = rss[o] / dof;
        for m in 0..nm {
            let (ia, ib) = (2 * m, 2 * m + 1);
            residues[m][o] = c64::new(x[(ia, o)] / scale[ia], x[(ib, o)] / scale[ib]);
            let va = s2 * ginv[(ia, ia)] / (scale[ia] * scale[ia]);
            let vb = s2 * ginv[(ib, ib)] / (scale[ib] * scale[ib]);
            residue_std[m][o] = ((va + vb) / 2.0).sqrt();
        }
    }
    let mut k = 2 * nm;
    let mut take = |on: bool| -> Vec<f64> {
        if !on {
            return vec![0.0; no];
        }
        let v = (0..no).map(|o| x[(k, o)] / scale[k]).collect();
        k += 1;
        v
    };
    let upper = take(res.upper);
    let lower = take(res.lower);
    ResidueFit {
        residues,
        residue_std,
        upper,
        lower,
        rss,
        basis_conditioning,
    }
}

/// Synthesised FRFs `[channel][line]` in the measured quantity.
pub fn synthesise(poles: &[Pole], fit: &ResidueFit, band: &BandData) -> Vec<Vec<c64>> {
    let q = band.quantity_factor();
    let no = fit.upper.len();
    (0..no)
        .map(|o| {
            band.omega
                .iter()
                .enumerate()
                .map(|(k, &w)| {
                    let mut h: c64 = poles
                        .iter()
                        .zip(&fit.residues)
                        .map(|(p, r)| p.receptance(r[o], w))
                        .sum();
                    h += fit.upper[o];
                    if fit.lower[o] != 0.0 {
                        h += -fit.lower[o] / (w * w);
                    }
                    h * q[k]
                })
                .collect()
        })
        .collect()
}

/// Result of the pole refinement.
#[derive(Debug, Clone)]
pub struct Refined {
    pub poles: Vec<Pole>,
    /// Covariance of `(Re λ, Im λ)` per pole (rad/s)².
    pub covariance: Vec<[[f64; 2]; 2]>,
    pub iterations: usize,
    pub converged: bool,
    /// Weighted cost before and after.
    pub cost: (f64, f64),
}

fn cost_and_coeffs(
    poles: &[Pole],
    band: &BandData,
    data: &Mat<f64>,
    res: Residuals,
) -> (f64, Mat<f64>, Vec<f64>, TallQr, Mat<f64>) {
    let cols = basis_columns(poles, band, res);
    let (a, scale) = stack(&cols);
    let qr = TallQr::new(a.clone());
    let (x, rss) = qr.solve(data);
    (rss.iter().sum(), x, scale, qr, a)
}

/// Levenberg–Marquardt on the variable-projection functional (Golub & Pereyra; Kaufman's
/// Jacobian `J = −P⊥ (∂Φ/∂θ) c`): minimises `Σ_o ‖w_o (h_o − Φ(λ) c_o)‖²` over the poles,
/// the residues being the LSFD solution for each trial set. For noise-free data this
/// converges to the exact poles, which the polynomial (LSCF/LSCE) estimators only
/// approach; with noise it is the least-squares estimate, and `σ²(JᵀJ)⁻¹` its covariance.
pub fn refine(poles: &[Pole], band: &BandData, chans: &[Vec<c64>], res: Residuals) -> Refined {
    let n = band.n_lines();
    let no = chans.len();
    let weighted: Vec<Vec<c64>> = chans
        .iter()
        .map(|h| {
            let rms = (h.iter().map(|z| z.norm_sqr()).sum::<f64>() / n as f64).sqrt();
            h.iter().map(|z| z / rms).collect()
        })
        .collect();
    let data = stack_data(&weighted);
    let q = band.quantity_factor();
    let nm = poles.len();
    let np = 2 * nm;
    let mut cur: Vec<Pole> = poles.to_vec();
    let (mut cost, mut x, mut scale, mut qr, mut a) = cost_and_coeffs(&cur, band, &data, res);
    let cost0 = cost;
    let mut mu = 1e-3;
    let mut converged = false;
    let mut iterations = 0;
    let mut gram = Mat::<f64>::zeros(np, np);
    for it in 0..30 {
        iterations = it + 1;
        // v_{j,o} = (∂Φ/∂θ_j) c_o:  ∂/∂Reλ → q(R u + R* u'),  ∂/∂Imλ → q(iR u − iR* u'),
        // with u = 1/(s−λ)², u' = 1/(s−λ*)² and R = a + ib the residue of channel o.
        let mut v = Mat::<f64>::zeros(2 * n, np * no);
        for (m, p) in cur.iter().enumerate() {
            let u: Vec<(c64, c64)> = band
                .omega
                .iter()
                .enumerate()
                .map(|(k, &w)| {
                    let s = c64::new(0.0, w);
                    let a1 = 1.0 / (s - p.0);
                    let a2 = 1.0 / (s - p.0.conj());
                    (q[k] * a1 * a1, q[k] * a2 * a2)
                })
                .collect();
            for o in 0..no {
                let r = c64::new(
                    x[(2 * m, o)] / scale[2 * m],
                    x[(2 * m + 1, o)] / scale[2 * m + 1],
                );
                let i = c64::new(0.0, 1.0);
                for k in 0..n {
                    let dre = r * u[k].0 + r.conj() * u[k].1;
                    let dim = i * r * u[k].0 - i * r.conj() * u[k].1;
                    let (cre, cim) = ((2 * m) * no + o, (2 * m + 1) * no + o);
                    v[(k, cre)] = dre.re;
                    v[(k + n, cre)] = dre.im;
                    v[(k, cim)] = dim.re;
                    v[(k + n, cim)] = dim.im;
                }
            }
        }
        // P⊥v = v − Φ Φ⁺ v
        let (coef, _) = qr.solve(&v);
        let pv = &v - &a * &coef;
        let resid = &data - &a * &x;
        let mut g = vec![0.0; np];
        for j in 0..np {
            for l in 0..=j {
                let mut s = 0.0;
                for o in 0..no {
                    let (cj, cl) = (j * no + o, l * no + o);
                    for k in 0..2 * n {
                        s += pv[(k, cj)] * pv[(k, cl)];
                    }
                }
                gram[(j, l)] = s;
                gram[(l, j)] = s;
            }
            let mut s = 0.0;
            for o in 0..no {
                for k in 0..2 * n {
                    s += pv[(k, j * no + o)] * resid[(k, o)];
                }
            }
            g[j] = s;
        }
        // LM step with Marquardt scaling; retry with more damping until the cost drops.
        let mut accepted = false;
        for _ in 0..12 {
            let lhs = Mat::from_fn(np, np, |i, j| {
                gram[(i, j)] + if i == j { mu * gram[(i, i)] } else { 0.0 }
            });
            let rhs = Mat::from_fn(np, 1, |i, _| g[i]);
            let Some(step) = linalg::solve_square(&lhs, &rhs) else {
                mu *= 10.0;
                continue;
            };
            let trial: Vec<Pole> = cur
                .iter()
                .enumerate()
                .map(|(m, p)| Pole(p.0 + c64::new(step[(2 * m, 0)], step[(2 * m + 1, 0)])))
                .collect();
            if trial.iter().any(|p| !(p.0.re < 0.0 && p.0.im > 0.0)) {
                mu *= 10.0;
                continue;
            }
            let (c2, x2, s2, qr2, a2) = cost_and_coeffs(&trial, band, &data, res);
            if c2 <= cost {
                let rel_step = (0..nm)
                    .map(|m| {
                        c64::new(step[(2 * m, 0)], step[(2 * m + 1, 0)]).norm()
                            / cur[m].half_bandwidth().max(1e-300)
                    })
                    .fold(0.0, f64::max);
                let small = rel_step < 1e-9 || (cost - c2) <= 1e-14 * cost;
                cur = trial;
                (cost, x, scale, qr, a) = (c2, x2, s2, qr2, a2);
                mu = (mu / 10.0).max(1e-12);
                accepted = true;
                if small {
                    converged = true;
                }
                break;
            }
            mu *= 10.0;
        }
        if !accepted {
            // No descent direction left: at the minimum to working precision.
            converged = true;
        }
        if converged {
            break;
        }
    }
    // Covariance σ²(JᵀJ)⁻¹ at the final point (gram from the last linearisation).
    let dof = (2 * n * no).saturating_sub(no * a.ncols() + np).max(1) as f64;
    let s2 = cost / dof;
    let inv = linalg::solve_square(&gram, &Mat::identity(np, np));
    let covariance = (0..nm)
        .map(|m| match &inv {
            Some(ci) => [
                [s2 * ci[(2 * m, 2 * m)], s2 * ci[(2 * m, 2 * m + 1)]],
                [s2 * ci[(2 * m + 1, 2 * m)], s2 * ci[(2 * m + 1, 2 * m + 1)]],
            ],
            None => [[f64::INFINITY, 0.0], [0.0, f64::INFINITY]],
        })
        .collect();
    Refined {
        poles: cur,
        covariance,
        iterations,
        converged,
        cost: (cost0, cost),
    }
}
