//! Analyser-style exports (scripts/make_uff_exports.py: written by pyuff, then edited as
//! analysers write them) read to the SI values the script computed by hand, to the
//! precision of the file; or refused with the error the script expects.

use rbprops_uff::{
    inventory, parse, read_campaign, ChannelMap, GeometrySource, ReadOptions, UffCampaign, UffError,
};
use serde_json::Value;
use std::path::PathBuf;

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/uff/exports")
}

fn sidecar(name: &str) -> Value {
    serde_json::from_slice(&std::fs::read(dir().join(format!("{name}.json"))).unwrap()).unwrap()
}

fn f(v: &Value) -> f64 {
    v.as_f64().expect("number")
}

/// Reads the sidecar's file with its geometry file and channel map, if any.
fn read(side: &Value) -> Result<UffCampaign, UffError> {
    let file = side["file"].as_str().unwrap();
    let uff = parse(&std::fs::read(dir().join(file)).unwrap(), file)?;
    let geo = side["geometry"].as_str().map(|g| {
        parse(&std::fs::read(dir().join(g)).unwrap(), g).unwrap_or_else(|e| panic!("{e}"))
    });
    let map = side["channels_map"]
        .as_str()
        .map(|m| ChannelMap::parse(&std::fs::read_to_string(dir().join(m)).unwrap(), m).unwrap());
    read_campaign(
        &uff,
        &ReadOptions {
            geometry: geo
                .as_ref()
                .map_or(GeometrySource::InFile, GeometrySource::Uff),
            channels: map.as_ref(),
        },
    )
}

fn check(name: &str) {
    let side = sidecar(name);
    let result = read(&side);
    if side["expect"] == "error" {
        let e = result
            .err()
            .unwrap_or_else(|| panic!("{name}: read, expected an error"));
        let text = e.to_string();
        for want in side["error_contains"].as_array().unwrap() {
            assert!(
                text.contains(want.as_str().unwrap()),
                "{name}: error '{text}' lacks '{want}'"
            );
        }
        assert!(text.contains(side["file"].as_str().unwrap()), "{text}");
        return;
    }
    let c = result.unwrap_or_else(|e| panic!("{name}: {e}"));
    let rel = f(&side["rel_tol"]);
    assert_eq!(c.frf.quantity.name(), side["quantity"].as_str().unwrap());
    let hz: Vec<f64> = side["frequency_hz"]
        .as_array()
        .unwrap()
        .iter()
        .map(f)
        .collect();
    // Abscissae are printed E13.5 by pyuff; the script uses values exact in 6 digits.
    assert_eq!(c.frf.frequency_hz, hz, "{name}");
    let ids = |v: &Value| -> Vec<String> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|s| s.as_str().unwrap().to_string())
            .collect()
    };
    let channels: Vec<String> = c.geometry.channels.iter().map(|x| x.id.clone()).collect();
    let excitations: Vec<String> = c
        .geometry
        .excitations
        .iter()
        .map(|x| x.id.clone())
        .collect();
    assert_eq!(channels, ids(&side["channels"]), "{name}");
    assert_eq!(excitations, ids(&side["excitations"]), "{name}");
    let frfs = side["frfs"].as_array().unwrap();
    assert_eq!(frfs.len(), channels.len() * excitations.len(), "{name}");
    for cell in frfs {
        let ci = channels.iter().position(|x| x == &cell["channel"]).unwrap();
        let ei = excitations
            .iter()
            .position(|x| x == &cell["excitation"])
            .unwrap();
        let got = c.frf.frf(ei, ci);
        let (re, im) = (
            cell["re"].as_array().unwrap(),
            cell["im"].as_array().unwrap(),
        );
        for (k, g) in got.iter().enumerate() {
            let (wr, wi) = (f(&re[k]), f(&im[k]));
            // Each component is printed (or stored) on its own: its error is relative to
            // itself, plus the rounding of one multiplication by the SI factor.
            let mag = wr.hypot(wi);
            assert!(
                (g.re - wr).abs() <= rel * wr.abs() + 4e-16 * mag
                    && (g.im - wi).abs() <= rel * wi.abs() + 4e-16 * mag,
                "{name}: {} / {} line {k}: {g} vs {wr}+{wi}i (rel {rel})",
                cell["channel"],
                cell["excitation"]
            );
        }
    }
    if let Some(nodes) = side["nodes"].as_object() {
        let tol = side["pos_tol"].as_f64().unwrap_or(1e-15);
        for p in &c.geometry.points {
            let Some(want) = nodes.get(&p.id) else {
                continue;
            };
            let want: Vec<f64> = want.as_array().unwrap().iter().map(f).collect();
            for k in 0..3 {
                assert!(
                    (p.position[k] - want[k]).abs() <= tol * want[k].abs().max(0.1),
                    "{name}: point {} coordinate {k}: {} vs {}",
                    p.id,
                    p.position[k],
                    want[k]
                );
            }
        }
        for ch in &c.geometry.channels {
            let node = ch.id.trim_end_matches(['x', 'y', 'z', '-']);
            assert!(nodes.contains_key(node), "{name}: {}", ch.id);
        }
    }
    if let Some(dirs) = side["directions"].as_object() {
        let all = c
            .geometry
            .channels
            .iter()
            .map(|x| (&x.id, x.direction))
            .chain(c.geometry.excitations.iter().map(|x| (&x.id, x.direction)));
        for (id, d) in all {
            let want: Vec<f64> = dirs[id.as_str()]
                .as_array()
                .unwrap()
                .iter()
                .map(f)
                .collect();
            for k in 0..3 {
                // Directions come from 17-digit matrices or exact three-point systems.
                assert!(
                    (d[k] - want[k]).abs() < 1e-12,
                    "{name}: {id}: {d:?} vs {want:?}"
                );
            }
        }
    }
    match side["coherence"].as_array() {
        None => assert!(c.coherence.is_none(), "{name}: unexpected coherence"),
        Some(cells) => {
            let coh = c.coherence.as_ref().expect("coherence read");
            assert_eq!(coh.count(), cells.len());
            for cell in cells {
                let ci = channels.iter().position(|x| x == &cell["channel"]).unwrap();
                let ei = excitations
                    .iter()
                    .position(|x| x == &cell["excitation"])
                    .unwrap();
                let want: Vec<f64> = cell["values"].as_array().unwrap().iter().map(f).collect();
                // Binary doubles: exact.
                assert_eq!(coh.values[ei][ci].as_ref().unwrap(), &want, "{name}");
            }
        }
    }
    for w in side["warnings"].as_array().into_iter().flatten() {
        let w = w.as_str().unwrap();
        assert!(
            c.warnings.iter().any(|x| x.contains(w)),
            "{name}: no warning containing '{w}' in {:?}",
            c.warnings
        );
    }
}

