//! The FRF noise model of the bootstrap, fitted to the residual of the modal model.
//!
//! For excitation k, channel i and line l the measured FRF is taken as
//! `H_kil = S_kil + ε_kil` with `S` the synthesised (fitted) FRF and `ε` circular complex
//! Gaussian noise of variance
//!
//! ```text
//!   E|ε_kil|² = σ²_kil = a²_ki |S_kil|² + b²_ki
//! ```
//!
//! (a relative part, as for calibration and leakage errors that scale with the response,
//! and a floor, as for transducer noise). For each (k, i), `(a², b²) ≥ 0` are the maximum
//! likelihood estimates from the residuals `r_l = H_l − S_l`: `|r_l|²` is exponential
//! with mean `κσ²_l`, and Fisher scoring for a variance that is linear in the parameters is
//! iteratively reweighted least squares of `|r_l|²` on `(|S_l|², 1)` with weights `σ⁻⁴_l`.
//! `κ = 1 − p/(2N)` corrects for the `p` real parameters per channel the modal fit spent
//! on `N` complex lines (the residual is shorter than the noise by those dimensions).

use rbprops_core::c64;
use rbprops_core::noise::NoiseModel;

/// Half-width (lines) of the window over which residual power is averaged to find
/// structured misfit.
pub const MISFIT_HALF_WINDOW: usize = 7;
/// A window whose mean standardised residual power `|r|²/σ²` exceeds this is misfit, not
/// noise. For pure noise the mean of 15 unit exponentials has sd 0.26 and exceeds 2.5 with
/// probability ≈ 1e-5.
pub const MISFIT_THRESHOLD: f64 = 2.5;

/// Relative precision floor of the misfit test: residual power below `(ε|S|)² + (ε S_rms)²`
/// (ε = 1e-5 of the synthesised value, and of the channel's RMS for lines near a zero) is
/// not structure. On exact data the noise fit returns σ ≈ 0 and every rounding or model
/// truncation residual (1e-8…1e-6 of |H| after a modal fit) would otherwise read as a
/// "missed mode"; a misfit that small cannot move an estimate beyond 1e-5 either.
pub const MISFIT_PRECISION_FLOOR: f64 = 1e-5;

/// The noise of one channel and the lines where the modal model misses structure.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelFit {
    /// Noise model `σ² = a²|H|² + b²` fitted to the residuals off the misfit lines.
    pub noise: NoiseModel,
    /// Per line: the residual there is structured (a mode the fit missed, …), not noise.
    pub misfit: Vec<bool>,
}

/// Robust version of [`fit_channel_noise`]: structured misfit (e.g. a weakly excited mode
/// the modal fit left out) must not pass for noise, or the bootstrap would spread it over
/// the whole band. Lines where the window mean of `|r|²/σ²` over `2·7 + 1` lines exceeds
/// [`MISFIT_THRESHOLD`] (dilated by the window) are flagged and left out of the noise fit;
/// three rounds.
pub fn fit_channel(
    measured: &[c64],
    synthesised: &[c64],
    parameters_per_channel: f64,
) -> ChannelFit {
    let n = measured.len();
    assert_eq!(n, synthesised.len());
    let mut misfit = vec![false; n];
    let mut noise = fit_lines(
        noise_lines(measured, synthesised, None),
        parameters_per_channel,
    );
    let rms2 = synthesised.iter().map(|z| z.norm_sqr()).sum::<f64>() / n.max(1) as f64;
    let eps2 = MISFIT_PRECISION_FLOOR * MISFIT_PRECISION_FLOOR;
    for _ in 0..3 {
        let u = measured.iter().zip(synthesised).map(|(h, s)| {
            let v = noise.variance(*s) + eps2 * (s.norm_sqr() + rms2);
            let r2 = (h - s).norm_sqr();
            if v > 0.0 {
                r2 / v
            } else if r2 > 0.0 {
                f64::INFINITY
            } else {
                1.0
            }
        });
        let flag = structured_windows(u, n);
        if flag == misfit {
            break;
        }
        misfit = flag;
        noise = fit_lines(
            noise_lines(measured, synthesised, Some(&misfit)),
            parameters_per_channel,
        );
    }
    ChannelFit { noise, misfit }
}

