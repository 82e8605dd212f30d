//! Where `frf-est`'s time goes on one recording: the phases of the executable timed one
//! by one, best of `RUNS` runs each (reading and parsing the universal file with its
//! digest, the index, the hit checks, τ, windows + FFT + spectral sums, the estimates, the
//! UFF mapping, the run record, MCAP encoding).
//!
//! ```sh
//! python3 scripts/refgen/rbref.py scripts/refgen/examples/tc2-impact-time.toml \
//!     --time-layout per-hit --binary -o rec.uff --truth truth.json
//! cargo bench -p rbprops-cli --bench frfest_phases -- rec.uff [RUNS]
//! ```
//!
//! Without a file argument it prints this usage and exits (so `cargo bench` over the
//! workspace passes). Figures: docs/results.md, "FRFs from impact time histories".

use rbprops_cli::frf_est::{estimate_uff_timed, EstimationOptions, PhaseTimes};
use std::collections::BTreeMap;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let Some(path) = args.first() else {
        eprintln!("usage: cargo bench -p rbprops-cli --bench frfest_phases -- FILE.uff [RUNS]");
        return;
    };
    let runs: usize = args.get(1).and_then(|r| r.parse().ok()).unwrap_or(5);
    let mut best: BTreeMap<usize, (&'static str, f64)> = BTreeMap::new();
    let mut keep = |k: usize, name: &'static str, t: f64| {
        let e = best.entry(k).or_insert((name, f64::INFINITY));
        e.1 = e.1.min(t);
    };
    let mut total = f64::INFINITY;
    for _ in 0..runs {
        let t0 = Instant::now();
        let mut th =
            rbprops_cli::read_time_histories(std::path::Path::new(path)).expect("readable");
        keep(
            0,
            "read + parse + SHA-256 + set aside",
            t0.elapsed().as_secs_f64(),
        );
        let mut times = PhaseTimes::default();
        let est = estimate_uff_timed(
            &mut th.data,
            th.samples.as_ref(),
            &Default::default(),
            &EstimationOptions::default(),
            &mut times,
        )
        .expect("estimated");
        for (k, (name, t)) in times.phases.iter().enumerate() {
            keep(k + 1, name, *t);
        }
        let t1 = Instant::now();
        let bytes = rbprops_formats::mcap_file::write(&est.record).expect("encoded");
        keep(100, "MCAP encoding", t1.elapsed().as_secs_f64());
        total = total.min(t0.elapsed().as_secs_f64());
        assert!(!bytes.is_empty());
    }
    println!(
        "{path}: best of {runs} per phase ({} threads)",
        rayon::current_num_threads()
    );
    for (name, t) in best.values() {
        println!("  {name:<32} {:8.1} ms", 1e3 * t);
    }
    println!("  {:<32} {:8.1} ms (best whole run)", "total", 1e3 * total);
}
