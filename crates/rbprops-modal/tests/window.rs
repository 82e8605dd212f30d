//! FRFs processed with an exponential window: the windowed data are written here from the
//! Laplace-domain modal sum at s = iω + σ (not by the crate's synthesiser), then
//! `window::remove_quantity_window`, the fit and `window::restore_poles` must give back
//! the unwindowed modes to the noise-free tolerances of `noise_free.rs`.
mod common;
use common::*;
use rbprops_core::{c64, Quantity};
use rbprops_modal::{fit_campaign, testdata, window, FitOptions};

/// `D(ω) = (iω + σ)^k Σ_r A_r / (s² + 2ζ_r ω_r s + ω_r²)` at `s = iω + σ`.
fn windowed(s: &testdata::Synthetic, sigma: f64) -> rbprops_core::FrfSet {
    let mut frf = s.frf.clone();
    let k = frf.quantity.order();
    let nl = frf.frequency_hz.len();
    for e in 0..frf.n_excitations {
        let a = s.true_modal_constants(e);
        for c in 0..frf.n_channels {
            let h = frf.frf_mut(e, c);
            for l in 0..nl {
                let sl = c64::new(sigma, 2.0 * std::f64::consts::PI * s.frf.frequency_hz[l]);
                let mut sum = c64::new(0.0, 0.0);
                for (r, m) in s.modes.iter().enumerate() {
                    let w = m.omega();
                    sum += a[r][c] / (sl * sl + 2.0 * m.damping_ratio * w * sl + w * w);
                }
                h[l] = sum * sl.powi(k);
            }
        }
    }
    frf
}

/// Largest relative error in frequency, damping or amplitude, or 1 − MAC, over the
/// excited modes.
fn worst_error(s: &testdata::Synthetic, modes: &[rbprops_core::records::ModeEstimate]) -> f64 {
    let mut worst: f64 = 0.0;
    for (e, ex) in s.geometry.excitations.iter().enumerate() {
        for er in compare(s, e, &modes_of(modes, &ex.id), &s.excited_modes(e, 20.0)) {
            worst = worst
                .max(er.freq_rel)
                .max(er.damp_rel)
                .max(er.amp_rel)
                .max(1.0 - er.mac);
        }
    }
    worst
}

#[test]
fn windowed_accelerance_and_mobility_give_back_the_unwindowed_modes() {
    let sigma = 0.25; // τ = 4 s: adds 0.25/ω to ζ, 4 % at 1 Hz (ζ itself is 1–2 %)
    for q in [
        Quantity::Accelerance,
        Quantity::Mobility,
        Quantity::Receptance,
    ] {
        let s = testdata::test_case(12.5, 1024, q);
        let mut frf = windowed(&s, sigma);
        window::remove_quantity_window(&mut frf, sigma);
        let mut out = fit_campaign(&s.geometry, &frf, &FitOptions::default()).unwrap();
        let warnings = window::restore_poles(&mut out.record.modes, sigma);
        assert!(warnings.is_empty(), "{warnings:?}");
        // Noise-free and exact model after the correction: round-off only, as in
        // noise_free.rs (which reaches < 1e-9 on unwindowed data).
        let w = worst_error(&s, &out.record.modes);
        assert!(w < 1e-8, "{q:?}: worst relative error {w:e}");
    }
}

#[test]
fn without_the_correction_the_window_biases_damping_and_phase() {
    // The null: the same data fitted as they are. Damping is off by σ/ω_r (several
    // times ζ here: measured 7.2 relative for the first mode), so the correction above is
    // doing the work.
    let sigma = 0.25;
    let s = testdata::test_case(12.5, 1024, Quantity::Accelerance);
    let frf = windowed(&s, sigma);
    let out = fit_campaign(&s.geometry, &frf, &FitOptions::default()).unwrap();
    let w = worst_error(&s, &out.record.modes);
    assert!(w > 0.1, "uncorrected worst relative error {w:e}");
}

#[test]
fn restore_poles_moves_an_exact_pole_by_sigma() {
    // λ' = λ − σ: ω_d unchanged, decay +σ. Pole at 2 Hz, ζ = 0.02, σ = 0.3.
    let (f, z, sigma) = (2.0f64, 0.02f64, 0.3f64);
    let w = 2.0 * std::f64::consts::PI * f;
    let (wd, d) = (w * (1.0 - z * z).sqrt(), z * w + sigma);
    let w1 = (wd * wd + d * d).sqrt();
    let mut m = vec![rbprops_core::records::ModeEstimate {
        excitation: "e".into(),
        setup: "A".into(),
        mode: 1,
        frequency_hz: w1 / (2.0 * std::f64::consts::PI),
        frequency_std_hz: 0.0,
        damping_ratio: d / w1,
        damping_std: 0.0,
        residues: vec![],
        residue_std: vec![],
        confidence: 1.0,
        mpc: 1.0,
        weak: false,
        warnings: vec![],
    }];
    assert!(window::restore_poles(&mut m, sigma).is_empty());
    assert!(
        (m[0].frequency_hz - f).abs() < 1e-14 * f,
        "{}",
        m[0].frequency_hz
    );
    assert!(
        (m[0].damping_ratio - z).abs() < 1e-13,
        "{}",
        m[0].damping_ratio
    );
    // Too large a σ: negative damping, reported.
    assert_eq!(window::restore_poles(&mut m, 1.0).len(), 1);
}
