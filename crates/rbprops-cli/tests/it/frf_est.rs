//! `frf-est` on time histories written by the independent generator (`scripts/refgen`,
//! numpy and pyuff; fixtures in `fixtures/timehist`, see its README): the H1 against the
//! generator's own numpy H1 with the same windows, the hit verdicts against its truth, the
//! two file layouts against each other, and bad input.

use rbprops_core::records::{ProcessingRecord, PROCESSING_TOPIC};
use rbprops_frfest::SpectralSums;
use rbprops_uff::timehist::{self, HitLayout};
use std::path::{Path, PathBuf};
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
            let refs: Vec<&[f64]> = hit
                .responses
                .iter()
                .map(|&i| timehist::samples(&uff, i))
                .collect();
            sums.add_windowed_hit(&[force], &refs, Some(&wf), Some(&w))
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
    let mut all = vec![input];
    all.extend(args.iter().map(String::as_str));
    stage(env!("CARGO_BIN_EXE_frf-est"), &all, out);
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
    // The force noise's common error of every excitation: ρ² on every line, whose RMS
    // root is the averages table's force_noise_relative_error; the window's bins sum to 1.
    assert_eq!(v.common.len(), frf.n_excitations);
    let geometry = rec.geometry().unwrap().unwrap();
    for (c, x) in v.common.iter().zip(&geometry.excitations) {
        let a = est.averages.iter().find(|a| a.excitation == x.id).unwrap();
        let c = c.as_ref().expect("a common error per excitation");
        assert_eq!(c.relative_variance.len(), frf.n_lines());
        let rms = (c.relative_variance.iter().sum::<f64>() / frf.n_lines() as f64).sqrt();
        assert!(
            (rms / a.force_noise_relative_error - 1.0).abs() < 1e-12,
            "{rms} against {}",
            a.force_noise_relative_error
        );
        assert!((c.weights.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert!((c.correlation(0.0).re - 1.0).abs() < 1e-12);
    }
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

/// The run `frf-est` wrote to `out`, without its provenance (the input's path and digest),
/// as MCAP bytes.
fn without_provenance(out: &Path) -> (Vec<u8>, rbprops_formats::RunRecord) {
    let mut rec = rbprops_formats::read_path(out).unwrap();
    rec.topics
        .retain(|t| t.name != rbprops_formats::topics::PROVENANCE);
    (rbprops_formats::mcap_file::write(&rec).unwrap(), rec)
}

/// The first difference of two runs, for the failure message.
fn first_difference(a: &rbprops_formats::RunRecord, b: &rbprops_formats::RunRecord) -> String {
    if a.frf != b.frf {
        return "the FRFs".into();
    }
    for (x, y) in a.topics.iter().zip(&b.topics) {
        if x != y {
            for (m, n) in x.messages.iter().zip(&y.messages) {
                if m != n {
                    return format!("topic {}: {m}\n vs {n}", x.name);
                }
            }
            return format!("topic {} (messages or schema)", x.name);
        }
    }
    format!("{} vs {} topics", a.topics.len(), b.topics.len())
}

/// The same recording as UFF (per-hit ASCII and throughput 58b), as the MCAP time-history
/// topic (f64 samples) and as a CSV directory gives byte-identical `frf-est` output, its
/// provenance aside; `rbprops convert --list` describes the time histories of each the
/// same way.
#[test]
fn the_same_recording_in_uff_mcap_and_csv_gives_the_same_output() {
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
        let bytes = std::fs::read(fixture(file)).unwrap();
        let uff = rbprops_uff::parse(&bytes, file).unwrap();
        let index = timehist::index_time_histories(&uff, &Default::default()).unwrap();
        let recording = rbprops_uff::timerec::from_uff(&uff, &index).unwrap();
        let mcap = dir.path().join(format!("{file}.mcap"));
        let mut run = rbprops_formats::RunRecord::default();
        run.set(
            rbprops_formats::topics::TIME_HISTORY,
            &recording.to_messages(false),
        );
        std::fs::write(&mcap, rbprops_formats::mcap_file::write(&run).unwrap()).unwrap();
        let csv = dir.path().join(format!("{file}-csv"));
        std::fs::create_dir(&csv).unwrap();
        for (name, text) in recording.to_csv() {
            std::fs::write(csv.join(name), text).unwrap();
        }
        let mut outputs = Vec::new();
        let mut lists = Vec::new();
        for (k, input) in [
            fixture(file),
            mcap.display().to_string(),
            csv.display().to_string(),
        ]
        .iter()
        .enumerate()
        {
            let out = dir.path().join(format!("{file}-out-{k}.mcap"));
            estimate_to(input, &extra, &out);
            outputs.push(without_provenance(&out));
            let list = super::common::rbprops()
                .args(["convert", input, "--list"])
                .output()
                .unwrap();
            assert!(
                list.status.success(),
                "{input}: {}",
                String::from_utf8_lossy(&list.stderr)
            );
            let text = String::from_utf8(list.stdout).unwrap();
            let th = text
                .lines()
                .skip_while(|l| !l.starts_with("time histories:"))
                .collect::<Vec<_>>()
                .join("\n");
            assert!(th.contains("sampled at 128 Hz"), "{input}: {text}");
            assert!(
                th.contains("2 excitation(s)") && th.contains("3 response channel(s)"),
                "{input}: {text}"
            );
            lists.push(th);
        }
        for (k, what) in [(1, "MCAP"), (2, "CSV")] {
            assert!(
                outputs[0].0 == outputs[k].0,
                "{file}: UFF and {what} outputs differ: {}",
                first_difference(&outputs[0].1, &outputs[k].1)
            );
        }
        assert_eq!(lists[0], lists[1], "{file}");
        assert_eq!(lists[0], lists[2], "{file}");
        if file == "small-per-hit.uff" {
            assert!(lists[0].contains("3 hits"), "{}", lists[0]);
        }
    }
}

/// `rbprops report` shows `frf-est`'s per-hit table, in HTML and Markdown: one row per
/// hit of the recording, accepted or rejected as the generator's truth says, the clipped
/// hit with its overload reason and clipped samples on the clipped channel, the double
/// hit with its delay and ratio (the truth's second contact).
#[test]
fn report_shows_the_hit_table() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    std::fs::create_dir(&run).unwrap();
    estimate_to(&fixture("small-per-hit.uff"), &[], &run.join("run.mcap"));
    let truth = json("small-truth.json");
    let html = dir.path().join("report.html");
    let md = dir.path().join("report.md");
    for out in [&html, &md] {
        let st = super::common::rbprops()
            .arg("report")
            .arg(&run)
            .arg("-o")
            .arg(out)
            .output()
            .unwrap();
        assert!(
            st.status.success(),
            "{}",
            String::from_utf8_lossy(&st.stderr)
        );
    }
    let md = std::fs::read_to_string(&md).unwrap();
    let html = std::fs::read_to_string(&html).unwrap();
    assert!(md.contains("## Hits (frf-est)"), "{md}");
    assert!(html.contains("<h3>Hits (frf-est)</h3>"));
    let rows: Vec<&str> = md
        .lines()
        .skip_while(|l| !l.starts_with("## Hits"))
        .filter(|l| l.starts_with("| force"))
        .collect();
    let mut n = 0;
    for ex in truth["recording"]["excitations"].as_array().unwrap() {
        let id = ex["id"].as_str().unwrap();
        for th in ex["hits"].as_array().unwrap() {
            n += 1;
            let h = th["hit"].as_u64().unwrap();
            let row = rows
                .iter()
                .find(|r| r.starts_with(&format!("| {id} | {h} |")))
                .unwrap_or_else(|| panic!("{id} hit {h} missing: {rows:?}"));
            let cells: Vec<&str> = row.trim_matches('|').split(" | ").map(str::trim).collect();
            let accepted = th["accepted"].as_bool().unwrap();
            assert_eq!(
                cells[2],
                if accepted { "accepted" } else { "rejected" },
                "{row}"
            );
            assert!(html.contains(&format!(
                "<td class=\"t\">{id}</td><td class=\"t\">{h}</td>"
            )));
            if th["clipped"].as_bool().unwrap() {
                assert!(cells[3].contains("overload"), "{row}");
                let clipped: Vec<usize> = cells[5].split(' ').map(|c| c.parse().unwrap()).collect();
                let want = &th["clipped_samples"];
                assert_eq!(clipped[0] as u64, want["force"].as_u64().unwrap(), "{row}");
                for (k, c) in want["response"].as_array().unwrap().iter().enumerate() {
                    assert_eq!(clipped[k + 1] as u64, c.as_u64().unwrap(), "{row}");
                }
            }
            if let Some(d) = th["double"].as_object() {
                assert!(cells[3].contains("double hit"), "{row}");
                let delay: f64 = cells[6].parse().unwrap();
                let ratio: f64 = cells[7].trim_end_matches(" %").parse().unwrap();
                let want_delay = 1e3 * d["delay_s"].as_f64().unwrap();
                let want_ratio = 100.0 * d["ratio"].as_f64().unwrap();
                // The detector measures the second contact on the sampled force: one
                // sample (7.8 ms at 128 Hz) of delay, and its peak within a few percent.
                assert!(
                    (delay - want_delay).abs() <= 1e3 / 128.0 + 0.1,
                    "{row}: {want_delay} ms"
                );
                assert!(
                    (ratio - want_ratio).abs() <= 0.2 * want_ratio,
                    "{row}: {want_ratio} %"
                );
            } else {
                assert_eq!(cells[6], "–", "{row}");
            }
        }
    }
    assert_eq!(rows.len(), n, "{rows:?}");
}

