//! The correction of a modal fit for an exponential response window: the poles a fit
//! finds in windowed FRFs moved back to the physical ones. A transform of FRFs and modal
//! records, not a fit (the fits are rbprops-modal's); `modal-fit` applies it to the fit it
//! writes and the bootstrap of rbprops-uq undoes it to resample the windowed data.

use crate::records::{ModalFitRecord, WindowCorrectionRecord};
use crate::{c64, CoreError, FrfSet};

/// The correction for an exponential window `w(t) = e^{−t/τ}` applied to the response
/// records (and to the force records, or to a force pulse short against τ) before the FRFs
/// were computed: the window's τ and what it does to the FRFs and the poles. (The
/// simulator's effect that applies such a window is `rbprops_sim`'s `exponential_window`.)
///
/// For a transient inside the record the transform of a windowed signal is its Laplace
/// transform at `s = iω + σ` with `σ = 1/τ`, and the force's window cancels, so a measured
/// FRF of quantity order k (receptance 0, mobility 1, accelerance 2) is
///
/// ```text
///   D_w(ω) = (iω + σ)^k H(iω + σ),   H(s) = Σ_r R_r/(s − λ_r) + R_r*/(s − λ_r*).
/// ```
///
/// Each mode's impulse response `R e^{λt}` becomes `R e^{(λ − σ)t}`: every pole moves to
/// `λ − σ` (its decay rate `ζω_r` grows by σ, the damped frequency `ω_d` is kept) and the
/// pole–residue residue `R` is unchanged. Since the receptance-form modal constant of
/// `docs/conventions` (README "Conventions"), `A/(ω_r² − ω² + 2iζ_rω_rω)`, is `A = 2iω_d R`
/// and `ω_d` is kept, `A` is unchanged too.
///
/// The quantity factor `(iω + σ)^k` is not the `(iω)^k` a modal fit assumes, so the fit is
/// given [`WindowCorrection::prefilter`]ed data `(iω/(iω + σ))^k D_w = (iω)^k H(iω + σ)`:
/// exactly a modal model (with the same residual terms) of poles `λ − σ` and residues `R`.
/// The fitted poles are then moved back by [`WindowCorrection::corrected_pole`].
/// Residual terms: the upper residual (a flexibility, an impulse at t = 0) is not changed by
/// a window; the lower ones (modes below the band) are modes like the others and move
/// with them. The accelerance mass line `lim s²H(s) = S M⁻¹ F` (the band-limited fit of
/// `Re D_w = a0 + Σ b_k/ω^{2k}`, even in ω because `D_w(−ω) = D_w(ω)*`) is unchanged.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindowCorrection {
    /// τ (s).
    pub time_constant_s: f64,
}

impl WindowCorrection {
    /// A window of time constant `tau` (s); refuses non-positive or non-finite values.
    pub fn new(tau: f64) -> Result<Self, CoreError> {
        if tau.is_finite() && tau > 0.0 {
            Ok(Self {
                time_constant_s: tau,
            })
        } else {
            Err(CoreError::NonFinite {
                what: "exponential window time constant τ (s) must be positive and finite".into(),
                value: tau,
            })
        }
    }

    /// `σ = 1/τ` (1/s).
    pub fn decay_per_s(&self) -> f64 {
        1.0 / self.time_constant_s
    }

    /// The pole `(f, ζ)` a mode of natural frequency `f_hz` and damping `zeta` shows in
    /// windowed data: `λ − σ`.
    pub fn windowed_pole(&self, f_hz: f64, zeta: f64) -> (f64, f64) {
        let wr = 2.0 * std::f64::consts::PI * f_hz;
        let decay = zeta * wr + self.decay_per_s();
        let wd = wr * (1.0 - zeta * zeta).max(0.0).sqrt();
        pole_from_parts(decay, wd)
    }

    /// The physical pole of a mode fitted as `(f_hz, zeta)` on windowed data: `μ + σ`,
    /// with `ω_d` kept, `ω_r = √(ω_d² + (ζ'ω'_r − σ)²)`, `ζ = (ζ'ω'_r − σ)/ω_r`. A fitted decay
    /// rate below σ (the window said to have damped more than the data show) gives a
    /// negative ζ, returned as is so the caller can say so.
    pub fn corrected_pole(&self, f_hz: f64, zeta: f64) -> (f64, f64) {
        let wr = 2.0 * std::f64::consts::PI * f_hz;
        let decay = zeta * wr - self.decay_per_s();
        let wd = wr * (1.0 - zeta * zeta).max(0.0).sqrt();
        pole_from_parts(decay, wd)
    }

