//! `frf-est` on time histories written by the independent generator (`scripts/refgen`,
//! numpy and pyuff; fixtures in `fixtures/timehist`, see its README): the H1 against the
//! generator's own numpy H1 with the same windows, the hit verdicts against its truth, the
//! two file layouts against each other, and bad input.

use rbprops_core::records::{ProcessingRecord, PROCESSING_TOPIC};
use rbprops_frfest::SpectralSums;
use rbprops_uff::timehist::{self, HitLayout};
use std::path::Path;
use std::process::Command;

fn fixture(name: &str) -> String {
    format!(
        "{}/../../fixtures/timehist/{name}",
        env!("CARGO_MANIFEST_DIR")
    )
}

fn frf_est() -> Command {
    Command::new(env!("CARGO_BIN_EXE_frf-est"))
}

fn json(name: &str) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(fixture(name)).unwrap()).unwrap()
}

/// The H1 of the per-hit fixture computed here from the file's samples, with the truth's
/// windows (force rectangle [first, last] times the exponential, which is 1 before the
/// trigger sample n₀ and e^{−(n − n₀)/(τ f_s)} from it) over the truth's accepted hits,
/// equals the generator's numpy H1 to 1e-10 of each FRF's largest value: the DFT, the sums
/// and the ratio are the same computation in two implementations (numpy's FFT, realfft).
#[test]
fn h1_equals_the_generators_numpy_h1_with_the_same_windows() {
    let bytes = std::fs::read(fixture("small-per-hit.uff")).unwrap();
    let uff = rbprops_uff::parse(&bytes, "small-per-hit.uff").unwrap();
    let index = timehist::index_time_histories(&uff, &Default::default()).unwrap();
    let truth = json("small-truth.json");
    let rec = &truth["recording"];
    let reference = json("small-h1.json");
    let fs = index.sample_rate_hz;
    let n = index.record_samples;
    assert_eq!(n as u64, rec["record_samples"].as_u64().unwrap());
    let tau = rec["window"]["tau_s"]
        .as_f64()
        .expect("the fixture has a window");
    let n_lines = reference["frequency_hz"].as_array().unwrap().len();
    let mut worst = 0.0f64;
    for (e, ex) in index.excitations.iter().enumerate() {
        let HitLayout::PerHit(hits) = &ex.layout else {
            panic!("per-hit layout expected")
        };
        let mut sums = SpectralSums::new(n, fs, 1, ex.responses.len()).unwrap();
        for (h, hit) in hits.iter().enumerate() {
            let t = &rec["excitations"][e]["hits"][h];
            if !t["accepted"].as_bool().unwrap() {
                continue;
            }
            let n0 = t["windows"]["exponential_start_sample"].as_u64().unwrap() as usize;
            let rect = t["windows"]["force_rectangle"].as_array().unwrap();
            let (a, b) = (
                rect[0].as_u64().unwrap() as usize,
                rect[1].as_u64().unwrap() as usize,
            );
            let w: Vec<f64> = (0..n)
                .map(|i| {
                    if i < n0 {
                        1.0
                    } else {
                        (-((i - n0) as f64) / (fs * tau)).exp()
                    }
                })
                .collect();
            let wf: Vec<f64> = (0..n)
                .map(|i| if i >= a && i <= b { w[i] } else { 0.0 })
                .collect();
            let force = timehist::samples(&uff, hit.force);
            let resp: Vec<Vec<f64>> = hit
                .responses
                .iter()
                .map(|&i| timehist::samples(&uff, i))
                .collect();
            let refs: Vec<&[f64]> = resp.iter().map(|r| r.as_slice()).collect();
            sums.add_windowed_hit(&[&force], &refs, Some(&wf), Some(&w))
                .unwrap();
        }
        let est = sums.h1(Some(0..n_lines), &Default::default()).unwrap();
        for c in 0..ex.responses.len() {
            let re = reference["re"][e][c].as_array().unwrap();
            let im = reference["im"][e][c].as_array().unwrap();
            let ours = est.frf(c, 0);
            let peak = ours.iter().map(|v| v.norm()).fold(0.0, f64::max);
            for l in 0..n_lines {
                let theirs =
                    rbprops_core::c64::new(re[l].as_f64().unwrap(), im[l].as_f64().unwrap());
                worst = worst.max((ours[l] - theirs).norm() / peak);
            }
        }
    }
    assert!(
        worst < 1e-10,
        "H1 differs from numpy's by {worst:e} of max |H|"
    );
}

/// `frf-est INPUT ARGS -o out`, which must succeed.
fn estimate_to(input: &str, args: &[String], out: &Path) {
    let st = frf_est()
        .arg(input)
        .args(args)
        .arg("-o")
        .arg(out)
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{input}: {}",
        String::from_utf8_lossy(&st.stderr)
    );
}

fn processing(mcap: &Path) -> ProcessingRecord {
    let rec = rbprops_formats::read_path(mcap).unwrap();
    rec.get_one(PROCESSING_TOPIC)
        .unwrap()
        .expect("processing topic")
}

