//! Modal identification per excitation (rbprops stage `modal-fit`).
//!
//! For each excitation (a SIMO data set: one force, all channels) the modes in the band
//! are identified: natural frequency, damping ratio, complex modal constant per channel
//! with standard errors, and fit quality. Pipeline of the default method:
//!
//! 1. poles per model order by LSCF (module `lscf`) or LSCE (module `lsce`);
//! 2. stabilisation diagram and automatic selection by clustering ([`stabilisation`]);
//! 3. joint refinement of the poles by variable-projection least squares ([`lsfd::refine`])
//!    on the lines near the poles ([`band::BandData::focus_indices`]), then model-order
//!    tests on the residual, each a χ² test at p = 1e-4 for the 2 + 2·channels parameters
//!    of a pole: intermittently stable diagram clusters added, close or low-confidence
//!    poles dropped when insignificant (over-split pairs), poles split when a partner
//!    half a bandwidth away is significant (merged pairs);
//! 4. residues and residual terms by LSFD on every line ([`lsfd::fit_residues`]);
//! 5. records: modal constants `A = 2iω_d R` (see [`pole`]) in the receptance form of
//!    docs/conventions.md, whatever the input quantity.
//!
//! [`Method::Circle`] replaces steps 3–4 by Kennedy–Pancu circle fits (module `circle`).
//!
//! Excitations run in parallel with rayon; every per-excitation computation is
//! sequential and seeded by nothing, so results are identical for any thread count.
//! The crate does no I/O. Its public surface is the campaign fit ([`fit_campaign`],
//! [`fit_excitation`]), its options and results, poles, the stabilisation diagram and the
//! LSFD residues; the estimators behind them (LSCF, LSCE, poly-reference, circle fit,
//! root finding, linear algebra) are internal.

#![warn(missing_docs)]

pub mod band;
pub(crate) mod circle;
pub mod error;
pub mod evidence;
mod fit;
pub(crate) mod linalg;
pub(crate) mod lsce;
pub(crate) mod lscf;
pub mod lsfd;
pub mod options;
pub(crate) mod plscf;
pub(crate) mod plsfd;
pub(crate) mod plsfd_refine;
pub mod pole;
mod poly;
pub mod prof;
pub(crate) mod reciprocity;
pub(crate) mod roots;
pub(crate) mod setup_bands;
#[macro_use]
pub mod stabilisation;
mod tallmul;
pub mod weighting;

pub use error::ModalError;
pub use fit::{
    fit_campaign, fit_excitation, ExcitationDiagnostics, ExcitationFit, ModalFitOutput,
    RESIDUE_CONVENTION,
};
pub use options::{FitOptions, Method, PoleMode, PoleSearchParams, StabilisationTolerances};
pub use pole::{mac, mpc, Pole};
pub use stabilisation::{DiagramPole, StabilisationDiagram, StabilityClass};
pub use weighting::CoherenceWeighting;
