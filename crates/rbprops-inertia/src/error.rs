use rbprops_core::CoreError;
use thiserror::Error;

/// Errors of the inertia stage. Every variant names the mode, excitation, channel or
/// record concerned and says what is wrong.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum InertiaError {
    #[error(transparent)]
    Core(#[from] CoreError),
    #[error("geometry: {0}")]
    Geometry(String),
    #[error("origin: {0}")]
    Origin(String),
    #[error("selected mode {mode} of set-up '{setup}' (excitation '{excitation}'): {reason}")]
    Mode {
        setup: String,
        mode: usize,
        excitation: String,
        reason: String,
    },
    #[error("{method}: needs {needed}, got {got}")]
    TooFewModes {
        method: &'static str,
        needed: String,
        got: usize,
    },
    #[error("bretl_conti: the modal matrix Φ0 is singular or ill-conditioned (cond = {condition:.3e}); the selected modes are not six independent rigid-body motions")]
    SingularModalMatrix { condition: f64 },
    #[error(
        "{method}: the ten parameters are not identifiable (rank {rank} of 10): {description}"
    )]
    Unidentifiable {
        method: &'static str,
        rank: usize,
        description: String,
    },
    #[error("mass_line: {0}")]
    MassLine(String),
    #[error("side information: {0}")]
    SideInformation(String),
    #[error("{what}: result is not finite")]
    NonFinite { what: String },
    #[error("no estimator produced a result: {}", .0.join("; "))]
    NoEstimate(Vec<String>),
    #[error("linear algebra: {0}")]
    LinearAlgebra(String),
}
