//! Poles of one excitation (or set-up): sweeps ([`super::sweeps`]), automatic
//! selection, the joint refinement that drops poles the data do not support, the
//! model-order tests ([`super::order_tests`]) and the close-pair report.

use super::order_tests::{flag_close_pairs, OrderTest, TrackedPoles};
use super::sweeps::{order_limit, safety_sweeps, sweep_plan, Sweeper};
use super::{modal_std, warn_multiplicity, Multiplicity, MultiplicityWarning, PoleSet};
use crate::band::BandData;
use crate::lsfd::{self, Residuals};
use crate::options::{FitOptions, Method};
use crate::pole::Pole;
use crate::stabilisation::{self};
use crate::ModalError;
use rbprops_core::c64;
use rbprops_core::stats::chi2_isf_wilson_hilferty;

/// Refinement lines: every line within this many half-power half-bandwidths of a pole
/// (≈ 97 % of the pole information, see `BandData::focus_indices`) …
pub(super) const FOCUS_HALF_WIDTHS: f64 = 20.0;
/// … plus this many evenly spaced lines over the band.
pub(super) const SKELETON_LINES: usize = 256;

/// The lines `keep` of every channel.
pub(super) fn select_lines(chans: &[Vec<c64>], keep: &[usize]) -> Vec<Vec<c64>> {
    chans
        .iter()
        .map(|h| keep.iter().map(|&k| h[k]).collect())
        .collect()
}

/// Poles from the channels `chans` of `band` (one excitation, or a whole set-up).
pub(super) fn estimate_poles(
    band: &BandData,
    chans: &[Vec<c64>],
    opts: &FitOptions,
    name: &str,
) -> Result<PoleSet, ModalError> {
    estimate_poles_from(band, chans, opts, name, None)
}

/// The per-pole results while the refinement and the model-order tests change the poles.
pub(super) struct PoleTrack {
    pub(super) poles: Vec<Pole>,
    /// Standard deviations of (f Hz, ζ) per pole.
    pub(super) std: Vec<(f64, f64)>,
    pub(super) confidence: Vec<f64>,
    pub(super) mode_warnings: Vec<Vec<String>>,
}

/// How the drop-and-refine stage ended.
pub(super) enum Refinement {
    /// The refined poles (possibly none left).
    Refined(lsfd::Refined),
    /// A dropped pole showed that the modes sit low in the band: the whole estimate was
    /// redone on a sub-band; its result.
    Restarted(PoleSet),
}