/// The per-hit fixture as the recording model (to write it as MCAP or CSV).
fn recording(file: &str) -> rbprops_uff::timerec::TimeRecording {
    let bytes = std::fs::read(fixture(file)).unwrap();
    let uff = rbprops_uff::parse(&bytes, file).unwrap();
    let index = timehist::index_time_histories(&uff, &Default::default()).unwrap();
    rbprops_uff::timerec::from_uff(&uff, &index).unwrap()
}

fn write_mcap(path: &Path, msgs: &[rbprops_formats::wire::TimeHistoryMsg]) {
    let mut run = rbprops_formats::RunRecord::default();
    run.set(rbprops_formats::topics::TIME_HISTORY, msgs);
    std::fs::write(path, rbprops_formats::mcap_file::write(&run).unwrap()).unwrap();
}

fn write_csv(dir: &Path, files: &[(String, String)]) {
    std::fs::create_dir_all(dir).unwrap();
    for (name, text) in files {
        std::fs::write(dir.join(name), text).unwrap();
    }
}

/// The per-hit UFF fixture's text with `edit` applied to the lines of its `k`-th dataset
/// 58 (0-based; the line after `    58`, its record 7, is `lines[7]`).
fn edited_uff(k: usize, edit: impl FnOnce(&mut Vec<String>)) -> String {
    let text = std::fs::read_to_string(fixture("small-per-hit.uff")).unwrap();
    let lines: Vec<String> = text.lines().map(String::from).collect();
    let starts: Vec<usize> = (0..lines.len())
        .filter(|&i| lines[i].trim_end() == "    58" && i > 0 && lines[i - 1].trim() == "-1")
        .collect();
    let start = starts[k];
    let end = (start..lines.len())
        .find(|&i| lines[i].trim() == "-1")
        .unwrap();
    let mut block: Vec<String> = lines[start..end].to_vec();
    edit(&mut block);
    let mut out: Vec<String> = lines[..start].to_vec();
    out.extend(block);
    out.extend(lines[end..].iter().cloned());
    out.join("\n") + "\n"
}

