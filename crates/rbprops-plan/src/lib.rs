//! **rbprops-plan**: where to mount the sensors and where to hit so that the ten
//! rigid-body properties (m, c, J; docs/conventions.md §3) are best determined.
//!
//! The predicted covariance of a layout is the linear propagation of the FRF noise
//! through the pipeline's own chain:
//!
//! 1. FRF noise `E|ε|² = a²|H|² + b²` (docs/conventions.md §8) → the real modal constants
//!    of each excitation's fit, linearising `modal-fit`'s two least-squares steps (pole
//!    refinement on the focus lines, residues on every line) about the noiseless FRFs
//!    ([`fitcov`]);
//! 2. → the Norm-Indicator choice of each mode's excitation, the rigid transform (Eq. 5),
//!    the mass normalisation and the estimator (Toivola–Nuutila Eq. 10 by default, or
//!    Bretl–Conti Eq. 2) → `Cov p̂ = G Σ Gᵀ` ([`estimate`]).
//!
//! [`select`] chooses sensors and hits among candidates (D-optimal by default; A-optimal
//! and worst-property criteria), greedily with exchange passes, deterministically.
//! A layout that cannot determine the properties is reported as [`Unobservable`] with
//! the combination it leaves free, never with a number.
//!
//! No I/O: specs come in parsed, results go out as data.

// Index loops mirror the equations; `!(x > y)` deliberately rejects NaN too.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]
#![warn(missing_docs)]

pub mod estimate;
pub mod fitcov;
pub mod model;
pub mod select;

pub use estimate::{Estimator, JacobianCache, SetupPrediction, Unobservable};
pub use fitcov::{
    combine, excitation_covariance, ChannelTerms, ExcitationBasis, ExcitationCovariance,
};
pub use model::{property_scales, Hit, Layout, PlanModel, Sensor, SetupModes};
pub use select::{
    evaluate, plan, Candidates, Criterion, Evaluation, PlanOptions, PlanOutcome, Suggestion,
};

/// Names of the ten properties, docs/conventions.md §3 order.
pub const PROPERTY_NAMES: [&str; 10] = [
    "m", "cx", "cy", "cz", "Jxx", "Jyy", "Jzz", "Jxy", "Jxz", "Jyz",
];

/// Errors of the planner.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// The spec cannot be planned on.
    #[error("spec: {0}")]
    Spec(String),
    /// The candidates or options are unusable.
    #[error("{0}")]
    Layout(String),
}
