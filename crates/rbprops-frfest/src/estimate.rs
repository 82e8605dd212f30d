//! FRF estimators from the spectral sums, coherence, each line's variance, quantity
//! conversion and the hit-quality summary.
//!
//! Notation (crate docs): `n_d` hits, `S_ff` (`n_refs × n_refs`), `S_xf` (row `S_xf,o` per
//! response o), `S_xx,o`, all at one line k.
//!
//! # H1 (default)
//!
//! ```text
//!   SIMO:  Ĥ₁ = S_xf / S_ff          MIMO:  Ĥ₁,o = S_xf,o S_ff⁻¹   (row of n_refs)
//! ```
//!
//! MIMO needs `S_ff` well conditioned: its eigenvalues (Hermitian) give
//! `κ = λ_max/λ_min`, and a line with `λ_min ≤ 0` or `κ >` [`ConditioningOptions::max_condition`]
//! is an error naming the line ([`crate::FrfError::IllConditioned`]) — coherent inputs,
//! a dead reference, or fewer hits than references.
//!
//! # H2 and Hv (SIMO; Hv also MIMO)
//!
//! `Ĥ₂ = S_xx / S_fx` with `S_fx = conj(S_xf)`. `Ĥ_v` is the total-least-squares estimate:
//! with `C = Σ_d z zᴴ`, `z = [F; X]`, i.e. `C = [S_ff S_fx; S_xf S_xx]`, the eigenvector
//! `v` of C's smallest eigenvalue `λ` gives `H = −conj(v_f/v_x)`. For SIMO, in closed form,
//!
//! ```text
//!   λ = (S_ff S_xx − |S_xf|²)/λ_max,   Ĥ_v = S_xf/(S_ff − λ) = (S_xx − λ)/S_fx,
//! ```
//!
//! each form used where it has no cancellation. Hv weighs force and response noise
//! equally *in the units given*: it depends on the channels' scaling. Without noise
//! `Ĥ₁ = Ĥ₂ = Ĥ_v`.
//!
//! # Coherence
//!
//! Ordinary (SIMO) `γ² = |S_xf|²/(S_ff S_xx)`; multiple (MIMO)
//! `γ²_o = S_xf,o S_ff⁻¹ S_fx,o / S_xx,o = 1 − R_o/S_xx,o`.
//!
//! # Each line's variance (H1)
//!
//! With noise `N` on the response only, `X_d = H F_d + N_d`, and `N_d` independent from hit
//! to hit with `E|N_d|² = σ_N²` (white in the averages; any distribution), conditionally on
//! the forces `Ĥ₁ − H = Σ_d N_d F_dᴴ S_ff⁻¹`, so
//!
//! ```text
//!   E|Ĥ₁,or − H_or|² = σ²_N,o [S_ff⁻¹]_rr            (SIMO: σ_N²/S_ff)
//! ```
//!
//! and the residual `R_o = S_xx,o − S_xf,o S_ff⁻¹ S_fx,o = Σ_d |X_d − Ĥ₁ F_d|²` (the Schur
//! complement of `S_ff` in C) is the noise projected off the `n_refs` force vectors, with
//! `E R_o = (n_d − n_refs) σ²_N,o` exactly. Hence the **unbiased** estimate
//!
//! ```text
//!   σ̂²_or = R_o [S_ff⁻¹]_rr / (n_d − n_refs)
//!   SIMO:  σ̂² = R/((n_d − 1) S_ff) = |Ĥ₁|² (1 − γ̂²) / ((n_d − 1) γ̂²)
//! ```
//!
//! (the two SIMO forms are the same number: `|Ĥ₁|² = γ̂² S_xx/S_ff`, `R = S_xx(1 − γ̂²)`).
//! It is Bendat & Piersol's `|H|²(1 − γ²)/(n_d γ²)` (rbprops-core's `CoherenceNoise`, the
//! noise model's `σ² = E|ε|²`) with the *measured* coherence, whose `1 − γ̂²` is low by
//! `(n_d − n_refs)/n_d` on average, hence `n_d − n_refs`. With `n_d ≤ n_refs` the
//! variance is unknown: [`FrfEstimate::variance`] is None. As an estimate, `R_o/σ²_N`
//! has `2(n_d − n_refs)` real degrees of freedom (complex Gaussian noise): from 5 hits its
//! relative standard deviation is 50 %, hence [`smoothed_variance`].
//!
//! For H2 and Hv the variance is the same first-order expression with their own `|Ĥ|²`
//! (Bendat & Piersol: to first order H1 and H2 have the same random error).

