//! Fault corpus (issue #42): output paths, size bombs, arguments, records, signals, full
//! devices, closed streams and FIFOs, against the debug binaries.
//!
//! For every case: either a clean `error:` with exit status 1 (2 for clap's command-line
//! errors) and no panic, or output identical to the clean run; no file outside the output
//! path touched; no temporary file left. Deterministic: no timing (the signal case waits
//! on a FIFO the program opens once its temporary file exists).

use rbprops_formats::{mcap_file, topics, JsonTopic, RunRecord};
use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

fn exe(name: &str) -> &'static str {
    match name {
        "frf-sim" => env!("CARGO_BIN_EXE_frf-sim"),
        "modal-fit" => env!("CARGO_BIN_EXE_modal-fit"),
        "ni-select" => env!("CARGO_BIN_EXE_ni-select"),
        "rb-solve" => env!("CARGO_BIN_EXE_rb-solve"),
        "model-check" => env!("CARGO_BIN_EXE_model-check"),
        _ => env!("CARGO_BIN_EXE_rbprops"),
    }
}

/// A run's result.
struct Out {
    code: Option<i32>,
    signal: Option<i32>,
    stdout: Vec<u8>,
    stderr: String,
}

impl Out {
    fn ok(&self) -> &Self {
        assert_eq!(self.code, Some(0), "expected success: {}", self.stderr);
        self
    }
    /// A clean error: the status, an `error:` line, no panic.
    fn error(&self, code: i32, mentions: &[&str]) -> &Self {
        assert_eq!(
            self.code,
            Some(code),
            "expected exit {code}, got {:?}/{:?}: {}",
            self.code,
            self.signal,
            self.stderr
        );
        assert!(self.stderr.contains("error:"), "{}", self.stderr);
        assert!(!self.stderr.contains("panicked"), "{}", self.stderr);
        for m in mentions {
            assert!(self.stderr.contains(m), "'{m}' not in: {}", self.stderr);
        }
        self
    }
}

fn run_in(dir: &Path, tool: &str, args: &[&str]) -> Out {
    run_with(dir, tool, args, Stdio::null(), Stdio::piped())
}

fn run_with(dir: &Path, tool: &str, args: &[&str], stdin: Stdio, stdout: Stdio) -> Out {
    let o = Command::new(exe(tool))
        .args(args)
        .current_dir(dir)
        .stdin(stdin)
        .stdout(stdout)
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    Out {
        code: o.status.code(),
        signal: o.status.signal(),
        stdout: o.stdout,
        stderr: String::from_utf8_lossy(&o.stderr).into_owned(),
    }
}

/// Every file under `dir` with its bytes (directories as empty entries).
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            let rel = p.strip_prefix(dir).unwrap().to_path_buf();
            let m = std::fs::symlink_metadata(&p).unwrap();
            if m.is_dir() {
                stack.push(p);
                out.insert(rel, Vec::new());
            } else if m.is_file() {
                out.insert(rel, std::fs::read(&p).unwrap());
            } else {
                out.insert(rel, b"<special>".to_vec());
            }
        }
    }
    out
}

/// No temporary file or directory of ours anywhere under `dir`.
fn no_temporaries(dir: &Path) {
    for p in snapshot(dir).keys() {
        let name = p.file_name().unwrap().to_string_lossy();
        assert!(
            !(name.starts_with('.') && (name.contains(".tmp.") || name.contains(".old."))),
            "temporary left: {}",
            p.display()
        );
    }
}

/// The clean inputs: a 100-line demo campaign (`spec.toml`, `sim.mcap`) and, with
/// `stages`, `fit.mcap` and `sel.mcap`.
fn fixture(stages: bool) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/specs/demo.toml"),
    )
    .unwrap();
    assert!(text.contains("lines = 1601"));
    std::fs::write(
        d.join("spec.toml"),
        text.replace("lines = 1601", "lines = 100"),
    )
    .unwrap();
    run_in(d, "frf-sim", &["spec.toml", "-o", "sim.mcap"]).ok();
    if stages {
        run_in(d, "modal-fit", &["sim.mcap", "-o", "fit.mcap"]).ok();
        run_in(d, "ni-select", &["fit.mcap", "-o", "sel.mcap"]).ok();
    }
    dir
}