macro_rules! exports {
    ($($name:ident),* $(,)?) => {$(
        #[test]
        fn $name() {
            check(stringify!($name));
        }
    )*};
}

exports!(
    label_latin1_product,
    label_utf8_mm_s2_per_n,
    label_upper_g_lbf,
    label_in_s2_lbf_crlf,
    label_paren_ascii_single,
    label_contradicts_record9,
    label_db_refused,
    binary_double_stray_line_end,
    ascii_blank_separated,
    ascii_blank_separated_count_mismatch,
    split_data,
    split_data_alone,
    node0_dofs_in_names,
    node0_channel_map,
    node0_channel_map_without_map,
    mixed_frf_coherence_autospectra,
    no_frf_time_and_psd,
);

/// Every sidecar in the directory is one of the tests above (none forgotten).
#[test]
fn every_export_is_checked() {
    let listed = include_str!("exports.rs");
    for e in std::fs::read_dir(dir()).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "json") {
            let stem = p.file_stem().unwrap().to_string_lossy().to_string();
            assert!(
                listed.contains(&format!("    {stem},\n")),
                "{stem}.json has no test"
            );
        }
    }
}

/// The inventory names what a file holds: datasets, function types, units, axes.
#[test]
fn inventory_lists_the_file() {
    let name = "mixed_frf_coherence_autospectra.uff";
    let uff = parse(&std::fs::read(dir().join(name)).unwrap(), name).unwrap();
    let inv = inventory(&uff);
    for want in [
        "16 datasets:",
        "dataset 58 functions at nodal DOFs: 15 (15 binary)",
        "dataset 2411 nodes (double precision): 1",
        "FRF (type 4): 6",
        "coherence (type 6): 6",
        "auto spectrum (type 2): 3",
        "FRF g (type 12) / N (type 13): 6",
        "frequency 7 lines 0.5…3.5 Hz (even spacing): 15",
        "nodes: 4 defined (1-4)",
        "units: no dataset 164 (SI assumed)",
    ] {
        assert!(inv.contains(want), "inventory lacks '{want}':\n{inv}");
    }
}
