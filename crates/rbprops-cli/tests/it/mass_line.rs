//! Acceptance tests for the inertia-restraint (mass-line) estimator through the whole
//! pipeline: noise-free article whose first elastic mode is 10× the highest rigid mode,
//! band chosen automatically. Limits: m within 0.5 %, c within 1 mm, J within 2 % of ‖J‖.

use rbprops_cli::stages;
use rbprops_core::records::{InertiaEstimate, TruthRecord};
use rbprops_formats::topics;
use rbprops_inertia::{Estimator, SolveOptions};

#[test]
fn mass_line_recovers_the_article_with_an_automatic_band() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/specs/mass-line.toml"
    );
    let (mut rec, _) =
        stages::simulate(&std::fs::read_to_string(path).unwrap(), path, None).unwrap();
    // The rigid-body modes are identified in their own band; the mass line uses all lines.
    let fit = rbprops_modal::FitOptions {
        band_hz: Some((0.0, 12.5)),
        ..Default::default()
    };
    stages::modal_fit(&mut rec, &fit, "t").unwrap();
    stages::ni_select(&mut rec, &Default::default(), "t").unwrap();
    let opts = SolveOptions {
        estimators: vec![Estimator::MassLine],
        ..Default::default()
    };
    let out = stages::rb_solve(&mut rec, &opts, true, "t").unwrap();
    let band = out.mass_line_band.expect("band");
    assert!(
        band.automatic && band.lo_hz > 5.41 && band.hi_hz < 54.1,
        "{band:?}"
    );
    let truth: TruthRecord = rec.get_one(topics::TRUTH).unwrap().unwrap();
    let t = truth.properties.to_properties();
    let est: Vec<InertiaEstimate> = rec.get(topics::ESTIMATES).unwrap();
    let e = est
        .iter()
        .find(|e| e.method == "mass_line")
        .expect("a mass-line estimate");
    let p = rbprops_core::records::PropertiesRecord {
        mass_kg: e.mass_kg,
        com_m: e.com_m,
        inertia_cm_kg_m2: e.inertia_cm_kg_m2,
    }
    .to_properties();
    assert!(
        (p.mass - t.mass).abs() < 0.005 * t.mass,
        "mass {} vs {}",
        p.mass,
        t.mass
    );
    assert!(
        (p.com - t.com).norm() < 1e-3,
        "CoM off by {} m",
        (p.com - t.com).norm()
    );
    let jn = t.inertia_cm.norm();
    let worst = (p.inertia_cm - t.inertia_cm).abs().max();
    assert!(
        worst < 0.02 * jn,
        "worst J entry off by {worst} (‖J‖ = {jn})"
    );
}
