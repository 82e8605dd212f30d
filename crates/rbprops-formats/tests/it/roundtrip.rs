//! MCAP ↔ CSV round trips (bit-exact), error reporting, and no-panic fuzzing of readers.

use proptest::prelude::*;
use rbprops_core::records::{
    Diagnostic, DiagnosticKind, DiagnosticSubject, ModalFitRecord, ModeEstimate, PropertiesRecord,
    Severity, StageProvenance,
};
use rbprops_core::{
    c64, Channel, Excitation, FrfSet, Geometry, Point, Quantity, SuspensionSetup, Vec3,
};
use rbprops_formats::{csv_dir, mcap_file, topics, RunRecord};

pub(crate) fn geometry() -> Geometry {
    let mut g = Geometry::default();
    g.setups.push(SuspensionSetup {
        id: "A".into(),
        description: "springs through the CoM".into(),
    });
    for (k, p) in [
        Vec3::new(0.1, 0.0, 0.0),
        Vec3::new(-0.05, 0.09, 0.0),
        Vec3::new(-0.05, -0.09, 0.02),
    ]
    .iter()
    .enumerate()
    {
        let pid = format!("{}", k + 1);
        g.points.push(Point {
            id: pid.clone(),
            position: *p,
        });
        for (a, d) in [("x", Vec3::x()), ("y", Vec3::y()), ("z", Vec3::z())] {
            g.channels.push(Channel {
                id: format!("{pid}{a}"),
                point: pid.clone(),
                position: *p,
                direction: d,
            });
        }
    }
    g.excitations.push(Excitation {
        id: "F1".into(),
        point: "1".into(),
        setup: "A".into(),
        position: Vec3::new(0.1, 0.0, 0.0),
        direction: Vec3::x(),
    });
    g.excitations.push(Excitation {
        id: "42".into(),
        point: "2".into(),
        setup: "A".into(),
        position: Vec3::new(-0.05, 0.09, 0.0),
        direction: Vec3::new(0.6, 0.8, 0.0),
    });
    g
}

pub(crate) fn record() -> RunRecord {
    let g = geometry();
    let mut frf = FrfSet::zeros(
        Quantity::Accelerance,
        (0..50).map(|l| l as f64 * 0.1 + 0.1).collect(),
        2,
        9,
    );
    for (i, v) in frf.values.iter_mut().enumerate() {
        // Awkward floats: subnormals, huge, negative zero, long mantissas.
        let x = (i as f64 * 0.7368).sin() / 3.0;
        *v = c64::new(
            x * 1e-7,
            if i % 17 == 0 {
                -0.0
            } else {
                x * x * 1e300 / 1e300 + 5e-324
            },
        );
    }
    let mut rec = RunRecord::default();
    rec.push_provenance(StageProvenance {
        tool: "test".into(),
        version: "0".into(),
        args: vec!["--x".into(), "1".into()],
        input_sha256: "ab".into(),
    })
    .unwrap();
    rec.set_geometry(&g);
    rec.frf = Some(frf);
    rec.set(
        topics::TRUTH,
        &[PropertiesRecord {
            mass_kg: 15.69,
            com_m: [0.17725, 0.0304, -0.00535],
            inertia_cm_kg_m2: [
                [0.1, -0.2, 0.3],
                [-0.2, 0.5, 1.0 / 3.0],
                [0.3, 1.0 / 3.0, 0.7],
            ],
        }],
    );
    let mode = ModeEstimate {
        excitation: "42".into(),
        setup: "A".into(),
        mode: 1,
        frequency_hz: 1.234567890123,
        frequency_std_hz: 1e-9,
        damping_ratio: 0.01,
        damping_std: 0.0,
        residues: (0..9)
            .map(|k| c64::new(k as f64 / 7.0, -(k as f64) / 11.0))
            .collect(),
        residue_std: vec![1e-3; 9],
        confidence: 0.99,
        mpc: 1.0,
        weak: false,
        warnings: vec!["true".into(), "".into(), "a, \"quoted\" warning".into()],
    };
    rec.set(
        topics::MODAL_FIT,
        &[ModalFitRecord {
            residue_convention: "A/(wr^2-w^2+2i z wr w)".into(),
            excitations: vec![],
            modes: vec![
                mode.clone(),
                ModeEstimate {
                    mode: 2,
                    warnings: vec![],
                    ..mode
                },
            ],
            window_correction: None,
            diagnostics: vec![
                Diagnostic {
                    stage: "modal-fit".into(),
                    kind: DiagnosticKind::RepeatedRoot,
                    severity: Severity::Note,
                    subject: DiagnosticSubject {
                        setup: Some("A".into()),
                        excitations: vec!["fx".into(), "fy".into()],
                        modes: vec![5, 6],
                        frequencies_hz: vec![0.503008305530331, 0.5045284481387717],
                        ..Default::default()
                    },
                    message: "one root, \"quoted\", separated".into(),
                    advice: String::new(),
                },
                Diagnostic {
                    stage: "modal-fit".into(),
                    kind: DiagnosticKind::DeadChannel,
                    severity: Severity::ChangesAnswer,
                    subject: DiagnosticSubject {
                        channel: Some("3x".into()),
                        hit: Some(2),
                        ..Default::default()
                    },
                    message: "zero".into(),
                    advice: "check the cable".into(),
                },
            ],
        }],
    );
    rec
}

