//! The model-check speed bench's recordings (`fixtures/model-check/bench/`: made by the
//! independent reference generator `scripts/refgen`, not by rbprops-sim) and their
//! nominal specs (`fixtures/model-check/nominal.toml`, and `bench/nominal-6.toml` for the
//! six-hit case). Shared by the bench and the determinism test.

use rbprops_core::{FrfSet, Geometry};
use rbprops_sim::CampaignSpec;
use std::path::PathBuf;

/// The bench cases: recording file stem and the effects concealed in it (as the
/// check's candidate ids; the generator's case files in `scripts/refgen/examples/`
/// `bench-<stem>.toml`).
pub const CASES: [(&str, &[&str]); 4] = [
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
    // Six hits, six effects at once (issue 37's worst case; checked against
    // `bench/nominal-6.toml`): the dashpots read as the general viscous damping.
    (
        "six-effects",
        &[
            "nonproportional_damping",
            "sensor_misorientation",
            "sensor_position",
            "force_direction",
            "force_gauge_mass",
            "exponential_window",
        ],
    ),
];

pub fn fixtures() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/model-check")
}

/// The nominal spec the three-hit recordings are checked against.
pub fn nominal() -> CampaignSpec {
    spec_file(fixtures().join("nominal.toml"))
}

/// The nominal spec a bench recording is checked against.
#[allow(dead_code)] // the bench's; the tests that share this file use the three-hit cases
pub fn nominal_for(stem: &str) -> CampaignSpec {
    match stem {
        "six-effects" => spec_file(fixtures().join("bench").join("nominal-6.toml")),
        _ => nominal(),
    }
}

fn spec_file(p: PathBuf) -> CampaignSpec {
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
