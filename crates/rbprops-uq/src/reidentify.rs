//! Modal re-identification of one bootstrap replicate.

use crate::model::{ExcitationModel, FittedModel};
use crate::scratch::{Scratch, SharedStore};
use rand_chacha::ChaCha8Rng;
use rbprops_core::records::{ModalFitRecord, ModeEstimate};
use rbprops_core::{c64, FrfSet, Geometry};
use rbprops_modal::band::BandData;
use rbprops_modal::lsfd::{self, Residuals};
use rbprops_modal::{fit_campaign, fit_excitation, mac, mpc, FitOptions, PoleMode};
use std::borrow::Cow;

/// How a replicate's modes are identified.
#[derive(Debug, Clone, PartialEq)]
pub enum Reidentify {
    /// The modal fit's final stages, started from the record's poles: variable-projection
    /// refinement of the poles ([`lsfd::refine`], jointly over the group's live channels)
    /// and LSFD residues ([`lsfd::fit_residues`]) on the replicate's band. The pole
    /// estimates of the modal fit are exactly such a least-squares optimum (the
    /// stabilisation diagram only supplies starting values), so this reproduces the
    /// estimator's scatter at a fraction of the cost. Mode numbers are kept.
    Refine,
    /// The whole modal identification (stabilisation diagram, selection, refinement,
    /// residues) with these options, then each selected mode is found again by MAC
    /// and pole distance.
    Full(FitOptions),
}

/// Tolerances of the re-identification.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MatchTolerances {
    /// A replicate pole further than this many half-power half-bandwidths from the
    /// record's pole is not the same mode (the modal fit drops poles that move > 10).
    pub max_shift_bandwidths: f64,
    /// [`Reidentify::Full`]: lowest MAC between the record's and the replicate's residues.
    pub min_mac: f64,
    /// Poles with damping at or above this are not physical (the fit's default 0.2).
    pub max_damping: f64,
}

impl Default for MatchTolerances {
    fn default() -> Self {
        Self {
            max_shift_bandwidths: 10.0,
            min_mac: 0.9,
            max_damping: 0.2,
        }
    }
}

/// The modes of one refitted excitation and the map from the record's mode numbers to
/// the replicate's.
#[derive(Debug, Clone)]
pub struct ReplicateModes {
    /// Excitation id.
    pub excitation: String,
    /// The replicate's modes of this excitation.
    pub modes: Vec<ModeEstimate>,
    /// `(record mode number, replicate mode number)` of every mode found again.
    pub mode_map: Vec<(usize, usize)>,
}

/// The replicate's grid `band` with the replicate's values `channels`.
fn band_with(band: &BandData, channels: Vec<Vec<c64>>) -> BandData {
    BandData {
        quantity: band.quantity,
        frequency_hz: band.frequency_hz.clone(),
        omega: band.omega.clone(),
        channels,
        first_line: band.first_line,
        line_quality: band.line_quality.clone(),
    }
}

/// One replicate's draws of a group's excitations, `[member][channel][grid line]`: held,
/// or, when more than the scratch holds, in a store of the replicate's own (issue 41's
/// memory bound: a set-up of 192 excitations drew 44 MB per replicate in flight).
struct GroupDraws {
    held: Vec<Vec<Vec<c64>>>,
    store: Option<SharedStore>,
    /// Channels and grid lines of every member.
    shape: (usize, usize),
}

