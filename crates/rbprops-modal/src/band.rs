//! The data one fit works on: the lines of a band and the FRFs of a set of channels.

use crate::ModalError;
use rbprops_core::{c64, FrfSet, Quantity};
use std::f64::consts::PI;

/// FRFs of several channels on one band (any quantity, any axis).
#[derive(Debug, Clone)]
pub struct BandData {
    /// Receptance, mobility or accelerance, as measured.
    pub quantity: Quantity,
    /// Frequency of every line (Hz), ascending.
    pub frequency_hz: Vec<f64>,
    /// `ω = 2πf`, rad/s.
    pub omega: Vec<f64>,
    /// `[channel][line]` in the measured quantity.
    pub channels: Vec<Vec<c64>>,
    /// Index of the band's first line in the full axis.
    pub first_line: usize,
    /// Measured-quality factor of each line multiplying the fits' default weights
    /// (`crate::weighting`); `None`: default weights.
    pub line_quality: Option<Vec<f64>>,
}

impl BandData {
    /// [`Self::extract`] of excitation `e` of a source: its values are asked for, the
    /// band copied out and the rest let go (a reader's excitation is not held beyond).
    pub fn extract_from(
        frf: &dyn rbprops_core::FrfSource,
        e: usize,
        band: Option<(f64, f64)>,
        name: &str,
    ) -> Result<Self, ModalError> {
        let x = frf
            .excitation(e)
            .map_err(|err| ModalError::Source(err.to_string()))?;
        Self::extract(x.set(), x.index(), band, name)
    }

    /// Lines of excitation `e` inside `band` (Hz, inclusive). Refuses empty bands and
    /// non-finite values, naming the channel and line.
    pub fn extract(
        frf: &FrfSet,
        e: usize,
        band: Option<(f64, f64)>,
        name: &str,
    ) -> Result<Self, ModalError> {
        let bad = |reason: String| ModalError::BadInput {
            excitation: name.to_string(),
            reason,
        };
        let axis = &frf.frequency_hz;
        let (lo, hi) = band.unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
        let inside = |l: usize| axis[l] >= lo && axis[l] <= hi;
        let Some(first) = (0..axis.len()).find(|&l| inside(l)) else {
            return Err(bad(format!(
                "band [{lo}, {hi}] Hz holds no spectral line (axis {} to {} Hz)",
                axis.first().copied().unwrap_or(f64::NAN),
                axis.last().copied().unwrap_or(f64::NAN)
            )));
        };
        // The lines inside must be one run (a sorted axis); then each channel is a slice.
        let end = (first..axis.len())
            .find(|&l| !inside(l))
            .unwrap_or(axis.len());
        if (end..axis.len()).any(inside) {
            return Err(bad("frequency axis is not sorted".into()));
        }
        let mut channels = Vec::with_capacity(frf.n_channels);
        for c in 0..frf.n_channels {
            let v = frf.frf(e, c)[first..end].to_vec();
            if let Some(k) = v
                .iter()
                .position(|z| !(z.re.is_finite() && z.im.is_finite()))
            {
                return Err(bad(format!(
                    "channel {c}, line {} ({} Hz): value {} is not finite",
                    first + k,
                    axis[first + k],
                    v[k]
                )));
            }
            channels.push(v);
        }
        let frequency_hz = axis[first..end].to_vec();
        if let Some(w) = frequency_hz.windows(2).find(|w| !(w[1] > w[0])) {
            return Err(bad(format!(
                "frequency axis does not increase ({} then {} Hz)",
                w[0], w[1]
            )));
        }
        Ok(Self {
            quantity: frf.quantity,
            omega: frequency_hz.iter().map(|f| 2.0 * PI * f).collect(),
            frequency_hz,
            channels,
            first_line: first,
            line_quality: None,
        })
    }

    /// This band with the coherence factors of `excitations` (`crate::weighting`), when
    /// `weighting` is given and they have coherence; unchanged otherwise.
    pub fn with_line_factors(
        mut self,
        weighting: Option<&crate::weighting::CoherenceWeighting>,
        excitations: &[usize],
    ) -> Self {
        if let Some(q) = weighting.and_then(|w| w.line_factors(excitations)) {
            self.line_quality = Some(q[self.first_line..self.first_line + self.n_lines()].to_vec());
        }
        self
    }

    /// The lines up to `f_hi` Hz (a sub-band for pole estimation).
    pub fn up_to(&self, f_hi: f64) -> BandData {
        let n = self.frequency_hz.partition_point(|&f| f <= f_hi);
        BandData {
            quantity: self.quantity,
            frequency_hz: self.frequency_hz[..n].to_vec(),
            omega: self.omega[..n].to_vec(),
            channels: self.channels.iter().map(|h| h[..n].to_vec()).collect(),
            first_line: self.first_line,
            line_quality: self.line_quality.as_ref().map(|q| q[..n].to_vec()),
        }
    }

    /// Indices of every `stride`-th line of `n` (always keeping the first and the
    /// last), so that at most about `max_lines` remain; all lines when `n <= max_lines`.
    ///
    /// Why: the LSCF stabilisation sweep needs a few lines per half-power bandwidth, not
    /// every line of a 4,096-line spectrum, and its sums cost linear in the lines. (The
    /// refinement uses [`Self::focus_indices`] instead, which keeps every line near a
    /// pole; this is its even skeleton.)
    pub fn decimation_indices(n: usize, max_lines: usize) -> Vec<usize> {
        let stride = n.div_ceil(max_lines.max(2)).max(1);
        let mut keep: Vec<usize> = (0..n).step_by(stride).collect();
        if n > 0 && *keep.last().unwrap() != n - 1 {
            keep.push(n - 1);
        }
        keep
    }