/// As [`estimate_poles`], with the pole-estimation sub-band capped at `cap_hz`.
///
/// Stages: the model-order limit ([`order_limit`]), the sweep plan that chooses the
/// sub-band of the stabilisation diagram ([`sweep_plan`]), the lower-band safety sweeps
/// ([`safety_sweeps`]), the refinement that drops computational poles
/// ([`refine_supported`]), the χ² model-order tests ([`OrderTest`]) and the close-pair
/// report ([`flag_close_pairs`]). Thresholds: [`crate::PoleSearchParams`].
pub(super) fn estimate_poles_from(
    band: &BandData,
    chans: &[Vec<c64>],
    opts: &FitOptions,
    name: &str,
    cap_hz: Option<f64>,
) -> Result<PoleSet, ModalError> {
    let n = band.n_lines();
    let mut warnings = Vec::new();
    let mut multiplicity = Vec::new();
    let n_max = order_limit(n, opts, name, &mut warnings)?;
    let sweeper = Sweeper { chans, opts, name };
    let (sub, mut sel) = sweep_plan(band, cap_hz, &sweeper, &mut warnings)?;
    if opts.n_modes.is_none() {
        safety_sweeps(&sub, &mut sel, &sweeper)?;
    }
    warnings.extend(
        sel.warnings
            .iter()
            .map(|w| format!("excitation '{name}': {w}")),
    );
    if sel.modes.is_empty() {
        return Err(ModalError::NoModes {
            excitation: name.into(),
            reason: format!(
                "{} poles in the diagram up to order {n_max}, none stable in frequency, damping and shape",
                sel.diagram.poles.len()
            ),
        });
    }
    let mut track = PoleTrack {
        poles: sel.modes.iter().map(|m| m.pole).collect(),
        std: sel.modes.iter().map(|m| m.spread).collect(),
        confidence: sel.modes.iter().map(|m| m.presence).collect(),
        mode_warnings: vec![Vec::new(); sel.modes.len()],
    };
    let res = Residuals::for_band(opts.residual_terms, band);
    // Refinement and model-order test on the lines that carry the pole information:
    // those near the selected poles and the candidates the residual test may add, plus
    // an even skeleton for the residual terms (see `BandData::focus_indices`). The
    // residues are then fitted on every line.
    let focus: Vec<Pole> = track
        .poles
        .iter()
        .copied()
        .chain(sel.candidates.iter().map(|c| c.pole))
        .collect();
    let keep = band.focus_indices(&focus, FOCUS_HALF_WIDTHS, 4.0, SKELETON_LINES);
    let rband = band.lines(&keep);
    let rchans = select_lines(chans, &keep);
    let rn = rband.n_lines();
    if opts.refine && opts.method != Method::Circle {
        let rows = 2 * rn;
        let unknowns = 2 * track.poles.len() + 2;
        if rows <= unknowns + 2 * track.poles.len() {
            warnings.push(format!(
                "excitation '{name}': {n} lines are too few to refine {} poles; LSCF poles kept",
                track.poles.len()
            ));
        } else {
            let refine = RefineInputs {
                band,
                chans,
                rband: &rband,
                rchans: &rchans,
                res,
                opts,
                name,
                cap_hz,
                sub_top_hz: *sub.frequency_hz.last().unwrap(),
            };
            let tested = refine_and_test_order(
                &refine,
                &sel.candidates,
                &mut track,
                (&mut warnings, &mut multiplicity),
            )?;
            if let Some(restarted) = tested {
                return Ok(restarted);
            }
        }
    }
    let mut track = track.sorted();
    flag_close_pairs(
        &mut track,
        &opts.search,
        name,
        &mut warnings,
        &mut multiplicity,
    );
    Ok(PoleSet {
        poles: track.poles,
        std: track.std,
        confidence: track.confidence,
        mode_warnings: track.mode_warnings,
        diagram: sel.diagram,
        warnings,
        multiplicity,
    })
}

/// The refinement that drops unsupported poles ([`refine_supported`]), then, unless
/// the mode count is forced, the χ² model-order tests ([`OrderTest`]): intermittent
/// candidates added, over-split pairs pruned, merged pairs split. Leaves the refined
/// poles and their standard deviations in `track`; `Some` when a dropped pole sent
/// the estimate to a sub-band and it was redone there (its result).
pub(super) fn refine_and_test_order(
    refine: &RefineInputs,
    candidates: &[stabilisation::SelectedPole],
    track: &mut PoleTrack,
    (warnings, multiplicity): (&mut Vec<String>, &mut Vec<MultiplicityWarning>),
) -> Result<Option<PoleSet>, ModalError> {
    let (opts, name) = (refine.opts, refine.name);
    let mut r = match refine_supported(refine, track, warnings)? {
        Refinement::Refined(r) => r,
        Refinement::Restarted(ps) => return Ok(Some(ps)),
    };
    if track.poles.is_empty() {
        return Err(ModalError::NoModes {
            excitation: name.into(),
            reason: "every selected pole was dropped by the refinement".into(),
        });
    }
    if opts.n_modes.is_none() {
        let (band, chans) = (refine.band, refine.chans);
        let test = OrderTest {
            band: refine.rband,
            chans: refine.rchans,
            res: refine.res,
            threshold: chi2_isf_wilson_hilferty(
                opts.search.order_test_z,
                (2 + 2 * chans.len()) as f64,
            ),
            max_damping: opts.tolerances.max_damping,
            full_band_w: (band.omega[0], *band.omega.last().unwrap()),
            search: &opts.search,
            name,
        };
        let mut tracked = TrackedPoles {
            r: &mut r,
            confidence: &mut track.confidence,
            mode_warnings: &mut track.mode_warnings,
            warnings,
            multiplicity,
        };
        test.add_intermittent_modes(&mut tracked, candidates);
        test.prune_close_poles(&mut tracked);
        test.split_merged_poles(&mut tracked);
    }
    if r.singular {
        warn_multiplicity(
            warnings,
            multiplicity,
            Multiplicity::SingularInformation,
            format!(
                "excitation '{name}': the poles are not all identifiable (singular information matrix): two poles cannot be separated"
            ),
        );
    }
    if !r.converged {
        warnings.push(format!(
            "excitation '{name}': pole refinement did not converge in {} iterations",
            r.iterations
        ));
    }
    track.poles = r.poles.clone();
    track.std = track
        .poles
        .iter()
        .zip(&r.covariance)
        .map(|(p, c)| modal_std(p, c))
        .collect();
    Ok(None)
}

