//! `rbprops report OUT -o report.html` on a campaign of UFF exports (written by pyuff with
//! FRFs computed by numpy in `scripts/uff_campaign.py`, not by rbprops-sim), with a model
//! check against a nominal spec from `init-spec`: one self-contained page, opened in
//! headless Chromium, where every figure renders with a non-empty box.

use crate::common::rbprops;
use rbprops_core::records::DiagnosticKind;
use rbprops_testkit::{chromium, ok, python, repo_root};
use std::path::{Path, PathBuf};
use std::process::Command;

/// A campaign of `n` exports with a nominal spec from init-spec, run with `--runs`, in
/// `dir/out` (summary.csv and runs/).
fn campaign(py: &str, dir: &Path, n: usize) -> PathBuf {
    let ex = dir.join("exports");
    ok(Command::new(py)
        .arg(repo_root().join("scripts/uff_campaign.py"))
        .arg("generate")
        .arg(&ex)
        .args(["--n", &n.to_string(), "--df", "0.05"])
        .output()
        .unwrap());
    let init = dir.join("init.toml");
    ok(rbprops()
        .arg("init-spec")
        .arg(ex.join("run-01.uff"))
        .arg("-o")
        .arg(&init)
        .output()
        .unwrap());
    ok(Command::new(py)
        .arg(repo_root().join("scripts/uff_campaign.py"))
        .arg("fill-spec")
        .arg(&init)
        .arg(ex.join("truth.json"))
        .arg("-o")
        .arg(ex.join("nominal.toml"))
        .output()
        .unwrap());
    // Three effects screened to keep a debug build quick (as in tests/uff_campaign.rs).
    let cfg = ex.join("campaign.toml");
    let mut text = std::fs::read_to_string(&cfg).unwrap();
    text += "check_only = [\"channel_gain\", \"sensor_position\", \"exponential_window\"]\n";
    std::fs::write(&cfg, text).unwrap();
    let out = dir.join("out");
    ok(rbprops()
        .arg("campaign")
        .arg(&ex)
        .arg("-o")
        .arg(out.join("summary.csv"))
        .arg("--runs")
        .arg(out.join("runs"))
        .output()
        .unwrap());
    out
}

/// What the browser shows of the page: the number of top-level `<svg>` elements, of those
/// with a non-empty box, and every diagnostic kind's heading with the sentence rendered
/// under it (visible text, one pair per kind group).
struct Rendered {
    svgs: usize,
    rendered: usize,
    kinds: Vec<(String, String)>,
}

/// Opens `page` in headless Chromium with a script appended (to a copy: the report itself
/// runs no script) that counts the `<svg>` elements and those whose bounding box is
/// non-empty, and reads each diagnostic kind's heading and sentence as rendered, and
/// returns what it wrote into the DOM.
fn rendered(chrome: &Path, page: &Path) -> Rendered {
    let html = std::fs::read_to_string(page).unwrap();
    let probe = "<script>window.addEventListener('load',()=>{const s=[...document.querySelectorAll('body svg')].filter(e=>!e.parentElement.closest('svg'));const n=s.filter(e=>{const r=e.getBoundingClientRect();return r.width>1&&r.height>1;}).length;const k=[...document.querySelectorAll('li.kind')].map(e=>e.querySelector('b').innerText+'|'+e.querySelector('p.expl').innerText);const p=document.createElement('pre');p.id='rbprops-probe';p.textContent='svgs='+s.length+' rendered='+n+'\\n'+k.join('\\n');document.body.appendChild(p);});</script>";
    let probe_page = page.with_file_name("probe.html");
    std::fs::write(
        &probe_page,
        html.replace("</body>", &format!("{probe}</body>")),
    )
    .unwrap();
    let profile = tempfile::tempdir().unwrap();
    let out = Command::new(chrome)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--virtual-time-budget=5000",
        ])
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .arg("--dump-dom")
        .arg(format!("file://{}", probe_page.display()))
        .output()
        .unwrap();
    let dom = String::from_utf8_lossy(&out.stdout);
    let text = dom
        .split("id=\"rbprops-probe\">")
        .nth(1)
        .and_then(|s| s.split('<').next())
        .unwrap_or_else(|| {
            panic!(
                "chromium did not run the probe (status {}):\n{}",
                out.status,
                String::from_utf8_lossy(&out.stderr)
            )
        });
    let mut lines = text.lines();
    let line = lines.next().unwrap_or_default();
    let num = |key: &str| -> usize {
        line.split_whitespace()
            .find_map(|w| w.strip_prefix(key))
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("probe line '{line}'"))
    };
    // The page is HTML-escaped in the DOM dump: the sentences hold no markup characters
    // but apostrophes, which Chromium writes as they are.
    let kinds = lines
        .filter_map(|l| l.split_once('|'))
        .map(|(k, s)| (k.trim().to_string(), s.trim().replace("&amp;", "&")))
        .collect();
    Rendered {
        svgs: num("svgs="),
        rendered: num("rendered="),
        kinds,
    }
}

