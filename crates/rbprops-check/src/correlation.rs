//! Noise correlated from line to line: detected, reported and weighed.
//!
//! FRFs estimated from windowed time histories do not have independent noise at
//! neighbouring lines: the DFT of white noise times a window w(t) has the line-to-line
//! covariance of the DFT of w²(t). An exponential window e^{−t/τ} over a record T = 1/Δf
//! gives, for white noise sampled at f_s,
//!
//! ```text
//!   γ_m = E[ε_k ε̄_{k−m}] / E|ε|² = (1 − q)/(1 − q e^{∓2πi m/N}),   q = e^{−2/(τ f_s)}
//! ```
//!
//! |γ₁| = 0.79 for τ = T/4 (c = πτΔf = 0.785 below). Every χ² of the check counts
//! independent lines. With such noise (a) the local polynomial noise estimate reads only
//! the part of the noise a quartic cannot follow, and its lower quantile less still: σ²
//! is read low by the factor L of `noise::correlated_level` (0.26 at c = 0.785;
//! measured on the H1 of five impacts: 0.27), and (b) the χ² of a smooth signature —
//! what every effect's change to the FRFs is over a few lines — has the variance of the
//! noise's spectral density at zero quefrency, κ = Σ_m Re γ_m times the per-line one
//! (4.0 at c = 0.785; measured 3.8), so every threshold passes noise.
//!
//! Prewhitening (generalised least squares) was tried and is not used: the correlation of
//! a windowed record has a jump in its quefrency density where the record wraps, right
//! at the quefrencies of smooth signatures, and the whitening filter amplifies any error
//! in σ's shape across lines there; an order-16 predictor left the smooth signatures'
//! χ² 1.6–1.8 times too variable on measured H1 noise. Instead, when the correlation is
//! that of an exponential window (γ_m = 1/(1 + i c m), fitted to the moments below),
//! every σ is scaled by √(κ/L) with the noise estimated from the data (√κ with σ given):
//! the level is right and the tests are conservative for smooth signatures (calibrated
//! in their limit, and less powerful for sharp ones), and χ²/ν is stated per line (×κ)
//! with a noise band of ν/κ effective lines. The second pass looks for the correlation
//! again in the first pass's residual (with that residual's noise model: on exact data the
//! data's local residual is the FRF's own curvature and reads as correlated) and takes
//! the level from the residual's median |r|²/σ² (circular normal values whatever the
//! correlation), times κ. c comes from the model's window when it has one (named, or
//! declared in the spec): c = πΔf/decay. Correlation of another shape is reported, and
//! the check's claims then are not calibrated.
//!
//! Detection, from the data without a model: the local quartic's residual over a window
//! of 11 lines is r = M ε (M = I − P, P the quartic's hat matrix), so E[r rᴴ] = c·M R M
//! with R the lines' correlation. Averaged over windows (each scaled by the current noise
//! model's mean σ² over its lines; windows whose residual exceeds `TRIM` × the median
//! left out: there the quartic cannot follow the FRF), the lag-1 ratio
//! ĝ = Σ_a Ĝ_{a+1,a} / Σ_a Ĝ_aa equals Σ_a M_{a+1,a} / tr M for independent noise
//! whatever its level. Its excess is the statistic: reported when it is both practically
//! ([`MIN_EXCESS`]) and statistically (5 standard errors on independent noise) large.
use nalgebra::{Complex, DMatrix};
use rayon::prelude::*;
use rbprops_core::c64;

/// The smallest excess reported: windowed noise with |γ₁| = 0.3 gives about 0.2.
pub const MIN_EXCESS: f64 = 0.1;
/// The largest relative misfit of the exponential window's correlation to the residual
/// moments acted on. Measured: 0.02–0.03 on simulated windowed noise, 0.16 on the H1 of
/// five impacts (structure left after trimming).
pub const MAX_MISFIT: f64 = 0.3;
/// Windows whose scaled residual exceeds TRIM × the median are structure, not noise.
const TRIM: f64 = 4.0;
/// Standard error of the lag-1 ratio on independent noise, times √(values in the kept
/// windows): 0.86 measured in `white_noise_is_not_reported` (40 recordings of 27 × 400
/// values), rounded up.
const SE_LAG1: f64 = 1.0;

/// The local polynomial's window (lines), that of `noise::hat_matrix`.
const W: usize = 11;

