//! Model-check speed on 1000-line × 9-channel × 3-excitation recordings with three
//! concealed effects and 1 % noise, made by the independent reference generator
//! (`fixtures/model-check/bench/`, see its README).
//!
//! ```sh
//! RAYON_NUM_THREADS=2 cargo bench -p rbprops-check --bench check_speed \
//!     [--features phase-timing] -- [--case STEM] [--repeat N]
//! ```
//!
//! Prints per case: wall and CPU time, the effects named against the concealed ones,
//! χ²/ν before → after, the time line of the check's stages (from its progress lines,
//! with the model evaluations made since the previous line under `phase-timing`), a
//! digest of the report (equal digests at 1 and 2 threads: the output does not depend
//! on the thread count) and, with `phase-timing`, thread-seconds per phase. Then the
//! anatomy of one model evaluation in CPU time: as the check makes it, by the
//! simulator's column solve and by its inverse, the set-up models alone.
//!
//! Current figures (2 threads, `phase-timing`; 2-core machine shared with other work,
//! load 8–10, so wall times (29.9, 37.7, 27.2 s) are inflated and CPU seconds are the
//! comparable figure; the reference, the code before these changes, gave 23.4 CPU s on
//! the first case under such load and 22.6 idle): gain-orient-gauge 14.2 CPU s / 7 572
//! evaluations (before 22.6 / 9 807), position-force-elastic 19.8 / 13 737
//! (32.6 / 17 104), gravity-window-gain 12.8 / 8 265 (22.5 / 11 147); 1.9, 1.4 and
//! 1.5 ms CPU per evaluation all in. Idle, the wall time was 0.58 × CPU s, so about 8,
//! 11 and 7 s: under the 20 s worst case, not under the 5 s typical. Each names its
//! three concealed effects and nothing else with χ²/ν 0.986, 0.975 and 0.995 as before,
//! every screening step finds as many significant candidates and refits the same ones;
//! report digests 7daafb35d6ea4778, 84036c32b012f0ca, 6b319ca0a56017bd (equal at 1 and
//! 2 threads; they moved: the elastic-mode profile's last bits, and a profile point no
//! longer chord-refined keeps its lower one-point gain).
//! Changes: the profile screening chord-refines only the 8 points per start whose first
//! chord step promises most, and a grid of more than 100 points (the cords', ~170
//! string-mode frequencies 2 % apart × 2 starts, each an evaluation of the slow cords'
//! model; this profile was half the CPU time) is first evaluated at every other point,
//! then at the skipped neighbours of the most promising ones (screening evaluations per
//! step on the first case 1 493 / 1 318 / 831 / 882 → 603 / 457 / 490 / 739; the
//! coarse pass alone changed no digest); `resonance::profile_starts` takes its line
//! factor per line, not per value; extra modes (the cords' string modes) are added in
//! line blocks that stay in L1, and the noise model's quantile fit takes ln(s/q_r) once
//! per value, not per grid point (both bit-identical; the noise phase halved). Where the
//! time goes (perf, first case, 1 thread, self time, before the coarse pass; 16.3 CPU s
//! and the same digest at 1 thread): the per-line solve 20 %, extra-mode terms 8 %,
//! `lm::gram` and `tr_mul` 10 %, the noise model 9 % (before its ln change), the cords'
//! eigen-decomposition 4 %, `profile_starts` 3.5 % (8 % before); the cords' profile was
//! still about a third of the CPU time then (~350 evaluations per step at ~3.5 ms).
//! By stage the candidate refits are now the largest share of the evaluations (5 159 of
//! 7 572), the screening's Jacobians and the backward fits next. Next: grouped
//! finite-difference columns for parameters that touch disjoint cells (an elastic mode's
//! 27 residues, the channel gains), and a cheaper reduction of the cords' model.
//!
//! The tables below are the history, each with the code of its time (gravity-window-gain
//! then still named a false `elastic_mode`; see docs/results.md, "Model check speed").
//!
//! Figures (2-core machine shared with other builds, load 10–16: wall times were 45–660 s
//! and are not comparable, CPU seconds are; `--features phase-timing`, 2 threads; two
//! free cores would give about CPU/2 of wall time, i.e. 11, 16 and 23 s):
//!
//! | case | CPU s before | CPU s after | model evaluations | named (all three concealed) |
//! |---|---|---|---|---|
//! | gain-orient-gauge | 27.9 | 21.9 | 8181 → 8036 | same; χ²/ν 142.236 → 0.970 both |
//! | position-force-elastic | not re-measured | 31.1 | 14520 after | same; χ²/ν 3359.213 → 0.975 |
//! | gravity-window-gain | 74.1 | 45.5 | 24950 → 24911 | same, with the false `elastic_mode`; χ²/ν 156.956 → 1.980 both |
//!
//! One model evaluation of the nominal model (27 000 values): 1.08 ms CPU before
//! (inverse of Z, `S G` per line), 0.53 ms after ([`rbprops_sim::SolveMethod::Columns`]:
//! one LU per line solved for the three force columns; the same under an exponential
//! window, which before took one nalgebra LU per input and line); set-up models
//! 0.004 ms. The two solves differ by 5e-14 relative at most (model rounding), so report
//! digests moved (986a20fda0c3ec5b → 16e695e2e9371eb3 on the first case) while every
//! named effect and χ²/ν to the digits printed stayed. The model evaluations are now a
//! minority of the time: the rest is spread over the normal equations (`lm::gram`,
//! ~12 %), the screening's SVDs and eigen-decompositions, the noise model and the
//! cross-validation (`perf record` of the first case).
//!
//! Later figures (same command, same load of 10–16; the reference run was re-measured in
//! the same session, since CPU seconds too move with the load, 21.9 → 27.0 s on the
//! first case). Changes: the chord solver's SVD of the current Jacobian taken once per
//! screening step instead of once per profile-screened candidate; a profile's points
//! refined in parallel (same best point); `lm::gram`/`tr_mul` two columns per pass; the
//! held-out folds' information summed in place; `lm::fit` keeps its last Jacobian when no
//! step followed it. All bit-identical: report digests unchanged.
//!
//! | case | CPU s before → after | model evaluations | ms CPU per evaluation, all in | report digest (unchanged) |
//! |---|---|---|---|---|
//! | gain-orient-gauge | 27.0 → 24.3 | 9 803 | 2.5 | 6eb49ea7241b12bc |
//! | position-force-elastic | 39.5 → 35.7 | 17 099 | 2.1 | bd0f8c804e4d13e3 |
//! | gravity-window-gain | 54.5 → 46.2 | 27 978 | 1.7 | 860332042e338d0f |
//!
//! Wall time on two free cores would be about CPU/2: 12, 18 and 23 s (goal: 5 s typical,
//! 20 s worst; not met). Where the evaluations go (counts from the stage lines): the
//! screening steps with the backward fits 4 520 / 8 817 / 15 947 and 61–68 % of the
//! wall time, the candidate refits 5 159 / 8 278 / 11 650 and 25–32 %, the rest (noise
//! floors, final report) under 8 %. One evaluation of the nominal model is 0.5 ms, but
//! the screening's profiles evaluate the cords' model (a 102-dof modal reduction per
//! evaluation) and their chord steps read the 54 000 × p singular vectors each
//! (`SVD::solve`). perf of the first case after the change (self time; before in
//! brackets): the per-line solve 15 % (14), extra-mode terms (the cords' string modes)
//! 12 % (9), the elastic-mode profile `resonance::profile_starts` (999 lines × 6 damping
//! ratios × 27 000 values per step) 7 % (7), `SVD::solve` 7 % (6), the cords' modal
//! reduction 9 % (10), the noise model 6 % (5), `lm::gram` 5 % (10), the screening's
//! tall SVDs 4 % (5). Next: `profile_starts` with its line factors computed per line
//! rather than per value, and fewer or cheaper profile points for the cords.

