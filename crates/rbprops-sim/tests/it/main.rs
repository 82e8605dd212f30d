//! The integration tests of rbprops-sim, one binary (`cargo nextest run -p rbprops-sim --test it`):
//! one module per topic, shared fixtures in `common`.

mod common;
mod cord_mass;
mod cords;
mod effects;
mod effects_catalogue;
mod noise_determinism;
mod physics;
mod registry;
mod spec_errors;
