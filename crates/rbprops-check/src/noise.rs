//! The noise floor, estimated from the data alone before any model is fitted.
//!
//! Local polynomial method (Pintelon & Schoukens 2012, §7; research note §6.2): around
//! each line k a complex polynomial of degree 4 is fitted by least squares to the
//! 2R+1 = 11 lines k−R..k+R of the same FRF. With circular complex noise of variance
//! σ² = E|ε|², the residual sum of squares obeys SSR/σ² ~ χ²₁₂/2 (11 − 5 = 6 complex
//! degrees of freedom), so σ̂²_k = SSR/6 has σ̂²/σ² ~ χ²₁₂/12.
//!
//! Where the polynomial cannot follow the FRF (near lightly damped peaks, coarse line
//! spacing) σ̂² is inflated, never deflated. So per channel the variance model
//! σ² = a²|H|² + b² is fitted to (|Ĥ_k|², σ̂²_k) by quantile regression in log space at
//! the lower quantile p = 0.15 (pinball loss), matched to the p-quantile of χ²₁₂/12: the
//! inflated lines sit above that quantile and barely move it.

use crate::error::CheckError;
use rbprops_core::c64;
use serde::{Deserialize, Serialize};

const HALF_WIDTH: usize = 5;
const DEGREE: usize = 4;
/// Quantile level of the robust fit.
const LEVEL: f64 = 0.15;