#[test]
fn mcap_round_trip_is_exact() {
    let rec = record();
    let bytes = mcap_file::write(&rec).unwrap();
    let back = mcap_file::read(&bytes, "mem").unwrap();
    assert_eq!(back, rec);
    let f0 = rec.frf.as_ref().unwrap();
    let f1 = back.frf.as_ref().unwrap();
    assert!(f0
        .values
        .iter()
        .zip(&f1.values)
        .all(|(a, b)| a.re.to_bits() == b.re.to_bits() && a.im.to_bits() == b.im.to_bits()));
    // Byte-identical when written twice.
    assert_eq!(bytes, mcap_file::write(&back).unwrap());
}

#[test]
fn csv_round_trip_is_bit_exact_and_back_to_identical_mcap() {
    let rec = record();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run");
    csv_dir::write(&rec, &path).unwrap();
    let back = csv_dir::read(&path).unwrap();
    let f0 = rec.frf.as_ref().unwrap();
    let f1 = back.frf.as_ref().unwrap();
    assert!(f0
        .values
        .iter()
        .zip(&f1.values)
        .all(|(a, b)| a.re.to_bits() == b.re.to_bits() && a.im.to_bits() == b.im.to_bits()));
    assert_eq!(back.topics, rec.topics);
    let m: Vec<ModalFitRecord> = back.get(topics::MODAL_FIT).unwrap();
    assert_eq!(m[0].modes[0].warnings[1], "");
    assert_eq!(
        mcap_file::write(&back).unwrap(),
        mcap_file::write(&rec).unwrap()
    );
    // Overwriting an existing directory is atomic and leaves no temp files.
    csv_dir::write(&back, &path).unwrap();
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(leftovers.len(), 1, "{leftovers:?}");
}

#[test]
fn csv_errors_name_file_line_and_problem() {
    let rec = record();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run");
    csv_dir::write(&rec, &path).unwrap();
    let frf = path.join("frf.csv");
    let text = std::fs::read_to_string(&frf).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let cols: Vec<String> = lines[5].split(',').map(String::from).collect();
    lines[5] = format!("{},{},{},NaN,0", cols[0], cols[1], cols[2]);
    std::fs::write(&frf, lines.join("\n")).unwrap();
    let e = csv_dir::read(&path).unwrap_err().to_string();
    assert!(
        e.contains("frf.csv") && e.contains("line 6") && e.contains("not finite"),
        "{e}"
    );
    lines[5] = format!("{},nosuch,{},1,0", cols[0], cols[2]);
    std::fs::write(&frf, lines.join("\n")).unwrap();
    let e = csv_dir::read(&path).unwrap_err().to_string();
    assert!(e.contains("unknown channel 'nosuch'"), "{e}");
    // Drop a row: the axis of that pair no longer matches.
    lines.remove(5);
    std::fs::write(&frf, lines.join("\n")).unwrap();
    let e = csv_dir::read(&path).unwrap_err().to_string();
    assert!(e.contains("inconsistent frequency axes"), "{e}");
}

