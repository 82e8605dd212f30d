//! The noise floor, estimated from the data alone before any model is fitted.
//!
//! The noise is the workspace's one noise model ([`rbprops_core::noise`]): circular
//! complex, `σ² = E|ε|² = a²|H|² + b²` per channel, plus the floor that the data's own
//! precision and the model's evaluation set ([`precision_variance`]):
//!
//! ```text
//!   σ²_i = a²_c h_i² + b²_c + q(Y_i) + (ρ_c h_i)²
//! ```
//!
//! with `q(Y)` the quantisation variance of the stored value ([`DataPrecision`]: single
//! precision, decimal digits or double precision, detected from the values) and `ρ_c`
//! ([`COMPUTATION_FLOOR`]) the relative precision to which two double-precision
//! computations of the same FRF agree. So a single-precision recording with no added
//! noise has `a = b = 0` and is weighed by its quantisation, and an exact
//! double-precision recording by the computation floor.
//!
//! Local polynomial method (Pintelon & Schoukens 2012, §7): around each line k a complex
//! polynomial of degree 4 is fitted by least squares to the 2R+1 = 11 lines k−R..k+R of
//! the same FRF. With circular complex noise of variance σ² = E|ε|², the residual sum of
//! squares obeys SSR/σ² ~ χ²₁₂/2 (11 − 5 = 6 complex degrees of freedom), so
//! σ̂²_k = SSR/6 has σ̂²/σ² ~ χ²₁₂/12.
//!
//! Where the polynomial cannot follow the FRF (near lightly damped peaks, coarse line
//! spacing) σ̂² is inflated, never deflated. So per channel the variance model
//! σ² = a²|H|² + b² + q̄ (q̄ the window's known quantisation variance) is fitted to
//! (|Ĥ_k|², σ̂²_k) by quantile regression in log space at the lower quantile p = 0.15
//! (pinball loss), matched to the p-quantile of χ²₁₂/12: the inflated lines sit above
//! that quantile and barely move it.

use crate::error::CheckError;
use rayon::prelude::*;
use rbprops_core::noise::NoiseModel;
use rbprops_core::{c64, DataPrecision};
use serde::{Deserialize, Serialize};

/// Relative precision `ρ_c` to which two double-precision computations of the same FRF
/// agree — ours and the one that made an exact recording: 1e-10 of |H|.
///
/// Our prediction goes through an eigenproblem or a solve of the suspension's 6×6
/// matrices, whose condition (10²–10³ for soft suspensions) multiplies the 2.2e-16 of
/// each operation: ~1e-13. A recording made by another formulation typically linearises
/// a potential energy by finite differences, whose truncation and rounding (ε/h with
/// h ≈ 1e-4–1e-5: 1e-12–1e-11 of the stiffness) a resonance amplifies by its quality
/// factor 1/(2ζ) ≈ 10–50: 1e-11–1e-10 near the peaks. Measured: the reference
/// generator's exact Test Case II recordings differ from rbprops-sim's model by 2e-12
/// (RMS over the values, the inertia refitted). Below 1e-10 no tester can act on a
/// difference between FRFs (the best calibrations are good to 1e-4), so nothing is lost
/// by weighing exact data at this floor, and rounding is not read as physics.
pub const COMPUTATION_FLOOR: f64 = 1e-10;

/// The precision floor of value `y` whose reference magnitude is `h`: its quantisation
/// variance plus the computation floor, `q(y) + (ρ_c h)²` (module docs).
pub fn precision_variance(precision: &DataPrecision, y: c64, h: f64) -> f64 {
    let r = COMPUTATION_FLOOR * h;
    precision.variance(y) + r * r
}

const HALF_WIDTH: usize = 5;
const DEGREE: usize = 4;
/// Quantile level of the robust fit.
const LEVEL: f64 = 0.15;

/// The local fit in words, for the report's method text.
pub(crate) fn local_fit_text() -> String {
    let degree = match DEGREE {
        2 => "quadratic",
        3 => "cubic",
        4 => "quartic",
        _ => "polynomial",
    };
    format!(
        "local {degree} over {} lines, {LEVEL}-quantile fit",
        2 * HALF_WIDTH + 1
    )
}

/// The LEVEL-quantile of χ²_{2(w−d−1)}/(2(w−d−1)), the distribution of σ̂²/σ².
fn reference_quantile() -> f64 {
    let k = 2.0 * (2 * HALF_WIDTH + 1 - (DEGREE + 1)) as f64;
    rbprops_core::stats::chi2_quantile(LEVEL, k) / k
}

