//! Errors of the inertia stage.

use rbprops_core::CoreError;
use thiserror::Error;

/// Errors of the inertia stage. Every variant names the mode, excitation, channel or
/// record concerned and says what is wrong.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum InertiaError {
    /// An invalid domain record (geometry, FRF set, properties).
    #[error(transparent)]
    Core(#[from] CoreError),
    /// Channels or forces that cannot support the estimate (e.g. `SᵀS` singular).
    #[error("geometry: {0}")]
    Geometry(String),
    /// An origin that is not finite or not usable.
    #[error("origin: {0}")]
    Origin(String),
    /// A selected mode that cannot be used (missing, no residues, not excited).
    #[error("selected mode {mode} of set-up '{setup}' (excitation '{excitation}'): {reason}")]
    Mode {
        /// Its suspension set-up.
        setup: String,
        /// Its 1-based physical mode number.
        mode: usize,
        /// The excitation whose estimate was selected.
        excitation: String,
        /// What is wrong with it.
        reason: String,
    },
    /// Fewer modes than the estimator needs (six for Eq. (2), four for Eq. (10)).
    #[error("{method}: needs {needed}, got {got}")]
    TooFewModes {
        /// The estimator.
        method: &'static str,
        /// What it needs, in words.
        needed: String,
        /// How many modes it got.
        got: usize,
    },
    /// `Φ0` of Eq. (2) cannot be inverted.
    #[error("bretl_conti: the modal matrix Φ0 is singular or ill-conditioned (cond = {condition:.3e}); the selected modes are not six independent rigid-body motions")]
    SingularModalMatrix {
        /// Its condition number.
        condition: f64,
    },
    /// The design matrix of the ten properties is rank-deficient.
    #[error(
        "{method}: the ten parameters are not identifiable (rank {rank} of 10): {description}"
    )]
    Unidentifiable {
        /// The estimator.
        method: &'static str,
        /// Numerical rank of the design matrix.
        rank: usize,
        /// Which combinations of properties the data do not determine.
        description: String,
    },
    /// The mass-line estimator failed (band, data or fit).
    #[error("mass_line: {0}")]
    MassLine(String),
    /// Inconsistent or unusable known values (a known mass, CoM, …) imposed as constraints.
    #[error("side information: {0}")]
    SideInformation(String),
    /// A result that is NaN or infinite.
    #[error("{what}: result is not finite")]
    NonFinite {
        /// What was being computed.
        what: String,
    },
    /// Every estimator failed; one message per estimator.
    #[error("no estimator produced a result: {}", .0.join("; "))]
    NoEstimate(Vec<String>),
    /// A decomposition that did not converge.
    #[error("linear algebra: {0}")]
    LinearAlgebra(String),
}
