//! Coordinates a screening form leaves free only for its score test, held at their
//! physical values once the effect is in the model ([`Effect::physical_holds`]: the
//! gravity form's load-term factor, 1 once its cords have a length). Left free, such a
//! coordinate takes up what another effect should explain, and the model reported is
//! not the one the improved spec states.
//!
//! When to hold is a question of the selection's path. Held as gravity is accepted, the
//! factor cannot stand in for a force gauge's mass (study seed 6027: the gauge named,
//! nothing false); but at that step the model may still lack an in-band elastic mode,
//! and the held refit can carry the cords' length contrasts into another basin (seed
//! 6034: three false effects filled it). Held only once the forward selection ends, the
//! two recordings swap outcomes. So the selection holds at acceptance, and when that
//! path ends above the noise band it is run again holding at the end, and the model
//! with the lower BIC is kept (docs/results.md, session 32).
//!
//! [`Effect::physical_holds`]: rbprops_sim::effects::Effect::physical_holds

use super::problem::active_dims;
use super::selection::Selection;
use super::take_back::FloorYardstick;
use crate::error::CheckError;
use crate::report::diagnostic;
use rbprops_core::records::{DiagnosticKind, Severity};

/// When the selection holds an accepted effect's screening-only coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum HoldTiming {
    /// As the effect is accepted.
    AtAcceptance,
    /// Once the forward selection ends (then it goes on from the held model).
    AtEnd,
}

impl<'p, 'a> Selection<'p, 'a> {
    /// Holds active effect `k`'s screening-only coordinates at their physical values and
    /// refits the model so; true when it did. The held model stands even when its χ²
    /// is higher: later steps and the backward check weigh it as it is.
    pub(super) fn hold_physical(&mut self, k: usize, step: usize) -> bool {
        let p = self.p;
        let k0 = p.n_base() + active_dims(&self.model.active[..k]);
        let a = &self.model.active[k];
        let cand = &p.cands[a.c];
        let phi = a.phi(&cand.neutral, &self.model.cur.theta[k0..k0 + a.dim()]);
        let Ok(effect) = cand.effect.with_values(&phi) else {
            return false;
        };
        let holds: Vec<(usize, f64)> = effect
            .physical_holds()
            .into_iter()
            .filter(|(j, _)| a.kept.contains(j))
            .collect();
        if holds.is_empty() {
            return false;
        }
        let mut held = a.clone();
        held.kept.retain(|j| holds.iter().all(|(h, _)| h != j));
        held.held.extend_from_slice(&holds);
        let mut theta = self.model.cur.theta[..k0].to_vec();
        theta.extend(held.kept.iter().map(|&j| phi[j]));
        theta.extend_from_slice(&self.model.cur.theta[k0 + a.dim()..]);
        let mut act = self.model.active.clone();
        act[k] = held;
        let Ok(fit) = p.fit(
            &format!("{} held at its physical values", cand.id),
            &theta,
            &act,
            self.options.max_iterations,
        ) else {
            return false;
        };
        let infos = cand.effect.parameters();
        let what: Vec<String> = holds
            .iter()
            .map(|(j, v)| format!("{} held at {v} (fitted {:.3})", infos[*j].name, phi[*j]))
            .collect();
        let note = format!(
            "{}; χ² {:+.1} for it",
            what.join(", "),
            fit.chi2 - self.model.cur.chi2
        );
        self.options
            .progress
            .say(|| format!("step {step}: {}: {note}", cand.id));
        if let Some(e) = self
            .findings
            .screening
            .iter_mut()
            .rev()
            .find(|e| e.step <= step && e.id == cand.id)
        {
            e.decision.push_str(&format!(" ({note})"));
        }
        let ev = &mut self.model.accepted[k];
        ev.kept = act[k].kept.clone();
        ev.rank = ev.rank.min(ev.kept.len());
        self.model.active = act;
        self.model.cur = fit;
        true
    }

    /// With [`HoldTiming::AtEnd`], holds every active effect's coordinates not yet held;
    /// true when some were (the selection then goes on from the held model).
    pub(super) fn hold_at_end(&mut self, step: usize) -> bool {
        if self.hold != HoldTiming::AtEnd {
            return false;
        }
        let mut any = false;
        for k in 0..self.model.active.len() {
            any |= self.hold_physical(k, step);
        }
        any
    }
}

/// Runs `path` on `sel`, holding at acceptance; when a hold was made so and the final
/// model is above the noise band, runs it again from the same start holding at the
/// end, and keeps the path whose model has the lower BIC (module docs). The report
/// says which.
pub(super) fn with_hold_timing<'p, 'a>(
    sel: &mut Selection<'p, 'a>,
    floor: FloorYardstick,
    path: impl Fn(&mut Selection<'p, 'a>) -> Result<(), CheckError>,
) -> Result<(), CheckError> {
    let mut late = sel.fork();
    path(sel)?;
    if !(sel.held_early && floor.above(sel)) {
        return Ok(());
    }
    sel.options.progress.say(|| {
        "above the noise band with a coordinate held as its effect was accepted: the selection again, holding once it ends".into()
    });
    late.hold = HoldTiming::AtEnd;
    path(&mut late)?;
    // A path stopped by its step cap has not held yet.
    let last_step = late.findings.screening.iter().map(|e| e.step).max();
    late.hold_at_end(last_step.unwrap_or(0));
    let (early_bic, late_bic) = (sel.bic(), late.bic());
    let kept_late = late_bic < early_bic;
    let text = format!(
        "a coordinate held at its physical value as its effect was accepted (gravity's load-term factor) left the model above the noise band; the selection was run again holding it only once the forward selection ended, and the {} path's model is reported (BIC {:.1} held at acceptance, {:.1} held at the end)",
        if kept_late { "second" } else { "first" },
        early_bic,
        late_bic
    );
    sel.options.progress.say(|| text.clone());
    if kept_late {
        *sel = late;
    }
    sel.findings.warnings.push(diagnostic(
        DiagnosticKind::CheckProcedure,
        Severity::Note,
        text,
    ));
    Ok(())
}
