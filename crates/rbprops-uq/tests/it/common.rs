//! Shared pipeline fixture: the demo campaign (Test Case II with 1 % relative noise)
//! through modal fit, NI selection and the modal estimators.

use rbprops_core::records::{ModalFitRecord, SelectionRecord, TruthRecord};
use rbprops_core::{FrfSet, Geometry};
use rbprops_inertia::{Estimator, SolveOptions};

pub struct Case {
    pub geometry: Geometry,
    pub frf: FrfSet,
    pub truth: TruthRecord,
    pub modal: ModalFitRecord,
    pub selection: SelectionRecord,
    pub solve_opts: SolveOptions,
}

/// `example` with the given seed and (optionally) another relative noise level.
pub fn case(example: &str, seed: u64, relative_noise: Option<f64>) -> Case {
    let mut spec =
        rbprops_sim::CampaignSpec::from_toml_str(rbprops_sim::example(example).unwrap()).unwrap();
    spec.seed = seed;
    if let Some(r) = relative_noise {
        spec.noise.relative = r;
    }
    case_from_spec(spec)
}

/// A campaign spec through the pipeline.
pub fn case_from_spec(spec: rbprops_sim::CampaignSpec) -> Case {
    let sim = rbprops_sim::simulate(&spec).unwrap();
    let modal = rbprops_modal::fit_campaign(&sim.geometry, &sim.frf, &Default::default())
        .unwrap()
        .record;
    let selection = rbprops_ni::select_modes(&sim.geometry, &sim.frf, &modal, &Default::default())
        .unwrap()
        .record;
    Case {
        geometry: sim.geometry,
        frf: sim.frf,
        truth: sim.truth,
        modal,
        selection,
        solve_opts: SolveOptions {
            estimators: vec![Estimator::BretlConti, Estimator::ToivolaNuutila],
            ..Default::default()
        },
    }
}

/// The truth in `rbprops_uq::N_PROPS` order.
pub fn truth_vector(t: &TruthRecord) -> [f64; 10] {
    rbprops_core::InertiaProperties::from_rigid_body(&t.properties.to_properties()).to_vector()
}
