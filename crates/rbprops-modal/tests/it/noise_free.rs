//! Noise-free Test-Case-like data: the identified modes must be exact to the issue's
//! tolerances (frequency 1e-6, damping 1e-3 relative, MAC > 0.99999, amplitude 1e-4).
use crate::common::*;
use rbprops_core::Quantity;
use rbprops_modal::{fit_campaign, FitOptions, Method, RESIDUE_CONVENTION};
use rbprops_testkit::synthetic;

fn assert_exact(s: &synthetic::Synthetic, opts: &FitOptions, label: &str) -> f64 {
    let out = fit_campaign(&s.geometry, &s.frf, opts).unwrap();
    assert_eq!(out.record.residue_convention, RESIDUE_CONVENTION);
    let mut worst: f64 = 0.0;
    for (e, ex) in s.geometry.excitations.iter().enumerate() {
        let which = s.excited_modes(e, 20.0);
        assert!(
            which.len() >= 2,
            "{label}: test data should excite several modes"
        );
        let modes = modes_of(&out.record.modes, &ex.id);
        for er in compare(s, e, &modes, &which) {
            assert!(er.freq_rel < 1e-6, "{label} e{e} {er:?}");
            assert!(er.damp_rel < 1e-3, "{label} e{e} {er:?}");
            assert!(er.mac > 0.99999, "{label} e{e} {er:?}");
            assert!(er.amp_rel < 1e-4, "{label} e{e} {er:?}");
            worst = worst.max(er.freq_rel).max(er.damp_rel).max(er.amp_rel);
        }
        let rec = &out.record.excitations[e];
        assert!(
            rec.fit_error.iter().all(|x| *x < 1e-12),
            "{label}: {:?}",
            rec.fit_error
        );
    }
    worst
}

#[test]
fn lscf_is_exact_for_every_quantity() {
    for q in [
        Quantity::Accelerance,
        Quantity::Receptance,
        Quantity::Mobility,
    ] {
        let s = synthetic::test_case(12.5, 1024, q);
        let w = assert_exact(&s, &FitOptions::default(), q.name());
        assert!(w < 1e-9, "{q:?}: worst relative error {w:e}");
    }
}

#[test]
fn zoom_band_needs_and_uses_residual_terms() {
    // Modes at 0.3/0.4 Hz below and 6 Hz above a 1–3 Hz zoom band. The lower (mass-line)
    // and upper (constant) residual terms are first-order models of those modes, so the
    // in-band modes are accurate but not exact (measured: freq ≤ 8e-5, amplitude ≤ 0.6 %);
    // without residual terms the out-of-band modes wreck the fit.
    let s = synthetic::with_modes(
        [0.3, 0.4, 1.5, 1.8, 2.2, 6.0],
        [0.012, 0.015, 0.010, 0.018, 0.014, 0.02],
        3,
        8.0,
        4096,
    );
    let run = |res: bool| {
        let o = FitOptions {
            band_hz: Some((1.0, 3.0)),
            residual_terms: res,
            ..Default::default()
        };
        fit_campaign(&s.geometry, &s.frf, &o).unwrap()
    };
    let with = run(true);
    let without = run(false);
    let mut worst_with: f64 = 0.0;
    let mut worst_without: f64 = 0.0;
    for (e, ex) in s.geometry.excitations.iter().enumerate() {
        let which: Vec<usize> = s
            .excited_modes(e, 20.0)
            .into_iter()
            .filter(|&r| (2..=4).contains(&r))
            .collect();
        for er in compare(&s, e, &modes_of(&with.record.modes, &ex.id), &which) {
            assert!(er.freq_rel < 2e-4 && er.damp_rel < 0.01, "zoom e{e} {er:?}");
            assert!(er.mac > 0.9999 && er.amp_rel < 0.01, "zoom e{e} {er:?}");
            worst_with = worst_with.max(er.amp_rel);
        }
        let m = modes_of(&without.record.modes, &ex.id);
        if m.len() < which.len() {
            worst_without = f64::INFINITY;
        } else if let Ok(errs) = std::panic::catch_unwind(|| compare(&s, e, &m, &which)) {
            for er in errs {
                worst_without = worst_without.max(er.amp_rel);
            }
        } else {
            worst_without = f64::INFINITY;
        }
    }
    eprintln!(
        "zoom amplitude error: with residual terms {worst_with:e}, without {worst_without:e}"
    );
    assert!(worst_without > 5.0 * worst_with);
}

#[test]
fn lsce_is_exact_on_a_baseband_with_or_without_refinement() {
    let s = synthetic::test_case(12.5, 1024, Quantity::Accelerance);
    let lsce = FitOptions {
        method: Method::Lsce,
        ..Default::default()
    };
    assert_exact(&s, &lsce, "lsce");
    // Without refinement: the polynomial estimators alone. Measured on these data:
    // LSCE ~1e-13 (over-modelling absorbs the impulse-response truncation of this
    // baseband), LSCF ~6e-5 (z-domain model of an s-domain system): the refinement is
    // what makes LSCF exact.
    let worst_freq = |m: Method| {
        let o = FitOptions {
            method: m,
            refine: false,
            ..Default::default()
        };
        let out = fit_campaign(&s.geometry, &s.frf, &o).unwrap();
        let mut w: f64 = 0.0;
        // Excitations F1, F2 (F3's unrefined diagram keeps a computational 6.7 Hz pole
        // that only the refinement removes; see the report's known limits).
        for (e, ex) in s.geometry.excitations.iter().enumerate().take(2) {
            let modes = modes_of(&out.record.modes, &ex.id);
            for er in compare(&s, e, &modes, &s.excited_modes(e, 20.0)) {
                w = w.max(er.freq_rel);
            }
        }
        w
    };
    let (f_lsce, f_lscf) = (worst_freq(Method::Lsce), worst_freq(Method::Lscf));
    eprintln!("unrefined worst frequency error: LSCE {f_lsce:e}, LSCF {f_lscf:e}");
    assert!(f_lsce < 1e-6, "LSCE unrefined {f_lsce:e}");
    assert!(f_lscf < 1e-3, "LSCF unrefined {f_lscf:e}");
}
