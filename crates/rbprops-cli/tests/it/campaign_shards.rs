//! `rbprops campaign --shard K/N` and `rbprops campaign merge`: a campaign split over
//! shards and merged equals the one-machine run byte for byte (summary, runs, report), and
//! the merge refuses shards that are not one campaign's complete, non-overlapping set.

use crate::common::rbprops;
use rbprops_testkit::ok;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The demo campaign shrunk to 51 lines (0–12.5 Hz: the six rigid-body modes still
/// resolved), so that an item costs a few tens of milliseconds in a debug build.
fn tiny_spec(seed: usize, mass_scale: f64) -> String {
    let base = String::from_utf8(
        ok(Command::new(env!("CARGO_BIN_EXE_frf-sim"))
            .args(["--example", "demo", "--print-spec"])
            .output()
            .unwrap())
        .stdout,
    )
    .unwrap();
    let mut out = String::new();
    for line in base.lines() {
        let l = if line.starts_with("lines = ") {
            "lines = 51".to_string()
        } else if line.starts_with("seed = ") {
            format!("seed = {seed}")
        } else if let Some(m) = line.strip_prefix("mass_kg = ") {
            format!("mass_kg = {}", m.parse::<f64>().unwrap() * mass_scale)
        } else {
            line.to_string()
        };
        out.push_str(&l);
        out.push('\n');
    }
    out
}

/// A campaign of `n` tiny specs in three folders (labels `rig-a/…`, `rig-b/…`, top level),
/// plus, when `with_bad`, one spec that does not parse (an item that fails).
fn campaign(dir: &Path, n: usize, with_bad: bool) {
    for sub in ["rig-a", "rig-b"] {
        std::fs::create_dir_all(dir.join(sub)).unwrap();
    }
    for i in 0..n {
        let folder = ["rig-a/", "rig-b/", ""][i % 3];
        let text = tiny_spec(1000 + i, 0.9 + 0.2 * (i as f64 / n.max(1) as f64));
        std::fs::write(dir.join(format!("{folder}item-{i:03}.toml")), text).unwrap();
    }
    if with_bad {
        std::fs::write(dir.join("rig-b/broken.toml"), "name = 1\n").unwrap();
    }
}

fn run(cmd: &mut Command) -> Output {
    cmd.output().unwrap()
}

/// The stderr lines of a campaign without its last line (the counts, worded per run).
fn warning_lines(out: &Output) -> Vec<String> {
    let text = String::from_utf8_lossy(&out.stderr);
    text.lines()
        .filter(|l| l.starts_with("rbprops campaign: "))
        .map(String::from)
        .collect()
}

fn shard(dir: &Path, k: usize, n: usize, out: &Path, extra: &[&str]) -> Output {
    run(rbprops()
        .arg("campaign")
        .arg(dir)
        .args([
            "--uncertainty",
            "linearised",
            "--shard",
            &format!("{k}/{n}"),
        ])
        .arg("-o")
        .arg(out)
        .args(extra))
}

fn merge(shards: &[&Path], out: &Path) -> Output {
    run(rbprops()
        .args(["campaign", "merge"])
        .args(shards)
        .arg("-o")
        .arg(out))
}

fn labels(csv: &str) -> Vec<String> {
    let mut l: Vec<String> = rbprops_cli::summary::from_csv(csv)
        .unwrap()
        .into_iter()
        .map(|r| r.campaign)
        .collect();
    l.dedup();
    l
}

#[test]
fn two_hundred_items_in_four_shards_merge_to_the_single_run_byte_for_byte() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("campaign");
    campaign(&dir, 199, true);
    let single = tmp.path().join("single.csv");
    let one = run(rbprops()
        .arg("campaign")
        .arg(&dir)
        .args(["--uncertainty", "linearised", "-o"])
        .arg(&single));
    // The broken item fails the run, after the table is written.
    assert_eq!(
        one.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&one.stderr)
    );
    let single_csv = std::fs::read_to_string(&single).unwrap();
    let all = labels(&single_csv);
    assert_eq!(all.len(), 200);
    let mut sorted = all.clone();
    sorted.sort();
    assert_eq!(all, sorted, "items in path order");

    let shards: Vec<PathBuf> = (1..=4)
        .map(|k| tmp.path().join(format!("shard-{k}")))
        .collect();
    for (k, s) in shards.iter().enumerate() {
        let out = shard(&dir, k + 1, 4, s, &[]);
        // Only the shard holding the broken item fails.
        let broken = all.iter().position(|l| l == "rig-b/broken.toml").unwrap();
        let expect_fail = broken % 4 == k;
        assert_eq!(
            out.status.success(),
            !expect_fail,
            "shard {}: {}",
            k + 1,
            String::from_utf8_lossy(&out.stderr)
        );
        // Shard K holds exactly the items i with i mod 4 = K − 1, in order.
        let mine = labels(&std::fs::read_to_string(s.join("summary.csv")).unwrap());
        let want: Vec<String> = all.iter().skip(k).step_by(4).cloned().collect();
        assert_eq!(mine, want, "shard {}", k + 1);
    }
    let merged = tmp.path().join("merged");
    // Shards in any order.
    let m = merge(&[&shards[3], &shards[1], &shards[0], &shards[2]], &merged);
    assert_eq!(
        m.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&m.stderr)
    );
    let merged_csv = std::fs::read(merged.join("summary.csv")).unwrap();
    assert!(
        merged_csv == single_csv.as_bytes(),
        "merged summary differs from the single run's"
    );
    assert_eq!(warning_lines(&m), warning_lines(&one));
    assert!(!warning_lines(&one).is_empty());
    let last = String::from_utf8_lossy(&m.stderr);
    assert!(
        last.contains("200 items") && last.contains("1 failed"),
        "{last}"
    );
}

