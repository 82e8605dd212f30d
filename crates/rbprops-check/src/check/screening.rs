use super::gauges::{gauge_pivots, REOPEN_SIGNATURE};
use super::problem::{project_out, span_basis, Act, Problem, ScaledSpan};
use crate::error::CheckError;
use crate::lm;
use crate::lm::Fit;
use crate::params::ParamKind;
use nalgebra::DMatrix;
use rayon::prelude::*;
use rbprops_core::c64;

/// Score-test quantities of one candidate at the current model.
#[derive(Clone)]
pub(super) struct Score {
    pub(super) rank: usize,
    pub(super) score: f64,
    pub(super) basis: DMatrix<f64>,
    /// Free coordinates of φ (one dropped per exact gauge).
    pub(super) kept: Vec<usize>,
    /// Gauss–Newton start of the kept coordinates.
    pub(super) start: Vec<f64>,
    /// Unit φ-space directions without first-order signature.
    pub(super) gauge: Vec<Vec<f64>>,
    /// Fraction of the candidate's signature each parameter group explains alone.
    pub(super) absorbed_by: Vec<(String, f64)>,
    /// Number of parameter points the statistic is the best of (1 for the score test;
    /// the profile's size for grid-screened candidates): the threshold is Bonferroni
    /// corrected for it.
    pub(super) n_tests: usize,
    /// Start of the current model's parameters for the refit (re-adjusted to the
    /// profile's best point), when not the current fit's.
    pub(super) theta_start: Option<Vec<f64>>,
}

/// The chord (fixed-Jacobian Gauss–Newton) solver of a screening: the pseudo-inverse of
/// the current model's Jacobian from the SVD that gives the span's basis
/// ([`ScaledSpan`]), shared by every profile-screened candidate of the step.
///
/// Why from the span's SVD: the solver took a second SVD of the same Jacobian (unscaled)
/// at every step, a tenth of a profile's time; its pseudo-inverse over the directions
/// the span keeps is also the better conditioned one (a near-gauge, dropped from the
/// span, no longer takes a long step).
pub(super) struct Chord<'s> {
    span: &'s ScaledSpan,
}

impl<'s> Chord<'s> {
    pub(super) fn new(span: &'s ScaledSpan) -> Self {
        Chord { span }
    }

    /// The chord steps `J⁺(−r)` of several residuals at once, `D⁻¹ V S⁻¹ (Uᵀ(−r))`
    /// ([`ScaledSpan`]), `Uᵀ(−r)` one product for all of them ([`lm::tr_mul`]).
    ///
    /// Why together: one solve reads all of U (52 MB at 60 parameters) for 2np flops,
    /// from memory; a profile's refinements took 64 of them per candidate and step.
    fn steps(&self, rs: &[&nalgebra::DVector<f64>]) -> Vec<nalgebra::DVector<f64>> {
        let u = &self.span.basis;
        let b = DMatrix::from_iterator(
            u.nrows(),
            rs.len(),
            rs.iter().flat_map(|r| r.iter().copied()),
        );
        // −Uᵀr negated after the product: the same values as the product of −r (IEEE
        // negation is exact), without a negated copy of the residuals.
        let d = &self.span.pseudo_inverse_right * -lm::tr_mul(u, &b);
        d.column_iter().map(|c| c.into_owned()).collect()
    }
}

/// The current model a candidate is screened at: the problem, the current fit with its
/// active effects, the orthonormal basis of the fit's Jacobian span and the chord solver
/// shared by the step's profile-screened candidates.
#[derive(Clone, Copy)]
pub(super) struct AtModel<'s, 'a> {
    pub(super) p: &'s Problem<'a>,
    pub(super) cur: &'s Fit,
    pub(super) active: &'s [Act],
    pub(super) q0: &'s DMatrix<f64>,
    pub(super) chord: &'s Chord<'s>,
}

/// Profile screening of a candidate whose signature vanishes to every order at its
/// neutral point (see `Candidate::grid`): at each grid point φ_g the residual r_g of the
/// current model plus the effect at φ_g, with the current parameters re-adjusted
/// linearly (their Jacobian's span projected out), gives the approximate likelihood
/// ratio `‖P⊥ r‖² − ‖P⊥ r_g‖²`. The best point starts the refit; the statistic is the
/// best of `G` tests, so its threshold is Bonferroni corrected over the grid.
pub(super) fn grid_candidate(
    at: AtModel,
    c: usize,
    grid: &[Vec<f64>],
    delay_scan: bool,
) -> Result<Score, CheckError> {
    let (grid, n_tests) = profile_points(at.p, grid, delay_scan, &at.cur.residual);
    profile_candidate(at, c, &grid, n_tests, true)
}

/// An in-band resonance ([`crate::resonance`]): the profile over (ω_m, ζ_m) of the
/// linear residue fit to the current residual proposes the starting points, which are
/// then evaluated as a grid; Bonferroni over every profile point searched.
pub(super) fn resonance_candidate(at: AtModel, c: usize) -> Result<Score, CheckError> {
    let AtModel { p, cur, .. } = at;
    let (starts, n_tests) =
        crate::resonance::profile_starts(p.layout, &p.used, p.sigma, &cur.residual);
    if starts
        .first()
        .is_some_and(|s| s.len() != p.cands[c].neutral.len())
    {
        return Err(CheckError::Model(
            "elastic_mode: the spec's channels and excitations do not match the recording's layout"
                .into(),
        ));
    }
    profile_candidate(at, c, &starts, n_tests, false)
}

