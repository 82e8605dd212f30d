//! The domain model's error type.

use thiserror::Error;

/// Errors raised by the domain model: every one names the record and what is wrong.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum CoreError {
    /// A direction that must be a unit vector (a channel's `s`, a force's `d`) is not.
    #[error("{what}: direction {dir:?} is not a unit vector (|d| = {norm})")]
    NonUnitDirection {
        /// The record the direction belongs to.
        what: String,
        /// The direction as given.
        dir: [f64; 3],
        /// Its Euclidean norm.
        norm: f64,
    },
    /// A number that must be finite is NaN or infinite.
    #[error("{what}: value is not finite ({value})")]
    NonFinite {
        /// The record and field holding the value.
        what: String,
        /// The offending value.
        value: f64,
    },
    /// Inconsistent or unusable geometry: a duplicate id, a dangling reference, channels
    /// that cannot determine rigid motion (`SᵀS` singular).
    #[error("{0}")]
    Geometry(String),
    /// A frequency axis that is empty, not ascending or not finite.
    #[error("frequency axis: {0}")]
    FrequencyAxis(String),
    /// FRF values whose count does not match excitations × channels × lines.
    #[error("FRF set: {0}")]
    FrfShape(String),
    /// An [`crate::FrfSource`] that could not give an excitation's values (the file it
    /// reads them from changed or cannot be read); the message names the file and record.
    #[error("{0}")]
    FrfSource(String),
    /// Inertia properties that are not physical (non-positive mass, indefinite tensor).
    #[error("inertia: {0}")]
    Inertia(String),
    /// Invalid processing settings (e.g. an exponential window's time constant).
    #[error("processing: {0}")]
    Processing(String),
    /// A name (quantity, method, …) that is not one of the accepted ones.
    #[error("unknown {kind} '{value}' (expected one of: {expected})")]
    Unknown {
        /// What was being named ("quantity", "method", …).
        kind: &'static str,
        /// The name as given.
        value: String,
        /// The accepted names, comma-separated.
        expected: &'static str,
    },
}
