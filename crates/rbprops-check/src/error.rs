//! Typed errors of the model check.

use thiserror::Error;

/// Why a model check could not run to the end.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum CheckError {
    /// The spec and the recording do not describe the same test.
    #[error("recording does not match the spec: {0}")]
    Mismatch(String),
    /// The recording cannot be used (too few lines, no finite values, ...).
    #[error("recording: {0}")]
    Data(String),
    /// The model cannot be built or evaluated at some parameter values.
    #[error("model: {0}")]
    Model(String),
    /// The noise floor cannot be estimated from the data.
    #[error("noise floor: {0}")]
    Noise(String),
    /// The least-squares problem is singular or diverged.
    #[error("fit '{stage}': {problem}")]
    Fit {
        /// Which fit (the baseline, a candidate's refit, …).
        stage: String,
        /// What went wrong.
        problem: String,
    },
}
