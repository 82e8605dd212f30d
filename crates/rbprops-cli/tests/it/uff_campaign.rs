//! A test engineer's UFF campaign end to end: exports written by pyuff (with FRFs computed
//! by numpy from the rigid-body equations in `scripts/uff_campaign.py`, not by
//! rbprops-sim), a spec from `rbprops init-spec`, its placeholders filled in, and
//! `rbprops campaign` with a campaign file (window τ, nominal spec, uncertainty) giving one
//! summary table with the model check's verdict per recording.

use crate::common::rbprops;
use rbprops_cli::summary::SummaryRow;
use rbprops_testkit::{ok, python, repo_root, NUMPY_PYUFF};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Writes `n` exports into `dir` (0.05 Hz lines: 251 lines, small enough for debug builds).
fn generate(py: &str, dir: &Path, n: usize) {
    ok(Command::new(py)
        .arg(repo_root().join("scripts/uff_campaign.py"))
        .arg("generate")
        .arg(dir)
        .args(["--n", &n.to_string(), "--df", "0.05"])
        .output()
        .unwrap());
}

fn truth(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap()).unwrap()
}

#[test]
fn init_spec_names_everything_as_the_recording_does() {
    let Some(py) = python(NUMPY_PYUFF) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let ex = dir.path().join("exports");
    generate(&py, &ex, 1);
    let init = dir.path().join("init.toml");
    ok(rbprops()
        .args(["init-spec"])
        .arg(ex.join("run-01.uff"))
        .arg("-o")
        .arg(&init)
        .output()
        .unwrap());
    let text = std::fs::read_to_string(&init).unwrap();
    // Parsed without validation: the placeholders are nan on purpose.
    let spec: rbprops_sim::CampaignSpec = toml::from_str(&text).unwrap();
    assert_eq!(spec.quantity, rbprops_core::Quantity::Accelerance);
    assert_eq!(
        (
            spec.frequency.start_hz,
            spec.frequency.stop_hz,
            spec.frequency.lines
        ),
        (0.0, 12.5, 251)
    );
    assert!(spec.body.mass_kg.is_nan() && text.contains("FILL IN"));
    let ids: Vec<String> = spec.channels().into_iter().map(|c| c.id).collect();
    let want: Vec<String> = ["101", "102", "103"]
        .iter()
        .flat_map(|n| ["x", "y", "z"].map(|a| format!("{n}{a}")))
        .collect();
    assert_eq!(ids, want);
    // Node 103 measures in a system rotated 0.3 rad about z (dataset 2420): its axes are
    // the rows of that rotation, written by pyuff with 17 digits.
    let s103 = spec.sensors.iter().find(|s| s.id == "103").unwrap();
    let (c, s) = (0.3f64.cos(), 0.3f64.sin());
    let rot = [[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]];
    let axes = s103.axes.unwrap();
    for i in 0..3 {
        for j in 0..3 {
            assert!((axes[i][j] - rot[i][j]).abs() < 1e-15, "{axes:?}");
        }
    }
    let ex_ids: Vec<(&str, &str, [f64; 3])> = spec
        .excitations
        .iter()
        .map(|e| (e.id.as_str(), e.point.as_deref().unwrap(), e.direction))
        .collect();
    assert_eq!(
        ex_ids,
        vec![
            ("201-x", "201", [-1.0, 0.0, 0.0]),
            ("202y", "202", [0.0, 1.0, 0.0]),
            ("203-z", "203", [0.0, 0.0, -1.0])
        ]
    );
    assert_eq!(spec.excitations[2].at_m, [0.05, 0.16, 0.17]);
    assert_eq!(spec.setups.len(), 1);
    assert_eq!(spec.setups[0].id, "A");

    // Unfilled, model-check refuses it and says why.
    let out = Command::new(env!("CARGO_BIN_EXE_model-check"))
        .arg(&init)
        .arg("-i")
        .arg(ex.join("run-01.uff"))
        .args(["--format", "json"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("body.mass_kg") && err.contains("FILL IN"),
        "{err}"
    );

    // A spec with other ids (the built-in demo names channels `1x`…): every unmatched id
    // is named, and init-spec is suggested.
    let out = Command::new(env!("CARGO_BIN_EXE_model-check"))
        .args(["--example", "demo", "-i"])
        .arg(ex.join("run-01.uff"))
        .args(["--format", "json"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("'101x'")
            && err.contains("'103z'")
            && err.contains("'201-x'")
            && err.contains("init-spec"),
        "{err}"
    );
}

#[test]
fn uff_campaign_gives_one_summary_with_model_check_verdicts() {
    let Some(py) = python(NUMPY_PYUFF) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let ex = dir.path().join("exports");
    let n = 20;
    generate(&py, &ex, n);
    // The nominal spec: init-spec, then the placeholders filled in from the article's
    // data (as a person would from the CAD model and the rig).
    let init = dir.path().join("init.toml");
    ok(rbprops()
        .arg("init-spec")
        .arg(ex.join("run-01.uff"))
        .arg("-o")
        .arg(&init)
        .output()
        .unwrap());
    ok(Command::new(&py)
        .arg(repo_root().join("scripts/uff_campaign.py"))
        .arg("fill-spec")
        .arg(&init)
        .arg(ex.join("truth.json"))
        .arg("-o")
        .arg(ex.join("nominal.toml"))
        .output()
        .unwrap());
    // The generator's campaign file (linearised errors, τ = 4 s, nominal.toml), screening
    // three effects to keep a debug build under a minute (the whole catalogue takes ten
    // times longer).
    let cfg = ex.join("campaign.toml");
    let mut text = std::fs::read_to_string(&cfg).unwrap();
    text += "check_only = [\"channel_gain\", \"sensor_position\", \"exponential_window\"]\n";
    std::fs::write(&cfg, text).unwrap();
    let summary = dir.path().join("summary.csv");
    let out = ok(rbprops()
        .arg("campaign")
        .arg(&ex)
        .arg("-o")
        .arg(&summary)
        .output()
        .unwrap());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&format!("{n} items")) && err.contains("0 model checks failed"),
        "{err}"
    );
    let text = std::fs::read_to_string(&summary).unwrap();
    let rows = rbprops_cli::summary::from_csv(&text).unwrap();
    let t = truth(&ex);
    let runs = t["runs"].as_array().unwrap();
    assert_eq!(runs.len(), n);
    for run in runs {
        let file = run["file"].as_str().unwrap();
        let mine: Vec<&SummaryRow> = rows.iter().filter(|r| r.campaign == file).collect();
        assert!(!mine.is_empty(), "no rows for {file}:\n{text}");
        let r = mine[0];
        assert_ne!(r.method, "error", "{file}: {}", r.warnings);
        // Every row of a recording carries the same verdict columns.
        assert!(mine.iter().all(|x| x.check_verdict == r.check_verdict));
        let gain = run["channel_gain"].as_object().unwrap();
        let (before, after) = (
            r.check_chi2_nu_before.unwrap(),
            r.check_chi2_nu_after.unwrap(),
        );
        if gain.is_empty() {
            // The nominal spec (with the declared window) is the truth: nothing is
            // missing, and the residual is not above the noise (the check's own noise
            // estimate runs ~20 % high on these short records, so χ²/ν sits near 0.75–0.85
            // rather than in its band around 1).
            assert_eq!(r.check_effects, "", "{file}: {}", r.check_verdict);
            assert!(
                r.check_verdict.starts_with("no missing physics found") && after < 1.1,
                "{file}: {}",
                r.check_verdict
            );
        } else {
            // A channel reading 6 % high: named, and the fit reaches the noise.
            assert!(
                r.check_effects.contains("channel_gain"),
                "{file}: {} / {}",
                r.check_effects,
                r.check_verdict
            );
            assert!(after < before, "{file}: χ²/ν {before} → {after}");
            assert_eq!(
                r.check_noise_floor_reached,
                Some(true),
                "{file}: {}",
                r.check_verdict
            );
        }
    }
    // The estimates: the window is removed before the fit, so the mass is unbiased. The
    // noise is 0.1 % per value: each estimate's own standard error bounds the error
    // (4σ: a 6e-5 chance per row of a false alarm for a correct estimator).
    let mass = t["mass_kg"].as_f64().unwrap();
    let clean = |file: &str| {
        runs.iter()
            .any(|x| x["file"] == file && x["channel_gain"].as_object().unwrap().is_empty())
    };
    for r in rows
        .iter()
        .filter(|r| r.method == "bretl_conti" && clean(&r.campaign))
    {
        assert!(r.mass_std_kg > 0.0, "{}: no standard error", r.campaign);
        assert!(
            (r.mass_kg - mass).abs() <= 4.0 * r.mass_std_kg,
            "{}: mass {} ± {} vs {mass}",
            r.campaign,
            r.mass_kg,
            r.mass_std_kg
        );
    }
}