/// A profile point after its chord refinement: the gain, the index of the (grid point,
/// start) pair, and the current model's re-adjusted parameters and the residual there
/// (`None` for a point not chord-refined).
type ProfilePoint = (f64, usize, Option<(Vec<f64>, nalgebra::DVector<f64>)>);

/// Profile points whose residuals are projected onto the current span together
/// ([`projected_norms`]).
const PROBE_BATCH: usize = 16;

/// `‖q0ᵀ r‖²` of each residual `r` (q0 orthonormal, n × p), so that `‖P⊥ r‖² = ‖r‖² −
/// ‖q0ᵀ r‖²`: the residuals lie mostly outside the span (the current fit's residual is
/// orthogonal to it), so the difference loses no significant digits.
///
/// Why a batch: one residual's projection reads all of q0 (27 MB at 60 parameters) for
/// 2np flops, from memory; the batch's is one matrix product `Rᵀ q0` (cache-blocked),
/// which reads q0 once for all of them. A profile of the cords has about 180 points.
fn projected_norms(q0: &DMatrix<f64>, rs: &[&nalgebra::DVector<f64>]) -> Vec<f64> {
    if q0.ncols() == 0 || rs.is_empty() {
        return vec![0.0; rs.len()];
    }
    let rm = DMatrix::from_iterator(
        q0.nrows(),
        rs.len(),
        rs.iter().flat_map(|r| r.iter().copied()),
    );
    let c = lm::tr_mul(&rm, q0);
    (0..rs.len()).map(|k| c.row(k).norm_squared()).collect()
}

/// Points per start of a profile that are chord-refined (the most promising by the
/// first chord step's prediction; see [`profile_candidate`]).
const PROFILE_REFINED: usize = 8;

/// Grid size above which a profile is first evaluated at every other point (see
/// [`profile_candidate`]): the cords' grid (string-mode frequencies 2 % apart, about
/// 170 points), not the gravity stiffness's lengths (41 or 66) nor the record lengths
/// (8 and the lag scan's, whose neighbours are not close).
const PROFILE_COARSE_ABOVE: usize = 100;

/// Indices into `points` ((grid point, start) pairs) of the [`PROFILE_REFINED`]
/// evaluated points per start with the smallest predicted χ² (ties: the first).
fn most_promising(
    first: &[Option<(f64, f64)>],
    points: &[(usize, usize)],
    n_starts: usize,
) -> Vec<usize> {
    let mut out = Vec::new();
    for k in 0..n_starts {
        let mut order: Vec<(f64, usize)> = (0..points.len())
            .filter(|&i| points[i].1 == k)
            .filter_map(|i| first[i].map(|(_, predicted)| (predicted, i)))
            .collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        out.extend(order.iter().take(PROFILE_REFINED).map(|&(_, i)| i));
    }
    out
}

