//! Acceptance tests of the selection on noise-free models.
use crate::common::*;
use rbprops_ni::{select_modes, Criterion, NiError, SelectOptions, SelectionOutput};

fn run(
    model: &Model,
    rec: &rbprops_core::records::ModalFitRecord,
    opts: &SelectOptions,
) -> SelectionOutput {
    let hz = axis(0.1, 1.5, 0.0005);
    select_modes(&model.geometry, &frfs(model, &hz), rec, opts).unwrap()
}

/// Every selected mode is the true mode nearest in frequency, all six are found in each
/// set-up, and each is taken from an excitation that excites it strongly: the one with the
/// largest true participation (f_kᵀφ0_r)², or within 1 dB of it.
fn check_against_truth(model: &Model, out: &SelectionOutput, setup: &str) {
    let sel: Vec<_> = out
        .record
        .selected
        .iter()
        .filter(|s| s.setup == setup)
        .collect();
    assert_eq!(sel.len(), 6, "set-up {setup}: {:?}", out.record);
    let truth = model.modes_of(setup);
    let mut seen = [false; 6];
    for s in &sel {
        let r = model.true_mode_near(setup, s.frequency_hz);
        assert!(!seen[r], "true mode {} selected twice", r + 1);
        seen[r] = true;
        assert_eq!(s.mode, r + 1, "physical numbering follows frequency");
        assert!((s.frequency_hz / truth[r].frequency_hz - 1.0).abs() < 1e-3);
        let exs: Vec<&str> = model
            .geometry
            .excitations
            .iter()
            .filter(|e| e.setup == setup)
            .map(|e| e.id.as_str())
            .collect();
        let best = exs
            .iter()
            .map(|e| model.participation(e, r))
            .fold(0.0, f64::max);
        let got = model.participation(&s.excitation, r);
        assert!(
            got >= best * 10f64.powf(-0.1),
            "set-up {setup} mode {}: chose {} with (fᵀφ)² = {got:.3e}, best is {best:.3e}",
            r + 1,
            s.excitation
        );
        // The measured strength is the true participation within 4 propagated standard
        // errors of the residue noise.
        let g = out
            .matches
            .iter()
            .find(|g| g.setup == setup && g.mode == s.mode)
            .unwrap();
        let row = g
            .ranking
            .iter()
            .find(|x| x.excitation == s.excitation)
            .unwrap();
        let sd = row.strength_std.unwrap();
        assert!(
            (s.strength - got).abs() < 4.0 * sd,
            "{} vs {got} ± {sd}",
            s.strength
        );
        assert_eq!(s.criterion, "ni");
    }
}

#[test]
fn test_case_one_ni_selects_all_six_modes_in_both_setups() {
    let m = test_case_one();
    let rec = estimates(&m, EstimateSpec::default());
    let out = run(&m, &rec, &SelectOptions::default());
    check_against_truth(&m, &out, "A");
    check_against_truth(&m, &out, "B");
    assert!(out.record.missing.is_empty(), "{:?}", out.record.missing);
    // No single force excites all six modes in set-up A; the selected set uses all three.
    let mut used: Vec<&str> = out
        .record
        .selected
        .iter()
        .filter(|s| s.setup == "A")
        .map(|s| s.excitation.as_str())
        .collect();
    used.sort_unstable();
    used.dedup();
    assert_eq!(used, ["F0x", "F0y", "F0z"]);
    // The margin over the runner-up is the NI difference: mode 6 (θz) gets
    // (f_kᵀφ)² = 0.0667 from F0y and 0.0167 from F0x, a factor 4 = 6.02 dB.
    let m6 = out
        .record
        .selected
        .iter()
        .find(|s| s.setup == "A" && s.mode == 6)
        .unwrap();
    assert_eq!(m6.excitation, "F0y");
    assert_eq!(m6.runner_up.as_deref(), Some("F0x"));
    assert!(
        (m6.margin_db - 10.0 * 4f64.log10()).abs() < 0.1,
        "{}",
        m6.margin_db
    );
    // Plot data are complete and finite.
    assert_eq!(out.curves.excitations.len(), 5);
    for c in &out.curves.excitations {
        assert_eq!(c.ni_db.len(), out.curves.frequency_hz.len());
        assert!(c
            .ni_db
            .iter()
            .chain(&c.hybrid_mif)
            .chain(&c.prf_mif)
            .all(|x| x.is_finite()));
    }
    assert_eq!(out.strength_db.len(), 2);
    assert_eq!(out.strength_db[0].measured_db.len(), 6);
    assert_eq!(out.strength_db[0].excitations, ["F0x", "F0y", "F0z"]);
}

