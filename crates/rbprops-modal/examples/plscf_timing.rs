//! Cost of one poly-reference fit (`Method::Plscf`) of a set-up of 3 excitations ×
//! 9 channels × 1,000 lines (accelerance, 0–12.5 Hz, 1 % noise, the Test Case II body
//! on springs). Usage: `cargo run --release -p rbprops-modal --example plscf_timing --
//! [repeats]`; prints the median and the minimum wall time of a whole fit
//! (`fit_campaign`: sweep, selection, shapes, records) on one thread.

use rbprops_core::Quantity;
use rbprops_modal::{fit_campaign, testdata, FitOptions, Method};
use std::time::Instant;

fn main() {
    let repeats: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(21);
    let s = testdata::test_case(12.5, 1000, Quantity::Accelerance).with_noise(0.01, 7);
    let opts = FitOptions {
        method: Method::Plscf,
        ..Default::default()
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let mut ms = Vec::with_capacity(repeats);
    let mut modes = 0;
    for _ in 0..repeats {
        let t = Instant::now();
        let out = pool.install(|| fit_campaign(&s.geometry, &s.frf, &opts).unwrap());
        ms.push(1e3 * t.elapsed().as_secs_f64());
        modes = out.record.modes.len() / s.frf.n_excitations;
    }
    ms.sort_by(f64::total_cmp);
    println!(
        "plscf, {} excitations × {} channels × {} lines: median {:.2} ms, min {:.2} ms over {repeats} fits ({modes} modes)",
        s.frf.n_excitations,
        s.frf.n_channels,
        s.frf.n_lines(),
        ms[ms.len() / 2],
        ms[0]
    );
}