#[test]
fn uff_campaign_is_byte_identical_for_any_thread_count_and_refuses_unknown_options() {
    let Some(py) = python(NUMPY_PYUFF) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let ex = dir.path().join("exports");
    generate(&py, &ex, 4);
    std::fs::write(
        ex.join("campaign.toml"),
        "uncertainty = \"linearised\"\nwindow_time_constant_s = 4.0\nband_hz = [0.2, 10.0]\n",
    )
    .unwrap();
    let run = |threads: &str| {
        let out = ok(rbprops()
            .env("RAYON_NUM_THREADS", threads)
            .arg("campaign")
            .arg(&ex)
            .output()
            .unwrap());
        out.stdout
    };
    let one = run("1");
    assert_eq!(one, run("2"));
    let text = String::from_utf8(one).unwrap();
    assert_eq!(
        text.lines()
            .skip(1)
            .map(|l| l.split(',').next().unwrap().to_string())
            .collect::<std::collections::BTreeSet<_>>()
            .len(),
        4,
        "{text}"
    );
    // A typo in the campaign file is an error naming the file and the key.
    std::fs::write(ex.join("campaign.toml"), "windw_time_constant_s = 4.0\n").unwrap();
    let out = rbprops().arg("campaign").arg(&ex).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("campaign.toml") && err.contains("windw_time_constant_s"),
        "{err}"
    );
    // A geometry file that is not there is named.
    std::fs::write(ex.join("campaign.toml"), "geometry = \"nodes.unv\"\n").unwrap();
    let out = rbprops().arg("campaign").arg(&ex).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("nodes.unv") && err.contains("no such file"),
        "{err}"
    );
    // No output file on failure.
    let out = rbprops()
        .arg("campaign")
        .arg(&ex)
        .arg("-o")
        .arg(dir.path().join("s.csv"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(!dir.path().join("s.csv").exists());
}

#[test]
fn model_check_names_the_undeclared_window() {
    // The generator's window (τ = 4 s, σ = 0.25 1/s) left out of the campaign file: the
    // model check must find it among the candidates and measure σ (one recording).
    let Some(py) = python(NUMPY_PYUFF) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let ex = dir.path().join("exports");
    generate(&py, &ex, 1);
    let init = dir.path().join("init.toml");
    ok(rbprops()
        .arg("init-spec")
        .arg(ex.join("run-01.uff"))
        .arg("-o")
        .arg(&init)
        .output()
        .unwrap());
    let nominal = dir.path().join("nominal.toml");
    ok(Command::new(&py)
        .arg(repo_root().join("scripts/uff_campaign.py"))
        .arg("fill-spec")
        .arg(&init)
        .arg(ex.join("truth.json"))
        .arg("-o")
        .arg(&nominal)
        .output()
        .unwrap());
    let out = ok(Command::new(env!("CARGO_BIN_EXE_model-check"))
        .arg(&nominal)
        .arg("-i")
        .arg(ex.join("run-01.uff"))
        .args(["--format", "json", "--only"])
        .arg("channel_gain,sensor_position,exponential_window")
        .output()
        .unwrap());
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let accepted = report["accepted"].as_array().unwrap();
    assert_eq!(accepted.len(), 1, "{}", report["verdict"]);
    assert_eq!(accepted[0]["id"], "exponential_window");
    let p = &accepted[0]["parameters"][0];
    let (v, se) = (
        p["value"].as_f64().unwrap(),
        p["standard_error"].as_f64().unwrap(),
    );
    // Within 4 standard errors (the values carry 12 digits in ASCII 58 and 0.1 % noise:
    // the noise is the only error).
    assert!((v - 0.25).abs() <= 4.0 * se, "σ = {v} ± {se}");
}

/// The datasets of a UFF file, each with its type, split at the `    -1` delimiter lines.
fn uff_datasets(text: &str) -> Vec<(u32, String)> {
    let mut out = Vec::new();
    let mut lines = text.lines().peekable();
    while let Some(l) = lines.next() {
        if l.trim() != "-1" {
            continue;
        }
        let Some(kind) = lines.next() else { break };
        let ty: u32 = kind
            .trim()
            .split_whitespace()
            .next()
            .unwrap()
            .parse()
            .unwrap();
        let mut block = format!("{l}\n{kind}\n");
        for b in lines.by_ref() {
            block.push_str(b);
            block.push('\n');
            if b.trim() == "-1" {
                break;
            }
        }
        out.push((ty, block));
    }
    out
}

/// Analyser exports split as several programs write them: the node and unit datasets once
/// in a geometry file, the 58s alone in each data file. With `geometry` in the campaign
/// file, the campaign gives the same summary as on the complete exports; without it, the
/// data files are refused by name.
#[test]
fn uff_campaign_reads_exports_split_into_geometry_and_data() {
    let Some(py) = python(NUMPY_PYUFF) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let whole = dir.path().join("whole");
    generate(&py, &whole, 2);
    let split = dir.path().join("split");
    let data = split.join("data");
    std::fs::create_dir_all(&data).unwrap();
    let mut exports: Vec<PathBuf> = std::fs::read_dir(&whole)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| rbprops_cli::campaign::is_uff(p))
        .collect();
    exports.sort();
    assert_eq!(exports.len(), 2);
    let mut geometry = None;
    for p in &exports {
        let sets = uff_datasets(&std::fs::read_to_string(p).unwrap());
        assert!(sets.iter().any(|(t, _)| *t == 58), "{}: no 58", p.display());
        let (fun, geo): (Vec<_>, Vec<_>) = sets.into_iter().partition(|(t, _)| *t == 58);
        assert!(!geo.is_empty(), "{}: nothing but 58s", p.display());
        let geo: String = geo.into_iter().map(|(_, b)| b).collect();
        // Every export of the campaign carries the same geometry.
        assert_eq!(geometry.get_or_insert_with(|| geo.clone()), &geo);
        let fun: String = fun.into_iter().map(|(_, b)| b).collect();
        std::fs::write(data.join(p.file_name().unwrap()), fun).unwrap();
    }
    std::fs::write(split.join("geometry.unv"), geometry.unwrap()).unwrap();
    let options = "uncertainty = \"linearised\"\nwindow_time_constant_s = 4.0\n";
    std::fs::write(whole.join("campaign.toml"), options).unwrap();
    let summary = |d: &Path| {
        String::from_utf8(ok(rbprops().arg("campaign").arg(d).output().unwrap()).stdout).unwrap()
    };
    let reference = summary(&whole);
    // Without the geometry the data files cannot be placed.
    std::fs::write(split.join("campaign.toml"), options).unwrap();
    let out = rbprops().arg("campaign").arg(&split).output().unwrap();
    assert!(!out.status.success());
    // Each data file's row says why (the geometry file alone has no functions).
    let table = String::from_utf8_lossy(&out.stdout);
    for name in exports
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy())
    {
        let row = table
            .lines()
            .find(|l| l.starts_with(&format!("data/{name},")))
            .unwrap_or_else(|| panic!("no row for data/{name}: {table}"));
        assert!(row.contains("no coordinates"), "{row}");
    }
    std::fs::write(
        split.join("campaign.toml"),
        format!("{options}geometry = \"geometry.unv\"\n"),
    )
    .unwrap();
    let got = summary(&split);
    // Same rows but for the label (data/…) of each recording.
    let rows = |t: &str| -> Vec<String> {
        t.lines()
            .map(|l| {
                l.split_once(',')
                    .map(|(_, rest)| rest.to_string())
                    .unwrap_or_default()
            })
            .collect()
    };
    assert_eq!(rows(&got), rows(&reference));
    assert!(got.lines().skip(1).all(|l| l.starts_with("data/")), "{got}");
}