#[test]
fn ni_tells_how_many_modes_each_excitation_excites() {
    let m = test_case_one();
    let rec = estimates(&m, EstimateSpec::default());
    let out = run(&m, &rec, &SelectOptions::default());
    // Set-up A decouples: the true participations are exactly zero outside these sets.
    let expect = [
        ("F0x", vec![1, 6]),
        ("F0y", vec![5, 6]),
        ("F0z", vec![2, 3, 4]),
    ];
    for (ex, modes) in expect {
        let s = out
            .excitation_summaries
            .iter()
            .find(|s| s.excitation == ex)
            .unwrap();
        let truly: Vec<usize> = (0..6)
            .filter(|&r| m.participation(ex, r) > 1e-12)
            .map(|r| r + 1)
            .collect();
        assert_eq!(truly, modes, "fixture");
        assert_eq!(s.modes_excited, modes, "{ex}");
        let peak_modes: Vec<Option<usize>> = s.peaks.iter().map(|p| p.mode).collect();
        assert_eq!(
            peak_modes,
            modes.iter().map(|&r| Some(r)).collect::<Vec<_>>(),
            "{ex} NI peaks"
        );
        // The modes it misses: not identified, predicted strength zero to rounding.
        for row in s.modes.iter().filter(|r| !modes.contains(&r.mode)) {
            assert!(row.excitation_mode.is_none());
            assert!(!row.eligible);
            // Zero up to the reference shape's error from the 1e-3 residue noise, which
            // leaks (1e-3)²-level power into other forces: 50 dB below its strongest mode.
            let top = modes
                .iter()
                .map(|&r| m.participation(ex, r - 1))
                .fold(0.0, f64::max);
            assert!(row.predicted_strength.unwrap() < 1e-5 * top, "{row:?}");
            assert!(row
                .reason
                .as_deref()
                .unwrap()
                .contains("no mode identified"));
        }
    }
    // Set-up B: F2y drives all six; F1x barely drives mode 4 ((fᵀφ)² = 1.3e-4, 29 dB
    // below its mode 1) so its residues are at the noise level there.
    let f2y = out
        .excitation_summaries
        .iter()
        .find(|s| s.excitation == "F2y")
        .unwrap();
    assert_eq!(f2y.modes_excited, [1, 2, 3, 4, 5, 6]);
    assert_eq!(f2y.peaks.len(), 6);
    // "Mostly": within 20 dB of the excitation's strongest mode, by true participation.
    for s in &out.excitation_summaries {
        let k_modes = m.modes_of(&s.setup).len();
        let parts: Vec<f64> = (0..k_modes)
            .map(|r| m.participation(&s.excitation, r))
            .collect();
        for &r in &s.modes_mostly_excited {
            let top = s
                .modes_excited
                .iter()
                .map(|&q| parts[q - 1])
                .fold(0.0, f64::max);
            assert!(
                parts[r - 1] >= top * 10f64.powf(-2.0 - 0.01),
                "{} mode {r}",
                s.excitation
            );
        }
    }
}

#[test]
fn a_mode_one_excitation_misses_is_taken_from_another() {
    let m = test_case_one();
    let rec = estimates(&m, EstimateSpec::default());
    let out = run(&m, &rec, &SelectOptions::default());
    let f0x = out
        .excitation_summaries
        .iter()
        .find(|s| s.excitation == "F0x")
        .unwrap();
    assert!(f0x.modes_not_excited.contains(&5) && f0x.modes_not_excited.contains(&3));
    let pick = |mode| {
        out.record
            .selected
            .iter()
            .find(|s| s.setup == "A" && s.mode == mode)
            .unwrap()
    };
    assert_eq!(pick(5).excitation, "F0y");
    assert_eq!(pick(3).excitation, "F0z");
    // The NI of F0x at mode 5 is far below F0y's: the excitation simply has no response there.
    let g5 = out
        .matches
        .iter()
        .find(|g| g.setup == "A" && g.mode == 5)
        .unwrap();
    let ni = |ex: &str| {
        g5.ranking
            .iter()
            .find(|r| r.excitation == ex)
            .unwrap()
            .ni_db
    };
    assert!(ni("F0y") - ni("F0x") > 20.0, "{} {}", ni("F0y"), ni("F0x"));
    assert_eq!(g5.ranking[0].excitation, "F0y");
}