/// The lines of every window of `2·MISFIT_HALF_WINDOW + 1` lines (shorter at the ends)
/// whose mean standardised residual power `u` exceeds [`MISFIT_THRESHOLD`]. The window
/// sums are differences of running sums (one pass, not one sum per window); an infinite
/// `u` (residual power where no noise is expected) makes its windows structured.
fn structured_windows(u: impl Iterator<Item = f64>, n: usize) -> Vec<bool> {
    // Running sums of the finite values and counts of the infinite ones.
    let mut sum = Vec::with_capacity(n + 1);
    let mut infinite = Vec::with_capacity(n + 1);
    let (mut acc, mut inf) = (0.0, 0usize);
    sum.push(acc);
    infinite.push(inf);
    for x in u {
        if x.is_finite() {
            acc += x;
        } else if x > 0.0 {
            inf += 1;
        }
        sum.push(acc);
        infinite.push(inf);
    }
    let h = MISFIT_HALF_WINDOW;
    let mut flag = vec![false; n];
    for l in 0..n {
        let (lo, hi) = (l.saturating_sub(h), (l + h + 1).min(n));
        let mean = (sum[hi] - sum[lo]) / (hi - lo) as f64;
        if infinite[hi] > infinite[lo] || mean > MISFIT_THRESHOLD {
            flag[lo..hi].iter_mut().for_each(|f| *f = true);
        }
    }
    flag
}

/// `(|S|², |r|²)` of every line not `skip`ped (none without a mask), leaving out lines
/// where both the measurement and the synthesis are exactly zero (e.g. 0 Hz of an
/// accelerance): they carry no information.
fn noise_lines(measured: &[c64], synthesised: &[c64], skip: Option<&[bool]>) -> Vec<(f64, f64)> {
    let skipped = |l: usize| skip.is_some_and(|s| s[l]);
    measured
        .iter()
        .zip(synthesised)
        .enumerate()
        .filter(|&(l, (h, s))| !skipped(l) && (h.norm_sqr() > 0.0 || s.norm_sqr() > 0.0))
        .map(|(_, (h, s))| (s.norm_sqr(), (h - s).norm_sqr()))
        .collect()
}

/// Fits `σ² = a²|S|² + b²` to the residual `measured − synthesised` of one channel.
/// `parameters_per_channel` is the `p` of the degrees-of-freedom correction (0 for none).
/// Lines where both the measurement and the synthesis are exactly zero (e.g. 0 Hz of an
/// accelerance) carry no information and are skipped. Returns zeros for a noise-free fit.
pub fn fit_channel_noise(
    measured: &[c64],
    synthesised: &[c64],
    parameters_per_channel: f64,
) -> NoiseModel {
    assert_eq!(measured.len(), synthesised.len());
    fit_lines(
        noise_lines(measured, synthesised, None),
        parameters_per_channel,
    )
}

/// [`fit_channel_noise`] of the lines' `(|S|², |r|²)`.
fn fit_lines(lines: Vec<(f64, f64)>, parameters_per_channel: f64) -> NoiseModel {
    let n = lines.len() as f64;
    if lines.is_empty() {
        return NoiseModel {
            relative: 0.0,
            floor: 0.0,
        };
    }
    let kappa = (1.0 - parameters_per_channel / (2.0 * n)).clamp(0.5, 1.0);
    let mean_r2 = lines.iter().map(|l| l.1).sum::<f64>() / n;
    if !(mean_r2 > 0.0) {
        return NoiseModel {
            relative: 0.0,
            floor: 0.0,
        };
    }
    // Start from equal shares of the mean residual power, then Fisher scoring.
    let mean_s2 = lines.iter().map(|l| l.0).sum::<f64>() / n;
    let mut theta = if mean_s2 > 0.0 {
        [0.5 * mean_r2 / mean_s2, 0.5 * mean_r2]
    } else {
        [0.0, mean_r2]
    };
    // A variance floor so that lines with σ² → 0 cannot take all the weight.
    let tiny = 1e-12 * mean_r2;
    // The boundary MLE does not depend on θ: found once, on the first step that needs it.
    let boundary = std::cell::OnceCell::new();
    for _ in 0..50 {
        let next = scoring_step(&lines, theta, tiny)
            .unwrap_or_else(|| *boundary.get_or_init(|| boundary_mle(&lines, tiny)));
        let change = (next[0] - theta[0]).abs() * mean_s2.max(f64::MIN_POSITIVE)
            + (next[1] - theta[1]).abs();
        theta = next;
        if change <= 1e-10 * mean_r2 {
            break;
        }
    }
    NoiseModel {
        relative: (theta[0] / kappa).max(0.0).sqrt(),
        floor: (theta[1] / kappa).max(0.0).sqrt(),
    }
}