/// The detection statistic of the module docs.
#[derive(Debug, Clone)]
pub struct LineCorrelation {
    /// ĝ minus its value for independent noise.
    pub excess: c64,
    /// |excess| in standard errors on independent noise.
    pub z: f64,
    /// The windows averaged.
    pub windows: usize,
    /// The exponential window's c fitted to the residual moments, and its relative misfit.
    pub window: (f64, f64),
    /// c from the decay rate of the model's exponential window (c = πΔf/decay), which
    /// replaces the moments' c when the model has one.
    pub known_c: Option<f64>,
}

/// How the check weighs a recording whose noise is correlated like an exponential
/// window's (module docs): σ² × κ/L with the noise estimated from the data.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inflation {
    /// The window's c = πτΔf.
    pub c: f64,
    /// κ = Σ_m Re γ_m = (π/c) coth(π/c): a smooth signature's χ² variance factor.
    pub kappa: f64,
    /// L: the factor by which the local polynomial estimate reads σ².
    pub level: f64,
}

impl Inflation {
    /// The exponential window's inflation for c.
    pub fn exponential(c: f64) -> Self {
        let x = std::f64::consts::PI / c.abs();
        let r = window_toeplitz(c);
        Inflation {
            c,
            kappa: x / x.tanh(),
            level: crate::noise::correlated_level(&r),
        }
    }
}

/// γ_m = 1/(1 + i c m) of an exponential window (module docs).
fn exponential_gamma(c: f64, m: usize) -> c64 {
    c64::new(1.0, 0.0) / c64::new(1.0, c * m as f64)
}

/// The window's correlation between the lines of one window, R_ab = γ_{a−b}.
fn window_toeplitz(c: f64) -> DMatrix<Complex<f64>> {
    DMatrix::from_fn(W, W, |a, b| match a.cmp(&b) {
        std::cmp::Ordering::Equal => Complex::new(1.0, 0.0),
        std::cmp::Ordering::Greater => exponential_gamma(c, a - b),
        std::cmp::Ordering::Less => exponential_gamma(c, b - a).conj(),
    })
}

/// Relative misfit min_λ ‖M R M − λ Ĝ‖ / ‖M R M‖ of the window's correlation to Ĝ.
fn misfit(g: &DMatrix<Complex<f64>>, m: &DMatrix<Complex<f64>>, c: f64) -> f64 {
    let a = m * window_toeplitz(c) * m;
    let lam = g
        .iter()
        .zip(a.iter())
        .map(|(x, y)| (x.conj() * y).re)
        .sum::<f64>()
        / g.iter().map(|x| x.norm_sqr()).sum::<f64>();
    (&a - g * Complex::new(lam, 0.0)).norm() / a.norm()
}

/// The window's c that fits Ĝ best (|c| on a log grid 0.05..50, either sign: the sign
/// follows the transform's convention) and its misfit.
fn fit_window(g: &DMatrix<Complex<f64>>) -> (f64, f64) {
    let m = residual_projector().map(|v| Complex::new(v, 0.0));
    let mut best = (0.0, f64::INFINITY);
    for k in 0..400 {
        let mag = 0.05 * 1000f64.powf((k % 200) as f64 / 199.0);
        let c = if k < 200 { mag } else { -mag };
        let r = misfit(g, &m, c);
        if r < best.1 {
            best = (c, r);
        }
    }
    best
}

impl LineCorrelation {
    /// Whether the excess is both practically and statistically significant.
    pub fn detected(&self) -> bool {
        self.excess.norm() >= MIN_EXCESS && self.z >= 5.0
    }

    /// The inflation, when the correlation is detected and an exponential window's fits.
    pub fn inflation(&self) -> Option<Inflation> {
        (self.detected() && self.window.1 <= MAX_MISFIT)
            .then(|| Inflation::exponential(self.known_c.unwrap_or(self.window.0)))
    }

    /// The same finding with c known from the model's window: the moments give c to
    /// ±15 %, and the level factor L is steep in c (×1.2 for +10 % at c = 0.8); the
    /// fitted decay rate gives it to its standard error.
    pub fn with_window_decay(mut self, decay_per_s: Option<f64>, line_spacing_hz: f64) -> Self {
        self.known_c = decay_per_s
            .filter(|d| *d > 0.0)
            .map(|d| std::f64::consts::PI * line_spacing_hz / d);
        self
    }