    /// `(iω/(iω + σ))^k · D_w`: windowed FRFs of quantity order k turned into `(iω)^k H(iω+σ)`,
    /// which a modal fit models exactly (see the type's documentation). Receptance is
    /// returned unchanged.
    pub fn prefilter(&self, frf: &FrfSet) -> FrfSet {
        let k = frf.quantity.order();
        let mut out = frf.clone();
        if k == 0 {
            return out;
        }
        let sigma = self.decay_per_s();
        let nl = frf.n_lines();
        let factors: Vec<c64> = frf
            .frequency_hz
            .iter()
            .map(|&f| {
                let s = c64::new(0.0, 2.0 * std::f64::consts::PI * f);
                (s / (s + sigma)).powi(k)
            })
            .collect();
        for (i, v) in out.values.iter_mut().enumerate() {
            *v *= factors[i % nl];
        }
        out
    }
}

/// An [`FrfSource`](crate::FrfSource) whose excitations come [`WindowCorrection::prefilter`]ed,
/// one at a time as they are asked for (the prefiltered set is never made whole).
pub struct Prefiltered<'a> {
    /// The window whose damping is taken out.
    pub window: &'a WindowCorrection,
    /// The windowed FRFs.
    pub frf: &'a dyn crate::FrfSource,
}

impl crate::FrfSource for Prefiltered<'_> {
    fn quantity(&self) -> crate::Quantity {
        self.frf.quantity()
    }
    fn frequency_hz(&self) -> &[f64] {
        self.frf.frequency_hz()
    }
    fn n_excitations(&self) -> usize {
        self.frf.n_excitations()
    }
    fn n_channels(&self) -> usize {
        self.frf.n_channels()
    }
    fn validate(&self) -> Result<(), crate::CoreError> {
        self.frf.validate()
    }
    fn excitation(&self, e: usize) -> Result<crate::ExcitationFrf<'_>, crate::CoreError> {
        let one = self.frf.excitation(e)?.into_set();
        Ok(crate::ExcitationFrf::owned(self.window.prefilter(&one)))
    }
}

impl WindowCorrection {
    /// Moves every pole of a modal fit made on [`WindowCorrection::prefilter`]ed windowed
    /// data back to the physical pole (modal constants unchanged, see the type's
    /// documentation) and marks the record, so the correction is never applied twice: a
    /// record that already carries a correction is an error. The damping standard error
    /// scales with `ω'_r/ω_r` (the decay-rate error is the fit's; σ is exact). A fitted decay
    /// rate below σ cannot be corrected: the damping is set to 0 and the mode says why.
    pub fn correct_modal_fit(
        &self,
        rec: &mut ModalFitRecord,
        source: &str,
    ) -> Result<(), CoreError> {
        if let Some(w) = &rec.window_correction {
            return Err(CoreError::Processing(format!(
                "the modal fit was already corrected for an exponential window (τ = {} s, from {}); it is not corrected twice",
                w.time_constant_s, w.source
            )));
        }
        for m in &mut rec.modes {
            let (f, z) = self.corrected_pole(m.frequency_hz, m.damping_ratio);
            if z < 0.0 {
                m.warnings.push(format!(
                    "the fitted decay rate ζω_r = {:.4} 1/s is below the window's 1/τ = {:.4} 1/s: τ = {} s is too short for these data (or they were not windowed); the damping is set to 0",
                    m.damping_ratio * 2.0 * std::f64::consts::PI * m.frequency_hz,
                    self.decay_per_s(),
                    self.time_constant_s
                ));
            }
            m.damping_std *= m.frequency_hz / f;
            m.frequency_hz = f;
            m.damping_ratio = z.max(0.0);
        }
        for e in &mut rec.excitations {
            e.warnings.push(format!(
                "poles corrected for an exponential window τ = {} s ({}): each decay rate ζω_r reduced by 1/τ = {:.6} 1/s",
                self.time_constant_s,
                source,
                self.decay_per_s()
            ));
        }
        rec.window_correction = Some(WindowCorrectionRecord {
            time_constant_s: self.time_constant_s,
            source: source.into(),
        });
        Ok(())
    }

    /// The inverse of [`WindowCorrection::correct_modal_fit`]: the record's poles as the
    /// windowed data show them (for resampling those data), without the mark. `None` when
    /// the record carries no correction.
    pub fn windowed_modal_fit(rec: &ModalFitRecord) -> Option<(Self, ModalFitRecord)> {
        let wc = rec.window_correction.as_ref()?;
        let w = Self {
            time_constant_s: wc.time_constant_s,
        };
        let mut out = rec.clone();
        out.window_correction = None;
        for m in &mut out.modes {
            let (f, z) = w.windowed_pole(m.frequency_hz, m.damping_ratio);
            m.damping_std *= m.frequency_hz / f;
            m.frequency_hz = f;
            m.damping_ratio = z;
        }
        let mark = "poles corrected for an exponential window";
        for e in &mut out.excitations {
            e.warnings.retain(|w| !w.starts_with(mark));
        }
        Some((w, out))
    }
}