fn mkfifo(p: &Path) {
    use std::os::unix::ffi::OsStrExt;
    let c = std::ffi::CString::new(p.as_os_str().as_bytes()).unwrap();
    // SAFETY: a valid NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
}

// ---------------------------------------------------------------- output paths

#[test]
fn output_never_replaces_a_directory_that_is_not_a_run() {
    let dir = fixture(false);
    let d = dir.path();
    std::fs::create_dir(d.join("results")).unwrap();
    std::fs::write(d.join("results/thesis.tex"), "my thesis").unwrap();
    let before = snapshot(d);
    run_in(d, "frf-sim", &["spec.toml", "-o", "results"]).error(1, &["results", "--force"]);
    assert_eq!(snapshot(d), before);
    // `.` (the working directory, not a run) likewise.
    run_in(d, "rbprops", &["convert", "sim.mcap", "-o", "."]).error(1, &[]);
    run_in(
        d,
        "rbprops",
        &["convert", "results/../sim.mcap", "-o", "results"],
    )
    .error(1, &["not an rbprops CSV run"]);
    assert_eq!(snapshot(d), before);
    // A CSV run of ours is replaced; --force replaces a foreign directory.
    run_in(d, "rbprops", &["convert", "sim.mcap", "-o", "run"]).ok();
    run_in(d, "rbprops", &["convert", "sim.mcap", "-o", "run"]).ok();
    run_in(d, "frf-sim", &["spec.toml", "-o", "results", "--force"]).ok();
    assert!(!d.join("results/thesis.tex").exists());
    assert!(d.join("results/manifest.csv").exists());
    no_temporaries(d);
}

