//! Spec builders and a comparison shared by the simulator's tests.

use rbprops_core::c64;
use rbprops_sim::spec::EffectSpec;
use rbprops_sim::{example, CampaignSpec};

/// The bundled example campaign `name` as a spec.
pub fn spec(name: &str) -> CampaignSpec {
    CampaignSpec::from_toml_str(example(name).unwrap()).unwrap()
}

/// The bundled Test Case II campaign.
pub fn tc2() -> CampaignSpec {
    spec("test-case-2")
}

/// `s` with one more `[[effect]]`, given as the TOML table's body.
pub fn with_effect(mut s: CampaignSpec, table: &str) -> CampaignSpec {
    let e: EffectSpec = toml::from_str(table).unwrap();
    s.effects.push(e);
    s
}

/// The largest deviation of `a` from `b`, relative to the largest |b|.
pub fn max_dev(a: &[c64], b: &[c64]) -> f64 {
    let scale = b.iter().map(|x| x.norm()).fold(0.0, f64::max);
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).norm())
        .fold(0.0, f64::max)
        / scale
}
