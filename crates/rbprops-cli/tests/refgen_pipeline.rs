//! The whole pipeline (`modal-fit | ni-select | rb-solve`) on recordings that rbprops-sim
//! did NOT make: `scripts/refgen` (Python/numpy: finite-rotation potential energy, Newton
//! equilibrium, finite-difference Hessian, state-space solve), through `$RBPROPS_PYTHON`.
//! Unset: the tests print a note and pass, unless `RBPROPS_REQUIRE_PYTHON=1` (CI), which
//! makes that a failure.
//!
//! Cases (`scripts/refgen/examples`): a 15.8 kg body on four vertical cords under gravity,
//! 3 excitations × 9 channels × 1000 lines of accelerance with 1 % complex noise, whose
//! two pendulum modes are
//! - `repeated-cords`: one root of multiplicity two (and so are the two rocking modes:
//!   Jxx = Jyy, cords on a square), and
//! - `near-repeated-cords`: 0.3 % apart at 0.50 Hz with ζ = 2 % (0.15 half-bandwidths: one
//!   peak), which single-reference fits merge.

use rbprops_cli::stages;
use rbprops_core::records::{InertiaEstimate, SelectionRecord};
use rbprops_formats::topics;
use rbprops_inertia::{Estimator, SolveOptions};
use rbprops_modal::{FitOptions, Method};
use std::path::Path;

const REPO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");

fn python() -> Option<String> {
    match std::env::var("RBPROPS_PYTHON") {
        Ok(p) if !p.is_empty() => Some(p),
        _ => {
            if std::env::var("RBPROPS_REQUIRE_PYTHON").is_ok_and(|v| v == "1") {
                panic!("RBPROPS_REQUIRE_PYTHON=1 but RBPROPS_PYTHON is not set");
            }
            eprintln!("note: RBPROPS_PYTHON is not set: the independent-generator test is skipped");
            None
        }
    }
}

/// What the generator says is true: mass, inertia about the CoM, the set-up's poles (Hz).
struct Truth {
    mass: f64,
    inertia: [[f64; 3]; 3],
    frequencies_hz: Vec<f64>,
}

fn read_truth(path: &Path) -> Truth {
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    let p = &v["properties"];
    let inertia = std::array::from_fn(|i| {
        std::array::from_fn(|j| p["inertia_cm_kg_m2"][i][j].as_f64().unwrap())
    });
    let frequencies_hz = v["setups"][0]["undamped_frequencies_hz"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_f64().unwrap())
        .collect();
    Truth {
        mass: p["mass_kg"].as_f64().unwrap(),
        inertia,
        frequencies_hz,
    }
}

/// Generates `case` (an example of `scripts/refgen`) for seeds `seeds` (`"A:B"`) with
/// extra `--set` options; returns (recording, truth) paths per seed.
fn generate(
    py: &str,
    dir: &Path,
    case: &str,
    seeds: std::ops::RangeInclusive<u64>,
    sets: &[&str],
) -> Vec<(std::path::PathBuf, std::path::PathBuf)> {
    let mut cmd = std::process::Command::new(py);
    cmd.arg(format!("{REPO}/scripts/refgen/rbref.py"))
        .arg(format!("{REPO}/scripts/refgen/examples/{case}.toml"))
        .args(["--seeds", &format!("{}:{}", seeds.start(), seeds.end())])
        .arg("-o")
        .arg(dir.join(format!("{case}-{{seed}}.uff")))
        .arg("--truth")
        .arg(dir.join(format!("{case}-{{seed}}.json")))
        .args(["--binary", "--quiet"]);
    for s in sets {
        cmd.args(["--set", s]);
    }
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "refgen {case}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    seeds
        .map(|s| {
            (
                dir.join(format!("{case}-{s}.uff")),
                dir.join(format!("{case}-{s}.json")),
            )
        })
        .collect()
}