impl GroupDraws {
    /// Draws the members of `group` in turn from `rng` (the order [`FittedModel`] lists
    /// them in, so the values do not depend on where they are kept); with the first
    /// member's grid (its lines; its values are the draws').
    fn draw(
        model: &FittedModel,
        group: &[usize],
        rng: &mut ChaCha8Rng,
        scratch: Option<&Scratch>,
    ) -> std::io::Result<(Self, BandData)> {
        let e = &model.excitations[group[0]];
        let n = e.stored_lines.unwrap_or(e.draw_band.n_lines());
        let shape = (e.noise.len(), n);
        let store = Scratch::store_for(scratch, group.len() * shape.0 * n * 16);
        let mut first = None;
        let mut held = Vec::new();
        for &i in group {
            let grid = model.grid(i)?;
            let d = model.excitations[i].draw(&grid, rng);
            if first.is_none() {
                first = Some(band_with(&grid.band, Vec::new()));
            }
            match &store {
                Some(s) => {
                    s.put_channels(held.len(), &d, &[])?;
                    held.push(Vec::new());
                }
                None => held.push(d),
            }
        }
        let first = first.expect("a group has a member");
        Ok((Self { held, store, shape }, first))
    }

    /// Member `k`'s draws, taken (a held member's are moved out).
    fn take(&mut self, k: usize) -> std::io::Result<Vec<Vec<c64>>> {
        match &self.store {
            None => Ok(std::mem::take(&mut self.held[k])),
            Some(s) => Ok(s.channels(k, self.shape.0, self.shape.1, 0)?.0),
        }
    }
}

/// The live channels of a group's draws, as the joint refinement reads them (one at a
/// time, once per trial); a failed store read is kept and reported after the refinement.
struct LiveChannels<'a> {
    draws: &'a GroupDraws,
    /// `(member, channel)` of each.
    live: Vec<(usize, usize)>,
    failed: std::sync::Mutex<Option<String>>,
}

impl lsfd::Channels for LiveChannels<'_> {
    fn count(&self) -> usize {
        self.live.len()
    }
    fn channel(&self, o: usize) -> Cow<'_, [c64]> {
        let (k, c) = self.live[o];
        let Some(s) = &self.draws.store else {
            return Cow::Borrowed(&self.draws.held[k][c]);
        };
        let n = self.draws.shape.1;
        s.channel(k, c, n).map(Cow::Owned).unwrap_or_else(|e| {
            let mut f = self.failed.lock().unwrap_or_else(|p| p.into_inner());
            f.get_or_insert_with(|| e.to_string());
            Cow::Owned(vec![c64::new(0.0, 0.0); n])
        })
    }
}

/// Re-identifies one group of [`FittedModel::groups`] by [`Reidentify::Refine`] on a
/// replicate's draws of its members from `rng` (held, or kept in a store of `scratch`'s
/// when larger than it holds: the same values either way, so the same modes).
pub fn refine_group(
    model: &FittedModel,
    group: &[usize],
    (rng, scratch): (&mut ChaCha8Rng, Option<&Scratch>),
    modal: &ModalFitRecord,
    tol: &MatchTolerances,
) -> Result<Vec<ReplicateModes>, String> {
    let scratch_error = |e: std::io::Error| format!("bootstrap scratch store: {e}");
    let first = &model.excitations[group[0]];
    let (mut draws, band0) = GroupDraws::draw(model, group, rng, scratch).map_err(scratch_error)?;
    let chans = LiveChannels {
        live: group
            .iter()
            .enumerate()
            .flat_map(|(k, &i)| model.excitations[i].live.iter().map(move |&c| (k, c)))
            .collect(),
        draws: &draws,
        failed: Default::default(),
    };
    let res = Residuals::for_band(model.residuals_enabled, &band0);
    let refined = lsfd::refine_channels(&first.poles, &band0, &chans, res);
    if let Some(e) = chans.failed.into_inner().unwrap_or_else(|p| p.into_inner()) {
        return Err(format!("bootstrap scratch store: {e}"));
    }
    let poles = checked_poles(model, group, &refined.poles, &band0, tol)?;
    let mut out = Vec::with_capacity(group.len());
    for (k, &i) in group.iter().enumerate() {
        let e = &model.excitations[i];
        let data = draws.take(k).map_err(scratch_error)?;
        let band = match k {
            0 => band_with(&band0, data),
            _ => band_with(&model.grid(i).map_err(scratch_error)?.band, data),
        };
        let band = &band;
        let own =
            (group.len() == 1 && poles == refined.poles).then(|| own_residues(&refined, e, band));
        let fitted = own
            .flatten()
            .unwrap_or_else(|| lsfd::fit_residues(&poles, band, &band.channels, res).residues);
        let mut modes = Vec::with_capacity(e.poles.len());
        for (m, p) in poles.iter().enumerate() {
            let number = e.mode_numbers[m];
            let orig = modal
                .modes
                .iter()
                .find(|x| x.excitation == e.id && x.mode == number)
                .expect("the model was built from these modes");
            let residues: Vec<c64> = fitted[m].iter().map(|r| p.modal_constant(*r)).collect();
            modes.push(ModeEstimate {
                frequency_hz: p.frequency_hz(),
                damping_ratio: p.damping(),
                mpc: mpc(&residues),
                // Zero input errors: the replicate's estimate needs no propagation.
                residue_std: vec![0.0; residues.len()],
                residues,
                ..orig.clone()
            });
        }
        out.push(ReplicateModes {
            excitation: e.id.clone(),
            modes,
            mode_map: e.mode_numbers.iter().map(|&n| (n, n)).collect(),
        });
    }
    Ok(out)
}