use crate::spectra::SpectralSums;
use crate::{c64, FrfError};
use nalgebra::DMatrix;
use std::ops::Range;

/// Which estimator (`frf-est --estimator`; the help there is the user's view of each).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Estimator {
    /// `S_xf S_ff⁻¹` (module docs).
    #[cfg_attr(
        feature = "clap",
        value(help = "S_xf/S_ff: unbiased by response noise (default; impact tests)")
    )]
    H1,
    /// `S_xx/S_fx` (SIMO).
    #[cfg_attr(feature = "clap", value(help = "S_xx/S_fx: unbiased by force noise"))]
    H2,
    /// Total least squares, the smallest eigenvector of `C`.
    #[cfg_attr(feature = "clap", value(help = "Total least squares between the two"))]
    Hv,
}

/// The conditioning check of MIMO `S_ff`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConditioningOptions {
    /// Largest `λ_max/λ_min` of `S_ff` accepted (default 1e8: the inverse then loses
    /// at most 8 of 16 digits).
    pub max_condition: f64,
}

impl Default for ConditioningOptions {
    fn default() -> Self {
        ConditioningOptions { max_condition: 1e8 }
    }
}

/// The FRFs of one excitation over a band of lines, with coherence and variance.
#[derive(Debug, Clone, PartialEq)]
pub struct FrfEstimate {
    /// Which estimator made `h`.
    pub estimator: Estimator,
    /// The DFT line indices k covered (`f_k = k · line_spacing_hz`).
    pub lines: Range<usize>,
    /// `f_s/N` (Hz).
    pub line_spacing_hz: f64,
    /// Force channels.
    pub n_refs: usize,
    /// Response channels.
    pub n_resp: usize,
    /// Averages `n_d`.
    pub n_averages: usize,
    /// `Ĥ` as `[o][r][j]`, j the index within `lines`.
    pub h: Vec<c64>,
    /// Ordinary (SIMO) or multiple (MIMO) coherence, `[o][j]`.
    pub coherence: Vec<f64>,
    /// The residual noise power `R_o` (module docs), `[o][j]`.
    pub residual: Vec<f64>,
    /// `[S_ff⁻¹]_rr`, `[r][j]` (SIMO: `1/S_ff`).
    pub sff_inv_diag: Vec<f64>,
    /// `σ̂² = E|Ĥ − H|²` per value, `[o][r][j]`; None when `n_d ≤ n_refs` (unknown).
    pub variance: Option<Vec<f64>>,
}

impl FrfEstimate {
    /// Lines in the band.
    pub fn len(&self) -> usize {
        self.lines.len()
    }
    /// True for an empty band.
    pub fn is_empty(&self) -> bool {
        self.lines.is_empty()
    }
    /// Frequency of band index j (Hz).
    pub fn freq_hz(&self, j: usize) -> f64 {
        (self.lines.start + j) as f64 * self.line_spacing_hz
    }
    /// `Ĥ_or` at band index j.
    pub fn h(&self, o: usize, r: usize, j: usize) -> c64 {
        self.h[(o * self.n_refs + r) * self.len() + j]
    }
    /// The FRF `Ĥ_or` over the band.
    pub fn frf(&self, o: usize, r: usize) -> &[c64] {
        let n = self.len();
        &self.h[(o * self.n_refs + r) * n..(o * self.n_refs + r + 1) * n]
    }
    /// Coherence of response o over the band.
    pub fn coherence_of(&self, o: usize) -> &[f64] {
        &self.coherence[o * self.len()..(o + 1) * self.len()]
    }
    /// `σ̂²` of `Ĥ_or` over the band, when known.
    pub fn variance_of(&self, o: usize, r: usize) -> Option<&[f64]> {
        let n = self.len();
        self.variance
            .as_ref()
            .map(|v| &v[(o * self.n_refs + r) * n..(o * self.n_refs + r + 1) * n])
    }
}

impl SpectralSums {
    fn band(&self, band: Option<Range<usize>>) -> Result<Range<usize>, FrfError> {
        let b = band.unwrap_or(0..self.lines());
        if b.start > b.end || b.end > self.lines() {
            return Err(FrfError::Band {
                start: b.start,
                end: b.end,
                lines: self.lines(),
            });
        }
        if self.count() == 0 {
            return Err(FrfError::NoAverages);
        }
        Ok(b)
    }

