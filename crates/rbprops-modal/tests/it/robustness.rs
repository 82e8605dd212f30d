//! Bad input, per-excitation failures, thread-count determinism, PerSetup poles, and
//! the axis limits of LSCE.
use crate::common::*;
use rbprops_core::{c64, Quantity};
use rbprops_modal::{fit_campaign, fit_excitation, FitOptions, Method, ModalError, PoleMode};
use rbprops_testkit::synthetic;

#[test]
fn bad_excitations_become_warnings_and_others_complete() {
    let mut s = synthetic::test_case(12.5, 1024, Quantity::Accelerance);
    s.frf.frf_mut(1, 4)[100] = c64::new(f64::NAN, 0.0);
    for v in s.frf.frf_mut(2, 7) {
        *v = c64::new(0.0, 0.0);
    }
    let out = fit_campaign(&s.geometry, &s.frf, &FitOptions::default()).unwrap();
    let r1 = &out.record.excitations[1];
    assert_eq!(r1.model_order, 0);
    assert!(
        r1.warnings[0].contains("'F2'") && r1.warnings[0].contains("channel 4, line 100"),
        "{:?}",
        r1.warnings
    );
    assert!(out.diagnostics[1].synthesised.is_empty());
    // The zero channel is named, its residues are 0, the other channels are still exact.
    let r2 = &out.record.excitations[2];
    assert!(
        r2.warnings
            .iter()
            .any(|w| w.contains("P3y") && w.contains("identically zero")),
        "{:?}",
        r2.warnings
    );
    let m2 = modes_of(&out.record.modes, "F3");
    assert!(m2.iter().all(|m| m.residues[7] == c64::new(0.0, 0.0)));
    for er in compare(&s, 2, &m2, &s.excited_modes(2, 20.0)) {
        assert!(er.freq_rel < 1e-9, "{er:?}");
    }
    // Excitation 0 is untouched.
    for er in compare(
        &s,
        0,
        &modes_of(&out.record.modes, "F1"),
        &s.excited_modes(0, 20.0),
    ) {
        assert!(er.freq_rel < 1e-9 && er.amp_rel < 1e-6, "{er:?}");
    }
}

#[test]
fn clear_errors_for_empty_band_too_few_lines_and_bad_options() {
    let s = synthetic::test_case(12.5, 1024, Quantity::Accelerance);
    let o = FitOptions {
        band_hz: Some((20.0, 30.0)),
        ..Default::default()
    };
    let e = fit_excitation(&s.geometry, &s.frf, 0, &o).unwrap_err();
    assert!(
        matches!(e, ModalError::BadInput { .. }) && e.to_string().contains("no spectral line"),
        "{e}"
    );
    let o = FitOptions {
        band_hz: Some((1.0, 1.02)),
        ..Default::default()
    };
    let e = fit_excitation(&s.geometry, &s.frf, 0, &o).unwrap_err();
    assert!(
        e.to_string().contains("'F1'") && e.to_string().contains("lines"),
        "{e}"
    );
    let o = FitOptions {
        band_hz: Some((3.0, 1.0)),
        ..Default::default()
    };
    assert!(matches!(
        fit_campaign(&s.geometry, &s.frf, &o),
        Err(ModalError::Options(_))
    ));
    assert!(matches!(
        fit_excitation(&s.geometry, &s.frf, 7, &FitOptions::default()),
        Err(ModalError::NoSuchExcitation { .. })
    ));
    let mut g = s.geometry.clone();
    g.channels.pop();
    assert!(matches!(
        fit_campaign(&g, &s.frf, &FitOptions::default()),
        Err(ModalError::Shape(_))
    ));
}

