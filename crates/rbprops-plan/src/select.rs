//! Judging a layout and choosing one: criteria, evaluation, greedy selection with
//! exchange passes.
//!
//! Criteria on the covariance made relative to the properties' scales
//! ([`crate::property_scales`]), `C_n = diag(1/s) Cov p̂ diag(1/s)`, all minimised:
//! - **D** (default): `ln det C_n`, the volume of the confidence ellipsoid;
//! - **A**: `tr C_n`, the sum of the relative variances;
//! - **worst**: `max_k √(C_n)_kk`, the worst property's relative standard deviation.
//!
//! The search runs on [`PlanModel::search_model`] (the lines near the modes); the
//! planned layout is then predicted on the full model.
//!
//! Selection (one set-up): the first sensors maximise `det SᵀS` (rotations scaled by the
//! body's radius of gyration; a rigid motion seen from every side), hits are added
//! greedily (while a layout is still unobservable, the one that best covers the
//! unexcited modes, `Σ_r ln max_k (f_kᵀφ_r)²`), then exchange passes replace one sensor
//! or one hit at a time by the candidate that improves the criterion most, until no
//! exchange improves it. Candidates are tried in their given order and ties keep the
//! earlier one; evaluations run in parallel but are reduced in order, so the plan does
//! not depend on the thread count.

use crate::estimate::{predict_setup, Estimator, JacobianCache, SetupPrediction, Unobservable};
use crate::fitcov::{
    combine, excitation_covariance, ChannelTerms, ExcitationBasis, ExcitationCovariance,
};
use crate::model::{Hit, Layout, PlanModel, Sensor};
use crate::PlanError;
use nalgebra::RowVector6;
use rayon::prelude::*;

/// The optimality criterion (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Criterion {
    /// `ln det` of the relative covariance.
    #[default]
    D,
    /// Trace of the relative covariance.
    A,
    /// Largest relative standard deviation.
    Worst,
}

impl Criterion {
    /// The criterion's value for a prediction (lower is better).
    pub fn value(self, model: &PlanModel, p: &SetupPrediction) -> f64 {
        let s = model.scales;
        let c = nalgebra::SMatrix::<f64, 10, 10>::from_fn(|r, k| p.cov[(r, k)] / (s[r] * s[k]));
        match self {
            Criterion::D => {
                let eig = c.symmetric_eigenvalues();
                eig.iter().map(|l| l.max(1e-300).ln()).sum()
            }
            Criterion::A => c.trace(),
            Criterion::Worst => (0..10).map(|k| c[(k, k)].sqrt()).fold(0.0, f64::max),
        }
    }

    /// Name for messages.
    pub fn name(self) -> &'static str {
        match self {
            Criterion::D => "D",
            Criterion::A => "A",
            Criterion::Worst => "worst",
        }
    }
}

/// Candidate sensor positions (triaxial, with their frames) and hits (a point with one
/// allowed direction each; a point with several directions appears several times).
#[derive(Debug, Clone, Default)]
pub struct Candidates {
    /// Sensor candidates.
    pub sensors: Vec<Sensor>,
    /// Hit candidates.
    pub hits: Vec<Hit>,
}

/// Options of [`plan`].
#[derive(Debug, Clone)]
pub struct PlanOptions {
    /// Number of triaxial sensors.
    pub sensors: usize,
    /// Number of hits.
    pub hits: usize,
    /// Criterion.
    pub criterion: Criterion,
    /// Estimator whose spread is minimised.
    pub estimator: Estimator,
    /// Sensors that must stay (indices into the candidates).
    pub keep_sensors: Vec<usize>,
    /// Least distance between two chosen sensors (m); 0: none.
    pub min_spacing_m: f64,
    /// Exchange rounds (sensors then hits) at most.
    pub max_rounds: usize,
}

impl Default for PlanOptions {
    fn default() -> Self {
        Self {
            sensors: 4,
            hits: 6,
            criterion: Criterion::D,
            estimator: Estimator::ToivolaNuutila,
            keep_sensors: Vec::new(),
            min_spacing_m: 0.0,
            max_rounds: 2,
        }
    }
}

/// The judgement of a layout: per set-up, a prediction or why there is none.
#[derive(Debug, Clone)]
pub struct Evaluation {
    /// `(set-up id, prediction)` for every set-up with a hit.
    pub setups: Vec<(String, Result<SetupPrediction, Unobservable>)>,
}

