//! One pool's physical modes: matching and consolidation, then each mode's table of
//! excitations with their indicators and eligibility.

use super::{
    check_manual_modes, choose, db10, excitation_summaries, ranking, strength_matrix,
    CriterionChoices, Member, ModeExcitation, ModeGroup, PhysicalModes, PoolChoices, PoolInputs,
    PoolResult, RejectedEstimate,
};
use crate::consolidate::{consolidate, estimate_quality, Evidence, RIGID_BODY_MODES};
use crate::indicators::{local_spacing, window_lines};
use crate::matching::{mac, match_candidates, reference_member, Candidate};
use crate::{diagnostic, NiError};
use rbprops_core::records::{Diagnostic, DiagnosticKind, DiagnosticSubject, Severity};

/// Processes one pool: (1) pool building and matching, (2) consolidation into at most six
/// physical modes ([`physical_modes`]); then for each mode (3) the excitation table with
/// eligibility ([`mode_table`]) and (4) the choice ([`choose`]); finally the
/// per-excitation summaries and the strength matrix.
pub(super) fn process_pool(p: &PoolInputs) -> Result<PoolResult, NiError> {
    let mut warnings = Vec::new();
    let modes = physical_modes(p, &mut warnings);
    let floor_db = noise_floor_db(p, &modes.groups);
    let mut mode_groups = Vec::with_capacity(modes.groups.len());
    let mut choices = PoolChoices::default();
    let mut per_excitation: Vec<Vec<ModeExcitation>> = vec![Vec::new(); p.pool.excitations.len()];
    for (gi, group) in modes.groups.iter().enumerate() {
        let mode = gi + 1;
        let rm = &p.members[reference_member(group, &modes.cands)];
        let table = mode_table(p, mode, group, rm, floor_db);
        let by = CriterionChoices::of(&table);
        let g = ModeGroup {
            setup: p.pool.label.clone(),
            mode,
            frequency_hz: p.estimate(rm).frequency_hz,
            damping_ratio: p.estimate(rm).damping_ratio,
            reference_excitation: p.excitation_id(rm.excitation),
            ranking: ranking(&table, p.opts.criterion),
            choice_ni: by.ni.clone(),
            choice_hybrid_mif: by.hybrid_mif.clone(),
            choice_prf_mif: by.prf_mif.clone(),
            choice_strength: by.strength.clone(),
        };
        if let Some(d) = by.disagreement(&p.pool.label, mode, g.frequency_hz) {
            choices.disagreements.push(d);
        }
        choose(p, &g, group, &table, &by, &mut choices)?;
        for (slot, row) in per_excitation.iter_mut().zip(&table) {
            slot.push(row.clone());
        }
        mode_groups.push(g);
    }
    check_manual_modes(p, mode_groups.len())?;
    warnings.append(&mut choices.warnings);
    let summaries = excitation_summaries(p, per_excitation, &mode_groups, &mut warnings);
    let matrix = strength_matrix(p, &mode_groups, &summaries);
    Ok(PoolResult {
        rejected: modes.rejected,
        selected: choices.selected,
        missing: choices.missing,
        diagnostics: warnings,
        summaries,
        groups: mode_groups,
        matrix,
        disagreements: choices.disagreements,
    })
}

