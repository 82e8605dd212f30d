//! Implausible items of a refit set back to neutral (docs/physics.md, M6d).
//!
//! An effect of several items (a position error per sensor, a force direction per
//! excitation) is refitted with every item free. When other effects are still missing,
//! the items the recording does not need can take implausible values to stand in for
//! them (force1 moved by 243 mm, force2 by 755 mm, while the truth is force3 by 11 mm),
//! and the whole effect fails its plausibility test: the true item is then never
//! accepted and other, false effects fill its place. The effect's own items are
//! physically independent, so the refit is repeated with the implausible items held at
//! their neutral values; the plausible items' evidence is then tested with the usual
//! likelihood-ratio, ΔBIC, held-out and plausibility tests.

use super::acceptance::{holds, Evidence, RefitBaseline};
use super::problem::{active_dims, Act};
use super::screening::Score;
use super::selection::Selection;
use crate::error::CheckError;
use rayon::prelude::*;
use rbprops_sim::effects::Reach;

/// The items of candidate `c`'s coordinates `kept`: coordinates of one reach (a sensor's
/// channels, one excitation) form one item, in order of first appearance. `None` when
/// the effect declares no narrower reach than the whole recording.
fn items(reach: &[Reach], kept: &[usize]) -> Option<Vec<Vec<usize>>> {
    let mut keys: Vec<&Reach> = Vec::new();
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for &j in kept {
        let r = reach.get(j)?;
        if *r == Reach::Any {
            return None;
        }
        match keys.iter().position(|k| *k == r) {
            Some(i) => groups[i].push(j),
            None => {
                keys.push(r);
                groups.push(vec![j]);
            }
        }
    }
    Some(groups)
}

/// What the final re-test's narrowing of an effect did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Narrowed {
    /// Refitted with its implausible items at neutral.
    Yes,
    /// No item plausible, all plausible, or the refit failed: dropped as before.
    No,
    /// The implausible items are needed by the data: the effect stays whole.
    NeededWhole,
}

/// The value of φ's coordinate `j` among `values` of the coordinates `kept`.
fn value_at(kept: &[usize], values: &[f64], j: usize) -> f64 {
    values[kept
        .iter()
        .position(|&k| k == j)
        .expect("a kept coordinate")]
}

/// The fitted values of `e`'s kept coordinates (the last entries of its θ).
fn fitted(e: &Evidence) -> &[f64] {
    &e.fit.theta[e.fit.theta.len() - e.kept.len()..]
}

impl<'p, 'a> Selection<'p, 'a> {
    /// The coordinates of `e`'s refit that belong to plausible items, when `e` failed
    /// on plausibility and some of its items, each judged alone (the others at neutral),
    /// are plausible while others are not; `None` otherwise.
    fn plausible_items(&self, e: &Evidence) -> Option<Vec<usize>> {
        if e.ok()
            || !e
                .why
                .iter()
                .any(|w| w.starts_with(super::acceptance::IMPLAUSIBLE))
        {
            return None;
        }
        self.plausible_coordinates(&e.fit.theta, e.c, &e.kept, fitted(e))
    }

    /// The coordinates among `kept` (fitted to `values` in the model at `theta`) of
    /// candidate `c`'s items that are plausible each judged alone (the others at
    /// neutral), when some are and others are not; `None` otherwise.
    pub(super) fn plausible_coordinates(
        &self,
        theta: &[f64],
        c: usize,
        kept: &[usize],
        values: &[f64],
    ) -> Option<Vec<usize>> {
        let p = self.p;
        let cand = &p.cands[c];
        let reach = cand.effect.parameter_reach(&p.layout.spec_geometry);
        let groups = items(&reach, kept)?;
        if groups.len() < 2 {
            return None;
        }
        let mut keep: Vec<usize> = Vec::new();
        for g in &groups {
            let mut phi = cand.neutral.clone();
            g.iter().for_each(|&j| phi[j] = value_at(kept, values, j));
            if p.plausibility(theta, c, &phi).iter().all(holds) {
                keep.extend(g);
            }
        }
        keep.sort_unstable();
        (!keep.is_empty() && keep.len() < kept.len()).then_some(keep)
    }

