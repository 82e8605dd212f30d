//! Typed errors of the simulator. Every message names the TOML path, set-up, excitation
//! or effect concerned and says what is wrong.

use thiserror::Error;

/// One problem found in a campaign spec: where (`sensor[2].direction`) and what.
#[derive(Debug, Clone, PartialEq)]
pub struct SpecIssue {
    /// TOML path, array indices 0-based (`setup[1].spring[0].stiffness_n_per_m`).
    pub path: String,
    /// What is wrong there.
    pub problem: String,
}

impl std::fmt::Display for SpecIssue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.path, self.problem)
    }
}

/// A campaign spec that cannot be used.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SpecError {
    /// Not UTF-8, not TOML, an unknown key or a wrong type. The message carries the
    /// line and column from the TOML parser.
    #[error("campaign spec: {0}")]
    Toml(String),
    /// Well-formed TOML whose content is inconsistent; every problem found is listed.
    #[error("campaign spec has {} problem(s): {}", .0.len(), join_issues(.0))]
    Invalid(Vec<SpecIssue>),
}

fn join_issues(issues: &[SpecIssue]) -> String {
    issues
        .iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join("; ")
}

impl SpecError {
    /// The issues of an [`SpecError::Invalid`] (empty for a parse error).
    pub fn issues(&self) -> &[SpecIssue] {
        match self {
            SpecError::Invalid(v) => v,
            SpecError::Toml(_) => &[],
        }
    }
}

/// Errors of [`crate::simulate()`].
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SimError {
    /// The campaign spec cannot be used.
    #[error(transparent)]
    Spec(#[from] SpecError),
    /// A set-up whose dynamics cannot be solved (free direction, unstable, singular).
    #[error("set-up '{setup}': {problem}")]
    Setup {
        /// The set-up's id.
        setup: String,
        /// What is wrong.
        problem: String,
    },
    /// An effect that cannot be applied with its parameters.
    #[error("effect[{index}] '{id}': {problem}")]
    Effect {
        /// 0-based index of the effect in the spec's `[[effect]]` list.
        index: usize,
        /// The effect's id.
        id: String,
        /// What is wrong with its parameters.
        problem: String,
    },
    /// The requested output would not fit in memory.
    #[error("campaign too large: {0}")]
    TooLarge(String),
    /// The core types refused the built geometry or FRF set.
    #[error(transparent)]
    Core(#[from] rbprops_core::CoreError),
}