/// Per-hit covariances of a layout, computed in parallel, in hit order.
fn hit_data(
    model: &PlanModel,
    rows: &[RowVector6<f64>],
    hits: &[Hit],
) -> Vec<ExcitationCovariance> {
    hits.par_iter()
        .map(|h| excitation_covariance(model, &model.setups[h.setup], rows, &h.column()))
        .collect()
}

/// Predicted covariance of every set-up's estimate for a layout.
pub fn evaluate(model: &PlanModel, layout: &Layout, est: Estimator) -> Evaluation {
    let rows = layout.rows();
    let data = hit_data(model, &rows, &layout.hits);
    let cache = JacobianCache::default();
    let setups = (0..model.setups.len())
        .filter(|&s| layout.hits.iter().any(|h| h.setup == s))
        .map(|s| {
            let idx: Vec<usize> = (0..layout.hits.len())
                .filter(|&k| layout.hits[k].setup == s)
                .collect();
            let hits: Vec<&Hit> = idx.iter().map(|&k| &layout.hits[k]).collect();
            let d: Vec<&ExcitationCovariance> = idx.iter().map(|&k| &data[k]).collect();
            let p = predict_setup(model, s, &rows, &hits, &d, est, &cache).map(|mut p| {
                // Report hit indices into the layout.
                for sel in p.selected_hits.iter_mut() {
                    *sel = sel.map(|k| idx[k]);
                }
                p
            });
            (model.setups[s].id.clone(), p)
        })
        .collect();
    Evaluation { setups }
}

/// What adding one candidate would do for the weakest property.
#[derive(Debug, Clone, PartialEq)]
pub enum Suggestion {
    /// Add this candidate sensor.
    Sensor(usize),
    /// Add this candidate hit.
    Hit(usize),
}

/// The candidate sensor or hit whose addition lowers property `k`'s predicted standard
/// deviation most for set-up `setup`, with the new standard deviation.
pub fn best_addition(
    model: &PlanModel,
    layout: &Layout,
    setup: usize,
    k: usize,
    est: Estimator,
    cands: &Candidates,
) -> Option<(Suggestion, f64)> {
    let cache = JacobianCache::default();
    let std_of = |l: &Layout| -> Option<f64> {
        let ev = evaluate_setup(model, l, setup, est, &cache)?;
        Some(ev.std()[k])
    };
    let mut best: Option<(Suggestion, f64)> = None;
    let sensor_std: Vec<Option<f64>> = cands
        .sensors
        .par_iter()
        .map(|s| {
            let mut l = layout.clone();
            l.sensors.push(s.clone());
            std_of(&l)
        })
        .collect();
    for (i, v) in sensor_std.into_iter().enumerate() {
        if let Some(v) = v {
            if best.as_ref().is_none_or(|b| v < b.1) {
                best = Some((Suggestion::Sensor(i), v));
            }
        }
    }
    let rows = layout.rows();
    let base: Vec<ExcitationCovariance> = hit_data(model, &rows, &layout.hits);
    let hit_std: Vec<Option<f64>> = cands
        .hits
        .par_iter()
        .map(|h| {
            if h.setup != setup {
                return None;
            }
            let extra = excitation_covariance(model, &model.setups[setup], &rows, &h.column());
            let mut hits: Vec<&Hit> = Vec::new();
            let mut d: Vec<&ExcitationCovariance> = Vec::new();
            for (k, hh) in layout.hits.iter().enumerate() {
                if hh.setup == setup {
                    hits.push(hh);
                    d.push(&base[k]);
                }
            }
            hits.push(h);
            d.push(&extra);
            predict_setup(model, setup, &rows, &hits, &d, est, &cache)
                .ok()
                .map(|p| p.std()[k])
        })
        .collect();
    for (i, v) in hit_std.into_iter().enumerate() {
        if let Some(v) = v {
            if best.as_ref().is_none_or(|b| v < b.1) {
                best = Some((Suggestion::Hit(i), v));
            }
        }
    }
    best
}

fn evaluate_setup(
    model: &PlanModel,
    layout: &Layout,
    setup: usize,
    est: Estimator,
    cache: &JacobianCache,
) -> Option<SetupPrediction> {
    let rows = layout.rows();
    let hits: Vec<&Hit> = layout.hits.iter().filter(|h| h.setup == setup).collect();
    let data: Vec<ExcitationCovariance> = hits
        .iter()
        .map(|h| excitation_covariance(model, &model.setups[setup], &rows, &h.column()))
        .collect();
    let d: Vec<&ExcitationCovariance> = data.iter().collect();
    predict_setup(model, setup, &rows, &hits, &d, est, cache).ok()
}

