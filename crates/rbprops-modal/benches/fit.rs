//! Per-excitation cost of the default fit (LSCF + refinement + LSFD) on
//! 9 channels × 4,096 lines, on 1 and 2 rayon threads.
//!
//! The workload is 1,000 excitations; the loop fits a batch of
//! `BATCH` excitations (copies of three Test-Case-like excitations with different noise)
//! and criterion reports the batch time: per-excitation cost = time / BATCH.

use criterion::{criterion_group, criterion_main, Criterion};
use rbprops_core::{FrfSet, Quantity};
use rbprops_modal::{fit_campaign, testdata, FitOptions};

const BATCH: usize = 24;

fn campaign() -> (rbprops_core::Geometry, FrfSet) {
    let base = testdata::test_case(12.5, 4096, Quantity::Accelerance);
    let mut geometry = base.geometry.clone();
    let per = base.frf.n_channels * base.frf.n_lines();
    let mut values = Vec::with_capacity(BATCH * per);
    let mut excitations = Vec::new();
    for b in 0..BATCH {
        let noisy = base.with_noise(0.01, 1000 + b as u64);
        let e = b % base.frf.n_excitations;
        values.extend_from_slice(noisy.frf.excitation_block(e));
        let mut ex = base.geometry.excitations[e].clone();
        ex.id = format!("E{b}");
        excitations.push(ex);
    }
    geometry.excitations = excitations;
    let frf = FrfSet {
        quantity: base.frf.quantity,
        frequency_hz: base.frf.frequency_hz.clone(),
        n_excitations: BATCH,
        n_channels: base.frf.n_channels,
        values,
    };
    (geometry, frf)
}

fn bench(c: &mut Criterion) {
    let (geometry, frf) = campaign();
    let opts = FitOptions::default();
    let mut group = c.benchmark_group(format!("fit_campaign_{BATCH}_excitations_9ch_4096lines"));
    group.sample_size(10);
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        group.bench_function(format!("{threads}_threads"), |b| {
            b.iter(|| pool.install(|| fit_campaign(&geometry, &frf, &opts).unwrap()))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
