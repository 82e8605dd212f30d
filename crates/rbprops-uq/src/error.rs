use rbprops_inertia::InertiaError;
use rbprops_modal::ModalError;
use thiserror::Error;

/// Errors of the bootstrap. Each names the excitation, mode or estimate concerned.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum UqError {
    #[error("bootstrap options: {0}")]
    Options(String),
    #[error("the FRF set ({frf}) does not match the geometry ({geometry})")]
    Shape { frf: String, geometry: String },
    #[error("excitation '{excitation}': {reason}")]
    Excitation { excitation: String, reason: String },
    #[error("excitation '{excitation}': {source}")]
    Modal {
        excitation: String,
        #[source]
        source: ModalError,
    },
    #[error("the estimate on the measured data failed: {0}")]
    Inertia(#[from] InertiaError),
    #[error("no estimate could be bootstrapped: {}", .0.join("; "))]
    Nothing(Vec<String>),
}