    fn empty_estimate(&self, estimator: Estimator, lines: Range<usize>) -> FrfEstimate {
        let n = lines.len();
        FrfEstimate {
            estimator,
            lines,
            line_spacing_hz: self.line_spacing_hz(),
            n_refs: self.n_refs(),
            n_resp: self.n_resp(),
            n_averages: self.count(),
            h: vec![c64::new(0.0, 0.0); self.n_resp() * self.n_refs() * n],
            coherence: vec![0.0; self.n_resp() * n],
            residual: vec![0.0; self.n_resp() * n],
            sff_inv_diag: vec![0.0; self.n_refs() * n],
            variance: None,
        }
    }

    /// H1 over `band` (None: every one-sided line), SIMO or MIMO (module docs).
    pub fn h1(
        &self,
        band: Option<Range<usize>>,
        cond: &ConditioningOptions,
    ) -> Result<FrfEstimate, FrfError> {
        let lines = self.band(band)?;
        let (nr, no, n) = (self.n_refs(), self.n_resp(), lines.len());
        let mut est = self.empty_estimate(Estimator::H1, lines.clone());
        let dof = self.count() as f64 - nr as f64;
        let mut var = (dof > 0.0).then(|| vec![0.0; no * nr * n]);
        for (j, k) in lines.clone().enumerate() {
            let inv = self.sff_inverse(k, cond)?;
            for r in 0..nr {
                est.sff_inv_diag[r * n + j] = inv[r * nr + r].re;
            }
            for o in 0..no {
                let row = self.sxf_row(k, o);
                let mut explained = 0.0;
                for r in 0..nr {
                    let mut h = c64::new(0.0, 0.0);
                    for (s, x) in row.iter().enumerate() {
                        h += x * inv[s * nr + r];
                    }
                    est.h[(o * nr + r) * n + j] = h;
                    explained += (h * row[r].conj()).re;
                }
                let sxx = self.sxx(k, o);
                let resid = (sxx - explained).max(0.0);
                est.residual[o * n + j] = resid;
                est.coherence[o * n + j] = if sxx > 0.0 {
                    (explained / sxx).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                if let Some(v) = var.as_mut() {
                    for r in 0..nr {
                        v[(o * nr + r) * n + j] = resid * est.sff_inv_diag[r * n + j] / dof;
                    }
                }
            }
        }
        // SIMO: the coherence in its textbook form (identical up to rounding).
        if nr == 1 {
            for (j, k) in lines.enumerate() {
                for o in 0..no {
                    let (f, x, c) = (self.sff(k, 0, 0).re, self.sxx(k, o), self.sxf(k, o, 0));
                    est.coherence[o * n + j] = if f > 0.0 && x > 0.0 {
                        (c.norm_sqr() / (f * x)).min(1.0)
                    } else {
                        0.0
                    };
                }
            }
        }
        est.variance = var;
        Ok(est)
    }

    /// `S_ff⁻¹` at line k, row-major, after the conditioning check.
    fn sff_inverse(&self, k: usize, cond: &ConditioningOptions) -> Result<Vec<c64>, FrfError> {
        let nr = self.n_refs();
        let block = self.sff_block(k);
        if nr == 1 {
            let f = block[0].re;
            if !(f > 0.0) {
                return Err(self.ill(k, f64::INFINITY, cond));
            }
            return Ok(vec![c64::new(1.0 / f, 0.0)]);
        }
        let m = DMatrix::from_fn(nr, nr, |r, s| {
            // Hermitian by construction; symmetrise the rounding.
            0.5 * (block[r * nr + s] + block[s * nr + r].conj())
        });
        let eig = m.symmetric_eigen();
        let (lo, hi) = eig
            .eigenvalues
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(*v), b.max(*v))
            });
        let kappa = if lo > 0.0 { hi / lo } else { f64::INFINITY };
        if !(kappa <= cond.max_condition) {
            return Err(self.ill(k, kappa, cond));
        }
        let v = &eig.eigenvectors;
        let mut inv = vec![c64::new(0.0, 0.0); nr * nr];
        for r in 0..nr {
            for s in 0..nr {
                let mut acc = c64::new(0.0, 0.0);
                for (i, l) in eig.eigenvalues.iter().enumerate() {
                    acc += v[(r, i)] * v[(s, i)].conj() / *l;
                }
                inv[r * nr + s] = acc;
            }
        }
        Ok(inv)
    }

    fn ill(&self, k: usize, condition: f64, cond: &ConditioningOptions) -> FrfError {
        FrfError::IllConditioned {
            line: k,
            freq_hz: self.freq_hz(k),
            condition,
            max: cond.max_condition,
        }
    }

    /// H2 over `band` (SIMO only, module docs).
    pub fn h2(&self, band: Option<Range<usize>>) -> Result<FrfEstimate, FrfError> {
        if self.n_refs() != 1 {
            return Err(FrfError::SimoOnly("H2"));
        }
        let lines = self.band(band)?;
        let mut est = self.empty_estimate(Estimator::H2, lines.clone());
        let n = lines.len();
        for (j, k) in lines.enumerate() {
            let f = self.sff(k, 0, 0).re;
            est.sff_inv_diag[j] = if f > 0.0 { 1.0 / f } else { f64::INFINITY };
            for o in 0..self.n_resp() {
                let (x, c) = (self.sxx(k, o), self.sxf(k, o, 0));
                est.h[o * n + j] = c64::new(x, 0.0) / c.conj();
                fill_simo_stats(&mut est, o, j, f, x, c);
            }
        }
        est.variance = first_order_variance(&est);
        Ok(est)
    }

    /// Hv over `band` (module docs): closed form for SIMO, the smallest eigenvector of
    /// the `(n_refs + 1)²` matrix `C` per response for MIMO (after the same conditioning
    /// check on `S_ff` as H1).
    pub fn hv(
        &self,
        band: Option<Range<usize>>,
        cond: &ConditioningOptions,
    ) -> Result<FrfEstimate, FrfError> {
        let lines = self.band(band)?;
        let (nr, no, n) = (self.n_refs(), self.n_resp(), lines.len());
        if nr > 1 {
            // Coherence, residual and S_ff⁻¹ from H1; H from the eigenvectors.
            let mut est = self.h1(Some(lines.clone()), cond)?;
            est.estimator = Estimator::Hv;
            for (j, k) in lines.enumerate() {
                let block = self.sff_block(k);
                for o in 0..no {
                    let row = self.sxf_row(k, o);
                    let c = DMatrix::from_fn(nr + 1, nr + 1, |a, b| match (a < nr, b < nr) {
                        (true, true) => 0.5 * (block[a * nr + b] + block[b * nr + a].conj()),
                        (true, false) => row[a].conj(),
                        (false, true) => row[b],
                        (false, false) => c64::new(self.sxx(k, o), 0.0),
                    });
                    let eig = c.symmetric_eigen();
                    let imin = eig
                        .eigenvalues
                        .iter()
                        .enumerate()
                        .fold(
                            (0, f64::INFINITY),
                            |(i0, m), (i, v)| {
                                if *v < m {
                                    (i, *v)
                                } else {
                                    (i0, m)
                                }
                            },
                        )
                        .0;
                    let vx = eig.eigenvectors[(nr, imin)];
                    for r in 0..nr {
                        est.h[(o * nr + r) * n + j] = -(eig.eigenvectors[(r, imin)] / vx).conj();
                    }
                }
            }
            est.variance = first_order_variance(&est);
            return Ok(est);
        }
        let mut est = self.empty_estimate(Estimator::Hv, lines.clone());
        for (j, k) in lines.enumerate() {
            let a = self.sff(k, 0, 0).re;
            est.sff_inv_diag[j] = if a > 0.0 { 1.0 / a } else { f64::INFINITY };
            for o in 0..no {
                let (d, c) = (self.sxx(k, o), self.sxf(k, o, 0));
                let half = 0.5 * (a - d);
                let root = half.hypot(c.norm());
                let lmax = 0.5 * (a + d) + root;
                let lmin = if lmax > 0.0 {
                    (a * d - c.norm_sqr()) / lmax
                } else {
                    0.0
                };
                est.h[o * n + j] = if half >= 0.0 {
                    // S_ff − λ = (a − d)/2 + root, no cancellation.
                    let _ = lmin;
                    c / (half + root)
                } else {
                    c64::new(-half + root, 0.0) / c.conj()
                };
                fill_simo_stats(&mut est, o, j, a, d, c);
            }
        }
        est.variance = first_order_variance(&est);
        Ok(est)
    }

    /// The estimate of `estimator` (H1, H2 or Hv) over `band`.
    pub fn estimate(
        &self,
        estimator: Estimator,
        band: Option<Range<usize>>,
        cond: &ConditioningOptions,
    ) -> Result<FrfEstimate, FrfError> {
        match estimator {
            Estimator::H1 => self.h1(band, cond),
            Estimator::H2 => self.h2(band),
            Estimator::Hv => self.hv(band, cond),
        }
    }
}

