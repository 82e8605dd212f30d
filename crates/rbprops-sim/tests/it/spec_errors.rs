//! Every bad-spec path gives an error that names where and what.

use proptest::prelude::*;
use rbprops_sim::{example, simulate, CampaignSpec, SpecError};

fn base() -> String {
    example("test-case-2").unwrap().to_string()
}

/// Replaces `from` (which must occur) by `to` in the base spec and returns the error text.
fn err_after(from: &str, to: &str) -> String {
    let b = base();
    assert!(b.contains(from), "base spec lacks {from:?}");
    let text = b.replacen(from, to, 1);
    match CampaignSpec::from_toml_str(&text) {
        Ok(_) => panic!("spec with {from:?} → {to:?} was accepted"),
        Err(e) => e.to_string(),
    }
}

fn assert_has(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "error {msg:?} lacks {p:?}");
    }
}

#[test]
fn malformed_toml_reports_line() {
    let e = err_after("lines = 1601", "lines = = 1601");
    let line = base().lines().position(|l| l == "lines = 1601").unwrap() + 1;
    assert_has(&e, &[&format!("line {line}"), "lines = = 1601"]);
    let e = CampaignSpec::from_toml_bytes(&[b'n', 0xff, 0xfe]).unwrap_err();
    assert!(matches!(e, SpecError::Toml(_)));
    assert_has(&e.to_string(), &["UTF-8"]);
}

#[test]
fn unknown_keys_and_wrong_types_are_rejected() {
    assert_has(
        &err_after("seed = 2", "seed = 2\ncolour = \"red\""),
        &["unknown field", "colour"],
    );
    assert_has(
        &err_after("kind = \"triaxial\"", "kind = \"triaxial\"\nmass_g = 5"),
        &["unknown field", "mass_g"],
    );
    assert_has(&err_after("lines = 1601", "lines = \"many\""), &["lines"]);
    assert_has(
        &err_after("kind = \"triaxial\"", "kind = \"biaxial\""),
        &["biaxial"],
    );
}

#[test]
fn unknown_quantity() {
    assert_has(
        &err_after("quantity = \"accelerance\"", "quantity = \"furlongs\""),
        &["furlongs", "receptance"],
    );
}

#[test]
fn non_unit_zero_and_non_finite_directions() {
    assert_has(
        &err_after(
            "direction = [-1.0, 0.0, 0.0]",
            "direction = [-1.0, 1.0, 0.0]",
        ),
        &["excitation[0].direction", "not a unit vector", "1.414"],
    );
    assert_has(
        &err_after("direction = [0.0, 1.0, 0.0]", "direction = [0.0, 0.0, 0.0]"),
        &["excitation[1].direction", "|d| = 0"],
    );
    assert_has(
        &err_after(
            "direction = [0.0, 0.0, -1.0]",
            "direction = [0.0, nan, -1.0]",
        ),
        &["excitation[2].direction", "not finite"],
    );
    let e = err_after(
        "id = \"3\"\nat_m = [0.13810, -0.05568, -0.13278]\nkind = \"triaxial\"",
        "id = \"3\"\nat_m = [0.13810, -0.05568, -0.13278]\nkind = \"triaxial\"\n\n[[sensor]]\nid = \"u\"\nat_m = [0.0, 0.0, 0.0]\nkind = \"uniaxial\"\ndirection = [1.0, 1.0, 0.0]",
    );
    assert_has(&e, &["sensor[3].direction: not a unit vector (|d| = 1.41"]);
    let e = err_after(
        "kind = \"triaxial\"",
        "kind = \"triaxial\"\naxes = [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]",
    );
    assert_has(&e, &["sensor[0].axes", "coplanar"]);
    let e = err_after("kind = \"triaxial\"", "kind = \"uniaxial\"");
    assert_has(&e, &["sensor[0].direction: missing"]);
}