#[test]
fn mode_numbers_within_an_excitation_are_mapped_to_physical_modes() {
    let m = test_case_one();
    let rec = estimates(&m, EstimateSpec::default());
    let out = run(&m, &rec, &SelectOptions::default());
    // F0y identifies only modes 5 and 6: its own numbers 1 and 2.
    let s5 = out
        .record
        .selected
        .iter()
        .find(|s| s.setup == "A" && s.mode == 5)
        .unwrap();
    assert_eq!((s5.excitation.as_str(), s5.excitation_mode), ("F0y", 1));
    for g in &out.matches {
        let truth = m.modes_of(&g.setup);
        let r = m.true_mode_near(&g.setup, g.frequency_hz);
        assert_eq!(g.mode, r + 1);
        for row in g.ranking.iter().filter(|r| r.eligible) {
            let est = rec
                .modes
                .iter()
                .find(|e| e.excitation == row.excitation && Some(e.mode) == row.excitation_mode)
                .unwrap();
            assert!((est.frequency_hz / truth[r].frequency_hz - 1.0).abs() < 1e-3);
            assert!(row.mac_to_reference.unwrap() > 0.999, "{row:?}");
        }
    }
}

#[test]
fn near_repeated_pair_is_matched_by_mac_not_swapped() {
    // Set-up A with J_zz tuned so that the θz mode sits 0.2 % above the y mode.
    let ky_total = 4.0 * 50.0;
    let wy2 = ky_total / 10.0;
    let k_tz = 4.0 * (10.0 * 0.2f64.powi(2) + 50.0 * 0.3f64.powi(2));
    let props = body(k_tz / (wy2 * 1.002f64.powi(2)));
    let mut g = rbprops_core::Geometry::default();
    sensors(&mut g);
    g.setups.push(rbprops_core::SuspensionSetup {
        id: "A".into(),
        description: String::new(),
    });
    g.excitations.push(force(
        "E1",
        rbprops_core::Vec3::new(0.2, -0.1, 0.0),
        rbprops_core::Vec3::y(),
        "A",
    ));
    g.excitations.push(force(
        "E2",
        rbprops_core::Vec3::new(-0.15, 0.1, 0.0),
        rbprops_core::Vec3::new(1.0, 1.0, 0.0),
        "A",
    ));
    let mut corners = Vec::new();
    for sx in [-1.0, 1.0] {
        for sy in [-1.0, 1.0] {
            corners.push(rbprops_core::Vec3::new(sx * 0.3, sy * 0.2, 0.0));
        }
    }
    let k = spring_stiffness(&corners, [10.0, 50.0, 20.0]);
    let model = Model {
        setups: vec![("A".into(), rigid_modes(&props, &k, |_| ZETA))],
        props,
        geometry: g,
    };
    let truth = model.modes_of("A");
    let (ry, rz) = (4, 5); // y translation, then θz 0.2 % higher
    assert!(
        truth[ry].shape[1].abs() > 0.3 && truth[rz].shape[5].abs() > 1.0,
        "fixture"
    );
    assert!((truth[rz].frequency_hz / truth[ry].frequency_hz - 1.002).abs() < 1e-9);
    for ex in ["E1", "E2"] {
        assert!(model.participation(ex, ry) > 1e-3 && model.participation(ex, rz) > 1e-3);
    }
    // modal-fit output: E1 has the pair in the true order, E2 has their frequencies swapped
    // (each off by 0.3 %, beyond their 0.2 % separation).
    let mut rec = estimates(
        &model,
        EstimateSpec {
            frequency_noise: 0.0,
            ..Default::default()
        },
    );
    for e in rec.modes.iter_mut().filter(|e| e.excitation == "E2") {
        let r = model.true_mode_near("A", e.frequency_hz);
        if r == ry {
            e.frequency_hz *= 1.003;
        } else if r == rz {
            e.frequency_hz /= 1.003;
        }
    }
    // Renumber E2 in ascending (perturbed) frequency, as modal-fit would.
    let mut e2: Vec<usize> = (0..rec.modes.len())
        .filter(|&i| rec.modes[i].excitation == "E2")
        .collect();
    e2.sort_by(|&a, &b| {
        rec.modes[a]
            .frequency_hz
            .total_cmp(&rec.modes[b].frequency_hz)
    });
    for (n, &i) in e2.iter().enumerate() {
        rec.modes[i].mode = n + 1;
    }
    let out = run(&model, &rec, &SelectOptions::default());
    assert!(out.record.missing.is_empty());
    for g in &out.matches {
        let r = model.true_mode_near("A", g.frequency_hz);
        for row in g.ranking.iter().filter(|r| r.excitation_mode.is_some()) {
            let est = rec
                .modes
                .iter()
                .find(|e| e.excitation == row.excitation && Some(e.mode) == row.excitation_mode)
                .unwrap();
            // The estimate's shape is the true shape of this group's mode.
            let (re, _) = rbprops_core::real_modal_constants(&est.residues);
            let basis = rbprops_core::RigidBasis::new(model.geometry.channel_matrix()).unwrap();
            let q = basis.fit(&re).unwrap().q;
            assert!(
                mac_s(&model, &q, &truth[r].shape) > 0.999,
                "group {} (true mode {}) holds {} mode {} of another shape",
                g.mode,
                r + 1,
                row.excitation,
                est.mode
            );
        }
    }
    // The pair: E2's estimate of the y mode is its higher-numbered one, and still joins
    // E1's y mode.
    let group_of = |r: usize| {
        out.matches
            .iter()
            .find(|g| model.true_mode_near("A", g.frequency_hz) == r)
            .unwrap()
    };
    let gy = group_of(ry);
    let n = |ex: &str| {
        gy.ranking
            .iter()
            .find(|r| r.excitation == ex)
            .unwrap()
            .excitation_mode
            .unwrap()
    };
    let gz = group_of(rz);
    let nz = |ex: &str| {
        gz.ranking
            .iter()
            .find(|r| r.excitation == ex)
            .unwrap()
            .excitation_mode
            .unwrap()
    };
    assert!(
        n("E1") < nz("E1") && n("E2") > nz("E2"),
        "the fixture swaps the order in E2"
    );
}

