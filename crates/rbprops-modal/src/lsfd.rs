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
    /// No residual terms (the poles' own columns only).
    pub const NONE: Self = Self {
        upper: false,
        lower: false,
    };
    fn count(self) -> usize {
        self.upper as usize + self.lower as usize
    }
}

/// Per-line weights shared by all channels: `w_k = 1/√(mean_o |h_ok/rms_o|²)`.
///
/// Noise in measured FRFs is roughly proportional to |H| (1 % per line in the tests), so
/// unweighted least squares lets the resonance peaks dominate and makes the residual
/// variance meaningless for a model-order test. A weight common to all channels keeps
/// the basis shared (one QR for all channels) while equalising the lines.
pub fn line_weights(chans: &[Vec<c64>]) -> Vec<f64> {
    let n = chans[0].len();
    let rms: Vec<f64> = chans
        .iter()
        .map(|h| (h.iter().map(|z| z.norm_sqr()).sum::<f64>() / n as f64).sqrt())
        .collect();
    let live: Vec<usize> = (0..chans.len()).filter(|&o| rms[o] > 0.0).collect();
    if live.is_empty() {
        return vec![1.0; n];
    }
    let level: Vec<f64> = (0..n)
        .map(|k| {
            live.iter()
                .map(|&o| chans[o][k].norm_sqr() / (rms[o] * rms[o]))
                .sum::<f64>()
                / live.len() as f64
        })
        .collect();
    let mean = level.iter().sum::<f64>() / n as f64;
    level
        .iter()
        .map(|l| 1.0 / l.max(1e-12 * mean).sqrt())
        .collect()
}

/// Complex basis columns (before real stacking), each multiplied by `q(ω)` and the line
/// weight.
fn basis_columns(poles: &[Pole], band: &BandData, res: Residuals, w: &[f64]) -> Vec<Vec<c64>> {
    let q: Vec<c64> = band
        .quantity_factor()
        .iter()
        .zip(w)
        .map(|(q, w)| q * *w)
        .collect();
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
    let mut a = Mat::<f64>::zeros(2 * n, cols.len());
    for (j, (c, s)) in cols.iter().zip(&scale).enumerate() {
        let col = a.col_mut(j).try_as_col_major_mut().unwrap().as_slice_mut();
        let (re, im) = col.split_at_mut(n);
        for ((r, i), z) in re.iter_mut().zip(im.iter_mut()).zip(c) {
            *r = z.re / s;
            *i = z.im / s;
        }
    }
    (a, scale)
}

