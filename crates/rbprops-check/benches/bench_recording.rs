//! The model-check speed bench's recordings (`fixtures/model-check/bench/`: made by the
//! independent reference generator `scripts/refgen`, not by rbprops-sim) and their
//! nominal spec (`fixtures/model-check/nominal.toml`). Shared by the bench and the
//! determinism test.

use rbprops_core::{FrfSet, Geometry};
use rbprops_sim::CampaignSpec;
use std::path::PathBuf;

/// The bench cases: recording file stem and the effects concealed in it (as the
/// check's candidate ids; the generator's case files in `scripts/refgen/examples/`
/// `bench-<stem>.toml`).
pub const CASES: [(&str, &[&str]); 3] = [
    (
        "gain-orient-gauge",
        &["channel_gain", "sensor_misorientation", "force_gauge_mass"],
    ),
    (
        "position-force-elastic",
        &["sensor_position", "force_direction", "elastic_mode"],
    ),
    (
        "gravity-window-gain",
        &["gravity_stiffness", "exponential_window", "channel_gain"],
    ),
];

pub fn fixtures() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/model-check")
}

/// The nominal spec the recordings are checked against.
pub fn nominal() -> CampaignSpec {
    let p = fixtures().join("nominal.toml");
    let text = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    CampaignSpec::from_toml_str(&text).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// A bench recording (UFF 58b, single precision) as geometry and FRFs.
pub fn recording(stem: &str) -> (Geometry, FrfSet) {
    let p = fixtures().join("bench").join(format!("{stem}.uff"));
    let bytes = std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    let name = p.display().to_string();
    let uff = rbprops_uff::parse(&bytes, &name).unwrap_or_else(|e| panic!("{name}: {e}"));
    rbprops_uff::to_campaign(&uff).unwrap_or_else(|e| panic!("{name}: {e}"))
}
