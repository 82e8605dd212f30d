//! From matched groups to at most six rigid-body modes per set-up.
//!
//! A rigid body on a suspension has exactly six rigid-body modes, and each excitation
//! identifies each of them at most once. What `modal-fit` returns on noisy data breaks both:
//! - a *split pole*: one physical mode fitted as two or three poles a fraction of a
//!   half-bandwidth apart, whose residues share the true residue between them (strongly
//!   complex, opposite phases, low confidence). Their shapes are the same mode's, so the
//!   one-to-one matcher puts them into separate groups with near-identical shapes;
//! - a *leakage pole*: a pole at one mode's frequency whose residues carry a neighbouring
//!   mode's shape (its shape duplicates another group's at a different frequency);
//! - a *noise or elastic pole*: a shape far from rigid-body motion, or seen only weakly.
//!
//! `consolidate` (1) merges groups with the same shape at nearly the same frequency,
//! (2) keeps one estimate per excitation and group, (3) rejects groups whose shape
//! duplicates a better-supported group's, (4) if more than six groups remain, rejects the
//! least supported. Every rejection carries its reason.
//!
//! The support of a group is `Σ quality` over its reliable estimates, with the estimate
//! quality (each factor 1 for a clean, real, rigid estimate, see [`estimate_quality`])
//! `Q = confidence · cos²α · 1/(1 + (r/r0)²)`: modal-fit's confidence that the pole is one
//! physical mode; `α` the phase that rotates the residues onto the real line (a
//! proportionally damped rigid-body mode has real residues, `α = 0`; each half of a split
//! pole has `|α|` near 1 rad or more); `r = ‖A − Sq‖/‖A‖` the rigid-body residual (paper
//! Eq. 5) with `r0` = 0.1. A mode seen cleanly by one excitation has support ≈ 1, by three ≈ 3.

use crate::diagnostic;
use crate::matching::{mac, reference_member, Candidate, MatchTolerances};
use rbprops_core::records::{Diagnostic, DiagnosticKind, DiagnosticSubject, Severity};
use rbprops_core::Mat6;

/// A rigid body has six rigid-body modes.
pub const RIGID_BODY_MODES: usize = 6;

/// Rigid-body residual at which the quality factor `1/(1 + (r/r0)²)` halves.
pub const RIGID_RESIDUAL_SCALE: f64 = 0.1;

/// When the best rejected group has at least this fraction of the support of the weakest
/// kept group, the evidence does not clearly decide between them and a warning says so.
pub const UNDECIDED_SUPPORT_RATIO: f64 = 0.5;

/// Quality `Q = confidence · cos²α · 1/(1 + (r/r0)²)` of one estimate, in [0, 1].
pub fn estimate_quality(confidence: f64, phase_rad: f64, rigid_residual: f64) -> f64 {
    let c = if confidence.is_finite() {
        confidence.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = rigid_residual / RIGID_RESIDUAL_SCALE;
    let q = c * phase_rad.cos().powi(2) / (1.0 + x * x);
    if q.is_finite() {
        q
    } else {
        0.0
    }
}

/// What is known of one estimate besides its matching data (parallel to the candidates).
#[derive(Debug, Clone)]
pub(crate) struct Evidence {
    /// "force1 mode 4 (3.6628 Hz)".
    pub label: String,
    pub confidence: f64,
    /// Rotation `α` of the residues onto the real line (rad).
    pub phase: f64,
    pub rigid_residual: f64,
    pub weak: bool,
    /// [`estimate_quality`].
    pub quality: f64,
}

/// A rejected estimate with its reason.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Rejection {
    pub candidate: usize,
    /// The frequency of the group it was rejected from (or its own).
    pub group_frequency_hz: f64,
    pub reason: String,
}

#[derive(Debug, Clone, Default)]
pub(crate) struct Consolidation {
    /// Kept groups, ascending in reference frequency; one estimate per excitation.
    pub groups: Vec<Vec<usize>>,
    pub rejected: Vec<Rejection>,
    pub diagnostics: Vec<Diagnostic>,
}

/// Support of a group: `Σ Q` over its reliable members.
pub(crate) fn support(group: &[usize], cands: &[Candidate], ev: &[Evidence]) -> f64 {
    group
        .iter()
        .filter(|&&i| cands[i].reliable)
        .map(|&i| ev[i].quality)
        // `+ 0.0`: an empty float sum is −0.0.
        .sum::<f64>()
        + 0.0
}