#[test]
fn shards_with_runs_merge_to_the_single_runs_runs_and_report() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("campaign");
    campaign(&dir, 7, false);
    let single = tmp.path().join("single");
    ok(run(rbprops()
        .arg("campaign")
        .arg(&dir)
        .args(["--uncertainty", "linearised", "-o"])
        .arg(single.join("summary.csv"))
        .arg("--runs")
        .arg(single.join("runs"))));
    let shards: Vec<PathBuf> = (1..=3).map(|k| tmp.path().join(format!("s{k}"))).collect();
    for (k, s) in shards.iter().enumerate() {
        let runs = s.join("runs");
        ok(shard(
            &dir,
            k + 1,
            3,
            s,
            &["--runs", runs.to_str().unwrap()],
        ));
    }
    let merged = tmp.path().join("merged");
    ok(merge(&[&shards[0], &shards[1], &shards[2]], &merged));
    // Every file of the single run's output, byte for byte, and no other but the manifest.
    let files = |root: &Path| -> Vec<(PathBuf, Vec<u8>)> {
        fn walk(root: &Path, d: &Path, out: &mut Vec<(PathBuf, Vec<u8>)>) {
            for e in std::fs::read_dir(d).unwrap() {
                let p = e.unwrap().path();
                if p.is_dir() {
                    walk(root, &p, out);
                } else {
                    out.push((
                        p.strip_prefix(root).unwrap().to_path_buf(),
                        std::fs::read(&p).unwrap(),
                    ));
                }
            }
        }
        let mut out = Vec::new();
        walk(root, root, &mut out);
        out.sort();
        out
    };
    let mut got = files(&merged);
    got.retain(|(p, _)| p != Path::new("rbprops-campaign.json"));
    let want = files(&single);
    assert_eq!(
        got.iter().map(|(p, _)| p).collect::<Vec<_>>(),
        want.iter().map(|(p, _)| p).collect::<Vec<_>>()
    );
    assert!(want.iter().any(|(p, _)| p.ends_with("run.mcap")));
    for ((p, a), (_, b)) in got.iter().zip(&want) {
        assert!(a == b, "{} differs", p.display());
    }
    // And the report made from either.
    let report = |input: &Path, out: &Path| {
        ok(run(rbprops().arg("report").arg(input).arg("-o").arg(out)));
        std::fs::read(out).unwrap()
    };
    assert!(
        report(&merged, &tmp.path().join("a.html")) == report(&single, &tmp.path().join("b.html")),
        "reports differ"
    );
    // A merge replaces its previous output (marked by its manifest), not anything else.
    ok(merge(&[&shards[0], &shards[1], &shards[2]], &merged));
}

