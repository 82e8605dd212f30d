//! Two pairs of rigid modes each closer than its half-power bandwidth (0.800/0.812 Hz
//! and 1.550/1.575 Hz), 1 % noise, 5 excitations: every excited mode found, none merged
//! (frequency error < 1e-3, MAC > 0.99). Several seeds, all required to pass.
mod common;
use common::*;
use rbprops_modal::{fit_campaign, testdata, FitOptions, Method};

#[test]
fn close_pairs_are_resolved_not_merged() {
    let base = testdata::close_modes(5.0, 4096);
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
    let s = testdata::close_modes(5.0, 4096);
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
