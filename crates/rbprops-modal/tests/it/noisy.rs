//! 1 % complex noise, 20 seeds: frequency error < 1e-3, damping error < 5 %, MAC > 0.999
//! for every mode the excitation excites (peak NI within 20 dB of its strongest mode).
//! Required of all 20 seeds × 3 excitations (60 fits): the tolerances sit 10–50× above
//! the observed scatter, so a single failure is a real defect, not bad luck.
use crate::common::*;
use rbprops_core::Quantity;
use rbprops_modal::{fit_campaign, FitOptions};
use rbprops_testkit::synthetic;

#[test]
fn one_percent_noise_twenty_seeds() {
    let base = synthetic::test_case(12.5, 2048, Quantity::Accelerance);
    let (mut wf, mut wz, mut wm) = (0.0f64, 0.0f64, 1.0f64);
    let mut std_ratio = Vec::new();
    for seed in 0..20 {
        let s = base.with_noise(0.01, seed);
        let out = fit_campaign(&s.geometry, &s.frf, &FitOptions::default()).unwrap();
        for (e, ex) in s.geometry.excitations.iter().enumerate() {
            let which = s.excited_modes(e, 20.0);
            let modes = modes_of(&out.record.modes, &ex.id);
            for er in compare(&s, e, &modes, &which) {
                assert!(er.freq_rel < 1e-3, "seed {seed} e{e} {er:?}");
                assert!(er.damp_rel < 0.05, "seed {seed} e{e} {er:?}");
                assert!(er.mac > 0.999, "seed {seed} e{e} {er:?}");
                wf = wf.max(er.freq_rel);
                wz = wz.max(er.damp_rel);
                wm = wm.min(er.mac);
                let est = modes
                    .iter()
                    .min_by(|a, b| {
                        let f = s.modes[er.truth].frequency_hz;
                        (a.frequency_hz - f)
                            .abs()
                            .total_cmp(&(b.frequency_hz - f).abs())
                    })
                    .unwrap();
                let err = est.frequency_hz - s.modes[er.truth].frequency_hz;
                std_ratio.push(err / est.frequency_std_hz);
            }
        }
    }
    // The reported frequency standard errors must be honest: the normalised errors
    // should have unit RMS (loose bounds for ~300 samples with 1/|H|-type noise).
    let rms = (std_ratio.iter().map(|x| x * x).sum::<f64>() / std_ratio.len() as f64).sqrt();
    eprintln!(
        "worst: freq {wf:e}, damping {wz:e}, MAC {wm}; RMS(err/std) = {rms:.2} over {}",
        std_ratio.len()
    );
    assert!(
        rms > 0.3 && rms < 3.0,
        "frequency std is off by a factor: RMS(err/std) = {rms}"
    );
}

/// A baseband eight times wider than the modes (0–100 Hz, 8,001 lines, rigid modes
/// below 3 Hz), 1 % noise, 5 seeds: the automatic band narrowing and the lower-band
/// sweeps find every excited mode within the same tolerances, without `--band`.
#[test]
fn wide_baseband_without_band_option_finds_every_excited_mode() {
    let base = synthetic::test_case(100.0, 8001, Quantity::Accelerance);
    let mut wf = 0.0f64;
    for seed in 0..5 {
        let s = base.with_noise(0.01, 700 + seed);
        let out = fit_campaign(&s.geometry, &s.frf, &FitOptions::default()).unwrap();
        for (e, ex) in s.geometry.excitations.iter().enumerate() {
            let which = s.excited_modes(e, 20.0);
            let modes = modes_of(&out.record.modes, &ex.id);
            assert!(modes.len() <= 6, "seed {seed} e{e}: {} poles", modes.len());
            for er in compare(&s, e, &modes, &which) {
                assert!(er.freq_rel < 1e-3, "seed {seed} e{e} {er:?}");
                assert!(er.damp_rel < 0.05, "seed {seed} e{e} {er:?}");
                assert!(er.mac > 0.999, "seed {seed} e{e} {er:?}");
                wf = wf.max(er.freq_rel);
            }
        }
    }
    eprintln!("wide baseband: worst frequency error {wf:e}");
}
