//! Files written by the independent writer pyuff (scripts/make_uff_fixtures.py) are read
//! to the precision of the fields pyuff printed, with the expected SI conversions and
//! directions the script computed with numpy.

use rbprops_core::Quantity;
use rbprops_uff::{parse, to_campaign, Record, UffError};
use serde_json::Value;
use std::path::PathBuf;

fn fixtures() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/uff")
}

fn f(v: &Value) -> f64 {
    v.as_f64().expect("number")
}

fn check_fixture(name: &str) {
    let dir = fixtures();
    let bytes = std::fs::read(dir.join(format!("{name}.uff"))).expect("fixture");
    let side: Value =
        serde_json::from_slice(&std::fs::read(dir.join(format!("{name}.json"))).unwrap()).unwrap();
    let uff = parse(&bytes, &format!("{name}.uff")).unwrap_or_else(|e| panic!("{e}"));
    let (geo, frf) = to_campaign(&uff).unwrap_or_else(|e| panic!("{e}"));

    let q: Quantity = side["quantity"].as_str().unwrap().parse().unwrap();
    assert_eq!(frf.quantity, q, "{name}");
    let (rel, pos_tol, dir_tol) = (
        f(&side["rel_tol"]),
        f(&side["pos_tol"]),
        f(&side["dir_tol"]),
    );
    let (to_si, len_si) = (f(&side["value_to_si"]), f(&side["length_to_si"]));

    let hz: Vec<f64> = side["frequency_hz"]
        .as_array()
        .unwrap()
        .iter()
        .map(f)
        .collect();
    assert_eq!(frf.frequency_hz.len(), hz.len());
    for (a, b) in frf.frequency_hz.iter().zip(&hz) {
        assert!(
            (a - b).abs() <= rel.max(1e-15) * b.abs(),
            "{name}: {a} vs {b} Hz"
        );
    }

    let ids = |k: &str| -> Vec<String> {
        side[k]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap().to_string())
            .collect()
    };
    assert_eq!(
        geo.channels
            .iter()
            .map(|c| c.id.clone())
            .collect::<Vec<_>>(),
        ids("channels")
    );
    assert_eq!(
        geo.excitations
            .iter()
            .map(|e| e.id.clone())
            .collect::<Vec<_>>(),
        ids("excitations")
    );

    // Node positions (file units × factor), and every channel/excitation sits at its node.
    let nodes = side["nodes"].as_object().unwrap();
    assert_eq!(geo.points.len(), nodes.len());
    for (label, xyz) in nodes {
        let p = geo
            .point(label)
            .unwrap_or_else(|| panic!("{name}: point {label}"));
        for k in 0..3 {
            let want = f(&xyz[k]) * len_si;
            assert!(
                (p.position[k] - want).abs() <= pos_tol * want.abs() + 1e-300,
                "{name}: node {label} coordinate {k}: {} vs {want}",
                p.position[k]
            );
        }
    }
    for c in &geo.channels {
        assert_eq!(geo.point(&c.point).unwrap().position, c.position);
    }

    // Directions in global coordinates, computed by the script from 2420 / 18.
    for (id, d) in side["directions"].as_object().unwrap() {
        let got = geo
            .channels
            .iter()
            .find(|c| &c.id == id)
            .map(|c| c.direction)
            .or_else(|| {
                geo.excitations
                    .iter()
                    .find(|e| e.id == *id || e.id.starts_with(&format!("{id}@")))
                    .map(|e| e.direction)
            })
            .unwrap_or_else(|| panic!("{name}: no DOF {id}"));
        for k in 0..3 {
            assert!(
                (got[k] - f(&d[k])).abs() <= dir_tol,
                "{name}: {id} direction {got:?} vs {d:?}"
            );
        }
    }

    // Values: each component within the printed relative precision.
    let mut worst = 0.0f64;
    for rec in side["frfs"].as_array().unwrap() {
        let ci = geo.channel_index(rec["channel"].as_str().unwrap()).unwrap();
        let ei = geo
            .excitation_index(rec["excitation"].as_str().unwrap())
            .unwrap();
        let got = frf.frf(ei, ci);
        let re = rec["re"].as_array().unwrap();
        let im = rec["im"].as_array().unwrap();
        for (l, v) in got.iter().enumerate() {
            for (g, w) in [(v.re, f(&re[l]) * to_si), (v.im, f(&im[l]) * to_si)] {
                let err = (g - w).abs() / w.abs().max(f64::MIN_POSITIVE);
                worst = worst.max(if g == w { 0.0 } else { err });
                assert!(
                    (g - w).abs() <= rel * w.abs() * (1.0 + 1e-12) + 2.0 * f64::EPSILON * w.abs(),
                    "{name}: excitation {ei} channel {ci} line {l}: {g} vs {w}"
                );
            }
        }
    }
    eprintln!("{name}: worst relative value error {worst:.2e} (printed precision {rel:.0e})");
}

#[test]
fn ascii_complex_double_even_si_with_labels() {
    check_fixture("ascii_complex_double_even");
}

#[test]
fn ascii_complex_single_uneven_inch_units_and_2420_system() {
    check_fixture("ascii_complex_single_uneven_inch");
}

#[test]
fn binary_complex_double_uneven_mm_units_18_system_two_setups() {
    check_fixture("binary_complex_double_uneven_mm");
    // The coherence function travels along but is not an FRF.
    let bytes = std::fs::read(fixtures().join("binary_complex_double_uneven_mm.uff")).unwrap();
    let uff = parse(&bytes, "x.uff").unwrap();
    let types: Vec<i64> = uff
        .datasets
        .iter()
        .filter_map(|d| match &d.record {
            Record::Function(f) => Some(f.function_type),
            _ => None,
        })
        .collect();
    assert!(types.contains(&6) && types.iter().filter(|&&t| t == 4).count() == 18);
    let (geo, _) = to_campaign(&uff).unwrap();
    assert_eq!(
        geo.setups.iter().map(|s| s.id.as_str()).collect::<Vec<_>>(),
        ["A", "B"]
    );
}

#[test]
fn binary_real_double_even_g_label() {
    check_fixture("binary_real_double_even_g");
}

#[test]
fn missing_node_coordinates_is_an_error_naming_file_dataset_and_field() {
    let bytes = std::fs::read(fixtures().join("error_missing_node.uff")).unwrap();
    let uff = parse(&bytes, "error_missing_node.uff").unwrap();
    let e = to_campaign(&uff).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, UffError::Field { .. }), "{msg}");
    assert!(msg.contains("error_missing_node.uff"), "{msg}");
    assert!(msg.contains("dataset #2 (type 58"), "{msg}");
    assert!(msg.contains("record 6 (response/reference node)"), "{msg}");
    assert!(msg.contains("have no coordinates: 9;"), "{msg}");
}