    /// The finding in words, for the report's warnings; `line_spacing_hz` turns c into
    /// the window's time constant.
    pub fn describe(&self, line_spacing_hz: f64) -> String {
        let head = format!(
            "the noise is correlated from line to line (lag-1 excess {:.2} of the local polynomial residual, {:.0} SE over {} windows), as a window on the time histories makes it",
            self.excess.norm(),
            self.z,
            self.windows
        );
        match self.inflation() {
            Some(inf) => format!(
                "{head}: an exponential window's correlation fits it (τ = |c|/(πΔf) = {:.3} s{}, misfit {:.2}), so σ² is scaled by κ/L = {:.2}/{:.3} (the local polynomial reads σ² low by L, and a smooth signature's χ² varies κ times more than independent lines'): the tests are conservative for smooth signatures, χ²/ν is stated per line and its band counts ν/κ lines",
                inf.c.abs() / (std::f64::consts::PI * line_spacing_hz),
                if self.known_c.is_some() {
                    ", the model's window decay"
                } else {
                    ", from the moments"
                },
                self.window.1,
                inf.kappa,
                inf.level
            ),
            None => format!(
                "{head}, and no exponential window's correlation fits it (misfit {:.2} > {MAX_MISFIT}): the check's χ² statistics assume independent lines, so on this recording its claims and its noise floor are not calibrated (effects may be claimed from noise)",
                self.window.1
            ),
        }
    }
}

/// The local quartic's residual projector M = I − P over W lines.
fn residual_projector() -> DMatrix<f64> {
    DMatrix::identity(W, W) - crate::noise::hat_matrix()
}

/// Ĝ of the module docs from `series` (`[frf][line]`, `n_lines` per FRF), each window
/// scaled by the mean σ² of its lines (`sigma`, 0: a value left out, and so its windows):
/// the sum of the kept r rᴴ and the number of windows kept.
fn window_moments(
    series: &[c64],
    sigma: &[f64],
    n_frf: usize,
    n_lines: usize,
) -> (DMatrix<Complex<f64>>, usize) {
    let m = residual_projector();
    // Per FRF in parallel, collected in order: the same sums at any thread count.
    let per_frf: Vec<Vec<(f64, DMatrix<Complex<f64>>)>> = (0..n_frf)
        .into_par_iter()
        .map(|b| {
            let (x, s) = (
                &series[b * n_lines..(b + 1) * n_lines],
                &sigma[b * n_lines..(b + 1) * n_lines],
            );
            let mut out = Vec::new();
            for start in 0..(n_lines + 1).saturating_sub(W) {
                let s2 = &s[start..start + W];
                if s2.iter().any(|v| !(*v > 0.0)) {
                    continue;
                }
                let scale = (s2.iter().map(|v| v * v).sum::<f64>() / W as f64).sqrt();
                let u: Vec<c64> = x[start..start + W].iter().map(|v| v / scale).collect();
                let r: Vec<c64> = (0..W)
                    .map(|a| (0..W).map(|j| u[j] * m[(a, j)]).sum())
                    .collect();
                let t: f64 = r.iter().map(|v| v.norm_sqr()).sum();
                if t.is_finite() {
                    out.push((t, DMatrix::from_fn(W, W, |a, c| r[a] * r[c].conj())));
                }
            }
            out
        })
        .collect();
    let mut t: Vec<f64> = per_frf.iter().flatten().map(|w| w.0).collect();
    if t.is_empty() {
        return (DMatrix::zeros(W, W), 0);
    }
    t.sort_by(|a, b| a.total_cmp(b));
    let cut = TRIM * t[t.len() / 2];
    let mut g = DMatrix::zeros(W, W);
    let mut n = 0;
    for (tw, rr) in per_frf.iter().flatten() {
        if *tw <= cut {
            g += rr;
            n += 1;
        }
    }
    (g / Complex::new(n.max(1) as f64, 0.0), n)
}