#[test]
fn geometry_errors_are_reported() {
    let mut rec = record();
    let mut g = geometry();
    g.channels[0].direction = Vec3::new(0.0, 0.0, 0.0);
    rec.set_geometry(&g);
    let e = mcap_file::read(
        &mcap_file::write(&RunRecord {
            frf: None,
            ..rec.clone()
        })
        .unwrap(),
        "x.mcap",
    )
    .and_then(|r| r.geometry())
    .unwrap_err()
    .to_string();
    assert!(e.contains("channel '1x' direction"), "{e}");
}

#[test]
fn truncated_mcap_is_an_error_not_a_panic() {
    let bytes = mcap_file::write(&record()).unwrap();
    for cut in [0, 8, 100, bytes.len() / 2, bytes.len() - 1] {
        assert!(
            mcap_file::read(&bytes[..cut], "cut.mcap").is_err(),
            "cut at {cut}"
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    #[test]
    fn mcap_reader_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..2048)) {
        let _ = mcap_file::read(&bytes, "fuzz.mcap");
    }

    #[test]
    fn mcap_reader_never_panics_on_mutations(pos in 0usize..100_000, val in any::<u8>()) {
        let mut bytes = mcap_file::write(&record()).unwrap();
        let p = pos % bytes.len();
        bytes[p] = val;
        let _ = mcap_file::read(&bytes, "mutated.mcap");
    }

    #[test]
    fn csv_reader_never_panics(manifest in "[a-z_,\n0-9]{0,200}", table in "\\PC{0,300}") {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("manifest.csv"), format!("table,topic,parent,field,schema\n{manifest}")).unwrap();
        std::fs::write(dir.path().join("t.csv"), &table).unwrap();
        std::fs::write(dir.path().join("geometry.csv"), &table).unwrap();
        let _ = csv_dir::read(dir.path());
    }
}

#[test]
fn python_mcap_reads_our_file() {
    // The reference reader (PyPI `mcap`) must decode every topic: CI installs it.
    let Some(py) = rbprops_testkit::python(&["mcap"]) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("run.mcap");
    std::fs::write(&file, mcap_file::write(&record()).unwrap()).unwrap();
    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../scripts/check_mcap_python.py"
    );
    let out = std::process::Command::new(&py)
        .arg(script)
        .arg(&file)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}\n{}",
        stdout,
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("/rbprops/frf 2") && stdout.contains("/rbprops/geometry 1"),
        "{stdout}"
    );
}