#[test]
fn campaign_report_is_one_page_with_every_figure_rendered() {
    let Some(py) = python(&["pyuff", "numpy", "pandas"]) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    // Six exports: run-06 (index 5) has channel 102y reading 6 % high (the generator's
    // calibration error), so one recording's check names an effect and draws its worst
    // channels.
    let out = campaign(&py, dir.path(), 6);
    let page = out.join("report.html");
    ok(rbprops()
        .arg("report")
        .arg(&out)
        .arg("-o")
        .arg(&page)
        .args(["--title", "UFF campaign <6 exports>"])
        .output()
        .unwrap());
    let html = std::fs::read_to_string(&page).unwrap();
    // Self-contained: no script, no link to another file, no image by reference.
    for banned in ["<script", "<link", "<img", "src=", "href=", "url("] {
        assert!(!html.contains(banned), "report holds '{banned}'");
    }
    assert!(html.contains("<h1>UFF campaign &lt;6 exports&gt;</h1>"));
    // A section per recording, with its estimates, verdict and warnings.
    for k in 1..=6 {
        assert!(html.contains(&format!("Recording run-0{k}.")), "run-0{k}");
    }
    assert_eq!(html.matches("<h3>Model check</h3>").count(), 6);
    assert_eq!(html.matches("<h3>Warnings</h3>").count(), 6);
    assert!(html.contains("channel_gain"), "run-06's verdict");
    // The summary table gives each check's verdict as a short label (the full text is in
    // each recording's section); what a test cannot see is said once, not per row.
    let table = &html[html.find("<h2>Summary</h2>").unwrap()..];
    let table = &table[..table.find("</table>").unwrap()];
    assert!(!table.contains("cannot be seen"), "{table}");
    assert!(table.contains("clean, "), "{table}");
    let gain_rows = table
        .lines()
        .filter(|l| l.contains("run-06") && l.contains("channel_gain"))
        .count();
    assert!(gain_rows >= 1, "{table}");
    assert!(html.matches("What these tests cannot see").count() <= 1);
    // Every figure each run directory holds is on the page, and the model check's
    // figures are among them (worst channels only where a cell was flagged).
    let mut n_files = 0;
    for e in std::fs::read_dir(out.join("runs")).unwrap() {
        let d = e.unwrap().path();
        let names: Vec<String> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".svg"))
            .collect();
        for kind in [
            "residual_map_before.svg",
            "residual_map_after.svg",
            "ni.svg",
            "estimates.svg",
        ] {
            assert!(
                names.iter().any(|n| n == kind),
                "{}: no {kind}",
                d.display()
            );
        }
        assert!(names.iter().any(|n| n.starts_with("fit_")));
        assert!(names.iter().any(|n| n.starts_with("stabilisation_")));
        n_files += names.len();
    }
    // The worst channels of run-06: its three strongest pairs are the miscalibrated
    // channel 102y under each of the three excitations (weaker pairs follow where the
    // baseline fit spread the error), each panel with the measured, nominal, baseline and
    // improved traces.
    let worst =
        std::fs::read_to_string(out.join("runs/run-06_unv/check_worst_channels.svg")).unwrap();
    let titles: Vec<&str> = worst
        .split('>')
        .filter_map(|t| t.split('<').next())
        .map(str::trim)
        .filter(|t| t.contains(" / "))
        .collect();
    assert!(titles.len() >= 3, "worst-channel panels: {titles:?}");
    let mut first: Vec<&str> = titles[..3].to_vec();
    first.sort();
    assert_eq!(
        first,
        ["201-x / 102y", "202y / 102y", "203-z / 102y"],
        "worst-channel panels: {titles:?}"
    );
    for legend in ["measured", "nominal spec", "baseline fit", "improved"] {
        assert!(worst.contains(legend), "legend '{legend}'");
    }
    // The campaign's own figure (mass per recording) plus every run's figures.
    let n_svg = html.matches("<svg").count();
    assert_eq!(n_svg, n_files + 1, "figures on the page vs files written");
    // pandas reads the summary with plain read_csv: one row per recording and estimator.
    let check = "import pandas as pd, sys\nd = pd.read_csv(sys.argv[1])\nassert d['campaign'].nunique() == 6, set(d['campaign'])\nassert 'check_verdict' in d.columns and d['mass_kg'].dtype.kind == 'f'\nprint(len(d))\n";
    let o = ok(Command::new(&py)
        .arg("-c")
        .arg(&check)
        .arg(out.join("summary.csv"))
        .output()
        .unwrap());
    assert!(
        String::from_utf8_lossy(&o.stdout)
            .trim()
            .parse::<usize>()
            .unwrap()
            >= 6
    );
    // Diagnostics are grouped by kind, each kind with its own sentence; no generic one.
    assert!(!html.contains("A condition the stage noticed while computing"));
    assert!(
        html.contains("<li class=\"kind\">"),
        "no diagnostic kind on the page"
    );
    // The page in a browser: every figure has a non-empty box, and every kind group shows
    // the sentence written for that kind.
    let Some(chrome) = chromium() else { return };
    let r = rendered(&chrome, &page);
    assert_eq!(
        r.svgs, n_svg,
        "top-level <svg> elements seen by the browser"
    );
    assert_eq!(r.rendered, r.svgs, "figures with an empty box");
    assert_eq!(
        r.kinds.len(),
        html.matches("<li class=\"kind\">").count(),
        "kind groups seen by the browser"
    );
    for (name, sentence) in &r.kinds {
        let kind: DiagnosticKind = name.replace(' ', "_").parse().unwrap();
        assert_eq!(sentence, kind.sentence(), "the sentence shown for {name}");
    }
}

