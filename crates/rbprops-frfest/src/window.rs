//! Force and response windows, the automatic exponential time constant, and the
//! line-to-line correlation a window gives the noise.
//!
//! # Force window
//!
//! [`ForceWindow`] is 1 on `[a, b)` with `a = trigger − pre_s f_s` and
//! `b = pulse_end + post_s f_s` (both clamped to the record; `pulse_end` from
//! [`crate::HitReport`]), 0 elsewhere, and optionally a cosine (half-Hann) taper of
//! `m = taper_s f_s` samples *outside* the flat part, so the pulse is never touched:
//! `w[a − j] = w[b − 1 + j] = ½(1 + cos(π j/m))` for `j = 1..m`. The pretrigger `pre_s`
//! must cover the pulse's rise before the trigger sample.
//!
//! # Exponential window
//!
//! [`ResponseWindow::Exponential`] is `w[n] = e^{−(n − n₀)/(τ f_s)}` over the **whole**
//! record, `n₀` the trigger sample: 1 at the trigger, slightly above 1 on the pretrigger.
//! That choice makes the window exact: with `q = e^{−1/(τ f_s)}`, `w[n] = q^{n−n₀}` and
//! for a response `y = h ∗ f` (linear convolution, system at rest at the record's start)
//! `w·y = (q^m h[m]) ∗ (w·f)`, so applying the window to **force and response** (the
//! default of [`HitWindows`]) turns the estimated FRF into that of the damped impulse
//! response `e^{−t/τ} h(t)`: `H_w(iω) = H(iω + 1/τ)` — every pole moves by `−1/τ`, the
//! residues unchanged (docs/conventions.md §9). A window that were 1 before the trigger
//! would break the identity by the (small) pretrigger part.
//!
//! # Automatic τ
//!
//! [`auto_tau`]: the response's peak envelope `P = max |x[n]|` for `n ≥ n₀`, its end
//! envelope `E = max |x[n]|` over the last 5 % of the record (at least 16 samples), and
//! `T = (N − 1 − n₀)/f_s`. The window is chosen so the windowed response's end envelope is
//! 1 % of its peak, `E e^{−T/τ} = 0.01 P`:
//!
//! ```text
//!   τ = T / ln(E/(0.01 P))          when E > 0.01 P, else no window (None).
//! ```
//!
//! (The peak is near the trigger, where the window is ≈ 1.)
//!
//! # Line correlation
//!
//! White noise `e[n]` (variance s²) times a window `w` has the DFT `ε_k = Σ w e e^{−2πikn/N}`
//! with `E[ε_k ε̄_{k−m}] = s² Σ_n w²[n] e^{−2πimn/N}`, so
//!
//! ```text
//!   γ_m = E[ε_k ε̄_{k−m}] / E|ε_k|² = Σ_n w²[n] e^{−2πimn/N} / Σ_n w²[n]
//! ```
//!
//! exactly, for every k (the normalised DFT of w²) — [`line_correlation`]. For the
//! exponential window from `n₀ = 0`, `w² = qⁿ` with `q = e^{−2/(τ f_s)}` and the geometric
//! sum gives `γ_m = (1 − q)/(1 − q e^{−2πim/N})` ([`exponential_line_correlation`]), the form
//! the model check uses (rbprops-check `correlation.rs`). For H1 from impacts the FRF noise
//! `Σ X̄... /S_ff` is the response noise's DFT over a smooth `F`, so its line correlation is
//! that of the response window.

use crate::c64;

/// The force window (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceWindow {
    /// Time kept before the trigger (s).
    pub pre_s: f64,
    /// Time kept after the pulse's end (s).
    pub post_s: f64,
    /// Cosine taper length outside the flat part (s); 0 for a plain rectangle.
    pub taper_s: f64,
}

impl ForceWindow {
    /// The window's values over a record of `out.len()` samples.
    pub fn fill(&self, fs: f64, trigger: usize, pulse_end: usize, out: &mut [f64]) {
        let (a, b) = self.flat_part(fs, trigger, pulse_end, out.len());
        let (a, b) = (a as isize, b as isize);
        let m = (self.taper_s * fs).round().max(0.0) as isize;
        for (i, w) in out.iter_mut().enumerate() {
            let i = i as isize;
            *w = if i >= a && i < b {
                1.0
            } else if m > 0 && i < a && a - i <= m {
                0.5 * (1.0 + (std::f64::consts::PI * (a - i) as f64 / m as f64).cos())
            } else if m > 0 && i >= b && i - b < m {
                0.5 * (1.0 + (std::f64::consts::PI * (i - b + 1) as f64 / m as f64).cos())
            } else {
                0.0
            };
        }
    }