/// The hits `frf-est` rejects are exactly the truth's (the double hit of force2 and the
/// clipped channel of force1), with the reasons' kinds; both layouts of the same samples
/// give the same verdicts, and each excitation averages the truth's accepted hits.
#[test]
fn rejected_hits_are_the_truths_in_both_layouts() {
    let dir = tempfile::tempdir().unwrap();
    let truth = json("small-truth.json");
    let n_record = truth["recording"]["record_samples"].as_u64().unwrap();
    let fs = truth["recording"]["sample_rate_hz"].as_f64().unwrap();
    let pre = truth["recording"]["pretrigger_samples"].as_u64().unwrap() as f64 / fs;
    for (file, extra) in [
        ("small-per-hit.uff", vec![]),
        (
            "small-throughput-58b.uff",
            vec![
                "--record-s".to_string(),
                format!("{}", n_record as f64 / fs),
                "--pretrigger".into(),
                format!("{pre}"),
            ],
        ),
    ] {
        let out = dir.path().join(format!("{file}.mcap"));
        estimate_to(&fixture(file), &extra, &out);
        let p = processing(&out);
        let est = p.frf_estimation.expect("frf_estimation");
        for (e, ex) in truth["recording"]["excitations"]
            .as_array()
            .unwrap()
            .iter()
            .enumerate()
        {
            let id = ex["id"].as_str().unwrap();
            for (h, th) in ex["hits"].as_array().unwrap().iter().enumerate() {
                let ours = est
                    .hits
                    .iter()
                    .find(|x| x.excitation == id && x.hit == h + 1)
                    .unwrap_or_else(|| panic!("{file}: {id} hit {} missing", h + 1));
                assert_eq!(
                    ours.accepted,
                    th["accepted"].as_bool().unwrap(),
                    "{file}: {id} hit {}: {:?}",
                    h + 1,
                    ours.reasons
                );
                if th["double"].is_object() {
                    assert!(ours.reasons.iter().any(|r| r.starts_with("double hit")));
                }
                if th["clipped"].as_bool().unwrap() {
                    assert!(ours.reasons.iter().any(|r| r.starts_with("overload")));
                }
            }
            let used = truth["recording"]["hits_used"][id]
                .as_array()
                .unwrap()
                .len();
            assert_eq!(est.averages[e].accepted, used, "{file}: {id}");
        }
    }
}

/// The line variances are written, positive where the FRF is, and the model check is
/// told the window and record length (its known effects) by the processing topic.
#[test]
fn variance_topic_and_processing_are_written() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run.mcap");
    estimate_to(&fixture("small-per-hit.uff"), &[], &out);
    let rec = rbprops_formats::read_path(&out).unwrap();
    let v = rbprops_cli::variance::get(&rec)
        .unwrap()
        .expect("frf_variance topic");
    let frf = rec.frf.as_ref().unwrap();
    assert_eq!(v.sigma2.len(), frf.values.len());
    assert!(v.sigma2.iter().all(|s| s.is_finite() && *s > 0.0));
    assert!(v.degrees_of_freedom.iter().all(|d| *d > 2.0));
    let p = processing(&out);
    let est = p.frf_estimation.unwrap();
    assert_eq!(p.exponential_window_s, est.exponential_window_s);
    assert!(est.line_correlation.len() > 1 && est.line_correlation[0] == [1.0, 0.0]);
}

/// Bad input: an FRF export (no time histories), a missing file, a non-number option:
/// `error:` naming the problem, exit 1, no output file.
#[test]
fn bad_input_is_a_clear_error_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run.mcap");
    let frf_only = format!(
        "{}/../../fixtures/uff/ascii_complex_double_even.uff",
        env!("CARGO_MANIFEST_DIR")
    );
    let cases: Vec<(Vec<String>, &str)> = vec![
        (vec![frf_only.clone()], "no time histories"),
        (vec![fixture("missing.uff")], "missing.uff"),
        (
            vec![
                fixture("small-per-hit.uff"),
                "--min-hits".into(),
                "3".into(),
            ],
            "hits accepted",
        ),
        (
            vec![
                fixture("small-per-hit.uff"),
                "--band".into(),
                "100:200".into(),
            ],
            "--band",
        ),
    ];
    for (args, what) in cases {
        if args[0] == frf_only && !Path::new(&frf_only).exists() {
            continue;
        }
        let st = frf_est().args(&args).arg("-o").arg(&out).output().unwrap();
        let err = String::from_utf8_lossy(&st.stderr);
        assert_eq!(st.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains("error:") && err.contains(what),
            "{args:?}: {err}"
        );
        assert!(!out.exists(), "{args:?}: output written");
    }
    // Nonsense option values are command-line errors (exit 2) naming the option.
    for args in [
        &["--window=-3"][..],
        &["--trigger", "1"],
        &["--taper=-0.1"],
        &["--band", "2:1"],
        &["--force-window", "0.01"],
        &["--force-dof", "201:W"],
        &["--min-hits", "1"],
        &["--record-s", "0"],
    ] {
        let st = frf_est()
            .arg(fixture("small-per-hit.uff"))
            .args(args)
            .arg("-o")
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&st.stderr);
        assert_eq!(st.status.code(), Some(2), "{args:?}: {err}");
        let flag = args[0].split('=').next().unwrap();
        assert!(err.contains(flag), "{args:?}: {err}");
        assert!(!out.exists(), "{args:?}: output written");
    }
}

/// Every stage takes a time-history export directly: `rbprops convert` of the per-hit
/// file gives the FRFs, coherence and variances `frf-est` writes with its defaults.
#[test]
fn stages_take_time_history_exports_directly() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("est.mcap"), dir.path().join("conv.mcap"));
    estimate_to(&fixture("small-per-hit.uff"), &[], &a);
    let st = super::common::rbprops()
        .args(["convert", &fixture("small-per-hit.uff"), "-o"])
        .arg(&b)
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let (ra, rb) = (
        rbprops_formats::read_path(&a).unwrap(),
        rbprops_formats::read_path(&b).unwrap(),
    );
    assert_eq!(ra.frf, rb.frf);
    assert_eq!(
        rbprops_cli::variance::get(&ra).unwrap(),
        rbprops_cli::variance::get(&rb).unwrap()
    );
    assert_eq!(processing(&a), processing(&b));
}
