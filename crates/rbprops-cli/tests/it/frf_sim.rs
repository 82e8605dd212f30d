//! End-to-end behaviour of `frf-sim` as a program: reproducibility, formats, bad input.

use std::path::Path;
use std::process::Command;

fn frf_sim() -> Command {
    Command::new(env!("CARGO_BIN_EXE_frf-sim"))
}

fn run_ok(cmd: &mut Command) -> Vec<u8> {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

fn dir_bytes(p: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<(String, Vec<u8>)> = walk(p)
        .into_iter()
        .map(|f| {
            (
                f.strip_prefix(p).unwrap().display().to_string(),
                std::fs::read(&f).unwrap(),
            )
        })
        .collect();
    v.sort();
    v
}

fn walk(p: &Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(p).unwrap() {
        let path = e.unwrap().path();
        if path.is_dir() {
            out.extend(walk(&path));
        } else {
            out.push(path);
        }
    }
    out
}

#[test]
fn same_spec_and_seed_give_identical_bytes_for_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let mut outputs = Vec::new();
    for threads in ["1", "2"] {
        let mcap = dir.path().join(format!("t{threads}.mcap"));
        let csv = dir.path().join(format!("t{threads}"));
        for out in [&mcap, &csv] {
            // Same arguments apart from the output path would change the provenance, so
            // run in the output's directory with a relative name.
            let name = out
                .file_name()
                .unwrap()
                .to_str()
                .unwrap()
                .replace(threads, "X");
            let sub = dir.path().join(format!("run{threads}"));
            std::fs::create_dir_all(&sub).unwrap();
            run_ok(
                frf_sim()
                    .current_dir(&sub)
                    .env("RAYON_NUM_THREADS", threads)
                    .args(["--example", "demo", "--seed", "7", "-o", &name]),
            );
        }
        let sub = dir.path().join(format!("run{threads}"));
        outputs.push((
            std::fs::read(sub.join("tX.mcap")).unwrap(),
            dir_bytes(&sub.join("tX")),
        ));
    }
    assert!(
        outputs[0].0 == outputs[1].0,
        "MCAP differs between 1 and 2 threads"
    );
    assert!(
        outputs[0].1 == outputs[1].1,
        "CSV differs between 1 and 2 threads"
    );
    // A different seed changes the noise.
    let sub = dir.path().join("run1");
    run_ok(
        frf_sim()
            .current_dir(&sub)
            .args(["--example", "demo", "--seed", "8", "-o", "tX.mcap"]),
    );
    assert!(std::fs::read(sub.join("tX.mcap")).unwrap() != outputs[0].0);
}

#[test]
fn print_spec_is_a_valid_spec_for_every_example() {
    let list = String::from_utf8(run_ok(frf_sim().arg("--list-examples"))).unwrap();
    let names: Vec<&str> = list.lines().collect();
    assert!(
        names.contains(&"test-case-1") && names.contains(&"test-case-2"),
        "{names:?}"
    );
    let dir = tempfile::tempdir().unwrap();
    for n in names {
        let spec = run_ok(frf_sim().args(["--example", n, "--print-spec"]));
        let path = dir.path().join(format!("{n}.toml"));
        std::fs::write(&path, spec).unwrap();
        run_ok(
            frf_sim()
                .arg(&path)
                .arg("-o")
                .arg(dir.path().join(format!("{n}.mcap"))),
        );
    }
}

#[test]
fn bad_spec_fails_clearly_without_output() {
    let dir = tempfile::tempdir().unwrap();
    let spec = dir.path().join("bad.toml");
    let good = String::from_utf8(run_ok(frf_sim().args([
        "--example",
        "test-case-2",
        "--print-spec",
    ])))
    .unwrap();
    std::fs::write(&spec, good.replacen("[body]", "[body]\nbogus_key = 1", 1)).unwrap();
    let out_path = dir.path().join("out.mcap");
    let out = frf_sim()
        .arg(&spec)
        .arg("-o")
        .arg(&out_path)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bad.toml") && err.contains("bogus_key"),
        "{err}"
    );
    assert!(!out_path.exists());
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "no temp files left behind"
    );
    // Malformed TOML.
    std::fs::write(&spec, "name = \"x\"\n[body\n").unwrap();
    let out = frf_sim()
        .arg(&spec)
        .arg("-o")
        .arg(&out_path)
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("bad.toml"));
    // Unknown example.
    let out = frf_sim().args(["--example", "nope"]).output().unwrap();
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("test-case-1"));
}

#[test]
fn convert_mcap_csv_mcap_is_byte_identical() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.mcap");
    let csv = dir.path().join("a_csv");
    let b = dir.path().join("b.mcap");
    run_ok(frf_sim().args(["--example", "test-case-1", "-o"]).arg(&a));
    let rbprops = env!("CARGO_BIN_EXE_rbprops");
    run_ok(
        Command::new(rbprops)
            .arg("convert")
            .arg(&a)
            .arg("-o")
            .arg(&csv),
    );
    run_ok(
        Command::new(rbprops)
            .arg("convert")
            .arg(&csv)
            .arg("-o")
            .arg(&b),
    );
    assert!(
        std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap(),
        "MCAP → CSV → MCAP changed bytes"
    );
}
