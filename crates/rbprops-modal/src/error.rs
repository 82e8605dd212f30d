//! Errors of the modal stage: each names the excitation (and channel/line) at fault.

use thiserror::Error;

/// Why an excitation (or the whole campaign) could not be fitted.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ModalError {
    /// An excitation index beyond the FRF set.
    #[error("excitation index {index} is out of range (the FRF set has {n} excitations)")]
    NoSuchExcitation {
        /// The index asked for (0-based).
        index: usize,
        /// Number of excitations in the FRF set.
        n: usize,
    },
    /// The geometry and the FRF set do not describe the same test.
    #[error("geometry and FRF set disagree: {0}")]
    Shape(String),
    /// The excitation's data cannot be fitted (unsorted axis, all-zero channels, …).
    #[error("excitation '{excitation}': {reason}")]
    BadInput {
        /// The excitation's id.
        excitation: String,
        /// What is wrong.
        reason: String,
    },
    /// The method needs another frequency axis (LSCE: uniform from 0 Hz).
    #[error("excitation '{excitation}': {method} cannot use this frequency axis: {reason}")]
    Axis {
        /// The excitation's id.
        excitation: String,
        /// The method's name.
        method: &'static str,
        /// What the axis lacks.
        reason: String,
    },
    /// The stabilisation diagram holds no stable cluster to select.
    #[error("excitation '{excitation}': no stable physical pole found ({reason})")]
    NoModes {
        /// The excitation's id.
        excitation: String,
        /// Why nothing was selected.
        reason: String,
    },
    /// A factorisation or solve failed.
    #[error("excitation '{excitation}': numerical failure: {reason}")]
    Numerical {
        /// The excitation's id.
        excitation: String,
        /// Which step failed.
        reason: String,
    },
    /// The FRF source could not give an excitation's values (its file changed or cannot be
    /// read): the run stops, it is not one excitation's failed fit.
    #[error("{0}")]
    Source(String),
    /// An option is out of range (the message names it).
    #[error("invalid options: {0}")]
    Options(String),
}