/// The planned layout and how it was reached.
#[derive(Debug, Clone)]
pub struct PlanOutcome {
    /// Chosen sensor candidates (indices), in choice order.
    pub sensors: Vec<usize>,
    /// Chosen hit candidates (indices), in choice order.
    pub hits: Vec<usize>,
    /// The layout.
    pub layout: Layout,
    /// Its prediction.
    pub prediction: SetupPrediction,
    /// Criterion value.
    pub value: f64,
    /// Layouts evaluated.
    pub evaluations: usize,
}

/// Score of a layout: observable layouts by the criterion; unobservable ones rank below
/// every observable one, by how well their hits cover the modes.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Score {
    observable: bool,
    value: f64,
}

impl Score {
    fn better_than(&self, o: &Score) -> bool {
        match (self.observable, o.observable) {
            (true, false) => true,
            (false, true) => false,
            _ => self.value < o.value,
        }
    }
}

struct Planner<'a> {
    model: &'a PlanModel,
    cands: &'a Candidates,
    opts: &'a PlanOptions,
    setup: usize,
    cache: JacobianCache,
    evaluations: std::sync::atomic::AtomicUsize,
}

impl Planner<'_> {
    fn rows(&self, sensors: &[usize]) -> Vec<RowVector6<f64>> {
        sensors
            .iter()
            .flat_map(|&s| self.cands.sensors[s].rows())
            .collect()
    }

    fn score(
        &self,
        rows: &[RowVector6<f64>],
        hits: &[usize],
        data: &[&ExcitationCovariance],
    ) -> (Score, Option<SetupPrediction>) {
        self.evaluations
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let h: Vec<&Hit> = hits.iter().map(|&k| &self.cands.hits[k]).collect();
        match predict_setup(
            self.model,
            self.setup,
            rows,
            &h,
            data,
            self.opts.estimator,
            &self.cache,
        ) {
            Ok(p) => (
                Score {
                    observable: true,
                    value: self.opts.criterion.value(self.model, &p),
                },
                Some(p),
            ),
            Err(_) => (
                Score {
                    observable: false,
                    value: -self.coverage(&h),
                },
                None,
            ),
        }
    }

    /// `Σ_r ln(1e-12 + m · max_k (f_kᵀφ_r)²)`: how well the hits excite every mode.
    fn coverage(&self, hits: &[&Hit]) -> f64 {
        let m = self.model.truth[0];
        self.model.setups[self.setup]
            .modes
            .iter()
            .map(|mode| {
                let best = hits
                    .iter()
                    .map(|h| h.column().dot(&mode.shape).powi(2))
                    .fold(0.0, f64::max);
                (1e-12 + m * best).ln()
            })
            .sum()
    }

    fn spaced(&self, chosen: &[usize], cand: usize) -> bool {
        let p = self.cands.sensors[cand].position;
        chosen.iter().all(|&c| {
            c != cand && (self.cands.sensors[c].position - p).norm() >= self.opts.min_spacing_m
        })
    }

    /// Initial sensors: greedy `ln det(SᵀS + δI)` on the scaled rigid rows.
    fn initial_sensors(&self) -> Vec<usize> {
        let l = self.model.scales[1];
        let gram = |s: &[usize]| {
            let mut g = nalgebra::Matrix6::<f64>::zeros();
            for r in self.rows(s) {
                let mut r = r;
                for c in 3..6 {
                    r[c] /= l;
                }
                g += r.transpose() * r;
            }
            (g + nalgebra::Matrix6::identity() * 1e-6)
                .symmetric_eigenvalues()
                .iter()
                .map(|x| x.max(1e-300).ln())
                .sum::<f64>()
        };
        let mut chosen: Vec<usize> = self.opts.keep_sensors.clone();
        while chosen.len() < self.opts.sensors {
            let mut best: Option<(usize, f64)> = None;
            for c in 0..self.cands.sensors.len() {
                if !self.spaced(&chosen, c) {
                    continue;
                }
                let mut s = chosen.clone();
                s.push(c);
                let v = gram(&s);
                if best.is_none_or(|b| v > b.1) {
                    best = Some((c, v));
                }
            }
            match best {
                Some((c, _)) => chosen.push(c),
                None => break,
            }
        }
        chosen
    }

    /// Greedy hits then hit exchanges, for fixed sensors.
    fn choose_hits(&self, sensors: &[usize], start: &[usize]) -> (Vec<usize>, Score) {
        let rows = self.rows(sensors);
        let setup_hits: Vec<usize> = (0..self.cands.hits.len())
            .filter(|&k| self.cands.hits[k].setup == self.setup)
            .collect();
        let all: Vec<Option<ExcitationCovariance>> = (0..self.cands.hits.len())
            .into_par_iter()
            .map(|k| {
                let h = &self.cands.hits[k];
                (h.setup == self.setup).then(|| {
                    excitation_covariance(
                        self.model,
                        &self.model.setups[h.setup],
                        &rows,
                        &h.column(),
                    )
                })
            })
            .collect();
        let data = |hits: &[usize]| -> Vec<&ExcitationCovariance> {
            hits.iter().map(|&k| all[k].as_ref().unwrap()).collect()
        };
        let mut hits: Vec<usize> = start.to_vec();
        while hits.len() < self.opts.hits {
            let scores: Vec<Option<Score>> = setup_hits
                .par_iter()
                .map(|&c| {
                    if hits.contains(&c) {
                        return None;
                    }
                    let mut h = hits.clone();
                    h.push(c);
                    Some(self.score(&rows, &h, &data(&h)).0)
                })
                .collect();
            let best = pick(&setup_hits, &scores);
            match best {
                Some((c, _)) => hits.push(c),
                None => break,
            }
        }
        let mut current = self.score(&rows, &hits, &data(&hits)).0;
        while exchange_pass(
            &mut hits,
            &setup_hits,
            |_, _, _| true,
            |h| self.score(&rows, h, &data(h)).0,
            &mut current,
        ) {}
        (hits, current)
    }

    /// Sensor exchanges for fixed hits. The fit's line weights couple the channels of a
    /// hit; within one pass they are held at the pass's starting layout, so that every
    /// candidate channel's share of the linearisation ([`ChannelTerms`]) is computed once
    /// per hit and a trial layout only sums its channels' terms ([`combine`]). The pass
    /// compares layouts under the same weights; [`Planner::choose_hits`] re-scores the
    /// result with its own.
    // The closure is called once and then handed to exchange_pass (clippy sees only the call).
    #[allow(clippy::redundant_closure_call)]
    fn exchange_sensors(&self, sensors: &mut [usize], hits: &[usize], current: &mut Score) -> bool {
        let setup = &self.model.setups[self.setup];
        let start_rows = self.rows(sensors);
        let bases: Vec<ExcitationBasis> = hits
            .iter()
            .map(|&k| {
                ExcitationBasis::new(self.model, setup, &self.cands.hits[k].column(), &start_rows)
            })
            .collect();
        // terms[c][hit] = the three channels of candidate sensor c.
        let terms: Vec<Vec<Vec<ChannelTerms>>> = (0..self.cands.sensors.len())
            .into_par_iter()
            .map(|c| {
                let rows = self.cands.sensors[c].rows();
                bases
                    .iter()
                    .map(|b| rows.iter().map(|r| b.channel(r)).collect())
                    .collect()
            })
            .collect();
        let score_of = |s: &[usize]| -> Score {
            let data: Vec<ExcitationCovariance> = (0..hits.len())
                .map(|h| {
                    let t: Vec<&ChannelTerms> =
                        s.iter().flat_map(|&c| terms[c][h].iter()).collect();
                    combine(&t)
                })
                .collect();
            let d: Vec<&ExcitationCovariance> = data.iter().collect();
            self.score(&self.rows(s), hits, &d).0
        };
        *current = score_of(sensors);
        let pool: Vec<usize> = (0..self.cands.sensors.len()).collect();
        let keep = &self.opts.keep_sensors;
        exchange_pass(
            sensors,
            &pool,
            |chosen, j, c| {
                let others: Vec<usize> = (0..chosen.len())
                    .filter(|&i| i != j)
                    .map(|i| chosen[i])
                    .collect();
                !keep.contains(&chosen[j]) && self.spaced(&others, c)
            },
            score_of,
            current,
        )
    }
}