/// The detection statistic of `series` (`[frf][line]`), with `sigma` the current noise
/// model's σ per value (0: left out; its level need not be right, its shape across lines
/// should be). None with fewer than 110 windows.
pub fn detect(
    series: &[c64],
    sigma: &[f64],
    n_frf: usize,
    n_lines: usize,
) -> Option<LineCorrelation> {
    let (g, windows) = window_moments(series, sigma, n_frf, n_lines);
    if windows < 10 * W {
        return None;
    }
    let m = residual_projector();
    let lag1 = |a: usize| if a + 1 < W { 1.0 } else { 0.0 };
    let (mut num, mut den) = (Complex::new(0.0, 0.0), 0.0);
    let (mut wnum, mut wden) = (0.0, 0.0);
    for a in 0..W {
        if lag1(a) > 0.0 {
            num += g[(a + 1, a)];
            wnum += m[(a + 1, a)];
        }
        den += g[(a, a)].re;
        wden += m[(a, a)];
    }
    let excess = num / den - wnum / wden;
    // Overlapping windows share lines: the information is that of the lines they cover.
    let values = (windows + W - 1).min(series.len()) as f64;
    Some(LineCorrelation {
        excess,
        z: excess.norm() * values.sqrt() / SE_LAG1,
        windows,
        window: fit_window(&g),
        known_c: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A seeded stream of standard normals (LCG uniforms, Box–Muller).
    struct StdRng(u64);
    impl StdRng {
        fn seed_from_u64(s: u64) -> Self {
            StdRng(s.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
        }
        fn uniform(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        }
        fn normal(&mut self) -> f64 {
            let (u1, u2) = (self.uniform(), self.uniform());
            (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        }
    }

    fn cn(rng: &mut StdRng) -> c64 {
        c64::new(rng.normal(), rng.normal()) * std::f64::consts::FRAC_1_SQRT_2
    }

    /// Independent formulation of windowed noise: white noise e^{−t/τ}-windowed in time,
    /// then a direct DFT at `lines` bins (no FFT, no model of the correlation).
    fn windowed_noise(rng: &mut StdRng, n: usize, tau_samples: f64, lines: usize) -> Vec<c64> {
        let x: Vec<f64> = (0..n)
            .map(|t| rng.normal() * (-(t as f64) / tau_samples).exp())
            .collect();
        (0..lines)
            .map(|k| {
                let w = -2.0 * std::f64::consts::PI * k as f64 / n as f64;
                x.iter()
                    .enumerate()
                    .map(|(t, v)| c64::from_polar(*v, w * t as f64))
                    .sum()
            })
            .collect()
    }

    /// `n_frf` FRFs of `lines` lines: a smooth curve plus `noise(b)`.
    fn recording(n_frf: usize, lines: usize, mut noise: impl FnMut(usize) -> Vec<c64>) -> Vec<c64> {
        let mut series = Vec::new();
        for b in 0..n_frf {
            let e = noise(b);
            series.extend((0..lines).map(|k| {
                let x = k as f64 / lines as f64;
                c64::new(50.0 * (3.0 * x + b as f64).sin(), 30.0 * x * x) + e[k]
            }));
        }
        series
    }

    /// Windowed noise (an independent time-domain formulation: white noise times
    /// e^{−t/τ}, DFT) is detected at τ = T/4 (|γ₁| = 0.79) and at τ = T (|γ₁| = 0.30),
    /// on a smooth FRF the quartic follows, and the window's c = πτ/T is recovered (within
    /// 15 %: 2 400 lines, and the moments' structure-free windows only).
    #[test]
    fn windowed_noise_is_detected() {
        for (tau_frac, min_excess) in [(0.25, 0.3), (1.0, MIN_EXCESS)] {
            let mut rng = StdRng::seed_from_u64(3);
            let (n, lines, n_frf) = (1024, 200, 12);
            let series = recording(n_frf, lines, |_| {
                windowed_noise(&mut rng, n, n as f64 * tau_frac, lines)
            });
            let d = detect(&series, &vec![1.0; series.len()], n_frf, lines).unwrap();
            assert!(d.detected(), "τ = {tau_frac} T: {d:?}");
            assert!(d.excess.norm() > min_excess, "τ = {tau_frac} T: {d:?}");
            let c = std::f64::consts::PI * tau_frac;
            assert!(
                (d.window.0.abs() / c - 1.0).abs() < 0.15,
                "τ = {tau_frac} T: c {c} vs {d:?}"
            );
            assert!(d.window.1 < MAX_MISFIT && d.inflation().is_some(), "{d:?}");
        }
    }

    /// `n_frf` FRFs of windowed noise alone (τ = T/4).
    fn windowed_frfs(seed: u64, n_frf: usize, lines: usize) -> Vec<Vec<c64>> {
        let mut rng = StdRng::seed_from_u64(seed);
        let n = 1024;
        (0..n_frf)
            .map(|_| windowed_noise(&mut rng, n, n as f64 / 4.0, lines))
            .collect()
    }

    /// L of the module docs is what the local polynomial's quantile estimate reads on
    /// windowed noise: its σ̂² = SSR/6 over windows, LEVEL-quantile over the reference
    /// quantile of χ²₁₂/12, against the true variance (sampling: 16 000 overlapping
    /// windows, the 0.15-quantile to ≈ 2 %; the law's approximation 0.7 %: within 5 %;
    /// the two-moment gamma law, 7 % low, fails it).
    /// And 1 exactly for independent lines.
    #[test]
    fn the_level_factor_is_what_the_local_polynomial_reads() {
        let ident = DMatrix::identity(W, W).map(|v: f64| Complex::new(v, 0.0));
        assert!((crate::noise::correlated_level(&ident) - 1.0).abs() < 1e-12);
        let frfs = windowed_frfs(21, 80, 210);
        let var =
            frfs.iter().flatten().map(|v| v.norm_sqr()).sum::<f64>() / (frfs.len() * 210) as f64;
        let m = residual_projector();
        let mut s: Vec<f64> = Vec::new();
        for f in &frfs {
            for start in 0..=f.len() - W {
                let ssr: f64 = (0..W)
                    .map(|a| {
                        (0..W)
                            .map(|j| f[start + j] * m[(a, j)])
                            .sum::<c64>()
                            .norm_sqr()
                    })
                    .sum();
                s.push(ssr / 6.0 / var);
            }
        }
        s.sort_by(|a, b| a.total_cmp(b));
        let q = s[(0.15 * (s.len() - 1) as f64).round() as usize];
        let read = q / (rbprops_core::stats::chi2_quantile(0.15, 12.0) / 12.0);
        let l = Inflation::exponential(std::f64::consts::PI / 4.0).level;
        assert!((read / l - 1.0).abs() < 0.05, "read {read} vs L {l}");
        assert!(l < 0.35, "{l}");
    }

    /// κ = (π/c) coth(π/c) is Σ_m Re γ_m, and it is the factor by which the χ² of a
    /// smooth signature (a complex quadratic over the band) varies more than independent
    /// lines': mean ‖Qᴴε‖²/(3 σ²) over 200 FRFs of windowed noise (sampling ≈ 7 %:
    /// within 20 %), where independent lines give 1.
    #[test]
    fn kappa_is_the_smooth_signatures_variance_factor() {
        let c = std::f64::consts::PI / 4.0;
        let inf = Inflation::exponential(c);
        let sum = 1.0
            + 2.0
                * (1..200_000)
                    .map(|m| exponential_gamma(c, m).re)
                    .sum::<f64>();
        assert!(
            (inf.kappa / sum - 1.0).abs() < 1e-4,
            "{} vs {sum}",
            inf.kappa
        );
        let lines = 200;
        let frfs = windowed_frfs(33, 200, lines);
        let var =
            frfs.iter().flatten().map(|v| v.norm_sqr()).sum::<f64>() / (frfs.len() * lines) as f64;
        let x = DMatrix::from_fn(lines, 3, |k, j| {
            Complex::new(
                (2.0 * k as f64 / (lines - 1) as f64 - 1.0).powi(j as i32),
                0.0,
            )
        });
        let q = x.qr().q();
        let mean = frfs
            .iter()
            .map(|f| {
                let e = nalgebra::DVector::from_column_slice(f);
                (q.adjoint() * e).norm_squared() / 3.0 / var
            })
            .sum::<f64>()
            / frfs.len() as f64;
        assert!(
            (mean / inf.kappa - 1.0).abs() < 0.2,
            "{mean} vs κ {}",
            inf.kappa
        );
    }

    /// Independent noise is never reported, and the spread of the statistic there is
    /// the SE_LAG1 the significance test assumes (RMS × √values within [0.5, 1.2]).
    #[test]
    fn white_noise_is_not_reported() {
        let mut rng = StdRng::seed_from_u64(11);
        let (lines, n_frf) = (400, 27);
        let mut ex = Vec::new();
        for _ in 0..40 {
            let series = recording(n_frf, lines, |_| (0..lines).map(|_| cn(&mut rng)).collect());
            let d = detect(&series, &vec![1.0; series.len()], n_frf, lines).unwrap();
            assert!(!d.detected(), "{d:?}");
            ex.push(d.excess);
        }
        let values = (n_frf * lines) as f64;
        let rms = (ex.iter().map(|g| g.norm_sqr()).sum::<f64>() / ex.len() as f64).sqrt();
        let ratio = rms * values.sqrt() / SE_LAG1;
        assert!((0.5..1.2).contains(&ratio), "RMS·√n {ratio}");
    }

    /// Structure the quartic cannot follow (a lightly damped resonance) does not read as
    /// correlated noise: its windows are trimmed.
    #[test]
    fn a_sharp_resonance_is_not_read_as_correlation() {
        let mut rng = StdRng::seed_from_u64(5);
        let (lines, n_frf) = (400, 9);
        let series: Vec<c64> = (0..n_frf * lines)
            .map(|i| {
                let f = (i % lines) as f64 / lines as f64;
                let h = c64::new(1.0, 0.0) / c64::new(0.5 * 0.5 - f * f, 2.0 * 0.002 * 0.5 * f);
                h + 0.05 * cn(&mut rng)
            })
            .collect();
        let d = detect(&series, &vec![0.05; series.len()], n_frf, lines).unwrap();
        assert!(!d.detected(), "{d:?}");
    }
}
