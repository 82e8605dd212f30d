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
use rbprops_core::records::{
    Diagnostic, DiagnosticKind, FitMethod, InertiaEstimate, SelectionRecord, Severity,
};
use rbprops_formats::topics;
use rbprops_inertia::{Estimator, SolveOptions};
use rbprops_modal::{FitOptions, Method};
use rbprops_testkit::{python, refgen, NUMPY_PYUFF};
use std::path::Path;

const REPO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");

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
    let path = format!("{REPO}/scripts/refgen/examples/{case}.toml");
    generate_from(py, dir, Path::new(&path), case, seeds, sets)
}

/// [`generate`] of the case or spec file `case`, its outputs named `{stem}-{seed}`.
fn generate_from(
    py: &str,
    dir: &Path,
    case: &Path,
    stem: &str,
    seeds: std::ops::RangeInclusive<u64>,
    sets: &[&str],
) -> Vec<(std::path::PathBuf, std::path::PathBuf)> {
    let mut cmd = refgen(py);
    cmd.arg(case)
        .args(["--seeds", &format!("{}:{}", seeds.start(), seeds.end())])
        .arg("-o")
        .arg(dir.join(format!("{stem}-{{seed}}.uff")))
        .arg("--truth")
        .arg(dir.join(format!("{stem}-{{seed}}.json")))
        .args(["--binary", "--quiet"]);
    for s in sets {
        cmd.args(["--set", s]);
    }
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "refgen {stem}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    seeds
        .map(|s| {
            (
                dir.join(format!("{stem}-{s}.uff")),
                dir.join(format!("{stem}-{s}.json")),
            )
        })
        .collect()
}

/// The pipeline's result on one recording.
struct Run {
    selection: SelectionRecord,
    estimates: Vec<InertiaEstimate>,
    warnings: Vec<String>,
    /// modal-fit's typed diagnostics and the method of every excitation's fit.
    diagnostics: Vec<Diagnostic>,
    methods: Vec<FitMethod>,
}

