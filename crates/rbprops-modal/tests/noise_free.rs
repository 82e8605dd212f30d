mod common;
use common::*;
use rbprops_core::Quantity;
use rbprops_modal::{fit_campaign, testdata, FitOptions, Method};

#[test]
fn noise_free_test_case_is_exact() {
    for q in [
        Quantity::Accelerance,
        Quantity::Receptance,
        Quantity::Mobility,
    ] {
        let s = testdata::test_case(12.5, 1024, q);
        let out = fit_campaign(&s.geometry, &s.frf, &FitOptions::default()).unwrap();
        for (e, ex) in s.geometry.excitations.iter().enumerate() {
            let which = s.excited_modes(e, 20.0);
            let modes = modes_of(&out.record.modes, &ex.id);
            let errs = compare(&s, e, &modes, &which);
            for er in &errs {
                eprintln!("{q:?} {e} {er:?}");
            }
        }
        eprintln!("{:?}", out.record.excitations);
    }
}