#[test]
fn output_never_replaces_its_own_input() {
    let dir = fixture(false);
    let d = dir.path();
    std::fs::create_dir(d.join("project")).unwrap();
    std::fs::copy(d.join("sim.mcap"), d.join("project/input.mcap")).unwrap();
    std::fs::write(d.join("project/notes.txt"), "notes").unwrap();
    std::os::unix::fs::symlink("sim.mcap", d.join("link.mcap")).unwrap();
    let before = snapshot(d);
    for force in [false, true] {
        let f: &[&str] = if force { &["--force"] } else { &[] };
        let args = |a: &[&'static str]| [a, f].concat();
        run_in(
            d,
            "modal-fit",
            &args(&["project/input.mcap", "-o", "project"]),
        )
        .error(1, &["input of this run"]);
        run_in(
            d,
            "rbprops",
            &args(&["convert", "sim.mcap", "-o", "sim.mcap"]),
        )
        .error(1, &["input of this run"]);
        run_in(
            d,
            "rbprops",
            &args(&["convert", "sim.mcap", "-o", "link.mcap"]),
        )
        .error(1, &["input of this run"]);
        assert_eq!(snapshot(d), before);
    }
    no_temporaries(d);
}

#[test]
fn output_never_replaces_a_file_of_another_kind() {
    let dir = fixture(false);
    let d = dir.path();
    std::fs::write(d.join("report"), "a text file").unwrap();
    std::fs::write(d.join("notes.mcap"), "not mcap").unwrap();
    std::fs::write(d.join("data.uff"), "not uff\n").unwrap();
    let before = snapshot(d);
    run_in(d, "rbprops", &["convert", "sim.mcap", "-o", "report"]).error(1, &["report"]);
    run_in(d, "rbprops", &["convert", "sim.mcap", "-o", "notes.mcap"])
        .error(1, &["not an MCAP file"]);
    run_in(d, "rbprops", &["convert", "sim.mcap", "-o", "data.uff"]).error(1, &["not a UFF file"]);
    assert_eq!(snapshot(d), before);
    // An MCAP file of ours is replaced, identical to a fresh write.
    run_in(d, "rbprops", &["convert", "sim.mcap", "-o", "copy.mcap"]).ok();
    run_in(d, "rbprops", &["convert", "sim.mcap", "-o", "copy.mcap"]).ok();
    assert_eq!(
        std::fs::read(d.join("copy.mcap")).unwrap(),
        std::fs::read(d.join("sim.mcap")).unwrap()
    );
    run_in(
        d,
        "rbprops",
        &["convert", "sim.mcap", "-o", "notes.mcap", "--force"],
    )
    .ok();
    no_temporaries(d);
}

#[test]
fn dev_null_and_stdout_are_written_straight_through() {
    let dir = fixture(false);
    let d = dir.path();
    let before = snapshot(d);
    for out in ["/dev/null", "-"] {
        run_in(d, "rbprops", &["convert", "sim.mcap", "-o", out]).ok();
    }
    let o = run_in(d, "rbprops", &["convert", "sim.mcap", "-o", "-"]);
    assert_eq!(o.ok().stdout, std::fs::read(d.join("sim.mcap")).unwrap());
    run_in(d, "frf-sim", &["spec.toml", "-o", "/dev/null"]).ok();
    assert!(std::os::unix::fs::FileTypeExt::is_char_device(
        &std::fs::metadata("/dev/null").unwrap().file_type()
    ));
    assert_eq!(snapshot(d), before);
}

// ---------------------------------------------------------------- full and closed streams

#[test]
fn full_devices_and_closed_streams_end_cleanly() {
    let dir = fixture(false);
    let d = dir.path();
    let before = snapshot(d);
    // -o /dev/full: the write fails; no temporary anywhere.
    run_in(d, "rbprops", &["convert", "sim.mcap", "-o", "/dev/full"]).error(1, &["/dev/full"]);
    // stdout on a full device.
    let full = || {
        std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap()
    };
    run_with(
        d,
        "rbprops",
        &["convert", "sim.mcap"],
        Stdio::null(),
        full().into(),
    )
    .error(1, &["stdout"]);
    // stderr on a full device: the error cannot be printed, the status still says it.
    let o = Command::new(exe("modal-fit"))
        .args(["missing.mcap", "-o", "x.mcap"])
        .current_dir(d)
        .stderr(full())
        .status()
        .unwrap();
    assert_eq!(o.code(), Some(1), "{o:?}");
    // stdout a closed pipe: ends quietly (SIGPIPE, as Unix tools do), no panic.
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let o = run_with(
        d,
        "rbprops",
        &["convert", "sim.mcap"],
        Stdio::null(),
        writer.into(),
    );
    assert!(
        o.signal == Some(libc::SIGPIPE) || o.code == Some(0),
        "{:?} {:?}: {}",
        o.code,
        o.signal,
        o.stderr
    );
    // A stage whose stderr is full and whose run succeeds.
    let o = Command::new(exe("frf-sim"))
        .args(["spec.toml", "-o", "/dev/null", "-v"])
        .current_dir(d)
        .stderr(full())
        .status()
        .unwrap();
    assert_eq!(o.code(), Some(0));
    assert_eq!(snapshot(d), before);
}

// ---------------------------------------------------------------- FIFOs

#[test]
fn fifo_inputs_are_read_once() {
    let dir = fixture(false);
    let d = dir.path();
    run_in(d, "rbprops", &["convert", "sim.mcap", "-o", "sim.uff"]).ok();
    run_in(
        d,
        "rbprops",
        &["convert", "sim.uff", "-o", "from-file.mcap"],
    )
    .ok();
    // A FIFO named like a UFF file, and one without an extension (what `<(zcat …)`
    // gives): the bytes decide the format.
    for (name, src) in [
        ("pipe.uff", "sim.uff"),
        ("pipe", "sim.uff"),
        ("pipe2", "sim.mcap"),
    ] {
        mkfifo(&d.join(name));
        let bytes = std::fs::read(d.join(src)).unwrap();
        let path = d.join(name);
        let feeder = std::thread::spawn(move || {
            let mut f = std::fs::OpenOptions::new().write(true).open(path).unwrap();
            let _ = f.write_all(&bytes);
        });
        let out = format!("{name}.mcap");
        run_in(d, "rbprops", &["convert", name, "-o", &out]).ok();
        feeder.join().unwrap();
        let want = if src == "sim.uff" {
            "from-file.mcap"
        } else {
            "sim.mcap"
        };
        let (a, b) = (
            mcap_file::read(&std::fs::read(d.join(&out)).unwrap(), "a").unwrap(),
            mcap_file::read(&std::fs::read(d.join(want)).unwrap(), "b").unwrap(),
        );
        assert_eq!(a.frf, b.frf, "{name}");
    }
    // A FIFO as output is written straight through.
    mkfifo(&d.join("outfifo"));
    let path = d.join("outfifo");
    let reader = std::thread::spawn(move || {
        let mut v = Vec::new();
        std::fs::File::open(path)
            .unwrap()
            .read_to_end(&mut v)
            .unwrap();
        v
    });
    run_in(d, "rbprops", &["convert", "sim.mcap", "-o", "outfifo"]).ok();
    assert_eq!(
        reader.join().unwrap(),
        std::fs::read(d.join("sim.mcap")).unwrap()
    );
    no_temporaries(d);
}

/// `ni-select` reads a regular MCAP file one excitation at a time (its FRF set left in
/// the file) and a FIFO whole: the same command line writes the same bytes either way,
/// to MCAP and to a CSV run.
#[test]
fn a_stage_reading_one_excitation_at_a_time_writes_what_a_whole_read_writes() {
    let dir = fixture(true);
    let d = dir.path();
    let bytes = std::fs::read(d.join("fit.mcap")).unwrap();
    for out in ["sel.mcap", "seldir"] {
        let (file, fifo) = (d.join("file"), d.join("fifo"));
        for p in [&file, &fifo] {
            let _ = std::fs::remove_dir_all(p);
            std::fs::create_dir(p).unwrap();
        }
        std::fs::write(file.join("fit.mcap"), &bytes).unwrap();
        mkfifo(&fifo.join("fit.mcap"));
        let (path, b) = (fifo.join("fit.mcap"), bytes.clone());
        let feeder = std::thread::spawn(move || {
            let mut f = std::fs::OpenOptions::new().write(true).open(path).unwrap();
            let _ = f.write_all(&b);
        });
        run_in(&fifo, "ni-select", &["fit.mcap", "-o", out]).ok();
        feeder.join().unwrap();
        run_in(&file, "ni-select", &["fit.mcap", "-o", out]).ok();
        let outputs = |dir: &Path| {
            let mut m = snapshot(dir);
            m.remove(Path::new("fit.mcap"));
            m
        };
        let (a, b) = (outputs(&file), outputs(&fifo));
        assert!(a.keys().any(|k| k.starts_with(out)));
        assert!(a == b, "{out}: the deferred read wrote other bytes");
    }
    no_temporaries(d);
}

/// On a pipe the stages spool stdin to a temporary file and read it one excitation at a
/// time; with no usable temporary directory they read it whole. Both write the same
/// bytes to stdout (`modal-fit`, `ni-select`, `rb-solve` with either error method).
#[test]
fn a_stage_on_a_pipe_writes_what_a_whole_read_writes() {
    let dir = fixture(true);
    let d = dir.path();
    for (tool, input, args) in [
        ("modal-fit", "sim.mcap", &[][..]),
        ("ni-select", "fit.mcap", &[][..]),
        (
            "rb-solve",
            "sel.mcap",
            &["--uncertainty", "linearised", "--format", "mcap"][..],
        ),
        (
            "rb-solve",
            "sel.mcap",
            &["--bootstrap", "6", "--format", "mcap"][..],
        ),
    ] {
        let run = |tmpdir: &Path| {
            let o = Command::new(exe(tool))
                .args(args)
                .current_dir(d)
                .env("TMPDIR", tmpdir)
                .stdin(std::fs::File::open(d.join(input)).unwrap())
                .output()
                .unwrap();
            assert!(
                o.status.success(),
                "{tool}: {}",
                String::from_utf8_lossy(&o.stderr)
            );
            o.stdout
        };
        let spooled = run(d);
        let whole = run(&d.join("no-such-directory"));
        assert!(spooled.starts_with(b"\x89MCAP0\r\n"), "{tool}");
        assert!(
            spooled == whole,
            "{tool}: the spooled read wrote other bytes"
        );
    }
    no_temporaries(d);
}

// ---------------------------------------------------------------- signals

#[test]
fn sigterm_and_sigint_remove_the_temporary_files() {
    let dir = fixture(false);
    let d = dir.path();
    for (sig, out) in [(libc::SIGTERM, "out.mcap"), (libc::SIGINT, "outdir")] {
        let hold = d.join("hold");
        mkfifo(&hold);
        let before = snapshot(d);
        let child = Command::new(exe("rbprops"))
            .args(["convert", "sim.mcap", "-o", out])
            .current_dir(d)
            .env("RBPROPS_FAULT_HOLD_TEMP", &hold)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        // Opening the FIFO's write end returns once the program opened its read end,
        // which it does with its temporary output written: the signal meets it there.
        let w = std::fs::OpenOptions::new().write(true).open(&hold).unwrap();
        let temps: Vec<_> = snapshot(d)
            .into_keys()
            .filter(|p| !before.contains_key(p))
            .collect();
        assert!(!temps.is_empty(), "no temporary while held");
        // SAFETY: signals our own child.
        unsafe { libc::kill(child.id() as i32, sig) };
        let status = child.wait_with_output().unwrap().status;
        drop(w);
        assert_eq!(status.code(), Some(128 + sig), "{status:?}");
        std::fs::remove_file(&hold).unwrap();
        assert_eq!(snapshot(d), {
            let mut b = before.clone();
            b.remove(Path::new("hold"));
            b
        });
        no_temporaries(d);
    }
}

// ---------------------------------------------------------------- size bombs

/// Runs `tool` and returns its outcome and peak resident set (kB) from `wait4` (which
/// reaps the child itself, hence the lint's exception).
#[allow(clippy::zombie_processes)]
fn run_measured(dir: &Path, tool: &str, args: &[&str]) -> (Out, i64) {
    let err = dir.join("stderr.txt");
    let child = Command::new(exe(tool))
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&err).unwrap())
        .spawn()
        .unwrap();
    let mut status = 0;
    // SAFETY: zeroed rusage filled by wait4 on our own child.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let pid = unsafe { libc::wait4(child.id() as i32, &mut status, 0, &mut usage) };
    assert_eq!(pid, child.id() as i32);
    let code = libc::WIFEXITED(status).then(|| libc::WEXITSTATUS(status));
    let stderr = std::fs::read_to_string(&err).unwrap();
    std::fs::remove_file(&err).unwrap();
    (
        Out {
            code,
            signal: libc::WIFSIGNALED(status).then(|| libc::WTERMSIG(status)),
            stdout: Vec::new(),
            stderr,
        },
        usage.ru_maxrss,
    )
}

