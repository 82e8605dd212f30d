//! The integration tests of rbprops-ni, one binary (`cargo nextest run -p rbprops-ni --test it`):
//! one module per topic, shared fixtures in `common`.

mod common;
mod noisy;
mod selection;
mod spurious;
