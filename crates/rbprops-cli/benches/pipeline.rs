//! The whole pipeline on one recording of 3 excitations × 9 channels × 1,000 lines
//! (Test Case II with 1 % noise): `modal-fit` (default LSCF, and the poly-reference fit),
//! `ni-select` and `rb-solve` (Bretl–Conti and Toivola–Nuutila with linearised errors;
//! the FRF-level bootstrap is reported separately, as it re-identifies the modes per
//! replicate). The stages are the library functions the executables call, on a record
//! in memory: no file I/O or MCAP encoding is timed.
//!
//! `cargo bench -p rbprops-cli --bench pipeline`
//!
//! Measured (2 cores, load average near 10 from parallel builds): 21 ms per recording with
//! LSCF and linearised errors, 29 ms with the poly-reference fit (before its refinement,
//! which adds about 12 ms), 0.40 s with the bootstrap.

use criterion::{criterion_group, criterion_main, Criterion};
use rbprops_cli::stages;
use rbprops_inertia::{Estimator, SolveOptions};
use rbprops_modal::{FitOptions, Method};

/// Test Case II at 1,000 lines (0–12.5 Hz) with 1 % relative noise.
fn spec_text() -> String {
    let text = rbprops_sim::examples::example("test-case-2").expect("built-in example");
    let edited = text
        .replace("lines = 1601", "lines = 1000")
        .replace("[noise]\nrelative = 0.0", "[noise]\nrelative = 0.01");
    assert!(edited.contains("lines = 1000") && edited.contains("relative = 0.01"));
    edited
}

fn run(rec: &rbprops_formats::RunRecord, fit: &FitOptions, uq: &stages::Uncertainty) {
    let mut rec = rec.clone();
    stages::modal_fit(&mut rec, fit, "bench").unwrap();
    stages::ni_select(&mut rec, &Default::default(), "bench").unwrap();
    let opts = SolveOptions {
        estimators: vec![Estimator::BretlConti, Estimator::ToivolaNuutila],
        ..Default::default()
    };
    let (out, _) = stages::rb_solve_with(&mut rec, &opts, uq, false, "bench").unwrap();
    assert_eq!(out.estimates.len(), 2);
}

fn bench(c: &mut Criterion) {
    let (rec, _) = stages::simulate(&spec_text(), "bench", Some(1)).unwrap();
    let lscf = FitOptions::default();
    let plscf = FitOptions {
        method: Method::Plscf,
        ..Default::default()
    };
    let mut group = c.benchmark_group("pipeline_3exc_9ch_1000lines");
    group.sample_size(10);
    group.bench_function("lscf_linearised", |b| {
        b.iter(|| run(&rec, &lscf, &stages::Uncertainty::Linearised))
    });
    group.bench_function("plscf_linearised", |b| {
        b.iter(|| run(&rec, &plscf, &stages::Uncertainty::Linearised))
    });
    group.bench_function("lscf_bootstrap", |b| {
        b.iter(|| {
            run(
                &rec,
                &lscf,
                &stages::Uncertainty::Bootstrap(Default::default()),
            )
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
