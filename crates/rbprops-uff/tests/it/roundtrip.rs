//! Our campaign → UFF → our campaign.

use crate::common::{campaign, even_axis, Spec};
use rbprops_core::{FrfSet, Geometry, Quantity};
use rbprops_uff::{from_campaign, parse, to_campaign, NodeFormat, Record, WriteOptions};

fn ids(n: usize) -> Vec<String> {
    (0..n).map(|k| format!("acc-{k}")).collect()
}

fn round_trip(g: &Geometry, frf: &FrfSet, opts: &WriteOptions) -> (Geometry, FrfSet, Vec<u8>) {
    let bytes = from_campaign(g, frf, opts).unwrap();
    let uff = parse(&bytes, "rt.uff").unwrap_or_else(|e| panic!("{e}"));
    let (g2, f2) = to_campaign(&uff).unwrap_or_else(|e| panic!("{e}"));
    (g2, f2, bytes)
}

/// Largest per-component relative error between two FRF sets.
fn worst_relative(a: &FrfSet, b: &FrfSet) -> f64 {
    a.values
        .iter()
        .zip(&b.values)
        .flat_map(|(x, y)| [(x.re, y.re), (x.im, y.im)])
        .map(|(x, y)| if x == y { 0.0 } else { (x - y).abs() / y.abs() })
        .fold(0.0, f64::max)
}

#[test]
fn binary_58b_round_trip_is_bit_exact_with_offaxis_sensors() {
    for (seed, q) in [
        (1, Quantity::Accelerance),
        (2, Quantity::Mobility),
        (3, Quantity::Receptance),
    ] {
        let spec = Spec {
            point_ids: ids(4),
            misoriented: true,
            quantity: q,
            // 1/3 Hz steps cannot be written exactly in a 13-column field: the binary
            // writer falls back to double abscissae.
            frequency_hz: (1..=40).map(|k| k as f64 / 3.0).collect(),
            seed,
        };
        let (g, frf) = campaign(&spec);
        let opts = WriteOptions {
            binary: true,
            ..Default::default()
        };
        let (g2, f2, bytes) = round_trip(&g, &frf, &opts);
        assert_eq!(g2, g, "seed {seed}");
        assert_eq!(f2, frf, "seed {seed}");
        // Off-axis directions need displacement systems and extra nodes.
        let uff = parse(&bytes, "rt.uff").unwrap();
        assert!(uff
            .datasets
            .iter()
            .any(|d| matches!(&d.record, Record::CoordinateSystems(s) if !s.systems.is_empty())));
    }
}

#[test]
fn binary_even_axis_is_bit_exact_and_uses_even_spacing() {
    let spec = Spec {
        point_ids: vec!["1".into(), "2".into(), "3".into(), "40".into()],
        misoriented: false,
        quantity: Quantity::Accelerance,
        frequency_hz: even_axis(64, 0.0125),
        seed: 4,
    };
    let (g, frf) = campaign(&spec);
    let opts = WriteOptions {
        binary: true,
        ..Default::default()
    };
    let (g2, f2, bytes) = round_trip(&g, &frf, &opts);
    assert_eq!((g2, f2), (g, frf));
    let uff = parse(&bytes, "rt.uff").unwrap();
    let mut n58 = 0;
    for d in &uff.datasets {
        match &d.record {
            Record::Function(f) => {
                n58 += 1;
                assert!(f.even && f.binary.is_some());
            }
            Record::Nodes(n) => {
                // Integer point ids are the node labels.
                let labels: Vec<i64> = n.nodes.iter().map(|n| n.label).collect();
                assert_eq!(labels, [1, 2, 3, 40]);
            }
            Record::CoordinateSystems(_) => panic!("axis-aligned DOFs need no 2420"),
            _ => {}
        }
    }
    assert_eq!(n58, 3 * 9);
}

#[test]
fn ascii_58_round_trip_within_13_digits() {
    let mut worst = 0.0f64;
    for seed in 10..16 {
        let spec = Spec {
            point_ids: ids(4),
            misoriented: seed % 2 == 0,
            quantity: Quantity::Mobility,
            frequency_hz: even_axis(50, 0.25),
            seed,
        };
        let (g, frf) = campaign(&spec);
        let (g2, f2, _) = round_trip(&g, &frf, &WriteOptions::default());
        // Geometry (2411 + 2420, 17 digits) and the 0.25 Hz axis are exact.
        assert_eq!(g2, g);
        assert_eq!(f2.frequency_hz, frf.frequency_hz);
        assert_eq!(f2.quantity, frf.quantity);
        let w = worst_relative(&f2, &frf);
        // 13 significant digits: half a unit in the 13th digit is 5e-13 relative.
        assert!(w <= 5e-13, "seed {seed}: {w:e}");
        worst = worst.max(w);
    }
    eprintln!("ASCII 58 worst relative error over 6 campaigns: {worst:.2e}");
}