fn reference_frequency(group: &[usize], cands: &[Candidate]) -> f64 {
    cands[reference_member(group, cands)].frequency_hz
}

fn relative_gap(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(f64::MIN_POSITIVE)
}

/// Summary of a group's evidence for messages.
fn describe(group: &[usize], cands: &[Candidate], ev: &[Evidence]) -> String {
    let n_rel = group.iter().filter(|&&i| cands[i].reliable).count();
    let members = group
        .iter()
        .map(|&i| {
            let e = &ev[i];
            format!(
                "{}{}: Q {:.2} (confidence {:.2}, phase {:.2} rad, rigid residual {:.1}%)",
                e.label,
                if e.weak {
                    ", weak"
                } else if !cands[i].reliable {
                    ", not above the noise"
                } else {
                    ""
                },
                e.quality,
                e.confidence,
                e.phase,
                100.0 * e.rigid_residual
            )
        })
        .collect::<Vec<_>>()
        .join("; ");
    format!(
        "support {:.2} from {n_rel} reliable estimate(s) [{members}]",
        support(group, cands, ev)
    )
}

/// Ordering key of the estimates of one excitation within one group: reliable first, then
/// quality, then the earlier candidate.
fn better(a: usize, b: usize, cands: &[Candidate], ev: &[Evidence]) -> bool {
    (cands[a].reliable, ev[a].quality)
        .partial_cmp(&(cands[b].reliable, ev[b].quality))
        .map_or(a < b, |o| o.is_gt() || (o.is_eq() && a < b))
}

/// What every step of the consolidation reads: the matcher's candidates and their
/// evidence, the MAC weight, the tolerances and the set-up named in messages.
struct Step<'a> {
    cands: &'a [Candidate],
    ev: &'a [Evidence],
    w: &'a Mat6,
    tol: &'a MatchTolerances,
    setup: &'a str,
}

/// Consolidates the matcher's groups (see the module docs). `setup` names the set-up in
/// messages. Deterministic: every choice breaks ties by candidate or group order.
pub(crate) fn consolidate(
    groups: Vec<Vec<usize>>,
    cands: &[Candidate],
    ev: &[Evidence],
    w: &Mat6,
    tol: &MatchTolerances,
    setup: &str,
) -> Consolidation {
    let c = Step {
        cands,
        ev,
        w,
        tol,
        setup,
    };
    let mut out = Consolidation::default();
    let mut groups = groups;
    merge_same_shape(&c, &mut groups, &mut out);
    keep_one_estimate_per_excitation(&c, &mut groups, &mut out);
    let mut rejected_group = reject_leakage_copies(&c, &groups, &mut out);
    keep_best_supported(&c, &groups, &mut rejected_group, &mut out);
    let mut kept: Vec<Vec<usize>> = groups
        .into_iter()
        .zip(rejected_group)
        .filter(|(_, r)| !r)
        .map(|(g, _)| g)
        .collect();
    warn_unsupported(&c, &kept, &mut out);
    kept.sort_by(|a, b| reference_frequency(a, cands).total_cmp(&reference_frequency(b, cands)));
    out.groups = kept;
    out
}

/// Step (1): same shape at nearly the same frequency is one physical mode; the pair of
/// groups with the highest MAC is merged first, until no pair is left.
fn merge_same_shape(c: &Step, groups: &mut Vec<Vec<usize>>, out: &mut Consolidation) {
    loop {
        let mut best: Option<(f64, usize, usize)> = None;
        for g in 0..groups.len() {
            for h in g + 1..groups.len() {
                let (rg, rh) = (
                    reference_member(&groups[g], c.cands),
                    reference_member(&groups[h], c.cands),
                );
                let df = relative_gap(c.cands[rh].frequency_hz, c.cands[rg].frequency_hz);
                if !(df <= c.tol.frequency_tolerance) {
                    continue;
                }
                let m = mac(&c.cands[rg].q, &c.cands[rh].q, c.w);
                if m >= c.tol.mac_threshold && best.is_none_or(|(b, _, _)| m > b) {
                    best = Some((m, g, h));
                }
            }
        }
        let Some((m, g, h)) = best else { break };
        let (fg, fh) = (
            reference_frequency(&groups[g], c.cands),
            reference_frequency(&groups[h], c.cands),
        );
        // Correctly handled (one mode kept, its estimates pooled): a note.
        out.diagnostics.push(diagnostic(
            DiagnosticKind::DuplicatePoles,
            Severity::Note,
            DiagnosticSubject::setup(c.setup).at_hz(&[fg, fh]),
            format!(
                "the modes matched at {fg:.4} and {fh:.4} Hz have the same shape (MAC {m:.3}): \
                 one physical mode fitted as several poles; merged"
            ),
        ));
        let moved = groups.remove(h);
        groups[g].extend(moved);
        groups[g].sort_unstable();
    }
}