/// Bad time histories in every format: each a clear error (exit 1, `error:`, the file,
/// the record and the problem, no output), or a rejected hit with its reason.
#[test]
fn bad_time_histories_are_named_errors_or_rejected_hits() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("out.mcap");
    let rec = recording("small-per-hit.uff");
    let mut cases: Vec<(String, Vec<&str>)> = Vec::new();
    // No recognisable force channel: UFF (record 9 says acceleration, no force label),
    // MCAP (the first channel is not a force), CSV (likewise).
    let uff = d.join("no-force.uff");
    let text = std::fs::read_to_string(fixture("small-per-hit.uff"))
        .unwrap()
        .replace(
            "        13    0    1    0 NONE                 N   ",
            "        12    0    1    0 NONE                 NONE",
        );
    std::fs::write(&uff, text).unwrap();
    cases.push((
        uff.display().to_string(),
        vec!["no-force.uff", "no force channel"],
    ));
    let mut msgs = rec.to_messages(false);
    msgs[1].channels[0].quantity = "acceleration".into();
    write_mcap(&d.join("no-force.mcap"), &msgs);
    cases.push((
        d.join("no-force.mcap").display().to_string(),
        vec![
            "no-force.mcap",
            "message 2",
            "no recognisable force channel",
        ],
    ));
    let mut files = rec.to_csv();
    files[0].1 = files[0].1.replace(",force,N,", ",acceleration,m/s^2,");
    write_csv(&d.join("no-force-csv"), &files);
    cases.push((
        d.join("no-force-csv").display().to_string(),
        vec!["no-force-csv", "no recognisable force channel"],
    ));
    // Channels of different length: UFF (a response record one sample short), MCAP (a
    // record declared shorter than its samples: a corrupted block), CSV (a row missing).
    let uff = d.join("short.uff");
    std::fs::write(
        &uff,
        edited_uff(1, |b| {
            b[7] = b[7].replacen("       256", "       255", 1);
            let last = b.len() - 1;
            let l = b[last].clone();
            b[last] = l[..l.len() - 20].to_string();
        }),
    )
    .unwrap();
    cases.push((
        uff.display().to_string(),
        vec!["short.uff", "dataset #4", "255 samples", "one length"],
    ));
    let mut files = rec.to_csv();
    let f = files.iter_mut().find(|f| f.0 == "force2-hit3.csv").unwrap();
    let mut lines: Vec<&str> = f.1.lines().collect();
    lines.pop();
    f.1 = lines.join("\n") + "\n";
    write_csv(&d.join("short-csv"), &files);
    cases.push((
        d.join("short-csv").display().to_string(),
        vec!["short-csv", "force2-hit3.csv", "255 samples", "one length"],
    ));
    // Different sampling: UFF (one record's increment), CSV (one file's time column).
    let uff = d.join("rate.uff");
    std::fs::write(
        &uff,
        edited_uff(2, |b| b[7] = b[7].replace("7.81250e-03", "7.81300e-03")),
    )
    .unwrap();
    cases.push((
        uff.display().to_string(),
        vec!["rate.uff", "dataset #5", "one sampling rate"],
    ));
    let mut files = rec.to_csv();
    let f = files.iter_mut().find(|f| f.0 == "force1-hit2.csv").unwrap();
    f.1 =
        f.1.lines()
            .enumerate()
            .map(|(k, l)| match (k, l.split_once(',')) {
                (0, _) | (_, None) => l.to_string(),
                (_, Some((_, rest))) => format!("{},{rest}", (k - 1) as f64 / 100.0),
            })
            .collect::<Vec<_>>()
            .join("\n");
    write_csv(&d.join("rate-csv"), &files);
    cases.push((
        d.join("rate-csv").display().to_string(),
        vec!["rate-csv", "force1-hit2.csv", "one sampling rate"],
    ));
    // A non-uniform time column (CSV: one time stamp moved by a third of a step).
    let mut files = rec.to_csv();
    let f = files.iter_mut().find(|f| f.0 == "force1-hit1.csv").unwrap();
    f.1 = f.1.replacen("\n0.078125,", "\n0.08,", 1);
    write_csv(&d.join("uneven-csv"), &files);
    cases.push((
        d.join("uneven-csv").display().to_string(),
        vec![
            "uneven-csv",
            "force1-hit1.csv",
            "line 12",
            "non-uniform time column",
        ],
    ));
    // A non-uniform abscissa in a UFF: record 7 field 3 = 0 (uneven), the data as (time,
    // value) pairs, one instant a third of a step late.
    let uff = d.join("uneven.uff");
    std::fs::write(
        &uff,
        edited_uff(0, |b| {
            b[7] = b[7].replacen("       256         1  ", "       256         0  ", 1);
            let values: Vec<String> = b[12..]
                .iter()
                .flat_map(|l| l.split_whitespace().map(String::from).collect::<Vec<_>>())
                .collect();
            b.truncate(12);
            for (k, v) in values.iter().enumerate() {
                let late = if k == 10 { 1.0 / 3.0 } else { 0.0 };
                b.push(format!("{:.12e} {v}", (k as f64 + late) * 7.8125e-3));
            }
        }),
    )
    .unwrap();
    cases.push((
        uff.display().to_string(),
        vec![
            "uneven.uff",
            "dataset #3",
            "record 7 field 3",
            "uneven abscissa",
        ],
    ));
    // A truncated or corrupted record: UFF cut short, MCAP samples cut short, a CSV cell
    // that is not a number.
    let uff = d.join("cut.uff");
    let bytes = std::fs::read(fixture("small-per-hit.uff")).unwrap();
    std::fs::write(&uff, &bytes[..bytes.len() * 3 / 5]).unwrap();
    cases.push((uff.display().to_string(), vec!["cut.uff"]));
    let mut msgs = rec.to_messages(true);
    let s = &mut msgs[0].records[2].samples;
    s.truncate(s.len() - 8);
    write_mcap(&d.join("cut.mcap"), &msgs);
    cases.push((
        d.join("cut.mcap").display().to_string(),
        vec![
            "cut.mcap",
            "message 1",
            "hit 3",
            "truncated or corrupted record",
        ],
    ));
    let mut files = rec.to_csv();
    let f = files.iter_mut().find(|f| f.0 == "force2-hit1.csv").unwrap();
    f.1 = f.1.replacen("\n0.0078125,", "\n0.0078125,x", 1);
    write_csv(&d.join("cell-csv"), &files);
    cases.push((
        d.join("cell-csv").display().to_string(),
        vec!["cell-csv", "force2-hit1.csv", "line 3", "is not a number"],
    ));
    for (input, want) in &cases {
        let st = frf_est().arg(input).arg("-o").arg(&out).output().unwrap();
        let err = String::from_utf8_lossy(&st.stderr);
        assert_eq!(st.status.code(), Some(1), "{input}: {err}");
        assert!(err.contains("error:"), "{input}: {err}");
        for w in want {
            assert!(err.contains(w), "{input}: '{w}' not in {err}");
        }
        assert!(!out.exists(), "{input}: output written");
    }
    // A hit at the record's edge (throughput records of 1728 samples, hits cut 4.5 s =
    // 576 samples long from 0.125 s before each trigger: the third hit's record, from
    // sample 1153, would cross the end): rejected with that reason, in the hit table.
    let st = frf_est()
        .arg(fixture("small-throughput-58b.uff"))
        .args([
            "--record-s",
            "4.5",
            "--pretrigger",
            "0.125",
            "--keep-rejected",
            "-o",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let est = processing(&out).frf_estimation.unwrap();
    let edge: Vec<_> = est
        .hits
        .iter()
        .filter(|h| h.reasons.iter().any(|r| r == "at the record's edge"))
        .collect();
    assert!(!edge.is_empty(), "{:?}", est.hits);
    assert!(edge.iter().all(|h| h.hit == 3), "{edge:?}");
}

/// `stage ARGS -o out`, which must succeed.
fn stage(bin: &str, args: &[&str], out: &Path) {
    let o = Command::new(bin)
        .args(args)
        .arg("-o")
        .arg(out)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "{bin} {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// The generator's Python and its impact-test case (`examples/tc2-impact-time.toml`:
/// five hits per excitation, anti-alias filter, 24-bit autoranged ADC, force and
/// response noise); `None` without numpy and pyuff.
fn impact_case() -> Option<(String, String)> {
    let py = rbprops_testkit::python(rbprops_testkit::NUMPY_PYUFF)?;
    let case = format!(
        "{}/../../scripts/refgen/examples/tc2-impact-time.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    Some((py, case))
}

/// An impact test of the independent generator (`case`, `seed`) written as per-hit
/// time histories and run through `frf-est | modal-fit | ni-select` with their defaults
/// (band 0.01–12.5 Hz) in `d`: the selection's MCAP and the truth file.
fn impact_selection(py: &str, case: &str, seed: &str, d: &Path) -> (PathBuf, PathBuf) {
    let (uff, truth) = (d.join("th.uff"), d.join("truth.json"));
    let o = rbprops_testkit::refgen(py)
        .arg(case)
        .args([
            "--seed",
            seed,
            "--time-layout",
            "per-hit",
            "--binary",
            "--quiet",
        ])
        .arg("-o")
        .arg(&uff)
        .arg("--truth")
        .arg(&truth)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let path = |p: &Path| p.to_str().unwrap().to_string();
    let (frf, fit, ni) = (d.join("frf.mcap"), d.join("fit.mcap"), d.join("ni.mcap"));
    stage(
        env!("CARGO_BIN_EXE_frf-est"),
        &[&path(&uff), "--band", "0.01:12.5", "--force"],
        &frf,
    );
    stage(
        &sibling("modal-fit"),
        &[&path(&frf), "--band", "0.01:12.5", "--force"],
        &fit,
    );
    stage(&sibling("ni-select"), &[&path(&fit), "--force"], &ni);
    (ni, truth)
}

/// The path of another binary of this build (beside `frf-est`).
fn sibling(name: &str) -> String {
    let here = PathBuf::from(env!("CARGO_BIN_EXE_frf-est"));
    here.with_file_name(name).to_str().unwrap().to_string()
}

/// `rb-solve`'s default bootstrap on an impact test through `frf-est` (seed 9001 of
/// `examples/tc2-impact-time.toml`): modal-fit weighted its fits by frf-est's line
/// variances and kept a spurious 6 Hz pole and a weak mode-2 estimate the selection does
/// not use. The replicates were refitted with the default weights instead, those poles
/// ran off in 99 of 100 replicates, and rb-solve fell back to the linearised errors; with
/// the fit's weighting the bootstrap runs (every estimate says `bootstrap`, no replicate
/// fails: 23 of 100 still did with the unused poles checked as the used ones) and its mass σ
/// is the scatter of the weighted estimator, about the linearised one (1.5 g each on this
/// seed; the unweighted replicates had given 56 g). Factor 3 either way: the two
/// estimate one scatter from different approximations (docs/results.md, session 35).
#[test]
fn the_bootstrap_refits_impact_tests_as_modal_fit_weighted_them() {
    let Some((py, case)) = impact_case() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (ni, _) = impact_selection(&py, &case, "9001", dir.path());
    let solve = |u: &str| -> serde_json::Value {
        let o = Command::new(sibling("rb-solve"))
            .arg(&ni)
            .args(["--format", "json", "--uncertainty", u])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{stderr}");
        // The unused poles held where they run off: no replicate lost (23 of 100 were).
        assert!(!stderr.contains("replicates failed"), "{stderr}");
        serde_json::from_slice(&o.stdout).unwrap()
    };
    let (boot, lin) = (solve("bootstrap"), solve("linearised"));
    for (b, l) in boot.as_array().unwrap().iter().zip(lin.as_array().unwrap()) {
        if !["bretl_conti", "toivola_nuutila"].contains(&b["method"].as_str().unwrap()) {
            continue;
        }
        assert_eq!(b["uncertainty_method"], "bootstrap", "{}", b["method"]);
        let ratio = b["mass_std_kg"].as_f64().unwrap() / l["mass_std_kg"].as_f64().unwrap();
        assert!(
            (1.0 / 3.0..3.0).contains(&ratio),
            "{}: bootstrap mass σ {} against linearised {}",
            b["method"],
            b["mass_std_kg"],
            l["mass_std_kg"]
        );
    }
}

/// Coverage of `rb-solve`'s bootstrap intervals on impact tests of the independent
/// generator through `frf-est` (`scripts/refgen/coverage_study.py --impact`, seeds
/// 9081–9100): every property of both estimators inside ±1.96σ on at least 16 of the
/// 20. At the nominal 95 % fewer than 16 has probability 1.6 %; before the force noise's
/// common error was drawn once for all channels of an excitation Jzz was covered on 52 of
/// 100 such tests, and at that rate 16 or more of 20 has probability 0.5 %
/// (docs/results.md, session 36).
#[test]
fn bootstrap_intervals_cover_impact_tests() {
    let Some((py, _)) = impact_case() else {
        return;
    };
    let root = format!("{}/../..", env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("coverage.json");
    let o = Command::new(py)
        .arg(format!("{root}/scripts/refgen/coverage_study.py"))
        .args(["--impact", "--seeds", "9081:9100", "--bin"])
        .arg(PathBuf::from(sibling("rb-solve")).parent().unwrap())
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rows: Vec<serde_json::Value> =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(rows.len(), 20);
    const PROPS: [&str; 10] = [
        "m", "cx", "cy", "cz", "Jxx", "Jyy", "Jzz", "Jxy", "Jxz", "Jyz",
    ];
    for method in ["bretl_conti/bootstrap", "toivola_nuutila/bootstrap"] {
        for (i, p) in PROPS.iter().enumerate() {
            let covered = rows
                .iter()
                .filter(|r| {
                    let (e, s) = (&r[method]["err"][i], &r[method]["sigma"][i]);
                    e.as_f64().unwrap().abs() <= 1.96 * s.as_f64().unwrap()
                })
                .count();
            assert!(covered >= 16, "{method} {p}: {covered} of 20 covered");
        }
    }
}

/// The force noise's common error that `frf-est` states (`force_noise` in
/// `/rbprops/frf_variance`) against the error it makes, on hits of the independent
/// generator recorded with its force noise only and with no noise
/// (`scripts/refgen/force_noise_study.py --seeds 9501:9530 --json`, 90 excitations):
/// - the error is common to the channels: their spread about the mean below 5 % of it
///   (measured: median 6·10⁻⁴, worst 7·10⁻³; per-channel errors would make it about 1);
/// - its power `mean |ε̄|²` over the stated `mean ρ²` is 1 within 3.5 standard errors of
///   the mean over excitations (each is a χ²₂/2-like ratio; SE about 0.1, so a ρ² off by
///   2× either way fails; these 30 seeds give 1.13 ± 0.11, 40 gave 1.13 ± 0.09);
/// - the null: the noise-free hits state no common error above 10⁻⁶ of the noisy ones'.
#[test]
fn the_stated_force_noise_error_is_the_error_it_makes() {
    let Some((py, _)) = impact_case() else {
        return;
    };
    let root = format!("{}/../..", env!("CARGO_MANIFEST_DIR"));
    let o = Command::new(py)
        .arg(format!("{root}/scripts/refgen/force_noise_study.py"))
        .args(["--seeds", "9501:9530", "--json", "--bin"])
        .arg(PathBuf::from(sibling("frf-est")).parent().unwrap())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let f = |k: &str| r[k].as_f64().unwrap();
    assert_eq!(r["excitations"].as_u64(), Some(90));
    assert!(f("spread_worst") < 0.05, "{r}");
    let (ratio, se) = (f("size_ratio_mean"), f("size_ratio_se"));
    assert!(se > 0.0 && se < 0.2, "{r}");
    assert!(
        (ratio - 1.0).abs() <= 3.5 * se,
        "stated ρ² against the error: {r}"
    );
    assert!(f("null_ratio_worst") <= 1e-6, "{r}");
}

/// Raw impact time histories of Test Case II from the independent generator
/// (`examples/tc2-impact-time.toml`: five hits per excitation, anti-alias filter, 24-bit
/// autoranged ADC, force and response noise) through `frf-est | modal-fit | ni-select |
/// rb-solve` with every default (the window `auto`, no `--exp-window`): the mass within
/// 0.2 % (issue 36), the centre of mass within 1 mm and the inertia within 0.5 % of the
/// largest moment about the centre-of-mass axes. On seeds 2001–2020 the generator's own
/// H1 over the same hits gives RMS errors of 0.30 %, 0.79 mm and 0.15 % (worst 0.59 %,
/// 1.6 mm, 0.26 %), this pipeline 0.011 %, 0.051 mm and 0.047 % (worst 0.020 %,
/// 0.14 mm, 0.091 %; docs/results.md, session 26). Seeds 2004 and 2013 gave 1.7 t and
/// 14 t while modal-fit's forward model-order test split its own partners.
#[test]
fn raw_impact_time_histories_give_the_properties_through_the_pipeline() {
    let Some((py, case)) = impact_case() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for seed in ["2001", "2004", "2013"] {
        let (ni, truth) = impact_selection(&py, &case, seed, d);
        let o = Command::new(sibling("rb-solve"))
            .arg(&ni)
            .args(["--format", "json", "--uncertainty", "linearised"])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let est: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let t: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&truth).unwrap()).unwrap();
        let (e, p) = (&est[0], &t["properties"]);
        let f = |v: &serde_json::Value| v.as_f64().unwrap();
        let mass = (f(&e["mass_kg"]) - f(&p["mass_kg"])) / f(&p["mass_kg"]);
        let com = (0..3)
            .map(|i| (f(&e["com_m"][i]) - f(&p["com_m"][i])).powi(2))
            .sum::<f64>()
            .sqrt();
        let largest = (0..3)
            .map(|i| f(&p["moments_kg_m2"][i]))
            .fold(0.0, f64::max);
        let inertia = (0..3)
            .flat_map(|i| (0..3).map(move |j| (i, j)))
            .map(|(i, j)| (f(&e["inertia_cm_kg_m2"][i][j]) - f(&p["inertia_cm_kg_m2"][i][j])).abs())
            .fold(0.0, f64::max)
            / largest;
        assert!(
            mass.abs() < 2e-3 && com < 1e-3 && inertia < 5e-3,
            "seed {seed}: mass {:.4} %, CoM {:.3} mm, J {:.4} % of the largest moment",
            100.0 * mass,
            1e3 * com,
            100.0 * inertia
        );
    }
}

/// Exactly-nominal impact tests from the independent generator (Test Case II,
/// `examples/tc2-impact-time.toml`, 24-bit) through `frf-est` and `model-check`: the check
/// names nothing and ends in its noise band. Seeds 1016 and 1093 are two of the three
/// nulls on which the check claimed `added_mass` (session 26 null study): the force
/// channel's noise puts a common complex gain error on all of an excitation's FRFs, and
/// a per-direction mass change mimics it; the claim must explain the data beyond a
/// per-excitation gain (docs/results.md, session 27).
#[test]
fn null_impact_tests_through_frf_est_name_nothing() {
    let Some(py) = rbprops_testkit::python(rbprops_testkit::NUMPY_PYUFF) else {
        return;
    };
    let root = format!("{}/../..", env!("CARGO_MANIFEST_DIR"));
    let case = format!("{root}/scripts/refgen/examples/tc2-impact-time.toml");
    let spec = format!("{root}/fixtures/specs/test-case-2.toml");
    let dir = tempfile::tempdir().unwrap();
    let (uff, frf) = (dir.path().join("th.uff"), dir.path().join("frf.mcap"));
    let path = |p: &Path| p.to_str().unwrap().to_string();
    let here = std::path::PathBuf::from(env!("CARGO_BIN_EXE_frf-est"));
    for seed in ["1016", "1093"] {
        let o = rbprops_testkit::refgen(&py)
            .arg(&case)
            .args([
                "--seed",
                seed,
                "--set",
                "time.adc_bits=24",
                "--time-layout",
                "per-hit",
            ])
            .args(["--binary", "--quiet", "-o"])
            .arg(&uff)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        stage(
            env!("CARGO_BIN_EXE_frf-est"),
            &[&path(&uff), "--band", "0.01:12.5", "--force"],
            &frf,
        );
        let o = Command::new(here.with_file_name("model-check"))
            .args([spec.as_str(), "-i", &path(&frf), "--format", "json"])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let c: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let named: Vec<&str> = c["accepted"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|a| a["id"].as_str())
            .collect();
        let (chi, band) = (c["chi2_nu_after"].as_f64().unwrap(), &c["noise_band"]);
        let (lo, hi) = (band[0].as_f64().unwrap(), band[1].as_f64().unwrap());
        assert!(
            named.is_empty() && c["ambiguous"].as_array().is_none_or(|a| a.is_empty()),
            "seed {seed}: named {named:?}, ambiguous {}",
            c["ambiguous"]
        );
        assert!(
            lo <= chi && chi <= hi,
            "seed {seed}: χ²/ν {chi} outside [{lo}, {hi}]"
        );
    }
}