#[path = "bench_recording.rs"]
mod bench_recording;

use bench_recording::{nominal, recording, CASES};
use rbprops_check::{check, prof, CheckOptions, Progress};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// CPU seconds of this process so far, all threads (the sum of the first field of
/// `/proc/self/task/*/schedstat`, nanoseconds on a CPU; Linux): on a shared machine
/// the comparable figure, where wall time depends on the other load. `NaN` elsewhere.
fn cpu_seconds() -> f64 {
    let Ok(tasks) = std::fs::read_dir("/proc/self/task") else {
        return f64::NAN;
    };
    let mut ns = 0u64;
    for t in tasks.flatten() {
        if let Ok(s) = std::fs::read_to_string(t.path().join("schedstat")) {
            ns += s
                .split_whitespace()
                .next()
                .and_then(|v| v.parse::<u64>().ok())
                .unwrap_or(0);
        }
    }
    ns as f64 * 1e-9
}

/// Model evaluations so far (calls of the `predict` phase; 0 without `phase-timing`).
fn evaluations() -> u64 {
    prof::totals().map_or(0, |t| t[prof::PREDICT].0)
}

/// FNV-1a of the report's JSON: a short stand-in for comparing whole reports.
fn digest(s: &str) -> u64 {
    s.bytes().fold(0xcbf29ce484222325u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x100000001b3)
    })
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut only: Option<String> = None;
    let mut repeat = 1usize;
    let mut i = 0;
    while i < args.len() {
        match args[i].as_str() {
            "--case" => {
                only = args.get(i + 1).cloned();
                i += 1;
            }
            "--repeat" => {
                repeat = args
                    .get(i + 1)
                    .and_then(|s| s.parse().ok())
                    .expect("--repeat N");
                i += 1;
            }
            _ => {} // `cargo bench` passes `--bench`; filters are not used
        }
        i += 1;
    }
    let spec = nominal();
    println!(
        "model-check speed: {} rayon threads{}",
        rayon::current_num_threads(),
        if prof::totals().is_some() {
            ", phase timing on"
        } else {
            ""
        }
    );
    let mut times = Vec::new();
    for (stem, concealed) in CASES {
        if only.as_deref().is_some_and(|o| o != stem) {
            continue;
        }
        let (geometry, frf) = recording(stem);
        for _ in 0..repeat {
            prof::reset();
            let c0 = cpu_seconds();
            let t0 = Instant::now();
            let lines: Arc<Mutex<Vec<(f64, u64, String)>>> = Arc::default();
            let sink = lines.clone();
            let opts = CheckOptions {
                progress: Progress::new(move |l| {
                    sink.lock().unwrap().push((
                        t0.elapsed().as_secs_f64(),
                        evaluations(),
                        l.to_string(),
                    ))
                }),
                ..Default::default()
            };
            let out = check(&spec, &geometry, &frf, &opts).expect("check");
            let dt = t0.elapsed().as_secs_f64();
            let cpu = cpu_seconds() - c0;
            times.push((stem, dt));
            let r = &out.report;
            let mut named: Vec<String> = r.accepted.iter().map(|a| a.id.clone()).collect();
            for f in &r.ambiguous {
                named.push(format!("{{{}}}", f.ids.join("|")));
            }
            let missed: Vec<&str> = concealed
                .iter()
                .copied()
                .filter(|c| !named.iter().any(|n| n.contains(c)))
                .collect();
            println!("\n== {stem}: {dt:.2} s wall, {cpu:.2} CPU s");
            println!("  concealed {concealed:?}");
            println!("  named     {named:?}; missed {missed:?}");
            println!(
                "  χ²/ν {:.3} → {:.3} (band {:.3}–{:.3}), floor reached: {}",
                r.chi2_nu_before,
                r.chi2_nu_after,
                r.noise_band[0],
                r.noise_band[1],
                r.noise_floor_reached
            );
            for m in r
                .method
                .iter()
                .filter(|m| m.starts_with("noise re-estimated"))
            {
                println!("  {m}");
            }
            let json = serde_json::to_string(r).expect("report json");
            println!("  report digest {:016x}", digest(&json));
            println!(
                "  stages (s at the end of each; Δ since the previous; model evaluations since the previous, with phase-timing):"
            );
            let (mut last, mut last_n) = (0.0, 0);
            for (t, n, l) in lines.lock().unwrap().iter() {
                println!("    {t:7.2} (+{:6.2}) {:>6}  {l}", t - last, n - last_n);
                (last, last_n) = (*t, *n);
            }
            println!(
                "    {dt:7.2} (+{:6.2}) {:>6}  done",
                dt - last,
                evaluations() - last_n
            );
            if let Some(tot) = prof::totals() {
                println!("  phases (calls, thread-seconds; nested, see prof::PHASES):");
                for ((n, s), name) in tot.iter().zip(prof::PHASES) {
                    println!("    {name:<45} {n:>7} {s:9.2}");
                }
            }
        }
    }
    if !times.is_empty() {
        let worst = times.iter().map(|t| t.1).fold(0.0, f64::max);
        let mut v: Vec<f64> = times.iter().map(|t| t.1).collect();
        v.sort_by(f64::total_cmp);
        println!(
            "\nsummary: {} runs, median {:.2} s, worst {:.2} s",
            v.len(),
            v[v.len() / 2],
            worst
        );
    }
    model_evaluation_anatomy(&spec);
}