#[test]
fn a_mode_no_excitation_excites_above_the_noise_is_reported_missing() {
    // Set-up A with only F0x and F0y: modes 2–4 (out of plane) get no force at all.
    let mut m = test_case_one();
    m.geometry
        .excitations
        .retain(|e| e.id == "F0x" || e.id == "F0y");
    let hz = axis(0.1, 1.5, 0.0005);
    let frf = frfs(&m, &hz);
    let mut rec = estimates(&m, EstimateSpec::default());
    // modal-fit nevertheless reports mode 3 (z, 0.450 Hz): in F0x as a noise-level pole
    // (residues are pure noise of the stated standard error), in F0y flagged weak.
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(9);
    let z = m.modes_of("A")[2];
    for (k, weak) in [(0usize, false), (1usize, true)] {
        let mut est = estimate(&m, k, &z, 0, 1e-4, 1e-4, &mut rng);
        assert!(
            est.residues.iter().all(|r| r.norm() < 1e-3),
            "zero participation + noise"
        );
        est.weak = weak;
        rec.modes.push(est);
    }
    for ex in ["F0x", "F0y"] {
        let mut idx: Vec<usize> = (0..rec.modes.len())
            .filter(|&i| rec.modes[i].excitation == ex)
            .collect();
        idx.sort_by(|&a, &b| {
            rec.modes[a]
                .frequency_hz
                .total_cmp(&rec.modes[b].frequency_hz)
        });
        for (n, &i) in idx.iter().enumerate() {
            rec.modes[i].mode = n + 1;
        }
    }
    let opts = SelectOptions {
        setup: Some("A".into()),
        ..Default::default()
    };
    let out = select_modes(&m.geometry, &frf, &rec, &opts).unwrap();
    assert_eq!(out.record.missing.len(), 1, "{:?}", out.record);
    let miss = &out.record.missing[0];
    assert_eq!(miss.mode, 2, "x, z, y, θz are matched: z is the second");
    assert!((miss.frequency_hz / z.frequency_hz - 1.0).abs() < 1e-3);
    assert_eq!(miss.tried, ["F0x", "F0y"]);
    assert!(
        miss.reason.contains("mode 2")
            && miss.reason.contains("F0x:")
            && miss.reason.contains("F0y:")
    );
    // F0x's noise pole: fᵀq is either ≤ 0 or within 3 standard errors of zero.
    assert!(
        miss.reason.contains("F0x: fᵀq") && miss.reason.contains("F0y: modal-fit flagged it weak"),
        "{}",
        miss.reason
    );
    // The rest is still selected for downstream stages.
    let modes: Vec<usize> = out.record.selected.iter().map(|s| s.mode).collect();
    assert_eq!(modes, [1, 3, 4]);
    assert!(out.record.diagnostics.iter().any(|d| d.kind
        == rbprops_core::records::DiagnosticKind::ModeMissing
        && d.severity == rbprops_core::records::Severity::ChangesAnswer
        && d.message.contains("only 4 of the six")));
}

