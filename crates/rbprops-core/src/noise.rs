//! The FRF noise model, one for the simulator, the model check and the bootstrap, and
//! the seeded normal stream every random draw of the workspace comes from.
//!
//! A recorded FRF value is `Y = H + ε`, with `ε` circular complex Gaussian noise:
//!
//! ```text
//!   E ε = 0,   E ε² = 0 (circular),   σ² = E|ε|² = a²|H|² + b²
//! ```
//!
//! so `Re ε` and `Im ε` are independent normals of variance `σ²/2` each. `a`
//! ([`NoiseModel::relative`]) is the part that scales with the response (calibration,
//! leakage, force-signal noise) and `b` ([`NoiseModel::floor`], FRF units) the part that
//! does not (transducer and ADC noise). The two come from independent sources, so their
//! *variances* add; `σ = √(a²|H|² + b²)`, not `a|H| + b`.
//!
//! [`NormalStream`] draws the standard normals: a `ChaCha8Rng` seeded with a 64-bit seed
//! (bytes 0–7 of its 32-byte key, little-endian) and a 64-bit stream index (bytes 8–15),
//! so that, e.g., every excitation of a simulated campaign has its own stream and the
//! draws do not depend on the thread count or the order in which excitations are
//! computed. Each pair of normals is one Box–Muller transform of two uniforms.

use crate::c64;
use rand::{Rng, RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// Circular complex Gaussian FRF noise with `E|ε|² = σ² = a²|H|² + b²` (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, schemars::JsonSchema)]
pub struct NoiseModel {
    /// Relative part `a` (fraction of |H|).
    pub relative: f64,
    /// Absolute floor `b` (FRF units).
    pub floor: f64,
}

impl NoiseModel {
    /// No noise.
    pub const NONE: NoiseModel = NoiseModel {
        relative: 0.0,
        floor: 0.0,
    };

    /// The model `σ² = a²|H|² + b²` with `a = relative` and `b = floor` (docs/conventions.md §8).
    pub fn new(relative: f64, floor: f64) -> Self {
        NoiseModel { relative, floor }
    }

    /// True when the model adds nothing.
    pub fn is_zero(&self) -> bool {
        self.relative == 0.0 && self.floor == 0.0
    }

    /// `σ² = E|ε|² = a²|H|² + b²` at the noise-free value `h = H`.
    pub fn variance(&self, h: c64) -> f64 {
        self.relative * self.relative * h.norm_sqr() + self.floor * self.floor
    }

    /// `σ = √(a²|H|² + b²)` at a value of magnitude `magnitude = |H|`, computed as
    /// `hypot(a|H|, b)`: exactly `a|H|` when `b = 0` and exactly `b` when `a = 0`.
    pub fn std_dev(&self, magnitude: f64) -> f64 {
        (self.relative * magnitude).hypot(self.floor)
    }

    /// Adds one draw of the noise to each value, in order, with the noise of each value
    /// taken at its own noise-free magnitude. Two normals per value (one Box–Muller pair):
    /// `ε = σ (n₁ + i n₂)/√2`.
    pub fn add_to(&self, values: &mut [c64], normals: &mut NormalStream) {
        if self.is_zero() {
            return;
        }
        for v in values {
            *v += normals.circular(self.std_dev(v.norm()));
        }
    }
}

/// The FRF noise a measured ordinary coherence `γ²` implies for an H1 estimate from
/// `n_d` averages (Bendat & Piersol, *Random Data*, the random error of a frequency
/// response estimate), in the noise model's terms:
///
/// ```text
///   σ²/|H|² = E|ε|²/|H|² ≈ (1 − γ²)/(n_d γ²)
/// ```
///
/// Half of it in each of `Re ε` and `Im ε`, i.e. the textbook `(1 − γ²)/(2 n_d γ²)` for
/// `var|Ĥ|/|H|²` and for the phase variance (rad²). Why: with noise on the response only,
/// `Ĥ₁ − H = Σ X*N / Σ|X|²` and `(1 − γ²)/γ² = G_nn/(|H|² G_xx)`; for Gaussian inputs the
/// exact expectation has `n_d − 1` in place of `n_d` (the mean of the inverse of a
/// complex χ²), which the approximation drops.
///
/// `γ²` is a measured value: `1 − γ²` is floored at `floor` (the precision the coherence
/// was stored with, or a few of its last units) so that a line with `γ² = 1` to storage
/// precision gets a finite, large weight and not an infinite one; `γ² ≤ 0` (no linear
/// relation at all) gives an infinite ratio.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoherenceNoise {
    /// Floor of `1 − γ²` (> 0).
    pub floor: f64,
}