/// Step (2): one estimate per excitation and group; the others are parts of a split pole
/// (the better one kept, see [`better`]).
fn keep_one_estimate_per_excitation(c: &Step, groups: &mut [Vec<usize>], out: &mut Consolidation) {
    for group in groups.iter_mut() {
        let f = reference_frequency(group, c.cands);
        let mut keep: Vec<usize> = Vec::with_capacity(group.len());
        for &i in group.iter() {
            match keep
                .iter()
                .position(|&j| c.cands[j].excitation == c.cands[i].excitation)
            {
                None => keep.push(i),
                Some(p) => {
                    let j = keep[p];
                    let (win, lose) = if better(i, j, c.cands, c.ev) {
                        (i, j)
                    } else {
                        (j, i)
                    };
                    keep[p] = win;
                    let reason = format!(
                        "{} and {} are the same physical mode (MAC {:.3}) from one excitation: \
                             a split pole; kept {} (Q {:.2} against {:.2})",
                        c.ev[lose].label,
                        c.ev[win].label,
                        mac(&c.cands[lose].q, &c.cands[win].q, c.w),
                        c.ev[win].label,
                        c.ev[win].quality,
                        c.ev[lose].quality
                    );
                    out.diagnostics.push(diagnostic(
                        DiagnosticKind::ModeRejected,
                        Severity::Note,
                        DiagnosticSubject::setup(c.setup).at_hz(&[f]),
                        format!("rejected {}: {reason}", c.ev[lose].label),
                    ));
                    out.rejected.push(Rejection {
                        candidate: lose,
                        group_frequency_hz: f,
                        reason,
                    });
                }
            }
        }
        keep.sort_unstable();
        *group = keep;
    }
}

/// Step (3): two groups with one shape at different frequencies. A rigid body has no two
/// such modes: the less supported one copies its neighbour's shape (leakage) and is
/// rejected. Returns which groups are rejected.
fn reject_leakage_copies(c: &Step, groups: &[Vec<usize>], out: &mut Consolidation) -> Vec<bool> {
    let mut rejected_group = vec![false; groups.len()];
    let mut order: Vec<usize> = (0..groups.len()).collect();
    // Most supported first, so that each group is compared with the better ones kept.
    order.sort_by(|&a, &b| {
        support(&groups[b], c.cands, c.ev)
            .total_cmp(&support(&groups[a], c.cands, c.ev))
            .then(a.cmp(&b))
    });
    for (pos, &h) in order.iter().enumerate() {
        let rh = reference_member(&groups[h], c.cands);
        let twin = order[..pos]
            .iter()
            .filter(|&&g| !rejected_group[g])
            .map(|&g| {
                let rg = reference_member(&groups[g], c.cands);
                (g, mac(&c.cands[rg].q, &c.cands[rh].q, c.w))
            })
            .filter(|&(_, m)| m >= c.tol.mac_threshold)
            .max_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((g, m)) = twin {
            rejected_group[h] = true;
            reject_group(
                out,
                &groups[h],
                c.cands,
                c.ev,
                c.setup,
                format!(
                    "its shape is that of the mode at {:.4} Hz (MAC {m:.3}, {}): a rigid body \
                     has no two modes of one shape, so it is a copy (leakage) of that mode",
                    reference_frequency(&groups[g], c.cands),
                    describe(&groups[g], c.cands, c.ev)
                ),
            );
        }
    }

    rejected_group
}