#[test]
fn other_criteria_choose_among_eligible_excitations_and_disagreements_are_reported() {
    let m = test_case_one();
    let rec = estimates(&m, EstimateSpec::default());
    for crit in [Criterion::HybridMif, Criterion::PrfMif] {
        let out = run(
            &m,
            &rec,
            &SelectOptions {
                criterion: crit,
                ..Default::default()
            },
        );
        assert_eq!(out.record.selected.len(), 12);
        for s in &out.record.selected {
            assert_eq!(s.criterion, crit.name());
            let g = out
                .matches
                .iter()
                .find(|g| g.setup == s.setup && g.mode == s.mode)
                .unwrap();
            let row = g
                .ranking
                .iter()
                .find(|r| r.excitation == s.excitation)
                .unwrap();
            assert!(row.eligible);
            // The chosen one has the deepest dip among the eligible.
            let key = |r: &rbprops_ni::ModeExcitation| {
                if crit == Criterion::HybridMif {
                    r.hybrid_mif
                } else {
                    r.prf_mif
                }
            };
            for other in g.ranking.iter().filter(|r| r.eligible) {
                assert!(key(row) <= key(other));
            }
            assert_eq!(g.ranking[0].excitation, s.excitation);
        }
    }
    let out = run(&m, &rec, &SelectOptions::default());
    for g in &out.matches {
        let differ = [&g.choice_hybrid_mif, &g.choice_prf_mif, &g.choice_strength]
            .iter()
            .any(|c| **c != g.choice_ni);
        let listed = out
            .criterion_disagreements
            .iter()
            .any(|d| d.contains(&format!("set-up '{}' mode {} ", g.setup, g.mode)));
        assert_eq!(differ, listed, "{g:?}");
    }
    // θz in set-up A: the MIFs see the purer response from F0x, NI the stronger from F0y.
    let g6 = out
        .matches
        .iter()
        .find(|g| g.setup == "A" && g.mode == 6)
        .unwrap();
    assert_eq!(g6.choice_ni.as_deref(), Some("F0y"));
    assert_eq!(g6.choice_strength.as_deref(), Some("F0y"));
}