fn pipeline(rec: &Path, fit: &FitOptions, window_s: Option<f64>) -> Run {
    let input = rbprops_cli::read_input(Some(rec)).unwrap();
    let mut r = input.record;
    let fo = stages::modal_fit_windowed(&mut r, fit, window_s, "test").unwrap();
    for d in &fo.record.diagnostics {
        eprintln!("  diagnostic {} {}: {}", d.severity, d.kind, d.line());
    }
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
    warnings.extend(so.record.diagnostics.iter().map(Diagnostic::line));
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
    warnings.extend(out.diagnostics.iter().map(Diagnostic::line));
    let selection = r.get_one(topics::SELECTION).unwrap().unwrap();
    Run {
        selection,
        estimates: out.estimates,
        warnings,
        diagnostics: fo.record.diagnostics.clone(),
        methods: fo.record.excitations.iter().map(|e| e.method).collect(),
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
    let Some(py) = python(NUMPY_PYUFF) else {
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
            est.push((e.method.to_string(), dm, dj));
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

/// Test Case II (springs) from the reference generator at 1601 lines, 0–12.5 Hz, for
/// `seed`, with an exponential window of τ = `tau_s` on force and response when given;
/// returns (recording, truth).
fn test_case_2(
    py: &str,
    dir: &Path,
    seed: u64,
    tau_s: Option<f64>,
    noise: f64,
) -> (std::path::PathBuf, std::path::PathBuf) {
    let tag = tau_s.map_or("plain".to_string(), |t| format!("tau{t}"));
    let (rec, truth) = (
        dir.join(format!("tc2-{tag}-{seed}.uff")),
        dir.join(format!("tc2-{tag}-{seed}.json")),
    );
    let mut cmd = refgen(py);
    cmd.arg(format!("{REPO}/fixtures/specs/test-case-2.toml"))
        .args(["--seed", &seed.to_string()])
        .args(["--set", &format!("noise.relative={noise}")])
        .args(["-o"])
        .arg(&rec)
        .arg("--truth")
        .arg(&truth)
        .args(["--binary", "--quiet"]);
    if let Some(t) = tau_s {
        cmd.args(["--set", &format!("window.tau_s={t}")]);
    }
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "refgen failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    (rec, truth)
}

/// The exponential window (τ = 8 s on force and response, as testers use on soft
/// suspensions) given to `modal-fit` gives the properties of the unwindowed recording:
/// exactly on noise-free data (the window moves every pole by −1/τ and leaves the
/// receptance residues as they are, so the corrected fit identifies the same modal
/// model), and to the noise at 1 % noise: the two estimates differ by less than
/// 3 combined standard errors (the noise of the two recordings is drawn independently,
/// so the difference has variance σ_w² + σ_0², and 3σ is a two-sided 0.3 % false-alarm
/// rate per comparison). Without the correction the noise-free windowed recording's mass
/// must be off by far more than the corrected one's, or the test could not tell the
/// correction from its absence. Measured (seeds 2, 3 at 1 % noise): differences of 1.9
/// and 0.5 combined standard errors (σ ≈ 8e-3 kg on 15.69 kg); J differs by 0.6 %.
#[test]
fn the_exponential_window_given_gives_the_unwindowed_properties() {
    let Some(py) = python(NUMPY_PYUFF) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let fit = FitOptions::default();
    let tau = 8.0;
    let estimate = |run: &Run, method: &str| -> InertiaEstimate {
        run.estimates
            .iter()
            .find(|e| e.method == method)
            .unwrap_or_else(|| panic!("no {method} estimate"))
            .clone()
    };
    let mass = |run: &Run, method: &str| -> (f64, f64, [[f64; 3]; 3]) {
        let e = estimate(run, method);
        (e.mass_kg, e.mass_std_kg, e.inertia_cm_kg_m2)
    };
    for (seed, noise) in [(1, 0.0), (2, 0.01), (3, 0.01)] {
        let (plain, truth) = test_case_2(&py, dir.path(), seed, None, noise);
        let (windowed, _) = test_case_2(&py, dir.path(), seed + 100, Some(tau), noise);
        let t = read_truth(&truth);
        let p = pipeline(&plain, &fit, None);
        let w = pipeline(&windowed, &fit, Some(tau));
        let raw = pipeline(&windowed, &fit, None);
        for method in ["bretl_conti", "toivola_nuutila"] {
            let ((m0, s0, j0), (mw, sw, jw)) = (mass(&p, method), mass(&w, method));
            let (mr, _, _) = mass(&raw, method);
            eprintln!(
                "seed {seed} noise {noise} {method}: m plain {m0:.5} ± {s0:.1e}, windowed+τ {mw:.5} ± {sw:.1e}, windowed without τ {mr:.5}; truth {:.5}; J diff {:.2e}",
                t.mass,
                inertia_error(&jw, &j0)
            );
            if noise == 0.0 {
                assert!((mw / m0 - 1.0).abs() < 1e-6, "{method}: {mw} vs {m0}");
                assert!(
                    inertia_error(&jw, &j0) < 1e-5,
                    "{method}: J {jw:?} vs {j0:?}"
                );
                assert!(
                    (m0 / t.mass - 1.0).abs() < 1e-6,
                    "{method}: {m0} vs truth {}",
                    t.mass
                );
            } else {
                let sd = (s0 * s0 + sw * sw).sqrt();
                assert!(
                    sd > 0.0 && sd < 0.01 * m0,
                    "{method}: standard errors {s0}, {sw}"
                );
                assert!(
                    (mw - m0).abs() < 3.0 * sd,
                    "{method}: {mw} vs {m0} (sd {sd})"
                );
                // Every inertia entry likewise, against its own standard errors.
                let (e0, ew) = (estimate(&p, method), estimate(&w, method));
                for a in 0..3 {
                    for b in a..3 {
                        let sd = e0.inertia_cm_std_kg_m2[a][b].hypot(ew.inertia_cm_std_kg_m2[a][b]);
                        assert!(
                            (jw[a][b] - j0[a][b]).abs() < 3.0 * sd,
                            "{method}: J[{a}][{b}] {} vs {} (sd {sd})",
                            jw[a][b],
                            j0[a][b]
                        );
                    }
                }
            }
            if noise == 0.0 {
                // Measured: +0.23 % (Bretl–Conti) and +0.25 % (Toivola–Nuutila) without
                // the correction, where the corrected fit agrees to 1e-14.
                assert!(
                    (mr / m0 - 1.0).abs() > 1e-3,
                    "{method}: the uncorrected window did not move the mass ({mr} vs {m0})"
                );
            }
        }
    }
}

/// The default pipeline on pairs 0.3 % apart (0.15 half-bandwidths at ζ = 2 %: one peak),
/// on cords (`near-repeated-cords`, 3 excitations) and on springs
/// (`near-repeated-springs`, the close-modes article with its translation pair moved to
/// 0.3 %, 5 excitations), noise-free and with 1 % noise, two seeds each: the per-excitation
/// fits merge or split the pair, so the set-up is also fitted with the poly-reference
/// method, and the default gives exactly the poly-reference answer (bit for bit the same
/// estimates as `--method plscf`), one `fit_choice` note and one `repeated_root` note for
/// the pair naming every excitation, nothing at warning level from modal-fit, and on the
/// noise-free recordings no rigid-body-consistency alarm. Before (per-excitation fits by
/// default) the noise-free recordings raised that alarm (χ²/dof 21 and 17 against 3.6 and
/// 2.9) with estimates right to 1e-5.
#[test]
fn default_fit_gives_the_poly_reference_answer_on_near_repeated_pairs() {
    let Some(py) = python(NUMPY_PYUFF) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    for case in ["near-repeated-cords", "near-repeated-springs"] {
        for noise in [0.0, 0.01] {
            let set = format!("noise.relative={noise}");
            let sub = dir.path().join(format!("{case}-{noise}"));
            std::fs::create_dir_all(&sub).unwrap();
            for (s, (rec, truth)) in (1..=2).zip(generate(&py, &sub, case, 1..=2, &[&set])) {
                let t = read_truth(&truth);
                let run = pipeline(&rec, &FitOptions::default(), None);
                let poly = pipeline(&rec, &plscf(), None);
                let what = format!("{case} noise {noise} seed {s}");
                assert!(
                    run.methods.iter().all(|m| *m == FitMethod::Plscf),
                    "{what}: {:?}",
                    run.methods
                );
                assert_eq!(run.estimates.len(), poly.estimates.len(), "{what}");
                for (a, b) in run.estimates.iter().zip(&poly.estimates) {
                    assert_eq!(a.mass_kg, b.mass_kg, "{what}");
                    assert_eq!(a.inertia_cm_kg_m2, b.inertia_cm_kg_m2, "{what}");
                    let (dm, dj) = (
                        a.mass_kg / t.mass - 1.0,
                        inertia_error(&a.inertia_cm_kg_m2, &t.inertia),
                    );
                    assert!(dm.abs() < 0.005 && dj < 0.02, "{what}: m {dm}, J {dj}");
                    if noise == 0.0 {
                        assert_eq!(a.rigid_body_consistent, Some(true), "{what}");
                    }
                }
                if noise == 0.0 {
                    assert!(
                        !run.warnings
                            .iter()
                            .any(|w| w.contains("not rigid-body consistent")),
                        "{what}: {:?}",
                        run.warnings
                    );
                }
                // One line per fact.
                let of = |k: DiagnosticKind| run.diagnostics.iter().filter(move |d| d.kind == k);
                assert_eq!(of(DiagnosticKind::FitChoice).count(), 1, "{what}");
                let roots: Vec<&Diagnostic> = of(DiagnosticKind::RepeatedRoot).collect();
                assert_eq!(roots.len(), 1, "{what}: {roots:?}");
                let n_exc = run.methods.len();
                assert_eq!(roots[0].subject.excitations.len(), n_exc, "{what}");
                assert_eq!(roots[0].subject.modes.len(), 2, "{what}");
                assert_eq!(roots[0].severity, Severity::Note, "{what}");
                assert!(
                    run.diagnostics.iter().all(|d| d.severity == Severity::Note),
                    "{what}: {:?}",
                    run.diagnostics
                );
            }
        }
    }
}

/// The close-modes article (two pairs 1.5 % and 1.6 % apart, within their half-power
/// bandwidths; `fixtures/specs/close-modes.toml`) from the reference generator, 5
/// excitations at 1 % noise, two seeds: the default fit finds the six modes in every
/// excitation, each within 0.2 % of the generator's frequency (a tenth of a half-bandwidth
/// at ζ = 2 %), and never fewer modes in an excitation than the better of the two forced
/// fits (`--method lscf`, `--method plscf`).
#[test]
fn close_pairs_every_mode_in_every_excitation_on_generator_recordings() {
    let Some(py) = python(NUMPY_PYUFF) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let spec = format!("{REPO}/fixtures/specs/close-modes.toml");
    generate_from(&py, dir.path(), Path::new(&spec), "cm", 1..=2, &[]);
    for s in 1..=2 {
        let rec = dir.path().join(format!("cm-{s}.uff"));
        let t = read_truth(&dir.path().join(format!("cm-{s}.json")));
        let input = rbprops_cli::read_input(Some(&rec)).unwrap();
        let (geometry, frf) = input.record.require_geometry_and_frf().unwrap();
        every_mode_in_every_excitation(
            &geometry,
            frf,
            &t.frequencies_hz,
            true,
            &format!("seed {s}"),
        );
    }
}

/// Fits `frf` by default (and, with `forced`, by `lscf` and `plscf`); asserts the default
/// has one mode within 0.2 % of each of `truth_hz` in every excitation and no excitation
/// with fewer modes than the better forced fit has there.
fn every_mode_in_every_excitation(
    geometry: &rbprops_core::Geometry,
    frf: &rbprops_core::FrfSet,
    truth_hz: &[f64],
    forced: bool,
    what: &str,
) {
    let fit = |opts: &FitOptions| rbprops_modal::fit_campaign(geometry, frf, opts).unwrap();
    let default = fit(&FitOptions::default());
    let (lscf, poly) = if forced {
        (
            fit(&FitOptions {
                auto_poly_reference: false,
                ..Default::default()
            }),
            fit(&plscf()),
        )
    } else {
        (default.clone(), default.clone())
    };
    let count = |o: &rbprops_modal::ModalFitOutput, e: &str| {
        o.record.modes.iter().filter(|m| m.excitation == e).count()
    };
    for ex in &geometry.excitations {
        let e = ex.id.as_str();
        let f: Vec<f64> = default
            .record
            .modes
            .iter()
            .filter(|m| m.excitation == e)
            .map(|m| m.frequency_hz)
            .collect();
        for ft in truth_hz {
            let n = f.iter().filter(|x| (*x / ft - 1.0).abs() < 2e-3).count();
            assert_eq!(n, 1, "{what} excitation {e}: {f:?} vs truth {truth_hz:?}");
        }
        let best = count(&lscf, e).max(count(&poly, e)).min(truth_hz.len());
        assert!(count(&default, e) >= best, "{what} excitation {e}");
    }
}

/// The same article with 50 excitations (45 added at fixed pseudo-random points and
/// directions), simulated by frf-sim at 1 % noise: the default finds every mode in every
/// excitation (each of the six within 0.2 %, so no forced fit can have more).
#[test]
fn close_pairs_every_mode_in_every_excitation_with_fifty_excitations() {
    let spec = fifty_excitations(include_str!("../../../../fixtures/specs/close-modes.toml"));
    let (rec, _) = stages::simulate(&spec, "close-modes-50", None).unwrap();
    let truth: rbprops_core::records::TruthRecord = rec.get_one(topics::TRUTH).unwrap().unwrap();
    let f: Vec<f64> = truth.setups[0]
        .modes
        .iter()
        .map(|m| m.frequency_hz)
        .collect();
    let (geometry, frf) = rec.require_geometry_and_frf().unwrap();
    assert_eq!(geometry.excitations.len(), 50);
    every_mode_in_every_excitation(&geometry, frf, &f, false, "50 excitations");
}

/// The same fifty excitations from the reference generator (its own formulation, not
/// frf-sim's), 1 % noise: the poly-reference fit sweeps them on 16 real principal
/// references (the other 34 directions hold noise); the default finds every mode in
/// every excitation within 0.2 % of the generator's frequencies, and never fewer than
/// the better of the forced fits.
#[test]
fn close_pairs_with_fifty_excitations_on_generator_recordings() {
    let Some(py) = python(NUMPY_PYUFF) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let spec = dir.path().join("close-modes-50.toml");
    std::fs::write(
        &spec,
        fifty_excitations(include_str!("../../../../fixtures/specs/close-modes.toml")),
    )
    .unwrap();
    generate_from(&py, dir.path(), &spec, "cm50", 1..=1, &[]);
    let t = read_truth(&dir.path().join("cm50-1.json"));
    let input = rbprops_cli::read_input(Some(&dir.path().join("cm50-1.uff"))).unwrap();
    let (geometry, frf) = input.record.require_geometry_and_frf().unwrap();
    assert_eq!(geometry.excitations.len(), 50);
    every_mode_in_every_excitation(&geometry, frf, &t.frequencies_hz, true, "generator, 50");
}

/// `spec` with 45 more excitations of set-up A around (0.30, 0.22, 0.15) m, points and
/// directions from fixed trigonometric sequences (deterministic, spread over the sphere).
fn fifty_excitations(spec: &str) -> String {
    let mut s = spec.to_string();
    for k in 0..45 {
        let k = k as f64;
        let at = [
            0.3 + 0.15 * (1.3 * k + 0.5).sin(),
            0.22 + 0.15 * (2.1 * k + 0.2).cos(),
            0.15 + 0.15 * (0.7 * k + 1.0).sin(),
        ];
        let d = [
            (1.1 * k + 0.3).cos(),
            (1.7 * k + 0.9).sin(),
            (0.3 * k + 2.0).cos(),
        ];
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        s.push_str(&format!(
            "\n[[excitation]]\nid = \"X{}\"\nat_m = [{:?}, {:?}, {:?}]\ndirection = [{:?}, {:?}, {:?}]\nsetup = \"A\"\n",
            k as usize + 6,
            at[0],
            at[1],
            at[2],
            d[0] / n,
            d[1] / n,
            d[2] / n
        ));
    }
    s
}

/// The realistic combination (`scripts/refgen/examples/realistic-combination.toml`: the
/// near-repeated article on cords under gravity, three 30 g accelerometers, 1–2°
/// misorientations, an elastic mode 3× above the band, 1 % noise, τ = 8 s exponential
/// window given to modal-fit, float32 files) through the default pipeline: m within 1 %
/// and J within 3 % (‖ΔJ‖/‖J‖) of the body with its sensors, and the rigid-body check
/// warns (the misorientations are real, and they bias J beyond its noise interval).
/// Measured over seeds 1–5 (lscf): m −0.003 to +0.18 %, J 1.35–1.89 %.
#[test]
fn realistic_combination_meets_the_acceptance_or_warns() {
    let Some(py) = python(NUMPY_PYUFF) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let case = "realistic-combination";
    for (s, (rec, truth)) in (1..=3).zip(generate(&py, dir.path(), case, 1..=3, &[])) {
        let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&truth).unwrap()).unwrap();
        let tau = v["window_tau_s"]
            .as_f64()
            .expect("the truth gives the window");
        let p = &v["properties_with_sensor_masses"];
        let mass = p["mass_kg"].as_f64().unwrap();
        let inertia: [[f64; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|j| p["inertia_cm_kg_m2"][i][j].as_f64().unwrap())
        });
        let run = pipeline(&rec, &FitOptions::default(), Some(tau));
        assert!(!run.estimates.is_empty(), "{case} seed {s}: no estimate");
        for e in &run.estimates {
            let (dm, dj) = (
                e.mass_kg / mass - 1.0,
                inertia_error(&e.inertia_cm_kg_m2, &inertia),
            );
            eprintln!(
                "{case} seed {s} {}: m {:+.3} %, J {:.2} %",
                e.method,
                100.0 * dm,
                100.0 * dj
            );
            assert!(
                dm.abs() < 0.01 && dj < 0.03,
                "{case} seed {s} {}: m {dm:+.4}, J {dj:.4}",
                e.method
            );
            assert_eq!(
                e.rigid_body_consistent,
                Some(false),
                "{case} seed {s} {}",
                e.method
            );
        }
        assert!(
            run.warnings
                .iter()
                .any(|w| w.contains("not rigid-body consistent")),
            "{case} seed {s}: {:?}",
            run.warnings
        );
    }
}