impl CoherenceNoise {
    /// The floor of `1 − γ²` for coherence stored in single precision (UFF files hold
    /// it in single precision most often): a few units of `f32`'s last place at 1
    /// (2⁻²⁴ ≈ 6e-8), rounded to 1e-6 so that a γ² that is 1 to storage precision and one
    /// of 0.999999 weigh the same.
    pub const SINGLE_PRECISION_FLOOR: f64 = 1e-6;

    /// A coherence noise model whose `1 − γ²` is floored at `floor`.
    pub fn new(floor: f64) -> Self {
        CoherenceNoise { floor }
    }

    /// `(1 − γ²)/γ²` with `1 − γ²` floored: the relative FRF variance times `n_d`.
    /// Infinite for `γ² ≤ 0`; NaN for a NaN input (the caller refuses it).
    pub fn variance_ratio(&self, gamma2: f64) -> f64 {
        if gamma2.is_nan() {
            return f64::NAN;
        }
        if gamma2 <= 0.0 {
            return f64::INFINITY;
        }
        (1.0 - gamma2).max(self.floor) / gamma2.min(1.0)
    }

    /// `σ²/|H|² = (1 − γ²)/(n_d γ²)` (type docs) for `n_averages = n_d` averages.
    pub fn relative_variance(&self, gamma2: f64, n_averages: f64) -> f64 {
        self.variance_ratio(gamma2) / n_averages
    }

    /// `σ = |H| √((1 − γ²)/(n_d γ²))` at `magnitude = |H|`.
    pub fn std_dev(&self, magnitude: f64, gamma2: f64, n_averages: f64) -> f64 {
        magnitude * self.relative_variance(gamma2, n_averages).sqrt()
    }

    /// The least-squares weight of a line relative to `1/|H|` (the weight for noise
    /// proportional to |H|): `1/(σ/|H|) ∝ √(γ²/(1 − γ²))`, without the `√n_d`, which is
    /// the same for every line of a record and drops out of a weighted fit. 0 for
    /// `γ² ≤ 0`.
    pub fn relative_weight(&self, gamma2: f64) -> f64 {
        1.0 / self.variance_ratio(gamma2).sqrt()
    }
}

/// The seeded source of standard normal deviates (module docs).
#[derive(Debug, Clone)]
pub struct NormalStream {
    rng: ChaCha8Rng,
}

impl NormalStream {
    /// Stream `stream` of seed `seed`: key bytes 0–7 the seed, 8–15 the stream index
    /// (both little-endian), the rest zero.
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut key = [0u8; 32];
        key[..8].copy_from_slice(&seed.to_le_bytes());
        key[8..16].copy_from_slice(&stream.to_le_bytes());
        NormalStream {
            rng: ChaCha8Rng::from_seed(key),
        }
    }

    /// The stream of a generator seeded with `ChaCha8Rng::seed_from_u64(seed)`.
    pub fn seed_from_u64(seed: u64) -> Self {
        NormalStream {
            rng: ChaCha8Rng::seed_from_u64(seed),
        }
    }

    /// Two independent standard normals.
    pub fn pair(&mut self) -> (f64, f64) {
        standard_normal_pair(&mut self.rng)
    }

    /// One circular complex normal of `E|z|² = σ²`: `σ (n₁ + i n₂)/√2`.
    pub fn circular(&mut self, sigma: f64) -> c64 {
        let (n1, n2) = self.pair();
        let s = sigma * std::f64::consts::FRAC_1_SQRT_2;
        c64::new(s * n1, s * n2)
    }

    /// The underlying generator, for uniform draws that share the stream.
    pub fn rng(&mut self) -> &mut ChaCha8Rng {
        &mut self.rng
    }
}