/// The pipeline's result on one recording.
struct Run {
    selection: SelectionRecord,
    estimates: Vec<InertiaEstimate>,
    warnings: Vec<String>,
}

fn pipeline(rec: &Path, fit: &FitOptions, window_s: Option<f64>) -> Run {
    let input = rbprops_cli::read_input(Some(rec)).unwrap();
    let mut r = input.record;
    let fo = stages::modal_fit_windowed(&mut r, fit, window_s, "test").unwrap();
    let mut warnings: Vec<String> = fo
        .record
        .excitations
        .iter()
        .flat_map(|e| e.warnings.clone())
        .collect();
    for m in &fo.record.modes {
        eprintln!(
            "  fit {} mode {}: {:.5} Hz, ζ {:.4}, weak {}",
            m.excitation, m.mode, m.frequency_hz, m.damping_ratio, m.weak
        );
    }
    let so = stages::ni_select(&mut r, &Default::default(), "test").unwrap();
    warnings.extend(so.record.warnings.iter().cloned());
    for w in &warnings {
        eprintln!("  warning: {w}");
    }
    for m in &so.record.selected {
        eprintln!(
            "  selected mode {}: {:.5} Hz from {} (strength {:.3e})",
            m.mode, m.frequency_hz, m.excitation, m.strength
        );
    }
    for m in &so.record.missing {
        eprintln!("  missing mode {}: {:.5} Hz", m.mode, m.frequency_hz);
    }
    let opts = SolveOptions {
        estimators: vec![Estimator::BretlConti, Estimator::ToivolaNuutila],
        ..Default::default()
    };
    let out = stages::rb_solve(&mut r, &opts, false, "test").unwrap();
    warnings.extend(out.warnings.iter().cloned());
    let selection = r.get_one(topics::SELECTION).unwrap().unwrap();
    Run {
        selection,
        estimates: out.estimates,
        warnings,
    }
}

/// ‖ΔJ‖/‖J‖ over the six independent entries (the paper's measure).
fn inertia_error(j: &[[f64; 3]; 3], t: &[[f64; 3]; 3]) -> f64 {
    let idx = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];
    let d: f64 = idx.iter().map(|&(a, b)| (j[a][b] - t[a][b]).powi(2)).sum();
    let n: f64 = idx.iter().map(|&(a, b)| t[a][b].powi(2)).sum();
    (d / n).sqrt()
}

fn plscf() -> FitOptions {
    FitOptions {
        method: Method::Plscf,
        ..Default::default()
    }
}

