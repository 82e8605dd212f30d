//! Errors of the bootstrap.

use rbprops_inertia::InertiaError;
use rbprops_modal::ModalError;
use thiserror::Error;

/// Errors of the bootstrap. Each names the excitation, mode or estimate concerned.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum UqError {
    /// Invalid bootstrap options (replicate count, confidence level, …).
    #[error("bootstrap options: {0}")]
    Options(String),
    /// The FRF set's shape disagrees with the geometry's channels and excitations.
    #[error("the FRF set ({frf}) does not match the geometry ({geometry})")]
    Shape {
        /// The FRF set's excitations × channels, in words.
        frf: String,
        /// The geometry's excitations × channels, in words.
        geometry: String,
    },
    /// An excitation that cannot be resampled (no fit, no noise estimate, …).
    #[error("excitation '{excitation}': {reason}")]
    Excitation {
        /// Its id.
        excitation: String,
        /// What is wrong.
        reason: String,
    },
    /// The modal fit of a measured excitation failed.
    #[error("excitation '{excitation}': {source}")]
    Modal {
        /// Its id.
        excitation: String,
        /// The fit's error.
        #[source]
        source: ModalError,
    },
    /// The FRFs could not be read (a reader's excitation: the file changed, …).
    #[error("reading the FRFs: {0}")]
    Source(#[from] rbprops_core::CoreError),
    /// The inertia estimate of the measured data failed.
    #[error("the estimate on the measured data failed: {0}")]
    Inertia(#[from] InertiaError),
    /// The scratch store the bootstrap keeps a large set in failed (`crate::Scratch`).
    #[error("bootstrap scratch store: {0}")]
    Scratch(String),
    /// No estimate survived resampling; one message per estimate.
    #[error("no estimate could be bootstrapped: {}", .0.join("; "))]
    Nothing(Vec<String>),
}
