//! The integration tests of rbprops-uff, one binary (`cargo nextest run -p rbprops-uff --test it`):
//! one module per topic, shared fixtures in `common`.

mod bad_input;
mod common;
mod exports;
mod mapping;
mod pyuff_fixtures;
mod roundtrip;
mod streaming;
mod written_for_pyuff;
