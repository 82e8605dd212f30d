//! The records of one excitation, whichever estimator produced its poles and residues:
//! modal constants in the receptance form of docs/conventions.md, standard errors, fit
//! error per channel, warnings and the stabilisation diagram.

use super::{ExcitationDiagnostics, ExcitationFit, MultiplicityWarning};
use crate::band::BandData;
use crate::linalg;
use crate::options::FitOptions;
use crate::pole::{mpc, Pole};
use crate::stabilisation::StabilisationDiagram;
use rbprops_core::c64;
use rbprops_core::records::{ExcitationFitRecord, ModeEstimate};

/// What one excitation's records are made of, whichever estimator produced them.
pub(crate) struct ModeParts {
    /// Poles, ascending frequency.
    pub poles: Vec<Pole>,
    /// Standard deviations of (f Hz, ζ) per pole.
    pub std: Vec<(f64, f64)>,
    pub confidence: Vec<f64>,
    pub mode_warnings: Vec<Vec<String>>,
    /// Modal constants `A` (1/kg) per mode and channel, and their standard errors.
    pub modal_constants: Vec<Vec<c64>>,
    pub modal_constant_std: Vec<Vec<f64>>,
    /// Fitted FRFs `[channel][line]` in the measured quantity.
    pub synthesised: Vec<Vec<c64>>,
    /// The fit error per channel ([`fit_error`]), when made before the records (then
    /// `synthesised` may be empty).
    pub fit_error: Option<Vec<f64>>,
    pub warnings: Vec<String>,
    /// The multiplicity warnings among `warnings`, in order.
    pub multiplicity: Vec<MultiplicityWarning>,
    pub diagram: StabilisationDiagram,
}

/// The fit error of each channel of `band`: `‖h − ĥ‖² / ‖h‖²` against the fitted FRFs
/// `synthesised` (0 for a channel that is zero in the band).
pub(crate) fn fit_error(band: &BandData, synthesised: &[Vec<c64>]) -> Vec<f64> {
    band.channels
        .iter()
        .zip(synthesised)
        .map(|(h, s)| {
            let (meas, err) = (linalg::cdot(h, h), linalg::cdist_sqr(h, s));
            if meas > 0.0 {
                err / meas
            } else {
                0.0
            }
        })
        .collect()
}

/// The records of one excitation: fit error per channel, each mode's peak Norm
/// Indicator relative to the strongest (weak flags), and the plot data.
pub(crate) fn assemble(
    ex: &rbprops_core::Excitation,
    band: &BandData,
    mut parts: ModeParts,
    opts: &FitOptions,
    method: rbprops_core::records::FitMethod,
) -> ExcitationFit {
    let name = ex.id.as_str();
    let nm = parts.poles.len();
    let k = band.quantity.order();
    let fit_error = match parts.fit_error.take() {
        Some(e) => e,
        None => fit_error(band, &parts.synthesised),
    };

    // Peak Norm Indicator of each mode alone in the measured quantity.
    let ni: Vec<f64> = (0..nm)
        .map(|m| {
            let w = parts.poles[m].omega_n();
            let na = parts.modal_constants[m]
                .iter()
                .map(|z| z.norm_sqr())
                .sum::<f64>()
                .sqrt();
            na * w.powi(k) / (2.0 * parts.poles[m].damping().max(1e-12) * w * w)
        })
        .collect();
    let ni_max = ni.iter().cloned().fold(0.0, f64::max);
    let mut modes = Vec::with_capacity(nm);
    for m in 0..nm {
        let mut mw = parts.mode_warnings[m].clone();
        let rel_db = if ni_max > 0.0 && ni[m] > 0.0 {
            20.0 * (ni[m] / ni_max).log10()
        } else {
            f64::NEG_INFINITY
        };
        let na = parts.modal_constants[m]
            .iter()
            .map(|z| z.norm_sqr())
            .sum::<f64>()
            .sqrt();
        let ns = parts.modal_constant_std[m]
            .iter()
            .map(|s| s * s)
            .sum::<f64>()
            .sqrt();
        let mut weak = false;
        if rel_db < -opts.weak_below_db {
            weak = true;
            mw.push(format!(
                "barely excited: peak NI {rel_db:.1} dB below the excitation's strongest mode"
            ));
        }
        if ns > na / 3.0 {
            weak = true;
            mw.push(format!(
                "residue vector uncertain: ‖σ_A‖ = {ns:.3e} vs ‖A‖ = {na:.3e}"
            ));
        }
        modes.push(ModeEstimate {
            excitation: name.into(),
            setup: ex.setup.clone(),
            mode: m + 1,
            frequency_hz: parts.poles[m].frequency_hz(),
            frequency_std_hz: parts.std[m].0,
            damping_ratio: parts.poles[m].damping(),
            damping_std: parts.std[m].1,
            residues: parts.modal_constants[m].clone(),
            residue_std: parts.modal_constant_std[m].clone(),
            confidence: parts.confidence[m].clamp(0.0, 1.0),
            mpc: mpc(&parts.modal_constants[m]),
            weak,
            warnings: mw,
        });
    }
    let record = ExcitationFitRecord {
        excitation: name.into(),
        setup: ex.setup.clone(),
        method,
        model_order: nm,
        band_hz: band.band_hz(),
        n_lines: band.n_lines(),
        fit_error,
        warnings: parts.warnings,
    };
    ExcitationFit {
        record,
        modes,
        diagnostics: ExcitationDiagnostics {
            excitation: name.into(),
            stabilisation: parts.diagram,
            quantity: band.quantity,
            frequency_hz: band.frequency_hz.clone(),
            // Dropped here unless asked for: freed now, its pages serve the next
            // excitation instead of fresh ones (−140 page faults per excitation).
            synthesised: if opts.keep_synthesised {
                parts.synthesised
            } else {
                Vec::new()
            },
            poles_rad_s: parts.poles.iter().map(|p| p.0).collect(),
        },
        multiplicity: parts.multiplicity,
    }
}