/// A small MCAP file declaring `ne` excitations × `nc` channels × `nl` lines, with a few
/// bytes of values per excitation.
fn declared_bomb(sim: &Path, ne: usize, nc: usize, nl: usize) -> Vec<u8> {
    let rec = mcap_file::read(&std::fs::read(sim).unwrap(), "sim").unwrap();
    let mut g = rec.topic(topics::GEOMETRY).unwrap().messages[0].clone();
    let grow = |list: &mut serde_json::Value, n: usize, prefix: &str| {
        let first = list.as_array().unwrap()[0].clone();
        *list = (0..n)
            .map(|k| {
                let mut v = first.clone();
                v["id"] = format!("{prefix}{k}").into();
                v
            })
            .collect();
    };
    grow(&mut g["excitations"], ne, "F");
    grow(&mut g["channels"], nc, "C");
    let ids = |v: &serde_json::Value| -> Vec<String> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x["id"].as_str().unwrap().to_string())
            .collect()
    };
    let axis = serde_json::json!({
        "quantity": "receptance",
        "unit": "m/N",
        "excitations": ids(&g["excitations"]),
        "channels": ids(&g["channels"]),
        "frequency_hz": (1..=nl).map(|k| k as f64 * 0.01).collect::<Vec<_>>(),
    });
    let topic = |name: &str, messages: Vec<serde_json::Value>| JsonTopic {
        name: name.into(),
        schema_name: String::new(),
        schema: serde_json::Value::Bool(true),
        messages,
    };
    let bomb = RunRecord {
        frf: None,
        topics: vec![
            topic(topics::GEOMETRY, vec![g.clone()]),
            topic(topics::FRF_AXIS, vec![axis]),
            topic(
                topics::FRF,
                ids(&g["excitations"])
                    .into_iter()
                    .map(|e| serde_json::json!({"excitation": e, "values_f64le": "AAAAAAAAAAAAAAAAAAAAAA=="}))
                    .collect(),
            ),
        ],
        raw_topics: Vec::new(),
    };
    mcap_file::write(&bomb).unwrap()
}

