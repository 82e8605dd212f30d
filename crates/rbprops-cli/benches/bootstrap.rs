//! `rb-solve`'s bootstrap against its solve without it, at 102,401 lines × 3 excitations ×
//! 9 channels (the demo campaign, Test Case II with 1 % noise, `lines = 102401`): the
//! stage's library function on a record in memory (no file I/O), linearised errors and
//! the default bootstrap (100 replicates on every q-th line, `rbprops_uq::decimation`),
//! and the modal fit of the same record for scale.
//!
//! `cargo bench -p rbprops-cli --bench bootstrap`
//!
//! Measured (2 cores, quiet, session 34): linearised 50 ms, bootstrap 442 ms, modal fit
//! 96 ms (medians of 10). The whole processes (with reading the 44 MB record) are timed
//! as in docs/results.md ("rb-solve's bootstrap at scale"): 0.24 s and 0.65 s.

use criterion::{criterion_group, criterion_main, Criterion};
use rbprops_cli::stages;
use rbprops_inertia::SolveOptions;

fn spec_text() -> String {
    let text = rbprops_sim::examples::example("demo").expect("built-in example");
    let edited = text.replace("lines = 1601", "lines = 102401");
    assert!(edited.contains("lines = 102401"));
    edited
}

fn bench(c: &mut Criterion) {
    let (mut rec, _) = stages::simulate(&spec_text(), "bench", Some(1)).unwrap();
    let raw = rec.clone();
    stages::modal_fit(&mut rec, &Default::default(), "bench").unwrap();
    stages::ni_select(&mut rec, &Default::default(), "bench").unwrap();
    let solve = |uq: &stages::Uncertainty| {
        let mut r = rec.clone();
        let (out, _) =
            stages::rb_solve_with(&mut r, &SolveOptions::default(), uq, false, "bench").unwrap();
        assert!(!out.estimates.is_empty());
    };
    let mut group = c.benchmark_group("rb_solve_3exc_9ch_102401lines");
    group.sample_size(10);
    group.bench_function("linearised", |b| {
        b.iter(|| solve(&stages::Uncertainty::Linearised))
    });
    group.bench_function("bootstrap_100", |b| {
        b.iter(|| solve(&stages::Uncertainty::Bootstrap(Default::default())))
    });
    group.bench_function("modal_fit", |b| {
        b.iter(|| {
            let mut r = raw.clone();
            stages::modal_fit(&mut r, &Default::default(), "bench").unwrap();
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
