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
