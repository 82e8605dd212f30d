//! Errors of the mode-selection stage.

use rbprops_core::CoreError;
use thiserror::Error;

/// Errors of the mode-selection stage. Each names the excitation, mode, set-up or
/// manual-set entry at fault and what is wrong.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum NiError {
    /// An invalid geometry or FRF set, as the core types report it.
    #[error(transparent)]
    Core(#[from] CoreError),
    /// The FRF set, geometry and modal record disagree on sizes or names.
    #[error("inconsistent input: {0}")]
    Inconsistent(String),
    /// A `ModeEstimate` is unusable (names its excitation and mode).
    #[error("mode {mode} of excitation '{excitation}': {message}")]
    BadEstimate {
        /// The excitation whose modal record holds it.
        excitation: String,
        /// Its 1-based mode number in that record.
        mode: usize,
        /// What is wrong.
        message: String,
    },
    /// An excitation or manual set names a set-up the geometry does not define.
    #[error("unknown set-up '{setup}' (the geometry defines: {known})")]
    UnknownSetup {
        /// The set-up as named.
        setup: String,
        /// The geometry's set-up ids, comma-separated.
        known: String,
    },
    /// Modes of different suspension set-ups are different modes: combining them needs
    /// `force_mixed_setups`.
    #[error("refusing to mix suspension set-ups: {0} (set force_mixed_setups to override)")]
    MixedSetups(String),
    /// Nothing to select from.
    #[error("no identified modes for set-up '{setup}' in the modal record")]
    NoModes {
        /// The set-up.
        setup: String,
    },
    /// A manual set could not be read: `item` is the offending text (or line).
    #[error("manual set, {item}: {message}")]
    ManualParse {
        /// The offending text or line.
        item: String,
        /// What is wrong with it.
        message: String,
    },
    /// A manual set names something the data does not have.
    #[error("manual set: {0}")]
    Manual(String),
    /// An option is invalid (the message names it).
    #[error("invalid option: {0}")]
    Options(String),
}
