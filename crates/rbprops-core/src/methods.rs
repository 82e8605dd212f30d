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
            "`bretl_conti`, `toivola_nuutila`, `mass_line`, `model_fit`.",
        );
        plain(
            &e["properties"]["uncertainty_method"],
            "How the standard errors were obtained (`linearised`, `monte_carlo`, `none`).",
        );
        let s = serde_json::to_value(schemars::schema_for!(SelectionRecord)).unwrap();
        plain(
            &s["$defs"]["SelectedMode"]["properties"]["criterion"],
            "`ni`, `hybrid_mif`, `prf_mif` or `manual`.",
        );
        let m = serde_json::to_value(schemars::schema_for!(ModalFitRecord)).unwrap();
        plain(
            &m["$defs"]["ExcitationFitRecord"]["properties"]["method"],
            "`lsce`, `lscf` or `circle`.",
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
        }
    }
}
