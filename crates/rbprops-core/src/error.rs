use thiserror::Error;

/// Errors raised by the domain model: every one names the record and what is wrong.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum CoreError {
    #[error("{what}: direction {dir:?} is not a unit vector (|d| = {norm})")]
    NonUnitDirection {
        what: String,
        dir: [f64; 3],
        norm: f64,
    },
    #[error("{what}: value is not finite ({value})")]
    NonFinite { what: String, value: f64 },
    #[error("{0}")]
    Geometry(String),
    #[error("frequency axis: {0}")]
    FrequencyAxis(String),
    #[error("FRF set: {0}")]
    FrfShape(String),
    #[error("inertia: {0}")]
    Inertia(String),
    #[error("processing: {0}")]
    Processing(String),
    #[error("unknown {kind} '{value}' (expected one of: {expected})")]
    Unknown {
        kind: &'static str,
        value: String,
        expected: &'static str,
    },
}
