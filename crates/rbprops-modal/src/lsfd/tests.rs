//! The refinement by blocks of channels, and its residues.

use super::*;
use rbprops_core::{NormalStream, Quantity};

/// Receptance FRFs of `poles` on `lines` lines from `f0` to `f1` Hz, one channel per
/// entry of `level` (residues `residue(mode, channel)` times its level), with relative
/// noise `noise`; and the poles moved off the truth as a polynomial estimate would
/// leave them, to start the refinement from.
fn noisy_band(
    poles: &[Pole],
    level: &[f64],
    residue: impl Fn(usize, usize) -> c64,
    (lines, f0, f1): (usize, f64, f64),
    noise: f64,
) -> (Vec<Pole>, BandData) {
    let frequency_hz: Vec<f64> = (0..lines)
        .map(|l| f0 + l as f64 * (f1 - f0) / (lines - 1) as f64)
        .collect();
    let omega: Vec<f64> = frequency_hz
        .iter()
        .map(|f| std::f64::consts::TAU * f)
        .collect();
    let mut normals = NormalStream::seed_from_u64(41);
    let channels = (0..level.len())
        .map(|o| {
            omega
                .iter()
                .map(|&w| {
                    let s = c64::new(0.0, w);
                    let h: c64 = poles
                        .iter()
                        .enumerate()
                        .map(|(m, p)| {
                            let r = residue(m, o);
                            r / (s - p.0) + r.conj() / (s - p.0.conj())
                        })
                        .sum::<c64>()
                        * level[o];
                    h + normals.circular(noise * h.norm())
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
    let start = poles
        .iter()
        .map(|p| Pole(p.0 * c64::new(1.004, 0.0) + c64::new(-0.05, 0.0)))
        .collect();
    (start, band)
}

/// Three modes, four channels whose levels differ by 10⁶ (the refinement scales each
/// to unit RMS; the residues must come back in the channels' own units), 2 % noise, a
/// band from 3 to 14 Hz (both residual terms carried).
#[test]
fn refined_residues_are_the_lsfd_fit_at_the_refined_poles() {
    let poles = [
        Pole::from_modal(5.0, 0.02),
        Pole::from_modal(8.0, 0.015),
        Pole::from_modal(11.0, 0.03),
    ];
    let residue = |m: usize, o: usize| c64::new(1.0 + m as f64 - 0.3 * o as f64, 0.1 * o as f64);
    let level = [1.0, 1e-3, 1e3, 0.5];
    let (start, band) = noisy_band(&poles, &level, residue, (600, 3.0, 14.0), 0.02);
    let res = Residuals::for_band(true, &band);
    let refined = refine(&start, &band, &band.channels, res);
    assert!(refined.converged);
    let own = refined.residues();
    let again = fit_residues(&refined.poles, &band, &band.channels, res).residues;
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

/// Two modes seen by seven channels of levels spanning 10⁴, 1 % noise, 3–12 Hz.
fn seven_channels() -> (Vec<Pole>, BandData) {
    let poles = [Pole::from_modal(5.0, 0.02), Pole::from_modal(9.0, 0.03)];
    let level: Vec<f64> = (0..7).map(|o| 10f64.powi(o % 5 - 2)).collect();
    let residue = |m: usize, o: usize| c64::new(1.0 + m as f64 - 0.2 * o as f64, 0.1 * m as f64);
    noisy_band(&poles, &level, residue, (300, 3.0, 12.0), 0.01)
}

/// Issue 41: the trial's data made block by block of channels is the same fit as the
/// data made whole, to the last bit (each channel's least-squares solution and
/// residual are computed column by column in a fixed order; the blocks only bound
/// how many columns are held at once), and so is the candidate screen that makes the
/// residuals again.
#[test]
fn blocks_of_channels_refine_as_the_whole_set() {
    let (start, band) = seven_channels();
    let res = Residuals::for_band(true, &band);
    let whole = refine_in_blocks(&start, &band, &Slices(&band.channels), res, 7);
    assert!(whole.converged && whole.iterations > 1);
    let extra = [Pole::from_modal(7.0, 0.02), Pole::from_modal(10.5, 0.01)];
    let screen = screen_extra_poles(&whole, &extra, &band, &band.channels);
    for block in [1, 2, 3, 6] {
        let r = refine_in_blocks(&start, &band, &Slices(&band.channels), res, block);
        assert_eq!(r.poles, whole.poles, "block of {block}");
        assert_eq!(r.cost, whole.cost, "block of {block}");
        assert_eq!(r.covariance, whole.covariance, "block of {block}");
        assert_eq!(r.residues(), whole.residues(), "block of {block}");
        let s = screen_extra_poles(&r, &extra, &band, &band.channels);
        assert_eq!(s, screen, "block of {block}");
        assert!(
            s.1.iter().all(|&c| c < s.0),
            "the candidates explain something"
        );
    }
}

/// On a basis too ill-conditioned for its Gram matrix (two starting poles 10⁻⁶
/// apart), Householder QR solves the trials and its blocked reflections are not
/// summed in the same order for every number of columns: a block's trial is the
/// whole set's to rounding. (Where the refinement of such a start ends is not
/// compared: the two poles are not identifiable, the cost is flat along their split,
/// and the end point on that valley follows rounding whatever the blocks.)
#[test]
fn blocks_of_channels_refine_as_the_whole_set_by_householder() {
    let (mut start, band) = seven_channels();
    start.insert(1, Pole(start[0].0 * c64::new(1.000001, 0.0)));
    let res = Residuals::for_band(true, &band);
    let first = |block: usize| {
        let slices = Slices(&band.channels);
        let data = Weighted::new(&band, &slices, block);
        let q = weighted_quantity_factor(&band, &data.lw);
        let mut d = linalg::mat_for_overwrite(2 * band.n_lines(), 2 * start.len());
        trial(
            &start,
            &band,
            &data,
            &q,
            res,
            &mut Spares::default(),
            &mut d,
        )
    };
    let whole = first(7);
    let rd = whole.qr.r_diag();
    let ratio =
        rd.iter().cloned().fold(f64::INFINITY, f64::min) / rd.iter().cloned().fold(0.0, f64::max);
    assert!(
        ratio < TallLs::GRAM_LIMIT,
        "the Householder path ({ratio:.1e})"
    );
    let norm = |m: &Mat<f64>| m.norm_l2();
    for block in [1, 3] {
        let t = first(block);
        assert!(
            (t.cost - whole.cost).abs() < 1e-12 * whole.cost,
            "block of {block}"
        );
        let ddtr = norm(&(&t.dtr - &whole.dtr)) / norm(&whole.dtr);
        assert!(ddtr < 1e-9, "block of {block}: Dᵀr off by {ddtr:.1e}");
    }
}