/// One model evaluation of the nominal spec on the bench axis as the check makes it
/// ([`rbprops_sim::SolveMethod::Columns`]), the same with the simulator's default solve
/// (`Direct`: the inverse of Z and `S G` per line, what the check used before), and the
/// set-up models alone (mass, stiffness, damping, modes): the remainder is the per-line
/// solve and the assembly of the FRFs. Also the largest relative difference between the
/// two solves (rounding).
fn model_evaluation_anatomy(spec: &rbprops_sim::CampaignSpec) {
    use rbprops_sim::{SimOptions, SolveMethod};
    let (geometry, frf) = recording(CASES[0].0);
    let layout = rbprops_check::predict::Layout::new(spec, &geometry, &frf).expect("layout");
    let n = 200;
    // CPU time of the process (the column solve runs on the rayon pool, not here).
    let time = |f: &dyn Fn()| {
        let c0 = cpu_seconds();
        for _ in 0..n {
            f();
        }
        (cpu_seconds() - c0) / n as f64
    };
    let whole = time(&|| {
        std::hint::black_box(rbprops_check::predict::predict(spec, &layout, &[]).unwrap());
    });
    let axis = &layout.frequency_hz[1..];
    let sim = |method| {
        rbprops_sim::simulate::predict(
            spec,
            &layout.spec_geometry,
            &[],
            axis,
            &SimOptions { method },
        )
        .unwrap()
        .0
    };
    let direct = time(&|| {
        std::hint::black_box(sim(SolveMethod::Direct));
    });
    let columns = time(&|| {
        std::hint::black_box(sim(SolveMethod::Columns));
    });
    let models = time(&|| {
        std::hint::black_box(
            rbprops_sim::simulate::build_models(spec, &layout.spec_geometry, &[]).unwrap(),
        );
    });
    let (a, b) = (sim(SolveMethod::Direct), sim(SolveMethod::Columns));
    let rel = a
        .values
        .iter()
        .zip(&b.values)
        .map(|(x, y)| (x - y).norm() / x.norm().max(f64::MIN_POSITIVE))
        .fold(0.0, f64::max);
    println!(
        "\none model evaluation ({} values, CPU ms): {:.3} ms as the check makes it; \
         simulator only: {:.3} ms by the column solve, {:.3} ms by the inverse (Direct); \
         set-up models {:.3} ms; largest relative difference Direct vs Columns {rel:.1e}",
        layout.n_values(),
        whole * 1e3,
        columns * 1e3,
        direct * 1e3,
        models * 1e3
    );
}
