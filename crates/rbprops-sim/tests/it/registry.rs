//! The effect registry is the one list of the physics catalogue: the spec validation,
//! the gravity direction, the effect examples and docs/physics.md all follow it.

use crate::common::tc2;
use rbprops_sim::effects::{parse_effect, registry, EffectDescriptor, NeutralForm};
use rbprops_sim::spec::EffectSpec;
use rbprops_sim::{simulate, CampaignSpec};

/// The row of docs/physics.md's "Effect ids" table for an effect.
fn docs_row(d: &EffectDescriptor) -> String {
    format!("| `{}` | {} |", d.id, d.docs)
}

#[test]
fn ranks_number_the_catalogue_and_ids_are_unique_snake_case() {
    let reg = registry();
    let ranks: Vec<u16> = reg.iter().map(|d| d.rank).collect();
    let expect: Vec<u16> = (0..reg.len() as u16).collect();
    assert_eq!(ranks, expect, "ranks must be 0..n, each once");
    for (i, d) in reg.iter().enumerate() {
        assert!(
            !d.id.is_empty()
                && d.id
                    .chars()
                    .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_'),
            "{}",
            d.id
        );
        assert!(reg[..i].iter().all(|e| e.id != d.id), "{} twice", d.id);
        for (what, text) in [("title", d.title), ("reveal", d.reveal), ("docs", d.docs)] {
            assert!(!text.trim().is_empty(), "{}: empty {what}", d.id);
        }
    }
    assert_eq!(
        *rbprops_sim::effects::KNOWN_EFFECTS,
        reg.iter().map(|d| d.id).collect::<Vec<_>>()
    );
}

/// docs/physics.md lists every id with its registry line, and no id the registry lacks.
#[test]
fn physics_docs_list_every_effect_with_its_line() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/physics.md");
    let text = std::fs::read_to_string(path).unwrap();
    let missing: Vec<String> = registry()
        .iter()
        .map(|d| docs_row(d))
        .filter(|row| !text.lines().any(|l| l == row))
        .collect();
    assert!(
        missing.is_empty(),
        "docs/physics.md lacks these rows of its \"Effect ids\" table:\n{}",
        missing.join("\n")
    );
    let section = text
        .split("## Effect ids")
        .nth(1)
        .expect("an \"Effect ids\" section");
    let listed: Vec<&str> = section
        .lines()
        .take_while(|l| !l.starts_with('#'))
        .filter_map(|l| l.strip_prefix("| `"))
        .filter_map(|l| l.split('`').next())
        .collect();
    let ids: Vec<&str> = registry().iter().map(|d| d.id).collect();
    assert_eq!(listed, ids, "the table's ids, in catalogue order");
}

/// The unknown-id error names every effect of the registry, in its order.
#[test]
fn spec_validation_reads_the_registry() {
    let e = parse_effect(&EffectSpec {
        id: "no_such_effect".into(),
        parameters: toml::Table::new(),
    })
    .unwrap_err();
    let ids: Vec<&str> = registry().iter().map(|d| d.id).collect();
    assert!(e.ends_with(&format!("(known: {})", ids.join(", "))), "{e}");
    for d in registry() {
        let spec = CampaignSpec::from_toml_str(d.example).unwrap();
        spec.validate()
            .unwrap_or_else(|e| panic!("{}: example does not validate: {e}", d.id));
        assert_eq!(spec.effects.len(), 1, "{}", d.id);
        assert_eq!(spec.effects[0].id, d.id);
        let effect = (d.parse)(&spec.effects[0]).unwrap();
        assert_eq!(effect.id(), d.id);
    }
}

/// Every neutral table parses and leaves the simulated FRFs as they are (to roundoff):
/// "absent" really is absent. The ids without one are exactly those the model check
/// screens through its own forms.
#[test]
fn neutral_tables_parse_and_change_nothing() {
    let mut s = tc2();
    s.noise.relative = 0.0;
    s.noise.floor = 0.0;
    s.frequency.lines = 201;
    let g = s.geometry().unwrap();
    let nominal = simulate(&s).unwrap();
    let scale = nominal
        .frf
        .values
        .iter()
        .map(|v| v.norm())
        .fold(0.0, f64::max);
    let mut reparametrised = Vec::new();
    for d in registry() {
        let NeutralForm::Table(build) = d.neutral else {
            reparametrised.push(d.id);
            continue;
        };
        let entry = EffectSpec {
            id: d.id.into(),
            parameters: build(&s, &g),
        };
        let e = parse_effect(&entry).unwrap_or_else(|e| panic!("{}: {e}", d.id));
        assert!(!e.values().is_empty(), "{}: nothing to fit", d.id);
        let mut with = s.clone();
        with.effects.push(entry);
        let out = simulate(&with).unwrap_or_else(|e| panic!("{}: {e}", d.id));
        let worst = out
            .frf
            .values
            .iter()
            .zip(&nominal.frf.values)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        // Roundoff of a solve at 1e-16 relative, times the model's condition.
        assert!(
            worst <= 1e-10 * scale,
            "{}: neutral moves the FRFs by {worst:e}",
            d.id
        );
    }
    assert_eq!(
        reparametrised,
        [
            "gravity_stiffness",
            "elastic_mode",
            "record_truncation",
            "transducer_highpass",
            "cord_mass",
            "added_mass",
            "residual_flexibility"
        ]
    );
}