    /// The samples `[a, b)` where the window is 1 in a record of `n` samples (module docs):
    /// `a = trigger − pre_s f_s`, `b = pulse_end + post_s f_s`, both clamped to the record.
    pub fn flat_part(&self, fs: f64, trigger: usize, pulse_end: usize, n: usize) -> (usize, usize) {
        let n = n as isize;
        let a = (trigger as isize - (self.pre_s * fs).round() as isize).clamp(0, n);
        let b = (pulse_end as isize + (self.post_s * fs).round() as isize).clamp(a, n);
        (a as usize, b as usize)
    }

    /// The window's values over `n` samples.
    pub fn values(&self, n: usize, fs: f64, trigger: usize, pulse_end: usize) -> Vec<f64> {
        let mut w = vec![0.0; n];
        self.fill(fs, trigger, pulse_end, &mut w);
        w
    }
}

/// The response window (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ResponseWindow {
    /// Rectangular over the record.
    None,
    /// `e^{−(n − n₀)/(τ f_s)}` from the trigger `n₀`, over the whole record.
    Exponential {
        /// Time constant τ (s).
        tau_s: f64,
    },
}

impl ResponseWindow {
    /// The window's values over a record of `out.len()` samples, trigger at `trigger`.
    pub fn fill(&self, fs: f64, trigger: usize, out: &mut [f64]) {
        match *self {
            ResponseWindow::None => out.fill(1.0),
            ResponseWindow::Exponential { tau_s } => {
                let r = 1.0 / (tau_s * fs);
                for (i, w) in out.iter_mut().enumerate() {
                    *w = (-(i as f64 - trigger as f64) * r).exp();
                }
            }
        }
    }

    /// The window's values over `n` samples.
    pub fn values(&self, n: usize, fs: f64, trigger: usize) -> Vec<f64> {
        let mut w = vec![0.0; n];
        self.fill(fs, trigger, &mut w);
        w
    }

    /// The decay rate `1/τ` (1/s) the window adds to every pole, 0 for none.
    pub fn decay_per_s(&self) -> f64 {
        match *self {
            ResponseWindow::None => 0.0,
            ResponseWindow::Exponential { tau_s } => 1.0 / tau_s,
        }
    }
}

/// The sample values of one hit's windows: `force = force window × exponential` (when
/// the exponential applies to the force, the default) and `response = exponential`.
/// Reused from hit to hit without allocating ([`HitWindows::set`]).
#[derive(Debug, Clone, PartialEq)]
pub struct HitWindows {
    /// The force channel's window.
    pub force: Vec<f64>,
    /// The response channels' window.
    pub response: Vec<f64>,
}

impl HitWindows {
    /// Windows over `n` samples, all ones.
    pub fn new(n: usize) -> Self {
        HitWindows {
            force: vec![1.0; n],
            response: vec![1.0; n],
        }
    }

    /// Sets the windows of a hit: `force_window` (None: rectangular over the record) times,
    /// if `exponential_on_force`, the response window.
    pub fn set(
        &mut self,
        fs: f64,
        trigger: usize,
        pulse_end: usize,
        force_window: Option<&ForceWindow>,
        response_window: &ResponseWindow,
        exponential_on_force: bool,
    ) {
        response_window.fill(fs, trigger, &mut self.response);
        match force_window {
            Some(fw) => fw.fill(fs, trigger, pulse_end, &mut self.force),
            None => self.force.fill(1.0),
        }
        if exponential_on_force {
            for (f, r) in self.force.iter_mut().zip(&self.response) {
                *f *= r;
            }
        }
    }
}

/// τ of the automatic exponential window (module docs), or None when the response has
/// decayed to 1 % of its peak by the record's end already (or is empty or zero).
pub fn auto_tau(response: &[f64], fs: f64, trigger: usize) -> Option<f64> {
    let n = response.len();
    if trigger + 2 >= n {
        return None;
    }
    let peak = response[trigger..]
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    let tail = (n / 20).max(16).min(n - trigger);
    let end = response[n - tail..]
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    let t = (n - 1 - trigger) as f64 / fs;
    (peak > 0.0 && end > 0.01 * peak).then(|| t / (end / (0.01 * peak)).ln())
}

/// `γ_m` for `m = 0..=max_lag` of a window's values (module docs): the normalised DFT of
/// `w²`, computed directly (`O(N · max_lag)`), the phase reduced mod N exactly.
pub fn line_correlation(window: &[f64], max_lag: usize) -> Vec<c64> {
    let n = window.len();
    let total: f64 = window.iter().map(|w| w * w).sum();
    (0..=max_lag)
        .map(|m| {
            let mut s = c64::new(0.0, 0.0);
            for (i, w) in window.iter().enumerate() {
                let phase = ((m as u128 * i as u128) % n as u128) as f64;
                let a = -std::f64::consts::TAU * phase / n as f64;
                s += c64::from_polar(w * w, a);
            }
            s / total
        })
        .collect()
}

