//! Warnings on clean data: a recording whose only departure from the ideal rigid body
//! is measurement noise (made by the independent reference generator in
//! `scripts/refgen`, not by rbprops-sim) goes through modal-fit | ni-select | rb-solve
//! with no warning line on stderr by default (at most one summary line of notes per
//! stage); `-v` lists the stages' notes, none of them
//! a warning (the class that changes the answer).

use rbprops_testkit::{python, refgen, repo_root, NUMPY_PYUFF};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Test Case II recorded by the reference generator with 0.1 % relative noise, 401 lines
/// (0–12.5 Hz), plus the `extra` settings; returns the UFF file.
fn record(py: &str, dir: &Path, extra: &[&str]) -> PathBuf {
    let rec = dir.join("rec.uff");
    let mut cmd = refgen(py);
    cmd.arg(repo_root().join("fixtures/specs/test-case-2.toml"))
        .args([
            "--set",
            "frequency.lines=401",
            "--set",
            "noise.relative=0.001",
        ]);
    for e in extra {
        cmd.args(["--set", e]);
    }
    let o = cmd
        .arg("-o")
        .arg(&rec)
        .arg("--truth")
        .arg(dir.join("truth.json"))
        .arg("--quiet")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    rec
}

/// Runs the three stages (each writing an MCAP file) and returns their stderr and the
/// estimates JSON.
fn pipeline(dir: &Path, rec: &Path, verbose: bool) -> (Vec<String>, serde_json::Value) {
    let v: &[&str] = if verbose { &["-v"] } else { &[] };
    let mut errs = Vec::new();
    let fit = dir.join("fit.mcap");
    let sel = dir.join("sel.mcap");
    for (exe, input, output) in [
        (env!("CARGO_BIN_EXE_modal-fit"), rec, &fit),
        (env!("CARGO_BIN_EXE_ni-select"), fit.as_path(), &sel),
    ] {
        let o = Command::new(exe)
            .arg(input)
            .arg("-o")
            .arg(output)
            .args(v)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{exe}: {err}");
        errs.push(err);
    }
    let o = Command::new(env!("CARGO_BIN_EXE_rb-solve"))
        .arg(&sel)
        .args(["--format", "json", "--uncertainty", "linearised"])
        .args(v)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "rb-solve: {err}");
    errs.push(err);
    (errs, serde_json::from_slice(&o.stdout).unwrap())
}

#[test]
fn noise_only_recording_prints_no_warning() {
    let Some(py) = python(NUMPY_PYUFF) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let rec = record(&py, dir.path(), &[]);
    let (errs, est) = pipeline(dir.path(), &rec, false);
    // No warning line (the class that changes the answer); the fit's notes (poles the
    // order tests dropped, the band the poles were fitted on) are at most one summary
    // line per stage.
    for e in &errs {
        assert!(
            !e.lines()
                .any(|l| l.contains(": warning:") || l.contains(": changes the answer:")),
            "a warning on noise-only data:\n{e}"
        );
        assert!(
            e.lines().all(|l| l.ends_with("run with -v to list them")),
            "{e}"
        );
    }
    // The pipeline did run: the mass is within 4 standard errors of the generator's
    // (0.1 % noise; 4σ is a 6e-5 false-alarm chance for a correct estimator).
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("truth.json")).unwrap())
            .unwrap();
    let m_true = truth["properties"]["mass_kg"].as_f64().unwrap();
    let bc = est
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["method"] == "bretl_conti")
        .expect("a Bretl–Conti estimate");
    let (m, s) = (
        bc["mass_kg"].as_f64().unwrap(),
        bc["mass_std_kg"].as_f64().unwrap(),
    );
    assert!(
        s > 0.0 && (m - m_true).abs() <= 4.0 * s,
        "m = {m} ± {s}, truth {m_true}"
    );
    // With -v the notes (if any) are listed, never as warnings.
    let (verbose, _) = pipeline(dir.path(), &rec, true);
    for e in &verbose {
        assert!(!e.contains(": warning:"), "{e}");
        assert!(!e.contains(": changes the answer:"), "{e}");
        assert!(!e.contains("run with -v"), "{e}");
    }
}