/// Runs `case` for `seeds` through the pipeline with `fit`; checks that ni-select gets
/// six modes, one at each of the generator's frequencies, and returns per seed the
/// Bretl–Conti and Toivola–Nuutila (mass error, inertia error) with the warnings.
fn six_modes(
    case: &str,
    seeds: std::ops::RangeInclusive<u64>,
    fit: &FitOptions,
) -> Vec<(Vec<(String, f64, f64)>, Vec<String>)> {
    let Some(py) = python() else {
        return Vec::new();
    };
    let dir = tempfile::tempdir().unwrap();
    let mut out = Vec::new();
    for (s, (rec, truth)) in seeds
        .clone()
        .zip(generate(&py, dir.path(), case, seeds, &[]))
    {
        let t = read_truth(&truth);
        let run = pipeline(&rec, fit, None);
        let mut f: Vec<f64> = run
            .selection
            .selected
            .iter()
            .map(|m| m.frequency_hz)
            .collect();
        f.sort_by(f64::total_cmp);
        eprintln!(
            "{case} seed {s}: selected {f:?}, truth {:?}",
            t.frequencies_hz
        );
        // The six rigid-body modes, matched in order to the generator's undamped
        // frequencies. 3e-4 relative: with the poly-reference refinement the largest
        // error measured over these seeds is 8.3e-5 (the 0.3 %-apart pair, 0.15
        // half-bandwidths: its split carries the most noise), 1.5e-5 to 4.7e-5 on the
        // other cases; the noise part is ~1e-5 per mode (1 % noise, ζ = 2 %, 27 FRFs
        // over ~16 lines per half-bandwidth). The sweep's poles alone were biased by up
        // to 6.5e-4 (the 4.00 Hz mode). Before the low-band sweep, four modes came out
        // (the pendulum pair merged, the yaw mode missed) and no estimator could run.
        assert_eq!(
            f.len(),
            6,
            "{case} seed {s}: {f:?}; missing {:?}",
            run.selection.missing
        );
        for (a, b) in f.iter().zip(&t.frequencies_hz) {
            assert!(
                (a / b - 1.0).abs() < 3e-4,
                "{case} seed {s}: {f:?} vs {:?}",
                t.frequencies_hz
            );
        }
        let mut est = Vec::new();
        for e in &run.estimates {
            let (dm, dj) = (
                e.mass_kg / t.mass - 1.0,
                inertia_error(&e.inertia_cm_kg_m2, &t.inertia),
            );
            eprintln!(
                "  {}: m {:.5} ({:+.3} %), J err {:.3} %, consistent {}, rigid-body consistent {:?}",
                e.method,
                e.mass_kg,
                100.0 * dm,
                100.0 * dj,
                e.physically_consistent,
                e.rigid_body_consistent
            );
            est.push((e.method.clone(), dm, dj));
        }
        out.push((est, run.warnings));
    }
    out
}

/// An exactly repeated root (two pendulum modes, and two rocking modes): the poly-
/// reference fit gives the six modes, reports each pair as one root of multiplicity two
/// and splits it into the reciprocal modal basis.
#[test]
fn repeated_pair_on_cords_gives_six_modes() {
    for (_, warnings) in six_modes("repeated-cords", 1..=3, &plscf()) {
        let repeated = warnings
            .iter()
            .filter(|w| w.contains("one root of multiplicity 2") && w.contains("reciprocal basis"))
            .count();
        // Both pairs, on each of the three excitations' records.
        assert!(repeated >= 2, "{warnings:?}");
    }
}

/// A pair 0.3 % apart (0.15 half-bandwidths at ζ = 2 %: one peak): six modes, the pair
/// kept as two roots.
#[test]
fn near_repeated_pair_on_cords_gives_six_modes() {
    for (_, warnings) in six_modes("near-repeated-cords", 1..=3, &plscf()) {
        assert!(
            !warnings
                .iter()
                .any(|w| w.contains("one root of multiplicity")),
            "{warnings:?}"
        );
    }
}

/// The acceptance: m within 0.5 % and J within 2 % (‖ΔJ‖/‖J‖) for both
/// estimators. Measured over seeds 1–3 (1 % noise) with the poly-reference pole and
/// participation refinement: repeated pair m −0.038 to +0.020 %, J 0.03–0.08 %;
/// 0.3 %-apart pair m −0.025 to +0.048 %, J 0.10 %. From the sweep's poles and
/// participations alone (no refinement) they were: repeated pair m +0.25 to +1.0 %,
/// J 0.4–1.25 %; 0.3 %-apart pair Bretl–Conti m +1.0 to +1.7 %, Toivola–Nuutila −0.8 to
/// +0.4 %, J 1.0–2.1 %, with the rigid-body consistency check flagging the
/// participations. The margins (10× on m, 20× on J) are the issue's, not tightened:
/// the acceptance is a statement about the method on realistic recordings.
#[test]
fn near_and_exactly_repeated_pairs_meet_the_acceptance() {
    for case in ["repeated-cords", "near-repeated-cords"] {
        for (est, _) in six_modes(case, 1..=3, &plscf()) {
            for (method, dm, dj) in est {
                assert!(
                    dm.abs() < 0.005 && dj < 0.02,
                    "{case} {method}: m {dm:+.4}, J {dj:.4}"
                );
            }
        }
    }
}