/// Two independent standard normals from two uniforms of `rng` (Box–Muller):
/// `r = √(−2 ln U₁)`, `(r cos 2πU₂, r sin 2πU₂)`.
pub fn standard_normal_pair<R: Rng + ?Sized>(rng: &mut R) -> (f64, f64) {
    // 1 − U lies in (0, 1], so the logarithm is finite.
    let u1 = 1.0 - rng.random::<f64>();
    let u2 = rng.random::<f64>();
    let r = (-2.0 * u1.ln()).sqrt();
    let (s, c) = (std::f64::consts::TAU * u2).sin_cos();
    (r * c, r * s)
}

/// One standard normal (the first of a Box–Muller pair; the second is discarded).
pub fn standard_normal<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    standard_normal_pair(rng).0
}

/// The relative error one noisy force signal puts into every FRF of its excitation alike.
///
/// H1 over hits `d` whose measured force `F_d` carries the noise `N_d` (white, through
/// the force window `w`) is `Ĥ_c = H_c (1 + ε)` on every response c, with
///
/// ```text
///   ε(f) = −Σ_d F̄_d N_d / Σ_d |F_d|²,     E|ε(f)|² = ρ²(f) = E_N / S_ff(f)
///   E[ε(f) ε̄(f′)] = ρ(f) ρ(f′) γ(f − f′),  γ(Δf) = Σ_b W_b e^{−2πi Δf τ_b},  Σ_b W_b = 1
/// ```
///
/// (`E_N = σ_n² Σ w²` the noise energy through the window, `S_ff = Σ_d |F_d|²`; `W_b` the
/// window's `σ_n² w²` binned at times `τ_b` measured from the pulse's centroid). The
/// response noise is independent per channel; this part is not, and a short force window
/// makes it smooth over the whole band, so it does not average out over lines as the
/// per-channel noise does: to a fit it is a small gain and delay of the excitation.
///
/// A draw ([`CommonRelativeError::draw`]) is `ε(f) = ρ(f) Σ_b √W_b z_b e^{−2πi f τ_b}` with
/// real standard normals `z_b`: the noise is real, and with the times taken from the
/// pulse's centroid the pulse's own phase (`F̄` above) is removed to first order, so a short
/// window's error is a real gain at low frequency, as it is in H1.
#[derive(Debug, Clone, PartialEq)]
pub struct CommonRelativeError {
    /// `ρ²` per line of the FRF axis (dimensionless).
    pub relative_variance: Vec<f64>,
    /// `τ_b` (s from the pulse's centroid).
    pub times_s: Vec<f64>,
    /// `W_b`, summing to 1.
    pub weights: Vec<f64>,
}

impl CommonRelativeError {
    /// `γ(Δf)`, the correlation of the error at two lines `Δf` apart (type docs).
    pub fn correlation(&self, df_hz: f64) -> c64 {
        self.times_s
            .iter()
            .zip(&self.weights)
            .map(|(&t, &w)| c64::from_polar(w, -std::f64::consts::TAU * df_hz * t))
            .sum()
    }

    /// The variance factor of one line of a grid that keeps every q-th line, standing for
    /// its run of q lines `line_spacing_hz` apart (a fit on the grid weighs each of its
    /// lines as q): `κ² = (1/q) Σ_{|m|<q} (1 − |m|/q) Re γ(m Δf)`, the variance of the
    /// run's mean error over ρ². 1 for an error constant over the run, `1/q` for
    /// independent lines.
    pub fn run_variance_factor(&self, line_spacing_hz: f64, q: usize) -> f64 {
        let q = q.max(1);
        let sum: f64 = (1..q)
            .map(|m| (1.0 - m as f64 / q as f64) * self.correlation(m as f64 * line_spacing_hz).re)
            .sum();
        (1.0 + 2.0 * sum) / q as f64
    }