/// Peak RSS a size bomb may reach (kB).
const MAX_RSS_KB: i64 = 64 * 1024;

#[test]
fn size_bombs_are_refused_with_bounded_memory() {
    let dir = fixture(false);
    let d = dir.path();
    let bomb = declared_bomb(&d.join("sim.mcap"), 300, 300, 10_000);
    assert!(bomb.len() < 400_000, "{}", bomb.len());
    std::fs::write(d.join("bomb.mcap"), &bomb).unwrap();
    // A chunk declaring a huge uncompressed size: the length field patched in place.
    let mut chunk_bomb = std::fs::read(d.join("sim.mcap")).unwrap();
    let mut at = 8;
    while chunk_bomb[at] != 0x06 {
        let len = u64::from_le_bytes(chunk_bomb[at + 1..at + 9].try_into().unwrap());
        at += 9 + len as usize;
    }
    chunk_bomb[at + 9 + 16..at + 9 + 24].copy_from_slice(&(3u64 << 30).to_le_bytes());
    std::fs::write(d.join("chunk-bomb.mcap"), &chunk_bomb).unwrap();
    let before = snapshot(d);
    for (tool, args, why) in [
        (
            "rbprops",
            vec!["convert", "bomb.mcap", "-o", "out.mcap"],
            "base64",
        ),
        (
            "rbprops",
            vec!["convert", "bomb.mcap", "-o", "out"],
            "base64",
        ),
        ("modal-fit", vec!["bomb.mcap", "-o", "out.mcap"], "base64"),
        (
            "rbprops",
            vec!["convert", "chunk-bomb.mcap", "-o", "out.mcap"],
            "uncompressed size",
        ),
        (
            "modal-fit",
            vec!["chunk-bomb.mcap", "-o", "out.mcap"],
            "uncompressed size",
        ),
    ] {
        let (o, rss) = run_measured(d, tool, &args);
        o.error(1, &[args[args.len() - 3], why]);
        eprintln!("{tool} {args:?}: peak RSS {rss} kB");
        assert!(rss < MAX_RSS_KB, "{tool} {args:?}: peak RSS {rss} kB");
    }
    assert_eq!(snapshot(d), before);
    // Stdin likewise.
    let o = run_with(
        d,
        "modal-fit",
        &[],
        std::fs::File::open(d.join("bomb.mcap")).unwrap().into(),
        Stdio::piped(),
    );
    o.error(1, &["<stdin>"]);
    no_temporaries(d);
}