/// The gravity effects take the spec's `up`; the others refuse it as unknown.
#[test]
fn gravity_effects_follow_the_spec_up() {
    let up: Vec<&str> = registry()
        .iter()
        .filter(|d| d.follows_spec_up)
        .map(|d| d.id)
        .collect();
    assert_eq!(
        up,
        ["gravity_stiffness", "sensor_tilt_gravity", "cord_mass"]
    );
    let mut s = tc2();
    s.up = Some([0.0, 1.0, 0.0]);
    let e = rbprops_sim::effects::parse_effect_in(
        &EffectSpec {
            id: "sensor_tilt_gravity".into(),
            parameters: toml::Table::new(),
        },
        &s,
    )
    .unwrap();
    assert_eq!(
        e.parameters_json()["up"],
        serde_json::json!([0.0, 1.0, 0.0])
    );
}

/// The effect examples are `nominal` then the registry, in its order.
#[test]
fn effect_examples_follow_the_registry() {
    let ids: Vec<&str> = rbprops_sim::effect_examples()
        .iter()
        .map(|(id, _)| *id)
        .collect();
    let mut expect = vec!["nominal"];
    expect.extend(registry().iter().map(|d| d.id));
    assert_eq!(ids, expect);
}

/// Every effect's example campaign (a real test's magnitudes) lies inside the effect's
/// plausible ranges, and values a tester would reject fall outside them.
#[test]
fn effect_examples_are_plausible_and_gross_values_are_not() {
    for d in registry() {
        let spec = rbprops_sim::CampaignSpec::from_toml_str(d.example).unwrap();
        for e in spec.effects.iter().filter(|e| e.id == d.id) {
            for q in rbprops_sim::effects::plausibility(e, &spec).unwrap() {
                assert!(q.holds(), "{}: example's {q:?} outside its range", d.id);
            }
        }
    }
    let spec = rbprops_sim::CampaignSpec::from_toml_str(
        registry()
            .iter()
            .find(|d| d.id == "sensor_misorientation")
            .unwrap()
            .example,
    )
    .unwrap();
    let entry = |id: &str, toml: &str| rbprops_sim::spec::EffectSpec {
        id: id.into(),
        parameters: toml::from_str(toml).unwrap(),
    };
    for (id, toml) in [
        ("sensor_misorientation", "rotations_rad = { \"2\" = [0.3, 0.0, 0.0] }"),
        ("channel_gain", "gains = { 1x = 0.5 }"),
        ("force_gauge_mass", "masses_kg = { force1 = 0.5 }"),
        (
            "elastic_mode",
            "frequency_hz = 0.5\ndamping_ratio = 0.02\nchannels = { 1x = 0.1 }\nexcitations = { force1 = 0.1 }",
        ),
    ] {
        let q = rbprops_sim::effects::plausibility(&entry(id, toml), &spec).unwrap();
        assert!(q.iter().any(|q| !q.holds()), "{id}: {q:?}");
    }
}

/// Every screening form ([`NeutralForm::Screened`]) builds on Test Case II, in a distinct
/// place of the screened order, for the effect it belongs to; at its neutral values it
/// leaves the FRFs as they are (to roundoff), and a parameter moved off neutral by ten
/// of its scales changes them (but for the profiles', absent at neutral to every order,
/// moved to their first profile point instead), so "absent" is absent and the form acts.
#[test]
fn screening_forms_are_neutral_at_their_neutral_values() {
    use rbprops_sim::effects::screening::ScreeningKind;
    let (s, g, freq) = quiet_tc2();
    let frfs =
        |effects: &[Box<dyn rbprops_sim::effects::Effect>]| predicted(&s, &g, &freq, effects);
    let nominal = frfs(&[]);
    let scale = nominal.iter().map(|v| v.norm()).fold(0.0, f64::max);
    let mut ranks = Vec::new();
    for d in registry() {
        let NeutralForm::Screened(screened) = d.neutral else {
            continue;
        };
        ranks.push(screened.rank);
        let Some(form) = (screened.form)(&s, &g).unwrap_or_else(|n| panic!("{}: {n}", d.id)) else {
            panic!("{}: no form for Test Case II", d.id);
        };
        assert_eq!(form.effect.id(), d.id);
        assert_eq!(form.effect.values(), form.neutral, "{}", d.id);
        assert_eq!(form.scales.len(), form.neutral.len(), "{}", d.id);
        let at = |v: &[f64]| frfs(&[form.effect.with_values(v).unwrap()]);
        let off = |v: &[f64]| {
            at(v)
                .iter()
                .zip(&nominal)
                .map(|(a, b)| (a - b).norm())
                .fold(0.0, f64::max)
        };
        assert!(
            off(&form.neutral) <= 1e-10 * scale,
            "{}: neutral is not absent",
            d.id
        );
        let moved = match &form.screening {
            ScreeningKind::Profile { grid, .. } => grid[0].clone(),
            ScreeningKind::Score | ScreeningKind::Resonance => {
                // A parameter with a first-order signature: the first of a score's, a
                // residue of the resonance's (its pole has none while they are zero).
                let mut v = form.neutral.clone();
                let j = match form.screening {
                    ScreeningKind::Resonance => v.len() - 1,
                    _ => 0,
                };
                v[j] += 10.0 * form.scales[j];
                v
            }
        };
        assert!(
            off(&moved) > 1e-6 * scale,
            "{}: moved off neutral, no change",
            d.id
        );
    }
    let mut sorted = ranks.clone();
    sorted.sort();
    sorted.dedup();
    assert_eq!(
        sorted.len(),
        ranks.len(),
        "screened ranks repeat: {ranks:?}"
    );
}

