//! The model check's candidate list comes from rbprops-sim's effect registry: every
//! catalogue effect is screened (or a note says why not), at its registry title, in the
//! registry's order.

use rbprops_check::candidates::{candidates, describe, Screening, FURTHER_INSTANCES};
use rbprops_sim::effects::{registry, NeutralForm};
use rbprops_sim::{example, CampaignSpec};

fn tc2() -> CampaignSpec {
    CampaignSpec::from_toml_str(example("test-case-2").unwrap()).unwrap()
}

#[test]
fn candidates_follow_the_registry() {
    let spec = tc2();
    let g = spec.geometry().unwrap();
    let (cands, notes) = candidates(&spec, &g);
    for d in registry() {
        assert_eq!(describe(d.id), (d.title, d.reveal), "{}", d.id);
        let screened = cands.iter().find(|c| c.id == d.id);
        match screened {
            Some(c) => {
                assert_eq!(c.title, d.title, "{}", d.id);
                assert_eq!(c.reveal, d.reveal, "{}", d.id);
                assert_eq!(c.neutral, c.effect.values(), "{}", d.id);
            }
            None => assert!(
                notes.iter().any(|n| n.contains(d.id)),
                "{} is neither a candidate nor in a note: {notes:?}",
                d.id
            ),
        }
    }
    // The score-tested catalogue forms come first, in registry order.
    let scored: Vec<&str> = registry()
        .iter()
        .filter(|d| matches!(d.neutral, NeutralForm::Table(_)))
        .map(|d| d.id)
        .collect();
    let first: Vec<&str> = cands[..scored.len()]
        .iter()
        .map(|c| c.id.as_str())
        .collect();
    assert_eq!(first, scored);
    assert!(cands[..scored.len()]
        .iter()
        .all(|c| c.source == "rbprops-sim" && c.screening == Screening::Score));
    // The one local candidate the catalogue lacks (and its further instances).
    let local: Vec<&str> = cands
        .iter()
        .filter(|c| c.source == "rbprops-check (local)" && c.follows.is_none())
        .map(|c| c.id.as_str())
        .collect();
    assert_eq!(local, ["residual_flexibility"]);
    // Repeatable physics: each further instance follows the one before it, at the same
    // neutral point and screened the same way as the first.
    for first in ["elastic_mode", "residual_flexibility"] {
        let f = cands.iter().find(|c| c.id == first).expect(first);
        let mut prev = first.to_string();
        for k in 2..=1 + FURTHER_INSTANCES {
            let id = format!("{first}_{k}");
            let c = cands.iter().find(|c| c.id == id).expect(&id);
            assert_eq!(c.follows.as_deref(), Some(prev.as_str()), "{id}");
            assert_eq!(c.neutral, f.neutral, "{id}");
            assert_eq!(c.screening, f.screening, "{id}");
            assert_eq!(c.effect.id(), f.effect.id(), "{id}");
            prev = id;
        }
    }
    assert_eq!(
        cands.iter().filter(|c| c.follows.is_some()).count(),
        2 * FURTHER_INSTANCES
    );
}

/// An effect the nominal spec already has is not a candidate.
#[test]
fn an_effect_of_the_spec_is_not_a_candidate() {
    let mut spec = tc2();
    let g = spec.geometry().unwrap();
    for d in registry() {
        spec.effects = CampaignSpec::from_toml_str(d.example).unwrap().effects;
        let (cands, _) = candidates(&spec, &g);
        assert!(cands.iter().all(|c| c.id != d.id), "{}", d.id);
    }
}

/// The newest catalogue effect is screened with nothing added in rbprops-check: a
/// score test from its registry neutral table, one axial stiffness per excitation at 0.
#[test]
fn stinger_axial_stiffness_is_screened_from_its_descriptor() {
    let spec = tc2();
    let g = spec.geometry().unwrap();
    let (cands, _) = candidates(&spec, &g);
    let c = cands
        .iter()
        .find(|c| c.id == "stinger_axial_stiffness")
        .expect("a candidate");
    let names: Vec<String> = c.effect.parameters().into_iter().map(|p| p.name).collect();
    assert_eq!(
        names,
        [
            "axial_n_per_m.force1",
            "axial_n_per_m.force2",
            "axial_n_per_m.force3"
        ]
    );
    assert_eq!(c.neutral, [0.0; 3]);
    assert_eq!(c.screening, Screening::Score);
    assert_eq!(c.source, "rbprops-sim");
}

/// The gravity candidate on a body hung from linear springs (Test Case II, the mass of
/// the bench recording `gravity-window-gain`): with φ = (0, 1, 0, 0, 1) (no cord
/// lateral term, the load term of the weight, the springs turning with the sagged
/// body) its stiffness is the independent generator's Hessian at the sagged
/// equilibrium (`*.truth.json`, finite-difference Hessian of the potential with finite
/// rotations, ~1e-12 relative), to 1e-10 of the largest entry (measured: 3.3e-9 N/m,
/// 3e-13 of it); the cords' reading of
/// the springs (φ₅ = 0) misses the bounce–sway coupling of the turned springs (≈ 14 and
/// 22 N/m between z and x, y), which is what this parameter is for.
#[test]
fn gravity_candidate_with_turned_springs_is_the_generators_hanging_stiffness() {
    let truth: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(
            rbprops_testkit::repo_root()
                .join("fixtures/model-check/bench/gravity-window-gain.truth.json"),
        )
        .unwrap(),
    )
    .unwrap();
    let k_truth = &truth["setups"][0]["stiffness_6x6"];
    let mut spec = tc2();
    spec.body.mass_kg = truth["properties"]["mass_kg"].as_f64().unwrap();
    let g = spec.geometry().unwrap();
    let stiffness = |phi: &[f64]| {
        let e =
            rbprops_check::candidates::screening_effect("gravity_stiffness", &spec, phi).unwrap();
        rbprops_sim::build_models(&spec, &g, &[e]).unwrap()[0]
            .model
            .stiffness
    };
    let worst = |k: &rbprops_core::Mat6| {
        let mut d: f64 = 0.0;
        for i in 0..6 {
            for j in 0..6 {
                d = d.max((k[(i, j)] - k_truth[i][j].as_f64().unwrap()).abs());
            }
        }
        d
    };
    let scale = 10_000.0; // the largest entry, the vertical spring stiffness (N/m)
    let turned = worst(&stiffness(&[0.0, 1.0, 0.0, 0.0, 1.0]));
    let cords = worst(&stiffness(&[0.0, 1.0, 0.0, 0.0, 0.0]));
    eprintln!("worst entry off: turned springs {turned:.3e} N/m, cords {cords:.3e} N/m");
    assert!(
        turned < 1e-10 * scale,
        "turned springs: worst entry off by {turned:.3e}"
    );
    assert!(
        cords > 10.0,
        "the cords' reading should miss the turn: {cords:.3e}"
    );
}
