//! Per-excitation cost of the default fit on 9 channels × 4,096 lines (the issue's
//! workload shape). Usage: `RAYON_NUM_THREADS=1 cargo run --release -p rbprops-modal
//! --example timing [--features phase-timing] -- [excitations] [setup]`; prints ms per
//! excitation (and per phase with the feature). With `setup`, one pole set per
//! suspension set-up (`--poles setup`) instead of per excitation. Environment:
//! `TIMING_DIGEST` prints a hash of every estimate's bits, `TIMING_DUMP=file` writes
//! every estimate (one mode a line), `TIMING_GEN_ONLY` stops after the data generation.

use rbprops_modal::{fit_campaign, FitOptions, PoleMode};
use rbprops_testkit::synthetic;
use std::time::Instant;

fn main() {
    let batch: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(24);
    let (geometry, frf) = synthetic::bench_campaign(batch);
    // The data generation alone (to subtract from instruction counts of whole runs).
    if std::env::var_os("TIMING_GEN_ONLY").is_some() {
        println!("{} values generated", frf.values.len());
        return;
    }
    let mut opts = FitOptions::default();
    if std::env::args().nth(2).as_deref() == Some("setup") {
        opts.poles = PoleMode::PerSetup;
    }
    let t = Instant::now();
    let cpu0 = cpu_seconds();
    let out = fit_campaign(&geometry, &frf, &opts).unwrap();
    let dt = t.elapsed().as_secs_f64();
    let cpu = cpu_seconds().zip(cpu0).map(|(a, b)| a - b);
    let modes = out.record.modes.len();
    // A digest of every estimate's bits, to check that a change is bit-identical.
    if std::env::var_os("TIMING_DIGEST").is_some() {
        let mut h: u64 = 0xcbf29ce484222325;
        let mut eat = |x: f64| {
            for b in x.to_bits().to_le_bytes() {
                h = (h ^ b as u64).wrapping_mul(0x100000001b3);
            }
        };
        for m in &out.record.modes {
            eat(m.frequency_hz);
            eat(m.damping_ratio);
            eat(m.frequency_std_hz);
            eat(m.damping_std);
            for (a, s) in m.residues.iter().zip(&m.residue_std) {
                eat(a.re);
                eat(a.im);
                eat(*s);
            }
        }
        println!("digest {h:016x}");
    }
    // Every estimate in full precision, one mode a line, to compare two builds.
    if let Some(path) = std::env::var_os("TIMING_DUMP") {
        let mut text = String::new();
        for m in &out.record.modes {
            let mut line = format!(
                "{:e} {:e} {:e} {:e}",
                m.frequency_hz, m.damping_ratio, m.frequency_std_hz, m.damping_std
            );
            for (a, s) in m.residues.iter().zip(&m.residue_std) {
                line += &format!(" {:e} {:e} {:e}", a.re, a.im, s);
            }
            text += &line;
            text.push('\n');
        }
        std::fs::write(path, text).expect("TIMING_DUMP file");
    }
    if std::env::var_os("TIMING_VERBOSE").is_some() {
        for w in &out.record.excitations[0].warnings {
            println!("{w}");
        }
    }
    println!(
        "{batch} excitations, {} threads, poles {:?}: {:.2} ms per excitation ({modes} modes)",
        rayon::current_num_threads(),
        opts.poles,
        1e3 * dt / batch as f64
    );
    // On-CPU time of all threads (excludes time waiting for a core on a busy machine).
    if let Some(cpu) = cpu {
        println!(
            "  cpu time (all threads)   {:>8.2} ms per excitation",
            1e3 * cpu / batch as f64
        );
    }
    if let Some(totals) = rbprops_modal::prof::totals() {
        for (name, (calls, secs)) in rbprops_modal::prof::PHASES.iter().zip(totals) {
            println!(
                "  {name:<26} {:>8.2} ms per excitation ({calls} calls)",
                1e3 * secs / batch as f64
            );
        }
    }
}

/// Seconds on a CPU of every thread of this process so far (Linux
/// `/proc/self/task/*/schedstat`, nanosecond resolution), or `None` elsewhere.
fn cpu_seconds() -> Option<f64> {
    let mut ns = 0u64;
    for task in std::fs::read_dir("/proc/self/task").ok()? {
        let stat = std::fs::read_to_string(task.ok()?.path().join("schedstat")).ok()?;
        ns += stat.split_whitespace().next()?.parse::<u64>().ok()?;
    }
    Some(ns as f64 * 1e-9)
}