/// Profile screening over the parameter points `grid` (see [`grid_candidate`]), the
/// statistic the best of `n_tests` tests.
///
/// With `from_nominal`, each point is also tried with the nominal model's own
/// parameters (the spec's inertia, stiffness and damping; the active effects at their
/// current values) in place of the current fit's. A fit of a model that lacks an effect
/// with no neutral signature can be pulled far from the truth: a nominal with free
/// directions fits the pendulum region of a hanging body's FRFs with mass lines, with a
/// mass several times the body's and damping ratios of 0.5 and more, and from there the hanging
/// body at its true cord length fits worse than nothing and no re-adjustment reaches it,
/// while from the nominal's values it is nearly exact (the `independent_cords` tests).
pub(super) fn profile_candidate(
    at: AtModel,
    c: usize,
    grid: &[Vec<f64>],
    n_tests: usize,
    from_nominal: bool,
) -> Result<Score, CheckError> {
    let AtModel {
        p,
        cur,
        active,
        q0,
        chord,
    } = at;
    let cand = &p.cands[c];
    let np = cand.neutral.len();
    let mut act = active.to_vec();
    act.push(Act::full(c, np));
    let r0 = nalgebra::DVector::from_column_slice(&cur.residual);
    let base = r0.norm_squared() - projected_norms(q0, &[&r0])[0];
    // Chord (fixed-Jacobian Gauss–Newton) re-adjustment of the current parameters at
    // the most promising grid points: a few model evaluations, enough when the effect
    // moves them far.
    let nb = cur.theta.len();
    let eval = |t: &[f64]| -> Option<nalgebra::DVector<f64>> {
        p.residual(t, &act).ok().map(nalgebra::DVector::from_vec)
    };
    let starts = profile_starts(p, &cur.theta, from_nominal);
    let points: Vec<(usize, usize)> = (0..grid.len())
        .flat_map(|g| (0..starts.len()).map(move |k| (g, k)))
        .collect();
    let theta_at = |(g, k): (usize, usize)| {
        let mut t = starts[k].clone();
        t.extend_from_slice(&grid[g]);
        t
    };
    // A point once at a start: its χ² and the χ² the first chord step predicts,
    // ‖P⊥ r_g‖² (the step solves the linearised problem of the current Jacobian, whose
    // span `q0` is). From the current fit's parameters that prediction is also the
    // linearised gain (the score-like statistic).
    // The points of `idx` are evaluated in batches of [`PROBE_BATCH`], whose projections
    // onto q0 are one matrix product (see [`projected_norms`]); the most promising
    // residuals are kept ([`MostPromising`]).
    let n_starts = starts.len();
    let kept = MostPromising::new(n_starts);
    let probe_all = |idx: &[usize]| -> Vec<Option<(f64, f64)>> {
        idx.par_chunks(PROBE_BATCH)
            .flat_map_iter(|batch| {
                let rs: Vec<Option<nalgebra::DVector<f64>>> = batch
                    .par_iter()
                    .map(|&i| eval(&theta_at(points[i])))
                    .collect();
                let evaluated: Vec<&nalgebra::DVector<f64>> = rs.iter().flatten().collect();
                let mut projected = projected_norms(q0, &evaluated).into_iter();
                batch
                    .iter()
                    .zip(&rs)
                    .map(|(&i, r)| {
                        let r = r.as_ref()?;
                        let n2 = r.norm_squared();
                        let predicted = n2 - projected.next().expect("one per residual");
                        kept.offer(points[i].1, i, predicted, r);
                        Some((n2, predicted))
                    })
                    .collect::<Vec<_>>()
            })
            .collect()
    };
    let first = probe_profile(&points, grid.len(), n_starts, &probe_all);
    // Only the points the first step promises most, per start, are chord-refined (the
    // model evaluations of a profile were mostly those steps, and a profile of the
    // cords' string modes has hundreds of points): the others keep their one-point gain.
    let mut refine = vec![false; points.len()];
    for i in most_promising(&first, &points, n_starts) {
        refine[i] = true;
    }
    let kept = kept.residuals();
    let gain_of = |i: usize, chi: f64| {
        let (_, predicted) = first[i].expect("evaluated");
        let lin = if points[i].1 == 0 {
            base - predicted
        } else {
            f64::NEG_INFINITY
        };
        lin.max(r0.norm_squared() - chi)
    };
    // The refinements are independent of each other: they step together (one pass over
    // the chord's U per step, [`Chord::steps`]) with the points' models evaluated in
    // parallel (a profile of slow models, cords with their string modes, was the last
    // candidate of the screening to finish), and the best is then taken in the order of
    // the points, the first of equal gains, as a loop over them takes it.
    let chorded = refine_points(chord, &eval, &refine, &kept, &|i| theta_at(points[i]));
    let refined: Vec<Option<ProfilePoint>> = chorded
        .into_iter()
        .enumerate()
        .map(|(i, c)| {
            let (chi0, _) = first[i]?;
            if !refine[i] {
                return Some((gain_of(i, chi0), i, None));
            }
            let (_, chi, t, rg) = c?;
            Some((gain_of(i, chi), i, Some((t[..nb].to_vec(), rg))))
        })
        .collect();
    let (gain, i, theta_best, rg) =
        best_profile_point(refined, &cand.id, &|i| theta_at(points[i]), &eval, nb)?;
    Ok(profile_score(
        q0,
        &r0 - &rg,
        np,
        gain,
        grid[points[i].0].clone(),
        n_tests,
        theta_best,
    ))
}

/// The starts of a profile's chord refinement: the current parameters, and with
/// `from_nominal` the spec's baseline values with the active effects' current ones.
fn profile_starts(p: &Problem, theta: &[f64], from_nominal: bool) -> Vec<Vec<f64>> {
    let mut starts = vec![theta.to_vec()];
    if from_nominal {
        let mut t = theta.to_vec();
        t[..p.n_base()].copy_from_slice(&p.baseline.initial());
        starts.push(t);
    }
    starts
}

/// The residuals of the most promising profile points so far, per start (at most
/// `PROFILE_REFINED`, smallest predicted χ² first, the first of equal ones), kept so the
/// chord refinement starts from them rather than evaluating them again. The set kept
/// is the same in any order of the offers.
struct MostPromising {
    per_start: Vec<std::sync::Mutex<Vec<(f64, usize, nalgebra::DVector<f64>)>>>,
}

impl MostPromising {
    fn new(n_starts: usize) -> Self {
        MostPromising {
            per_start: (0..n_starts).map(|_| Default::default()).collect(),
        }
    }

    /// Point `i` at start `start`, with its predicted χ² and its residual `r`.
    fn offer(&self, start: usize, i: usize, predicted: f64, r: &nalgebra::DVector<f64>) {
        let mut list = self.per_start[start].lock().expect("no panic while held");
        let pos = list.partition_point(|(p, j, _)| p.total_cmp(&predicted).then(j.cmp(&i)).is_lt());
        if pos < PROFILE_REFINED {
            list.insert(pos, (predicted, i, r.clone()));
            list.truncate(PROFILE_REFINED);
        }
    }

    /// The kept residuals by point index.
    fn residuals(self) -> Vec<(usize, nalgebra::DVector<f64>)> {
        self.per_start
            .into_iter()
            .flat_map(|m| m.into_inner().expect("no panic while held"))
            .map(|(_, i, r)| (i, r))
            .collect()
    }
}