/// Pool building, matching and consolidation: the members become matcher candidates,
/// are matched across excitations by frequency and MAC ([`match_candidates`]) and
/// consolidated into at most six rigid-body modes ([`consolidate`]). Warns when more than
/// six or fewer than six modes come out.
pub(super) fn physical_modes(p: &PoolInputs, warnings: &mut Vec<Diagnostic>) -> PhysicalModes {
    let cands: Vec<Candidate> = p
        .members
        .iter()
        .map(|m| Candidate {
            excitation: m.excitation,
            frequency_hz: p.estimate(m).frequency_hz,
            q: m.q,
            strength: m.strength,
            reliable: m.reliable,
        })
        .collect();
    let evidence: Vec<Evidence> = p
        .members
        .iter()
        .map(|m| {
            let est = p.estimate(m);
            Evidence {
                label: format!(
                    "{} mode {} ({:.4} Hz)",
                    est.excitation, est.mode, est.frequency_hz
                ),
                confidence: est.confidence,
                phase: m.phase,
                rigid_residual: m.relative_residual,
                weak: est.weak,
                quality: estimate_quality(est.confidence, m.phase, m.relative_residual),
            }
        })
        .collect();
    let matched = match_candidates(&cands, p.gram, p.tol);
    let n_matched = matched.len();
    let consolidated = consolidate(matched, &cands, &evidence, p.gram, p.tol, &p.pool.label);
    let n_modes = consolidated.groups.len();
    if n_matched > RIGID_BODY_MODES {
        // The surplus is set aside by evidence (each rejection its own note): a note.
        warnings.push(diagnostic(
            DiagnosticKind::ExtraModes,
            Severity::Note,
            DiagnosticSubject::setup(&p.pool.label),
            format!(
                "{n_matched} distinct modes matched, more than the six rigid-body modes \
                 (split, leakage, noise or elastic poles in the modal record); {n_modes} kept"
            ),
        ));
    }
    warnings.extend(consolidated.diagnostics);
    let rejected = consolidated
        .rejected
        .iter()
        .map(|r| {
            let est = p.estimate(&p.members[r.candidate]);
            RejectedEstimate {
                setup: p.pool.label.clone(),
                excitation: est.excitation.clone(),
                excitation_mode: est.mode,
                frequency_hz: est.frequency_hz,
                group_frequency_hz: r.group_frequency_hz,
                reason: r.reason.clone(),
            }
        })
        .collect();
    if n_modes < RIGID_BODY_MODES {
        warnings.push(diagnostic(
            DiagnosticKind::ModeMissing,
            Severity::ChangesAnswer,
            DiagnosticSubject::setup(&p.pool.label),
            format!("only {n_modes} of the six rigid-body modes were identified by any excitation"),
        ));
    }
    PhysicalModes {
        cands,
        groups: consolidated.groups,
        rejected,
    }
}

/// The set-up's noise floor: `min_strength_db` below its strongest reliable estimate kept
/// in a mode (dB re 1/kg). Rejected estimates (a split pole's halves can be "stronger" than
/// the mode) do not set it.
pub(super) fn noise_floor_db(p: &PoolInputs, groups: &[Vec<usize>]) -> Option<f64> {
    let strongest = groups
        .iter()
        .flatten()
        .map(|&i| &p.members[i])
        .filter(|m| m.reliable)
        .map(|m| m.strength)
        .fold(0.0f64, f64::max);
    db10(strongest).map(|d| d - p.opts.min_strength_db)
}

/// Half-width of a mode's band on the frequency axis: its half-power half-width `2ζf_r`,
/// but at least 1.5 line spacings (`spacing`, the local line spacing) so that a lightly
/// damped mode still spans a line.
pub(super) fn mode_half_width(f_r: f64, zeta: f64, spacing: f64) -> f64 {
    (2.0 * zeta * f_r).max(1.5 * spacing)
}

