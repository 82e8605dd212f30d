//! **rbprops-ni** — which excitation gives each rigid-body mode its best shape.
//!
//! No single force excites all six rigid-body modes well (Almeida, Urgueira & Maia 2007).
//! This crate
//! - computes the Norm Indicator `NI_k(ω) = 20 log10 sqrt(Σ_i |H_ik(ω)|²)` (paper Eq. 12)
//!   of every excitation, its peaks, and how strongly each excitation drives each mode
//!   (`f_kᵀq = (f_kᵀφ0)²`, docs/conventions.md);
//! - matches the modes `modal-fit` identified per excitation into the physical modes of a
//!   suspension set-up by frequency and MAC of their rigid-body shapes
//!   (`q = (SᵀS)⁻¹SᵀA`, paper Eq. 5), so that "mode 3" is the same mode everywhere;
//! - selects for every mode the best excitation by NI (or by the hybrid MIF, Rades 1994,
//!   or the PRF MIF, Rades & Ewins 2000, or a manual set such as the paper's Sets I–V)
//!   and reports where the criteria disagree;
//! - returns plot-ready data: indicator curves and a mode × excitation strength matrix.
//!
//! Entry points: [`select_modes`], [`norm_indicator`], [`hybrid_mif`], [`prf_mif`],
//! [`parse_manual_set`], [`ManualSet::from_toml`], [`ManualSet::from_csv`].
//! The crate does no I/O.

#![warn(missing_docs)]
// `!(x > 0.0)` is deliberate throughout: it is also true for NaN, which must be refused.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod consolidate;
pub mod error;
pub mod indicators;
pub mod manual;
pub mod matching;
pub mod peaks;
pub mod select;

pub use consolidate::{estimate_quality, RIGID_BODY_MODES};
pub use error::NiError;
pub use indicators::{
    hybrid_mif, norm_indicator, prf_mif, principal_responses, PrincipalResponses, NI_FLOOR_DB,
};
pub use manual::{parse_manual_set, ManualEntry, ManualSet};
pub use matching::mac;
pub use select::{
    select_modes, Criterion, ExcitationCurves, ExcitationSummary, IndicatorCurves, ModeExcitation,
    ModeGroup, NiPeak, RejectedEstimate, SelectOptions, SelectionOutput, StrengthMatrix,
};

/// A diagnostic of `ni-select` (module docs of [`rbprops_core::records::Diagnostic`]).
pub(crate) fn diagnostic(
    kind: rbprops_core::records::DiagnosticKind,
    severity: rbprops_core::records::Severity,
    subject: rbprops_core::records::DiagnosticSubject,
    message: impl Into<String>,
) -> rbprops_core::records::Diagnostic {
    rbprops_core::records::Diagnostic::new("ni-select", kind, severity, subject, message)
}