// ---------------------------------------------------------------- arguments

#[test]
fn nonsense_arguments_are_command_line_errors() {
    let dir = fixture(true);
    let d = dir.path();
    let before = snapshot(d);
    let cases: &[(&str, &[&str])] = &[
        (
            "model-check",
            &["spec.toml", "-i", "sim.mcap", "--weighed-mass", "nan"],
        ),
        (
            "model-check",
            &["spec.toml", "-i", "sim.mcap", "--alpha", "0"],
        ),
        (
            "model-check",
            &["spec.toml", "-i", "sim.mcap", "--alpha", "2"],
        ),
        (
            "model-check",
            &["spec.toml", "-i", "sim.mcap", "--alpha", "nan"],
        ),
        (
            "model-check",
            &["spec.toml", "-i", "sim.mcap", "--noise-relative", "-1"],
        ),
        (
            "model-check",
            &["spec.toml", "-i", "sim.mcap", "--max-effects", "0"],
        ),
        ("modal-fit", &["sim.mcap", "--modes", "1000000"]),
        ("modal-fit", &["sim.mcap", "--band", "2:1"]),
        ("modal-fit", &["sim.mcap", "--band", "nan:3"]),
        ("modal-fit", &["sim.mcap", "--exp-window", "0"]),
        ("modal-fit", &["sim.mcap", "--low-coherence", "7"]),
        ("modal-fit", &["sim.mcap", "--max-order", "1"]),
        ("ni-select", &["fit.mcap", "--mac-threshold", "inf"]),
        ("rb-solve", &["sel.mcap", "--bootstrap", "0"]),
        ("rb-solve", &["sel.mcap", "--known-mass", "1e-300"]),
        ("rb-solve", &["sel.mcap", "--known-mass", "-3"]),
        ("rb-solve", &["sel.mcap", "--monte-carlo", "1"]),
        ("rb-solve", &["sel.mcap", "--mass-line-band", "5"]),
    ];
    for (tool, args) in cases {
        let o = run_in(d, tool, args);
        o.error(2, &[]);
        assert!(o.stdout.is_empty(), "{tool} {args:?}");
    }
    assert_eq!(snapshot(d), before);
}