/// The replicate's poles of `group` after the refinement (`refined`), checked against
/// the record's: a pole that moved more than the tolerated half-bandwidths, or left the
/// band or the damping range, is no longer the same mode. When the selection takes a
/// shape from it the replicate fails; otherwise it is held at the record's pole (and the
/// residues are fitted at the poles so held).
///
/// Why the latter: a modal fit weighted by an estimator's small line variances keeps
/// poles the selection does not use (a spurious 6 Hz pole beside the six rigid-body
/// modes of an impact test through frf-est, a weak estimate of a mode another
/// excitation supplies) that are no least-squares optimum of the refinement; they ran
/// away in 99 of 100 replicates and the bootstrap fell back to the linearised errors
/// (docs/results.md, session 35). The estimates never read those poles.
fn checked_poles(
    model: &FittedModel,
    group: &[usize],
    refined: &[rbprops_modal::Pole],
    band: &BandData,
    tol: &MatchTolerances,
) -> Result<Vec<rbprops_modal::Pole>, String> {
    let first = &model.excitations[group[0]];
    let (w_lo, w_hi) = (band.omega[0], *band.omega.last().unwrap());
    let mut poles = refined.to_vec();
    for (m, (p0, p)) in first.poles.iter().zip(refined).enumerate() {
        let d = p0.distance_in_bandwidths(p);
        let same_mode = d <= tol.max_shift_bandwidths
            && p.damping() > 0.0
            && p.damping() < tol.max_damping
            && p.omega_n() >= w_lo
            && p.omega_n() <= w_hi;
        if same_mode {
            continue;
        }
        if group.iter().any(|&i| model.excitations[i].selected[m]) {
            return Err(format!(
                "excitation '{}' mode {}: the refined pole ({:.5} Hz, ζ {:.4}) moved {d:.1} half-bandwidths from {:.5} Hz or left the band / damping range",
                first.id,
                first.mode_numbers[m],
                p.frequency_hz(),
                p.damping(),
                p0.frequency_hz()
            ));
        }
        poles[m] = *p0;
    }
    Ok(poles)
}

/// The residues of every channel of excitation `e` from the refinement itself, when it
/// refined `e` alone (a group of one: its live channels, the replicate's others all zero, so
/// their residues are zero): the LSFD solution at the refined poles that
/// [`lsfd::fit_residues`] would compute again (issue 41: that second fit was a sixth of a
/// replicate's cost). `None` for a group of several excitations, whose refinement
/// weighted the lines by all of them.
fn own_residues(
    refined: &lsfd::Refined,
    e: &ExcitationModel,
    band: &BandData,
) -> Option<Vec<Vec<c64>>> {
    let dead_are_zero = band
        .channels
        .iter()
        .enumerate()
        .filter(|(c, _)| !e.live.contains(c))
        .all(|(_, h)| h.iter().all(|z| z.norm_sqr() == 0.0));
    let residues = refined.residues();
    if residues.first().map(Vec::len) != Some(e.live.len()) || !dead_are_zero {
        return None;
    }
    Some(
        residues
            .into_iter()
            .map(|live| {
                let mut all = vec![c64::new(0.0, 0.0); band.channels.len()];
                for (&c, r) in e.live.iter().zip(live) {
                    all[c] = r;
                }
                all
            })
            .collect(),
    )
}

