//! The closed sets of names the records carry: how modes were fitted and chosen, which
//! estimator produced an inertia estimate, how its standard errors were obtained.
//!
//! Each is an enum that serialises as the snake_case string the files have always held
//! (`lscf`, `hybrid_mif`, `bretl_conti_projected`, `monte_carlo`, …). Reading any other
//! string fails with an error that names the value and the allowed ones (serde's
//! "unknown variant `x`, expected one of …" for records, [`CoreError::Unknown`] for
//! [`FromStr`]). In the JSON schemas the fields stay plain strings (`#[schemars(with =
//! "String")]` on the record fields), so the published schemas are unchanged.

use crate::CoreError;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// Declares an enum of named values: serde strings, `as_str`, `Display` (padding
/// honoured), `FromStr` (exact names only) and comparison with a `&str`.
macro_rules! named_values {
    (
        $(#[$meta:meta])*
        $name:ident ($kind:literal) {
            $(#[$fmeta:meta])* $first:ident => $first_s:literal
            $(, $(#[$vmeta:meta])* $var:ident => $s:literal)* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, JsonSchema)]
        pub enum $name {
            $(#[$fmeta])*
            #[serde(rename = $first_s)]
            $first,
            $(
                $(#[$vmeta])*
                #[serde(rename = $s)]
                $var,
            )*
        }

        impl $name {
            /// Every value, in declaration order.
            pub const ALL: &'static [$name] = &[$name::$first $(, $name::$var)*];
            /// The allowed names, comma separated (for messages).
            pub const NAMES: &'static str = concat!($first_s $(, ", ", $s)*);

            /// The name written in the records.
            pub fn as_str(self) -> &'static str {
                match self {
                    $name::$first => $first_s,
                    $($name::$var => $s,)*
                }
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.pad(self.as_str())
            }
        }

        impl FromStr for $name {
            type Err = CoreError;
            fn from_str(s: &str) -> Result<Self, CoreError> {
                Self::ALL
                    .iter()
                    .copied()
                    .find(|v| v.as_str() == s)
                    .ok_or_else(|| CoreError::Unknown {
                        kind: $kind,
                        value: s.to_string(),
                        expected: Self::NAMES,
                    })
            }
        }

        impl PartialEq<str> for $name {
            fn eq(&self, other: &str) -> bool {
                self.as_str() == other
            }
        }

        impl PartialEq<&str> for $name {
            fn eq(&self, other: &&str) -> bool {
                self.as_str() == *other
            }
        }
    };
}

named_values! {
    /// The modal identification method of one excitation's fit (`ExcitationFitRecord`).
    FitMethod ("fit method") {
        /// Least-squares complex frequency-domain estimator.
        Lscf => "lscf",
        /// Least-squares complex exponential.
        Lsce => "lsce",
        /// Poly-reference LSCF (PolyMAX).
        Plscf => "plscf",
        /// Kennedy–Pancu circle fit.
        Circle => "circle",
    }
}

named_values! {
    /// How the excitation of a selected mode was chosen (`SelectedMode`).
    SelectionCriterion ("selection criterion") {
        /// Highest Norm Indicator at the mode (paper Eq. 12).
        Ni => "ni",
        /// Deepest hybrid-MIF dip at the mode.
        HybridMif => "hybrid_mif",
        /// Deepest PRF-MIF dip at the mode.
        PrfMif => "prf_mif",
        /// Given by hand (a manual set).
        Manual => "manual",
    }
}

named_values! {
    /// The estimator behind an `InertiaEstimate`; a `…Projected` value is the nearest
    /// physically consistent version of the plain estimate (same mass, CoM and principal
    /// axes, principal moments projected onto the triangle-inequality cone).
    EstimateMethod ("estimate method") {
        /// Paper Eq. (2), six modes.
        BretlConti => "bretl_conti",
        /// Paper Eq. (10), four or more modes.
        ToivolaNuutila => "toivola_nuutila",
        /// Inertia restraint (mass line) from the FRFs.
        MassLine => "mass_line",
        /// [`EstimateMethod::BretlConti`] projected onto the physical cone.
        BretlContiProjected => "bretl_conti_projected",
        /// [`EstimateMethod::ToivolaNuutila`] projected onto the physical cone.
        ToivolaNuutilaProjected => "toivola_nuutila_projected",
        /// [`EstimateMethod::MassLine`] projected onto the physical cone.
        MassLineProjected => "mass_line_projected",
    }
}

impl EstimateMethod {
    /// The estimator itself (a projected estimate's unprojected method).
    pub fn base(self) -> EstimateMethod {
        match self {
            EstimateMethod::BretlContiProjected => EstimateMethod::BretlConti,
            EstimateMethod::ToivolaNuutilaProjected => EstimateMethod::ToivolaNuutila,
            EstimateMethod::MassLineProjected => EstimateMethod::MassLine,
            m => m,
        }
    }

    /// The projected (physically consistent) version of this estimator's estimate.
    pub fn projected(self) -> EstimateMethod {
        match self.base() {
            EstimateMethod::BretlConti => EstimateMethod::BretlContiProjected,
            EstimateMethod::ToivolaNuutila => EstimateMethod::ToivolaNuutilaProjected,
            _ => EstimateMethod::MassLineProjected,
        }
    }

    /// Whether this is a projected estimate.
    pub fn is_projected(self) -> bool {
        self != self.base()
    }
}

named_values! {
    /// How the standard errors of an `InertiaEstimate` were obtained.
    UncertaintyMethod ("uncertainty method") {
        /// Central differences of the whole estimator, one σ per input.
        Linearised => "linearised",
        /// Gaussian draws of the inputs.
        MonteCarlo => "monte_carlo",
        /// FRF-level parametric bootstrap.
        Bootstrap => "bootstrap",
        /// No input standard errors, or the propagation failed: the errors are zero.
        None => "none",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every value ↔ its name through `as_str`/`FromStr` and through serde, and an unknown
    /// name rejected by both with a message naming it and the allowed ones.
    fn round_trip<T>(expected: &[(T, &str)])
    where
        T: Copy
            + PartialEq
            + fmt::Debug
            + fmt::Display
            + FromStr<Err = CoreError>
            + Serialize
            + for<'de> Deserialize<'de>,
    {
        for &(v, s) in expected {
            assert_eq!(v.to_string(), s);
            assert_eq!(s.parse::<T>().unwrap(), v);
            assert_eq!(serde_json::to_string(&v).unwrap(), format!("\"{s}\""));
            assert_eq!(serde_json::from_str::<T>(&format!("\"{s}\"")).unwrap(), v);
        }
        let names: Vec<&str> = expected.iter().map(|(_, s)| *s).collect();
        for bad in ["", "LSCF", "bretl-conti", "not_a_name"] {
            let e = bad.parse::<T>().unwrap_err().to_string();
            assert!(e.contains(&format!("'{bad}'")), "{e}");
            assert!(names.iter().all(|n| e.contains(n)), "{e}");
            let e = serde_json::from_str::<T>(&format!("\"{bad}\""))
                .unwrap_err()
                .to_string();
            assert!(e.contains(&format!("`{bad}`")), "{e}");
            assert!(names.iter().all(|n| e.contains(n)), "{e}");
        }
    }

    #[test]
    fn fit_method_names_round_trip() {
        use FitMethod::*;
        round_trip(&[
            (Lscf, "lscf"),
            (Lsce, "lsce"),
            (Plscf, "plscf"),
            (Circle, "circle"),
        ]);
        assert_eq!(FitMethod::ALL.len(), 4);
    }

    #[test]
    fn selection_criterion_names_round_trip() {
        use SelectionCriterion::*;
        round_trip(&[
            (Ni, "ni"),
            (HybridMif, "hybrid_mif"),
            (PrfMif, "prf_mif"),
            (Manual, "manual"),
        ]);
        assert_eq!(SelectionCriterion::ALL.len(), 4);
    }

    #[test]
    fn estimate_method_names_round_trip() {
        use EstimateMethod::*;
        round_trip(&[
            (BretlConti, "bretl_conti"),
            (ToivolaNuutila, "toivola_nuutila"),
            (MassLine, "mass_line"),
            (BretlContiProjected, "bretl_conti_projected"),
            (ToivolaNuutilaProjected, "toivola_nuutila_projected"),
            (MassLineProjected, "mass_line_projected"),
        ]);
        assert_eq!(EstimateMethod::ALL.len(), 6);
        for &m in EstimateMethod::ALL {
            assert_eq!(m.projected().base(), m.base());
            assert!(m.projected().is_projected());
            assert!(!m.base().is_projected());
            assert_eq!(
                m.projected().as_str(),
                format!("{}_projected", m.base().as_str())
            );
        }
    }

    #[test]
    fn uncertainty_method_names_round_trip() {
        use UncertaintyMethod::*;
        round_trip(&[
            (Linearised, "linearised"),
            (MonteCarlo, "monte_carlo"),
            (Bootstrap, "bootstrap"),
            (None, "none"),
        ]);
        assert_eq!(UncertaintyMethod::ALL.len(), 4);
    }

    #[test]
    fn record_schemas_keep_the_fields_plain_strings() {
        use crate::records::{InertiaEstimate, ModalFitRecord, SelectionRecord};
        let plain = |v: &serde_json::Value, description: &str| {
            assert_eq!(
                *v,
                serde_json::json!({ "description": description, "type": "string" })
            );
        };
        let e = serde_json::to_value(schemars::schema_for!(InertiaEstimate)).unwrap();
        plain(
            &e["properties"]["method"],
            "`bretl_conti`, `toivola_nuutila`, `mass_line`, or one of them with `_projected`\n(the names of [`EstimateMethod`]).",
        );
        plain(
            &e["properties"]["uncertainty_method"],
            "How the standard errors were obtained (`linearised`, `monte_carlo`, `bootstrap`,\n`none`: the names of [`UncertaintyMethod`]).",
        );
        let s = serde_json::to_value(schemars::schema_for!(SelectionRecord)).unwrap();
        plain(
            &s["$defs"]["SelectedMode"]["properties"]["criterion"],
            "`ni`, `hybrid_mif`, `prf_mif` or `manual`.",
        );
        let m = serde_json::to_value(schemars::schema_for!(ModalFitRecord)).unwrap();
        plain(
            &m["$defs"]["ExcitationFitRecord"]["properties"]["method"],
            "`lsce`, `lscf`, `plscf` or `circle` (the names of [`FitMethod`]).",
        );
    }

    #[test]
    fn display_honours_width_as_the_strings_did() {
        assert_eq!(
            format!("[{:<14}]", EstimateMethod::MassLine),
            format!("[{:<14}]", "mass_line")
        );
        assert_eq!(format!("[{:>6}]", FitMethod::Lsce), "[  lsce]");
        assert!(EstimateMethod::MassLine == "mass_line");
        assert!(SelectionCriterion::Ni != "manual");
    }
}

named_values! {
    /// How much a [`crate::records::Diagnostic`] matters to the numbers a stage returns.
    Severity ("severity") {
        /// How the answer was reached (a correctly handled condition): counted, listed on
        /// request.
        Note => "note",
        /// The answer may be wrong or incomplete because of it (a dropped or merged mode,
        /// a fit far above the noise): always shown.
        Warning => "warning",
        /// The answer is different, incomplete or missing because of it (a failed
        /// excitation, a dead channel): always shown.
        ChangesAnswer => "changes_answer",
    }
}

named_values! {
    /// What a [`crate::records::Diagnostic`] is about: one closed set for every stage, each
    /// with one sentence for a test engineer ([`DiagnosticKind::sentence`]).
    DiagnosticKind ("diagnostic kind") {
        /// Two or more modes of a set-up share one frequency (or lie closer than a fit can
        /// separate them): one repeated root.
        RepeatedRoot => "repeated_root",
        /// Two modes closer than two half-power half-bandwidths, resolved.
        CloseModes => "close_modes",
        /// Which fit of a set-up was kept (per-excitation or poly-reference) and why.
        FitChoice => "fit_choice",
        /// One excitation's fit merged modes that another fit of the set-up separates.
        MergedModes => "merged_modes",
        /// A fit lost a mode another fit of the same data found.
        DroppedMode => "dropped_mode",
        /// An excitation's fit error is far above the noise its set-up fits to.
        FitErrorAboveNoise => "fit_error_above_noise",
        /// The misfit is what an exponential window on the responses, not declared to the
        /// fit, would leave.
        UndeclaredWindow => "undeclared_window",
        /// An excitation could not be fitted.
        ExcitationFailed => "excitation_failed",
        /// A channel is identically zero.
        DeadChannel => "dead_channel",
        /// Modes an excitation barely drives.
        WeakModes => "weak_modes",
        /// The pole search adjusted the model (orders, sub-bands, model-order tests).
        PoleSearch => "pole_search",
        /// The poles were corrected for a declared exponential window.
        WindowCorrection => "window_correction",
        /// A set-up's modal record holds no modes at all.
        NoModes => "no_modes",
        /// A rigid-body mode is missing: no excitation identifies or excites it usably.
        ModeMissing => "mode_missing",
        /// More candidate modes than a rigid body has; the least supported were set aside.
        ExtraModes => "extra_modes",
        /// One physical mode fitted as several poles (one shape, two frequencies); merged.
        DuplicatePoles => "duplicate_poles",
        /// A candidate mode or estimate was refused (a copy of another mode's shape, the
        /// least evidence among too many, a worse duplicate).
        ModeRejected => "mode_rejected",
        /// The evidence does not clearly decide between a kept and a rejected mode.
        UndecidedModes => "undecided_modes",
        /// A kept mode is supported only by weak or unexcited estimates.
        SpuriousMode => "spurious_mode",
        /// Set-ups forced together by the user.
        SetupsForced => "setups_forced",
        /// The manual selection left a mode out or chose an unreliable estimate.
        ManualSelection => "manual_selection",
        /// The selection criteria disagree on which excitation to take for a mode.
        CriteriaDisagree => "criteria_disagree",
        /// A normalised-indicator peak where no mode was identified.
        UnmatchedPeak => "unmatched_peak",
        /// A mode shape deviates from rigid-body motion by more than the threshold.
        ShapeNotRigid => "shape_not_rigid",
        /// Complex residues rotated onto the real line.
        ComplexResidues => "complex_residues",
        /// A selected mode could not be used and was left out of the estimate.
        ModeLeftOut => "mode_left_out",
        /// The modes do not move as one rigid body on the given geometry.
        RigidBodyInconsistent => "rigid_body_inconsistent",
        /// The inertia tensor violates a physical bound.
        PhysicallyInconsistent => "physically_inconsistent",
        /// The nearest physically consistent version of an estimate was added.
        ProjectedEstimate => "projected_estimate",
        /// The equations of an estimator are ill-conditioned or rank deficient.
        IllConditioned => "ill_conditioned",
        /// The geometry's channels alone do not resolve the six rigid motions as required.
        GeometryObservability => "geometry_observability",
        /// Side information (nominal values, constraints) the estimator used.
        SideInformation => "side_information",
        /// An estimator could not produce an estimate.
        EstimatorFailed => "estimator_failed",
        /// A standard error could not be computed in full: the intervals may be too narrow.
        UncertaintyIncomplete => "uncertainty_incomplete",
        /// The mount stiffness could not be computed.
        MountStiffness => "mount_stiffness",
        /// The mass line's band and its truncation bias.
        MassLineBand => "mass_line_band",
        /// The noise is correlated from line to line.
        CorrelatedNoise => "correlated_noise",
        /// Values without noise information left out of the model check.
        NoNoiseInformation => "no_noise_information",
        /// What the model check cannot see from these data (a free direction, an axis).
        CheckBlindSpot => "check_blind_spot",
        /// A refit or a candidate of the model check failed.
        CheckRefitFailed => "check_refit_failed",
        /// A choice the model check made on how to read the data.
        CheckProcedure => "check_procedure",
        /// The reader's note on converting an input (a UFF export's oddities).
        InputConversion => "input_conversion",
        /// How FRFs were estimated from time histories.
        FrfEstimation => "frf_estimation",
        /// Lines the modal model does not explain, kept out of the bootstrap's noise.
        UnmodelledLines => "unmodelled_lines",
        /// Relative errors against the reference are undefined (a zero reference value).
        ReferenceErrors => "reference_errors",
        /// A note of the simulator on what it simulated.
        Simulation => "simulation",
        /// A detail of one excitation's fit as the fit recorded it (model order, band).
        FitDetail => "fit_detail",
        /// A message written before diagnostics were typed (an older file): its
        /// severity is not known.
        Text => "text",
    }
}

impl DiagnosticKind {
    /// One sentence on what the kind means for the result, for a test engineer.
    pub fn sentence(self) -> &'static str {
        match self {
            DiagnosticKind::RepeatedRoot => "Two modes share one frequency (a repeated or nearly repeated root): only a fit over all excitations together (poly-reference) can separate their shapes.",
            DiagnosticKind::CloseModes => "Two modes lie within two half-power bandwidths of each other; they were resolved, but their shapes are more sensitive to noise than well-separated ones.",
            DiagnosticKind::FitChoice => "Both the per-excitation and the poly-reference fit were tried on this set-up; the one that explains the data better, without losing a mode, was kept.",
            DiagnosticKind::MergedModes => "One excitation's fit took two modes for one: its frequency, damping and shape of that mode are a blend and should not be used.",
            DiagnosticKind::DroppedMode => "A fit missed a mode that another fit of the same data found: a result built on it lacks that mode.",
            DiagnosticKind::FitErrorAboveNoise => "The fitted model does not explain this excitation's FRFs down to the noise: a mode is missing or merged, or the data hold something the model cannot represent.",
            DiagnosticKind::UndeclaredWindow => "The misfit has the shape an exponential window on the responses leaves: declare the window (--exp-window or the processing record) so that the damping is corrected.",
            DiagnosticKind::ExcitationFailed => "This excitation could not be fitted; the result is computed without it.",
            DiagnosticKind::DeadChannel => "A channel carried no signal and was left out of the computation.",
            DiagnosticKind::WeakModes => "An excitation barely drives these modes; another excitation's estimate of them is preferred.",
            DiagnosticKind::PoleSearch => "The pole search adjusted the model (a spurious pole dropped, a close pair split, the band narrowed to where the modes are); the reported modes already reflect it.",
            DiagnosticKind::WindowCorrection => "The poles were corrected for the declared exponential window; the frequencies and damping ratios are the physical ones.",
            DiagnosticKind::NoModes => "The modal fit found no modes in this set-up, so nothing could be selected from it.",
            DiagnosticKind::ModeMissing => "A rigid-body mode was not found, so the estimate rests on fewer modes than the method needs and some properties may be unobservable.",
            DiagnosticKind::ExtraModes => "The modal record holds more distinct modes than a rigid body has (split poles, leakage, noise or elastic modes); the best supported six were kept.",
            DiagnosticKind::DuplicatePoles => "Two poles at different frequencies have one shape: one physical mode fitted twice, merged into one.",
            DiagnosticKind::ModeRejected => "A candidate was refused (a copy of another mode's shape, or the least evidence among too many); the estimate is computed without it.",
            DiagnosticKind::UndecidedModes => "The evidence barely prefers the kept mode over a rejected one: check both, the answer depends on the choice.",
            DiagnosticKind::SpuriousMode => "A kept mode rests only on weak or unexcited estimates: it may be spurious, and the estimate built on it with it.",
            DiagnosticKind::SetupsForced => "Modes of different suspension set-ups were matched as if they were one suspension's, as requested.",
            DiagnosticKind::ManualSelection => "The manual selection left a mode out or took an estimate the selection criteria find unreliable.",
            DiagnosticKind::CriteriaDisagree => "The selection criteria would take different excitations for this mode; the chosen criterion's pick was used.",
            DiagnosticKind::UnmatchedPeak => "The normalised mode indicator peaks where no mode was identified: a mode may be missing from the modal fit.",
            DiagnosticKind::ShapeNotRigid => "A mode shape deviates from exact rigid-body motion by the amount stated; small values are the noise of the fit, large ones a sensor or an elastic mode.",
            DiagnosticKind::ComplexResidues => "Complex modal constants were rotated onto the real line, as the rigid-body equations need real mode shapes.",
            DiagnosticKind::ModeLeftOut => "A selected mode carried no usable data for the estimator and was left out of the computation.",
            DiagnosticKind::RigidBodyInconsistent => "The identified modes do not move as one rigid body on the given geometry: a sensor position, direction or calibration is probably wrong.",
            DiagnosticKind::PhysicallyInconsistent => "The inertia tensor violates a physical bound (a negative mass or moment, or the triangle inequality): do not use these numbers.",
            DiagnosticKind::ProjectedEstimate => "A physically consistent version of an inconsistent estimate was added next to it: same mass, centre of mass and axes, moments projected onto the physical cone.",
            DiagnosticKind::IllConditioned => "The equations are ill-conditioned: small errors in the data move the result a lot, so its uncertainty is larger than the noise alone suggests.",
            DiagnosticKind::GeometryObservability => "The sensor layout falls short of a geometric requirement for observing rigid motion, but its channels still resolve all six motions.",
            DiagnosticKind::SideInformation => "The estimator used the side information given (nominal values or constraints); the estimate depends on it.",
            DiagnosticKind::EstimatorFailed => "An estimator could not produce an estimate; the others' results are reported.",
            DiagnosticKind::UncertaintyIncomplete => "An uncertainty computation failed in part: the reported intervals may be too narrow.",
            DiagnosticKind::MountStiffness => "The suspension's mount stiffness could not be computed from these modes; the inertia estimate does not need it.",
            DiagnosticKind::MassLineBand => "The mass line's band and its truncation bias, as used for the mass estimate.",
            DiagnosticKind::CorrelatedNoise => "The FRFs' noise is shared by neighbouring lines (a window on the time histories, as in impact testing): the model check weighs it conservatively when it is an exponential window's, and otherwise its claims are not calibrated.",
            DiagnosticKind::NoNoiseInformation => "Values without a noise level (such as an accelerance's 0 Hz line) carry no statistical weight and were left out of the model check.",
            DiagnosticKind::CheckBlindSpot => "The model check cannot tell this effect from the data of this test; a different test (another suspension or excitation) would be needed to see it.",
            DiagnosticKind::CheckRefitFailed => "A refit of the model check did not converge; its candidate effect is not assessed.",
            DiagnosticKind::CheckProcedure => "How the model check read the data (the lines, statistics and candidates it used); the verdict already reflects it.",
            DiagnosticKind::InputConversion => "The input reader's note on how the export was converted (units, node and channel mapping, skipped datasets).",
            DiagnosticKind::FrfEstimation => "The FRFs were estimated from the time histories as stated (averages, windows, rejected hits).",
            DiagnosticKind::UnmodelledLines => "Some lines hold structure the modal model does not explain (an elastic mode above the band, a residual term): the bootstrap keeps the measured values there rather than resample them as noise.",
            DiagnosticKind::ReferenceErrors => "The reference values given cannot measure a relative error (a zero mass, centre of mass or inertia): the error columns are left empty.",
            DiagnosticKind::Simulation => "The simulator's note on what it simulated (the effects switched on, the noise drawn); the data are as the spec asks.",
            DiagnosticKind::FitDetail => "A detail of one excitation's fit (model order, band, pole selection) as the fit recorded it; the reported modes already reflect it.",
            DiagnosticKind::Text => "A message written by an earlier version, before diagnostics were typed; its weight is not known, read it in full.",
        }
    }
}
