//! Two pairs of rigid modes each closer than its half-power bandwidth (0.800/0.812 Hz
//! and 1.550/1.575 Hz), 1 % noise, 5 excitations: every excited mode found, none merged
//! (frequency error < 1e-3, MAC > 0.99). Several seeds, all required to pass.
use crate::common::*;
use rbprops_modal::{fit_campaign, FitOptions, Method};
use rbprops_testkit::synthetic;

#[test]
fn close_pairs_are_resolved_not_merged() {
    let base = synthetic::close_modes(5.0, 4096);
    for (a, b) in [(0, 1), (2, 3)] {
        let (ma, mb) = (&base.modes[a], &base.modes[b]);
        let hpb = 2.0 * ma.damping_ratio.min(mb.damping_ratio) * ma.frequency_hz;
        assert!(
            (mb.frequency_hz - ma.frequency_hz) < hpb,
            "test data must be closer than the half-power bandwidth"
        );
    }
    let (mut wf, mut wm) = (0.0f64, 1.0f64);
    for seed in 0..4 {
        let s = base.with_noise(0.01, 100 + seed);
        let out = fit_campaign(&s.geometry, &s.frf, &FitOptions::default()).unwrap();
        for (e, ex) in s.geometry.excitations.iter().enumerate() {
            let which = s.excited_modes(e, 20.0);
            let modes = modes_of(&out.record.modes, &ex.id);
            for er in compare(&s, e, &modes, &which) {
                assert!(er.freq_rel < 1e-3, "seed {seed} e{e} {er:?}");
                assert!(er.mac > 0.99, "seed {seed} e{e} {er:?}");
                wf = wf.max(er.freq_rel);
                wm = wm.min(er.mac);
            }
        }
    }
    eprintln!("close modes: worst freq {wf:e}, MAC {wm}");
}

#[test]
fn circle_fit_fails_on_close_modes_and_says_so() {
    let s = synthetic::close_modes(5.0, 4096);
    let opts = FitOptions {
        method: Method::Circle,
        ..Default::default()
    };
    let out = fit_campaign(&s.geometry, &s.frf, &opts).unwrap();
    let mut worst_mac: f64 = 1.0;
    let mut worst_freq: f64 = 0.0;
    for (e, ex) in s.geometry.excitations.iter().enumerate() {
        let rec = &out.record.excitations[e];
        assert!(
            rec.warnings
                .iter()
                .any(|w| w.contains("circle fit expected to fail")),
            "e{e}: {:?}",
            rec.warnings
        );
        let modes = modes_of(&out.record.modes, &ex.id);
        let close: Vec<usize> = s
            .excited_modes(e, 20.0)
            .into_iter()
            .filter(|&r| r < 4)
            .collect();
        for m in modes.iter().filter(|m| m.frequency_hz < 1.7) {
            assert!(m
                .warnings
                .iter()
                .any(|w| w.contains("circle fit expected to fail")));
        }
        for er in compare(&s, e, &modes, &close) {
            worst_mac = worst_mac.min(er.mac);
            worst_freq = worst_freq.max(er.freq_rel);
        }
    }
    eprintln!("circle on close modes (noise-free): worst freq {worst_freq:e}, MAC {worst_mac}");
    // Noise-free data, yet the SDOF assumption breaks: errors far above LSCF's ~1e-15.
    assert!(
        worst_mac < 0.999 || worst_freq > 1e-3,
        "circle fit unexpectedly accurate on close modes"
    );
}