/// The first step at every point of a profile (`points`: grid point and start), by
/// `probe_all`: a large grid (the cords' string-mode frequencies, 2 % apart) first at
/// every other point, then the skipped neighbours of the most promising ones. A point
/// left out counts as not evaluated (`None`).
fn probe_profile(
    points: &[(usize, usize)],
    grid_len: usize,
    n_starts: usize,
    probe_all: &dyn Fn(&[usize]) -> Vec<Option<(f64, f64)>>,
) -> Vec<Option<(f64, f64)>> {
    let coarse = grid_len > PROFILE_COARSE_ABOVE;
    let mut first: Vec<Option<(f64, f64)>> = vec![None; points.len()];
    let probed: Vec<usize> = (0..points.len())
        .filter(|&i| !coarse || points[i].0.is_multiple_of(2))
        .collect();
    for (i, f) in probed.iter().zip(probe_all(&probed)) {
        first[*i] = f;
    }
    if coarse {
        let mut fill: Vec<usize> = most_promising(&first, points, n_starts)
            .into_iter()
            .flat_map(|i| {
                let (g, k) = points[i];
                [g.wrapping_sub(1), g + 1]
                    .into_iter()
                    .filter(|&h| h < grid_len && h % 2 == 1)
                    .map(move |h| h * n_starts + k)
            })
            .collect();
        fill.sort_unstable();
        fill.dedup();
        for (i, f) in fill.iter().zip(probe_all(&fill)) {
            first[*i] = f;
        }
    }
    first
}

/// The profile's best point, in the order of the points (the first of equal gains, as
/// a loop over them takes it): its gain, index, base parameters (the first `nb`) and
/// residual; a best point that was not refined is evaluated again (the same
/// evaluation) at its parameters `theta_of(i)`.
fn best_profile_point(
    refined: Vec<Option<ProfilePoint>>,
    id: &str,
    theta_of: &dyn Fn(usize) -> Vec<f64>,
    eval: &dyn Fn(&[f64]) -> Option<nalgebra::DVector<f64>>,
    nb: usize,
) -> Result<(f64, usize, Vec<f64>, nalgebra::DVector<f64>), CheckError> {
    let mut best: Option<ProfilePoint> = None;
    for point in refined.into_iter().flatten() {
        if best.as_ref().is_none_or(|b| point.0 > b.0) {
            best = Some(point);
        }
    }
    let Some((gain, i, refined)) = best else {
        return Err(CheckError::Model(format!(
            "'{id}': no point of its screening profile could be evaluated"
        )));
    };
    let (theta_best, rg) = match refined {
        Some(refined) => refined,
        None => {
            let t = theta_of(i);
            let rg = eval(&t).ok_or_else(|| {
                CheckError::Model(format!("'{id}': its best profile point failed"))
            })?;
            (t[..nb].to_vec(), rg)
        }
    };
    Ok((gain, i, theta_best, rg))
}

/// The chord-refined points of a profile by index (`None` where not refined, or where
/// its model cannot be evaluated): each point `i` with `refine[i]` (an evaluated one)
/// from its kept residual, else evaluated again at `theta_of(i)` (see [`chord_refine`]).
fn refine_points(
    chord: &Chord,
    eval: &(dyn Fn(&[f64]) -> Option<nalgebra::DVector<f64>> + Sync),
    refine: &[bool],
    kept: &[(usize, nalgebra::DVector<f64>)],
    theta_of: &(dyn Fn(usize) -> Vec<f64> + Sync),
) -> Vec<Option<ChordPoint>> {
    let starts: Vec<(usize, Vec<f64>, nalgebra::DVector<f64>)> = (0..refine.len())
        .into_par_iter()
        .filter(|&i| refine[i])
        .filter_map(|i| {
            let t = theta_of(i);
            let rg = match kept.iter().find(|(j, _)| *j == i) {
                Some((_, r)) => r.clone(),
                None => eval(&t)?,
            };
            Some((i, t, rg))
        })
        .collect();
    let mut chorded: Vec<Option<ChordPoint>> = (0..refine.len()).map(|_| None).collect();
    for point in chord_refine(chord, eval, starts) {
        let i = point.0;
        chorded[i] = Some(point);
    }
    chorded
}

/// A chord-refined profile point: its index, χ², parameters and residual.
type ChordPoint = (usize, f64, Vec<f64>, nalgebra::DVector<f64>);

/// Up to four chord (fixed-Jacobian Gauss–Newton) steps from each point `(i, t, r)`
/// (its index, parameters and residual), each kept only if it lowers that point's χ²:
/// every point ends at its last improvement, returned as `(i, χ², t, r)`. A point's
/// steps do not depend on the others'; they are taken together so that each step
/// reads the chord's U once for all of them.
fn chord_refine(
    chord: &Chord,
    eval: &(dyn Fn(&[f64]) -> Option<nalgebra::DVector<f64>> + Sync),
    points: Vec<(usize, Vec<f64>, nalgebra::DVector<f64>)>,
) -> Vec<ChordPoint> {
    let mut at: Vec<ChordPoint> = points
        .into_iter()
        .map(|(i, t, r)| (i, r.norm_squared(), t, r))
        .collect();
    let mut live: Vec<usize> = (0..at.len()).collect();
    for _ in 0..4 {
        if live.is_empty() {
            break;
        }
        let rs: Vec<&nalgebra::DVector<f64>> = live.iter().map(|&k| &at[k].3).collect();
        let steps = chord.steps(&rs);
        let tried: Vec<Option<(Vec<f64>, nalgebra::DVector<f64>)>> = live
            .par_iter()
            .zip(steps.par_iter())
            .map(|(&k, d)| {
                let mut t1 = at[k].2.clone();
                t1.iter_mut().zip(d.iter()).for_each(|(x, d)| *x += d);
                let r1 = eval(&t1)?;
                (r1.norm_squared() < at[k].1).then_some((t1, r1))
            })
            .collect();
        let mut next = Vec::new();
        for (k, better) in live.into_iter().zip(tried) {
            if let Some((t1, r1)) = better {
                at[k] = (at[k].0, r1.norm_squared(), t1, r1);
                next.push(k);
            }
        }
        live = next;
    }
    at
}

