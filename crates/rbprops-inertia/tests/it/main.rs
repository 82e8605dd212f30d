//! The integration tests of rbprops-inertia, one binary (`cargo nextest run -p rbprops-inertia --test it`):
//! one module per topic, shared fixtures in `common`.

mod calibration;
mod common;
mod consistency;
mod mass_line;
mod modal;
mod rigid_consistency;
