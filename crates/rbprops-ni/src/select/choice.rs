//! The choice at each mode: the best eligible excitation by the criterion (or the manual
//! set's), its runner-up, and where the criteria disagree.

use super::{Criterion, CriterionChoices, ModeExcitation, ModeGroup, PoolChoices, PoolInputs};
use crate::{diagnostic, NiError};
use rbprops_core::records::{DiagnosticKind, DiagnosticSubject, Severity};
use rbprops_core::records::{MissingMode, SelectedMode, SelectionCriterion};

/// Index of the best entry by `key` (larger is better) among `items`; ties go to the
/// higher NI, then to geometry order.
pub(super) fn best_by(
    items: &[&ModeExcitation],
    key: impl Fn(&ModeExcitation) -> f64,
) -> Option<usize> {
    (0..items.len()).max_by(|&a, &b| {
        key(items[a])
            .total_cmp(&key(items[b]))
            .then(items[a].ni_db.total_cmp(&items[b].ni_db))
            .then(b.cmp(&a))
    })
}

pub(super) fn criterion_key(c: Criterion) -> impl Fn(&ModeExcitation) -> f64 {
    move |m: &ModeExcitation| match c {
        Criterion::Ni => m.ni_db,
        Criterion::HybridMif => -m.hybrid_mif,
        Criterion::PrfMif => -m.prf_mif,
    }
}

impl CriterionChoices {
    /// The best eligible excitation of `table` by each criterion and by strength.
    pub(super) fn of(table: &[ModeExcitation]) -> Self {
        let eligible: Vec<&ModeExcitation> = table.iter().filter(|m| m.eligible).collect();
        let pick = |c: Criterion| {
            best_by(&eligible, criterion_key(c)).map(|i| eligible[i].excitation.clone())
        };
        Self {
            ni: pick(Criterion::Ni),
            hybrid_mif: pick(Criterion::HybridMif),
            prf_mif: pick(Criterion::PrfMif),
            strength: best_by(&eligible, |m| m.strength.unwrap_or(0.0))
                .map(|i| eligible[i].excitation.clone()),
        }
    }

    pub(super) fn of_criterion(&self, c: Criterion) -> Option<String> {
        match c {
            Criterion::Ni => self.ni.clone(),
            Criterion::HybridMif => self.hybrid_mif.clone(),
            Criterion::PrfMif => self.prf_mif.clone(),
        }
    }

    /// A message when the criteria (and the strength ranking) do not all agree.
    pub(super) fn disagreement(&self, setup: &str, mode: usize, f_r: f64) -> Option<String> {
        let choices = [&self.ni, &self.hybrid_mif, &self.prf_mif, &self.strength];
        choices.iter().any(|c| *c != choices[0]).then(|| {
            format!(
                "set-up '{setup}' mode {mode} ({f_r:.4} Hz): NI picks {}, hybrid MIF {}, PRF MIF {}, strength fᵀq {}",
                describe_choice(&self.ni),
                describe_choice(&self.hybrid_mif),
                describe_choice(&self.prf_mif),
                describe_choice(&self.strength)
            )
        })
    }
}

pub(super) fn describe_choice(c: &Option<String>) -> String {
    c.clone().unwrap_or_else(|| "none".into())
}

/// The table ordered for the report: eligible rows first, in the order of `criterion`;
/// then the others by NI.
pub(super) fn ranking(table: &[ModeExcitation], criterion: Criterion) -> Vec<ModeExcitation> {
    let key = criterion_key(criterion);
    let mut ranking = table.to_vec();
    ranking.sort_by(|a, b| {
        b.eligible
            .cmp(&a.eligible)
            .then_with(|| {
                if a.eligible {
                    key(b).total_cmp(&key(a))
                } else {
                    std::cmp::Ordering::Equal
                }
            })
            .then(b.ni_db.total_cmp(&a.ni_db))
    });
    ranking
}

