//! Per-hit cost of the FRF estimation chain: inspect the hit, set its windows, add it to
//! the spectral sums (force + 9 responses, 16 384-sample records), and the H1 of the sums.
//!
//! `cargo bench -p rbprops-frfest` (criterion; per-iteration time = per hit).

use criterion::{criterion_group, criterion_main, Criterion};
use rbprops_frfest::*;
use std::f64::consts::{PI, TAU};

const N: usize = 16_384;
const FS: f64 = 4096.0;
const CH: usize = 9;

fn record() -> (Vec<f64>, Vec<Vec<f64>>) {
    let f: Vec<f64> = (0..N)
        .map(|i| {
            let t = i as f64 / FS - 0.05;
            let noise = 0.05 * ((i * 7919 % 101) as f64 / 50.0 - 1.0);
            noise
                + if t > 0.0 && t < 0.003 {
                    200.0 * (PI * t / 0.003).sin()
                } else {
                    0.0
                }
        })
        .collect();
    let x = (0..CH)
        .map(|c| {
            (0..N)
                .map(|i| {
                    let t = i as f64 / FS - 0.05;
                    if t > 0.0 {
                        (-t * (2.0 + c as f64)).exp() * (TAU * (5.0 + 3.0 * c as f64) * t).sin()
                    } else {
                        0.0
                    }
                })
                .collect()
        })
        .collect();
    (f, x)
}

fn bench(c: &mut Criterion) {
    let (f, x) = record();
    let xr: Vec<&[f64]> = x.iter().map(|v| v.as_slice()).collect();
    let opts = HitCheckOptions::default();
    let fw = ForceWindow {
        pre_s: 0.01,
        post_s: 0.01,
        taper_s: 0.0,
    };
    let rw = ResponseWindow::Exponential { tau_s: 1.0 };
    let mut sums = SpectralSums::new(N, FS, 1, CH).unwrap();
    let mut win = HitWindows::new(N);
    c.bench_function(
        "per hit: inspect + windows + add (1 force + 9 responses, N = 16384)",
        |b| {
            b.iter(|| {
                let rep = inspect_hit(&f, &xr, FS, &opts);
                win.set(FS, rep.trigger, rep.pulse_end, Some(&fw), &rw, true);
                sums.add_windowed_hit(&[&f], &xr, Some(&win.force), Some(&win.response))
                    .unwrap();
            })
        },
    );
    c.bench_function("H1 + variance of the sums (9 channels, 8193 lines)", |b| {
        b.iter(|| sums.h1(None, &ConditioningOptions::default()).unwrap())
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
