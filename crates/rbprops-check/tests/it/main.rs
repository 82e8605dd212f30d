//! The integration tests of rbprops-check, one binary (`cargo nextest run -p rbprops-check --test it`):
//! one module per topic, shared fixtures in `common`.

mod bench_determinism;
#[path = "../../benches/bench_recording.rs"]
mod bench_recording;
mod candidates_registry;
mod common;
mod explore;
mod fixtures;
mod independent_bench;
mod independent_cords;
mod independent_nulls;
mod independent_physics;
mod pipeline;
mod reach;
mod studies;