/// One exchange pass: each slot `j` in turn takes the candidate of `pool` (not already
/// chosen) whose layout scores best, when that improves on `current` by more than
/// rounding. `allowed(chosen, j, c)` vetoes putting candidate `c` in slot `j` (a sensor
/// that must stay, spacing).
/// Trials are scored in parallel and reduced in pool order (ties keep the earlier), so
/// the pass does not depend on the thread count. Returns whether anything changed.
fn exchange_pass(
    chosen: &mut [usize],
    pool: &[usize],
    allowed: impl Fn(&[usize], usize, usize) -> bool + Sync,
    score: impl Fn(&[usize]) -> Score + Sync,
    current: &mut Score,
) -> bool {
    let mut any = false;
    for j in 0..chosen.len() {
        let scores: Vec<Option<Score>> = pool
            .par_iter()
            .map(|&c| {
                if chosen.contains(&c) || !allowed(chosen, j, c) {
                    return None;
                }
                let mut trial = chosen.to_vec();
                trial[j] = c;
                Some(score(&trial))
            })
            .collect();
        if let Some((c, s)) = pick(pool, &scores) {
            if s.better_than(current) && relative_gain(&s, current) {
                chosen[j] = c;
                *current = s;
                any = true;
            }
        }
    }
    any
}

