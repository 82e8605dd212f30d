//! The campaign runner against single runs, and one pipeline through every input format.

use std::path::Path;
use std::process::{Command, Stdio};

fn bin(name: &str) -> Command {
    Command::new(match name {
        "frf-sim" => env!("CARGO_BIN_EXE_frf-sim"),
        "modal-fit" => env!("CARGO_BIN_EXE_modal-fit"),
        "ni-select" => env!("CARGO_BIN_EXE_ni-select"),
        "rb-solve" => env!("CARGO_BIN_EXE_rb-solve"),
        _ => env!("CARGO_BIN_EXE_rbprops"),
    })
}

fn ok(out: std::process::Output) -> Vec<u8> {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

/// `frf-sim SPEC | modal-fit | ni-select | rb-solve -o OUT` with real pipes.
fn pipeline(input: &[&str], out: &Path) {
    let mut sim = bin("frf-sim")
        .args(input)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut fit = bin("modal-fit")
        .stdin(sim.stdout.take().unwrap())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut sel = bin("ni-select")
        .stdin(fit.stdout.take().unwrap())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let solve = bin("rb-solve")
        .stdin(sel.stdout.take().unwrap())
        .arg("-o")
        .arg(out)
        .args(["--format", "json", "--uncertainty", "linearised"])
        .output()
        .unwrap();
    for c in [&mut sim, &mut fit, &mut sel] {
        assert!(c.wait().unwrap().success());
    }
    ok(solve);
}

#[test]
fn campaign_rows_equal_single_runs_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let specs = dir.path().join("specs");
    std::fs::create_dir_all(specs.join("sub")).unwrap();
    let base = String::from_utf8(ok(bin("frf-sim")
        .args(["--example", "demo", "--print-spec"])
        .output()
        .unwrap()))
    .unwrap();
    let names = ["a.toml", "sub/b.toml", "c.toml"];
    for (k, n) in names.iter().enumerate() {
        let text = base.replacen("seed = ", &format!("seed = {}{}", k + 1, ""), 1);
        std::fs::write(specs.join(n), text).unwrap();
    }
    let summary = dir.path().join("summary.csv");
    ok(bin("rbprops")
        .arg("campaign")
        .arg(&specs)
        .args(["--uncertainty", "linearised"])
        .arg("-o")
        .arg(&summary)
        .output()
        .unwrap());
    let rows = rbprops_cli::summary::from_csv(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    for n in names {
        let out = dir.path().join(format!("{}.mcap", n.replace('/', "_")));
        pipeline(&[specs.join(n).to_str().unwrap()], &out);
        let single = String::from_utf8(ok(bin("rbprops")
            .arg("summary")
            .arg(&out)
            .args(["--campaign", n])
            .output()
            .unwrap()))
        .unwrap();
        let single = rbprops_cli::summary::from_csv(&single).unwrap();
        let mine: Vec<_> = rows.iter().filter(|r| r.campaign == n).cloned().collect();
        assert!(!mine.is_empty(), "no campaign rows for {n}");
        // Same numbers bit for bit (warnings aside: single runs may differ only in wording).
        for (a, b) in mine.iter().zip(&single) {
            assert_eq!(a.numbers(), b.numbers(), "{n} {}", a.method);
            assert_eq!(a.modes, b.modes);
        }
        assert_eq!(mine.len(), single.len());
    }
}

#[test]
fn campaign_reports_a_bad_item_and_fails() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("bad.toml"), "name = 1\n").unwrap();
    let out = bin("rbprops")
        .arg("campaign")
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("bad.toml") && stdout.contains(",error,"),
        "{stdout}"
    );
}

#[test]
fn test_case_2_gives_the_same_properties_from_mcap_csv_and_uff() {
    let dir = tempfile::tempdir().unwrap();
    let mcap = dir.path().join("tc2.mcap");
    ok(bin("frf-sim")
        .args(["--example", "test-case-2", "-o"])
        .arg(&mcap)
        .output()
        .unwrap());
    let csv = dir.path().join("tc2_csv");
    let uff = dir.path().join("tc2.uff");
    let b58 = dir.path().join("tc2.58b");
    for target in [&csv, &uff, &b58] {
        ok(bin("rbprops")
            .arg("convert")
            .arg(&mcap)
            .arg("-o")
            .arg(target)
            .output()
            .unwrap());
    }
    let estimate = |input: &Path| -> Vec<f64> {
        let fit = dir.path().join("fit.mcap");
        ok(bin("modal-fit")
            .arg(input)
            .arg("-o")
            .arg(&fit)
            .output()
            .unwrap());
        let sel = ok(bin("ni-select").arg(&fit).output().unwrap());
        let mut solve = bin("rb-solve")
            .args([
                "--format",
                "json",
                "--method",
                "toivola-nuutila",
                "--uncertainty",
                "linearised",
            ])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .unwrap();
        use std::io::Write;
        solve.stdin.take().unwrap().write_all(&sel).unwrap();
        let json: serde_json::Value =
            serde_json::from_slice(&ok(solve.wait_with_output().unwrap())).unwrap();
        let e = &json[0];
        let mut v = vec![e["mass_kg"].as_f64().unwrap()];
        v.extend(
            e["com_m"]
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap()),
        );
        v.extend(
            e["inertia_cm_kg_m2"]
                .as_array()
                .unwrap()
                .iter()
                .flat_map(|r| {
                    r.as_array()
                        .unwrap()
                        .iter()
                        .map(|x| x.as_f64().unwrap())
                        .collect::<Vec<_>>()
                }),
        );
        v
    };
    let reference = estimate(&mcap);
    assert_eq!(estimate(&csv), reference, "CSV must be bit-exact");
    assert_eq!(estimate(&b58), reference, "binary 58b must be bit-exact");
    // ASCII UFF carries 13 significant digits: the estimate agrees to that precision.
    for (a, b) in estimate(&uff).iter().zip(&reference) {
        assert!((a - b).abs() <= 1e-10 * b.abs().max(1e-3), "{a} vs {b}");
    }
}

#[test]
fn pyuff_reads_what_we_write() {
    let Some(py) = rbprops_testkit::python(&["pyuff"]) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    for name in ["rbprops_ascii", "rbprops_binary"] {
        let uff = root.join(format!("fixtures/uff/written/{name}.uff"));
        let json = root.join(format!("fixtures/uff/written/{name}.json"));
        assert!(uff.exists(), "{} missing", uff.display());
        let out = Command::new(&py)
            .arg(root.join("scripts/check_uff_with_pyuff.py"))
            .arg(&uff)
            .arg(&json)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
    }
    // And a file written by the frf-sim → convert path.
    let mcap = dir.path().join("tc1.mcap");
    ok(bin("frf-sim")
        .args(["--example", "test-case-1", "-o"])
        .arg(&mcap)
        .output()
        .unwrap());
    let uff = dir.path().join("tc1.uff");
    ok(bin("rbprops")
        .arg("convert")
        .arg(&mcap)
        .arg("-o")
        .arg(&uff)
        .output()
        .unwrap());
    let out = Command::new(&py).args(["-c", "import pyuff,sys; d=pyuff.UFF(sys.argv[1]).read_sets(); print(sum(1 for s in d if s['type']==58))"]).arg(&uff).output().unwrap();
    assert_eq!(
        String::from_utf8_lossy(&out.stdout).trim(),
        "45",
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