#[test]
fn manual_sets_are_followed_and_mixed_setups_refused() {
    let m = test_case_one();
    let rec = estimates(&m, EstimateSpec::default());
    let hz = axis(0.1, 1.5, 0.0005);
    let frf = frfs(&m, &hz);
    let manual = rbprops_ni::parse_manual_set("1:F0x,2:F0z,3:F0z,4:F0z,5:F0y,6:F0x").unwrap();
    let out = select_modes(
        &m.geometry,
        &frf,
        &rec,
        &SelectOptions {
            manual: Some(manual),
            ..Default::default()
        },
    )
    .unwrap();
    let got: Vec<(usize, &str)> = out
        .record
        .selected
        .iter()
        .map(|s| (s.mode, s.excitation.as_str()))
        .collect();
    assert_eq!(
        got,
        [
            (1, "F0x"),
            (2, "F0z"),
            (3, "F0z"),
            (4, "F0z"),
            (5, "F0y"),
            (6, "F0x")
        ]
    );
    assert!(out
        .record
        .selected
        .iter()
        .all(|s| s.criterion == "manual" && s.setup == "A"));
    // Mode 6 from F0x is 6 dB below NI's choice: reported, with a negative margin.
    let s6 = &out.record.selected[5];
    assert_eq!(s6.runner_up.as_deref(), Some("F0y"));
    assert!(s6.margin_db < -5.0, "{}", s6.margin_db);
    assert!(out
        .criterion_disagreements
        .iter()
        .any(|d| d.contains("manual set takes F0x, NI picks F0y")));

    // A mode the chosen excitation did not identify becomes a MissingMode, the rest stays.
    let manual = rbprops_ni::parse_manual_set("1:F0x,2:F0x,5:F0y").unwrap();
    let out = select_modes(
        &m.geometry,
        &frf,
        &rec,
        &SelectOptions {
            manual: Some(manual),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(out.record.selected.len(), 2);
    assert_eq!(out.record.missing.len(), 1);
    assert_eq!(out.record.missing[0].tried, ["F0x"]);
    assert!(out.record.missing[0].reason.contains("did not identify it"));

    // Mixing set-ups: refused with the reason, accepted when forced.
    let mixed = rbprops_ni::parse_manual_set("1:F0x,2:F2y").unwrap();
    let e = select_modes(
        &m.geometry,
        &frf,
        &rec,
        &SelectOptions {
            manual: Some(mixed.clone()),
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(matches!(e, NiError::MixedSetups(_)));
    let msg = e.to_string();
    assert!(
        msg.contains("set-up 'A' (F0x)") && msg.contains("set-up 'B' (F2y)"),
        "{msg}"
    );
    let forced = select_modes(
        &m.geometry,
        &frf,
        &rec,
        &SelectOptions {
            manual: Some(mixed),
            force_mixed_setups: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(forced.record.selected.iter().all(|s| s.setup == "A+B"));
    assert!(forced
        .record
        .diagnostics
        .iter()
        .any(|d| d.kind == rbprops_core::records::DiagnosticKind::SetupsForced));

    // Unknown excitation and a manual set outside the requested set-up.
    let bad = rbprops_ni::parse_manual_set("1:F9").unwrap();
    let e = select_modes(
        &m.geometry,
        &frf,
        &rec,
        &SelectOptions {
            manual: Some(bad),
            ..Default::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("'F9'") && e.contains("F0x, F0y"), "{e}");
    let other = rbprops_ni::parse_manual_set("1:F1x").unwrap();
    let e = select_modes(
        &m.geometry,
        &frf,
        &rec,
        &SelectOptions {
            manual: Some(other),
            setup: Some("A".into()),
            ..Default::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("set-up 'B'") && e.contains("'A'"), "{e}");
    let seven = rbprops_ni::parse_manual_set("7:F0x").unwrap();
    let e = select_modes(
        &m.geometry,
        &frf,
        &rec,
        &SelectOptions {
            manual: Some(seven),
            ..Default::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("mode 7") && e.contains("6 matched modes"), "{e}");
}

#[test]
fn a_single_setup_can_be_requested() {
    let m = test_case_one();
    let rec = estimates(&m, EstimateSpec::default());
    let out = run(
        &m,
        &rec,
        &SelectOptions {
            setup: Some("B".into()),
            ..Default::default()
        },
    );
    assert!(out.record.selected.iter().all(|s| s.setup == "B"));
    assert_eq!(out.record.selected.len(), 6);
    assert_eq!(out.curves.excitations.len(), 2);
    let hz = axis(0.1, 1.5, 0.0005);
    let e = select_modes(
        &m.geometry,
        &frfs(&m, &hz),
        &rec,
        &SelectOptions {
            setup: Some("C".into()),
            ..Default::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("unknown set-up 'C'") && e.contains("A, B"),
        "{e}"
    );
}

#[test]
fn inconsistent_inputs_are_refused_with_names() {
    let m = test_case_one();
    let hz = axis(0.1, 1.5, 0.001);
    let frf = frfs(&m, &hz);
    let opts = SelectOptions::default();
    let mut rec = estimates(&m, EstimateSpec::default());
    rec.modes[0].setup = "B".into();
    let e = select_modes(&m.geometry, &frf, &rec, &opts)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("mode 1 of excitation 'F0x'") && e.contains("set-up 'B'"),
        "{e}"
    );
    let mut rec = estimates(&m, EstimateSpec::default());
    rec.modes[3].residues.pop();
    let e = select_modes(&m.geometry, &frf, &rec, &opts)
        .unwrap_err()
        .to_string();
    assert!(e.contains("8 residues for 9 channels"), "{e}");
    let mut rec = estimates(&m, EstimateSpec::default());
    rec.modes[2].excitation = "F7".into();
    let e = select_modes(&m.geometry, &frf, &rec, &opts)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("'F7'") && e.contains("no such excitation"),
        "{e}"
    );
    let rec = estimates(&m, EstimateSpec::default());
    let e = select_modes(&m.geometry, &frf.select_excitations(&[0, 1]), &rec, &opts)
        .unwrap_err()
        .to_string();
    assert!(e.contains("2 excitations, the geometry 5"), "{e}");
    let e = select_modes(
        &m.geometry,
        &frf,
        &rec,
        &SelectOptions {
            mac_threshold: 1.5,
            ..Default::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("mac_threshold"), "{e}");
    let empty = rbprops_core::records::ModalFitRecord::default();
    assert!(matches!(
        select_modes(&m.geometry, &frf, &empty, &opts),
        Err(NiError::NoModes { .. })
    ));
}

#[test]
fn output_serialises_without_nan() {
    let m = test_case_one();
    let rec = estimates(&m, EstimateSpec::default());
    let out = run(&m, &rec, &SelectOptions::default());
    let json = serde_json::to_string(&out).unwrap();
    let back: SelectionOutput = serde_json::from_str(&json).unwrap();
    assert_eq!(back.record, out.record);
    for s in &out.record.selected {
        assert!(s.ni_db.is_finite() && s.margin_db.is_finite() && s.strength.is_finite());
    }
}

#[test]
fn selection_does_not_depend_on_the_frf_quantity() {
    // NI compares excitations at the same frequency, where the factor −ω² between
    // receptance and accelerance is common to all: same choices, NI shifted by 40 log10 ω.
    let m = test_case_one();
    let rec = estimates(&m, EstimateSpec::default());
    let hz = axis(0.1, 1.5, 0.0005);
    let rcp = frfs(&m, &hz);
    let acc = rcp
        .to_quantity(rbprops_core::Quantity::Accelerance)
        .unwrap();
    let opts = SelectOptions::default();
    let a = select_modes(&m.geometry, &rcp, &rec, &opts).unwrap();
    let b = select_modes(&m.geometry, &acc, &rec, &opts).unwrap();
    assert_eq!(a.record.selected.len(), b.record.selected.len());
    for (x, y) in a.record.selected.iter().zip(&b.record.selected) {
        assert_eq!(
            (x.mode, &x.excitation, &x.runner_up),
            (y.mode, &y.excitation, &y.runner_up)
        );
        assert!(
            (x.margin_db - y.margin_db).abs() < 0.05,
            "{} vs {}",
            x.margin_db,
            y.margin_db
        );
        let w = 2.0 * std::f64::consts::PI * x.frequency_hz;
        assert!((y.ni_db - x.ni_db - 40.0 * w.log10()).abs() < 0.1);
    }
    // The MIFs use the receptance phase, so they are identical.
    for (x, y) in a.curves.excitations.iter().zip(&b.curves.excitations) {
        for (p, q) in x.hybrid_mif.iter().zip(&y.hybrid_mif) {
            assert!((p - q).abs() < 1e-9);
        }
    }
}

#[test]
fn principal_responses_count_the_excited_modes() {
    let m = test_case_one();
    let rec = estimates(&m, EstimateSpec::default());
    let opts = SelectOptions {
        principal_response_curves: true,
        ..Default::default()
    };
    let out = run(&m, &rec, &opts);
    let rank = |ex: &str| {
        out.curves
            .excitations
            .iter()
            .find(|c| c.excitation == ex)
            .unwrap()
            .prf_rank
    };
    // Set-up A (noise-free, decoupled): as many significant PRFs as modes with non-zero
    // participation; B couples everything and F2y drives all six.
    assert_eq!((rank("F0x"), rank("F0y"), rank("F0z")), (2, 2, 3));
    assert_eq!(rank("F2y"), 6);
    for c in &out.curves.excitations {
        assert_eq!(c.prf_db.len(), c.prf_rank);
    }
    // Without the curves: the same selection and indicators, no principal responses.
    let lean = run(&m, &rec, &SelectOptions::default());
    assert_eq!(lean.record, out.record);
    for (a, b) in lean.curves.excitations.iter().zip(&out.curves.excitations) {
        assert!(a.prf_db.is_empty());
        assert_eq!(
            (&a.ni_db, &a.prf_mif, a.prf_rank),
            (&b.ni_db, &b.prf_mif, b.prf_rank)
        );
    }
}