/// The score of a profiled candidate with `np` parameters from its best point: the
/// signature (the residual's `change` there with the current span `q0` projected out) as
/// its one-column basis, the gain, the grid point as the refit's start.
fn profile_score(
    q0: &DMatrix<f64>,
    change: nalgebra::DVector<f64>,
    np: usize,
    gain: f64,
    start: Vec<f64>,
    n_tests: usize,
    theta_best: Vec<f64>,
) -> Score {
    let sig = project_out(
        &DMatrix::from_column_slice(change.len(), 1, change.as_slice()),
        q0,
    );
    let n = sig.norm();
    let basis = if n > 0.0 {
        sig / n
    } else {
        DMatrix::zeros(sig.nrows(), 0)
    };
    Score {
        rank: if n > 0.0 { np } else { 0 },
        score: gain.max(0.0),
        basis,
        kept: (0..np).collect(),
        start,
        gauge: Vec::new(),
        absorbed_by: Vec::new(),
        n_tests,
        theta_start: Some(theta_best),
    }
}

/// The profile points of a grid-screened candidate and the number of tests its best
/// point is selected from: the grid, plus for a record length (`delay_scan`) the lags
/// of the current residual's lag scan ([`crate::candidates::delay_peaks`]) over
/// 1/(8Δf)·0.9 < T < 0.95/Δf, counted as the number of independent lags scanned.
pub(super) fn profile_points(
    p: &Problem,
    grid: &[Vec<f64>],
    delay_scan: bool,
    residual: &[f64],
) -> (Vec<Vec<f64>>, usize) {
    let n_grid = grid.len();
    let mut grid = grid.to_vec();
    let f = &p.layout.frequency_hz;
    let nl = f.len();
    if !delay_scan || nl < 2 {
        return (grid, n_grid);
    }
    let df = (f[nl - 1] - f[0]) / (nl - 1) as f64;
    let rows: Vec<(usize, usize, c64)> = p
        .used
        .iter()
        .enumerate()
        .map(|(j, &i)| {
            (
                i / nl,
                i % nl,
                c64::new(residual[2 * j], residual[2 * j + 1]),
            )
        })
        .collect();
    let (taus, m) = crate::candidates::delay_peaks(&rows, f, 0.9 / (8.0 * df), 0.95 / df, 4);
    grid.extend(taus.iter().map(|t| vec![1.0 / t]));
    (grid, n_grid + m)
}

/// Relative singular value below which a candidate direction counts as absorbed (no
/// power to detect it at first order).
pub(super) const ABSORBED: f64 = 1e-4;
/// Residual change per typical step of a candidate parameter, relative to the norm of
/// the data (both in noise units), below which the step has no signature at all: the
/// model's rounding (~1e-15 relative) over a finite-difference step of 1e-7 is about
/// 1e-8, and a signature this small would need 10⁴ typical steps to change χ² by 10.
pub(super) const NO_SIGNATURE: f64 = 1e-6;
/// Below this it is an exact gauge (a symmetry such as a common gain ↔ mass): such
/// directions are removed from the refit. Directions between the two are absorbed only
/// at first order and stay free in the refit, where the non-linear model can use them.
pub(super) const GAUGE: f64 = 1e-7;

/// `norms` (the candidate's Jacobian column norms) with 0 for each coordinate that
/// cannot move the residual by [`REOPEN_SIGNATURE`] noise units anywhere in half its
/// plausible range once the current model's parameters compensate: the data cannot
/// resolve it, so it is dropped from the refit as a gauge is (the refit frees it where
/// a fitted point makes it identifiable, [`super::gauges::reopen_dropped`]).
/// Normalised, such a column would count as a full direction: a force's location along
/// its own line, once a fitted force direction has turned that line by a milliradian,
/// then slides to its hard bound of a metre and stalls the fit of everything coupled
/// with it.
fn unresolvable_as_gauges(jp: &DMatrix<f64>, norms: Vec<f64>, half_range: &[f64]) -> Vec<f64> {
    norms
        .into_iter()
        .enumerate()
        .map(|(k, n)| {
            if n > 0.0 && jp.column(k).norm() * half_range[k] < REOPEN_SIGNATURE {
                0.0
            } else {
                n
            }
        })
        .collect()
}

/// The thin SVD of the projected candidate columns `jp` normalised by `norms`, after
/// dropping, one at a time, each coordinate absorbed at first order whose own
/// signature is unresolvable: its column's distance from the span of the other
/// coordinates' columns (after the current model's), `d_k = ‖(I − P_{J∖k}) j_k‖`, lies
/// between the exact-gauge and the absorbed level ([`GAUGE`] < d_k/‖j_k‖ ≤ [`ABSORBED`])
/// and `d_k` over half the plausible range moves the residual by less than
/// [`REOPEN_SIGNATURE`] noise units. Whatever such a coordinate does, the others do
/// within the noise, so the data cannot tell where on that near-gauge the truth lies;
/// left free, the refit slides along it to a hard bound. The case met: a force's
/// location along its own line, once a fitted direction of that force (turned by a few
/// milliradians to stand in for the location) has made it a combination, to one part in
/// 10⁵, of the perpendicular offsets; it went to its bound of a metre and left the
/// right two effects at χ²/ν 8 (docs/physics.md, M5). Exact gauges (`d_k/‖j_k‖ ≤ GAUGE`)
/// are left to [`gauge_pivots`], which keeps one coordinate of each. The smallest own
/// signature goes first and the rest is judged again without it, so a pair that is
/// nearly one direction loses one member, not both. `d_k` comes from the SVD of the
/// normalised columns, `d_k = 1/√(Σᵢ V_ki²/σᵢ²)`. Returned with the normalised columns
/// it is of (its singular values and `Vᵀ`, no U: [`lm::thin_sv`]).
fn svd_without_own_gauges(
    jp: &DMatrix<f64>,
    norms: &mut [f64],
    half_range: &[f64],
) -> (
    nalgebra::SVD<f64, nalgebra::Dyn, nalgebra::Dyn>,
    DMatrix<f64>,
) {
    loop {
        let mut jt = jp.clone();
        normalise_columns(&mut jt, norms);
        let svd = lm::thin_sv(&jt);
        let Some(k) = weakest_own_signature(&svd, norms, half_range) else {
            return (svd, jt);
        };
        norms[k] = 0.0;
    }
}