/// How every excitation of the pool does at one physical mode (`group`, with reference
/// member `rm`): the indicators within the mode's band, its own estimate's strength and
/// quality, and whether it is eligible (identified, reliable, above the noise floor, and
/// confident when another excitation is).
pub(super) fn mode_table(
    p: &PoolInputs,
    mode: usize,
    group: &[usize],
    rm: &Member,
    floor_db: Option<f64>,
) -> Vec<ModeExcitation> {
    let rest = p.estimate(rm);
    let (f_r, zeta) = (rest.frequency_hz, rest.damping_ratio);
    let phi_ref = (rm.strength > 0.0).then(|| rm.q / rm.strength.sqrt());
    let half_width = mode_half_width(f_r, zeta, local_spacing(p.frf.frequency_hz(), f_r));
    let lines = window_lines(p.frf.frequency_hz(), f_r, half_width);
    let mut table: Vec<ModeExcitation> = Vec::with_capacity(p.pool.excitations.len());
    for &k in &p.pool.excitations {
        let c = p.curves_of(k);
        let mut row = ModeExcitation {
            mode,
            frequency_hz: f_r,
            excitation: p.excitation_id(k),
            excitation_mode: None,
            weak: false,
            ni_db: c.ni_db[lines.clone()]
                .iter()
                .copied()
                .fold(f64::NEG_INFINITY, f64::max),
            hybrid_mif: c.hybrid_mif[lines.clone()]
                .iter()
                .copied()
                .fold(f64::INFINITY, f64::min),
            prf_mif: c.prf_mif[lines.clone()]
                .iter()
                .copied()
                .fold(f64::INFINITY, f64::min),
            strength: None,
            strength_std: None,
            strength_db: None,
            predicted_strength: phi_ref.map(|phi| p.columns[k].dot(&phi).powi(2)),
            rigid_residual: None,
            mac_to_reference: None,
            confidence: None,
            quality: None,
            eligible: false,
            reason: None,
        };
        let member = group
            .iter()
            .map(|&i| &p.members[i])
            .find(|m| m.excitation == k);
        match member {
            None => row.reason = Some(format!("no mode identified near {f_r:.4} Hz")),
            Some(m) => describe_estimate(p, &mut row, m, rm, floor_db),
        }
        table.push(row);
    }
    demote_low_confidence(&mut table, p.opts.min_confidence);
    table
}

/// Fills `row` from the excitation's own estimate `m` of the mode and decides its
/// eligibility: reliable (not weak, `f_kᵀq` > 0 and above `min_snr` standard errors) and
/// no more than `min_strength_db` below the set-up's strongest.
pub(super) fn describe_estimate(
    p: &PoolInputs,
    row: &mut ModeExcitation,
    m: &Member,
    rm: &Member,
    floor_db: Option<f64>,
) {
    let est = p.estimate(m);
    row.excitation_mode = Some(est.mode);
    row.weak = est.weak;
    row.strength = Some(m.strength);
    row.strength_std = m.strength_std;
    row.strength_db = db10(m.strength);
    row.rigid_residual = Some(m.relative_residual);
    row.mac_to_reference = Some(mac(&m.q, &rm.q, p.gram));
    row.confidence = Some(est.confidence);
    row.quality = Some(estimate_quality(
        est.confidence,
        m.phase,
        m.relative_residual,
    ));
    row.reason = m.why.clone();
    if row.reason.is_none() {
        if let (Some(s_db), Some(floor)) = (row.strength_db, floor_db) {
            if s_db < floor {
                row.reason = Some(format!(
                    "fᵀq = {:.3e} is {:.1} dB below the set-up's strongest (limit {} dB)",
                    m.strength,
                    floor + p.opts.min_strength_db - s_db,
                    p.opts.min_strength_db
                ));
            }
        }
    }
    row.eligible = row.reason.is_none();
}

/// A low-confidence estimate (typically half of a split pole) gives way to any confident
/// one of the same mode: when some eligible row has confidence ≥ `min_confidence`, the
/// eligible rows below it become ineligible.
pub(super) fn demote_low_confidence(table: &mut [ModeExcitation], min_confidence: f64) {
    if table
        .iter()
        .any(|r| r.eligible && r.confidence.is_some_and(|c| c >= min_confidence))
    {
        for row in table.iter_mut().filter(|r| r.eligible) {
            if let Some(c) = row.confidence.filter(|&c| c < min_confidence) {
                row.eligible = false;
                row.reason = Some(format!(
                    "modal-fit confidence {c:.2} is below {min_confidence} and another excitation \
                     gives a confident estimate of this mode"
                ));
            }
        }
    }
}
