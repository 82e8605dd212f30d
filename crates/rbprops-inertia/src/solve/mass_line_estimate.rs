//! The mass-line estimate of `rb-solve`: the mass line (paper Eq. 2) on the band above the
//! rigid-body modes, every excitation jointly, with its standard errors and the truncation
//! bias of the rigid-body tail, refused when too uncertain to report.

use super::{
    diagnostic, distinct, properties_about, uncertainty, EstimateParts, Estimator, SideConstraints,
    SolveOptions, MASS_LINE_MAX_RELATIVE_STD, SHAPE_RESIDUAL_WARNING,
};
use crate::error::InertiaError;
use crate::mass_line::{
    choose_band, mass_line, mass_line_values, MassLineBand, MassLineOptions, MlSolution,
};
use crate::params::N_PARAMS;
use crate::shapes::RigidFrame;
use crate::uncertainty::{property_vector, Propagation, N_PROPS};
use rbprops_core::records::{Diagnostic, DiagnosticKind, DiagnosticSubject, Severity};
use rbprops_core::records::{ModalFitRecord, SelectionRecord};
use rbprops_core::{FrfSource, Geometry};

/// The mass-line estimate (mass line, Eq. 2, on the band above the rigid-body modes, all
/// excitations jointly) with its standard errors, the truncation bias joined to them;
/// refused when the mass is not positive or its standard error above
/// [`MASS_LINE_MAX_RELATIVE_STD`].
#[allow(clippy::too_many_arguments)]
pub(super) fn mass_line_estimate(
    frame: &RigidFrame,
    geometry: &Geometry,
    modal: &ModalFitRecord,
    selection: &SelectionRecord,
    frf: &dyn FrfSource,
    opts: &SolveOptions,
    side: &SideConstraints,
    how: Propagation,
) -> Result<(EstimateParts, MassLineBand), InertiaError> {
    frf.validate()?;
    if frf.n_excitations() != geometry.excitations.len()
        || frf.n_channels() != geometry.channels.len()
    {
        return Err(InertiaError::MassLine(format!(
            "the FRF set has {} excitations × {} channels, the geometry {} × {}",
            frf.n_excitations(),
            frf.n_channels(),
            geometry.excitations.len(),
            geometry.channels.len()
        )));
    }
    let band = choose_band(
        frf,
        highest_rigid_frequency(selection, modal),
        &opts.mass_line,
    )?;
    let ml = mass_line_values(
        frf,
        &band,
        opts.mass_line.rigid_terms,
        opts.mass_line.flex_terms,
    )?;
    let fit = MassLineFit {
        frame,
        excitations: (0..frf.n_excitations()).collect(),
        side,
    };
    let mut warnings = Vec::new();
    if let Some(l) = side.label(None) {
        warnings.push(l);
    }
    warnings.push(band_note(&band));
    let sol = mass_line(frame, &fit.excitations, &ml.values, &side.constraints, None)?;
    if sol.estimate.rank < N_PARAMS && side.nominal.is_none() {
        return Err(InertiaError::Unidentifiable {
            method: "mass_line",
            rank: sol.estimate.rank,
            description: "the excitations' moment arms do not span three independent directions"
                .into(),
        });
    }
    let sol = fit.on(&ml.values)?;
    for (k, r) in sol.rigid_residual.iter().enumerate() {
        if *r > SHAPE_RESIDUAL_WARNING {
            warnings.push(diagnostic(
                DiagnosticKind::ShapeNotRigid,
                Severity::Note,
                DiagnosticSubject::run().excitation(&frame.excitation_ids[k]),
                format!(
                    "the mass line is {:.1} % away from rigid-body motion",
                    100.0 * r
                ),
            ));
        }
    }
    let nch = frf.n_channels();
    let x: Vec<f64> = ml.values.iter().flatten().copied().collect();
    let sigma: Vec<f64> = ml.std.iter().flatten().copied().collect();
    let f = |xs: &[f64]| -> Result<[f64; N_PROPS], InertiaError> {
        let vals: Vec<Vec<f64>> = xs.chunks(nch).map(<[f64]>::to_vec).collect();
        Ok(fit.properties(&fit.on(&vals)?))
    };
    let (mut std, method) = uncertainty(f, &x, &sigma, how, &mut warnings);
    if band.automatic {
        fit.add_truncation_bias(frf, &band, &opts.mass_line, &sol, &mut std, &mut warnings);
    }
    check_mass_line_reliable(&sol, std.as_ref(), &band)?;
    let setup = distinct(geometry.excitations.iter().map(|e| e.setup.clone())).join("+");
    Ok((
        EstimateParts {
            method: Estimator::MassLine.method(),
            setup,
            mass_matrix: sol.estimate.mass_matrix,
            std,
            uncertainty_method: method,
            mount_stiffness: None,
            residual: sol.estimate.residual,
            modes_used: Vec::new(),
            excitations_used: frame.excitation_ids.clone(),
            warnings,
            check: None,
            systematic: None,
        },
        band,
    ))
}

/// The highest rigid-body mode: the selected and missing modes' highest frequency, else
/// the highest identified mode (the mass-line band starts above it).
pub(super) fn highest_rigid_frequency(selection: &SelectionRecord, modal: &ModalFitRecord) -> f64 {
    let highest_rigid = selection
        .selected
        .iter()
        .map(|s| s.frequency_hz)
        .chain(selection.missing.iter().map(|m| m.frequency_hz))
        .fold(f64::NAN, f64::max);
    if highest_rigid.is_finite() {
        highest_rigid
    } else {
        modal
            .modes
            .iter()
            .map(|m| m.frequency_hz)
            .fold(0.0, f64::max)
    }
}