/// A pair 1 % apart at ζ = 1.5 % (0.67 half-bandwidths, like the campaign variant that
/// came out of the diagram as one pole for one excitation and three for another) on a
/// 0–12.5 Hz baseband, 1 % noise, 10 seeds × 3 excitations: the model order is right —
/// no merged pair (every excited mode found) and no over-split (at most one pole per
/// true mode, six in all). Without the forward/backward model-order tests this fails on
/// seed 0 (excitation 1 merges the pair into one pole).
#[test]
fn model_order_of_a_close_pair_is_right_neither_merged_nor_over_split() {
    let base = synthetic::with_modes(
        [0.873, 1.042, 1.612, 3.672, 3.709, 5.007],
        [0.015; 6],
        3,
        12.5,
        1601,
    );
    let pair = (base.modes[3].frequency_hz, base.modes[4].frequency_hz);
    let hb = 0.015 * pair.0;
    assert!(
        pair.1 - pair.0 < hb,
        "test data must be closer than a half-bandwidth"
    );
    let mut counts = Vec::new();
    for seed in 0..10 {
        let s = base.with_noise(0.01, 500 + seed);
        let out = fit_campaign(&s.geometry, &s.frf, &FitOptions::default()).unwrap();
        for (e, ex) in s.geometry.excitations.iter().enumerate() {
            let modes = modes_of(&out.record.modes, &ex.id);
            let which = s.excited_modes(e, 20.0);
            for er in compare(&s, e, &modes, &which) {
                assert!(er.freq_rel < 1e-3, "seed {seed} e{e} {er:?}");
                assert!(er.mac > 0.99, "seed {seed} e{e} {er:?}");
            }
            let near_pair = modes
                .iter()
                .filter(|m| {
                    m.frequency_hz > pair.0 - 3.0 * hb && m.frequency_hz < pair.1 + 3.0 * hb
                })
                .count();
            counts.push((seed, e, modes.len(), near_pair));
            assert!(
                near_pair <= 2 && modes.len() <= 6,
                "seed {seed} e{e}: {} poles, {near_pair} at the pair: {:?}",
                modes.len(),
                modes.iter().map(|m| m.frequency_hz).collect::<Vec<_>>()
            );
        }
    }
    eprintln!("(seed, excitation, poles, poles at the pair): {counts:?}");
}

/// The close pairs seen by fifty excitations: forces along a Fibonacci spiral at the
/// three accelerometer points in turn, 1,000 lines to 5 Hz.
fn fifty_excitations() -> synthetic::Synthetic {
    let body = synthetic::test_case_body();
    let forces = synthetic::fibonacci_forces(50);
    let geometry = synthetic::test_case_geometry(&body, &forces);
    let close = synthetic::close_modes(5.0, 16);
    let frf = synthetic::synthesise(
        &geometry,
        &close.modes,
        5.0,
        1000,
        rbprops_core::Quantity::Accelerance,
    );
    synthetic::Synthetic {
        geometry,
        modes: close.modes,
        frf,
    }
}

/// Fifty excitations: the poly-reference fit is exact on noise-free data (every mode of
/// every excitation; six real modes span 6 of the 50 reference directions, and on the
/// references as measured the sweep's normal equations were singular: no mode found),
/// and at 1 % noise both it and the default find every excited mode of both close
/// pairs, none merged.
#[test]
fn fifty_excitations_resolve_the_close_pairs() {
    let exact = fifty_excitations();
    let plscf = FitOptions {
        method: Method::Plscf,
        ..Default::default()
    };
    let noisy = exact.with_noise(0.01, 4100);
    for (s, opts, label, tol) in [
        (&exact, &plscf, "plscf, exact", 1e-8),
        (&noisy, &plscf, "plscf, 1 %", 1e-3),
        (&noisy, &FitOptions::default(), "default, 1 %", 1e-3),
    ] {
        let out = fit_campaign(&s.geometry, &s.frf, opts).unwrap();
        let mut worst = 0.0f64;
        for (e, ex) in s.geometry.excitations.iter().enumerate() {
            let which = s.excited_modes(e, 20.0);
            let modes = modes_of(&out.record.modes, &ex.id);
            for er in compare(s, e, &modes, &which) {
                assert!(er.freq_rel < tol, "{label}: e{e} {er:?}");
                assert!(er.mac > 0.99, "{label}: e{e} {er:?}");
                worst = worst.max(er.freq_rel);
            }
        }
        eprintln!("{label}: worst frequency error {worst:e}");
    }
}