#[test]
fn pandas_reads_every_csv_table_without_custom_parsing() {
    // A person's tool: every table must load with plain `pd.read_csv`, ids must be the
    // ids (no JSON quoting), and each child table must hold exactly the rows its parent
    // rows count. CI installs pandas.
    let Some(py) = rbprops_testkit::python(&["pandas"]) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run");
    csv_dir::write(&record(), &path).unwrap();
    let script = r#"
import sys, os
import pandas as pd
d = sys.argv[1]
m = pd.read_csv(os.path.join(d, "manifest.csv"), keep_default_na=False)
tables = {t: pd.read_csv(os.path.join(d, t + ".csv"), dtype=str, keep_default_na=False) for t in m["table"]}
for t, df in tables.items():
    assert "_parent" not in df.columns, t
    for c in df.columns:
        # No JSON quoting; the one exception is the empty string itself, written `""`
        # (an empty cell is an absent value).
        assert not any(str(v).startswith('"') and v != '""' for v in df[c]), (t, c)
for _, r in m.iterrows():
    if r["parent"]:
        p = tables[r["parent"]]
        n = pd.to_numeric(p[r["field"] + "_count"].replace("", "0")).sum()
        assert n == len(tables[r["table"]]), (r["table"], n, len(tables[r["table"]]))
pts = pd.read_csv(os.path.join(d, "geometry_points.csv"))
assert [str(x) for x in pts["id"]] == ["1", "2", "3"], list(pts["id"])
exc = pd.read_csv(os.path.join(d, "geometry_excitations.csv"))
assert [str(x) for x in exc["id"]] == ["F1", "42"], list(exc["id"])
assert list(exc["position_m.x"]) == [0.1, -0.05]
res = pd.read_csv(os.path.join(d, "modal_fit_modes_residues.csv"))
assert list(res.columns) == ["excitation", "setup", "mode", "index", "re", "im"], list(res.columns)
assert len(res) == 18 and res["re"].iloc[3] == 3 / 7
frf = pd.read_csv(os.path.join(d, "frf.csv"))
assert len(frf) == 2 * 9 * 50
print("ok", len(tables), "tables")
"#;
    let out = std::process::Command::new(&py)
        .args(["-c", script])
        .arg(&path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// An empty set-up description is an empty CSV cell (not `""` inside CSV quoting, which a
/// spreadsheet shows as `""`), reads back as the empty string, and a description column
/// that is missing altogether is still an error naming the field.
#[test]
fn empty_text_is_an_empty_cell_and_a_missing_required_field_an_error() {
    let mut rec = record();
    let mut g = geometry();
    g.setups.push(SuspensionSetup {
        id: "B".into(),
        description: String::new(),
    });
    g.excitations[1].setup = "B".into();
    rec.set_geometry(&g);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run");
    csv_dir::write(&rec, &path).unwrap();
    let setups = path.join("geometry_setups.csv");
    let text = std::fs::read_to_string(&setups).unwrap();
    assert_eq!(text, "id,description\nA,springs through the CoM\nB,\n");
    let back = csv_dir::read(&path).unwrap();
    assert_eq!(back.topics, rec.topics);
    assert_eq!(back.geometry().unwrap().unwrap().setups[1].description, "");
    // No text cell anywhere is a JSON-quoted empty string.
    for e in std::fs::read_dir(&path).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "csv") {
            let t = std::fs::read_to_string(&p).unwrap();
            assert!(!t.contains("\"\"\"\"\"\""), "{}: {t}", p.display());
        }
    }
    // Without the column the required field is absent: an error, not an empty text.
    std::fs::write(&setups, "id\nA\nB\n").unwrap();
    let e = csv_dir::read(&path)
        .and_then(|r| r.geometry().map(|_| ()))
        .unwrap_err()
        .to_string();
    assert!(e.contains("description"), "{e}");
}

/// A file read as it is parsed (`read_file_checked`) gives what its bytes give: the same
/// record, the same notes, the SHA-256 of its bytes; and for every mutated or truncated
/// file the same result, error text (file, record, offset) included.
#[test]
fn mcap_file_read_as_it_streams_equals_the_bytes_read() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.mcap");
    let bytes = mcap_file::write(&record()).unwrap();
    let same = |b: &[u8]| {
        std::fs::write(&path, b).unwrap();
        let from_bytes = mcap_file::read_checked(b, "run.mcap");
        let from_file = mcap_file::read_file_checked(&path, "run.mcap");
        match (from_bytes, from_file) {
            (Ok((r0, n0)), Ok((r1, n1, sha))) => {
                assert_eq!(r0, r1);
                assert_eq!(n0, n1);
                assert_eq!(sha, rbprops_formats::sha256_hex(b));
            }
            (Err(e0), Err(e1)) => assert_eq!(e0.to_string(), e1.to_string()),
            (a, b) => panic!("bytes {:?} but file {:?}", a.err(), b.err()),
        }
    };
    same(&bytes);
    for cut in [0, 8, 100, bytes.len() / 2, bytes.len() - 1] {
        same(&bytes[..cut]);
    }
    let mut lcg = 12345u64;
    for _ in 0..200 {
        lcg = lcg
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let mut b = bytes.clone();
        let p = (lcg >> 33) as usize % b.len();
        b[p] ^= 1 << ((lcg >> 20) % 8);
        same(&b);
    }
}
