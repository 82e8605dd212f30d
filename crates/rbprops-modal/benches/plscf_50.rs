//! The poly-reference workload: one set-up of 50 excitations × 9 channels ×
//! 1,000 lines (accelerance, 0–12.5 Hz, 1 % noise; the Test Case II body on springs,
//! its three triaxial accelerometers, fifty oblique forces at the three points), fitted
//! with the poly-reference method (`Method::Plscf`) and with the default per-excitation
//! fit (`Method::Lscf`, one pole set per excitation), on 1 and 2 rayon threads.
//!
//! `cargo bench -p rbprops-modal --bench plscf_50 [-- repeats] [plscf|lscf]` prints, per method and
//! thread count, the median wall time per fit and the process CPU time (user + sys,
//! `getrusage`) per fit — on a machine shared with other work the CPU time is the
//! steadier figure — and the ratio poly-reference / per-excitation. It also checks that
//! the poly-reference fit is byte-identical on 1 and 2 threads. With
//! `--features phase-timing` it prints where the poly-reference time goes (`prof`);
//! with `PLSCF_50_DUMP=prefix` it writes each fit's records to `prefix-<method>-<threads>.txt`.

use rbprops_core::Quantity;
use rbprops_modal::{fit_campaign, prof, FitOptions, Method, ModalFitOutput};
use rbprops_testkit::synthetic::{self, Synthetic};
use std::time::Instant;

const EXCITATIONS: usize = 50;
const LINES: usize = 1000;

/// Fifty force directions spread over the sphere (a Fibonacci spiral), at the three
/// accelerometer points in turn: every rigid-body mode is excited by many of them.
fn workload() -> Synthetic {
    let body = synthetic::test_case_body();
    let forces = synthetic::fibonacci_forces(EXCITATIONS);
    let geometry = synthetic::test_case_geometry(&body, &forces);
    let modes = synthetic::spring_modes(
        &body,
        [60.0, 90.0, 200.0],
        &[0.012, 0.015, 0.010, 0.018, 0.014, 0.020],
    );
    let frf = synthetic::synthesise(&geometry, &modes, 12.5, LINES, Quantity::Accelerance);
    Synthetic {
        geometry,
        modes,
        frf,
    }
    .with_noise(0.01, 7)
}

/// User + system CPU time of the whole process so far (s).
fn cpu_seconds() -> f64 {
    // SAFETY: getrusage fills the zeroed struct for our own process.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) };
    let tv = |t: libc::timeval| t.tv_sec as f64 + 1e-6 * t.tv_usec as f64;
    tv(u.ru_utime) + tv(u.ru_stime)
}

/// Median wall and median CPU time (ms) per fit over `repeats` fits, and the last output.
fn time_fits(
    s: &Synthetic,
    opts: &FitOptions,
    threads: usize,
    repeats: usize,
) -> (f64, f64, ModalFitOutput) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let (mut wall, mut cpu) = (Vec::new(), Vec::new());
    let mut last = None;
    for _ in 0..repeats {
        let (t, c) = (Instant::now(), cpu_seconds());
        last = Some(pool.install(|| fit_campaign(&s.geometry, &s.frf, opts).unwrap()));
        wall.push(1e3 * t.elapsed().as_secs_f64());
        cpu.push(1e3 * (cpu_seconds() - c));
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    (median(&mut wall), median(&mut cpu), last.unwrap())
}

fn main() {
    let repeats: usize = std::env::args()
        .skip(1)
        .find_map(|s| s.parse().ok())
        .unwrap_or(5);
    // `plscf` or `lscf` after the repeats: that method alone (no ratio printed).
    let only = std::env::args()
        .skip(1)
        .find(|a| a == "plscf" || a == "lscf");
    let s = workload();
    println!(
        "{} excitations × {} channels × {} lines, median of {repeats} fits:",
        s.frf.n_excitations,
        s.frf.n_channels,
        s.frf.n_lines()
    );
    let mut per_method = Vec::new();
    for (name, method) in [
        ("poly-reference (plscf)", Method::Plscf),
        ("per-excitation (lscf)", Method::Lscf),
    ]
    .into_iter()
    .filter(|(_, m)| match only.as_deref() {
        Some("plscf") => *m == Method::Plscf,
        Some(_) => *m == Method::Lscf,
        None => true,
    }) {
        let opts = FitOptions {
            method,
            ..Default::default()
        };
        let mut outs = Vec::new();
        for threads in [1, 2] {
            let (wall, cpu, out) = time_fits(&s, &opts, threads, repeats);
            let modes = out.record.modes.len() as f64 / s.frf.n_excitations as f64;
            println!(
                "  {name}, {threads} thread(s): wall {wall:.0} ms, CPU {cpu:.0} ms per fit ({modes:.1} modes per excitation)"
            );
            per_method.push((method, threads, wall, cpu));
            outs.push(format!("{:?}", out.record));
            // `PLSCF_50_DUMP=prefix`: the records as text, to compare two builds.
            if let Some(prefix) = std::env::var_os("PLSCF_50_DUMP") {
                let path = format!("{}-{method:?}-{threads}.txt", prefix.to_string_lossy());
                std::fs::write(path, outs.last().unwrap()).unwrap();
            }
        }
        assert!(
            outs[0] == outs[1],
            "{name}: the fit differs between 1 and 2 threads"
        );
    }
    for threads in [1, 2].into_iter().filter(|_| only.is_none()) {
        let get = |m: Method| {
            per_method
                .iter()
                .find(|r| r.0 == m && r.1 == threads)
                .map(|r| (r.2, r.3))
                .unwrap()
        };
        let (p, l) = (get(Method::Plscf), get(Method::Lscf));
        println!(
            "  {threads} thread(s): plscf / lscf = {:.2} wall, {:.2} CPU",
            p.0 / l.0,
            p.1 / l.1
        );
    }
    if let Some(totals) = prof::totals() {
        println!("  phases (all fits, both methods, all threads; wall summed over threads):");
        for (i, (calls, secs)) in totals.iter().enumerate() {
            println!(
                "    {:<26} {:>9.1} ms in {calls} calls",
                prof::PHASES[i],
                1e3 * secs
            );
        }
    }
}