/// One weighted least-squares step of `|r|² ≈ θ₀|S|² + θ₁` (weights `1/σ⁴`), or `None`
/// when its solution leaves `θ ≥ 0` (the MLE is then on the boundary, [`boundary_mle`]).
fn scoring_step(lines: &[(f64, f64)], theta: [f64; 2], tiny: f64) -> Option<[f64; 2]> {
    let (mut a00, mut a01, mut a11, mut b0, mut b1) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &(s2, r2) in lines {
        let v = (theta[0] * s2 + theta[1]).max(tiny);
        let w = 1.0 / (v * v);
        a00 += w * s2 * s2;
        a01 += w * s2;
        a11 += w;
        b0 += w * s2 * r2;
        b1 += w * r2;
    }
    let det = a00 * a11 - a01 * a01;
    if det > 1e-12 * a00 * a11 {
        let t0 = (a11 * b0 - a01 * b1) / det;
        let t1 = (a00 * b1 - a01 * b0) / det;
        if t0 >= 0.0 && t1 >= 0.0 {
            return Some([t0, t1]);
        }
    }
    None
}

/// The non-negativity of both parameters enforced by the one-parameter MLEs on the
/// boundary: the better of "relative only" `θ = (mean |r|²/|S|², 0)` and "floor only"
/// `θ = (0, mean |r|²)` by the negative log-likelihood `Σ |r|²/σ² + ln σ²`. For the floor
/// only (`σ² = b² ≥ tiny`) that is `Σ|r|²/b² + n ln b²`, without a logarithm per line.
fn boundary_mle(lines: &[(f64, f64)], tiny: f64) -> [f64; 2] {
    let n = lines.len() as f64;
    let sum_r2 = lines.iter().map(|l| l.1).sum::<f64>();
    let b2 = sum_r2 / n;
    let relative_only = lines
        .iter()
        .all(|l| l.0 > 0.0)
        .then(|| lines.iter().map(|l| l.1 / l.0).sum::<f64>() / n);
    let Some(a2) = relative_only.filter(|a2| a2.is_finite()) else {
        return [0.0, b2];
    };
    // Σ ln σ² = (lines at the floor)·ln tiny + (the others)·ln a² + their Σ ln |S|².
    let above = |s2: f64| a2 * s2 >= tiny;
    let n_above = lines.iter().filter(|l| above(l.0)).count() as f64;
    let sum_ln_v = (n - n_above) * tiny.ln()
        + n_above * a2.ln()
        + sum_ln(lines.iter().map(|l| l.0).filter(|&s2| above(s2)));
    let nll_relative: f64 = lines
        .iter()
        .map(|&(s2, r2)| r2 / (a2 * s2).max(tiny))
        .sum::<f64>()
        + sum_ln_v;
    let nll_floor = sum_r2 / b2.max(tiny) + n * b2.max(tiny).ln();
    if nll_relative < nll_floor {
        [a2, 0.0]
    } else {
        [0.0, b2]
    }
}

/// `Σ ln x` of positive finite values, as `ln(Π mantissas) + (Σ exponents)·ln 2`: one
/// logarithm instead of one per value (the per-line logarithms of the boundary likelihood
/// were a tenth of the bootstrap's model fit at 102,401 lines, issue 41). The running
/// product is renormalised to [1, 2) at every value, so it neither overflows nor
/// underflows; its rounding error is about `n·2⁻⁵³` relative, `n·10⁻¹⁶` in the sum.
fn sum_ln(values: impl Iterator<Item = f64>) -> f64 {
    let (mut mantissa, mut exponent) = (1.0_f64, 0_i64);
    for x in values {
        let (m, e) = split_exponent(x);
        let (m, e2) = split_exponent(mantissa * m);
        mantissa = m;
        exponent += e + e2;
    }
    mantissa.ln() + exponent as f64 * std::f64::consts::LN_2
}

