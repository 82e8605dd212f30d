//! Shared checks: compare identified modes with the synthetic truth.
#![allow(dead_code)]

use rbprops_core::c64;
use rbprops_core::records::ModeEstimate;
use rbprops_modal::mac;
use rbprops_testkit::synthetic::Synthetic;

/// Error of one identified mode against its true counterpart.
#[derive(Debug, Clone, Copy)]
pub struct ModeError {
    pub truth: usize,
    pub freq_rel: f64,
    pub damp_rel: f64,
    pub mac: f64,
    pub amp_rel: f64,
}

/// Matches each true mode in `which` to the closest identified mode (by frequency) of
/// excitation `e`, and reports the errors. Panics if a mode is missing or two true modes
/// map to the same estimate (a merge).
pub fn compare(s: &Synthetic, e: usize, modes: &[ModeEstimate], which: &[usize]) -> Vec<ModeError> {
    let truth_a = s.true_modal_constants(e);
    let mut used = vec![false; modes.len()];
    let mut out = Vec::new();
    for &r in which {
        let f = s.modes[r].frequency_hz;
        let (i, est) = modes
            .iter()
            .enumerate()
            .min_by(|a, b| {
                (a.1.frequency_hz - f)
                    .abs()
                    .total_cmp(&(b.1.frequency_hz - f).abs())
            })
            .unwrap_or_else(|| {
                panic!("excitation {e}: no mode identified, true mode {r} at {f} Hz")
            });
        assert!(
            !used[i],
            "excitation {e}: true modes merged into estimate {} at {} Hz",
            i + 1,
            est.frequency_hz
        );
        used[i] = true;
        let ta: Vec<c64> = truth_a[r].iter().map(|&x| c64::new(x, 0.0)).collect();
        let na: f64 = ta.iter().map(|z| z.norm_sqr()).sum::<f64>().sqrt();
        let amp: f64 = est
            .residues
            .iter()
            .zip(&ta)
            .map(|(a, b)| (a - b).norm_sqr())
            .sum::<f64>()
            .sqrt()
            / na;
        out.push(ModeError {
            truth: r,
            freq_rel: (est.frequency_hz - f).abs() / f,
            damp_rel: (est.damping_ratio - s.modes[r].damping_ratio).abs()
                / s.modes[r].damping_ratio,
            mac: mac(&est.residues, &ta),
            amp_rel: amp,
        });
    }
    out
}

pub fn modes_of<'a>(all: &'a [ModeEstimate], excitation: &str) -> Vec<ModeEstimate> {
    all.iter()
        .filter(|m| m.excitation == excitation)
        .cloned()
        .collect()
}
