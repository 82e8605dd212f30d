//! Line weights from the measured coherence (`modal-fit --weight coherence`) or from the
//! estimator's line variances (`modal-fit --weight variance`, the default when the input
//! carries the `frf_variance` topic: `frf-est` output, or an export's coherence with
//! `--averages N`).
//!
//! The default fits weight each line by `1/|H|` (relative errors: the maximum-likelihood
//! weight for noise proportional to |H|). A measured ordinary coherence `γ²` says how
//! much noise each line really carries: for an H1 estimate from `n_d` averages
//!
//! ```text
//!   σ²/|H|² ≈ (1 − γ²)/(n_d γ²)          (rbprops_core::CoherenceNoise)
//! ```
//!
//! so the weight `1/σ` is `|H|⁻¹ · √(γ²/(1 − γ²)) · √n_d`. `n_d` is the same on every
//! line of a record and drops out of a weighted fit; the coherence factor
//!
//! ```text
//!   q_k = 1/√( mean_c (1 − γ²_ck)/γ²_ck ),    1 − γ² floored (CoherenceNoise::floor)
//! ```
//!
//! multiplies the default weights of line `k`. With the estimator's variances σ²_ck (H1
//! over the hits, `frf-est`) the relative variance is known directly, `r_ck = σ²_ck/|H_ck|²`
//! ([`CoherenceWeighting::from_variance`]), and `q_k = 1/√(mean_c r_ck)`: the same
//! weights, where `(1 − γ²)/(n_d γ²)` was an estimate of `r`. Least squares weighted by
//! `1/σ²` (the inverse noise variance, the maximum-likelihood weight for independent
//! Gaussian errors); per channel through `1/|H_ck|` (LSCF), per line through `q_k`.
//!
//! One factor per line, shared by the channels (the mean of the channels' relative
//! variances): the residue fit's basis is
//! shared by every channel (one factorisation for all), and the pole estimate uses the
//! same factor so that the poles and the residues minimise the same weighted error.
//! A line where any channel has `γ² ≤ 0` has no linear relation to the force there and
//! gets weight 0. The factors are scaled to mean square 1 over the axis, so the weighted
//! data keep about unit mean square per line as with the default weights.

use rbprops_core::CoherenceNoise;

/// Each line's relative variance per excitation and channel on the FRF set's axis, from
/// the measured coherence or from the estimator's line variances, and the per-line
/// factors it gives (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct CoherenceWeighting {
    /// The relative variance up to a constant, `r = (1 − γ²)/γ²` or `σ²/|H|²`, floored,
    /// `[excitation][channel][line]`; `None` where the recording has none.
    ratio: Vec<Vec<Option<Vec<f64>>>>,
    noise: CoherenceNoise,
}

/// How far outside `[0, 1]` a stored coherence may lie (rounding of a value computed at
/// 1 or 0, in single precision a few 1e-7) before it is refused as not a coherence.
const RANGE_SLACK: f64 = 1e-4;

impl CoherenceWeighting {
    /// Checks `coherence` (`[excitation][channel]`, each `n_lines` long where present):
    /// every value finite and in `[0, 1]` (to `RANGE_SLACK`), and no excitation whose
    /// factor is 0 on every line. Errors name the excitation, channel and line.
    pub fn new(
        coherence: Vec<Vec<Option<Vec<f64>>>>,
        n_channels: usize,
        n_lines: usize,
        floor: f64,
    ) -> Result<Self, String> {
        if !(floor > 0.0 && floor < 1.0) {
            return Err(format!("coherence floor {floor} must lie in (0, 1)"));
        }
        for (e, row) in coherence.iter().enumerate() {
            if row.len() != n_channels {
                return Err(format!(
                    "excitation {e}: coherence for {} channels, the FRFs have {n_channels}",
                    row.len()
                ));
            }
            for (c, g) in row.iter().enumerate() {
                let Some(g) = g else { continue };
                if g.len() != n_lines {
                    return Err(format!(
                        "excitation {e}, channel {c}: {} coherence lines, the FRF axis has {n_lines}",
                        g.len()
                    ));
                }
                if let Some(k) = g
                    .iter()
                    .position(|v| !(v.is_finite() && *v >= -RANGE_SLACK && *v <= 1.0 + RANGE_SLACK))
                {
                    return Err(format!(
                        "excitation {e}, channel {c}, line {k}: coherence {} is not a value in [0, 1]",
                        g[k]
                    ));
                }
            }
        }
        let noise = CoherenceNoise::new(floor);
        let ratio = coherence
            .into_iter()
            .map(|row| {
                row.into_iter()
                    .map(|g| g.map(|g| g.iter().map(|&g| noise.variance_ratio(g)).collect()))
                    .collect()
            })
            .collect();
        CoherenceWeighting { ratio, noise }.checked()
    }