/// The note saying which band the mass line used and how it was found.
pub(super) fn band_note(band: &MassLineBand) -> Diagnostic {
    diagnostic(
        DiagnosticKind::MassLineBand,
        Severity::Note,
        DiagnosticSubject::run(),
        format!(
            "mass-line band {:.4}–{:.4} Hz ({} lines, {})",
            band.lo_hz,
            band.hi_hz,
            band.n_lines,
            if band.automatic {
                match band.first_elastic_hz {
                    Some(fe) => format!("automatic; first elastic resonance near {fe:.4} Hz"),
                    None => {
                        "automatic; no elastic resonance found below the top of the data".into()
                    }
                }
            } else {
                "given".into()
            }
        ),
    )
}

/// A mass line fitted on a band too short or too noisy gives numbers that look like an
/// estimate (even a negative mass): refused instead of reported.
pub(super) fn check_mass_line_reliable(
    sol: &MlSolution,
    std: Option<&[f64; N_PROPS]>,
    band: &MassLineBand,
) -> Result<(), InertiaError> {
    let m = sol.estimate.mass_matrix.mass();
    let sd_m = std.map(|s| s[0]).unwrap_or(0.0);
    if !(m > 0.0) || !sd_m.is_finite() || sd_m > MASS_LINE_MAX_RELATIVE_STD * m {
        return Err(InertiaError::MassLine(format!(
            "mass line unreliable on {:.3}–{:.3} Hz: m = {m:.4} ± {:.2e} kg (more than {:.0} % standard error); \
             the band between the rigid-body and the first elastic modes is too short or too noisy — give one with --mass-line-band",
            band.lo_hz,
            band.hi_hz,
            sd_m,
            100.0 * MASS_LINE_MAX_RELATIVE_STD
        )));
    }
    Ok(())
}

/// The mass-line solve of one estimate: every excitation, the side constraints and the
/// nominal values applied.
pub(super) struct MassLineFit<'a> {
    pub(super) frame: &'a RigidFrame,
    pub(super) excitations: Vec<usize>,
    pub(super) side: &'a SideConstraints,
}

impl MassLineFit<'_> {
    pub(super) fn on(&self, values: &[Vec<f64>]) -> Result<MlSolution, InertiaError> {
        mass_line(
            self.frame,
            &self.excitations,
            values,
            &self.side.constraints,
            self.side.nominal.as_ref(),
        )
    }

    /// The ten properties about the frame's origin.
    pub(super) fn properties(&self, sol: &MlSolution) -> [f64; N_PROPS] {
        property_vector(&properties_about(
            &sol.estimate.mass_matrix,
            &self.frame.origin,
        ))
    }

    /// Truncation bias of the rigid-body tail: the rigid modes' 1/ω^{2k} terms beyond the
    /// fitted ones (and the stiffness they stand for) bias `a0` most at the band's low end,
    /// where the band starts only `rigid_factor` × above the highest rigid mode. The same
    /// fit on the band starting 1.5× higher (or at the band's geometric middle when the
    /// band is shorter) has a smaller such bias (the tail falls as (f_r/f)^{2(R+1)}); the
    /// difference estimates it and joins the standard errors `std` (a warning when the
    /// shifted band gives no fit).
    pub(super) fn add_truncation_bias(
        &self,
        frf: &dyn FrfSource,
        band: &MassLineBand,
        opts: &MassLineOptions,
        sol: &MlSolution,
        std: &mut Option<[f64; N_PROPS]>,
        warnings: &mut Vec<Diagnostic>,
    ) {
        let hi_band = MassLineBand {
            lo_hz: (band.lo_hz * 1.5).min((band.lo_hz * band.hi_hz).sqrt()),
            ..band.clone()
        };
        let shifted = mass_line_values(frf, &hi_band, opts.rigid_terms, opts.flex_terms)
            .ok()
            .and_then(|v| self.on(&v.values).ok());
        let Some(s2) = shifted else {
            warnings.push(diagnostic(
                DiagnosticKind::UncertaintyIncomplete,
                Severity::Warning,
                DiagnosticSubject::run(),
                format!(
                    "mass-line truncation bias not estimated (no usable band from {:.4} Hz); the standard errors are noise only",
                    hi_band.lo_hz
                ),
            ));
            return;
        };
        let Some(sd) = std.as_mut() else {
            return;
        };
        let a = self.properties(sol);
        let b = self.properties(&s2);
        // Richardson: a bias ∝ f_lo^{−2(R+1)} (the first unfitted tail term) changes by
        // the fraction 1 − (f_lo/f_lo')^{2(R+1)} between the two bands.
        let p = 2.0 * (opts.rigid_terms as f64 + 1.0);
        let frac = 1.0 - (band.lo_hz / hi_band.lo_hz).powf(p);
        for k in 0..N_PROPS {
            sd[k] = sd[k].hypot((a[k] - b[k]) / frac);
        }
        warnings.push(diagnostic(
            DiagnosticKind::MassLineBand,
            Severity::Note,
            DiagnosticSubject::run(),
            format!(
                "mass-line truncation bias estimated from a band starting at {:.4} Hz instead: m changes by {:.3e} kg, i.e. a bias of about {:.3e} kg at this band; added to the standard errors",
                hi_band.lo_hz,
                b[0] - a[0],
                (a[0] - b[0]) / frac
            ),
        ));
    }
}
