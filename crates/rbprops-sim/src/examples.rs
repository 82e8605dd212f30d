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

/// The effect fixtures (`fixtures/specs/effects/<id>.toml`): test-case-2 with one effect
/// on and 1 % noise, plus `nominal` without any. Pairs of (effect id or `nominal`, TOML
/// text): `nominal` first, then every effect of the catalogue in its order
/// ([`crate::effects::registry`], [`crate::effects::EffectDescriptor::example`]).
pub fn effect_examples() -> &'static [(&'static str, &'static str)] {
    static EXAMPLES: std::sync::OnceLock<Vec<(&'static str, &'static str)>> =
        std::sync::OnceLock::new();
    EXAMPLES.get_or_init(|| {
        let nominal = include_str!("../../../fixtures/specs/effects/nominal.toml");
        std::iter::once(("nominal", nominal))
            .chain(crate::effects::registry().iter().map(|d| (d.id, d.example)))
            .collect()
    })
}