/// The improved spec is the model the check fitted: gravity's screening form on Test
/// Case II's three-axis springs, at a cord length and with the springs turned with the
/// sagged body (φ₅, the refgen bench's spring set-up fits φ₅ = 1 and 1/ℓ → 0), written as
/// its catalogue entry (`Effect::spec_entry`: `cord_length_m`, `spring_turn_fraction`)
/// and parsed back, predicts the same FRFs to 1e-9 of their largest value (both build the
/// same stiffness, summed in another order). Before `spring_turn_fraction` the entry
/// dropped φ₅ and the bench's improved spec re-simulated at χ²/ν 14.1 for the check's 0.995.
#[test]
fn gravity_form_on_springs_is_its_spec_entry() {
    let (s, g, freq) = quiet_tc2();
    let frfs =
        |effects: &[Box<dyn rbprops_sim::effects::Effect>]| predicted(&s, &g, &freq, effects);
    let form = rbprops_sim::effects::screening_form("gravity_stiffness", &s, &g)
        .unwrap()
        .expect("a form on springs");
    let names: Vec<String> = form
        .effect
        .parameters()
        .into_iter()
        .map(|p| p.name)
        .collect();
    let at = |name: &str| {
        names
            .iter()
            .position(|n| n == name)
            .unwrap_or_else(|| panic!("{name} in {names:?}"))
    };
    let nominal = frfs(&[]);
    for (inverse_length, turn) in [(1.0 / 1.3, 0.0), (1.0 / 1.3, 1.0), (1e-4, 1.0), (0.5, 0.4)] {
        let mut phi = form.neutral.clone();
        phi[at("inverse_cord_length_per_m")] = inverse_length;
        phi[at("load_term_factor")] = 1.0;
        phi[at("spring_turn_fraction")] = turn;
        let fitted = form.effect.with_values(&phi).unwrap();
        let entry = fitted.spec_entry(&s).unwrap();
        assert_eq!(
            entry.parameters.contains_key("spring_turn_fraction"),
            turn != 0.0,
            "{entry:?}"
        );
        let catalogue = rbprops_sim::effects::parse_effect(&entry).unwrap();
        let (a, b) = (frfs(&[fitted]), frfs(&[catalogue]));
        let scale = a.iter().map(|v| v.norm()).fold(0.0, f64::max);
        let err = a
            .iter()
            .zip(&b)
            .map(|(x, y)| (x - y).norm())
            .fold(0.0, f64::max);
        assert!(
            err <= 1e-9 * scale,
            "1/ℓ {inverse_length}, turn {turn}: {err:e} of {scale:e}"
        );
        let moved = a
            .iter()
            .zip(&nominal)
            .map(|(x, y)| (x - y).norm())
            .fold(0.0, f64::max);
        assert!(
            moved > 1e-4 * scale,
            "1/ℓ {inverse_length}, turn {turn}: gravity acts"
        );
    }
}

/// Test Case II without noise on 201 lines, its geometry and its lines above 0 Hz.
fn quiet_tc2() -> (CampaignSpec, rbprops_core::Geometry, Vec<f64>) {
    let mut s = tc2();
    s.noise.relative = 0.0;
    s.noise.floor = 0.0;
    s.frequency.lines = 201;
    let g = s.geometry().unwrap();
    let freq = s
        .frequency_axis()
        .into_iter()
        .filter(|&f| f > 0.0)
        .collect();
    (s, g, freq)
}

/// The FRF values `effects` give on `s` at the lines `freq`.
fn predicted(
    s: &CampaignSpec,
    g: &rbprops_core::Geometry,
    freq: &[f64],
    effects: &[Box<dyn rbprops_sim::effects::Effect>],
) -> Vec<rbprops_core::c64> {
    rbprops_sim::predict(s, g, effects, freq, &Default::default())
        .unwrap()
        .0
        .values
}