/// `(f_hz, ζ)` of the pole `−decay + iω_d`.
fn pole_from_parts(decay: f64, wd: f64) -> (f64, f64) {
    let wr = wd.hypot(decay);
    (wr / (2.0 * std::f64::consts::PI), decay / wr)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Prefiltering each excitation as it is asked for gives the whole set's prefilter
    /// to the bit.
    #[test]
    fn each_excitation_prefiltered_is_the_set_prefiltered() {
        use crate::{FrfSet, FrfSource, Quantity};
        let mut s = FrfSet::zeros(Quantity::Accelerance, vec![0.5, 1.0, 2.5, 7.0], 3, 2);
        for (i, v) in s.values.iter_mut().enumerate() {
            *v = c64::new(1.0 + i as f64, -0.3 * i as f64);
        }
        let w = WindowCorrection::new(4.0).unwrap();
        let whole = w.prefilter(&s);
        let p = Prefiltered {
            window: &w,
            frf: &s,
        };
        for e in 0..3 {
            assert_eq!(p.excitation(e).unwrap().block(), whole.excitation_block(e));
        }
    }
    /// Exact pole shift: the impulse response of a windowed mode is `R e^{(λ − σ)t}`;
    /// windowed_pole is checked against the pole written from that definition, and
    /// corrected_pole inverts it to rounding.
    #[test]
    fn window_moves_every_pole_by_minus_one_over_tau() {
        let w = WindowCorrection::new(8.0).unwrap();
        for (f, z) in [(0.51, 0.02), (1.7, 0.001), (12.0, 0.05), (0.05, 0.3)] {
            let wr = 2.0 * std::f64::consts::PI * f;
            let lam = c64::new(-z * wr, wr * (1.0f64 - z * z).sqrt());
            let mu = lam - 0.125;
            let (fw, zw) = w.windowed_pole(f, z);
            let wrw = 2.0 * std::f64::consts::PI * fw;
            let got = c64::new(-zw * wrw, wrw * (1.0 - zw * zw).sqrt());
            assert!(
                (got - mu).norm() < 1e-14 * mu.norm(),
                "{f} {z}: {got} vs {mu}"
            );
            let (fc, zc) = w.corrected_pole(fw, zw);
            assert!((fc - f).abs() < 1e-14 * f, "{fc} vs {f}");
            assert!((zc - z).abs() < 1e-13 * z.max(1e-3), "{zc} vs {z}");
        }
        assert!(WindowCorrection::new(0.0).is_err());
        assert!(WindowCorrection::new(f64::NAN).is_err());
    }

    /// The prefiltered windowed accelerance equals the modal model with shifted poles and
    /// unchanged modal constants, line by line (an exact identity, not a fit).
    #[test]
    fn prefiltered_windowed_accelerance_is_a_modal_model_of_the_shifted_poles() {
        let w = WindowCorrection::new(4.0).unwrap();
        let sigma = w.decay_per_s();
        let modes = [(0.6, 0.02, 1.3), (1.1, 0.01, -0.4), (2.5, 0.03, 0.8)];
        let hz: Vec<f64> = (0..200).map(|i| 0.02 * i as f64).collect();
        let mut frf = FrfSet::zeros(crate::Quantity::Accelerance, hz.clone(), 1, 1);
        let h_of = |s: c64| -> c64 {
            modes
                .iter()
                .map(|&(f, z, a)| {
                    let wr = 2.0 * std::f64::consts::PI * f;
                    c64::new(a, 0.0) / (s * s + 2.0 * z * wr * s + wr * wr)
                })
                .sum()
        };
        for (l, &f) in hz.iter().enumerate() {
            let s = c64::new(sigma, 2.0 * std::f64::consts::PI * f);
            frf.frf_mut(0, 0)[l] = s * s * h_of(s);
        }
        let pre = w.prefilter(&frf);
        for (l, &f) in hz.iter().enumerate() {
            let om = 2.0 * std::f64::consts::PI * f;
            let model: c64 = modes
                .iter()
                .map(|&(fr, z, a)| {
                    let (fw, zw) = w.windowed_pole(fr, z);
                    let wr = 2.0 * std::f64::consts::PI * fw;
                    // A/(ω_r'² − ω² + 2iζ'ω_r'ω) with the receptance form's A unchanged.
                    c64::new(a, 0.0) / c64::new(wr * wr - om * om, 2.0 * zw * wr * om)
                })
                .sum::<c64>()
                * (-om * om);
            let got = pre.frf(0, 0)[l];
            assert!(
                (got - model).norm() <= 1e-12 * model.norm().max(1e-300),
                "{f} Hz: {got} vs {model}"
            );
        }
    }
}
