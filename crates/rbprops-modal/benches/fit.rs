//! Per-excitation cost of the default fit (LSCF + refinement + LSFD) on
//! 9 channels × 4,096 lines, on 1 and 2 rayon threads.
//!
//! The workload is 1,000 excitations; the loop fits a batch of
//! `BATCH` excitations ([`synthetic::bench_campaign`]: copies of three Test-Case-like
//! excitations with different noise, the data of the `timing` example)
//! and criterion reports the batch time: per-excitation cost = time / BATCH.

use criterion::{criterion_group, criterion_main, Criterion};
use rbprops_modal::{fit_campaign, FitOptions};
use rbprops_testkit::synthetic;

/// 96, not fewer: the excitations' costs differ (some need a safety sweep), and with 24
/// the two threads' shares were uneven enough to read as a 1.7 speed-up.
const BATCH: usize = 96;

fn bench(c: &mut Criterion) {
    let (geometry, frf) = synthetic::bench_campaign(BATCH);
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