fn error_of(out: &Output) -> String {
    assert!(!out.status.success(), "expected a failure");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn merge_refuses_missing_overlapping_and_foreign_shards() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let dir = t.join("campaign");
    campaign(&dir, 3, false);
    let s = |name: &str| t.join(name);
    ok(shard(&dir, 1, 2, &s("a1"), &[]));
    ok(shard(&dir, 2, 2, &s("a2"), &[]));
    ok(shard(&dir, 1, 2, &s("a1-again"), &[]));
    let out = s("merged");

    let e = error_of(&merge(&[&s("a1")], &out));
    assert!(
        e.contains("shard 2/2 missing") && e.contains("a1 = 1/2"),
        "{e}"
    );
    let e = error_of(&merge(&[&s("a1"), &s("a2"), &s("a1-again")], &out));
    assert!(
        e.contains("a1") && e.contains("a1-again") && e.contains("both shard 1/2"),
        "{e}"
    );

    // Split differently.
    ok(shard(&dir, 2, 3, &s("b2"), &[]));
    let e = error_of(&merge(&[&s("a1"), &s("b2")], &out));
    assert!(
        e.contains("shard 1/2") && e.contains("shard 2/3") && e.contains("b2"),
        "{e}"
    );

    // Different options: the uncertainty method (bootstrap: the default).
    ok(run(rbprops()
        .arg("campaign")
        .arg(&dir)
        .args(["--shard", "2/2", "-o"])
        .arg(s("c2"))));
    let e = error_of(&merge(&[&s("a1"), &s("c2")], &out));
    assert!(
        e.contains("different options") && e.contains("c2") && e.contains("Bootstrap"),
        "{e}"
    );
    // Runs in one shard, not in the other.
    ok(shard(
        &dir,
        2,
        2,
        &s("d2"),
        &["--runs", s("d2").join("runs").to_str().unwrap()],
    ));
    let e = error_of(&merge(&[&s("a1"), &s("d2")], &out));
    assert!(
        e.contains("different options") && e.contains("--runs"),
        "{e}"
    );

    // A different campaign: one item more.
    std::fs::write(dir.join("extra.toml"), tiny_spec(7, 1.0)).unwrap();
    ok(shard(&dir, 2, 2, &s("e2"), &[]));
    let e = error_of(&merge(&[&s("a1"), &s("e2")], &out));
    assert!(
        e.contains("different campaigns")
            && e.contains("'extra.toml' is an item in")
            && e.contains("e2"),
        "{e}"
    );
    std::fs::remove_file(dir.join("extra.toml")).unwrap();

    // Not a shard; a shard whose table was edited.
    let e = error_of(&merge(&[&s("a1"), &dir], &out));
    assert!(e.contains("not a campaign shard"), "{e}");
    let edited = s("a2").join("summary.csv");
    let text = std::fs::read_to_string(&edited).unwrap();
    std::fs::write(&edited, text.replacen("bretl_conti", "bretl_kont", 1)).unwrap();
    let e = error_of(&merge(&[&s("a1"), &s("a2")], &out));
    assert!(
        e.contains("summary.csv") && e.contains("run the shard again"),
        "{e}"
    );
    assert!(!out.exists(), "no output from a refused merge");

    // Shard paths: not inside the campaign, runs in the shard's own directory.
    let e = error_of(&shard(&dir, 1, 2, &dir.join("shard-1"), &[]));
    assert!(e.contains("inside the campaign directory"), "{e}");
    let e = error_of(&shard(
        &dir,
        1,
        2,
        &s("f1"),
        &["--runs", s("elsewhere").to_str().unwrap()],
    ));
    assert!(e.contains("--runs") && e.contains("f1"), "{e}");
    let e = error_of(&run(rbprops()
        .arg("campaign")
        .arg(&dir)
        .args(["--shard", "3/2", "-o"])
        .arg(s("g"))));
    assert!(e.contains("1 ≤ K ≤ N"), "{e}");

    // The two good shards still merge, into the single run's table.
    std::fs::write(&edited, text).unwrap();
    ok(merge(&[&s("a2"), &s("a1")], &out));
    let single = ok(run(rbprops()
        .arg("campaign")
        .arg(&dir)
        .args(["--uncertainty", "linearised"])))
    .stdout;
    assert!(std::fs::read(out.join("summary.csv")).unwrap() == single);
}
