//! The χ² model-order tests after the refinement (on the refinement lines, one pole's
//! 2 + 2·channels parameters at p = `order_test_z`): intermittently stable diagram
//! clusters added when significant, close or low-confidence poles pruned when not
//! (over-split pairs), poles split when a partner half a bandwidth away is significant
//! (merged pairs); and the report of close pairs.

use super::poles::PoleTrack;
use super::{in_sigma2, test_variance, warn_multiplicity, Multiplicity, MultiplicityWarning};
use crate::band::BandData;
use crate::lsfd::{self, Residuals};
use crate::options::PoleSearchParams;
use crate::pole::Pole;
use crate::stabilisation::{self};
use rbprops_core::c64;

/// Close pairs: says plainly when two poles cannot be told apart (closer than
/// `inseparable_bandwidths`, or than twice their combined frequency standard deviation:
/// both lose half their confidence) and notes the close ones (`close_bandwidths`).
pub(super) fn flag_close_pairs(
    track: &mut PoleTrack,
    search: &PoleSearchParams,
    name: &str,
    warnings: &mut Vec<String>,
    multiplicity: &mut Vec<MultiplicityWarning>,
) {
    let PoleTrack {
        poles,
        std,
        confidence,
        mode_warnings,
    } = track;
    for i in 0..poles.len() {
        for j in i + 1..poles.len() {
            let d = poles[i].distance_in_bandwidths(&poles[j]);
            let sep_hz = (poles[j].frequency_hz() - poles[i].frequency_hz()).abs();
            let unc = 2.0 * (std[i].0.powi(2) + std[j].0.powi(2)).sqrt();
            if d < search.inseparable_bandwidths || (unc > 0.0 && sep_hz < unc) {
                let msg = format!(
                    "modes {} and {} ({:.5} and {:.5} Hz, {:.2} half-bandwidths apart) cannot be separated: treat them as one repeated root",
                    i + 1,
                    j + 1,
                    poles[i].frequency_hz(),
                    poles[j].frequency_hz(),
                    d
                );
                warn_multiplicity(
                    warnings,
                    multiplicity,
                    Multiplicity::RepeatedRoot,
                    format!("excitation '{name}': {msg}"),
                );
                mode_warnings[i].push(msg.clone());
                mode_warnings[j].push(msg);
                confidence[i] *= 0.5;
                confidence[j] *= 0.5;
            } else if d < search.close_bandwidths {
                let msg = format!(
                    "close to mode {} ({:.2} half-bandwidths): resolved, but sensitive to noise",
                    if i < j { j + 1 } else { i + 1 },
                    d
                );
                mode_warnings[i].push(msg.clone());
                mode_warnings[j]
                    .push(msg.replace(&format!("mode {}", j + 1), &format!("mode {}", i + 1)));
            }
        }
    }
}

/// The model-order tests after the refinement: the data a refinement runs on (the
/// refinement lines), the χ² threshold for one pole's 2 + 2·channels parameters and the
/// search thresholds.
pub(super) struct OrderTest<'a> {
    pub(super) band: &'a BandData,
    pub(super) chans: &'a [Vec<c64>],
    pub(super) res: Residuals,
    pub(super) threshold: f64,
    pub(super) max_damping: f64,
    /// The whole band's (ω_min, ω_max): where an added mode must lie.
    pub(super) full_band_w: (f64, f64),
    pub(super) search: &'a PoleSearchParams,
    pub(super) name: &'a str,
}

/// The refined poles and what is kept per pole, as the model-order tests change them.
pub(super) struct TrackedPoles<'a> {
    pub(super) r: &'a mut lsfd::Refined,
    pub(super) confidence: &'a mut Vec<f64>,
    pub(super) mode_warnings: &'a mut Vec<Vec<String>>,
    pub(super) warnings: &'a mut Vec<String>,
    pub(super) multiplicity: &'a mut Vec<MultiplicityWarning>,
}