/// The coordinate [`svd_without_own_gauges`] drops next, if any.
fn weakest_own_signature(
    svd: &nalgebra::SVD<f64, nalgebra::Dyn, nalgebra::Dyn>,
    norms: &[f64],
    half_range: &[f64],
) -> Option<usize> {
    let sv = &svd.singular_values;
    if sv.iter().all(|&s| s > ABSORBED || s <= GAUGE) {
        return None;
    }
    let vt = svd.v_t.as_ref().expect("requested");
    let own = |k: usize| {
        let inv: f64 = (0..sv.len())
            .filter(|&i| sv[i] > GAUGE)
            .map(|i| vt[(i, k)] * vt[(i, k)] / (sv[i] * sv[i]))
            .sum();
        let in_exact: f64 = (0..sv.len())
            .filter(|&i| sv[i] <= GAUGE)
            .map(|i| vt[(i, k)] * vt[(i, k)])
            .sum();
        (inv > 0.0 && in_exact < 0.01).then(|| 1.0 / inv.sqrt())
    };
    (0..norms.len())
        .filter(|&k| norms[k] > 0.0)
        .filter_map(|k| own(k).map(|d| (k, d)))
        .filter(|&(k, d)| {
            d > GAUGE && d <= ABSORBED && d * norms[k] * half_range[k] < REOPEN_SIGNATURE
        })
        .min_by(|a, b| {
            (a.1 * norms[a.0] * half_range[a.0])
                .total_cmp(&(b.1 * norms[b.0] * half_range[b.0]))
                .then(a.0.cmp(&b.0))
        })
        .map(|(k, _)| k)
}

/// The score test of candidate `c` at the current model (docs/physics.md, M5): its
/// Jacobian columns at neutral, normalised and with the current span projected out;
/// the score is the residual's projection on their detectable directions, and a
/// Gauss–Newton step on them starts the refit.
pub(super) fn score_candidate(at: AtModel, c: usize) -> Result<Score, CheckError> {
    let cand = &at.p.cands[c];
    let (jc, norms) = candidate_columns(at, c)?;
    // One projection serves both the unresolvable test (raw columns) and the score
    // (normalised ones): a column's projection scales with the column.
    let jp = project_out(&jc, at.q0);
    let half_range: Vec<f64> = (0..norms.len())
        .map(|k| at.p.cands[c].half_range(k))
        .collect();
    let mut norms = unresolvable_as_gauges(&jp, norms, &half_range);
    let (svd, jt) = svd_without_own_gauges(&jp, &mut norms, &half_range);
    let keep: Vec<usize> = (0..svd.singular_values.len())
        .filter(|&k| svd.singular_values[k] > ABSORBED)
        .collect();
    // The detectable directions' basis U = J̃ V S⁻¹ (kept σ > ABSORBED: at most 1e4 ε
    // from orthonormal), and the residual's projections on them, S⁻¹ Vᵀ (J̃ᵀ r).
    let vt = svd.v_t.as_ref().expect("requested");
    let v_over_s = DMatrix::from_fn(jt.ncols(), keep.len(), |j, k| {
        vt[(keep[k], j)] / svd.singular_values[keep[k]]
    });
    let basis = lm::mul(&jt, &v_over_s);
    let jtr = jt.tr_mul(&nalgebra::DVector::from_column_slice(&at.cur.residual));
    let proj = v_over_s.tr_mul(&jtr);
    let (kept, start) = gauss_newton_start(cand, c, &svd, &keep, &proj, &norms);
    let absorbed_by = if keep.is_empty() {
        absorbed_by(at, &jc, &norms)
    } else {
        Vec::new()
    };
    Ok(Score {
        rank: keep.len(),
        score: proj.norm_squared(),
        basis,
        kept,
        start,
        gauge: gauge_directions(&svd, cand.neutral.len(), &norms),
        absorbed_by,
        n_tests: 1,
        theta_start: None,
    })
}

/// Candidate `c`'s Jacobian columns at neutral (the current parameters fixed) and their
/// norms, 0 for a column that is rounding, not a signature.
fn candidate_columns(at: AtModel, c: usize) -> Result<(DMatrix<f64>, Vec<f64>), CheckError> {
    let AtModel { p, cur, active, .. } = at;
    let cand = &p.cands[c];
    let mut act = active.to_vec();
    act.push(Act::full(c, cand.neutral.len()));
    let f = |phi: &[f64]| {
        let mut t = cur.theta.clone();
        t.extend_from_slice(phi);
        p.residual(&t, &act)
    };
    let columns = p.columns(&act[act.len() - 1..], false);
    let jc =
        lm::jacobian_grouped_against(&f, &cand.neutral, &cand.scales, &cur.residual, &columns)?;
    // A column whose typical step moves the residual by less than NO_SIGNATURE of the
    // data's norm is rounding, not a signature: normalised, it would count as a
    // direction (the tilt of cords without gravity stiffness, 2e-4 noise units per
    // step where the data are 2e4, gave a rank of 3 for 2 and a wrong start).
    let floor = NO_SIGNATURE * p.data_norm();
    let norms = (0..jc.ncols())
        .map(|k| {
            let n = jc.column(k).norm();
            if n * cand.scales[k] < floor {
                0.0
            } else {
                n
            }
        })
        .collect();
    Ok((jc, norms))
}