/// The LEVEL-quantile of χ²_{2(w−d−1)}/(2(w−d−1)), the distribution of σ̂²/σ².
fn reference_quantile() -> f64 {
    let k = 2.0 * (2 * HALF_WIDTH + 1 - (DEGREE + 1)) as f64;
    crate::stats::chi2_quantile(LEVEL, k) / k
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

/// Noise standard deviation model per channel: σ² = (a|H|)² + b², σ² = E|ε|².
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct NoiseModel {
    /// Relative part a per recorded channel.
    pub relative: Vec<f64>,
    /// Absolute part b per recorded channel (FRF units).
    pub floor: Vec<f64>,
    /// Where it came from: "data (local polynomial)" or "given".
    pub source: String,
    /// Relative standard error of the σ² scale (0 when given): the spread of the scale
    /// estimated FRF by FRF, divided by √(number of FRFs). χ²/ν inherits it 1:1.
    pub variance_scale_se: f64,
}

/// Result of the estimate: the model and the per-value σ (layout `[exc][ch][line]`).
#[derive(Debug, Clone)]
pub struct NoiseFloor {
    pub model: NoiseModel,
    /// σ per value; 0 marks a value without information (excluded from fits).
    pub sigma: Vec<f64>,
}

/// Local polynomial fit at each line of `res`: (smoothed value, σ̂², h̄) where
/// h̄ = Σ_j (1 − P_jj)|Y_j|² / (w − d − 1), Y = `refr`, is the magnitude the window's
/// residual variance refers to: E[SSR] = Σ_j (1 − P_jj) σ_j² for a hat matrix P, so with
/// σ_j² = a²|H_j|² + b², E[σ̂²] = a² h̄ + b² even where |H| changes across the window.
/// For the data-only estimate `res` and `refr` are both the recording; for the
/// re-estimate they are the residual of a fitted model and its prediction.
fn local_fits(res: &[c64], refr: &[c64]) -> Vec<(c64, f64, f64)> {
    let n = res.len();
    let w = 2 * HALF_WIDTH + 1;
    // Projection onto quadratics on abscissae −R..R (uniform lines), as the hat matrix.
    let xs: Vec<f64> = (0..w).map(|i| i as f64 - HALF_WIDTH as f64).collect();
    let v = nalgebra::DMatrix::from_fn(w, DEGREE + 1, |i, j| {
        (xs[i] / HALF_WIDTH as f64).powi(j as i32)
    });
    let hat = &v
        * (v.transpose() * &v)
            .try_inverse()
            .expect("Vandermonde of 7 distinct points")
        * v.transpose();
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
        let dof = (w - DEGREE - 1) as f64;
        let hbar = (0..w)
            .map(|i| (1.0 - hat[(i, i)]) * refr[start + i].norm_sqr())
            .sum::<f64>()
            / dof;
        out.push((fitted_centre, ssr / dof, hbar));
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

/// Quantile regression of ln s against ln(a²h + b²) over a log grid, refined twice.
fn fit_variance_model(h: &[f64], s: &[f64]) -> (f64, f64) {
    let q = reference_quantile();
    let cost = |a2: f64, b2: f64| -> f64 {
        h.iter()
            .zip(s)
            .map(|(&h, &s)| pinball((s / q).ln() - (a2 * h + b2).ln()))
            .sum()
    };
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
                let c = cost(a2, b2);
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

/// Estimates the noise from the recorded FRFs alone (values `[exc][ch][line]`).
pub fn estimate(
    values: &[c64],
    n_exc: usize,
    n_ch: usize,
    n_lines: usize,
) -> Result<NoiseFloor, CheckError> {
    let fits = fits_of(values, values, n_exc * n_ch, n_lines)?;
    let model = model_of(
        &fits,
        n_exc,
        n_ch,
        format!("data (local quartic over 11 lines, {LEVEL}-quantile fit)"),
    )?;
    let smooth: Vec<c64> = fits.iter().flat_map(|f| f.iter().map(|x| x.0)).collect();
    Ok(NoiseFloor {
        sigma: sigma_of(&model, &smooth, n_exc, n_ch, n_lines),
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
    let residual: Vec<c64> = values.iter().zip(prediction).map(|(y, m)| y - m).collect();
    let fits = fits_of(&residual, prediction, n_exc * n_ch, n_lines)?;
    let mut model = model_of(
        &fits,
        n_exc,
        n_ch,
        format!("residual of the fitted model (local quartic over 11 lines, {LEVEL}-quantile fit)"),
    )?;
    rescale_homoscedastic(&mut model, &residual, prediction, n_exc, n_ch, n_lines)?;
    Ok(NoiseFloor {
        sigma: sigma_of(&model, prediction, n_exc, n_ch, n_lines),
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
/// that of χ²₁₂/12 estimates the channel's factor c, which scales a² and b².
fn rescale_homoscedastic(
    model: &mut NoiseModel,
    residual: &[c64],
    prediction: &[c64],
    n_exc: usize,
    n_ch: usize,
    n_lines: usize,
) -> Result<(), CheckError> {
    let s = sigma_of(model, prediction, n_exc, n_ch, n_lines);
    let u: Vec<c64> = residual
        .iter()
        .zip(&s)
        .map(|(e, s)| if *s > 0.0 { e / s } else { c64::new(0.0, 0.0) })
        .collect();
    let ones = vec![c64::new(1.0, 0.0); u.len()];
    let fits = fits_of(&u, &ones, n_exc * n_ch, n_lines)?;
    let w = 2 * HALF_WIDTH + 1;
    for c in 0..n_ch {
        let mut v = Vec::new();
        for e in 0..n_exc {
            let b = e * n_ch + c;
            for (k, f) in fits[b].iter().enumerate() {
                // Only windows without excluded values (σ = 0, e.g. accelerance at 0 Hz).
                let start = k.saturating_sub(HALF_WIDTH).min(n_lines - w);
                if (start..start + w).all(|j| s[b * n_lines + j] > 0.0) {
                    v.push(f.1);
                }
            }
        }
        if v.len() < 20 {
            continue;
        }
        let f = quantile(&mut v) / reference_quantile();
        model.relative[c] *= f.sqrt();
        model.floor[c] *= f.sqrt();
    }
    Ok(())
}

type LineFit = Vec<(c64, f64, f64)>;

fn fits_of(
    res: &[c64],
    refr: &[c64],
    n_frf: usize,
    n_lines: usize,
) -> Result<Vec<LineFit>, CheckError> {
    if n_lines < 2 * HALF_WIDTH + 1 {
        return Err(CheckError::Noise(format!(
            "{n_lines} lines: at least {} are needed for the local polynomial estimate",
            2 * HALF_WIDTH + 1
        )));
    }
    Ok((0..n_frf)
        .map(|b| {
            let r = b * n_lines..(b + 1) * n_lines;
            local_fits(&res[r.clone()], &refr[r])
        })
        .collect())
}

/// The per-channel variance model σ² = a²h + b² from the line fits, with the relative
/// standard error of its scale.
fn model_of(
    fits: &[LineFit],
    n_exc: usize,
    n_ch: usize,
    source: String,
) -> Result<NoiseModel, CheckError> {
    let mut relative = Vec::with_capacity(n_ch);
    let mut floor = Vec::with_capacity(n_ch);
    let mut frf_scales = Vec::new();
    for c in 0..n_ch {
        let mut hs = Vec::new();
        let mut ss = Vec::new();
        for e in 0..n_exc {
            for &(_, s, hbar) in &fits[e * n_ch + c] {
                if s > 0.0 && s.is_finite() {
                    hs.push(hbar);
                    ss.push(s);
                }
            }
        }
        if ss.len() < 10 {
            return Err(CheckError::Noise(format!(
                "channel {c}: only {} lines carry information (constant or noise-free data?)",
                ss.len()
            )));
        }
        // Subsample evenly to bound the cost of the grid search.
        let step = (ss.len() / 3000).max(1);
        let hsub: Vec<f64> = hs.iter().step_by(step).cloned().collect();
        let ssub: Vec<f64> = ss.iter().step_by(step).cloned().collect();
        let (a2, b2) = fit_variance_model(&hsub, &ssub);
        // Final scale on all lines: the p-quantile of σ̂²/model must be that of χ²/k.
        let mut u: Vec<f64> = hs
            .iter()
            .zip(&ss)
            .map(|(h, s)| s / (a2 * h + b2))
            .filter(|x| x.is_finite())
            .collect();
        let scale = quantile(&mut u) / reference_quantile();
        relative.push((a2 * scale).sqrt());
        floor.push((b2 * scale).sqrt());
        for e in 0..n_exc {
            let mut u: Vec<f64> = fits[e * n_ch + c]
                .iter()
                .filter(|f| f.1 > 0.0 && f.1.is_finite())
                .map(|f| f.1 / ((a2 * f.2 + b2) * scale))
                .filter(|x| x.is_finite())
                .collect();
            if u.len() >= 20 {
                frf_scales.push(quantile(&mut u) / reference_quantile());
            }
        }
    }
    let variance_scale_se = if frf_scales.len() >= 2 {
        let n = frf_scales.len() as f64;
        let mean = frf_scales.iter().sum::<f64>() / n;
        let var = frf_scales.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
        (var / n).sqrt()
    } else {
        0.0
    };
    let model = NoiseModel {
        relative,
        floor,
        source,
        variance_scale_se,
    };
    Ok(model)
}

/// Fraction of the local median magnitude below which a reference magnitude is not
/// trusted for the relative noise term (see [`sigma_of`]).
const NOTCH_FLOOR: f64 = 0.5;

/// σ per value from a noise model and reference magnitudes `[exc][ch][line]`;
/// values with σ below 1e-9 of the median σ get 0 (excluded).
///
/// The relative term uses `max(|H_k|, ½ median |H| over lines k−5..k+5)`: at a zero of
/// the FRF (0 Hz of an AC-coupled channel or of an accelerance, a sharp anti-resonance)
/// `a|H_k|` → 0 would give a line the weight of all the others together, and a model
/// that misses the zero by a hair would be judged by that line alone. Synthetic
/// records whose noise is relative to the true FRF are exact there; real ones are not.
/// Along a smooth FRF |H_k| is its own local median and nothing changes.
pub fn sigma_of(
    model: &NoiseModel,
    reference: &[c64],
    n_exc: usize,
    n_ch: usize,
    n_lines: usize,
) -> Vec<f64> {
    let mut s = vec![0.0; n_exc * n_ch * n_lines];
    let mut window = Vec::with_capacity(2 * HALF_WIDTH + 1);
    for e in 0..n_exc {
        for c in 0..n_ch {
            let (a, b) = (model.relative[c], model.floor[c]);
            let start = (e * n_ch + c) * n_lines;
            let mag: Vec<f64> = reference[start..start + n_lines]
                .iter()
                .map(|x| x.norm())
                .collect();
            for l in 0..n_lines {
                window.clear();
                window.extend_from_slice(
                    &mag[l.saturating_sub(HALF_WIDTH)..(l + HALF_WIDTH + 1).min(n_lines)],
                );
                let h = mag[l].max(NOTCH_FLOOR * median(&mut window));
                s[start + l] = (a * a * h * h + b * b).sqrt();
            }
        }
    }
    let mut pos: Vec<f64> = s.iter().cloned().filter(|x| *x > 0.0).collect();
    let med = median(&mut pos);
    for x in &mut s {
        if !(*x > 1e-9 * med) {
            *x = 0.0;
        }
    }
    s
}
