//! Built-in campaigns. The TOML files under `fixtures/specs/` are the single source;
//! they are compiled in with `include_str!`.

const EXAMPLES: &[(&str, &str)] = &[
    (
        "test-case-1",
        include_str!("../../../fixtures/specs/test-case-1.toml"),
    ),
    (
        "test-case-2",
        include_str!("../../../fixtures/specs/test-case-2.toml"),
    ),
    ("demo", include_str!("../../../fixtures/specs/demo.toml")),
    (
        "close-modes",
        include_str!("../../../fixtures/specs/close-modes.toml"),
    ),
    (
        "missing-mode",
        include_str!("../../../fixtures/specs/missing-mode.toml"),
    ),
];

const NAMES: &[&str] = &[
    "test-case-1",
    "test-case-2",
    "demo",
    "close-modes",
    "missing-mode",
];

/// The TOML text of a built-in campaign.
pub fn example(name: &str) -> Option<&'static str> {
    EXAMPLES.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// Names of the built-in campaigns.
pub fn example_names() -> &'static [&'static str] {
    NAMES
}

const EFFECT_EXAMPLES: &[(&str, &str)] = &[
    (
        "nominal",
        include_str!("../../../fixtures/specs/effects/nominal.toml"),
    ),
    (
        "gravity_stiffness",
        include_str!("../../../fixtures/specs/effects/gravity_stiffness.toml"),
    ),
    (
        "sensor_mass",
        include_str!("../../../fixtures/specs/effects/sensor_mass.toml"),
    ),
    (
        "channel_gain",
        include_str!("../../../fixtures/specs/effects/channel_gain.toml"),
    ),
    (
        "excitation_gain",
        include_str!("../../../fixtures/specs/effects/excitation_gain.toml"),
    ),
    (
        "global_gain",
        include_str!("../../../fixtures/specs/effects/global_gain.toml"),
    ),
    (
        "sensor_misorientation",
        include_str!("../../../fixtures/specs/effects/sensor_misorientation.toml"),
    ),
    (
        "elastic_mode",
        include_str!("../../../fixtures/specs/effects/elastic_mode.toml"),
    ),
    (
        "nonproportional_damping",
        include_str!("../../../fixtures/specs/effects/nonproportional_damping.toml"),
    ),
    (
        "exponential_window",
        include_str!("../../../fixtures/specs/effects/exponential_window.toml"),
    ),
    (
        "record_truncation",
        include_str!("../../../fixtures/specs/effects/record_truncation.toml"),
    ),
    (
        "sensor_position",
        include_str!("../../../fixtures/specs/effects/sensor_position.toml"),
    ),
    (
        "force_direction",
        include_str!("../../../fixtures/specs/effects/force_direction.toml"),
    ),
    (
        "force_location",
        include_str!("../../../fixtures/specs/effects/force_location.toml"),
    ),
    (
        "force_gauge_mass",
        include_str!("../../../fixtures/specs/effects/force_gauge_mass.toml"),
    ),
    (
        "transducer_highpass",
        include_str!("../../../fixtures/specs/effects/transducer_highpass.toml"),
    ),
    (
        "sensor_tilt_gravity",
        include_str!("../../../fixtures/specs/effects/sensor_tilt_gravity.toml"),
    ),
    (
        "suspension_coupling",
        include_str!("../../../fixtures/specs/effects/suspension_coupling.toml"),
    ),
    (
        "cord_mass",
        include_str!("../../../fixtures/specs/effects/cord_mass.toml"),
    ),
    (
        "channel_delay",
        include_str!("../../../fixtures/specs/effects/channel_delay.toml"),
    ),
    (
        "suspension_drift",
        include_str!("../../../fixtures/specs/effects/suspension_drift.toml"),
    ),
    (
        "added_mass",
        include_str!("../../../fixtures/specs/effects/added_mass.toml"),
    ),
    (
        "stinger_stiffness",
        include_str!("../../../fixtures/specs/effects/stinger_stiffness.toml"),
    ),
    (
        "hysteretic_damping",
        include_str!("../../../fixtures/specs/effects/hysteretic_damping.toml"),
    ),
];

/// The effect fixtures (`fixtures/specs/effects/<id>.toml`): test-case-2 with one effect
/// on and 1 % noise, plus `nominal` without any. Pairs of (effect id or `nominal`, TOML text).
pub fn effect_examples() -> &'static [(&'static str, &'static str)] {
    EFFECT_EXAMPLES
}