#[test]
fn nan_and_inf_values() {
    assert_has(
        &err_after("mass_kg = 15.69", "mass_kg = nan"),
        &["body.mass_kg", "NaN"],
    );
    assert_has(
        &err_after("com_m = [0.17725", "com_m = [inf"),
        &["body.com_m", "inf"],
    );
    assert_has(
        &err_after("stop_hz = 12.5", "stop_hz = inf"),
        &["frequency.stop_hz"],
    );
    assert_has(
        &err_after("at_m = [0.0, 0.0, 0.0]", "at_m = [0.0, -inf, 0.0]"),
        &["sensor[0].at_m"],
    );
    assert_has(
        &err_after("relative = 0.0", "relative = nan"),
        &["noise.relative"],
    );
}

#[test]
fn too_few_or_collinear_triaxial_points() {
    let b = base();
    let cut = b.find("[[sensor]]\nid = \"3\"").unwrap();
    let end = cut + b[cut..].find("[[excitation]]").unwrap();
    let two = format!("{}{}", &b[..cut], &b[end..]);
    let e = CampaignSpec::from_toml_str(&two).unwrap_err().to_string();
    assert_has(
        &e,
        &["sensor", "three non-collinear triaxial points", "has 2"],
    );
    let e = err_after(
        "at_m = [0.13810, -0.05568, -0.13278]",
        "at_m = [0.2036, 0.42964, 0.111438]",
    );
    assert_has(&e, &["sensor", "collinear"]);
}

#[test]
fn missing_setup_and_bad_ids() {
    let e = err_after(
        "direction = [0.0, 1.0, 0.0]\nsetup = \"A\"",
        "direction = [0.0, 1.0, 0.0]\nsetup = \"C\"",
    );
    assert_has(
        &e,
        &[
            "excitation[1].setup",
            "excitation 'force2': set-up 'C' is not defined",
        ],
    );
    assert_has(
        &err_after("id = \"force2\"", "id = \"force1\""),
        &["excitation[1].id", "'force1' is used twice"],
    );
    assert_has(
        &err_after("id = \"2\"", "id = \"1\""),
        &["sensor[1].id", "used twice"],
    );
}

#[test]
fn bad_mass_and_inertia() {
    assert_has(
        &err_after("mass_kg = 15.69", "mass_kg = 0.0"),
        &["body.mass_kg", "positive"],
    );
    assert_has(
        &err_after("mass_kg = 15.69", "mass_kg = -3"),
        &["body.mass_kg", "positive"],
    );
    // Triangle inequality: Jzz > Jxx + Jyy.
    assert_has(
        &err_after("0.31706832]", "0.9]"),
        &["body", "triangle inequality Jxx + Jyy ≥ Jzz"],
    );
    // Products so large the tensor is indefinite.
    assert_has(
        &err_after("xy = 0.07722671", "xy = 0.5"),
        &["body", "not positive definite"],
    );
    let e = err_after(
        "moments_kg_m2 = [0.35733194, 0.39469014, 0.31706832]\nproducts_kg_m2 = { xy = 0.07722671, xz = -0.08736156, yz = -0.06919817 }",
        "inertia_cm_kg_m2 = [[0.3, 0.01, 0.0], [0.02, 0.3, 0.0], [0.0, 0.0, 0.3]]",
    );
    assert_has(&e, &["body.inertia_cm_kg_m2", "not symmetric"]);
    let e = err_after(
        "products_kg_m2",
        "inertia_cm_kg_m2 = [[0.3, 0.0, 0.0], [0.0, 0.3, 0.0], [0.0, 0.0, 0.3]]\nproducts_kg_m2",
    );
    assert_has(&e, &["body", "not both"]);
    assert_has(
        &err_after("products_kg_m2 = {", "#products_kg_m2 = {"),
        &["body.products_kg_m2", "missing"],
    );
}