/// SIMO coherence and residual `R = S_xx(1 − γ²)` at band index j.
fn fill_simo_stats(est: &mut FrfEstimate, o: usize, j: usize, f: f64, x: f64, c: c64) {
    let n = est.len();
    let g = if f > 0.0 && x > 0.0 {
        (c.norm_sqr() / (f * x)).min(1.0)
    } else {
        0.0
    };
    est.coherence[o * n + j] = g;
    est.residual[o * n + j] = if f > 0.0 {
        (x - c.norm_sqr() / f).max(0.0)
    } else {
        x
    };
}

/// `|Ĥ|²(1 − γ²)/((n_d − n_refs) γ²)` per value (module docs), None for `n_d ≤ n_refs`.
fn first_order_variance(est: &FrfEstimate) -> Option<Vec<f64>> {
    let dof = est.n_averages as f64 - est.n_refs as f64;
    if dof <= 0.0 {
        return None;
    }
    let n = est.len();
    let mut v = vec![0.0; est.h.len()];
    for o in 0..est.n_resp {
        for r in 0..est.n_refs {
            for j in 0..n {
                let g = est.coherence[o * n + j];
                let i = (o * est.n_refs + r) * n + j;
                v[i] = if g > 0.0 {
                    est.h[i].norm_sqr() * (1.0 - g) / (dof * g)
                } else {
                    f64::INFINITY
                };
            }
        }
    }
    Some(v)
}

