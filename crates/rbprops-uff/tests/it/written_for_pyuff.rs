//! Our writer against the committed files the independent check reads
//! (`scripts/check_uff_with_pyuff.py <file.uff> <expected.json>`, run by rbprops-cli's
//! `pyuff_reads_what_we_write`): fixtures/uff/written/rbprops_{ascii,binary}.{uff,json}.
//! The test compares the bytes it writes with them and writes nothing into the source
//! tree (another test binary feeds the same files to pyuff), unless `RBPROPS_BLESS=1`
//! asks it to rewrite them after an intended change of the writer. The expected JSON
//! comes from the campaign, not from the file.

use crate::common::{campaign, even_axis, Spec};
use nalgebra::Rotation3;
use rbprops_core::{Quantity, Vec3};
use rbprops_uff::{from_campaign, parse, to_campaign, WriteOptions};
use serde_json::json;
use std::path::PathBuf;

#[test]
fn writer_gives_the_committed_files_for_the_pyuff_check() {
    let spec = Spec {
        point_ids: vec!["1".into(), "2".into(), "3".into(), "4".into()],
        misoriented: false,
        quantity: Quantity::Accelerance,
        frequency_hz: even_axis(16, 0.0125),
        seed: 2026,
    };
    let (mut g, frf) = campaign(&spec);
    // Point 2's triaxial sensor is rotated: its directions need a 2420 system.
    let r = Rotation3::from_euler_angles(0.2, -0.1, 0.7);
    for c in g.channels.iter_mut().filter(|c| c.point == "2") {
        c.direction = r * c.direction;
    }
    let dir = |d: Vec3| vec![d.x, d.y, d.z];
    let frfs: Vec<_> = g
        .excitations
        .iter()
        .enumerate()
        .flat_map(|(ei, e)| {
            let frf = &frf;
            g.channels.iter().enumerate().map(move |(ci, c)| {
                let v = frf.frf(ei, ci);
                json!({
                    "channel": c.id, "excitation": e.id,
                    "rsp_node": c.point.parse::<i64>().unwrap(),
                    "ref_node": e.point.parse::<i64>().unwrap(),
                    "response_direction": dir(c.direction),
                    "reference_direction": dir(e.direction),
                    "frequency_hz": frf.frequency_hz,
                    "re": v.iter().map(|z| z.re).collect::<Vec<_>>(),
                    "im": v.iter().map(|z| z.im).collect::<Vec<_>>(),
                })
            })
        })
        .collect();
    let nodes: serde_json::Map<String, serde_json::Value> = g
        .points
        .iter()
        .map(|p| (p.id.clone(), json!(dir(p.position))))
        .collect();
    let out = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/uff/written");
    let bless = std::env::var_os("RBPROPS_BLESS").is_some();
    if bless {
        std::fs::create_dir_all(&out).unwrap();
    }
    for (name, binary, rel) in [
        ("rbprops_ascii", false, 5e-13),
        ("rbprops_binary", true, 0.0),
    ] {
        let bytes = from_campaign(
            &g,
            &frf,
            &WriteOptions {
                binary,
                run_id: "rbprops-uff pyuff check".into(),
                ..Default::default()
            },
        )
        .unwrap();
        // Our own reader agrees before the file goes to pyuff.
        let (g2, f2) = to_campaign(&parse(&bytes, name).unwrap()).unwrap();
        assert_eq!(g2, g);
        if binary {
            assert_eq!(f2, frf);
        }
        let expected = json!({
            "nodes": nodes,
            "position_tol": 0.0,
            "direction_tol": 1e-15,
            "frequency_rel_tol": 0.0,
            "value_rel_tol": rel,
            "frfs": frfs,
        });
        let json_text = serde_json::to_string_pretty(&expected).unwrap() + "\n";
        for (file, written) in [
            (format!("{name}.uff"), bytes.as_slice()),
            (format!("{name}.json"), json_text.as_bytes()),
        ] {
            let path = out.join(&file);
            if bless {
                std::fs::write(&path, written).unwrap();
                continue;
            }
            let committed = std::fs::read(&path)
                .unwrap_or_else(|e| panic!("{}: {e} (RBPROPS_BLESS=1 writes it)", path.display()));
            assert!(
                committed == written,
                "{}: the writer's bytes differ from the committed file (RBPROPS_BLESS=1 rewrites it after an intended change)",
                path.display()
            );
        }
    }
}
