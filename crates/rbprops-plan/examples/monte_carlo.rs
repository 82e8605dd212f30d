//! Predicted standard deviations of the ten properties against the spread of the real
//! pipeline over noise seeds.
//!
//! `cargo run --release -p rbprops-plan --example monte_carlo -- SPEC|EXAMPLE SEEDS [RELATIVE_NOISE]`
//! (the noise replaces the spec's when given).

#[path = "../tests/it/pipeline_mc.rs"]
mod pipeline_mc;

use rbprops_core::records::EstimateMethod;
use rbprops_plan::{evaluate, Estimator, Layout, PlanModel, PROPERTY_NAMES};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let name = args.first().map(String::as_str).unwrap_or("test-case-2");
    let seeds: u64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(50);
    let text = match rbprops_sim::example(name) {
        Some(t) => t.to_string(),
        None => std::fs::read_to_string(name).expect("spec file"),
    };
    let mut spec = rbprops_sim::CampaignSpec::from_toml_str(&text).expect("spec");
    if let Some(a) = args.get(2).and_then(|s| s.parse().ok()) {
        spec.noise.relative = a;
    }
    let model = PlanModel::from_spec(&spec).expect("model");
    let layout = Layout::from_spec(&spec, &model).expect("layout");
    for (est, method) in [
        (Estimator::ToivolaNuutila, EstimateMethod::ToivolaNuutila),
        (Estimator::BretlConti, EstimateMethod::BretlConti),
    ] {
        let t = std::time::Instant::now();
        let ev = evaluate(&model, &layout, est);
        let pred = ev.setups[0].1.as_ref().expect("observable").std();
        let tp = t.elapsed();
        let (mc, mean, failed) = pipeline_spread(&spec, seeds, method);
        println!(
            "{name} {} ({seeds} seeds, {failed} failed; prediction {:.1} ms)",
            est.name(),
            tp.as_secs_f64() * 1e3
        );
        println!("prop        truth        mean      pred std     MC std   pred/MC");
        for k in 0..10 {
            println!(
                "{:4} {:12.6} {:12.6} {:12.4e} {:10.4e} {:8.3}",
                PROPERTY_NAMES[k],
                model.truth[k],
                mean[k],
                pred[k],
                mc[k],
                pred[k] / mc[k]
            );
        }
    }
}

use pipeline_mc::pipeline_spread;