    /// Lines for the pole refinement: around each pole `λ_r`, the lines within
    /// `half_widths` half-power half-bandwidths `σ_r = −Re λ_r` of its damped frequency,
    /// at least `per_half_width` of them per `σ_r`; elsewhere `skeleton` evenly spaced
    /// lines (first and last always kept).
    ///
    /// Why: the Fisher information on a pole comes from its resonance. With one mode
    /// dominating, `|∂H/∂λ|²/|H|² = 1/|iω − λ|²`, so lines beyond `x` half-bandwidths
    /// carry a fraction `≈ 2/(πx)` of it (6 % at x = 10, 3 % at 20), while they make
    /// up most of a baseband spectrum. The skeleton keeps the far field for the residual
    /// terms and the damping-independent part of the fit.
    pub fn focus_indices(
        &self,
        poles: &[crate::pole::Pole],
        half_widths: f64,
        per_half_width: f64,
        skeleton: usize,
    ) -> Vec<usize> {
        let n = self.n_lines();
        let mut keep = vec![false; n];
        for k in Self::decimation_indices(n, skeleton) {
            keep[k] = true;
        }
        if n > 1 {
            let spacing = (self.omega[n - 1] - self.omega[0]) / (n - 1) as f64;
            for p in poles {
                let sigma = p.half_bandwidth().max(spacing);
                let (lo, hi) = (p.0.im - half_widths * sigma, p.0.im + half_widths * sigma);
                let a = self.omega.partition_point(|&w| w < lo);
                let b = self.omega.partition_point(|&w| w <= hi);
                let stride = ((sigma / (per_half_width * spacing)).floor() as usize).max(1);
                for k in (a..b).step_by(stride) {
                    keep[k] = true;
                }
            }
        }
        (0..n).filter(|&k| keep[k]).collect()
    }

    /// The given lines (ascending indices into this band).
    pub fn lines(&self, keep: &[usize]) -> BandData {
        BandData {
            quantity: self.quantity,
            frequency_hz: keep.iter().map(|&k| self.frequency_hz[k]).collect(),
            omega: keep.iter().map(|&k| self.omega[k]).collect(),
            channels: self
                .channels
                .iter()
                .map(|h| keep.iter().map(|&k| h[k]).collect())
                .collect(),
            first_line: self.first_line,
            line_quality: self
                .line_quality
                .as_ref()
                .map(|q| keep.iter().map(|&k| q[k]).collect()),
        }
    }

    /// Number of frequency lines.
    pub fn n_lines(&self) -> usize {
        self.omega.len()
    }

    /// Root-mean-square magnitude of each channel (0 for an all-zero channel).
    pub fn channel_rms(&self) -> Vec<f64> {
        self.channels
            .iter()
            .map(|h| (h.iter().map(|z| z.norm_sqr()).sum::<f64>() / h.len() as f64).sqrt())
            .collect()
    }

    /// `(iω)^k` of the measured quantity relative to receptance, per line.
    pub fn quantity_factor(&self) -> Vec<c64> {
        self.omega
            .iter()
            .map(|&w| self.quantity.from_receptance_factor(w))
            .collect()
    }

    /// First and last frequency of the band (Hz).
    pub fn band_hz(&self) -> [f64; 2] {
        [self.frequency_hz[0], *self.frequency_hz.last().unwrap()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rbprops_core::Quantity;

    /// Two excitations × two channels, value `100·e + 10·c + line` at each line.
    fn set(axis: Vec<f64>) -> FrfSet {
        let n = axis.len();
        let values = (0..2)
            .flat_map(|e| (0..2).flat_map(move |c| (0..n).map(move |l| (e, c, l))))
            .map(|(e, c, l)| c64::new((100 * e + 10 * c + l) as f64, 0.5))
            .collect();
        FrfSet {
            quantity: Quantity::Receptance,
            frequency_hz: axis,
            n_excitations: 2,
            n_channels: 2,
            values,
        }
    }

    #[test]
    fn extract_takes_the_lines_inside_the_band_and_refuses_the_rest() {
        let frf = set((0..10).map(|l| l as f64).collect());
        let b = BandData::extract(&frf, 1, Some((2.5, 6.0)), "E").unwrap();
        assert_eq!(
            (b.first_line, b.frequency_hz.clone()),
            (3, vec![3.0, 4.0, 5.0, 6.0])
        );
        assert_eq!(
            b.channels[1],
            (3..7)
                .map(|l| c64::new((110 + l) as f64, 0.5))
                .collect::<Vec<_>>()
        );
        assert_eq!(b.omega[0], 2.0 * PI * 3.0);
        let whole = BandData::extract(&frf, 0, None, "E").unwrap();
        assert_eq!((whole.first_line, whole.n_lines()), (0, 10));
        let empty = BandData::extract(&frf, 0, Some((20.0, 30.0)), "E").unwrap_err();
        assert!(
            empty.to_string().contains("holds no spectral line"),
            "{empty}"
        );
        let unsorted = set(vec![0.0, 1.0, 5.0, 2.0, 3.0]);
        let err = BandData::extract(&unsorted, 0, Some((0.5, 3.5)), "E").unwrap_err();
        assert!(err.to_string().contains("not sorted"), "{err}");
        let mut nan = set((0..5).map(|l| l as f64).collect());
        nan.frf_mut(1, 0)[3] = c64::new(f64::NAN, 0.0);
        let err = BandData::extract(&nan, 1, Some((1.0, 4.0)), "E").unwrap_err();
        assert!(
            err.to_string().contains("channel 0, line 3 (3 Hz)"),
            "{err}"
        );
    }
}