#[test]
fn lsce_refuses_zoom_and_non_uniform_axes() {
    let s = synthetic::test_case(12.5, 1024, Quantity::Accelerance);
    let o = FitOptions {
        method: Method::Lsce,
        band_hz: Some((0.5, 5.0)),
        ..Default::default()
    };
    let e = fit_excitation(&s.geometry, &s.frf, 0, &o).unwrap_err();
    assert!(
        matches!(e, ModalError::Axis { method: "LSCE", .. }) && e.to_string().contains("0 Hz"),
        "{e}"
    );
    // Non-uniform axis: drop every third line. LSCE refuses, LSCF copes.
    let keep: Vec<usize> = (0..s.frf.n_lines()).filter(|l| l % 3 != 1).collect();
    let mut frf = rbprops_core::FrfSet::zeros(
        s.frf.quantity,
        keep.iter().map(|&l| s.frf.frequency_hz[l]).collect(),
        3,
        9,
    );
    for e in 0..3 {
        for c in 0..9 {
            let src = s.frf.frf(e, c).to_vec();
            for (k, &l) in keep.iter().enumerate() {
                frf.frf_mut(e, c)[k] = src[l];
            }
        }
    }
    let e = fit_excitation(
        &s.geometry,
        &frf,
        0,
        &FitOptions {
            method: Method::Lsce,
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("uniform"), "{e}");
    let fit = fit_excitation(&s.geometry, &frf, 0, &FitOptions::default()).unwrap();
    for er in compare(&s, 0, &fit.modes, &s.excited_modes(0, 20.0)) {
        assert!(er.freq_rel < 1e-9 && er.mac > 0.99999, "{er:?}");
    }
}

#[test]
fn results_are_identical_for_any_thread_count() {
    let s = synthetic::test_case(12.5, 1024, Quantity::Accelerance).with_noise(0.01, 7);
    let run = |t: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build()
            .unwrap()
            .install(|| fit_campaign(&s.geometry, &s.frf, &FitOptions::default()).unwrap())
    };
    let (a, b, c) = (run(1), run(2), run(3));
    assert_eq!(a, b);
    assert_eq!(a, c);
}

#[test]
fn per_setup_poles_are_shared_and_exact() {
    let s = synthetic::test_case(12.5, 1024, Quantity::Accelerance);
    let o = FitOptions {
        poles: PoleMode::PerSetup,
        ..Default::default()
    };
    let out = fit_campaign(&s.geometry, &s.frf, &o).unwrap();
    let f: Vec<Vec<f64>> = s
        .geometry
        .excitations
        .iter()
        .map(|ex| {
            modes_of(&out.record.modes, &ex.id)
                .iter()
                .map(|m| m.frequency_hz)
                .collect()
        })
        .collect();
    assert_eq!(f[0].len(), 6);
    assert!(f.iter().all(|x| x == &f[0]), "{f:?}");
    for (e, ex) in s.geometry.excitations.iter().enumerate() {
        let m = modes_of(&out.record.modes, &ex.id);
        for er in compare(&s, e, &m, &s.excited_modes(e, 20.0)) {
            assert!(
                er.freq_rel < 1e-9 && er.mac > 0.99999 && er.amp_rel < 1e-6,
                "{er:?}"
            );
        }
        // Modes this excitation barely drives are flagged, not reported as reliable.
        let ni = s.mode_peak_ni(e);
        let max = ni.iter().cloned().fold(0.0, f64::max);
        for (r, mm) in m.iter().enumerate() {
            if 20.0 * (ni[r] / max).log10() < -25.0 {
                assert!(mm.weak, "e{e} mode {r} should be weak");
            }
        }
    }
}

#[test]
fn standard_errors_and_records_are_finite_and_consistent() {
    let s = synthetic::test_case(12.5, 1024, Quantity::Mobility).with_noise(0.01, 3);
    let keep = FitOptions {
        keep_synthesised: true,
        ..Default::default()
    };
    let out = fit_campaign(&s.geometry, &s.frf, &keep).unwrap();
    // Without `keep_synthesised` the same record, and no curves.
    let lean = fit_campaign(&s.geometry, &s.frf, &FitOptions::default()).unwrap();
    assert_eq!(lean.record, out.record);
    assert!(lean.diagnostics.iter().all(|d| d.synthesised.is_empty()));
    for m in &out.record.modes {
        assert!(m.frequency_std_hz.is_finite() && m.frequency_std_hz > 0.0);
        assert!(m.damping_std.is_finite() && m.damping_std > 0.0);
        assert_eq!(m.residues.len(), 9);
        assert!(m.residue_std.iter().all(|x| x.is_finite() && *x > 0.0));
        assert!((0.0..=1.0).contains(&m.confidence) && (0.0..=1.0).contains(&m.mpc));
    }
    for (e, r) in out.record.excitations.iter().enumerate() {
        assert_eq!(r.method, "lscf");
        assert_eq!(r.fit_error.len(), 9);
        // 1 % noise: normalised error ≈ 1e-4 per channel.
        assert!(
            r.fit_error.iter().all(|x| *x > 1e-5 && *x < 1e-3),
            "{:?}",
            r.fit_error
        );
        let d = &out.diagnostics[e];
        assert_eq!(d.synthesised.len(), 9);
        assert_eq!(d.synthesised[0].len(), d.frequency_hz.len());
        assert!(!d.stabilisation.poles.is_empty());
    }
}