/// Re-identifies every excitation of `model` by [`Reidentify::Full`]: the replicate's
/// band data replace the measured lines, the modal fit runs with `opts`, and each of the
/// record's modes of the refitted excitations is matched to the replicate mode of highest
/// pole proximity among those with MAC ≥ `min_mac` (a mode with no match is an error only
/// if `required` lists it).
pub fn full_refit(
    geometry: &Geometry,
    frf: &FrfSet,
    model: &FittedModel,
    data: &[Vec<Vec<c64>>],
    modal: &ModalFitRecord,
    opts: &FitOptions,
    required: &[(String, usize)],
    tol: &MatchTolerances,
) -> Result<Vec<ReplicateModes>, String> {
    let mut frf_b = frf.clone();
    for (e, d) in model.excitations.iter().zip(data) {
        for (c, h) in d.iter().enumerate() {
            let dst = frf_b.frf_mut(e.excitation, c);
            dst[e.band.first_line..e.band.first_line + h.len()].copy_from_slice(h);
        }
    }
    let fits: Vec<(String, Vec<ModeEstimate>)> = match opts.poles {
        PoleMode::PerSetup => {
            let out = fit_campaign(geometry, &frf_b, opts).map_err(|e| e.to_string())?;
            model
                .excitations
                .iter()
                .map(|e| {
                    let modes = out
                        .record
                        .modes
                        .iter()
                        .filter(|m| m.excitation == e.id)
                        .cloned()
                        .collect();
                    (e.id.clone(), modes)
                })
                .collect()
        }
        PoleMode::PerExcitation => model
            .excitations
            .iter()
            .map(|e| {
                fit_excitation(geometry, &frf_b, e.excitation, opts)
                    .map(|f| (e.id.clone(), f.modes))
                    .map_err(|err| format!("excitation '{}': {err}", e.id))
            })
            .collect::<Result<_, _>>()?,
    };
    let mut out = Vec::new();
    for (e, (id, mut modes)) in model.excitations.iter().zip(fits) {
        for m in &mut modes {
            m.residue_std.iter_mut().for_each(|s| *s = 0.0);
        }
        let mut map = Vec::new();
        for (k, &number) in e.mode_numbers.iter().enumerate() {
            let orig = modal
                .modes
                .iter()
                .find(|x| x.excitation == id && x.mode == number)
                .expect("the model was built from these modes");
            let p0 = e.poles[k];
            let best = modes
                .iter()
                .filter(|m| mac(&m.residues, &orig.residues) >= tol.min_mac)
                .map(|m| {
                    let p = rbprops_modal::Pole::from_modal(m.frequency_hz, m.damping_ratio);
                    (m.mode, p0.distance_in_bandwidths(&p))
                })
                .filter(|(_, d)| *d <= tol.max_shift_bandwidths)
                .min_by(|a, b| a.1.total_cmp(&b.1));
            match best {
                Some((n, _)) if !map.iter().any(|(_, m)| *m == n) => map.push((number, n)),
                _ if required.iter().any(|(x, n)| *x == id && *n == number) => {
                    return Err(format!(
                        "excitation '{id}' mode {number} ({:.5} Hz) was not found again (MAC ≥ {} within {} half-bandwidths, not taken by another mode)",
                        orig.frequency_hz, tol.min_mac, tol.max_shift_bandwidths
                    ))
                }
                _ => {}
            }
        }
        out.push(ReplicateModes {
            excitation: id,
            modes,
            mode_map: map,
        });
    }
    Ok(out)
}
