//! The integration tests of rbprops-modal, one binary (`cargo nextest run -p rbprops-modal --test it`):
//! one module per topic, shared fixtures in `common`.

mod circle;
mod close_modes;
mod common;
mod noise_free;
mod noisy;
mod plscf;
mod robustness;