impl OrderTest<'_> {
    /// Residual degrees of freedom with `np` poles: 2 real equations per line and channel
    /// less the 2np + 2 residue and residual-term parameters per channel and the 2np pole
    /// parameters (at least 1).
    pub(super) fn dof(&self, np: usize) -> f64 {
        let (rn, no) = (self.band.n_lines(), self.chans.len());
        (2 * rn * no)
            .saturating_sub(no * (2 * np + 2) + 2 * np)
            .max(1) as f64
    }

    /// Forward model-order step on the residual: a weak mode beside a strong one is often
    /// only intermittently stable in the diagram. Try each rejected cluster as an extra
    /// mode; keep it when the cost drop is significant for the 2 + 2·channels parameters
    /// it adds (χ² at the `order_test_z` level) and the refined pole is physical, separate
    /// and stays within `candidate_drift_bandwidths` of the cluster. A cheap screen (the
    /// cost drop with each candidate as it is, all from one QR, recomputed only after a
    /// candidate is accepted) spares the full refinement for unpromising candidates.
    pub(super) fn add_intermittent_modes(
        &self,
        t: &mut TrackedPoles,
        candidates: &[stabilisation::SelectedPole],
    ) {
        let (band, chans, res, threshold, name) =
            (self.band, self.chans, self.res, self.threshold, self.name);
        let search = self.search;
        let rn = band.n_lines();
        let cand_poles: Vec<Pole> = candidates.iter().map(|c| c.pole).collect();
        let mut screen: Option<(f64, Vec<f64>)> = None;
        for (ci, cand) in candidates.iter().enumerate() {
            let r = &*t.r;
            let mut trial_poles = r.poles.clone();
            if trial_poles
                .iter()
                .any(|p| p.distance_in_bandwidths(&cand.pole) < search.inseparable_bandwidths)
            {
                continue;
            }
            trial_poles.push(cand.pole);
            if 2 * rn <= 2 * (2 * trial_poles.len() + 2) {
                break;
            }
            let dof0 = self.dof(trial_poles.len());
            let (c_now, c_with) = screen.get_or_insert_with(|| {
                crate::prof::time(3, || lsfd::screen_extra_poles(r, &cand_poles, band, chans))
            });
            let c_screen = c_with[ci];
            if (*c_now - c_screen) / test_variance(c_screen, dof0).0 < threshold {
                continue;
            }
            let r2 = crate::prof::time(2, || lsfd::refine(&trial_poles, band, chans, res));
            let added = *r2.poles.last().unwrap();
            let (s2, exact) = test_variance(r2.cost.1, self.dof(r2.poles.len()));
            let separate = r2.poles[..r2.poles.len() - 1]
                .iter()
                .all(|p| p.distance_in_bandwidths(&added) > search.inseparable_bandwidths);
            let physical = added.damping() > 0.0
                && added.damping() < self.max_damping
                && added.omega_n() >= self.full_band_w.0
                && added.omega_n() <= self.full_band_w.1;
            if physical
                && separate
                && !r2.singular
                && added.distance_in_bandwidths(&cand.pole) < search.candidate_drift_bandwidths
                && (r.cost.1 - r2.cost.1) / s2 > threshold
            {
                t.warnings.push(format!(
                    "excitation '{name}': mode at {:.4} Hz added by the residual test (intermittently stable in the diagram, {})",
                    added.frequency_hz(),
                    in_sigma2(
                        || format!("cost −{:.1}σ²", (r.cost.1 - r2.cost.1) / s2),
                        "cost lowered",
                        exact
                    )
                ));
                // Half its diagram presence: it was not stable throughout.
                t.confidence.push(0.5 * cand.presence);
                t.mode_warnings.push(vec![
                    "found by the residual model-order test, not stable throughout the diagram"
                        .into(),
                ]);
                *t.r = r2;
                screen = None;
            }
        }
    }

    /// Backward model-order step: a pole within two half-bandwidths of another, or with
    /// low diagram confidence, is dropped when the refit without it costs less than the
    /// χ² threshold (in units of the residual variance). Over-split close pairs (three
    /// poles for two modes) and weak computational poles go this way.
    pub(super) fn prune_close_poles(&self, t: &mut TrackedPoles) {
        let search = self.search;
        loop {
            let r: &lsfd::Refined = t.r;
            let n = r.poles.len();
            if n < 2 {
                return;
            }
            let suspect = |i: usize| {
                t.confidence[i] < search.suspect_confidence
                    || (0..n).any(|j| {
                        j != i
                            && r.poles[i].distance_in_bandwidths(&r.poles[j])
                                < search.close_bandwidths
                    })
            };
            let (s2, exact) = test_variance(r.cost.1, self.dof(n));
            // The least significant suspect pole, if any is insignificant.
            let weakest = (0..n)
                .filter(|&i| suspect(i))
                .map(|i| {
                    let rest: Vec<Pole> = (0..n).filter(|&j| j != i).map(|j| r.poles[j]).collect();
                    let ri = crate::prof::time(2, || {
                        lsfd::refine(&rest, self.band, self.chans, self.res)
                    });
                    (i, (ri.cost.1 - r.cost.1) / s2, ri)
                })
                .filter(|(_, gain, ri)| *gain < self.threshold && !ri.singular)
                .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
            let Some((i, gain, ri)) = weakest else { return };
            t.warnings.push(format!(
            "excitation '{}': pole at {:.4} Hz dropped by the backward model-order test (it {}, below the χ² threshold {:.1})",
            self.name,
            r.poles[i].frequency_hz(),
            in_sigma2(
                || format!("lowers the cost by only {gain:.1}σ²"),
                "lowers the cost",
                exact
            ),
            self.threshold
        ));
            t.confidence.remove(i);
            t.mode_warnings.remove(i);
            *t.r = ri;
        }
    }

    /// Forward model-order step for merged pairs: a pair closer than its half-power
    /// bandwidth can come out of the diagram as one pole. Each pole gets a partner a
    /// little below and above it (screened from one QR); the best significant one is
    /// refined jointly and kept when the χ² drop is significant and the pair stays
    /// separate, physical and identifiable. A partner is not split again: a merged pair
    /// is two modes, and a partner's partner fitted a systematic residual instead (on
    /// impact data, the force channel's noise through its window, a smooth error common
    /// to an excitation's channels): a cascade of splits, the partners running off by
    /// whole hertz, left 62–89 spurious modes on 4 of 40 Test Case II impact tests
    /// (docs/results.md, session 26).
    pub(super) fn split_merged_poles(&self, t: &mut TrackedPoles) {
        let TrackedPoles {
            r,
            confidence,
            mode_warnings,
            warnings,
            multiplicity,
        } = t;
        let r: &mut lsfd::Refined = r;
        let (band, chans, res, threshold, name) =
            (self.band, self.chans, self.res, self.threshold, self.name);
        let (search, max_damping) = (self.search, self.max_damping);
        let band_w = (band.omega[0], *band.omega.last().unwrap());
        let mut partner_of_split = vec![false; r.poles.len()];
        let mut tried = 0;
        while tried < r.poles.len() {
            let n = r.poles.len();
            if 2 * band.n_lines() <= 2 * (2 * (n + 1) + 2) {
                return;
            }
            let partners: Vec<(usize, Pole)> = r
                .poles
                .iter()
                .enumerate()
                .filter(|(i, _)| !partner_of_split[*i])
                .flat_map(|(i, p)| {
                    let d = search.split_offset_bandwidths * p.half_bandwidth();
                    [-d, d].map(|x| (i, Pole(p.0 + c64::new(0.0, x))))
                })
                .filter(|(_, p)| p.0.im > band_w.0 && p.0.im < band_w.1)
                .collect();
            let cands: Vec<Pole> = partners.iter().map(|(_, p)| *p).collect();
            let (c_now, c_with) =
                crate::prof::time(3, || lsfd::screen_extra_poles(r, &cands, band, chans));
            let dof = self.dof(n + 1);
            let best = c_with
                .iter()
                .enumerate()
                .map(|(k, c)| (k, (c_now - c) / test_variance(*c, dof).0))
                .filter(|(_, g)| *g > threshold)
                .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)));
            let Some((k, _)) = best else { return };
            let (i, partner) = partners[k];
            let mut trial = r.poles.clone();
            trial.push(partner);
            let r2 = crate::prof::time(2, || lsfd::refine(&trial, band, chans, res));
            let added = *r2.poles.last().unwrap();
            let (s2, exact) = test_variance(r2.cost.1, dof);
            let gain = (r.cost.1 - r2.cost.1) / s2;
            let separate = r2.poles[..n]
                .iter()
                .all(|p| p.distance_in_bandwidths(&added) > search.inseparable_bandwidths);
            let physical = added.damping() > 0.0
                && added.damping() < max_damping
                && added.omega_n() >= band_w.0
                && added.omega_n() <= band_w.1;
            if !(physical && separate && !r2.singular && gain > threshold) {
                return;
            }
            warn_multiplicity(
                warnings,
                multiplicity,
                Multiplicity::SplitPair,
                format!(
                    "excitation '{name}': pole at {:.4} Hz split into {:.4} and {:.4} Hz by the forward model-order test ({}): a close pair",
                    r.poles[i].frequency_hz(),
                    r2.poles[i].frequency_hz(),
                    added.frequency_hz(),
                    in_sigma2(|| format!("cost −{gain:.1}σ²"), "cost lowered", exact)
                ),
            );
            confidence.push(confidence[i]);
            partner_of_split.push(true);
            mode_warnings.push(vec![format!(
                "split from the pole at {:.4} Hz by the forward model-order test (close pair)",
                r.poles[i].frequency_hz()
            )]);
            *r = r2;
            tried += 1;
        }
    }
}