fn pinball(u: f64) -> f64 {
    if u >= 0.0 {
        LEVEL * u
    } else {
        (LEVEL - 1.0) * u
    }
}

/// The LEVEL-quantile of a sample.
fn quantile(v: &mut [f64]) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    let i = ((v.len() as f64 - 1.0) * LEVEL).round() as usize;
    v[i]
}

/// The noise of a recording: one [`NoiseModel`] per channel, σ² = a²|H|² + b² with
/// σ² = E|ε|², and the precision the values were stored with (module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct RecordingNoise {
    /// Relative part a per recorded channel.
    pub relative: Vec<f64>,
    /// Absolute part b per recorded channel (FRF units).
    pub floor: Vec<f64>,
    /// Where it came from: "data (local polynomial)" or "given".
    pub source: String,
    /// Relative standard error of the σ² scale (0 when given): the spread of the scale
    /// estimated FRF by FRF, divided by √(number of FRFs). χ²/ν inherits it 1:1.
    pub variance_scale_se: f64,
    /// The storage precision detected from the recorded values; its quantisation
    /// variance is added to every σ² (set by the check, whatever the noise's source).
    #[serde(default = "double_precision")]
    pub precision: DataPrecision,
}

fn double_precision() -> DataPrecision {
    DataPrecision::DOUBLE
}

impl RecordingNoise {
    /// A noise model given as side information (e.g. from repeated measurements):
    /// `relative` and `floor` per channel.
    pub fn given(relative: Vec<f64>, floor: Vec<f64>) -> Self {
        RecordingNoise {
            relative,
            floor,
            source: "given".into(),
            variance_scale_se: 0.0,
            precision: DataPrecision::DOUBLE,
        }
    }

    /// The noise model of channel `c`.
    pub fn channel(&self, c: usize) -> NoiseModel {
        NoiseModel::new(self.relative[c], self.floor[c])
    }
}

/// Each value's noise variance given by the FRF estimator (`frf-est`, or coherence and a
/// declared number of averages): the check weighs every value by it instead of estimating
/// the noise from the FRFs, and treats the estimator's window as known.
#[derive(Debug, Clone, PartialEq)]
pub struct GivenLineVariance {
    /// σ² = E|ε|² per value (layout `[exc][ch][line]`, FRF units²), already calibrated
    /// for χ² (`E|ε|²/σ² = 1` with σ² itself estimated); NaN or 0: left out.
    pub sigma2: Vec<f64>,
    /// τ (s) of the exponential window the FRFs were estimated with, whose correlation
    /// between neighbouring lines' noise ([`crate::correlation`]) the check then weighs;
    /// `None`: lines independent (a rectangular response window).
    pub window_time_constant_s: Option<f64>,
    /// Relative standard error of the σ² scale as a whole (χ²/ν inherits it 1:1).
    pub variance_scale_se: f64,
    /// Where it came from, for the report's method text.
    pub source: String,
}

impl GivenLineVariance {
    /// The per-channel summary the report shows: the median of σ/|Y| over each channel's
    /// values as the relative part, no floor.
    pub fn summary(&self, y: &[c64], n_ch: usize, n_lines: usize) -> RecordingNoise {
        let mut per: Vec<Vec<f64>> = vec![Vec::new(); n_ch];
        for (i, (&s2, v)) in self.sigma2.iter().zip(y).enumerate() {
            if s2 > 0.0 && v.norm() > 0.0 {
                per[(i / n_lines) % n_ch].push(s2.sqrt() / v.norm());
            }
        }
        let relative = per
            .iter_mut()
            .map(|v| if v.is_empty() { 0.0 } else { median(v) })
            .collect();
        RecordingNoise {
            relative,
            floor: vec![0.0; n_ch],
            source: self.source.clone(),
            variance_scale_se: self.variance_scale_se,
            precision: DataPrecision::DOUBLE,
        }
    }
}

/// Result of the estimate: the model and the per-value σ (layout `[exc][ch][line]`).
#[derive(Debug, Clone)]
pub struct NoiseFloor {
    /// The fitted noise model of the recording.
    pub model: RecordingNoise,
    /// σ per value; 0 marks a value without information (excluded from fits).
    pub sigma: Vec<f64>,
}

