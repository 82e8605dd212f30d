//! The integration tests of rbprops-uq, one binary (`cargo nextest run -p rbprops-uq --test it`):
//! one module per topic, shared fixtures in `common`.

mod bootstrap;
mod common;