    /// The same process with `ρ²` on `lines` of the axis only.
    pub fn on_lines(&self, lines: std::ops::Range<usize>) -> Self {
        CommonRelativeError {
            relative_variance: self.relative_variance[lines].to_vec(),
            times_s: self.times_s.clone(),
            weights: self.weights.clone(),
        }
    }

    /// At most `max_bins` bins: runs of consecutive bins merged, each into its total weight
    /// at its weighted mean time (the correlation is kept at line spacings small against
    /// the inverse of the merged bins' span).
    pub fn coarsened(&self, max_bins: usize) -> Self {
        let k = self.weights.len().div_ceil(max_bins.max(1)).max(1);
        if k == 1 {
            return self.clone();
        }
        let (times_s, weights) = self
            .times_s
            .chunks(k)
            .zip(self.weights.chunks(k))
            .map(|(t, w)| {
                let total: f64 = w.iter().sum();
                let mean = if total > 0.0 {
                    t.iter().zip(w).map(|(t, w)| t * w).sum::<f64>() / total
                } else {
                    t.iter().sum::<f64>() / t.len() as f64
                };
                (mean, total)
            })
            .unzip();
        CommonRelativeError {
            relative_variance: self.relative_variance.clone(),
            times_s,
            weights,
        }
    }

    /// One draw of `ε` at `freqs_hz` with standard deviation `sd` per line (`ρ`, times
    /// [`Self::run_variance_factor`]'s root on a decimated grid) from the real standard
    /// normals `z` (one per bin).
    pub fn draw(&self, freqs_hz: &[f64], sd: &[f64], z: &[f64]) -> Vec<c64> {
        self.draw_on(&self.phasors(freqs_hz), sd, z)
    }

    /// The bins' phase factors `e^{−2πi f τ_b}` at every line of `freqs_hz`, line by
    /// line: the same for every draw on that grid, so a caller drawing many times makes
    /// them once ([`Self::draw_on`]).
    pub fn phasors(&self, freqs_hz: &[f64]) -> Vec<c64> {
        freqs_hz
            .iter()
            .flat_map(|&f| {
                self.times_s
                    .iter()
                    .map(move |&t| c64::from_polar(1.0, -std::f64::consts::TAU * f * t))
            })
            .collect()
    }

