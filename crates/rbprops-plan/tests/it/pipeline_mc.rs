//! Monte Carlo of the real pipeline (the library functions behind `frf-sim | modal-fit |
//! ni-select | rb-solve`, default options) over noise seeds: the reference the plan's
//! predicted spread is checked against. Shared by the `it` tests and the
//! `monte_carlo` example.

use rayon::prelude::*;
use rbprops_core::records::EstimateMethod;
use rbprops_core::InertiaProperties;
use rbprops_inertia::{Estimator as SolveEstimator, SolveOptions};
use rbprops_sim::CampaignSpec;

/// Sample standard deviation of every property of `method`'s estimate over seeds
/// `0..seeds` (a seed whose run fails or lacks the estimate is counted in the second
/// value), and the sample mean.
pub fn pipeline_spread(
    spec: &CampaignSpec,
    seeds: u64,
    method: EstimateMethod,
) -> ([f64; 10], [f64; 10], usize) {
    let runs: Vec<Option<[f64; 10]>> = (0..seeds)
        .into_par_iter()
        .map(|seed| one_run(spec, seed, method))
        .collect();
    let ok: Vec<[f64; 10]> = runs.iter().flatten().copied().collect();
    let n = ok.len() as f64;
    let mean: [f64; 10] = std::array::from_fn(|k| ok.iter().map(|v| v[k]).sum::<f64>() / n);
    let std: [f64; 10] = std::array::from_fn(|k| {
        (ok.iter().map(|v| (v[k] - mean[k]).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
    });
    (std, mean, runs.len() - ok.len())
}

/// One seed through the pipeline.
pub fn one_run(spec: &CampaignSpec, seed: u64, method: EstimateMethod) -> Option<[f64; 10]> {
    let mut spec = spec.clone();
    spec.seed = seed;
    let sim = rbprops_sim::simulate(&spec).ok()?;
    let fit = rbprops_modal::fit_campaign(
        &sim.geometry,
        &sim.frf,
        &rbprops_modal::FitOptions::default(),
    )
    .ok()?;
    let sel = rbprops_ni::select_modes(
        &sim.geometry,
        &sim.frf,
        &fit.record,
        &rbprops_ni::SelectOptions::default(),
    )
    .ok()?;
    let opts = SolveOptions {
        estimators: vec![SolveEstimator::ToivolaNuutila, SolveEstimator::BretlConti],
        rigid_body_check: false,
        ..Default::default()
    };
    let out = rbprops_inertia::solve(&sim.geometry, &fit.record, &sel.record, None, &opts).ok()?;
    out.estimates
        .iter()
        .find(|e| e.method == method)
        .map(|e| InertiaProperties::of_estimate(e).to_vector())
}