/// Columns scaled to unit norm; those of norm 0 (no signature) zeroed.
fn normalise_columns(m: &mut DMatrix<f64>, norms: &[f64]) {
    for (k, &n) in norms.iter().enumerate() {
        if n > 0.0 {
            m.column_mut(k).scale_mut(1.0 / n);
        } else {
            m.column_mut(k).fill(0.0);
        }
    }
}

/// The refit's free coordinates and their start: the Gauss–Newton step on the
/// candidate's parameters alone (projected problem, `r + J̃ δ ≈ 0`, so δ = −V Σ⁻¹ Uᵀ r
/// in normalised coordinates over the detectable directions `keep`, whose projections
/// of the residual are `proj`), one coordinate dropped per exact gauge with the step
/// shifted along the gauges to leave it neutral, then shrunk towards neutral until it
/// respects the effect's bounds.
fn gauss_newton_start(
    cand: &crate::candidates::Candidate,
    c: usize,
    svd: &nalgebra::SVD<f64, nalgebra::Dyn, nalgebra::Dyn>,
    keep: &[usize],
    proj: &nalgebra::DVector<f64>,
    norms: &[f64],
) -> (Vec<usize>, Vec<f64>) {
    let vt = svd.v_t.as_ref().expect("requested");
    let np = cand.neutral.len();
    let sv = |k: usize| svd.singular_values.get(k).copied().unwrap_or(0.0);
    // Null directions (exact gauges) in normalised coordinates; V is complete (np×np)
    // only when rows ≥ columns, which holds (one row per residual entry).
    let null: Vec<usize> = (0..np).filter(|&k| sv(k) <= GAUGE).collect();
    // Minimum norm: no gauge component.
    let mut delta = vec![0.0; np];
    for (kk, &k) in keep.iter().enumerate() {
        let coef = -proj[kk] / svd.singular_values[k];
        for (j, d) in delta.iter_mut().enumerate() {
            *d += coef * vt[(k, j)];
        }
    }
    let dropped = gauge_pivots(&null, vt, &delta);
    let kept: Vec<usize> = (0..np).filter(|j| !dropped.contains(j)).collect();
    // Shift δ along the gauges so the dropped coordinates stay neutral (the gauges
    // leave the residual unchanged).
    if !dropped.is_empty() {
        let g = dropped.len();
        let a = DMatrix::from_fn(g, null.len(), |r, c| vt[(null[c], dropped[r])]);
        let b = nalgebra::DVector::from_iterator(g, dropped.iter().map(|&j| -delta[j]));
        if let Ok(beta) = a.svd(true, true).solve(&b, 1e-12) {
            for (c, &k) in null.iter().enumerate() {
                for (j, d) in delta.iter_mut().enumerate() {
                    *d += beta[c] * vt[(k, j)];
                }
            }
        }
    }
    let mut step: Vec<f64> = kept
        .iter()
        .map(|&j| {
            if norms[j] > 0.0 {
                delta[j] / norms[j]
            } else {
                0.0
            }
        })
        .collect();
    let infos = cand.effect.parameters();
    let probe = Act::new(c, kept.clone());
    let at = |step: &[f64]| -> Vec<f64> {
        kept.iter()
            .zip(step)
            .map(|(&j, d)| cand.neutral[j] + d)
            .collect()
    };
    for _ in 0..60 {
        let phi = probe.phi(&cand.neutral, &at(&step));
        if phi
            .iter()
            .zip(&infos)
            .all(|(v, pi)| *v >= pi.lower && *v <= pi.upper)
            && cand.effect.with_values(&phi).is_ok()
        {
            break;
        }
        step.iter_mut().for_each(|a| *a *= 0.5);
    }
    let start = at(&step);
    (kept, start)
}

/// Unit φ-space directions without first-order signature (singular value at most
/// [`ABSORBED`]), in the effect's own coordinates.
fn gauge_directions(
    svd: &nalgebra::SVD<f64, nalgebra::Dyn, nalgebra::Dyn>,
    np: usize,
    norms: &[f64],
) -> Vec<Vec<f64>> {
    let vt = svd.v_t.as_ref().expect("requested");
    let sv = |k: usize| svd.singular_values.get(k).copied().unwrap_or(0.0);
    (0..np)
        .filter(|&k| sv(k) <= ABSORBED)
        .map(|k| {
            let v: Vec<f64> = (0..np)
                .map(|j| {
                    if norms[j] > 0.0 {
                        vt[(k, j)] / norms[j]
                    } else {
                        vt[(k, j)]
                    }
                })
                .collect();
            let n = v
                .iter()
                .map(|x| x * x)
                .sum::<f64>()
                .sqrt()
                .max(f64::MIN_POSITIVE);
            v.iter().map(|x| x / n).collect()
        })
        .collect()
}