/// The choice at mode `g`: the manual set's excitation when one is given, otherwise the
/// criterion's. Records the selected mode (with its runner-up and margin) or a
/// `MissingMode` naming every excitation tried and why it failed.
pub(super) fn choose(
    p: &PoolInputs,
    g: &ModeGroup,
    group: &[usize],
    table: &[ModeExcitation],
    by: &CriterionChoices,
    out: &mut PoolChoices,
) -> Result<(), NiError> {
    let (label, mode, f_r) = (&p.pool.label, g.mode, g.frequency_hz);
    let manual_choice = p
        .opts
        .manual
        .as_ref()
        .map(|m| m.excitation_for(mode).map(str::to_string));
    let (chosen, criterion): (Option<String>, SelectionCriterion) = match &manual_choice {
        Some(Some(ex)) => (Some(ex.clone()), SelectionCriterion::Manual),
        Some(None) => (None, SelectionCriterion::Manual),
        None => (
            by.of_criterion(p.opts.criterion),
            p.opts.criterion.record_name(),
        ),
    };
    match (&manual_choice, chosen) {
        (Some(None), _) => out.warnings.push(diagnostic(
            DiagnosticKind::ManualSelection,
            Severity::ChangesAnswer,
            DiagnosticSubject::setup(label).mode(mode, f_r),
            "not in the manual set: not selected",
        )),
        (Some(Some(ex)), _) if !table.iter().any(|m| &m.excitation == ex) => {
            return Err(NiError::Manual(format!(
                "mode {mode}: excitation '{ex}' is not in set-up '{label}'"
            )));
        }
        (Some(Some(ex)), _)
            if table
                .iter()
                .any(|m| &m.excitation == ex && m.excitation_mode.is_none()) =>
        {
            out.missing.push(MissingMode {
                setup: label.clone(),
                mode,
                frequency_hz: f_r,
                tried: vec![ex.clone()],
                reason: format!(
                    "the manual set takes mode {mode} ({f_r:.4} Hz) from '{ex}', which did not identify it"
                ),
            });
        }
        (_, None) => out.missing.push(not_excited(label, mode, f_r, table)),
        (_, Some(ex)) => {
            let row = table
                .iter()
                .find(|m| m.excitation == ex)
                .expect("checked above");
            if !row.eligible {
                out.warnings.push(diagnostic(
                    DiagnosticKind::ManualSelection,
                    Severity::Warning,
                    DiagnosticSubject::setup(label)
                        .excitation(&ex)
                        .mode(mode, f_r),
                    format!(
                        "the manual choice '{ex}' is not reliable ({})",
                        row.reason.as_deref().unwrap_or("")
                    ),
                ));
            }
            let manual = criterion == SelectionCriterion::Manual;
            if manual && by.ni.as_ref().is_some_and(|c| c != &ex) {
                out.disagreements.push(format!(
                    "set-up '{label}' mode {mode} ({f_r:.4} Hz): the manual set takes {ex}, NI picks {}",
                    describe_choice(&by.ni)
                ));
            }
            let runner = runner_up(
                table,
                &ex,
                if manual {
                    Criterion::Ni
                } else {
                    p.opts.criterion
                },
            );
            let member = group
                .iter()
                .map(|&i| &p.members[i])
                .find(|m| p.excitation_id(m.excitation) == ex)
                .expect("a row with an excitation mode has a member");
            let est = p.estimate(member);
            out.selected.push(SelectedMode {
                setup: label.clone(),
                mode,
                frequency_hz: est.frequency_hz,
                excitation: ex.clone(),
                excitation_mode: est.mode,
                ni_db: row.ni_db,
                margin_db: runner.map_or(0.0, |r| row.ni_db - r.ni_db),
                runner_up: runner.map(|r| r.excitation.clone()),
                strength: member.strength,
                criterion,
            });
        }
    }
    Ok(())
}

/// The `MissingMode` of a mode no excitation of the pool excites above the noise: every
/// excitation tried, and why each failed.
fn not_excited(label: &str, mode: usize, f_r: f64, table: &[ModeExcitation]) -> MissingMode {
    let why_each = table
        .iter()
        .map(|m| {
            format!(
                "{}: {}",
                m.excitation,
                m.reason.as_deref().unwrap_or("eligible")
            )
        })
        .collect::<Vec<_>>()
        .join("; ");
    MissingMode {
        setup: label.to_string(),
        mode,
        frequency_hz: f_r,
        tried: table.iter().map(|m| m.excitation.clone()).collect(),
        reason: format!(
            "mode {mode} ({f_r:.4} Hz) is not excited above the noise by any excitation of set-up '{label}': {why_each}"
        ),
    }
}

/// The runner-up to `chosen`: the best other eligible excitation under `criterion` (the
/// selection's, or NI for a manual choice).
fn runner_up<'t>(
    table: &'t [ModeExcitation],
    chosen: &str,
    criterion: Criterion,
) -> Option<&'t ModeExcitation> {
    let others: Vec<&ModeExcitation> = table
        .iter()
        .filter(|m| m.eligible && m.excitation != chosen)
        .collect();
    best_by(&others, criterion_key(criterion)).map(|i| others[i])
}

/// A manual set naming a mode beyond the pool's matched modes is refused.
pub(super) fn check_manual_modes(p: &PoolInputs, n_modes: usize) -> Result<(), NiError> {
    if let Some(manual) = &p.opts.manual {
        for e in &manual.entries {
            if e.mode > n_modes {
                return Err(NiError::Manual(format!(
                    "mode {} (from '{}') does not exist: set-up '{}' has {n_modes} matched modes",
                    e.mode, e.excitation, p.pool.label
                )));
            }
        }
    }
    Ok(())
}
