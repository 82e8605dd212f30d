//! The integration tests of rbprops-cli, one binary (`cargo nextest run -p rbprops-cli --test it`):
//! one module per topic, shared fixtures in `common`.

mod bootstrap_variance;
mod campaign;
mod campaign_frf_est;
mod campaign_shards;
mod coherence_weight;
mod combination_seeds;
mod common;
mod exp_window;
mod faults;
mod frf_est;
mod frf_sim;
mod golden;
mod mass_line;
mod mutation;
mod plan;
mod refgen_pipeline;
mod report_html;
mod solve_diagnostics;
mod uff_campaign;
mod uff_exports;
mod warnings_null;