/// `x = m·2^e` with `m` in [1, 2), for positive finite `x` (subnormals included).
fn split_exponent(x: f64) -> (f64, i64) {
    const MANTISSA: u64 = (1 << 52) - 1;
    let field = (x.to_bits() >> 52) & 0x7ff;
    if field == 0 {
        // Subnormal: scale into the normal range first.
        let (m, e) = split_exponent(x * 2f64.powi(64));
        return (m, e - 64);
    }
    let m = f64::from_bits((x.to_bits() & MANTISSA) | (1023 << 52));
    (m, field as i64 - 1023)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rbprops_core::noise::standard_normal as normal;

    /// A resonance-like magnitude profile over `n` lines with known noise added.
    fn channel(n: usize, a: f64, b: f64, seed: u64) -> (Vec<c64>, Vec<c64>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let s: Vec<c64> = (0..n)
            .map(|l| {
                let w = l as f64 / n as f64 * 10.0;
                c64::new(1.0, 0.0) / c64::new(4.0 - w * w * 0.1, 0.05 * w)
            })
            .collect();
        let h = s
            .iter()
            .map(|z| {
                let sd = ((a * a * z.norm_sqr() + b * b) / 2.0).sqrt();
                z + c64::new(sd * normal(&mut rng), sd * normal(&mut rng))
            })
            .collect();
        (h, s)
    }

    #[test]
    fn recovers_relative_and_floor_levels() {
        // Both parts matter: |S| spans ~0.1..20 and the floor equals 1 % of |S| = 1.
        let (a, b) = (0.01, 0.01);
        let mut rel = Vec::new();
        let mut flo = Vec::new();
        for seed in 0..20 {
            let (h, s) = channel(1601, a, b, seed);
            let nz = fit_channel_noise(&h, &s, 0.0);
            rel.push(nz.relative / a);
            flo.push(nz.floor / b);
        }
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        // Each estimate's relative sd is a few %; the mean of 20 is within ±2 % with a
        // wide margin, and every single estimate within ±15 %.
        assert!((mean(&rel) - 1.0).abs() < 0.02, "relative {:?}", rel);
        assert!((mean(&flo) - 1.0).abs() < 0.03, "floor {:?}", flo);
        assert!(rel.iter().chain(&flo).all(|r| (r - 1.0).abs() < 0.15));
    }

    #[test]
    fn pure_relative_noise_gives_no_floor() {
        let (h, s) = channel(1601, 0.02, 0.0, 7);
        let nz = fit_channel_noise(&h, &s, 0.0);
        assert!((nz.relative / 0.02 - 1.0).abs() < 0.06, "{nz:?}");
        // The floor is at most a small fraction of the smallest relative noise level.
        let min_s = s.iter().map(|z| z.norm()).fold(f64::INFINITY, f64::min);
        assert!(nz.floor < 0.3 * 0.02 * min_s, "{nz:?}");
    }

    #[test]
    fn structured_misfit_is_not_noise() {
        let (a, b) = (0.01, 0.0);
        let (mut h, s) = channel(1601, a, b, 11);
        // A narrow bump the "fit" missed: 30× the local noise amplitude at its peak.
        for (l, z) in h.iter_mut().enumerate() {
            let x = (l as f64 - 500.0) / 3.0;
            *z += s[500] * 0.3 * (-x * x).exp();
        }
        let plain = fit_channel_noise(&h, &s, 0.0);
        let fit = fit_channel(&h, &s, 0.0);
        assert!(plain.floor > 0.1 * a * s[500].norm(), "{plain:?}");
        assert!(
            (fit.noise.relative / a - 1.0).abs() < 0.06,
            "{:?}",
            fit.noise
        );
        assert!(fit.misfit[495..506].iter().all(|f| *f));
        let flagged = fit.misfit.iter().filter(|f| **f).count();
        assert!(flagged < 200, "{flagged} lines flagged");
        // Pure noise: nothing (or next to nothing) is flagged.
        let (h, s) = channel(1601, a, b, 12);
        let fit = fit_channel(&h, &s, 0.0);
        assert!(fit.misfit.iter().filter(|f| **f).count() <= 15);
    }

    /// Exact data with a local structured residual (a smooth bump over ~20 lines, as model
    /// truncation leaves): at 1e-8 of |S| it is below the precision floor and not flagged
    /// (without the floor it would be, σ being ≈ 0 everywhere else); at 1e-3 of |S| (100×
    /// the floor) it is.
    #[test]
    fn exact_data_rounding_is_not_structure_but_a_real_misfit_is() {
        let (_, s) = channel(1601, 0.0, 0.0, 3);
        let bump = |amp: f64| -> Vec<c64> {
            s.iter()
                .enumerate()
                .map(|(l, z)| {
                    let x = (l as f64 - 500.0) / 6.0;
                    z + s[500] * amp * (-x * x).exp()
                })
                .collect()
        };
        let fit = fit_channel(&bump(1e-8), &s, 10.0);
        assert_eq!(fit.misfit.iter().filter(|f| **f).count(), 0);
        let fit = fit_channel(&bump(1e-3), &s, 10.0);
        assert!(
            fit.misfit[495..506].iter().all(|f| *f),
            "{:?}",
            &fit.misfit[490..510]
        );
    }

    #[test]
    fn noise_free_and_dof_correction() {
        let (_, s) = channel(100, 0.0, 0.0, 1);
        let nz = fit_channel_noise(&s, &s, 10.0);
        assert_eq!(nz.relative, 0.0);
        assert_eq!(nz.floor, 0.0);
        // Residual power κσ² with κ = 1 − 20/200: the correction restores σ.
        let (h, s) = channel(100, 0.0, 0.3, 2);
        let raw = fit_channel_noise(&h, &s, 0.0);
        let cor = fit_channel_noise(&h, &s, 20.0);
        assert!((cor.floor / raw.floor - (1.0f64 / 0.9).sqrt()).abs() < 1e-9);
    }

    #[test]
    fn sum_of_logarithms_by_mantissas_matches_the_direct_sum() {
        // Magnitudes from subnormal to 1e300, as |S|² of FRFs in any units can be.
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut values: Vec<f64> = (0..20_000)
            .map(|_| 10f64.powf(-300.0 + 600.0 * rng.random::<f64>()))
            .collect();
        values.extend([5e-324, 2.2e-310, 1.0, 2.0, 0.5, f64::MAX]);
        let direct: f64 = values.iter().map(|x| x.ln()).sum();
        let fast = sum_ln(values.iter().copied());
        // Each value's logarithm is rounded to ~2e-16 of up to 745: the direct sum is
        // itself good to about n·745·2⁻⁵³ ≈ 3e-9 absolute.
        assert!((fast - direct).abs() < 1e-8, "{fast} vs {direct}");
        assert_eq!(sum_ln(std::iter::empty()), 0.0);
        assert!((sum_ln([3.0].into_iter()) - 3f64.ln()).abs() < 1e-15);
    }

    #[test]
    fn structured_windows_by_running_sums_match_window_by_window_means() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let n = 500;
        // Exponential noise, one structured run, one line of residual power where no
        // noise is expected (u = ∞), and a NaN that flags nothing.
        let mut u: Vec<f64> = (0..n)
            .map(|_| -(1.0 - rng.random::<f64>()).ln())
            .collect::<Vec<f64>>();
        u[100..112].iter_mut().for_each(|x| *x *= 9.0);
        u[300] = f64::INFINITY;
        u[420] = f64::NAN;
        let h = MISFIT_HALF_WINDOW;
        let mut expected = vec![false; n];
        for l in 0..n {
            let (lo, hi) = (l.saturating_sub(h), (l + h + 1).min(n));
            let w = &u[lo..hi];
            let infinite = w.iter().any(|x| *x == f64::INFINITY);
            let finite: f64 = w.iter().filter(|x| x.is_finite()).sum();
            if infinite || finite / (hi - lo) as f64 > MISFIT_THRESHOLD {
                expected[lo..hi].iter_mut().for_each(|f| *f = true);
            }
        }
        let flags = structured_windows(u.iter().copied(), n);
        assert_eq!(flags, expected);
        // Every window holding line 300 is structured, and flags its 15 lines.
        assert!(flags[105] && flags[300] && flags[300 - 2 * h] && !flags[300 - 2 * h - 1]);
        assert!(!flags[0] && !flags[420] && !flags[n - 1]);
    }
}