#[test]
fn ascii_uneven_axis_and_dataset_15() {
    let spec = Spec {
        point_ids: ids(4),
        misoriented: false,
        quantity: Quantity::Receptance,
        frequency_hz: vec![0.5, 0.75, 1.125, 2.0, 3.5, 7.25, 12.5],
        seed: 21,
    };
    let (g, frf) = campaign(&spec);
    let opts = WriteOptions {
        nodes: NodeFormat::D15,
        ..Default::default()
    };
    let (g2, f2, bytes) = round_trip(&g, &frf, &opts);
    let uff = parse(&bytes, "rt.uff").unwrap();
    assert!(uff
        .datasets
        .iter()
        .any(|d| matches!(&d.record, Record::Function(f) if !f.even)));
    assert_eq!(f2.frequency_hz, frf.frequency_hz);
    assert!(worst_relative(&f2, &frf) <= 5e-13);
    // Dataset 15 has 13-column coordinates: at least 7 significant digits.
    for (a, b) in g2.points.iter().zip(&g.points) {
        assert_eq!(a.id, b.id);
        assert!((a.position - b.position).norm() <= 5e-7 * b.position.norm());
    }
    assert_eq!(
        g2.channels
            .iter()
            .map(|c| (&c.id, c.direction))
            .collect::<Vec<_>>(),
        g.channels
            .iter()
            .map(|c| (&c.id, c.direction))
            .collect::<Vec<_>>()
    );
}

#[test]
fn without_tags_ids_follow_node_and_direction() {
    let spec = Spec {
        point_ids: vec!["7".into(), "8".into(), "9".into(), "10".into()],
        misoriented: false,
        quantity: Quantity::Accelerance,
        frequency_hz: even_axis(5, 1.0),
        seed: 5,
    };
    let (g, frf) = campaign(&spec);
    let opts = WriteOptions {
        tags: false,
        ..Default::default()
    };
    let (g2, f2, _) = round_trip(&g, &frf, &opts);
    let ch: Vec<&str> = g2.channels.iter().map(|c| c.id.as_str()).collect();
    assert_eq!(
        ch,
        ["7x", "7-y", "7z", "8x", "8-y", "8z", "9x", "9-y", "9z"]
    );
    let ex: Vec<&str> = g2.excitations.iter().map(|e| e.id.as_str()).collect();
    assert_eq!(ex, ["10x", "10y", "10-z@B"]);
    // Without tags the set-up id still travels in ID line 4 (set-up B) and A is the default.
    assert_eq!(
        g2.setups.iter().map(|s| s.id.as_str()).collect::<Vec<_>>(),
        ["A", "B"]
    );
    for (a, b) in g2.channels.iter().zip(&g.channels) {
        assert_eq!((a.position, a.direction), (b.position, b.direction));
    }
    assert!(worst_relative(&f2, &frf) <= 5e-13);
}

#[test]
fn writer_rejects_inconsistent_input() {
    let spec = Spec {
        point_ids: ids(4),
        misoriented: false,
        quantity: Quantity::Accelerance,
        frequency_hz: even_axis(5, 1.0),
        seed: 6,
    };
    let (g, mut frf) = campaign(&spec);
    frf.n_channels -= 1;
    frf.values.truncate(frf.n_excitations * frf.n_channels * 5);
    let e = from_campaign(&g, &frf, &WriteOptions::default()).unwrap_err();
    assert!(e.to_string().contains("8 channels"), "{e}");
}

#[test]
fn realistic_size_round_trip() {
    // 3 excitations × 9 channels × 4001 lines (0-50 Hz at 12.5 mHz), both encodings.
    let spec = Spec {
        point_ids: ids(4),
        misoriented: true,
        quantity: Quantity::Accelerance,
        frequency_hz: even_axis(4001, 0.0125),
        seed: 77,
    };
    let (g, frf) = campaign(&spec);
    for binary in [false, true] {
        let t = std::time::Instant::now();
        let opts = WriteOptions {
            binary,
            ..Default::default()
        };
        let (g2, f2, bytes) = round_trip(&g, &frf, &opts);
        eprintln!(
            "{} {} bytes: write + parse + map in {:.0} ms (debug build)",
            if binary { "58b" } else { "58" },
            bytes.len(),
            t.elapsed().as_secs_f64() * 1e3
        );
        assert_eq!(g2, g);
        assert_eq!(f2.frequency_hz, frf.frequency_hz);
        assert!(worst_relative(&f2, &frf) <= if binary { 0.0 } else { 5e-13 });
    }
}