/// Most bins of [`ForceNoiseBins`]: a window longer than this many steps is binned more
/// coarsely (its error is then nearly independent between lines anyway).
pub const MAX_FORCE_NOISE_BINS: usize = 1024;

/// The force noise's energy through each accepted hit's force window, `σ_n² w²[n]`,
/// binned at times from the hit's pulse centroid: the line correlation of the error it
/// puts into every FRF of the excitation alike ([`rbprops_core::CommonRelativeError`]).
/// Bins of `step_s`, centred at `(b + ½) step_s`.
#[derive(Debug, Clone)]
pub struct ForceNoiseBins {
    step_s: f64,
    bins: std::collections::BTreeMap<i64, f64>,
}

impl ForceNoiseBins {
    /// One bin per sample, or coarser so that a window of `support_s` takes at most
    /// [`MAX_FORCE_NOISE_BINS`] (the consumer coarsens further for its band).
    pub fn new(fs: f64, support_s: f64) -> Self {
        let step = (1.0 / fs).max(support_s / MAX_FORCE_NOISE_BINS as f64);
        ForceNoiseBins {
            step_s: step,
            bins: Default::default(),
        }
    }

    /// Adds one hit: its force window `w` (times the exponential when it is on the force),
    /// the force noise's variance per sample and the pulse centroid (a fractional sample,
    /// [`pulse_centroid`]).
    pub fn add_hit(&mut self, w: &[f64], noise_var: f64, centroid: f64, fs: f64) {
        for (n, &x) in w.iter().enumerate() {
            if x != 0.0 {
                let t = (n as f64 - centroid) / fs;
                *self
                    .bins
                    .entry((t / self.step_s).floor() as i64)
                    .or_default() += noise_var * x * x;
            }
        }
    }

    /// The bins' times (s from the centroid) and weights summing to 1; None when no noise
    /// went in.
    pub fn finish(&self) -> Option<(Vec<f64>, Vec<f64>)> {
        let total: f64 = self.bins.values().sum();
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        Some(
            self.bins
                .iter()
                .map(|(&b, &v)| ((b as f64 + 0.5) * self.step_s, v / total))
                .unzip(),
        )
    }
}

/// The centroid of a hit's windowed force, `Σ n f[n] w[n] / Σ f[n] w[n]` (a fractional
/// sample): the pulse's group delay at low frequency. None when the sum is zero.
pub fn pulse_centroid(force: &[f64], w: &[f64]) -> Option<f64> {
    let (mut num, mut den) = (0.0, 0.0);
    for (n, (&f, &x)) in force.iter().zip(w).enumerate() {
        num += n as f64 * f * x;
        den += f * x;
    }
    (den != 0.0 && (num / den).is_finite()).then_some(num / den)
}

/// The exponential window's closed form `γ_m = (1 − q)/(1 − q e^{−2πim/N})`,
/// `q = e^{−2/(τ f_s)}` (module docs), for a record of `n` samples.
pub fn exponential_line_correlation(tau_s: f64, fs: f64, n: usize, m: usize) -> c64 {
    let q = (-2.0 / (tau_s * fs)).exp();
    let e = c64::from_polar(q, -std::f64::consts::TAU * (m % n) as f64 / n as f64);
    c64::new(1.0 - q, 0.0) / (c64::new(1.0, 0.0) - e)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A window of ones on samples 100..110 at 1 kHz, its pulse centred at 104.5: ten bins
    /// of one sample at −4.5 … 4.5 ms, a tenth of the energy each; a symmetric pulse's
    /// centroid is its centre.
    #[test]
    fn force_noise_bins_are_the_window_energy_about_the_centroid() {
        let fs = 1000.0;
        let mut w = vec![0.0; 300];
        w[100..110].iter_mut().for_each(|x| *x = 1.0);
        let force: Vec<f64> = (0..300)
            .map(|n| {
                if (100..110).contains(&n) {
                    1.0 - ((n as f64 - 104.5) / 6.0).powi(2)
                } else {
                    0.0
                }
            })
            .collect();
        let centroid = pulse_centroid(&force, &w).unwrap();
        assert!((centroid - 104.5).abs() < 1e-12, "{centroid}");
        let mut bins = ForceNoiseBins::new(fs, 0.01);
        bins.add_hit(&w, 2.0, centroid, fs);
        let (t, wt) = bins.finish().unwrap();
        assert_eq!(t.len(), 10);
        for (i, (t, wt)) in t.iter().zip(&wt).enumerate() {
            assert!((t - (i as f64 - 4.5) * 1e-3).abs() < 1e-12, "{i}: {t}");
            assert!((wt - 0.1).abs() < 1e-12);
        }
        assert!(ForceNoiseBins::new(fs, 0.01).finish().is_none());
        assert!(pulse_centroid(&force, &[0.0; 300]).is_none());
    }
}
