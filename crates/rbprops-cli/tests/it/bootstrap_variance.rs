//! `rb-solve`'s bootstrap takes the record's line variances (`/rbprops/frf_variance`) and
//! its estimates say so; without them, they name the residuals' noise model.

use rbprops_cli::stages::{self, Uncertainty};
use rbprops_core::records::InertiaEstimate;
use rbprops_formats::topics;
use rbprops_uq::BootstrapOptions;

fn sources(rec: &mut rbprops_formats::RunRecord) -> Vec<String> {
    let uq = Uncertainty::Bootstrap(BootstrapOptions {
        replicates: 4,
        ..Default::default()
    });
    stages::rb_solve_with(rec, &Default::default(), &uq, false, "test").unwrap();
    rec.get::<InertiaEstimate>(topics::ESTIMATES)
        .unwrap()
        .into_iter()
        .filter_map(|e| e.uncertainty_source)
        .collect()
}

#[test]
fn the_bootstrap_names_its_noise() {
    let spec = rbprops_sim::examples::example("demo").unwrap();
    let (mut rec, _) = stages::simulate(spec, "demo", Some(3)).unwrap();
    stages::modal_fit(&mut rec, &Default::default(), "test").unwrap();
    stages::ni_select(&mut rec, &Default::default(), "test").unwrap();
    let mut with = rec.clone();
    let without = sources(&mut rec);
    assert!(!without.is_empty());
    assert!(
        without
            .iter()
            .all(|s| s.contains("fitted to the modal fit's residuals")),
        "{without:?}"
    );
    let (geometry, frf) = with.require_geometry_and_frf().unwrap();
    let frf = frf.clone();
    let v = rbprops_cli::variance::LineVarianceSet {
        sigma2: frf.values.iter().map(|h| 1e-4 * h.norm_sqr()).collect(),
        degrees_of_freedom: vec![10.0; frf.n_excitations],
        common: vec![None; frf.n_excitations],
    };
    rbprops_cli::variance::set(&mut with, &geometry, &frf, &v);
    let given = sources(&mut with);
    assert!(!given.is_empty());
    assert!(
        given.iter().all(|s| s
            .contains("the FRF estimator's line variances (/rbprops/frf_variance")
            && !s.contains("residuals")),
        "{given:?}"
    );
}