/// The variance pooled over neighbouring lines ([`smoothed_variance`]).
#[derive(Debug, Clone, PartialEq)]
pub struct SmoothedVariance {
    /// Half-width L: lines `j − L ..= j + L` (clipped to the band).
    pub half_width: usize,
    /// `σ̃²` per value, `[o][r][j]` (the layout of [`FrfEstimate::h`]).
    pub variance: Vec<f64>,
    /// Real degrees of freedom of `σ̃²/σ²` (≈ χ²_dof/dof) per band index j.
    pub dof: Vec<f64>,
}

/// Each line's H1 variance with the noise power pooled over `±half_width` lines:
///
/// ```text
///   σ̃²_or,j = [S_ff⁻¹]_rr,j · (1/M_j) Σ_{i ∈ W_j} R_o,i/(n_d − n_refs)
/// ```
///
/// `W_j` = the `M_j` band lines within `half_width` of j. Only the noise power `R` is
/// pooled (for impacts the response noise spectrum is smooth); `S_ff⁻¹` is the line's own,
/// which is known exactly. Unbiased where the noise spectrum is flat over `W_j`.
///
/// Degrees of freedom, for complex Gaussian noise whose line-to-line correlation is
/// `γ_m` (`gamma`, from [`crate::line_correlation`]; None: independent lines, γ_m = δ_m):
/// `R_i` is `ν = n_d − n_refs` complex squares, so `Σ_{W} R_i` has mean `ν M σ²` and
/// variance `ν σ⁴ Σ_{a,b ∈ W} |γ_{a−b}|²`, and matching a scaled χ²,
///
/// ```text
///   dof_j = 2 ν M_j² / Σ_{a,b ∈ W_j} |γ_{a−b}|²      (independent lines: 2 ν M_j).
/// ```
///
/// Lags beyond `gamma`'s length count as uncorrelated. None when the variance is unknown.
pub fn smoothed_variance(
    est: &FrfEstimate,
    half_width: usize,
    gamma: Option<&[c64]>,
) -> Option<SmoothedVariance> {
    est.variance.as_ref()?;
    let nu = (est.n_averages - est.n_refs) as f64;
    let n = est.len();
    let mut variance = vec![0.0; est.h.len()];
    let mut dof = vec![0.0; n];
    let g2 = |m: usize| -> f64 {
        match gamma {
            Some(g) => g.get(m).map_or(0.0, |v| v.norm_sqr()),
            None => {
                if m == 0 {
                    1.0
                } else {
                    0.0
                }
            }
        }
    };
    for (j, d) in dof.iter_mut().enumerate() {
        let lo = j.saturating_sub(half_width);
        let hi = (j + half_width + 1).min(n);
        let m = hi - lo;
        let mut s = 0.0;
        for a in 0..m {
            for b in 0..m {
                s += g2(a.abs_diff(b));
            }
        }
        *d = 2.0 * nu * (m * m) as f64 / s;
        for o in 0..est.n_resp {
            let pooled = est.residual[o * n + lo..o * n + hi].iter().sum::<f64>() / (m as f64 * nu);
            for r in 0..est.n_refs {
                variance[(o * est.n_refs + r) * n + j] = pooled * est.sff_inv_diag[r * n + j];
            }
        }
    }
    Some(SmoothedVariance {
        half_width,
        variance,
        dof,
    })
}