/// An exchange must improve the criterion by more than rounding (1e-9 relative), so the
/// passes end.
fn relative_gain(new: &Score, old: &Score) -> bool {
    new.observable != old.observable || (old.value - new.value) > 1e-9 * old.value.abs().max(1.0)
}

/// The best of `scores` (ties: the first), as (candidate, score).
fn pick(cands: &[usize], scores: &[Option<Score>]) -> Option<(usize, Score)> {
    let mut best: Option<(usize, Score)> = None;
    for (c, s) in cands.iter().zip(scores) {
        if let Some(s) = s {
            if best.as_ref().is_none_or(|b| s.better_than(&b.1)) {
                best = Some((*c, *s));
            }
        }
    }
    best
}

/// Plans `opts.sensors` sensors and `opts.hits` hits on set-up `setup` (module docs).
pub fn plan(
    model: &PlanModel,
    cands: &Candidates,
    setup: usize,
    opts: &PlanOptions,
) -> Result<PlanOutcome, PlanError> {
    if setup >= model.setups.len() {
        return Err(PlanError::Layout(format!("no set-up {setup}")));
    }
    let n_hits = cands.hits.iter().filter(|h| h.setup == setup).count();
    if cands.sensors.len() < opts.sensors {
        return Err(PlanError::Layout(format!(
            "{} sensors asked for, {} candidate sensor positions",
            opts.sensors,
            cands.sensors.len()
        )));
    }
    if n_hits < opts.hits {
        return Err(PlanError::Layout(format!(
            "{} hits asked for, {} candidate hits on set-up '{}'",
            opts.hits, n_hits, model.setups[setup].id
        )));
    }
    if opts.sensors < 3 {
        return Err(PlanError::Layout(
            "at least three triaxial sensors are needed to resolve six rigid motions robustly"
                .into(),
        ));
    }
    if opts.keep_sensors.len() > opts.sensors {
        return Err(PlanError::Layout(format!(
            "{} sensors must stay but only {} are planned",
            opts.keep_sensors.len(),
            opts.sensors
        )));
    }
    let search = model.search_model();
    let planner = Planner {
        model: &search,
        cands,
        opts,
        setup,
        cache: JacobianCache::default(),
        evaluations: Default::default(),
    };
    let mut sensors = planner.initial_sensors();
    if sensors.len() < opts.sensors {
        return Err(PlanError::Layout(format!(
            "only {} sensors can be placed {} m apart",
            sensors.len(),
            opts.min_spacing_m
        )));
    }
    let (mut hits, mut current) = planner.choose_hits(&sensors, &[]);
    for _ in 0..opts.max_rounds {
        if !planner.exchange_sensors(&mut sensors, &hits, &mut current) {
            break;
        }
        let (h, s) = planner.choose_hits(&sensors, &hits);
        hits = h;
        current = s;
    }
    let layout = Layout {
        sensors: sensors.iter().map(|&s| cands.sensors[s].clone()).collect(),
        hits: hits.iter().map(|&k| cands.hits[k].clone()).collect(),
    };
    let rows = layout.rows();
    let data = hit_data(model, &rows, &layout.hits);
    let d: Vec<&ExcitationCovariance> = data.iter().collect();
    let h: Vec<&Hit> = layout.hits.iter().collect();
    let prediction = predict_setup(model, setup, &rows, &h, &d, opts.estimator, &planner.cache)
        .map_err(|u| {
            PlanError::Layout(format!(
                "no candidate layout determines the properties: {}",
                u.reason
            ))
        })?;
    Ok(PlanOutcome {
        value: opts.criterion.value(model, &prediction),
        sensors,
        hits,
        layout,
        prediction,
        evaluations: planner
            .evaluations
            .load(std::sync::atomic::Ordering::Relaxed),
    })
}