/// The local polynomial fit at one line.
#[derive(Debug, Clone, Copy)]
struct LineFit {
    /// The polynomial's value at the line.
    smooth: c64,
    /// σ̂² = SSR/(w − d − 1).
    s: f64,
    /// h̄ = Σ_j (1 − P_jj)|Y_j|² / (w − d − 1), Y = the reference.
    hbar: f64,
    /// q̄ = Σ_j (1 − P_jj) q_j / (w − d − 1): the window's known precision variance.
    qbar: f64,
}

/// The local polynomial's hat matrix P over its window of 2R+1 lines: projection onto
/// quartics on the abscissae −R..R (uniform lines).
pub(crate) fn hat_matrix() -> nalgebra::DMatrix<f64> {
    let w = 2 * HALF_WIDTH + 1;
    let v = nalgebra::DMatrix::from_fn(w, DEGREE + 1, |i, j| {
        ((i as f64 - HALF_WIDTH as f64) / HALF_WIDTH as f64).powi(j as i32)
    });
    &v * (v.transpose() * &v)
        .try_inverse()
        .expect("Vandermonde of 11 distinct points")
        * v.transpose()
}

/// The factor by which the estimate reads σ² when the noise has the correlation `r`
/// between the lines of a window (R_ab = E[ε_a ε̄_b]/σ², Hermitian): σ̂² = SSR/(w−d−1)
/// with SSR = Σ_j λ_j |z_j|² (λ the eigenvalues of M R M, M = I − P, z independent unit
/// circular normals: |z|² exponential), approximated by the shifted gamma law of the
/// same first three cumulants Σλ, Σλ², 2Σλ³ (Pearson type III; on an exponential
/// window's correlation at c = π/4 its 0.15-quantile is within 0.7 % of the exact law's,
/// the two-moment gamma's 7 % low), whose LEVEL-quantile over the reference quantile
/// of χ²₁₂/12 is the factor. 1 for independent lines (R = I: six unit λ, the law is
/// then χ²₁₂/2 exactly).
pub(crate) fn correlated_level(r: &nalgebra::DMatrix<num_complex::Complex<f64>>) -> f64 {
    let m = nalgebra::DMatrix::identity(r.nrows(), r.ncols()) - hat_matrix();
    let m = m.map(|v| num_complex::Complex::new(v, 0.0));
    let a = &m * r * &m;
    let a2 = &a * &a;
    let trace = |x: &nalgebra::DMatrix<num_complex::Complex<f64>>| -> f64 {
        (0..x.nrows()).map(|i| x[(i, i)].re).sum()
    };
    let (k1, k2, k3) = (trace(&a), trace(&a2), 2.0 * trace(&(&a2 * &a)));
    let skew = k3 / k2.powf(1.5);
    let (shape, scale) = (4.0 / (skew * skew), k2.sqrt() * skew / 2.0);
    let shift = k1 - shape * scale;
    let ssr_q = (shift + scale * rbprops_core::stats::chi2_quantile(LEVEL, 2.0 * shape) / 2.0)
        .max(f64::MIN_POSITIVE);
    let dof = (2 * HALF_WIDTH - DEGREE) as f64;
    ssr_q / dof / reference_quantile()
}