/// How good the averaged FRFs are ([`quality`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quality {
    /// `√(Σ σ̂² / Σ |Ĥ|²)` over every value of the band: the FRFs' relative standard error.
    pub relative_se: f64,
    /// `n_d`.
    pub n_averages: usize,
    /// Hits still to add to halve `relative_se`: `3 n_d` (module docs of [`quality`]).
    pub more_hits_to_halve: usize,
}

/// The hit-quality summary of an estimate (None without a variance):
///
/// ```text
///   RSE = √( Σ_{o,r,j} σ̂²_or,j / Σ_{o,r,j} |Ĥ_or,j|² )
/// ```
///
/// (an energy-weighted relative standard error: antiresonances do not dominate it). The
/// true variance is `σ_N² [S_ff⁻¹]_rr` and `S_ff` grows like `n_d` (impacts of similar
/// force), so `σ ∝ 1/√n_d`: halving it takes `4 n_d` hits, i.e. `3 n_d` more.
pub fn quality(est: &FrfEstimate) -> Option<Quality> {
    let v = est.variance.as_ref()?;
    let num: f64 = v.iter().filter(|x| x.is_finite()).sum();
    let den: f64 = est.h.iter().map(|h| h.norm_sqr()).sum();
    Some(Quality {
        relative_se: (num / den).sqrt(),
        n_averages: est.n_averages,
        more_hits_to_halve: 3 * est.n_averages,
    })
}

/// What a response transducer measures, and the FRF quantity wanted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// Displacement per force (m/N).
    Receptance,
    /// Velocity per force: `iω` × receptance.
    Mobility,
    /// Acceleration per force: `(iω)²` × receptance = `−ω²` × receptance.
    Accelerance,
}

impl Quantity {
    /// The power of `iω` relative to receptance.
    pub fn order(&self) -> i32 {
        match self {
            Quantity::Receptance => 0,
            Quantity::Mobility => 1,
            Quantity::Accelerance => 2,
        }
    }
}

/// The estimate in quantity `wanted` from one measured as `measured`:
/// `H_wanted = H_measured (iω)^{−p}`, `p = order(measured) − order(wanted)`, `ω = 2πf_k`,
/// the variance scaled by `ω^{−2p}` (e^{+iωt}: docs/conventions.md §1). With `p > 0` the
/// ω = 0 line is undefined and is **excluded**: the band then starts at line 1. With
/// `p < 0` it is 0 exactly. Coherence and the residual are unchanged; `sff_inv_diag` is
/// scaled like the variance, so [`smoothed_variance`] stays consistent.
pub fn convert_quantity(est: &FrfEstimate, measured: Quantity, wanted: Quantity) -> FrfEstimate {
    let p = measured.order() - wanted.order();
    if p == 0 {
        return est.clone();
    }
    let skip = usize::from(p > 0 && est.lines.start == 0 && !est.is_empty());
    let (n, m) = (est.len(), est.len() - skip);
    let lines = est.lines.start + skip..est.lines.end;
    let first = lines.start;
    let factor = |j: usize| {
        let w = std::f64::consts::TAU * (first + j) as f64 * est.line_spacing_hz;
        c64::new(0.0, w).powi(-p)
    };
    let remap = |v: &[f64], groups: usize, scale: bool| -> Vec<f64> {
        let mut out = Vec::with_capacity(groups * m);
        for g in 0..groups {
            for j in 0..m {
                let x = v[g * n + skip + j];
                out.push(if scale { x * factor(j).norm_sqr() } else { x });
            }
        }
        out
    };
    let mut h = Vec::with_capacity(est.n_resp * est.n_refs * m);
    for g in 0..est.n_resp * est.n_refs {
        for j in 0..m {
            h.push(est.h[g * n + skip + j] * factor(j));
        }
    }
    let groups = est.n_resp * est.n_refs;
    FrfEstimate {
        estimator: est.estimator,
        lines,
        line_spacing_hz: est.line_spacing_hz,
        n_refs: est.n_refs,
        n_resp: est.n_resp,
        n_averages: est.n_averages,
        h,
        coherence: remap(&est.coherence, est.n_resp, false),
        residual: remap(&est.residual, est.n_resp, false),
        sff_inv_diag: remap(&est.sff_inv_diag, est.n_refs, true),
        variance: est.variance.as_ref().map(|v| remap(v, groups, true)),
    }
}