    /// [`Self::draw`] with the grid's [`Self::phasors`] made beforehand. Each term is
    /// `(a cos θ, a sin θ)`, what `c64::from_polar(a, θ)` computes, so the draw is the
    /// same to the bit.
    pub fn draw_on(&self, phasors: &[c64], sd: &[f64], z: &[f64]) -> Vec<c64> {
        let amp: Vec<f64> = self
            .weights
            .iter()
            .zip(z)
            .map(|(w, z)| w.sqrt() * z)
            .collect();
        if self.times_s.is_empty() {
            return vec![c64::new(0.0, 0.0); sd.len()];
        }
        phasors
            .chunks(self.times_s.len())
            .zip(sd)
            .map(|(p, &s)| {
                let e: c64 = p
                    .iter()
                    .zip(&amp)
                    .map(|(p, &a)| c64::new(a * p.re, a * p.im))
                    .sum();
                e * s
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn common(times_s: Vec<f64>, weights: Vec<f64>) -> CommonRelativeError {
        CommonRelativeError {
            relative_variance: Vec::new(),
            times_s,
            weights,
        }
    }

    /// A draw on precomputed phase factors is, to the bit, the sum of
    /// `from_polar(√W_b z_b, −2πfτ_b)` over the bins (the form the replicates were drawn
    /// in before the factors were kept), and no bins draw zeros.
    #[test]
    fn a_draw_on_precomputed_phasors_is_the_polar_sum_to_the_bit() {
        let c = common(vec![-0.013, 0.0, 0.021, 0.057], vec![0.1, 0.4, 0.3, 0.2]);
        let freqs: Vec<f64> = (0..300).map(|l| 0.37 + l as f64 * 0.0931).collect();
        let sd: Vec<f64> = (0..300).map(|l| 1e-4 * (1.0 + (l as f64).sin())).collect();
        let z = [0.3, -1.7, 0.9, 2.2];
        let polar: Vec<c64> = freqs
            .iter()
            .zip(&sd)
            .map(|(&f, &s)| {
                let e: c64 = c
                    .times_s
                    .iter()
                    .zip(c.weights.iter().zip(&z))
                    .map(|(&t, (w, z))| {
                        c64::from_polar(w.sqrt() * z, -std::f64::consts::TAU * f * t)
                    })
                    .sum();
                e * s
            })
            .collect();
        let drawn = c.draw_on(&c.phasors(&freqs), &sd, &z);
        assert_eq!(drawn.len(), polar.len());
        for (a, b) in drawn.iter().zip(&polar) {
            assert_eq!(
                (a.re.to_bits(), a.im.to_bits()),
                (b.re.to_bits(), b.im.to_bits())
            );
        }
        assert_eq!(c.draw(&freqs, &sd, &z), drawn);
        let none = common(Vec::new(), Vec::new());
        assert_eq!(
            none.draw(&freqs[..3], &sd[..3], &[]),
            vec![c64::new(0.0, 0.0); 3]
        );
    }

    /// The draws' second moments are the stated ones, `E[ε_i ε̄_j] = ρ_i ρ_j γ(f_i − f_j)`:
    /// 40,000 draws, each empirical moment within 5 of its standard errors (about
    /// `ρ_i ρ_j/√N`, at most 2.5 % of `ρ_i ρ_j` here).
    #[test]
    fn common_error_draws_have_the_stated_covariance() {
        let c = common(vec![-0.01, 0.0, 0.02, 0.05], vec![0.1, 0.4, 0.3, 0.2]);
        let freqs = [1.0, 3.0, 7.5];
        let sd = [1.0, 2.0, 0.5];
        let mut s = NormalStream::new(11, 0);
        let n = 40_000;
        let mut m = [[c64::new(0.0, 0.0); 3]; 3];
        for _ in 0..n {
            let z: Vec<f64> = (0..4).map(|_| s.pair().0).collect();
            let e = c.draw(&freqs, &sd, &z);
            for i in 0..3 {
                for j in 0..3 {
                    m[i][j] += e[i] * e[j].conj() / n as f64;
                }
            }
        }
        for i in 0..3 {
            for j in 0..3 {
                let want = c.correlation(freqs[i] - freqs[j]) * sd[i] * sd[j];
                let tol = 5.0 * sd[i] * sd[j] / (n as f64).sqrt();
                assert!(
                    (m[i][j] - want).norm() < tol,
                    "{i} {j}: {} vs {want}",
                    m[i][j]
                );
            }
        }
        assert!((c.correlation(0.0) - 1.0).norm() < 1e-15);
    }

    /// `κ²` at its two ends, exactly: an error constant over the band (one bin at τ = 0)
    /// keeps its variance on any grid; bins spread evenly over one period `1/Δf` make the
    /// lines independent, `κ² = 1/q`.
    #[test]
    fn run_variance_factor_spans_constant_to_independent() {
        let gain = common(vec![0.0], vec![1.0]);
        for q in [1, 2, 7, 40] {
            assert!((gain.run_variance_factor(0.03125, q) - 1.0).abs() < 1e-12);
        }
        let m = 64;
        let df = 0.5;
        let even = common(
            (0..m).map(|b| (b as f64 + 0.5) / (m as f64 * df)).collect(),
            vec![1.0 / m as f64; m],
        );
        for q in [1, 2, 5, 63] {
            let k = even.run_variance_factor(df, q);
            assert!((k - 1.0 / q as f64).abs() < 1e-12, "q = {q}: {k}");
        }
    }

    /// Merging bins keeps the total weight and each run's weighted mean time, and changes
    /// nothing when the bins are already few enough.
    #[test]
    fn coarsening_keeps_weight_and_mean_time() {
        let c = common(vec![0.0, 1.0, 2.0, 3.0, 4.0], vec![0.1, 0.3, 0.2, 0.2, 0.2]);
        assert_eq!(c.coarsened(5), c);
        let k = c.coarsened(2);
        assert_eq!(k.weights.len(), 2);
        assert!((k.weights[0] - 0.6).abs() < 1e-15 && (k.weights[1] - 0.4).abs() < 1e-15);
        assert!((k.times_s[0] - (0.3 + 0.4) / 0.6).abs() < 1e-14);
        assert!((k.times_s[1] - 3.5).abs() < 1e-14);
    }

    #[test]
    fn std_dev_is_exact_at_the_ends() {
        let m = NoiseModel::new(0.013, 0.0);
        for h in [1e-9, 0.37, 3.3e4] {
            assert_eq!(m.std_dev(h), 0.013 * h);
        }
        let m = NoiseModel::new(0.0, 2.5e-7);
        assert_eq!(m.std_dev(12.0), 2.5e-7);
        let m = NoiseModel::new(0.03, 4.0);
        assert!((m.std_dev(100.0) - 5.0).abs() < 1e-12);
        assert!((m.variance(c64::new(60.0, 80.0)) - 25.0).abs() < 1e-12);
    }

    /// The drawn noise has the stated second moments: E|ε|² = a²|H|² + b², E ε² = 0,
    /// Re and Im uncorrelated with equal variance, and E ε = 0.
    ///
    /// Tolerance: with n = 200 000 draws of u = |ε|²/σ² (exponential, mean 1, sd 1) the
    /// sample mean has sd 1/√n = 2.2e-3; a 5-sd bound is 0.011 (false failure < 1e-6,
    /// and the draw is seeded, so the test is deterministic anyway). The same bound holds
    /// for the normalised E ε² (each part has sd ≤ 1/√n) and for √2 E ε/σ (sd 1/√n).
    #[test]
    fn drawn_noise_has_the_stated_variance() {
        let n = 200_000;
        let tol = 5.0 / (n as f64).sqrt();
        for (a, b) in [(0.02, 0.0), (0.0, 0.3), (0.01, 0.05)] {
            let model = NoiseModel::new(a, b);
            let mut normals = NormalStream::new(42, 7);
            // |H| varies over two decades so both parts matter where b ≠ 0.
            let h: Vec<c64> = (0..n)
                .map(|i| c64::from_polar(0.1 + 10.0 * (i % 100) as f64 / 100.0, i as f64))
                .collect();
            let mut y = h.clone();
            model.add_to(&mut y, &mut normals);
            let (mut m2, mut pseudo, mut mean) = (0.0, c64::new(0.0, 0.0), c64::new(0.0, 0.0));
            for (y, h) in y.iter().zip(&h) {
                let e = y - h;
                let s2 = model.variance(*h);
                m2 += e.norm_sqr() / s2;
                pseudo += e * e / s2;
                mean += e * (2.0 / s2).sqrt();
            }
            let nf = n as f64;
            assert!(
                (m2 / nf - 1.0).abs() < tol,
                "a={a} b={b}: E|ε|²/σ² = {}",
                m2 / nf
            );
            assert!(
                (pseudo / nf).norm() < 2.0 * tol,
                "E ε²/σ² = {}",
                pseudo / nf
            );
            assert!((mean / nf).norm() < 2.0 * tol, "E ε = {}", mean / nf);
        }
    }

    /// The coherence formula against an H1 estimate done by hand: `n_d` averages of a
    /// circular Gaussian force `X` and response noise `N`, `Ĥ₁ = Σ X*Y/Σ|X|²`, true
    /// `γ² = |H|²G_xx/(|H|²G_xx + G_nn)`. The mean of `|Ĥ₁ − H|²/|H|²` over `trials` is
    /// `(1 − γ²)/((n_d − 1)γ²)` exactly for Gaussian X (type docs), so the formula with
    /// `n_d` is checked to be that times `(n_d − 1)/n_d`.
    ///
    /// Tolerance: `|Ĥ₁ − H|²` given Σ|X|² is exponential, and 1/Σ|X|² (inverse χ² with
    /// 2n_d = 32 degrees of freedom) has relative sd ≈ 1/√(n_d − 2) = 0.27, so one trial's
    /// ratio has relative sd ≈ √(2·1.07 − 1) ≈ 1.07; over 40 000 trials the mean's relative
    /// sd is 0.0053 and a 4-sd bound is 0.022 (the draws are seeded: deterministic).
    #[test]
    fn coherence_variance_matches_a_monte_carlo_h1() {
        let n_d = 16usize;
        let trials = 40_000;
        let h = c64::new(0.3, -0.4);
        for gamma2 in [0.5, 0.9, 0.99] {
            // G_xx = 1, so G_nn = |H|² (1 − γ²)/γ².
            let g_nn = h.norm_sqr() * (1.0 - gamma2) / gamma2;
            let mut normals = NormalStream::new(5, (gamma2 * 1000.0) as u64);
            let mut mean = 0.0;
            for _ in 0..trials {
                let (mut sxy, mut sxx) = (c64::new(0.0, 0.0), 0.0);
                for _ in 0..n_d {
                    let x = normals.circular(1.0);
                    let y = h * x + normals.circular(g_nn.sqrt());
                    sxy += x.conj() * y;
                    sxx += x.norm_sqr();
                }
                mean += (sxy / sxx - h).norm_sqr() / h.norm_sqr();
            }
            mean /= trials as f64;
            let model = CoherenceNoise::new(1e-12);
            let exact =
                model.relative_variance(gamma2, n_d as f64) * n_d as f64 / (n_d as f64 - 1.0);
            assert!(
                (mean / exact - 1.0).abs() < 0.022,
                "γ² = {gamma2}: Monte Carlo {mean:e}, formula {exact:e}"
            );
            let sd = model.std_dev(h.norm(), gamma2, n_d as f64);
            assert!(
                (sd * sd / h.norm_sqr() - (1.0 - gamma2) / (n_d as f64 * gamma2)).abs() < 1e-15
            );
        }
    }

    /// The floor and the ends: γ² = 1 gives the floored finite weight, γ² ≤ 0 weight 0,
    /// and the weight is √(γ²/(1 − γ²)) in between.
    #[test]
    fn coherence_weight_ends_and_floor() {
        let m = CoherenceNoise::new(CoherenceNoise::SINGLE_PRECISION_FLOOR);
        assert_eq!(m.relative_weight(1.0), 1e3);
        // 1 − γ² = 1e-8 is below the floor: weighs as γ² = 1 (to the 1e-8 of γ² itself).
        assert!((m.relative_weight(1.0 - 1e-8) / 1e3 - 1.0).abs() < 1e-8);
        assert_eq!(m.relative_weight(0.0), 0.0);
        assert_eq!(m.relative_weight(-0.1), 0.0);
        assert!((m.relative_weight(0.8) - 2.0).abs() < 1e-15);
        assert!((m.relative_weight(0.5) - 1.0).abs() < 1e-15);
        assert!(m.variance_ratio(f64::NAN).is_nan());
    }

    /// The stream layout is the one frf-sim has always used (seed in key bytes 0–7,
    /// stream in 8–15), and `pair` is the Box–Muller transform of two uniforms.
    #[test]
    fn stream_layout_and_box_muller() {
        let mut key = [0u8; 32];
        key[..8].copy_from_slice(&9u64.to_le_bytes());
        key[8..16].copy_from_slice(&3u64.to_le_bytes());
        let mut rng = ChaCha8Rng::from_seed(key);
        let u1 = 1.0 - rng.random::<f64>();
        let u2 = rng.random::<f64>();
        let r = (-2.0 * u1.ln()).sqrt();
        let (n1, n2) = NormalStream::new(9, 3).pair();
        assert_eq!(n1, r * (std::f64::consts::TAU * u2).cos());
        assert_eq!(n2, r * (std::f64::consts::TAU * u2).sin());
        let mut a = NormalStream::new(9, 3);
        let mut b = NormalStream::new(9, 4);
        assert_ne!(a.pair(), b.pair());
    }
}