#[test]
fn arguments_that_contradict_the_data_are_errors() {
    let dir = fixture(true);
    let d = dir.path();
    let before = snapshot(d);
    run_in(
        d,
        "model-check",
        &[
            "spec.toml",
            "-i",
            "sim.mcap",
            "--only",
            "warp_drive",
            "--format",
            "json",
        ],
    )
    .error(1, &["warp_drive", "valid ids"]);
    for band in ["100:200", "2:2.0001"] {
        run_in(
            d,
            "modal-fit",
            &["sim.mcap", "--band", band, "-o", "out.mcap"],
        )
        .error(1, &["--band", "the data span"]);
    }
    run_in(
        d,
        "rb-solve",
        &[
            "sel.mcap",
            "--mass-line-band",
            "100:200",
            "--uncertainty",
            "linearised",
            "--format",
            "json",
        ],
    )
    .error(1, &["--mass-line-band", "the data span"]);
    run_in(
        d,
        "rb-solve",
        &["sel.mcap", "--origin", "nan,0,0", "--format", "json"],
    )
    .error(1, &["--origin", "finite"]);
    assert_eq!(snapshot(d), before);
}

// ---------------------------------------------------------------- records

fn edit(src: &Path, dst: &Path, topic: &str, f: impl FnOnce(&mut serde_json::Value)) {
    let mut rec = mcap_file::read(&std::fs::read(src).unwrap(), "src").unwrap();
    let t = rec.topics.iter_mut().find(|t| t.name == topic).unwrap();
    f(&mut t.messages[0]);
    std::fs::write(dst, mcap_file::write(&rec).unwrap()).unwrap();
}