/// Coherences closer than this to 0 or 1 are taken at it by [`coherence_line_variance`]: a
/// coherence written in single precision reads 1 on a clean line, and γ² = 0 would make
/// the variance infinite (`rbprops_core::CoherenceNoise::SINGLE_PRECISION_FLOOR`).
pub const COHERENCE_FLOOR: f64 = 1e-6;

/// The noise variance of an H1 FRF line known only by its value, its ordinary coherence
/// `γ²` and the number of averages `n_d` (an analyser's export; Bendat & Piersol, *Random
/// Data*, the random error of |Ĥ| and of the phase with noise on the response):
///
/// ```text
///   Var|Ĥ| ≈ (1 − γ²)/(2 n_d γ²) |H|²,   Var[arg Ĥ] ≈ (1 − γ²)/(2 n_d γ²)  (rad²)
/// ```
///
/// so each of the real and imaginary parts carries `(1 − γ²)/(2 n_d γ²) |H|²` and the
/// complex error, the variance the line-variance topic holds (docs/conventions.md §8), is
///
/// ```text
///   σ² = E|Ĥ − H|² ≈ (1 − γ²)/(n_d γ²) |Ĥ|²,
/// ```
///
/// `γ²` clamped to `[COHERENCE_FLOOR, 1 − COHERENCE_FLOOR]`. NaN when `|Ĥ|²` or `γ²` is
/// not finite.
pub fn coherence_line_variance(h_abs2: f64, gamma2: f64, n_averages: usize) -> f64 {
    if !(h_abs2.is_finite() && gamma2.is_finite()) || n_averages == 0 {
        return f64::NAN;
    }
    let g = gamma2.clamp(COHERENCE_FLOOR, 1.0 - COHERENCE_FLOOR);
    (1.0 - g) / (n_averages as f64 * g) * h_abs2
}

#[cfg(test)]
mod coherence_variance_tests {
    use super::*;

    /// The formula at a few points worked by hand (to a few units of rounding), and the
    /// clamps.
    #[test]
    fn coherence_variance_is_bendat_and_piersol() {
        let close = |a: f64, b: f64| (a - b).abs() <= 4.0 * f64::EPSILON * b.abs();
        // |H|² = 4, γ² = 0.5, n = 8: 4 × 0.5/(8 × 0.5) = 0.5.
        assert!(close(coherence_line_variance(4.0, 0.5, 8), 0.5));
        // |H|² = 1, γ² = 0.8, n = 5: 0.2/4 = 0.05.
        assert!(close(coherence_line_variance(1.0, 0.8, 5), 0.05));
        // γ² = 1 is taken at g = 1 − 1e-6: (1 − g)/(5 g) (1 − g is 1e-6 only to 1e-10,
        // the rounding of g).
        let g = 1.0 - COHERENCE_FLOOR;
        assert!(close(
            coherence_line_variance(1.0, 1.0, 5),
            (1.0 - g) / (5.0 * g)
        ));
        assert!(((1.0 - g) / (5.0 * g) / (1e-6 / 5.0) - 1.0).abs() < 1e-5);
        assert!(coherence_line_variance(1.0, 0.0, 5).is_finite());
        assert!(coherence_line_variance(f64::NAN, 0.5, 5).is_nan());
    }
}
