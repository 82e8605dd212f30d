//! The pole refinement's own residues (`Refined::residues`) against a separate LSFD fit at
//! the refined poles: the bootstrap takes the former instead of computing the latter.

use rbprops_core::{c64, NormalStream, Quantity};
use rbprops_modal::band::BandData;
use rbprops_modal::lsfd::{self, Residuals};
use rbprops_modal::Pole;

/// Three modes, four channels whose levels differ by 10⁶ (the refinement scales each to
/// unit RMS; the residues must come back in the channels' own units), 2 % relative
/// noise, a band from 3 to 14 Hz (both residual terms carried).
fn band_with_noise() -> (Vec<Pole>, BandData) {
    let poles = [
        Pole::from_modal(5.0, 0.02),
        Pole::from_modal(8.0, 0.015),
        Pole::from_modal(11.0, 0.03),
    ];
    let scale = [1.0, 1e-3, 1e3, 0.5];
    let residues = |m: usize, o: usize| c64::new(1.0 + m as f64 - 0.3 * o as f64, 0.1 * o as f64);
    let frequency_hz: Vec<f64> = (0..600).map(|l| 3.0 + l as f64 * 11.0 / 599.0).collect();
    let omega: Vec<f64> = frequency_hz
        .iter()
        .map(|f| std::f64::consts::TAU * f)
        .collect();
    let mut noise = NormalStream::seed_from_u64(41);
    let channels = (0..scale.len())
        .map(|o| {
            omega
                .iter()
                .map(|&w| {
                    let s = c64::new(0.0, w);
                    let h: c64 = poles
                        .iter()
                        .enumerate()
                        .map(|(m, p)| {
                            let r = residues(m, o);
                            r / (s - p.0) + r.conj() / (s - p.0.conj())
                        })
                        .sum::<c64>()
                        * scale[o];
                    h + noise.circular(0.02 * h.norm())
                })
                .collect()
        })
        .collect();
    let band = BandData {
        quantity: Quantity::Receptance,
        frequency_hz,
        omega,
        channels,
        first_line: 0,
        line_quality: None,
    };
    // Start the refinement away from the truth, as from a polynomial estimate.
    let start = poles
        .iter()
        .map(|p| Pole(p.0 * c64::new(1.004, 0.0) + c64::new(-0.05, 0.0)))
        .collect();
    (start, band)
}

#[test]
fn refined_residues_are_the_lsfd_fit_at_the_refined_poles() {
    let (start, band) = band_with_noise();
    let res = Residuals::for_band(true, &band);
    let refined = lsfd::refine(&start, &band, &band.channels, res);
    assert!(refined.converged);
    let own = refined.residues();
    let again = lsfd::fit_residues(&refined.poles, &band, &band.channels, res).residues;
    assert_eq!((own.len(), own[0].len()), (3, 4));
    for (m, (a, b)) in own.iter().zip(&again).enumerate() {
        for (o, (x, y)) in a.iter().zip(b).enumerate() {
            // Two solutions of one least-squares problem: equal to rounding (the channel
            // scales span 10⁶, so an unscaled residue would be off by orders of magnitude).
            let rel = (x - y).norm() / y.norm();
            assert!(rel < 1e-9, "mode {m} channel {o}: {x} vs {y} ({rel:.1e})");
        }
    }
}