fn stack_data(chans: &[Vec<c64>], w: &[f64]) -> Mat<f64> {
    let n = chans[0].len();
    Mat::from_fn(2 * n, chans.len(), |i, j| {
        let z = chans[j][i % n] * w[i % n];
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
    let w = line_weights(chans);
    let cols = basis_columns(poles, band, res, &w);
    let (a, scale) = stack(&cols);
    let rows = a.nrows();
    let p = a.ncols();
    let qr = TallQr::new(a);
    let (x, rss) = qr.solve(&stack_data(chans, &w));
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
    let mut out = vec![Vec::with_capacity(band.n_lines()); no];
    let mut h = vec![c64::new(0.0, 0.0); no];
    for (k, &w) in band.omega.iter().enumerate() {
        // The pole terms are shared by every channel: two divisions per pole and line.
        for (o, hk) in h.iter_mut().enumerate() {
            // The lower residual is zero when the band starts at 0 Hz (no 0/0 there).
            let lower = if fit.lower[o] != 0.0 {
                fit.lower[o] / (w * w)
            } else {
                0.0
            };
            *hk = c64::new(fit.upper[o] - lower, 0.0);
        }
        let s = c64::new(0.0, w);
        for (p, r) in poles.iter().zip(&fit.residues) {
            let u = 1.0 / (s - p.0);
            let v = 1.0 / (s - p.0.conj());
            for (hk, ro) in h.iter_mut().zip(r) {
                *hk += ro * u + ro.conj() * v;
            }
        }
        for (col, hk) in out.iter_mut().zip(&h) {
            col.push(hk * q[k]);
        }
    }
    out
}

/// Result of the pole refinement.
#[derive(Debug, Clone)]
pub struct Refined {
    pub poles: Vec<Pole>,
    /// Covariance of `(Re λ, Im λ)` per pole (rad/s)².
    pub covariance: Vec<[[f64; 2]; 2]>,
    /// `JᵀJ` was singular: some pole is not identifiable (two poles coincide).
    pub singular: bool,
    pub iterations: usize,
    pub converged: bool,
    /// Weighted cost before and after.
    pub cost: (f64, f64),
    /// The LSFD solution at the final poles, kept for [`screen_extra_poles`].
    fit: std::sync::Arc<Trial>,
}

/// The LSFD solution for one trial pole set (weighted data).
#[derive(Debug)]
struct Trial {
    cost: f64,
    /// Normalised basis columns (complex, before stacking) and their scales.
    cols: Vec<Vec<c64>>,
    qr: TallQr,
    /// Residues `R = a + ib` per mode and channel.
    residues: Vec<Vec<c64>>,
    /// Residual vectors per channel (complex).
    resid: Vec<Vec<c64>>,
    n_cols: usize,
}

fn trial(poles: &[Pole], band: &BandData, data: &[Vec<c64>], w: &[f64], res: Residuals) -> Trial {
    let raw = basis_columns(poles, band, res, w);
    let (a, scale) = stack(&raw);
    let cols: Vec<Vec<c64>> = raw
        .iter()
        .zip(&scale)
        .map(|(c, s)| c.iter().map(|z| z / *s).collect())
        .collect();
    let qr = TallQr::new(a);
    let (x, rss) = qr.solve(&stack_data(data, w));
    let no = data.len();
    let p = cols.len();
    let resid: Vec<Vec<c64>> = (0..no)
        .map(|o| {
            let mut r: Vec<c64> = data[o].iter().zip(w).map(|(z, wk)| z * *wk).collect();
            for j in 0..p {
                let c = x[(j, o)];
                for (rk, bk) in r.iter_mut().zip(&cols[j]) {
                    *rk -= bk * c;
                }
            }
            r
        })
        .collect();
    let residues = (0..poles.len())
        .map(|m| {
            (0..no)
                .map(|o| {
                    c64::new(
                        x[(2 * m, o)] / scale[2 * m],
                        x[(2 * m + 1, o)] / scale[2 * m + 1],
                    )
                })
                .collect()
        })
        .collect();
    Trial {
        cost: rss.iter().sum(),
        cols,
        qr,
        residues,
        resid,
        n_cols: p,
    }
}

/// Real inner product of real-stacked complex vectors: `Re Σ conj(a) b`.
fn dot(a: &[c64], b: &[c64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| x.re * y.re + x.im * y.im)
        .sum()
}

/// Channels scaled to unit RMS: the data [`refine`] and [`screen_extra_poles`] fit.
fn unit_rms(chans: &[Vec<c64>]) -> Vec<Vec<c64>> {
    chans
        .iter()
        .map(|h| {
            let rms = (h.iter().map(|z| z.norm_sqr()).sum::<f64>() / h.len() as f64).sqrt();
            h.iter().map(|z| z / rms).collect()
        })
        .collect()
}

/// The weighted cost `Σ_o ‖w (h_o/rms_o − Φ c_o)‖²` that [`refine`] minimised (at the
/// refined poles of `fit`, on the same `band` and `chans`), and the same cost with each
/// candidate pole added in turn (residues re-fitted, poles fixed): used to screen
/// candidates for the model-order test.
///
/// One QR serves every candidate. The candidate's two basis columns `N` are projected
/// off the current basis (`Ñ = P⊥N`, `ÑᵀÑ = NᵀN − (QᵀN)ᵀQᵀN`, `QᵀN = R⁻ᵀΦᵀN`); as the
/// residuals `r_o` are already orthogonal to the basis, the cost drops by
/// `Σ_o (Nᵀr_o)ᵀ(ÑᵀÑ)⁻¹(Nᵀr_o)` — O(N·(p + channels)) per candidate instead of a QR.
/// The refinement's own factorisation is reused (it is the basis at `fit.poles`).
pub fn screen_extra_poles(
    fit: &Refined,
    candidates: &[Pole],
    band: &BandData,
    chans: &[Vec<c64>],
) -> (f64, Vec<f64>) {
    let lw = line_weights(&unit_rms(chans));
    let t = &*fit.fit;
    let pc = t.n_cols;
    let with = candidates
        .iter()
        .map(|c| {
            let n = basis_columns(std::slice::from_ref(c), band, Residuals::NONE, &lw);
            // y = QᵀN by forward substitution on Rᵀ.
            let mut y = [vec![0.0; pc], vec![0.0; pc]];
            for (j, yj) in y.iter_mut().enumerate() {
                for i in 0..pc {
                    let mut v = dot(&t.cols[i], &n[j]);
                    for l in 0..i {
                        v -= t.qr.r(l, i) * yj[l];
                    }
                    yj[i] = v / t.qr.r(i, i);
                }
            }
            let g = |a: usize, b: usize| {
                dot(&n[a], &n[b]) - (0..pc).map(|l| y[a][l] * y[b][l]).sum::<f64>()
            };
            let (g00, g01, g11) = (g(0, 0), g(0, 1), g(1, 1));
            let det = g00 * g11 - g01 * g01;
            // A candidate in the span of the basis (det ≈ 0) explains nothing new.
            if !(det > 1e-12 * g00.max(g11).powi(2)) {
                return t.cost;
            }
            let drop: f64 = t
                .resid
                .iter()
                .map(|r| {
                    let (b0, b1) = (dot(&n[0], r), dot(&n[1], r));
                    (g11 * b0 * b0 - 2.0 * g01 * b0 * b1 + g00 * b1 * b1) / det
                })
                .sum();
            (t.cost - drop).max(0.0)
        })
        .collect();
    (t.cost, with)
}

/// Levenberg–Marquardt on the variable-projection functional (Golub & Pereyra; Kaufman's
/// Jacobian `J = −P⊥ (∂Φ/∂θ) c`): minimises `Σ_o ‖w_o (h_o − Φ(λ) c_o)‖²` over the poles,
/// the residues being the LSFD solution for each trial set (`w_o` = 1/RMS of channel o).
/// For noise-free data this converges to the exact poles, which the polynomial
/// (LSCF/LSCE) estimators only approach; with noise it is the least-squares estimate,
/// and `σ²(JᵀJ)⁻¹` its covariance.
///
/// Cost: with `∂Φ/∂Re λ_m · c = a d1 + b d2`, `∂Φ/∂Im λ_m · c = a d2 − b d1`
/// (`d1 = q(u + u')`, `d2 = q·i(u − u')`, `u = (iω−λ)⁻²`, `u' = (iω−λ*)⁻²`, `R = a + ib`),
/// `JᵀJ` and `Jᵀr` only need the Gram matrix `DᵀP⊥D` of the `2M` vectors `d` and `Dᵀr_o`:
/// O(N·M·(M + p + channels)) per iteration instead of forming J.
pub fn refine(poles: &[Pole], band: &BandData, chans: &[Vec<c64>], res: Residuals) -> Refined {
    let n = band.n_lines();
    let no = chans.len();
    let data = unit_rms(chans);
    let lw = line_weights(&data);
    let q: Vec<c64> = band
        .quantity_factor()
        .iter()
        .zip(&lw)
        .map(|(q, w)| q * *w)
        .collect();
    let nm = poles.len();
    let np = 2 * nm;
    let mut cur: Vec<Pole> = poles.to_vec();
    let mut t = trial(&cur, band, &data, &lw, res);
    let cost0 = t.cost;
    let mut mu = 1e-3;
    let mut converged = false;
    let mut iterations = 0;
    let mut jtj = Mat::<f64>::zeros(np, np);
    for it in 0..40 {
        iterations = it + 1;
        // Derivative vectors d1_m, d2_m.
        let mut d: Vec<Vec<c64>> = Vec::with_capacity(np);
        for p in &cur {
            let mut d1 = Vec::with_capacity(n);
            let mut d2 = Vec::with_capacity(n);
            for (k, &w) in band.omega.iter().enumerate() {
                let s = c64::new(0.0, w);
                let a1 = 1.0 / (s - p.0);
                let a2 = 1.0 / (s - p.0.conj());
                let (u, u2) = (a1 * a1, a2 * a2);
                d1.push(q[k] * (u + u2));
                d2.push(q[k] * c64::new(0.0, 1.0) * (u - u2));
            }
            d.push(d1);
            d.push(d2);
        }
        // G_D = DᵀD − (QᵀD)ᵀ(QᵀD), QᵀD = R⁻ᵀ Φ̃ᵀD.
        let pc = t.n_cols;
        let mut y = Mat::<f64>::zeros(pc, np);
        for j in 0..np {
            for i in 0..pc {
                let mut v = dot(&t.cols[i], &d[j]);
                for l in 0..i {
                    v -= t.qr.r(l, i) * y[(l, j)];
                }
                y[(i, j)] = v / t.qr.r(i, i);
            }
        }
        let mut gd = Mat::<f64>::zeros(np, np);
        for i in 0..np {
            for j in 0..=i {
                let mut v = dot(&d[i], &d[j]);
                for l in 0..pc {
                    v -= y[(l, i)] * y[(l, j)];
                }
                gd[(i, j)] = v;
                gd[(j, i)] = v;
            }
        }
        // JᵀJ and Jᵀr over channels; e-vectors: θ=Re λ_m → (a, b) on (d1, d2),
        // θ=Im λ_m → (−b, a).
        let mut g = vec![0.0; np];
        for v in jtj.col_iter_mut() {
            for x in v.iter_mut() {
                *x = 0.0;
            }
        }
        let dr: Vec<Vec<f64>> = (0..np)
            .map(|j| (0..no).map(|o| dot(&d[j], &t.resid[o])).collect())
            .collect();
        for o in 0..no {
            let e = |j: usize| -> (usize, f64, f64) {
                let m = j / 2;
                let r = t.residues[m][o];
                if j % 2 == 0 {
                    (m, r.re, r.im)
                } else {
                    (m, -r.im, r.re)
                }
            };
            for j in 0..np {
                let (mj, x1, x2) = e(j);
                g[j] += x1 * dr[2 * mj][o] + x2 * dr[2 * mj + 1][o];
                for k in 0..=j {
                    let (mk, y1, y2) = e(k);
                    let v = x1 * (y1 * gd[(2 * mj, 2 * mk)] + y2 * gd[(2 * mj, 2 * mk + 1)])
                        + x2 * (y1 * gd[(2 * mj + 1, 2 * mk)] + y2 * gd[(2 * mj + 1, 2 * mk + 1)]);
                    jtj[(j, k)] += v;
                    if k != j {
                        jtj[(k, j)] += v;
                    }
                }
            }
        }
        // Converged when even the undamped Gauss–Newton step predicts a cost drop below
        // the stall tolerance (see below): saves evaluating a step that cannot matter.
        let gn_rhs = Mat::from_fn(np, 1, |i, _| g[i]);
        if let Some(gn) = linalg::solve_square(&jtj, &gn_rhs) {
            let predicted: f64 = (0..np).map(|i| gn[(i, 0)] * g[i]).sum();
            if predicted.is_finite() && predicted >= 0.0 && predicted <= 1e-10 * t.cost {
                converged = true;
                break;
            }
        }
        // LM step with Marquardt scaling; more damping until the cost drops.
        let mut accepted = false;
        for _ in 0..12 {
            let lhs = Mat::from_fn(np, np, |i, j| {
                jtj[(i, j)] + if i == j { mu * jtj[(i, i)] } else { 0.0 }
            });
            let rhs = Mat::from_fn(np, 1, |i, _| g[i]);
            let Some(step) = linalg::solve_square(&lhs, &rhs) else {
                mu *= 10.0;
                continue;
            };
            let cand: Vec<Pole> = cur
                .iter()
                .enumerate()
                .map(|(m, p)| Pole(p.0 + c64::new(step[(2 * m, 0)], step[(2 * m + 1, 0)])))
                .collect();
            if cand.iter().any(|p| !(p.0.re < 0.0 && p.0.im > 0.0)) {
                mu *= 10.0;
                continue;
            }
            let t2 = trial(&cand, band, &data, &lw, res);
            if t2.cost <= t.cost {
                let rel_step = (0..nm)
                    .map(|m| {
                        c64::new(step[(2 * m, 0)], step[(2 * m + 1, 0)]).norm()
                            / cur[m].half_bandwidth().max(1e-300)
                    })
                    .fold(0.0, f64::max);
                // Converged when the step is negligible or the cost stalls: a relative
                // drop of 1e-10 of a cost ≈ ν·s² means the remaining step is about
                // √(1e-10·ν) ≈ 1e-3 of a standard error for ν ~ 10⁴ residuals.
                let small = rel_step < 1e-9 || (t.cost - t2.cost) <= 1e-10 * t.cost;
                cur = cand;
                t = t2;
                mu = (mu / 10.0).max(1e-12);
                accepted = true;
                converged = small;
                break;
            }
            mu *= 10.0;
        }
        if !accepted {
            // No descent left: at the minimum to working precision.
            converged = true;
        }
        if converged {
            break;
        }
    }
    // Covariance σ²(JᵀJ)⁻¹ (JᵀJ of the last linearisation).
    let dof = (2 * n * no).saturating_sub(no * t.n_cols + np).max(1) as f64;
    let s2 = t.cost / dof;
    let inv = linalg::solve_square(&jtj, &Mat::identity(np, np));
    let covariance = (0..nm)
        .map(|m| match &inv {
            Some(ci) => [
                [s2 * ci[(2 * m, 2 * m)], s2 * ci[(2 * m, 2 * m + 1)]],
                [s2 * ci[(2 * m + 1, 2 * m)], s2 * ci[(2 * m + 1, 2 * m + 1)]],
            ],
            None => [[0.0; 2]; 2],
        })
        .collect();
    Refined {
        poles: cur,
        covariance,
        singular: inv.is_none(),
        iterations,
        converged,
        cost: (cost0, t.cost),
        fit: std::sync::Arc::new(t),
    }
}