#[test]
fn bad_suspensions() {
    // Only vertical springs: x, y and yaw are free, which is a valid suspension (three
    // zero-frequency modes, see tests/cords.rs).
    let b = base().replace(
        "stiffness_n_per_m = [150.0, 220.0, 2500.0]",
        "stiffness_n_per_m = [0.0, 0.0, 2500.0]",
    );
    CampaignSpec::from_toml_str(&b).unwrap();
    assert_has(
        &err_after(
            "stiffness_n_per_m = [150.0, 220.0, 2500.0]",
            "stiffness_n_per_m = [150.0, -220.0, 2500.0]",
        ),
        &["setup[0].spring[0].stiffness_n_per_m", "negative"],
    );
    assert_has(
        &err_after(
            "stiffness_n_per_m = [150.0, 220.0, 2500.0]",
            "stiffness_matrix_n_per_m = [[100.0, 200.0, 0.0], [200.0, 100.0, 0.0], [0.0, 0.0, 10.0]]",
        ),
        &["setup[0].spring[0].stiffness_matrix_n_per_m", "not positive semi-definite"],
    );
    assert_has(
        &err_after("stiffness_n_per_m = [150.0, 220.0, 2500.0]", "stiffness_n_per_m = [150.0, 220.0, 2500.0]\nstiffness_matrix_n_per_m = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]"),
        &["setup[0].spring[0]", "exactly one"],
    );
}

#[test]
fn bad_frequency_damping_noise_and_effects() {
    assert_has(
        &err_after("stop_hz = 12.5", "stop_hz = 0.0"),
        &["frequency.stop_hz", "above start_hz"],
    );
    assert_has(
        &err_after("lines = 1601", "lines = 1"),
        &["frequency.lines"],
    );
    assert_has(
        &err_after("start_hz = 0.0", "start_hz = -1.0"),
        &["frequency.start_hz"],
    );
    assert_has(
        &err_after("ratio = 0.015", "ratios = [0.01, 0.01]"),
        &["damping.ratios", "needs 6"],
    );
    assert_has(
        &err_after("ratio = 0.015", "ratio = 1.5"),
        &["damping.ratio", "[0, 1)"],
    );
    assert_has(
        &err_after("ratio = 0.015", "ratio = 0.015\nalpha = 0.1"),
        &["damping", "not alpha/beta"],
    );
    assert_has(
        &err_after(
            "model = \"modal\"\nratio = 0.015",
            "model = \"proportional\"",
        ),
        &["damping", "alpha and/or beta"],
    );
    assert_has(&err_after("floor = 0.0", "floor = -1e-6"), &["noise.floor"]);
    assert_has(
        &err_after(
            "[damping]",
            "[[effect]]\nid = \"moon_gravity\"\n\n[damping]",
        ),
        &["effect[0]", "unknown effect id 'moon_gravity'"],
    );
}

#[test]
fn all_problems_are_listed_together() {
    let b = base()
        .replace("mass_kg = 15.69", "mass_kg = -1")
        .replace("lines = 1601", "lines = 0");
    let e = CampaignSpec::from_toml_str(&b).unwrap_err();
    assert_eq!(e.issues().len(), 2, "{e}");
}

#[test]
fn simulate_rechecks_a_programmatic_spec() {
    let mut s = CampaignSpec::from_toml_str(&base()).unwrap();
    s.body.mass_kg = f64::NAN;
    let e = simulate(&s).unwrap_err().to_string();
    assert_has(&e, &["body.mass_kg"]);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    #[test]
    fn parser_never_panics_on_strings(s in ".{0,400}") {
        let _ = CampaignSpec::from_toml_str(&s);
    }

    #[test]
    fn parser_never_panics_on_bytes(b in proptest::collection::vec(any::<u8>(), 0..400)) {
        let _ = CampaignSpec::from_toml_bytes(&b);
    }

    /// Damaged versions of a valid spec (a span deleted or a byte changed) give a result
    /// or an error, never a panic.
    #[test]
    fn parser_never_panics_on_damaged_specs(start in 0usize..3000, len in 0usize..40, byte in any::<u8>()) {
        let b = base().into_bytes();
        let start = start.min(b.len());
        let end = (start + len).min(b.len());
        let mut cut = b[..start].to_vec();
        cut.extend_from_slice(&b[end..]);
        let _ = CampaignSpec::from_toml_bytes(&cut);
        let mut changed = b.clone();
        if start < changed.len() { changed[start] = byte; }
        let _ = CampaignSpec::from_toml_bytes(&changed);
    }
}