/// Local polynomial fit at each line of `res`. h̄ is the magnitude the window's residual
/// variance refers to: E[SSR] = Σ_j (1 − P_jj) σ_j² for a hat matrix P, so with
/// σ_j² = a²|H_j|² + b² + q_j, E[σ̂²] = a² h̄ + b² + q̄ even where |H| changes across the
/// window. For the data-only estimate `res` and `refr` are both the recording; for the
/// re-estimate they are the residual of a fitted model and its prediction. `q` is the
/// known precision variance per line.
fn local_fits(res: &[c64], refr: &[c64], q: &[f64]) -> Vec<LineFit> {
    let n = res.len();
    let w = 2 * HALF_WIDTH + 1;
    let hat = hat_matrix();
    let dof = (w - DEGREE - 1) as f64;
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        let start = k.saturating_sub(HALF_WIDTH).min(n - w);
        let seg = &res[start..start + w];
        let centre = k - start;
        let mut ssr = 0.0;
        let mut fitted_centre = c64::new(0.0, 0.0);
        for i in 0..w {
            let mut fit = c64::new(0.0, 0.0);
            for j in 0..w {
                fit += seg[j] * hat[(i, j)];
            }
            if i == centre {
                fitted_centre = fit;
            }
            ssr += (seg[i] - fit).norm_sqr();
        }
        let (mut hbar, mut qbar) = (0.0, 0.0);
        for i in 0..w {
            hbar += (1.0 - hat[(i, i)]) * refr[start + i].norm_sqr();
            qbar += (1.0 - hat[(i, i)]) * q[start + i];
        }
        out.push(LineFit {
            smooth: fitted_centre,
            s: ssr / dof,
            hbar: hbar / dof,
            qbar: qbar / dof,
        });
    }
    out
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The pinball cost `Σ ρ(ln s_i/q_r − ln(a²h_i + b² + q_i))` of a grid point (`ls` the
/// first logarithms), summed in order and stopped once it reaches `bound` (the best cost
/// so far). Why that is exact: the terms are non-negative and a rounded sum never falls
/// when a non-negative term is added, so a stopped sum is `≥ bound` exactly when the full
/// one is, and the grid's minimum (strictly below the best) is the same to the bit while
/// most grid points far from it stop early.
fn quantile_cost(h: &[f64], ls: &[f64], q: &[f64], a2: f64, b2: f64, bound: f64) -> f64 {
    let mut c = -0.0;
    for ((&h, &ls), &q) in h.iter().zip(ls).zip(q) {
        c += pinball(ls - (a2 * h + b2 + q).ln());
        if c >= bound {
            break;
        }
    }
    c
}

/// Quantile regression of ln s against ln(a²h + b² + q) over a log grid, refined twice
/// (`q` the known precision variance of each line, not fitted).
fn fit_variance_model(h: &[f64], s: &[f64], q: &[f64]) -> (f64, f64) {
    let qr = reference_quantile();
    // ln(s/q_r) does not depend on the grid point: taken once per value, not once per
    // value and point (the same numbers, so the same cost to the bit).
    let ls: Vec<f64> = s.iter().map(|&s| (s / qr).ln()).collect();
    let cost = |a2: f64, b2: f64, bound: f64| quantile_cost(h, &ls, q, a2, b2, bound);
    let hmax = h.iter().cloned().fold(0.0, f64::max);
    let smax = s.iter().cloned().fold(0.0, f64::max);
    let smin = s
        .iter()
        .cloned()
        .filter(|&x| x > 0.0)
        .fold(f64::INFINITY, f64::min);
    // Ranges: a² from 1e-14 to (s/h) maximum; b² from the smallest to the largest σ̂².
    let mut ratios: Vec<f64> = h
        .iter()
        .zip(s)
        .filter(|(h, _)| **h > 0.0)
        .map(|(h, s)| s / h)
        .collect();
    let a2_mid = if ratios.is_empty() {
        0.0
    } else {
        median(&mut ratios)
    };
    let (mut la_lo, mut la_hi) = (
        (a2_mid.max(1e-300) * 1e-6).ln(),
        (a2_mid.max(1e-300) * 1e2).ln(),
    );
    let (mut lb_lo, mut lb_hi) = ((smin * 1e-3).ln(), (smax * 10.0).ln());
    let mut best = (f64::INFINITY, 0.0, 0.0);
    for round in 0..3 {
        let n = 40;
        for i in 0..=n {
            let a2 = if hmax > 0.0 && a2_mid > 0.0 {
                (la_lo + (la_hi - la_lo) * i as f64 / n as f64).exp()
            } else {
                0.0
            };
            for j in 0..=n + 1 {
                // j = n + 1: no absolute floor (only on the first round).
                let b2 = if j == n + 1 {
                    if round > 0 || a2 == 0.0 {
                        continue;
                    }
                    0.0
                } else {
                    (lb_lo + (lb_hi - lb_lo) * j as f64 / n as f64).exp()
                };
                let c = cost(a2, b2, best.0);
                if c < best.0 {
                    best = (c, a2, b2);
                }
            }
        }
        let (da, db) = ((la_hi - la_lo) / 40.0 * 2.0, (lb_hi - lb_lo) / 40.0 * 2.0);
        if best.1 > 0.0 {
            la_lo = best.1.ln() - da;
            la_hi = best.1.ln() + da;
        }
        if best.2 > 0.0 {
            lb_lo = best.2.ln() - db;
            lb_hi = best.2.ln() + db;
        } else {
            lb_lo = (smin * 1e-3).ln();
            lb_hi = lb_lo + 1e-9;
        }
    }
    (best.1, best.2)
}

/// The precision variance `q(Y_i) + (ρ_c |R_i|)²` of every value (`reference` R gives the
/// magnitude the computation floor refers to).
fn precision_of(precision: &DataPrecision, recorded: &[c64], reference: &[c64]) -> Vec<f64> {
    recorded
        .iter()
        .zip(reference)
        .map(|(y, r)| precision_variance(precision, *y, r.norm()))
        .collect()
}

/// The local-polynomial fits of `series` (the recording or a residual of it; |H| and
/// the computation floor from `reference`) with the precision floor of the recorded
/// `values`, and the noise model their quantile fit gives, described as from `source`.
fn local_fit(
    values: &[c64],
    series: &[c64],
    reference: &[c64],
    (n_exc, n_ch, n_lines): (usize, usize, usize),
    source: &str,
) -> Result<(Vec<Vec<LineFit>>, RecordingNoise), CheckError> {
    let precision = DataPrecision::detect(values);
    let q = precision_of(&precision, values, reference);
    let fits = fits_of(series, reference, &q, n_exc * n_ch, n_lines)?;
    let source = format!("{source} ({})", local_fit_text());
    let model = model_of(&fits, n_exc, n_ch, source, precision)?;
    Ok((fits, model))
}

/// Estimates the noise from the recorded FRFs alone (values `[exc][ch][line]`).
pub fn estimate(
    values: &[c64],
    n_exc: usize,
    n_ch: usize,
    n_lines: usize,
) -> Result<NoiseFloor, CheckError> {
    let _t = crate::prof::span(crate::prof::NOISE);
    let dims = (n_exc, n_ch, n_lines);
    let (fits, model) = local_fit(values, values, values, dims, "data")?;
    let smooth: Vec<c64> = fits
        .iter()
        .flat_map(|f| f.iter().map(|x| x.smooth))
        .collect();
    Ok(NoiseFloor {
        sigma: sigma_of(&model, &smooth, values, n_exc, n_ch, n_lines),
        model,
    })
}

/// Re-estimates the noise from the residual `values − prediction` of a fitted model
/// (all `[exc][ch][line]`), by the same local polynomial and quantile fit, with the
/// magnitudes h̄ taken from the prediction.
///
/// Why: the data-only estimate reads every deterministic structure the local quartic
/// cannot follow as noise, e.g. the leakage ripple of a truncated record, which
/// oscillates with a period of a few lines (`e^{−iωT}` at lines kΔf: period 1/(TΔf)
/// lines) and is indistinguishable from noise line by line. Once a model reproduces
/// that structure, its residual e = Y − Ŷ = ε − J δθ holds only the noise: the fitted
/// parameters remove a fraction p/(2N) of its variance (E|e_i|² = σ_i²(1 − h_ii) with
/// leverages h_ii summing to p), negligible for p ≪ N, and what the model still misses
/// is smooth and stays in the local polynomial, inflating σ̂² rather than deflating it.
/// So σ̂²_k = SSR_k/6 of the residual again has σ̂²/σ² ~ χ²₁₂/12 (module docs).
pub fn estimate_from_residual(
    values: &[c64],
    prediction: &[c64],
    n_exc: usize,
    n_ch: usize,
    n_lines: usize,
) -> Result<NoiseFloor, CheckError> {
    let _t = crate::prof::span(crate::prof::NOISE);
    let residual: Vec<c64> = values.iter().zip(prediction).map(|(y, m)| y - m).collect();
    let dims = (n_exc, n_ch, n_lines);
    let source = "residual of the fitted model";
    let (_, mut model) = local_fit(values, &residual, prediction, dims, source)?;
    rescale_homoscedastic(
        &mut model, values, &residual, prediction, n_exc, n_ch, n_lines,
    )?;
    Ok(NoiseFloor {
        sigma: sigma_of(&model, prediction, values, n_exc, n_ch, n_lines),
        model,
    })
}

/// Second step of the residual estimate: where |H| changes across a window (near the
/// peaks, at coarse line spacing) SSR is a sum of χ² terms of unequal weights, with
/// fewer effective degrees of freedom than 12 and a lower LEVEL-quantile relative to
/// its mean, so matching that quantile to χ²₁₂/12 underestimates σ² (by about 5 % at
/// 400 lines on Test Case II). The residual normalised by the first estimate,
/// u_j = e_j/σ̂_j, is homoscedastic under the model (E|u_j|² = c), its local-polynomial
/// σ̂²_k/c ~ χ²₁₂/12 exactly, and the LEVEL-quantile of σ̂²_k over a channel divided by
/// that of χ²₁₂/12 estimates the channel's factor c, which scales a² and b² (the
/// precision floor is known and stays; where it dominates, c is left at 1).
fn rescale_homoscedastic(
    model: &mut RecordingNoise,
    values: &[c64],
    residual: &[c64],
    prediction: &[c64],
    n_exc: usize,
    n_ch: usize,
    n_lines: usize,
) -> Result<(), CheckError> {
    let s = sigma_of(model, prediction, values, n_exc, n_ch, n_lines);
    let u: Vec<c64> = residual
        .iter()
        .zip(&s)
        .map(|(e, s)| if *s > 0.0 { e / s } else { c64::new(0.0, 0.0) })
        .collect();
    let ones = vec![c64::new(1.0, 0.0); u.len()];
    let zeros = vec![0.0; u.len()];
    let fits = fits_of(&u, &ones, &zeros, n_exc * n_ch, n_lines)?;
    let w = 2 * HALF_WIDTH + 1;
    for c in 0..n_ch {
        let mut v = Vec::new();
        // Share of the fitted noise (a, b) in σ² over the channel's values: the factor
        // applies to that share only.
        let (mut fitted, mut total) = (0.0, 0.0);
        let nm = model.channel(c);
        for e in 0..n_exc {
            let b = e * n_ch + c;
            for (k, f) in fits[b].iter().enumerate() {
                // Only windows without excluded values (σ = 0, e.g. accelerance at 0 Hz).
                let start = k.saturating_sub(HALF_WIDTH).min(n_lines - w);
                if (start..start + w).all(|j| s[b * n_lines + j] > 0.0) {
                    v.push(f.s);
                }
                let i = b * n_lines + k;
                if s[i] > 0.0 {
                    fitted += nm.variance(prediction[i]) / (s[i] * s[i]);
                    total += 1.0;
                }
            }
        }
        if v.len() < 20 || !(fitted > 0.5 * total) {
            continue;
        }
        let f = quantile(&mut v) / reference_quantile();
        model.relative[c] *= f.sqrt();
        model.floor[c] *= f.sqrt();
    }
    Ok(())
}

fn fits_of(
    res: &[c64],
    refr: &[c64],
    q: &[f64],
    n_frf: usize,
    n_lines: usize,
) -> Result<Vec<Vec<LineFit>>, CheckError> {
    if n_lines < 2 * HALF_WIDTH + 1 {
        return Err(CheckError::Noise(format!(
            "{n_lines} lines: at least {} are needed for the local polynomial estimate",
            2 * HALF_WIDTH + 1
        )));
    }
    // FRFs are independent (collected in order: the same values at any thread count).
    Ok((0..n_frf)
        .into_par_iter()
        .map(|b| {
            let r = b * n_lines..(b + 1) * n_lines;
            local_fits(&res[r.clone()], &refr[r.clone()], &q[r])
        })
        .collect())
}

/// The scale c ≥ 0 of the fitted part at which the LEVEL-quantile of
/// σ̂²/(c·(a²h̄ + b²) + q̄) is that of χ²₁₂/12 (bisection; the quantile falls as c grows).
/// 0 when the precision floor alone already explains the lower quantile.
fn scale_of(fits: &[&LineFit], a2: f64, b2: f64) -> f64 {
    let target = reference_quantile();
    let q_at = |c: f64| -> f64 {
        let mut u: Vec<f64> = fits
            .iter()
            .map(|f| f.s / (c * (a2 * f.hbar + b2) + f.qbar))
            .filter(|x| x.is_finite())
            .collect();
        if u.is_empty() {
            return 0.0;
        }
        quantile(&mut u)
    };
    if fits.iter().all(|f| f.qbar == 0.0) {
        // No precision floor: the quantile is exactly proportional to 1/c.
        return q_at(1.0) / target;
    }
    if q_at(0.0) <= target {
        return 0.0;
    }
    let mut hi = 1.0;
    while q_at(hi) > target && hi < 1e300 {
        hi *= 4.0;
    }
    let mut lo = 0.0;
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if q_at(mid) > target {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-10 * hi {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// The per-channel variance model σ² = a²h + b² (+ the known precision floor) from the
/// line fits, with the relative standard error of its scale.
fn model_of(
    fits: &[Vec<LineFit>],
    n_exc: usize,
    n_ch: usize,
    source: String,
    precision: DataPrecision,
) -> Result<RecordingNoise, CheckError> {
    // Channels are independent (the grid search is most of the noise model's time): in
    // parallel, collected and reduced in channel order, so the same values at any thread
    // count and the first failing channel's error.
    let per_channel: Vec<Result<ChannelModel, CheckError>> = (0..n_ch)
        .into_par_iter()
        .map(|c| channel_model(fits, n_exc, n_ch, c))
        .collect();
    let mut relative = Vec::with_capacity(n_ch);
    let mut floor = Vec::with_capacity(n_ch);
    let mut frf_scales = Vec::new();
    for r in per_channel {
        let (rel, fl, scales) = r?;
        relative.push(rel);
        floor.push(fl);
        frf_scales.extend(scales);
    }
    let variance_scale_se = if frf_scales.len() >= 2 {
        let n = frf_scales.len() as f64;
        let mean = frf_scales.iter().sum::<f64>() / n;
        let var = frf_scales.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
        (var / n).sqrt()
    } else {
        0.0
    };
    Ok(RecordingNoise {
        relative,
        floor,
        source,
        variance_scale_se,
        precision,
    })
}

/// A channel's relative and absolute noise and the scale of each of its FRFs.
type ChannelModel = (f64, f64, Vec<f64>);

/// One channel's variance model of [`model_of`]: its relative and absolute noise and the
/// scale of each of its FRFs (`[excitation]`, those with enough lines).
fn channel_model(
    fits: &[Vec<LineFit>],
    n_exc: usize,
    n_ch: usize,
    c: usize,
) -> Result<ChannelModel, CheckError> {
    let mut frf_scales = Vec::new();
    let lines: Vec<&LineFit> = (0..n_exc)
        .flat_map(|e| fits[e * n_ch + c].iter())
        .filter(|f| f.s > 0.0 && f.s.is_finite())
        .collect();
    if lines.len() < 10 {
        return Err(CheckError::Noise(format!(
            "channel {c}: only {} lines carry information (constant or noise-free data?)",
            lines.len()
        )));
    }
    // Subsample evenly to bound the cost of the grid search.
    let step = (lines.len() / 3000).max(1);
    let sub: Vec<&LineFit> = lines.iter().step_by(step).copied().collect();
    let hsub: Vec<f64> = sub.iter().map(|f| f.hbar).collect();
    let ssub: Vec<f64> = sub.iter().map(|f| f.s).collect();
    let qsub: Vec<f64> = sub.iter().map(|f| f.qbar).collect();
    let (a2, b2) = fit_variance_model(&hsub, &ssub, &qsub);
    // Final scale on all lines: the p-quantile of σ̂²/model must be that of χ²/k.
    let scale = scale_of(&lines, a2, b2);
    for e in 0..n_exc {
        let mut u: Vec<f64> = fits[e * n_ch + c]
            .iter()
            .filter(|f| f.s > 0.0 && f.s.is_finite())
            .map(|f| f.s / ((a2 * f.hbar + b2) * scale + f.qbar))
            .filter(|x| x.is_finite())
            .collect();
        if u.len() >= 20 {
            frf_scales.push(quantile(&mut u) / reference_quantile());
        }
    }
    Ok(((a2 * scale).sqrt(), (b2 * scale).sqrt(), frf_scales))
}

/// Fraction of the local median magnitude below which a reference magnitude is not
/// trusted for the relative noise term (see [`sigma_of`]).
const NOTCH_FLOOR: f64 = 0.5;

/// The magnitude each value's noise refers to, `h_k = max(|R_k|, ½ median |R| over lines
/// k−5..k+5)` of the reference R (`[frf][line]`, `n_lines` per FRF).
///
/// At a zero of the FRF (0 Hz of an AC-coupled channel or of an accelerance, a sharp
/// anti-resonance) `a|H_k|` → 0 would give a line the weight of all the others
/// together, and a model that misses the zero by a hair would be judged by that line
/// alone. Synthetic records whose noise is relative to the true FRF are exact there;
/// real ones are not. Along a smooth FRF |H_k| is its own local median and nothing
/// changes.
fn noise_magnitudes(reference: &[c64], n_lines: usize) -> Vec<f64> {
    let mut h = Vec::with_capacity(reference.len());
    let mut window = Vec::with_capacity(2 * HALF_WIDTH + 1);
    for frf in reference.chunks(n_lines) {
        let mag: Vec<f64> = frf.iter().map(|x| x.norm()).collect();
        for l in 0..mag.len() {
            window.clear();
            window.extend_from_slice(
                &mag[l.saturating_sub(HALF_WIDTH)..(l + HALF_WIDTH + 1).min(mag.len())],
            );
            h.push(mag[l].max(NOTCH_FLOOR * median(&mut window)));
        }
    }
    h
}

/// σ per value from a noise model, reference magnitudes and the recorded values (all
/// `[exc][ch][line]`): σ²_i = a²h_i² + b² + q(Y_i) + (ρ_c h_i)² (module docs, h_i from
/// `noise_magnitudes`); values with σ below 1e-9 of the median σ get 0 (excluded).
pub fn sigma_of(
    model: &RecordingNoise,
    reference: &[c64],
    recorded: &[c64],
    n_exc: usize,
    n_ch: usize,
    n_lines: usize,
) -> Vec<f64> {
    let h = noise_magnitudes(&reference[..n_exc * n_ch * n_lines], n_lines);
    let mut s: Vec<f64> = h
        .iter()
        .zip(recorded)
        .enumerate()
        .map(|(i, (&h, y))| {
            let fitted = model.channel((i / n_lines) % n_ch).std_dev(h);
            (fitted * fitted + precision_variance(&model.precision, *y, h)).sqrt()
        })
        .collect();
    let mut pos: Vec<f64> = s.iter().cloned().filter(|x| *x > 0.0).collect();
    let med = median(&mut pos);
    for x in &mut s {
        if !(*x > 1e-9 * med) {
            *x = 0.0;
        }
    }
    s
}

/// The precision floor per value alone, `√(q(Y_i) + (ρ_c h_i)²)` (h_i as in
/// [`sigma_of`]): what σ would be if the recording carried no noise but its storage
/// rounding and the computation its floor — the yardstick of practical
/// significance in the acceptance step.
pub fn precision_sigma(
    precision: &DataPrecision,
    reference: &[c64],
    recorded: &[c64],
    n_lines: usize,
) -> Vec<f64> {
    noise_magnitudes(reference, n_lines)
        .iter()
        .zip(recorded)
        .map(|(&h, y)| precision_variance(precision, *y, h).sqrt())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::quantile_cost;

    /// A deterministic stream in [0, 1) (xorshift64*).
    fn uniform(state: &mut u64) -> f64 {
        *state ^= *state >> 12;
        *state ^= *state << 25;
        *state ^= *state >> 27;
        (state.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// The stopped sum decides `c < bound` exactly as the full sum does, and without a
    /// bound it is the full sum in order, bit for bit: the grid search's minimum does not
    /// depend on the early stop.
    #[test]
    fn a_stopped_cost_decides_as_the_full_sum() {
        let mut st = 11u64;
        let n = 500;
        let h: Vec<f64> = (0..n)
            .map(|_| 10f64.powf(4.0 * uniform(&mut st) - 2.0))
            .collect();
        let q: Vec<f64> = (0..n)
            .map(|i| if i % 3 == 0 { 1e-6 } else { 0.0 })
            .collect();
        let ls: Vec<f64> = (0..n).map(|_| 3.0 * uniform(&mut st) - 4.0).collect();
        for _ in 0..200 {
            let (a2, b2) = (10f64.powf(-3.0 * uniform(&mut st)), 1e-3 * uniform(&mut st));
            let full: f64 = h
                .iter()
                .zip(&ls)
                .zip(&q)
                .map(|((&h, &ls), &q)| super::pinball(ls - (a2 * h + b2 + q).ln()))
                .sum();
            let unbounded = quantile_cost(&h, &ls, &q, a2, b2, f64::INFINITY);
            assert_eq!(unbounded.to_bits(), full.to_bits());
            for bound in [0.5 * full, full, full * (1.0 + 1e-15), 2.0 * full] {
                let stopped = quantile_cost(&h, &ls, &q, a2, b2, bound);
                assert_eq!(stopped < bound, full < bound, "bound {bound} full {full}");
            }
        }
    }
}