#[test]
fn impossible_modal_records_are_named() {
    let dir = fixture(true);
    let d = dir.path();
    type Edit = fn(&mut serde_json::Value);
    let cases: &[(&str, Edit)] = &[
        ("frequency_hz", |m| {
            m["modes"][0]["frequency_hz"] = (-1.0).into()
        }),
        ("frequency_hz", |m| {
            m["modes"][1]["frequency_hz"] = 0.0.into()
        }),
        ("damping_ratio", |m| {
            m["modes"][0]["damping_ratio"] = 1.5.into()
        }),
        ("damping_ratio", |m| {
            m["modes"][0]["damping_ratio"] = (-0.01).into()
        }),
        ("residue_std", |m| {
            m["modes"][0]["residue_std"].as_array_mut().unwrap().pop();
        }),
        ("residue_convention", |m| {
            m["residue_convention"] = "H = -A/(w^2)".into()
        }),
    ];
    for (k, (field, f)) in cases.iter().enumerate() {
        for (src, tool) in [("fit.mcap", "ni-select"), ("sel.mcap", "rb-solve")] {
            let name = format!("bad{k}-{src}");
            edit(&d.join(src), &d.join(&name), topics::MODAL_FIT, f);
            let before = snapshot(d);
            run_in(
                d,
                tool,
                &[&name, "-o", "out.mcap", "--format", "json"]
                    [..if tool == "rb-solve" { 5 } else { 3 }],
            )
            .error(1, &[&name, "modal_fit", field]);
            assert_eq!(snapshot(d), before, "{tool} {name}");
        }
    }
    edit(
        &d.join("sel.mcap"),
        &d.join("empty-sel.mcap"),
        topics::SELECTION,
        |s| s["selected"] = serde_json::json!([]),
    );
    run_in(d, "rb-solve", &["empty-sel.mcap", "--format", "json"])
        .error(1, &["selection", "selected"]);
    no_temporaries(d);
}

#[test]
fn a_zero_truth_gives_no_null_numbers() {
    let dir = fixture(true);
    let d = dir.path();
    edit(
        &d.join("sel.mcap"),
        &d.join("zero.mcap"),
        topics::TRUTH,
        |t| {
            t["properties"]["mass_kg"] = 0.0.into();
        },
    );
    let o = run_in(
        d,
        "rb-solve",
        &[
            "zero.mcap",
            "--uncertainty",
            "linearised",
            "--format",
            "json",
        ],
    );
    let v: serde_json::Value = serde_json::from_slice(&o.ok().stdout).unwrap();
    fn nulls(v: &serde_json::Value, key: &str, out: &mut Vec<String>) {
        match v {
            serde_json::Value::Null => out.push(key.to_string()),
            serde_json::Value::Array(a) => a.iter().for_each(|x| nulls(x, key, out)),
            serde_json::Value::Object(o) => o.iter().for_each(|(k, x)| nulls(x, k, out)),
            _ => {}
        }
    }
    let mut found = Vec::new();
    nulls(&v, "", &mut found);
    let clean = run_in(
        d,
        "rb-solve",
        &[
            "sel.mcap",
            "--uncertainty",
            "linearised",
            "--format",
            "json",
            "--no-reference",
        ],
    );
    let mut expected = Vec::new();
    nulls(
        &serde_json::from_slice(&clean.ok().stdout).unwrap(),
        "",
        &mut expected,
    );
    assert_eq!(found, expected, "nulls with a zero truth: {found:?}");
}