    /// Weights from the estimator's own line variances (the `frf_variance` topic):
    /// `r = σ²/|H|²` per excitation, channel and line, floored at `floor` like `1 − γ²`
    /// (exact data, σ² = 0, give uniform factors: the default fit). `sigma2` is
    /// `[excitation][channel]` on the FRF axis and `frf(e, c)` that FRF (borrowed: the
    /// set is not copied); a channel whose σ² is NaN on every
    /// line is unknown (`None`); a NaN, or σ² > 0 where |H| = 0, drops the line (r = ∞).
    /// Errors name the excitation, channel and line of a negative or infinite variance.
    pub fn from_variance<'f>(
        sigma2: Vec<Vec<Option<Vec<f64>>>>,
        frf: impl Fn(usize, usize) -> &'f [rbprops_core::c64],
        floor: f64,
    ) -> Result<Self, String> {
        if !(floor > 0.0 && floor < 1.0) {
            return Err(format!("variance floor {floor} must lie in (0, 1)"));
        }
        let mut ratio = Vec::with_capacity(sigma2.len());
        for (e, row) in sigma2.into_iter().enumerate() {
            let mut out = Vec::with_capacity(row.len());
            for (c, v) in row.into_iter().enumerate() {
                let Some(v) = v.filter(|v| v.iter().any(|x| !x.is_nan())) else {
                    out.push(None);
                    continue;
                };
                let h = frf(e, c);
                if h.len() != v.len() {
                    return Err(format!(
                        "excitation {e}, channel {c}: {} variance lines, the FRF axis has {}",
                        v.len(),
                        h.len()
                    ));
                }
                let mut r = Vec::with_capacity(v.len());
                for (k, (&s2, z)) in v.iter().zip(h).enumerate() {
                    if s2 < 0.0 || s2.is_infinite() {
                        return Err(format!(
                            "excitation {e}, channel {c}, line {k}: variance {s2} is not a value ≥ 0"
                        ));
                    }
                    r.push(match s2 {
                        _ if s2.is_nan() => f64::INFINITY,
                        0.0 => floor,
                        _ => (s2 / z.norm_sqr()).max(floor),
                    });
                }
                out.push(Some(r));
            }
            ratio.push(out);
        }
        CoherenceWeighting {
            ratio,
            noise: CoherenceNoise::new(floor),
        }
        .checked()
    }

    /// Refuses an excitation whose factor is 0 on every line.
    fn checked(self) -> Result<Self, String> {
        let w = self;
        for e in 0..w.ratio.len() {
            if let Some(q) = w.line_factors(&[e]) {
                if q.iter().all(|&x| x == 0.0) {
                    return Err(format!(
                        "excitation {e}: the weight is 0 on every line (coherence 0, or no finite variance, everywhere): no line to fit"
                    ));
                }
            }
        }
        Ok(w)
    }

    /// The floor of `1 − γ²`.
    pub fn floor(&self) -> f64 {
        self.noise.floor
    }

    /// Number of excitations with no coherence on any channel (fitted unweighted).
    pub fn unweighted_excitations(&self) -> usize {
        self.ratio
            .iter()
            .filter(|row| row.iter().all(|g| g.is_none()))
            .count()
    }

    /// The factors `q_k` (module docs) over the whole axis from every channel with
    /// coherence of the excitations `excitations` (one excitation, or a set-up's), scaled
    /// to mean square 1; `None` when none of them has coherence (default weights).
    pub fn line_factors(&self, excitations: &[usize]) -> Option<Vec<f64>> {
        let rows: Vec<&Vec<f64>> = excitations
            .iter()
            .filter_map(|&e| self.ratio.get(e))
            .flat_map(|row| row.iter().flatten())
            .collect();
        let n = rows.first()?.len();
        let mut q: Vec<f64> = (0..n)
            .map(|k| {
                let mean = rows.iter().map(|r| r[k]).sum::<f64>() / rows.len() as f64;
                // 1/√∞ = 0: a line with γ² ≤ 0 (or no variance) on some channel drops out.
                1.0 / mean.sqrt()
            })
            .collect();
        let ms = q.iter().map(|x| x * x).sum::<f64>() / n as f64;
        if ms > 0.0 {
            let s = 1.0 / ms.sqrt();
            q.iter_mut().for_each(|x| *x *= s);
        }
        Some(q)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Exact factors on a hand case: two channels, γ² = (0.5, 0.8) on line 0 gives mean
    /// variance ratio (1 + 0.25)/2 = 0.625; γ² = 1 on both (floored at 1e-6) gives 1e-6;
    /// a channel at γ² = 0 gives 0.
    #[test]
    fn factors_by_hand() {
        let coh = vec![vec![
            Some(vec![0.5, 1.0, 0.0, 0.8]),
            Some(vec![0.8, 1.0, 0.9, 0.8]),
        ]];
        let w = CoherenceWeighting::new(coh, 2, 4, 1e-6).unwrap();
        let q = w.line_factors(&[0]).unwrap();
        let raw = [1.0 / 0.625f64.sqrt(), 1e3, 0.0, 2.0];
        let ms = raw.iter().map(|x| x * x).sum::<f64>() / 4.0;
        for (a, b) in q.iter().zip(raw) {
            assert!((a - b / ms.sqrt()).abs() < 1e-12 * b.max(1.0), "{q:?}");
        }
        assert!((q.iter().map(|x| x * x).sum::<f64>() / 4.0 - 1.0).abs() < 1e-14);
        assert_eq!(w.unweighted_excitations(), 0);
    }

    #[test]
    fn bad_coherence_is_refused_by_position() {
        let e = CoherenceWeighting::new(vec![vec![Some(vec![0.5, 1.2]), None]], 2, 2, 1e-6)
            .unwrap_err();
        assert_eq!(
            e,
            "excitation 0, channel 0, line 1: coherence 1.2 is not a value in [0, 1]"
        );
        let e = CoherenceWeighting::new(vec![vec![None, Some(vec![f64::NAN, 1.0])]], 2, 2, 1e-6)
            .unwrap_err();
        assert!(e.starts_with("excitation 0, channel 1, line 0"), "{e}");
        let e = CoherenceWeighting::new(vec![vec![Some(vec![0.0, 0.0])]], 1, 2, 1e-6).unwrap_err();
        assert!(e.contains("0 on every line"), "{e}");
        let e = CoherenceWeighting::new(vec![vec![Some(vec![0.5])]], 1, 2, 1e-6).unwrap_err();
        assert!(e.contains("1 coherence lines"), "{e}");
        // No coherence at all for an excitation: default weights, counted.
        let w = CoherenceWeighting::new(vec![vec![None], vec![Some(vec![0.9, 0.9])]], 1, 2, 1e-6)
            .unwrap();
        assert_eq!(w.line_factors(&[0]), None);
        assert_eq!(w.unweighted_excitations(), 1);
        // A set-up combines its excitations' channels.
        assert_eq!(w.line_factors(&[0, 1]).unwrap(), vec![1.0, 1.0]);
    }
}
