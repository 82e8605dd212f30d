//! `rbprops convert` on analyser-style exports (fixtures/uff/exports, written by
//! scripts/make_uff_exports.py): separate geometry, inventory, channel-map template,
//! coherence topic, and the no-FRF error (non-zero exit, no output file).

use std::path::{Path, PathBuf};
use std::process::Command;

fn exports() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/uff/exports")
}

fn rbprops(args: &[&std::ffi::OsStr]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_rbprops"))
        .args(args)
        .output()
        .expect("run rbprops")
}

fn os(p: &Path) -> &std::ffi::OsStr {
    p.as_os_str()
}

#[test]
fn split_geometry_converts_to_the_library_result() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run.mcap");
    let (data, geo) = (
        exports().join("split_data.uff"),
        exports().join("split_geometry.uff"),
    );
    let o = rbprops(&[
        "convert".as_ref(),
        os(&data),
        "--geometry".as_ref(),
        os(&geo),
        "-o".as_ref(),
        os(&out),
        // The reader's notes are listed with -v.
        "-v".as_ref(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The unused geometry node 9 is reported.
    assert!(String::from_utf8_lossy(&o.stderr).contains("carry no FRF channel or excitation"));
    let rec = rbprops_formats::read_path(&out).unwrap();
    let parse = |p: &Path| {
        rbprops_uff::parse(&std::fs::read(p).unwrap(), &p.display().to_string()).unwrap()
    };
    let want = rbprops_uff::read_with_geometry(&parse(&data), &parse(&geo), None).unwrap();
    assert_eq!(rec.frf.as_ref().unwrap(), &want.frf);
    assert_eq!(rec.geometry().unwrap().unwrap(), want.geometry);
    // Without the geometry: an error naming the missing nodes, and no output file.
    let out2 = dir.path().join("alone.mcap");
    let o = rbprops(&["convert".as_ref(), os(&data), "-o".as_ref(), os(&out2)]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("have no coordinates: 1, 2, 3, 4"), "{err}");
    assert!(!out2.exists());
}

#[test]
fn no_frf_file_lists_what_it_holds() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run.mcap");
    let f = exports().join("no_frf_time_and_psd.uff");
    let o = rbprops(&["convert".as_ref(), os(&f), "-o".as_ref(), os(&out)]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    for want in [
        "no FRF datasets",
        "time response (type 1): 2",
        "PSD (type 9): 3",
    ] {
        assert!(err.contains(want), "{err}");
    }
    assert!(!out.exists());
    let o = rbprops(&["convert".as_ref(), os(&f), "--list".as_ref()]);
    assert!(o.status.success());
    let list = String::from_utf8_lossy(&o.stdout);
    assert!(
        list.contains("PSD (type 9): 3") && list.contains("nodes: 4 defined"),
        "{list}"
    );
}

#[test]
fn channel_template_then_map_reads_node0_exports() {
    let dir = tempfile::tempdir().unwrap();
    let f = exports().join("node0_channel_map.uff");
    let t = dir.path().join("map.csv");
    let o = rbprops(&[
        "convert".as_ref(),
        os(&f),
        "--channel-template".as_ref(),
        os(&t),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let template = std::fs::read_to_string(&t).unwrap();
    // Header plus one row per dataset 58 (six FRFs), DOFs unknown: left blank.
    let rows: Vec<&str> = template.lines().filter(|l| !l.starts_with('#')).collect();
    assert_eq!(rows.len(), 7, "{template}");
    assert_eq!(rows[1], "2,H1 : # 2 / # 1,FRF,,,,");
    // With the committed map the file converts, and coherence-free files carry no topic.
    let out = dir.path().join("run.mcap");
    let map = exports().join("node0_channel_map.csv");
    let o = rbprops(&[
        "convert".as_ref(),
        os(&f),
        "--channels".as_ref(),
        os(&map),
        "-o".as_ref(),
        os(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rec = rbprops_formats::read_path(&out).unwrap();
    assert_eq!(rec.frf.as_ref().unwrap().n_channels, 3);
    assert!(rbprops_cli::coherence::get(&rec).unwrap().is_none());
}

#[test]
fn coherence_travels_as_a_topic() {
    let dir = tempfile::tempdir().unwrap();
    let f = exports().join("mixed_frf_coherence_autospectra.uff");
    let out = dir.path().join("run.mcap");
    let o = rbprops(&["convert".as_ref(), os(&f), "-o".as_ref(), os(&out)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rec = rbprops_formats::read_path(&out).unwrap();
    let grid = rbprops_cli::coherence::get(&rec)
        .unwrap()
        .expect("coherence topic");
    let uff = rbprops_uff::parse(&std::fs::read(&f).unwrap(), "m").unwrap();
    let want = rbprops_uff::read_campaign(&uff, &Default::default()).unwrap();
    assert_eq!(grid, want.coherence.unwrap().values);
    // And through a CSV directory, bit-exact.
    let csv = dir.path().join("csv");
    let o = rbprops(&["convert".as_ref(), os(&out), "-o".as_ref(), os(&csv)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let back = rbprops_formats::read_path(&csv).unwrap();
    assert_eq!(rbprops_cli::coherence::get(&back).unwrap().unwrap(), grid);
}
