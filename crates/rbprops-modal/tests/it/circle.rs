//! Circle fit and LSCF agree on well-separated modes (≥ 5 half-power bandwidths).
use crate::common::*;
use rbprops_modal::{fit_campaign, FitOptions, Method};
use rbprops_testkit::synthetic;

#[test]
fn circle_fit_agrees_with_lscf_on_separated_modes() {
    let s = synthetic::with_modes(
        [0.6, 0.9, 1.3, 1.8, 2.4, 3.1],
        [0.012, 0.010, 0.015, 0.012, 0.014, 0.010],
        3,
        5.0,
        4096,
    );
    let run = |m: Method| {
        let o = FitOptions {
            method: m,
            ..Default::default()
        };
        fit_campaign(&s.geometry, &s.frf, &o).unwrap()
    };
    let (lscf, circ) = (run(Method::Lscf), run(Method::Circle));
    let (mut wf, mut wz, mut wm) = (0.0f64, 0.0f64, 1.0f64);
    for (e, ex) in s.geometry.excitations.iter().enumerate() {
        let which = s.excited_modes(e, 20.0);
        let a = compare(&s, e, &modes_of(&lscf.record.modes, &ex.id), &which);
        let b = compare(&s, e, &modes_of(&circ.record.modes, &ex.id), &which);
        assert!(!circ.record.excitations[e]
            .warnings
            .iter()
            .any(|w| w.contains("expected to fail")));
        for (x, y) in a.iter().zip(&b) {
            // LSCF is exact; the circle fit (independent, SDOF) agrees closely.
            assert!(x.freq_rel < 1e-9);
            assert!(y.freq_rel < 1e-6, "e{e} {y:?}");
            assert!(y.damp_rel < 1e-3, "e{e} {y:?}");
            assert!(y.mac > 0.99999, "e{e} {y:?}");
            assert!(y.amp_rel < 1e-3, "e{e} {y:?}");
            wf = wf.max(y.freq_rel);
            wz = wz.max(y.damp_rel);
            wm = wm.min(y.mac);
        }
    }
    eprintln!("circle vs truth on separated modes: freq {wf:e}, damping {wz:e}, MAC {wm}");
}
