use rbprops_core::CoreError;
use thiserror::Error;

/// Errors of the mode-selection stage. Each names the excitation, mode, set-up or
/// manual-set entry at fault and what is wrong.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum NiError {
    #[error(transparent)]
    Core(#[from] CoreError),
    /// The FRF set, geometry and modal record disagree on sizes or names.
    #[error("inconsistent input: {0}")]
    Inconsistent(String),
    /// A `ModeEstimate` is unusable (names its excitation and mode).
    #[error("mode {mode} of excitation '{excitation}': {message}")]
    BadEstimate {
        excitation: String,
        mode: usize,
        message: String,
    },
    #[error("unknown set-up '{setup}' (the geometry defines: {known})")]
    UnknownSetup { setup: String, known: String },
    /// Modes of different suspension set-ups are different modes: combining them needs
    /// `force_mixed_setups`.
    #[error("refusing to mix suspension set-ups: {0} (set force_mixed_setups to override)")]
    MixedSetups(String),
    /// Nothing to select from.
    #[error("no identified modes for set-up '{setup}' in the modal record")]
    NoModes { setup: String },
    /// A manual set could not be read: `item` is the offending text (or line).
    #[error("manual set, {item}: {message}")]
    ManualParse { item: String, message: String },
    /// A manual set names something the data does not have.
    #[error("manual set: {0}")]
    Manual(String),
    #[error("invalid option: {0}")]
    Options(String),
}
