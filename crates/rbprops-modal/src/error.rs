//! Errors of the modal stage: each names the excitation (and channel/line) at fault.

use thiserror::Error;

#[derive(Debug, Error, Clone, PartialEq)]
pub enum ModalError {
    #[error("excitation index {index} is out of range (the FRF set has {n} excitations)")]
    NoSuchExcitation { index: usize, n: usize },
    #[error("geometry and FRF set disagree: {0}")]
    Shape(String),
    #[error("excitation '{excitation}': {reason}")]
    BadInput { excitation: String, reason: String },
    #[error("excitation '{excitation}': {method} cannot use this frequency axis: {reason}")]
    Axis {
        excitation: String,
        method: &'static str,
        reason: String,
    },
    #[error("excitation '{excitation}': no stable physical pole found ({reason})")]
    NoModes { excitation: String, reason: String },
    #[error("excitation '{excitation}': numerical failure: {reason}")]
    Numerical { excitation: String, reason: String },
    #[error("invalid options: {0}")]
    Options(String),
}