/// Step (4): at most six rigid-body modes; the best supported are kept, and a warning
/// says when the evidence barely separates the last kept from the first rejected.
fn keep_best_supported(
    c: &Step,
    groups: &[Vec<usize>],
    rejected_group: &mut [bool],
    out: &mut Consolidation,
) {
    let mut alive: Vec<usize> = (0..groups.len()).filter(|&g| !rejected_group[g]).collect();
    if alive.len() > RIGID_BODY_MODES {
        // Ascending support; ties: fewer reliable members, then higher frequency, then
        // later group.
        let n_rel = |g: usize| groups[g].iter().filter(|&&i| c.cands[i].reliable).count();
        alive.sort_by(|&a, &b| {
            support(&groups[a], c.cands, c.ev)
                .total_cmp(&support(&groups[b], c.cands, c.ev))
                .then(n_rel(a).cmp(&n_rel(b)))
                .then(b.cmp(&a))
        });
        let n_out = alive.len() - RIGID_BODY_MODES;
        let weakest_kept = alive[n_out];
        let s_kept = support(&groups[weakest_kept], c.cands, c.ev);
        let total = alive.len();
        for &g in &alive[..n_out] {
            rejected_group[g] = true;
            let s = support(&groups[g], c.cands, c.ev);
            let mut reason = format!(
                "{total} candidate modes for six rigid-body modes; this one has the least \
                 evidence of being a rigid-body mode"
            );
            if s == 0.0 {
                reason.push_str(" (no excitation identifies it reliably)");
            }
            reject_group(out, &groups[g], c.cands, c.ev, c.setup, reason);
        }
        let best_rejected = alive[n_out - 1];
        let s_rej = support(&groups[best_rejected], c.cands, c.ev);
        if s_rej > 0.0 && s_rej >= UNDECIDED_SUPPORT_RATIO * s_kept {
            let (fk, fr) = (
                reference_frequency(&groups[weakest_kept], c.cands),
                reference_frequency(&groups[best_rejected], c.cands),
            );
            // The answer may hinge on this choice: a warning.
            out.diagnostics.push(diagnostic(
                DiagnosticKind::UndecidedModes,
                Severity::Warning,
                DiagnosticSubject::setup(c.setup).at_hz(&[fk, fr]),
                format!(
                    "the evidence does not clearly decide between the mode at {fk:.4} Hz ({}) \
                     and the rejected one at {fr:.4} Hz ({}); check both",
                    describe(&groups[weakest_kept], c.cands, c.ev),
                    describe(&groups[best_rejected], c.cands, c.ev)
                ),
            ));
        }
    }
}

/// A kept mode supported only by weak or unexcited estimates may be spurious: a warning.
fn warn_unsupported(c: &Step, kept: &[Vec<usize>], out: &mut Consolidation) {
    for g in kept {
        if support(g, c.cands, c.ev) == 0.0 {
            let f = reference_frequency(g, c.cands);
            out.diagnostics.push(diagnostic(
                DiagnosticKind::SpuriousMode,
                Severity::Warning,
                DiagnosticSubject::setup(c.setup).at_hz(&[f]),
                format!(
                    "the mode at {f:.4} Hz is supported only by weak or unexcited estimates \
                     ({}): it may be spurious",
                    describe(g, c.cands, c.ev)
                ),
            ));
        }
    }
}

fn reject_group(
    out: &mut Consolidation,
    group: &[usize],
    cands: &[Candidate],
    ev: &[Evidence],
    setup: &str,
    why: String,
) {
    let f = reference_frequency(group, cands);
    // A leakage copy or the least supported of too many: correctly set aside, a note.
    out.diagnostics.push(diagnostic(
        DiagnosticKind::ModeRejected,
        Severity::Note,
        DiagnosticSubject::setup(setup).at_hz(&[f]),
        format!(
            "rejected the mode at {f:.4} Hz: {why}; its evidence: {}",
            describe(group, cands, ev)
        ),
    ));
    for &i in group {
        out.rejected.push(Rejection {
            candidate: i,
            group_frequency_hz: f,
            reason: format!("in the mode at {f:.4} Hz, rejected: {why}"),
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quality_factors_are_exact() {
        assert_eq!(estimate_quality(1.0, 0.0, 0.0), 1.0);
        // 0.5 · cos²(π/3) · 1/(1 + 1) = 0.5 · 0.25 · 0.5.
        let q = estimate_quality(0.5, std::f64::consts::FRAC_PI_3, RIGID_RESIDUAL_SCALE);
        assert!((q - 0.0625).abs() < 1e-15, "{q}");
        // Nearly imaginary residues (a split pole's half) have almost no quality.
        assert!(estimate_quality(1.0, 1.52, 0.0) < 0.003);
        assert_eq!(estimate_quality(f64::NAN, 0.0, 0.0), 0.0);
        assert_eq!(estimate_quality(1.0, 0.0, f64::NAN), 0.0);
        assert_eq!(estimate_quality(2.0, 0.0, 0.0), 1.0);
    }
}