    /// Each of `evals` that failed on implausible items only where other items are
    /// plausible, refitted with those items at neutral and evaluated again; the new
    /// evidence replaces the old when it passes every test.
    pub(super) fn retry_plausible_items(
        &mut self,
        step: usize,
        round: &[(usize, Score, f64)],
        evals: Vec<Evidence>,
        base: &RefitBaseline,
    ) -> Result<Vec<Evidence>, CheckError> {
        let retries: Vec<(usize, Vec<usize>)> = evals
            .iter()
            .enumerate()
            .filter_map(|(i, e)| self.plausible_items(e).map(|k| (i, k)))
            .collect();
        if retries.is_empty() {
            return Ok(evals);
        }
        let fits: Vec<_> = retries
            .par_iter()
            .map(|(i, keep)| {
                let e = &evals[*i];
                let mut t0 = self.model.cur.theta.clone();
                t0.extend(keep.iter().map(|&j| value_at(&e.kept, fitted(e), j)));
                let mut act = self.model.active.clone();
                act.push(Act::new(e.c, keep.clone()));
                let stage = format!("refit {} (plausible items)", self.p.cands[e.c].id);
                (
                    e.c,
                    self.p.fit(&stage, &t0, &act, self.options.max_iterations),
                    keep.clone(),
                )
            })
            .collect();
        let mut evals = evals;
        for (c, fit, keep) in fits {
            // A retry that fails to converge leaves the original evidence standing.
            let Ok(fit) = fit else { continue };
            let n_tests = round.iter().find(|x| x.0 == c).expect("refitted").1.n_tests;
            let mut e = self.evaluate(c, n_tests, fit, keep, base);
            e.items_at_neutral = true;
            let id = &self.p.cands[c].id;
            self.options.progress.say(|| {
                format!(
                    "step {step}: {id} refitted with its implausible items at neutral: Δχ² {:.1}, ΔBIC {:.1}{}",
                    e.dchi2,
                    e.dbic,
                    if e.ok() { String::new() } else { format!("; fails: {}", e.why()) }
                )
            });
            if e.ok() {
                if let Some(entry) = self
                    .findings
                    .screening
                    .iter_mut()
                    .rev()
                    .find(|x| x.step == step && x.id == *id)
                {
                    entry.refit_delta_chi2 = Some(e.dchi2);
                    entry.refit_delta_bic = Some(e.dbic);
                }
                let i = evals.iter().position(|x| x.c == c).expect("refitted");
                evals[i] = e;
            }
        }
        evals.sort_by(|a, b| b.dbic.total_cmp(&a.dbic).then(a.c.cmp(&b.c)));
        Ok(evals)
    }
}

impl<'p, 'a> Selection<'p, 'a> {
    /// Active effect `k`, needed given the others but implausible on some of its items,
    /// refitted with those items at neutral (the final re-test's counterpart of
    /// [`Self::retry_plausible_items`]). When that refit costs more than the effect's
    /// likelihood-ratio threshold, the implausible items are needed by the data: the
    /// effect stays whole, its values shown against their ranges in the report.
    pub(super) fn narrow_to_plausible_items(
        &mut self,
        k: usize,
        step: usize,
        why: &str,
    ) -> Result<Narrowed, CheckError> {
        let p = self.p;
        let theta = &self.model.cur.theta;
        let k0 = p.n_base() + active_dims(&self.model.active[..k]);
        let a = &self.model.active[k];
        let values = &theta[k0..k0 + a.dim()];
        let Some(keep) = self.plausible_coordinates(theta, a.c, &a.kept, values) else {
            return Ok(Narrowed::No);
        };
        let mut t0 = theta[..k0].to_vec();
        t0.extend(keep.iter().map(|&j| value_at(&a.kept, values, j)));
        t0.extend_from_slice(&theta[k0 + a.dim()..]);
        let mut act = self.model.active.clone();
        act[k] = Act {
            c: a.c,
            kept: keep.clone(),
            gauge: Vec::new(),
            held: a.held.clone(),
        };
        let id = &p.cands[a.c].id;
        let Ok(fit) = p.fit(
            &format!("final re-test {id} (plausible items)"),
            &t0,
            &act,
            self.options.max_iterations,
        ) else {
            return Ok(Narrowed::No);
        };
        let cost = fit.chi2 - self.model.cur.chi2;
        let needed = cost > self.model.accepted[k].threshold;
        self.options.progress.say(|| {
            format!(
                "final re-test: {id} with its implausible items at neutral ({why}): Δχ² {cost:.1}, {}",
                if needed { "they are needed, kept whole" } else { "set back" }
            )
        });
        let note = if needed {
            format!(" (kept whole in the final re-test: its implausible items are needed, Δχ² {cost:.1} without them)")
        } else {
            " (its implausible items set back to neutral in the final re-test)".to_string()
        };
        if let Some(e) = self
            .findings
            .screening
            .iter_mut()
            .rev()
            .find(|e| e.step <= step && e.id == *id)
        {
            e.decision.push_str(&note);
        }
        if needed {
            return Ok(Narrowed::NeededWhole);
        }
        let ev = &mut self.model.accepted[k];
        ev.rank = keep.len();
        ev.kept = keep;
        ev.items_at_neutral = true;
        self.model.active = act;
        self.model.cur = fit;
        Ok(Narrowed::Yes)
    }
}

#[cfg(test)]
mod tests {
    use super::items;
    use rbprops_sim::effects::Reach;

    #[test]
    fn coordinates_of_one_reach_form_one_item() {
        let reach = vec![
            Reach::Excitation(0),
            Reach::Excitation(0),
            Reach::Excitation(1),
            Reach::Excitation(1),
            Reach::Excitation(0),
        ];
        assert_eq!(
            items(&reach, &[0, 1, 2, 3, 4]),
            Some(vec![vec![0, 1, 4], vec![2, 3]])
        );
        assert_eq!(items(&reach, &[2, 3]), Some(vec![vec![2, 3]]));
    }

    #[test]
    fn an_effect_reaching_everything_has_no_items() {
        let reach = vec![Reach::Channels(vec![0, 1]), Reach::Any];
        assert_eq!(items(&reach, &[0, 1]), None);
        assert_eq!(items(&reach, &[0]), Some(vec![vec![0]]));
    }
}