/// For a candidate without detectable direction: the fraction of its (normalised)
/// signature each parameter group of the baseline explains alone (the not-observable
/// report).
fn absorbed_by(at: AtModel, jc: &DMatrix<f64>, norms: &[f64]) -> Vec<(String, f64)> {
    let (p, cur) = (at.p, at.cur);
    let mut jcs = jc.clone();
    normalise_columns(&mut jcs, norms);
    let groups: [(&str, &dyn Fn(&ParamKind) -> bool); 3] = [
        ("inertia (10 free parameters)", &|k| {
            matches!(k, ParamKind::Inertia(_))
        }),
        ("suspension stiffness scales", &|k| {
            matches!(k, ParamKind::StiffnessScale { .. })
        }),
        ("damping", &|k| {
            matches!(
                k,
                ParamKind::ModalDampingLog(_) | ParamKind::RayleighAlpha | ParamKind::RayleighBeta
            )
        }),
    ];
    let mut out = Vec::new();
    for (name, sel) in groups {
        let cols: Vec<usize> = p
            .baseline
            .kinds
            .iter()
            .enumerate()
            .filter(|(_, k)| sel(k))
            .map(|(i, _)| i)
            .collect();
        if cols.is_empty() {
            continue;
        }
        let jg = DMatrix::from_fn(cur.jacobian.nrows(), cols.len(), |r, c| {
            cur.jacobian[(r, cols[c])]
        });
        let (qg, _) = span_basis(&jg, 1e-10);
        let rest = project_out(&jcs, &qg);
        let tot = jcs.norm_squared().max(f64::MIN_POSITIVE);
        out.push((name.to_string(), 1.0 - rest.norm_squared() / tot));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::{most_promising, Chord, ScaledSpan, PROFILE_REFINED};
    use nalgebra::{DMatrix, DVector};

    /// The chord steps of several residuals together are each the minimum-norm
    /// least-squares step in the scaled coordinates, `D⁻¹ (J D⁻¹)⁺ (−r)`, of nalgebra's
    /// SVD of the scaled Jacobian (rows not a multiple of the row block; a column twice
    /// another, so that a direction falls under the threshold and is dropped, and
    /// columns of scales 1e-3 to 1e3). Two backward-stable solutions differ by at most
    /// the perturbation bound of least squares, `c ε (κ ‖x‖ + κ² ‖res‖ / s₁)` per
    /// scaled coordinate (κ = s₁/s_min over the kept directions), with `c = 10 p`.
    #[test]
    fn chord_steps_together_are_each_scaled_minimum_norm_solve() {
        let (n, p) = (5 * 1024 + 13, 7);
        let mut j = DMatrix::from_fn(n, p, |i, k| {
            ((i * (k + 3)) as f64 * 0.37).sin() * 10f64.powi(k as i32 % 7 - 3)
        });
        let dup = j.column(1) * 2.0;
        j.set_column(4, &dup);
        let span = ScaledSpan::of(&j, 1e-10);
        assert_eq!(
            span.basis.ncols(),
            p - 1,
            "the duplicate direction is dropped"
        );
        let chord = Chord::new(&span);
        let rs: Vec<DVector<f64>> = (0..5)
            .map(|m| DVector::from_fn(n, |i, _| ((i + 31 * m) as f64 * 0.011).cos()))
            .collect();
        let refs: Vec<&DVector<f64>> = rs.iter().collect();
        let together = chord.steps(&refs);
        let norms: Vec<f64> = (0..p).map(|k| j.column(k).norm()).collect();
        let js = DMatrix::from_fn(n, p, |i, k| j[(i, k)] / norms[k]);
        let svd = js.clone().svd(true, true);
        let s1 = span.singular_values[0];
        let kappa = s1 / span.singular_values.last().unwrap();
        for (r, d) in rs.iter().zip(&together) {
            let x = svd.solve(&(-r), 1e-10).unwrap();
            let res = (&js * &x + r).norm();
            let bound =
                10.0 * p as f64 * f64::EPSILON * (kappa * x.norm() + kappa * kappa * res / s1);
            for k in 0..p {
                let err = (d[k] * norms[k] - x[k]).abs();
                assert!(err <= bound, "coordinate {k}: {err:e} > {bound:e}");
            }
        }
    }

    #[test]
    fn most_promising_takes_the_smallest_predictions_per_start() {
        let n = PROFILE_REFINED + 4;
        let points: Vec<(usize, usize)> = (0..n).flat_map(|g| [(g, 0), (g, 1)]).collect();
        let first: Vec<Option<(f64, f64)>> = points
            .iter()
            .map(|&(g, k)| match (g, k) {
                (0, 0) => None,
                (_, 0) => Some((0.0, (n - g) as f64)),
                (_, 1) => Some((0.0, if g < 3 { 1.0 } else { g as f64 })),
                _ => unreachable!(),
            })
            .collect();
        let chosen = most_promising(&first, &points, 2);
        let of_start = |k: usize| -> Vec<usize> {
            chosen
                .iter()
                .filter(|&&i| points[i].1 == k)
                .map(|&i| points[i].0)
                .collect()
        };
        // Start 0: the largest g have the smallest predictions; g = 0 was not evaluated.
        let want0: Vec<usize> = (n - PROFILE_REFINED..n).rev().collect();
        assert_eq!(of_start(0), want0);
        // Start 1: g = 0, 1, 2 tie at 1.0 (taken in order), then 3, 4, …
        let want1: Vec<usize> = (0..PROFILE_REFINED).collect();
        assert_eq!(of_start(1), want1);
    }
}