#[test]
fn markdown_report_still_works_and_html_refuses_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    // A summary CSV of a simulated run (rbprops' own pipeline: this test is about the
    // report's formats, not the numbers).
    let spec = dir.path().join("demo.toml");
    let o = ok(Command::new(env!("CARGO_BIN_EXE_frf-sim"))
        .args(["--example", "demo", "--print-spec"])
        .output()
        .unwrap());
    std::fs::write(&spec, &o.stdout).unwrap();
    let summary = dir.path().join("summary.csv");
    ok(rbprops()
        .arg("campaign")
        .arg(dir.path())
        .args(["--uncertainty", "linearised", "-o"])
        .arg(&summary)
        .output()
        .unwrap());
    let md_dir = dir.path().join("md");
    ok(rbprops()
        .arg("report")
        .arg(&summary)
        .arg("-o")
        .arg(&md_dir)
        .output()
        .unwrap());
    assert!(std::fs::read_to_string(md_dir.join("report.md"))
        .unwrap()
        .contains("| demo.toml |"));
    let page = dir.path().join("r.html");
    ok(rbprops()
        .arg("report")
        .arg(&summary)
        .arg("-o")
        .arg(&page)
        .output()
        .unwrap());
    let html = std::fs::read_to_string(&page).unwrap();
    assert!(html.contains("<td class=\"t\">demo.toml</td>"));
    // A directory that is neither a campaign's output nor a run: an error naming it, no file.
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let bad = dir.path().join("bad.html");
    let o = rbprops()
        .arg("report")
        .arg(&empty)
        .arg("-o")
        .arg(&bad)
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("empty") && err.contains("not a report input"),
        "{err}"
    );
    assert!(!bad.exists());
}