/// What the drop-and-refine stage reads: the whole band (for a restart), the refinement
/// lines, and the top of the sub-band the diagram was drawn on.
pub(super) struct RefineInputs<'a> {
    pub(super) band: &'a BandData,
    pub(super) chans: &'a [Vec<c64>],
    pub(super) rband: &'a BandData,
    pub(super) rchans: &'a [Vec<c64>],
    pub(super) res: Residuals,
    pub(super) opts: &'a FitOptions,
    pub(super) name: &'a str,
    pub(super) cap_hz: Option<f64>,
    pub(super) sub_top_hz: f64,
}

/// Refines the poles jointly ([`lsfd::refine`]). Refinement is local: a pole it pushes
/// more than `max_refinement_shift_bandwidths` away, out of the band or past the damping
/// limit is not supported by the data (a computational pole that looked stable): drop it
/// and refine again. A spurious high pole can hide that the modes sit low in the band:
/// when one is dropped and the remaining modes sit low, the whole estimate is redone on
/// the lines up to `sub_band_margin` × the highest remaining mode.
pub(super) fn refine_supported(
    p: &RefineInputs,
    track: &mut PoleTrack,
    warnings: &mut Vec<String>,
) -> Result<Refinement, ModalError> {
    let (band, opts, name, search) = (p.band, p.opts, p.name, &p.opts.search);
    let poles = &mut track.poles;
    let mut r = crate::prof::time(2, || lsfd::refine(poles, p.rband, p.rchans, p.res));
    let band_w = (band.omega[0], *band.omega.last().unwrap());
    loop {
        let bad = poles
            .iter()
            .zip(&r.poles)
            .enumerate()
            .map(|(i, (a, b))| {
                let off = b.damping() >= opts.tolerances.max_damping
                    || b.omega_n() < band_w.0
                    || b.omega_n() > band_w.1;
                (
                    i,
                    if off {
                        f64::INFINITY
                    } else {
                        a.distance_in_bandwidths(b)
                    },
                )
            })
            .filter(|(_, d)| *d > search.max_refinement_shift_bandwidths)
            .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)));
        let Some((i, d)) = bad else { break };
        warnings.push(format!(
            "excitation '{name}': pole at {:.4} Hz dropped: the refinement could not hold it (moved {d:.1} half-bandwidths or left the band), so it is computational",
            poles[i].frequency_hz()
        ));
        poles.remove(i);
        if let Some(f_top) = poles.iter().map(|p| p.frequency_hz()).reduce(f64::max) {
            let cap = search.sub_band_margin * f_top;
            let lines = band.frequency_hz.partition_point(|&f| f <= cap);
            if p.cap_hz.is_none()
                && cap < search.sub_band_max_fraction * p.sub_top_hz
                && lines >= 4 * opts.max_order.max(8)
            {
                let mut ps = estimate_poles_from(band, p.chans, opts, name, Some(cap))?;
                let mut w = warnings.clone();
                w.append(&mut ps.warnings);
                ps.warnings = w;
                return Ok(Refinement::Restarted(ps));
            }
        }
        track.std.remove(i);
        track.confidence.remove(i);
        track.mode_warnings.remove(i);
        if poles.is_empty() {
            break;
        }
        r = crate::prof::time(2, || lsfd::refine(poles, p.rband, p.rchans, p.res));
    }
    Ok(Refinement::Refined(r))
}

impl PoleTrack {
    /// Sorted by natural frequency (refinement may reorder two close poles).
    pub(super) fn sorted(self) -> Self {
        let mut idx: Vec<usize> = (0..self.poles.len()).collect();
        idx.sort_by(|&a, &b| self.poles[a].omega_n().total_cmp(&self.poles[b].omega_n()));
        Self {
            poles: idx.iter().map(|&i| self.poles[i]).collect(),
            std: idx.iter().map(|&i| self.std[i]).collect(),
            confidence: idx.iter().map(|&i| self.confidence[i]).collect(),
            mode_warnings: idx.iter().map(|&i| self.mode_warnings[i].clone()).collect(),
        }
    }
}
