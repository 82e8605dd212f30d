//! The model check: noise floor → baseline fit → localisation → screening (score test)
//! → refit and acceptance (likelihood ratio with Bonferroni, ΔBIC, plausible and
//! significant parameters, distinctness) → forward–backward selection → report.
//! Follows docs/physics.md (M1–M8), with the deviations listed in
//! the report's `method` field.

use crate::candidates::{candidates, local_effect, Candidate, Screening};
use crate::error::CheckError;
use crate::lm::{self, Bounds, Fit};
use crate::locate::{bands, residual_map};
use crate::noise::{self, RecordingNoise};
use crate::params::{inertia_quantities, theta_to_inertia, Baseline, ParamKind, INERTIA_NAMES};
use crate::predict::{predict, Layout};
use crate::report::*;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use rbprops_core::stats::chi2_isf;
use rbprops_core::{c64, DataPrecision, FrfSet, Geometry};
use rbprops_sim::effects::Effect;
use rbprops_sim::CampaignSpec;

/// Options of [`check`]. `Default` gives the documented defaults.
#[derive(Debug, Clone)]
pub struct CheckOptions {
    /// Noise model from side information (repeats, coherence); `None`: from the data.
    pub noise: Option<RecordingNoise>,
    /// Family-wise false-positive rate per selection step (Bonferroni over candidates).
    pub alpha: f64,
    /// At most this many effects are accepted.
    pub max_effects: usize,
    /// Significant candidates refitted with full NLS per step.
    pub refit_top: usize,
    /// ΔBIC an effect must exceed (and the margin under which rivals are ambiguous).
    pub min_delta_bic: f64,
    /// Largest canonical correlation under which two candidates count as distinct.
    pub max_correlation: f64,
    pub max_iterations: usize,
    /// Weighed mass (side information): fixes m, which makes a global gain observable.
    pub weighed_mass_kg: Option<f64>,
    /// Known masses at sensor points (point id, kg): added to the model as a known
    /// correction, so the reported inertia is the body's without the sensors.
    pub sensor_masses_kg: Vec<(String, f64)>,
    /// Restrict screening to these candidate ids (`None`: the whole catalogue).
    pub only: Option<Vec<String>>,
    /// Quantile of χ²_d the Wald statistic of an effect's parameters must exceed.
    pub wald_level: f64,
    /// Require the held-out check (cross-validation, [`crate::cv`]) for acceptance.
    pub cross_validation: bool,
    /// Receives one line per stage (noise, baseline, each selection step): a check
    /// takes seconds to minutes, and a person at a terminal wants to see it move.
    pub progress: Progress,
}

/// A sink for progress lines ([`CheckOptions::progress`]); silent by default.
#[derive(Clone, Default)]
pub struct Progress(Option<std::sync::Arc<dyn Fn(&str) + Send + Sync>>);

impl Progress {
    pub fn new(f: impl Fn(&str) + Send + Sync + 'static) -> Self {
        Progress(Some(std::sync::Arc::new(f)))
    }
    fn say(&self, line: impl FnOnce() -> String) {
        if let Some(f) = &self.0 {
            f(&line());
        }
    }
}

impl std::fmt::Debug for Progress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.0.is_some() {
            "Progress(on)"
        } else {
            "Progress(off)"
        })
    }
}

impl Default for CheckOptions {
    fn default() -> Self {
        CheckOptions {
            noise: None,
            alpha: 0.01,
            max_effects: 4,
            refit_top: 3,
            min_delta_bic: 10.0,
            max_correlation: 0.9,
            max_iterations: 60,
            weighed_mass_kg: None,
            sensor_masses_kg: Vec::new(),
            only: None,
            wald_level: 0.999,
            cross_validation: true,
            progress: Progress::default(),
        }
    }
}

/// Everything a front end needs: the report, the improved spec and the FRFs for plots.
#[derive(Debug)]
pub struct CheckOutcome {
    pub report: ModelCheckReport,
    /// The nominal spec with fitted parameters and the accepted effects switched on.
    pub improved_spec: CampaignSpec,
    pub layout: Layout,
    /// `[exc][ch][line]` in the recording's layout.
    pub measured: Vec<c64>,
    pub nominal: Vec<c64>,
    pub baseline: Vec<c64>,
    pub improved: Vec<c64>,
    /// σ per value (0: excluded).
    pub sigma: Vec<f64>,
    /// The final model's parameters, a start for the noise rerun of [`check`].
    prior: Prior,
}

/// A pass's final model: the nominal model's parameters θ and each accepted effect's φ.
/// The noise rerun of [`check`] refits every effect the first pass accepted from here
/// as well: under the re-estimated noise the baseline may drift to stand in for the
/// effect (a hanging body's mass ×4.5 for a record truncation), and from that basin the
/// effect's screening statistic and its refit from the current model see nothing.
#[derive(Debug, Clone, Default)]
struct Prior {
    base: Vec<f64>,
    effects: Vec<(String, Vec<f64>)>,
}

impl Prior {
    fn phi(&self, id: &str) -> Option<&[f64]> {
        self.effects
            .iter()
            .find(|(e, _)| e == id)
            .map(|(_, phi)| phi.as_slice())
    }

    /// θ for `active` (the last entry the effect being refitted, with its start `alpha`
    /// unless the prior has it) from the prior's θ and φ where it has them and from
    /// `current` (the current fit's θ for `active` minus its last entry) elsewhere.
    fn start(&self, p: &Problem, active: &[Act], current: &[f64], alpha: &[f64]) -> Vec<f64> {
        let nb = p.n_base();
        let mut t = self.base.clone();
        let mut k = nb;
        for (i, a) in active.iter().enumerate() {
            let d = a.dim();
            let fallback = if i + 1 == active.len() {
                alpha
            } else {
                &current[k..k + d]
            };
            match self.phi(&p.cands[a.c].id) {
                Some(phi) => t.extend(a.kept.iter().map(|&j| phi[j])),
                None => t.extend_from_slice(fallback),
            }
            k += d;
        }
        t
    }
}

/// An effect in the model. Its free parameters are the `kept` coordinates of φ; the
/// others stay at their neutral values. A coordinate is dropped for each exact gauge
/// of the effect (a direction with no signature once the current model's parameters
/// are free: a common gain the mass absorbs, a rotation of a force about itself), so a
/// gauge can neither drift nor take over the inertia parameters, while the kept
/// parameters keep their own units and bounds.
#[derive(Debug, Clone)]
struct Act {
    c: usize,
    kept: Vec<usize>,
    /// Unit directions in φ-space the data cannot see at first order (reported).
    gauge: Vec<Vec<f64>>,
}

impl Act {
    fn full(c: usize, n: usize) -> Act {
        Act {
            c,
            kept: (0..n).collect(),
            gauge: Vec::new(),
        }
    }
    fn dim(&self) -> usize {
        self.kept.len()
    }
    fn phi(&self, neutral: &[f64], alpha: &[f64]) -> Vec<f64> {
        let mut phi = neutral.to_vec();
        for (&j, a) in self.kept.iter().zip(alpha) {
            phi[j] = *a;
        }
        phi
    }
}

/// The fitting problem: data, weights, parametrisation and candidates.
struct Problem<'a> {
    baseline: Baseline,
    layout: &'a Layout,
    y: &'a [c64],
    sigma: &'a [f64],
    used: Vec<usize>,
    fixed_effects: Vec<Box<dyn Effect>>,
    cands: Vec<Candidate>,
    fixed_mass: Option<f64>,
}

impl<'a> Problem<'a> {
    fn n_base(&self) -> usize {
        self.baseline.len()
    }

    fn build(
        &self,
        theta: &[f64],
        active: &[Act],
    ) -> Result<(CampaignSpec, Vec<Box<dyn Effect>>), CheckError> {
        let spec = self.baseline.apply(&theta[..self.n_base()]);
        let mut effects: Vec<Box<dyn Effect>> = self
            .fixed_effects
            .iter()
            .map(|e| e.with_values(&e.values()).map_err(CheckError::Model))
            .collect::<Result<_, _>>()?;
        let mut k = self.n_base();
        for a in active {
            let cand = &self.cands[a.c];
            let n = a.dim();
            let phi = a.phi(&cand.neutral, &theta[k..k + n]);
            effects.push(cand.effect.with_values(&phi).map_err(CheckError::Model)?);
            k += n;
        }
        Ok((spec, effects))
    }

    fn model(&self, theta: &[f64], active: &[Act]) -> Result<Vec<c64>, CheckError> {
        let (spec, effects) = self.build(theta, active)?;
        predict(&spec, self.layout, &effects)
    }

    fn residual(&self, theta: &[f64], active: &[Act]) -> Result<Vec<f64>, CheckError> {
        let m = self.model(theta, active)?;
        let mut r = Vec::with_capacity(2 * self.used.len());
        for &i in &self.used {
            let d = (self.y[i] - m[i]) * (std::f64::consts::SQRT_2 / self.sigma[i]);
            r.push(d.re);
            r.push(d.im);
        }
        Ok(r)
    }

    fn bounds(&self, active: &[Act]) -> Bounds {
        let nb = self.n_base();
        let mut lower = vec![f64::NEG_INFINITY; nb];
        let mut upper = vec![f64::INFINITY; nb];
        let mut scales = self.baseline.scales.clone();
        if let Some(m) = self.fixed_mass {
            lower[0] = m.ln();
            upper[0] = m.ln();
        }
        for a in active {
            let cand = &self.cands[a.c];
            let infos = cand.effect.parameters();
            for &j in &a.kept {
                lower.push(infos[j].lower);
                upper.push(infos[j].upper);
                scales.push(cand.scales[j]);
            }
        }
        Bounds {
            lower,
            upper,
            scales,
        }
    }

    fn fit(
        &self,
        stage: &str,
        theta0: &[f64],
        active: &[Act],
        max_iter: usize,
    ) -> Result<Fit, CheckError> {
        let f = |t: &[f64]| self.residual(t, active);
        let b = self.bounds(active);
        let mut fit = lm::fit(stage, &f, theta0, &b, max_iter)?;
        self.zero_fixed(&mut fit.jacobian);
        Ok(fit)
    }

    fn zero_fixed(&self, j: &mut DMatrix<f64>) {
        if self.fixed_mass.is_some() {
            j.column_mut(0).fill(0.0);
        }
    }

    /// ‖y‖ in the residual's noise units (√2 |y_i| / σ_i over the lines used).
    fn data_norm(&self) -> f64 {
        self.used
            .iter()
            .map(|&i| 2.0 * (self.y[i].norm() / self.sigma[i]).powi(2))
            .sum::<f64>()
            .sqrt()
    }

    fn n_real(&self) -> f64 {
        2.0 * self.used.len() as f64
    }

    /// RMS over the values used of |Ŷ₁ − Ŷ₀|/σ_p: the change between two predictions in
    /// units of the precision floor `sigma_precision` (values with σ_p = 0, exact zeros
    /// of a model with no rounding to speak of, are left out).
    fn change_over_floor(&self, m1: &[c64], m0: &[c64], sigma_precision: &[f64]) -> f64 {
        let (mut s, mut n) = (0.0, 0usize);
        for &i in &self.used {
            if sigma_precision[i] > 0.0 {
                s += ((m1[i] - m0[i]).norm() / sigma_precision[i]).powi(2);
                n += 1;
            }
        }
        if n == 0 {
            return 0.0;
        }
        (s / n as f64).sqrt()
    }
}

/// How far above the precision floor an effect's fitted change to the FRFs must be, as
/// the RMS over all values of |ΔŶ|/σ_p (σ_p: the quantisation of the stored values and
/// the computation floor of double precision, [`noise::precision_sigma`]).
///
/// Why: the statistical tests treat every residual as noise, which rounding is not. Two
/// correct double-precision computations of the same physics differ by their rounding
/// and linearisation errors, a deterministic pattern that some effect's signature always
/// matches in part, and on exact data (σ near the floor) that part is "significant". A
/// least-squares fit cannot change the prediction by more than the residual it
/// explains, so an effect fitted to what lies within the floor changes the FRFs by at
/// most about 1 σ_p (RMS); one that changes them by ten times that is not rounding. On
/// any recording with measurement noise the test is void (an effect seen through 1 %
/// noise changes the FRFs by 10⁵ σ_p or more).
pub const PRACTICAL_MARGIN: f64 = 10.0;

/// Orthonormal basis of the column span of `j` (columns normalised first; directions
/// with relative singular value below `tol` dropped).
fn span_basis(j: &DMatrix<f64>, tol: f64) -> (DMatrix<f64>, Vec<f64>) {
    let mut js = j.clone();
    for k in 0..js.ncols() {
        let n = js.column(k).norm();
        if n > 0.0 {
            js.column_mut(k).scale_mut(1.0 / n);
        }
    }
    let svd = js.svd(true, false);
    let u = svd.u.expect("requested");
    let keep: Vec<usize> = (0..svd.singular_values.len())
        .filter(|&k| svd.singular_values[k] > tol)
        .collect();
    let basis = DMatrix::from_fn(u.nrows(), keep.len(), |r, c| u[(r, keep[c])]);
    (
        basis,
        keep.iter().map(|&k| svd.singular_values[k]).collect(),
    )
}

/// Removes the span of `q` (orthonormal columns) from the columns of `j`.
fn project_out(j: &DMatrix<f64>, q: &DMatrix<f64>) -> DMatrix<f64> {
    if q.ncols() == 0 {
        return j.clone();
    }
    j - q * lm::tr_mul(q, j)
}

/// Score-test quantities of one candidate at the current model.
struct Score {
    rank: usize,
    score: f64,
    basis: DMatrix<f64>,
    /// Free coordinates of φ (one dropped per exact gauge).
    kept: Vec<usize>,
    /// Gauss–Newton start of the kept coordinates.
    start: Vec<f64>,
    /// Unit φ-space directions without first-order signature.
    gauge: Vec<Vec<f64>>,
    /// Fraction of the candidate's signature each parameter group explains alone.
    absorbed_by: Vec<(String, f64)>,
    /// Number of parameter points the statistic is the best of (1 for the score test;
    /// the profile's size for grid-screened candidates): the threshold is Bonferroni
    /// corrected for it.
    n_tests: usize,
    /// Start of the current model's parameters for the refit (re-adjusted to the
    /// profile's best point), when not the current fit's.
    theta_start: Option<Vec<f64>>,
}

/// Profile screening of a candidate whose signature vanishes to every order at its
/// neutral point (see `Candidate::grid`): at each grid point φ_g the residual r_g of the
/// current model plus the effect at φ_g, with the current parameters re-adjusted
/// linearly (their Jacobian's span projected out), gives the approximate likelihood
/// ratio `‖P⊥ r‖² − ‖P⊥ r_g‖²`. The best point starts the refit; the statistic is the
/// best of `G` tests, so its threshold is Bonferroni corrected over the grid.
fn grid_candidate(
    p: &Problem,
    cur: &Fit,
    active: &[Act],
    c: usize,
    q0: &DMatrix<f64>,
    grid: &[Vec<f64>],
    delay_scan: bool,
) -> Result<Score, CheckError> {
    let (grid, n_tests) = profile_points(p, grid, delay_scan, &cur.residual);
    profile_candidate(p, cur, active, c, q0, &grid, n_tests)
}

/// An in-band resonance ([`crate::resonance`]): the profile over (ω_m, ζ_m) of the
/// linear residue fit to the current residual proposes the starting points, which are
/// then evaluated as a grid; Bonferroni over every profile point searched.
fn resonance_candidate(
    p: &Problem,
    cur: &Fit,
    active: &[Act],
    c: usize,
    q0: &DMatrix<f64>,
) -> Result<Score, CheckError> {
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
    profile_candidate(p, cur, active, c, q0, &starts, n_tests)
}

/// Profile screening over the parameter points `grid` (see [`grid_candidate`]), the
/// statistic the best of `n_tests` tests.
fn profile_candidate(
    p: &Problem,
    cur: &Fit,
    active: &[Act],
    c: usize,
    q0: &DMatrix<f64>,
    grid: &[Vec<f64>],
    n_tests: usize,
) -> Result<Score, CheckError> {
    let cand = &p.cands[c];
    let np = cand.neutral.len();
    let mut act = active.to_vec();
    act.push(Act::full(c, np));
    let r0 = nalgebra::DVector::from_column_slice(&cur.residual);
    let perp = |r: &nalgebra::DVector<f64>| {
        if q0.ncols() == 0 {
            r.clone()
        } else {
            r - q0 * q0.tr_mul(r)
        }
    };
    let base = perp(&r0).norm_squared();
    // Chord (fixed-Jacobian Gauss–Newton) re-adjustment of the current parameters at
    // each grid point: a few model evaluations, enough when the effect moves them far.
    let svd = cur.jacobian.clone().svd(true, true);
    let nb = cur.theta.len();
    let eval = |t: &[f64]| -> Option<nalgebra::DVector<f64>> {
        p.residual(t, &act).ok().map(nalgebra::DVector::from_vec)
    };
    let mut best: Option<(f64, usize, Vec<f64>, nalgebra::DVector<f64>)> = None;
    for (g, phi) in grid.iter().enumerate() {
        let mut t = cur.theta.clone();
        t.extend_from_slice(phi);
        let Some(mut rg) = eval(&t) else { continue };
        // Linearised gain at the current parameters (the score-like statistic).
        let lin = base - perp(&rg).norm_squared();
        let mut chi = rg.norm_squared();
        for _ in 0..4 {
            let Ok(d) = svd.solve(&(-&rg), 1e-10) else {
                break;
            };
            let mut t1 = t.clone();
            t1.iter_mut().zip(d.iter()).for_each(|(x, d)| *x += d);
            match eval(&t1) {
                Some(r1) if r1.norm_squared() < chi => {
                    chi = r1.norm_squared();
                    rg = r1;
                    t = t1;
                }
                _ => break,
            }
        }
        let gain = lin.max(r0.norm_squared() - chi);
        if best.as_ref().is_none_or(|b| gain > b.0) {
            best = Some((gain, g, t[..nb].to_vec(), rg));
        }
    }
    let Some((gain, g, theta_best, rg)) = best else {
        return Err(CheckError::Model(format!(
            "'{}': no point of its screening profile could be evaluated",
            cand.id
        )));
    };
    // Signature direction at the best point (for the distinctness check).
    let sig = perp(&(&r0 - &rg));
    let n = sig.norm();
    let basis = if n > 0.0 {
        DMatrix::from_column_slice(sig.len(), 1, (sig / n).as_slice())
    } else {
        DMatrix::zeros(r0.len(), 0)
    };
    let theta_start = Some(theta_best);
    Ok(Score {
        rank: if n > 0.0 { np } else { 0 },
        score: gain.max(0.0),
        basis,
        kept: (0..np).collect(),
        start: grid[g].clone(),
        gauge: Vec::new(),
        absorbed_by: Vec::new(),
        n_tests,
        theta_start,
    })
}

/// The profile points of a grid-screened candidate and the number of tests its best
/// point is selected from: the grid, plus for a record length (`delay_scan`) the lags
/// of the current residual's lag scan ([`crate::candidates::delay_peaks`]) over
/// 1/(8Δf)·0.9 < T < 0.95/Δf, counted as the number of independent lags scanned.
fn profile_points(
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

/// The leave-one-excitation-out check vetoes only candidates whose fit reaches
/// χ²/ν below this (see its use in [`check`]).
const LOEO_MAX_CHI2_NU: f64 = 2.0;

/// Relative singular value below which a candidate direction counts as absorbed (no
/// power to detect it at first order).
const ABSORBED: f64 = 1e-4;
/// Residual change per typical step of a candidate parameter, relative to the norm of
/// the data (both in noise units), below which the step has no signature at all: the
/// model's rounding (~1e-15 relative) over a finite-difference step of 1e-7 is about
/// 1e-8, and a signature this small would need 10⁴ typical steps to change χ² by 10.
const NO_SIGNATURE: f64 = 1e-6;
/// Below this it is an exact gauge (a symmetry such as a common gain ↔ mass): such
/// directions are removed from the refit. Directions between the two are absorbed only
/// at first order and stay free in the refit, where the non-linear model can use them.
const GAUGE: f64 = 1e-7;

/// The coordinates held at neutral to fix the exact gauges `null` (rows of `vt`), one
/// per gauge, by pivoted elimination. Among the coordinates that can serve as pivot
/// (|v_j| ≥ ½ max), the one whose neutral value puts the gauge shift at the median of
/// the shifts −δ_j/v_j is chosen: for a gauge such as a common gain, that keeps half
/// of the fitted gains above and half below neutral, so one faulty channel or force
/// gauge among many is reported as that one (1.05), not as all the others reading low
/// (0.988 each) with the mass moved by the difference. `delta` is the minimum-norm
/// Gauss–Newton step in the same normalised coordinates.
fn gauge_pivots(null: &[usize], vt: &DMatrix<f64>, delta: &[f64]) -> Vec<usize> {
    let np = delta.len();
    let mut vecs: Vec<Vec<f64>> = null
        .iter()
        .map(|&k| (0..np).map(|j| vt[(k, j)]).collect())
        .collect();
    let mut dropped: Vec<usize> = Vec::new();
    for i in 0..vecs.len() {
        let v = vecs[i].clone();
        let Some((_, j)) = median_pivot(&v, delta, |j| !dropped.contains(&j)) else {
            continue;
        };
        dropped.push(j);
        for w in vecs.iter_mut().skip(i + 1) {
            let f = w[j] / v[j];
            w.iter_mut().zip(&v).for_each(|(x, y)| *x -= f * y);
        }
    }
    dropped
}

/// The median rule of a gauge `v` at the offsets from neutral `x`: among the eligible
/// coordinates that carry the gauge (|v_j| ≥ ½ of the largest), the shift along v
/// that brings coordinate j to neutral is −x_j/v_j; returns the median shift and its
/// coordinate (`None` when no eligible coordinate carries v).
fn median_pivot(v: &[f64], x: &[f64], eligible: impl Fn(usize) -> bool) -> Option<(f64, usize)> {
    let vmax = (0..v.len())
        .filter(|&j| eligible(j))
        .map(|j| v[j].abs())
        .fold(0.0, f64::max);
    if vmax < 1e-12 {
        return None;
    }
    let mut shifts: Vec<(f64, usize)> = (0..v.len())
        .filter(|&j| eligible(j) && v[j].abs() >= 0.5 * vmax)
        .map(|j| (-x[j] / v[j], j))
        .collect();
    shifts.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    Some(shifts[(shifts.len() - 1) / 2])
}

fn score_candidate(
    p: &Problem,
    cur: &Fit,
    active: &[Act],
    c: usize,
    q0: &DMatrix<f64>,
) -> Result<Score, CheckError> {
    let cand = &p.cands[c];
    let mut act = active.to_vec();
    act.push(Act::full(c, cand.neutral.len()));
    let theta = &cur.theta;
    let f = |phi: &[f64]| {
        let mut t = theta.clone();
        t.extend_from_slice(phi);
        p.residual(&t, &act)
    };
    let jc = lm::jacobian(&f, &cand.neutral, &cand.scales, &cur.residual)?;
    // A column whose typical step moves the residual by less than NO_SIGNATURE of the
    // data's norm is rounding, not a signature: normalised, it would count as a
    // direction (the tilt of cords without gravity stiffness, 2e-4 noise units per
    // step where the data are 2e4, gave a rank of 3 for 2 and a wrong start).
    let floor = NO_SIGNATURE * p.data_norm();
    let norms: Vec<f64> = (0..jc.ncols())
        .map(|k| {
            let n = jc.column(k).norm();
            if n * cand.scales[k] < floor {
                0.0
            } else {
                n
            }
        })
        .collect();
    let mut jcs = jc.clone();
    for k in 0..jcs.ncols() {
        if norms[k] > 0.0 {
            jcs.column_mut(k).scale_mut(1.0 / norms[k]);
        } else {
            jcs.column_mut(k).fill(0.0);
        }
    }
    let jt = project_out(&jcs, q0);
    let svd = jt.clone().svd(true, true);
    let u = svd.u.expect("requested");
    let vt = svd.v_t.expect("requested");
    let keep: Vec<usize> = (0..svd.singular_values.len())
        .filter(|&k| svd.singular_values[k] > ABSORBED)
        .collect();
    let basis = DMatrix::from_fn(u.nrows(), keep.len(), |r, k| u[(r, keep[k])]);
    let r = nalgebra::DVector::from_column_slice(&cur.residual);
    let proj = basis.tr_mul(&r);
    let score = proj.norm_squared();
    // Gauss–Newton step on the candidate's parameters alone (projected problem):
    // r + J̃ δ ≈ 0 → δ = −V Σ⁻¹ Uᵀ r in normalised coordinates.
    let np = cand.neutral.len();
    let sv = |k: usize| svd.singular_values.get(k).copied().unwrap_or(0.0);
    // Null directions (exact gauges) in normalised coordinates; V is complete (np×np)
    // only when rows ≥ columns, which holds (one row per residual entry).
    let null: Vec<usize> = (0..np).filter(|&k| sv(k) <= GAUGE).collect();
    // Gauss–Newton step in normalised coordinates over the detectable directions,
    // δ = −Σ_k v_k (u_kᵀ r)/s_k (minimum norm: no gauge component).
    let mut delta = vec![0.0; np];
    for (kk, &k) in keep.iter().enumerate() {
        let coef = -proj[kk] / svd.singular_values[k];
        for (j, d) in delta.iter_mut().enumerate() {
            *d += coef * vt[(k, j)];
        }
    }
    let dropped = gauge_pivots(&null, &vt, &delta);
    let kept: Vec<usize> = (0..np).filter(|j| !dropped.contains(j)).collect();
    // Shift δ along the gauges so the dropped coordinates stay neutral (the gauges
    // leave the residual unchanged).
    if !dropped.is_empty() {
        let g = dropped.len();
        let a = DMatrix::from_fn(g, null.len(), |r, c| vt[(null[c], dropped[r])]);
        let b = nalgebra::DVector::from_iterator(g, dropped.iter().map(|&j| -delta[j]));
        if let Some(beta) = a.svd(true, true).solve(&b, 1e-12).ok() {
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
    // Shrink the start towards neutral until it respects the effect's bounds.
    let infos = cand.effect.parameters();
    let probe = Act {
        c,
        kept: kept.clone(),
        gauge: Vec::new(),
    };
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
    let gauge: Vec<Vec<f64>> = (0..np)
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
        .collect();
    // Which parameter groups absorb the signature (for the not-observable report).
    let mut absorbed_by = Vec::new();
    if keep.is_empty() {
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
                    ParamKind::ModalDampingLog(_)
                        | ParamKind::RayleighAlpha
                        | ParamKind::RayleighBeta
                )
            }),
        ];
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
            absorbed_by.push((name.to_string(), 1.0 - rest.norm_squared() / tot));
        }
    }
    Ok(Score {
        rank: keep.len(),
        score,
        basis,
        kept,
        start,
        gauge,
        absorbed_by,
        n_tests: 1,
        theta_start: None,
    })
}

/// Smallest residual signature, in noise units, of a dropped coordinate moved over
/// half its plausible range once the fitted parameters compensate, for
/// [`reopen_dropped`] to free it: a move that changes χ² by less than 9 cannot be
/// told from noise.
const REOPEN_SIGNATURE: f64 = 3.0;

/// The refit of candidate `c` with the coordinates [`score_candidate`] dropped as
/// exact gauges at the neutral point freed where they have become identifiable at the
/// fitted point. A coordinate bilinear with a kept one has no signature at neutral and
/// one once its partner moves: the tilt of the cords has none without their gravity
/// stiffness, the frequency of a residual mode none without its residues. Such a
/// coordinate is freed and the refit repeated from the fitted point (kept if better);
/// the exact gauges (a common gain the mass absorbs) stay dropped.
fn reopen_dropped(
    p: &Problem,
    fit: Fit,
    active: &[Act],
    c: usize,
    kept: &[usize],
    stage: &str,
    max_iter: usize,
) -> (Fit, Vec<usize>) {
    let free = identifiable_at(p, &fit, active, c, kept);
    if free.is_empty() {
        return (fit, kept.to_vec());
    }
    let mut kept2: Vec<usize> = kept.iter().chain(&free).copied().collect();
    kept2.sort_unstable();
    let (k0, phi) = last_effect_phi(p, &fit.theta, c, kept);
    let mut theta = fit.theta[..k0].to_vec();
    theta.extend(kept2.iter().map(|&j| phi[j]));
    let mut act = active.to_vec();
    act.push(Act {
        c,
        kept: kept2.clone(),
        gauge: Vec::new(),
    });
    match p.fit(stage, &theta, &act, max_iter) {
        Ok(f2) if f2.chi2 < fit.chi2 => (f2, kept2),
        _ => (fit, kept.to_vec()),
    }
}

/// Candidate `c`'s full φ from θ whose last entries are its `kept` coordinates (the
/// others at neutral), and the index in θ where those entries start.
fn last_effect_phi(p: &Problem, theta: &[f64], c: usize, kept: &[usize]) -> (usize, Vec<f64>) {
    let k0 = theta.len() - kept.len();
    let act = Act {
        c,
        kept: kept.to_vec(),
        gauge: Vec::new(),
    };
    (k0, act.phi(&p.cands[c].neutral, &theta[k0..]))
}

/// The coordinates of candidate `c` outside `kept` whose signature at the fit `fit`
/// (its last parameters are `c`'s kept ones), with the fitted parameters compensating,
/// reaches [`REOPEN_SIGNATURE`] over half their plausible range and is not a
/// combination of the fitted parameters' (relative size above [`ABSORBED`]). Taken
/// greedily, strongest first, each against the ones already taken.
fn identifiable_at(p: &Problem, fit: &Fit, active: &[Act], c: usize, kept: &[usize]) -> Vec<usize> {
    let cand = &p.cands[c];
    let np = cand.neutral.len();
    let dropped: Vec<usize> = (0..np).filter(|j| !kept.contains(j)).collect();
    if dropped.is_empty() {
        return Vec::new();
    }
    let (k0, phi) = last_effect_phi(p, &fit.theta, c, kept);
    let mut act = active.to_vec();
    act.push(Act::full(c, np));
    let g = |x: &[f64]| {
        let mut ph = phi.clone();
        dropped.iter().zip(x).for_each(|(&j, v)| ph[j] = *v);
        let mut t = fit.theta[..k0].to_vec();
        t.extend_from_slice(&ph);
        p.residual(&t, &act)
    };
    let x0: Vec<f64> = dropped.iter().map(|&j| phi[j]).collect();
    let steps: Vec<f64> = dropped.iter().map(|&j| cand.scales[j]).collect();
    let Ok(jd) = lm::jacobian(&g, &x0, &steps, &fit.residual) else {
        return Vec::new();
    };
    let infos = cand.effect.parameters();
    let half_range: Vec<f64> = dropped
        .iter()
        .map(|&j| 0.5 * (infos[j].plausible.1 - infos[j].plausible.0).abs())
        .collect();
    let (q, _) = span_basis(&fit.jacobian, 1e-10);
    let jp = project_out(&jd, &q);
    let strength = |k: usize| jp.column(k).norm() * half_range[k];
    let mut order: Vec<usize> = (0..dropped.len()).collect();
    order.sort_by(|a, b| strength(*b).total_cmp(&strength(*a)).then(a.cmp(b)));
    let mut basis: Vec<DVector<f64>> = Vec::new();
    let mut out = Vec::new();
    for k in order {
        let mut v = jp.column(k).into_owned();
        for b in &basis {
            let d = b.dot(&v);
            v -= b * d;
        }
        let n = v.norm();
        if n * half_range[k] >= REOPEN_SIGNATURE && n > ABSORBED * jd.column(k).norm() {
            out.push(dropped[k]);
            basis.push(v / n);
        }
    }
    out
}

/// Point masses rigidly attached to the body (`sensor_mass`) change only its mass, centre
/// of mass and inertia tensor, so with those free they are an exact gauge: not
/// observable, whatever the numerical rank at the current point says. (That rank can be
/// > 0 where the pseudo-inertia parametrisation is at the edge of physical consistency
/// and loses a direction; the masses then trade against the body's own and the fit
/// drifts along the gauge, as on the hanging probe of scripts/model_check_probe.py.)
/// With a weighed mass the total mass is pinned and the numerical screen applies.
fn rigid_mass_gauge(n_residuals: usize) -> Score {
    Score {
        rank: 0,
        score: 0.0,
        basis: DMatrix::zeros(n_residuals, 0),
        kept: Vec::new(),
        start: Vec::new(),
        gauge: Vec::new(),
        absorbed_by: vec![("inertia (10 free parameters)".to_string(), 1.0)],
        n_tests: 1,
        theta_start: None,
    }
}

/// Standard error scale factor and covariance of a fit.
fn fit_covariance(fit: &Fit, nu: f64) -> DMatrix<f64> {
    let s = (fit.chi2 / nu).max(1.0);
    lm::covariance(&fit.jacobian) * s
}

fn inertia_report(label: &str, theta: &[f64], cov: &DMatrix<f64>) -> InertiaEstimateReport {
    let body = theta_to_inertia(&theta[..10]);
    let q0 = inertia_quantities(&body);
    // Delta method: g = ∂q/∂θ by central differences.
    let mut g = DMatrix::zeros(10, 10);
    for j in 0..10 {
        let h = 1e-6 * theta[j].abs().max(1e-3);
        let mut tp = theta[..10].to_vec();
        tp[j] += h;
        let mut tm = theta[..10].to_vec();
        tm[j] -= h;
        let (qp, qm) = (
            inertia_quantities(&theta_to_inertia(&tp)),
            inertia_quantities(&theta_to_inertia(&tm)),
        );
        for i in 0..10 {
            g[(i, j)] = (qp[i] - qm[i]) / (2.0 * h);
        }
    }
    let c = cov.view((0, 0), (10, 10)).into_owned();
    let cq = &g * c * g.transpose();
    let j = body.inertia_cm;
    InertiaEstimateReport {
        label: label.into(),
        mass_kg: q0[0],
        com_m: [q0[1], q0[2], q0[3]],
        moments_kg_m2: [q0[4], q0[5], q0[6]],
        products_kg_m2: [q0[7], q0[8], q0[9]],
        inertia_cm_kg_m2: std::array::from_fn(|r| std::array::from_fn(|c| j[(r, c)])),
        standard_errors: std::array::from_fn(|i| cq[(i, i)].max(0.0).sqrt()),
    }
}

fn quantities(r: &InertiaEstimateReport) -> [f64; 10] {
    [
        r.mass_kg,
        r.com_m[0],
        r.com_m[1],
        r.com_m[2],
        r.moments_kg_m2[0],
        r.moments_kg_m2[1],
        r.moments_kg_m2[2],
        r.products_kg_m2[0],
        r.products_kg_m2[1],
        r.products_kg_m2[2],
    ]
}

/// Relative changes; CoM and products relative to a size scale (√(J̄/m) and J̄) so a
/// quantity near zero does not produce a meaningless ratio.
fn inertia_change(
    before: &InertiaEstimateReport,
    after: &InertiaEstimateReport,
) -> Vec<RelativeChange> {
    let (b, a) = (quantities(before), quantities(after));
    let jbar = (b[4] + b[5] + b[6]) / 3.0;
    let len = (jbar / b[0]).sqrt();
    (0..10)
        .map(|i| {
            let denom = match i {
                1..=3 => len,
                7..=9 => jbar,
                _ => b[i].abs(),
            };
            RelativeChange {
                quantity: INERTIA_NAMES[i].to_string(),
                relative: (a[i] - b[i]) / denom.max(f64::MIN_POSITIVE),
            }
        })
        .collect()
}

fn model_modes_band(
    spec: &CampaignSpec,
    layout: &Layout,
    effects: &[Box<dyn Effect>],
) -> (f64, f64) {
    match rbprops_sim::build_models(spec, &layout.spec_geometry, effects) {
        Ok(ms) => {
            // Free directions (0 Hz) are no suspension modes: they bound no band.
            let fs: Vec<f64> = ms
                .iter()
                .flat_map(|m| m.modes.iter().filter(|r| !r.is_free()))
                .map(|r| r.frequency_hz)
                .collect();
            if fs.is_empty() {
                return (
                    layout.frequency_hz[0],
                    layout.frequency_hz[layout.n_lines() - 1],
                );
            }
            (
                fs.iter().cloned().fold(f64::INFINITY, f64::min),
                fs.iter().cloned().fold(0.0, f64::max),
            )
        }
        Err(_) => (
            layout.frequency_hz[0],
            layout.frequency_hz[layout.n_lines() - 1],
        ),
    }
}

/// Runs the model check of a recording (`geometry`, `frf`) against a nominal spec.
/// With the noise estimated from the data, the noise is re-estimated from the final
/// model's residual and, if that moves the final χ²/ν out of its noise band, the check
/// is run once more with it (see [`noise::estimate_from_residual`]).
pub fn check(
    spec: &CampaignSpec,
    geometry: &Geometry,
    frf: &FrfSet,
    options: &CheckOptions,
) -> Result<CheckOutcome, CheckError> {
    options.progress.say(|| "estimating the noise floor".into());
    let first = check_with(spec, geometry, frf, options, None, None)?;
    if options.noise.is_some() {
        return Ok(first);
    }
    // Second pass: the noise re-estimated from the residual of the first pass's final
    // model ([`noise::estimate_from_residual`]), which no longer reads the structure the
    // accepted effects explain (a leakage ripple) as noise, nor, with nothing accepted,
    // the curvature the local polynomial cannot follow on data without noise (a
    // recording in single precision is then weighed by its quantisation alone).
    let (nex, nch, nl) = (frf.n_excitations, frf.n_channels, frf.n_lines());
    let nf = noise::estimate_from_residual(&first.measured, &first.improved, nex, nch, nl)?;
    // The rerun is needed when the final χ²/ν, re-expressed in the re-estimated noise
    // (χ²/ν · ρ), moves by more than the half-width of that noise's band on its side
    // (see `noise_band`): only then can it change the verdict.
    let rho = chi2_ratio(&first, &nf.sigma);
    let [lo, hi] = rbprops_core::stats::chi2_nu_band(
        first.report.nu_after,
        nf.model.variance_scale_se,
        rbprops_core::stats::BAND_TAIL,
    );
    let note = format!(
        "noise re-estimated from the residual of the final model: its χ² changes by the factor ρ = {rho:.3} (band half-widths −{:.3}/+{:.3})",
        1.0 - lo,
        hi - 1.0
    );
    if rho >= lo && rho <= hi {
        let mut first = first;
        first
            .report
            .method
            .push(format!("{note}: within it, the data-only estimate is kept"));
        return Ok(first);
    }
    options.progress.say(|| {
        format!("noise re-estimated from the final residual (χ² factor {rho:.3}): rerunning")
    });
    let mut second = check_with(
        spec,
        geometry,
        frf,
        options,
        Some((nf.model, nf.sigma)),
        Some(&first.prior),
    )?;
    second.report.method.push(format!(
        "{note}: beyond it, so the check was rerun with it (first pass: {})",
        first.report.verdict
    ));
    Ok(second)
}

/// ρ = χ²(σ')/χ²(σ) of the final model's residual of `o` under the noise `sigma2`
/// instead of the σ it was fitted with (values where both are positive).
fn chi2_ratio(o: &CheckOutcome, sigma2: &[f64]) -> f64 {
    let (mut a, mut b) = (0.0, 0.0);
    for i in 0..o.measured.len() {
        let (s1, s2) = (o.sigma[i], sigma2[i]);
        if s1 > 0.0 && s2 > 0.0 {
            let e = (o.measured[i] - o.improved[i]).norm_sqr();
            a += e / (s2 * s2);
            b += e / (s1 * s1);
        }
    }
    a / b
}

/// One pass of the check; `noise` overrides `options.noise` with a noise model and its
/// σ per value, and `prior` is the first pass's final model (the second pass of
/// [`check`]): the effects it accepted are refitted from it, whatever their screening.
fn check_with(
    spec: &CampaignSpec,
    geometry: &Geometry,
    frf: &FrfSet,
    options: &CheckOptions,
    noise_override: Option<(RecordingNoise, Vec<f64>)>,
    prior: Option<&Prior>,
) -> Result<CheckOutcome, CheckError> {
    frf.validate()
        .map_err(|e| CheckError::Data(e.to_string()))?;
    let layout = Layout::new(spec, geometry, frf)?;
    let (nex, nch, nl) = (frf.n_excitations, frf.n_channels, frf.n_lines());
    let y = &frf.values;
    let mut warnings = Vec::new();
    let mut method = vec![
        "noise: per-channel σ² = a²|H|² + b², from a local quartic over 11 lines (data only) unless given; |H| at least half its local median over 11 lines (no runaway weight at a zero of the FRF); the 0 Hz line left out; re-estimated from the final model's residual (the check is rerun with it if that moves χ²/ν out of the noise band); line-to-line correlation κ = 1 assumed".to_string(),
        "baseline: Levenberg–Marquardt on inertia (pseudo-inertia Cholesky, always physical), per-set-up axis stiffness scales, damping of the spec's model".to_string(),
        "screening: score test on the candidate Jacobian with the current model's Jacobian projected out; threshold χ²_{d,1−α/N}".to_string(),
        "acceptance: likelihood ratio > χ²_{d,1−α/N} (Bonferroni), ΔBIC > 10, Wald χ² > χ²_{d,0.999}, parameters not pinned at a bound, held-out χ² (10 interleaved frequency-block folds, one-step refit without each fold) lower by > 2 SE and in ≥ 80 % of folds, with ≥ 3 excitations and the candidate's fit at χ²/ν < 2 no held-out excitation (leave one out) worse by > 2 SE, distinct from rivals (canonical correlation ≤ 0.9 or ΔBIC margin > 10), and practically significant: its fitted change to the FRFs at least 10 times the precision floor (RMS over the values); backward elimination after each acceptance".to_string(),
        "not implemented: bootstrap calibration of the screening threshold".to_string(),
    ];
    // Stage 0: noise floor, with the precision floor of the data's storage format.
    let (noise_model, sigma) = match (noise_override, &options.noise) {
        (Some(given), _) => given,
        (None, Some(m)) => {
            if m.relative.len() != nch || m.floor.len() != nch {
                return Err(CheckError::Noise(format!(
                    "given noise model has {} / {} channel entries, the recording {nch}",
                    m.relative.len(),
                    m.floor.len()
                )));
            }
            let mut m = m.clone();
            m.precision = DataPrecision::detect(y);
            let s = noise::sigma_of(&m, y, y, nex, nch, nl);
            (m, s)
        }
        (None, None) => {
            let nf = noise::estimate(y, nex, nch, nl)?;
            (nf.model, nf.sigma)
        }
    };
    method.push(format!(
        "precision floor: values stored in {} (detected from the values), each σ² includes its quantisation variance (step²/12 per part) and the computation floor of double precision ({:.0e}·|H|)²; an exact recording (no fitted noise) whose χ²/ν is below the band is within that floor, and counts as at the floor",
        noise_model.precision.describe(),
        noise::COMPUTATION_FLOOR
    ));
    // The yardstick of practical significance: σ with no noise but the precision floor.
    let sigma_precision = noise::precision_sigma(&noise_model.precision, y, y, nl);
    // The 0 Hz line is left out: an AC-coupled channel reads 0 there whatever its time
    // constant and a DC-coupled one its static value, so a high-pass candidate's model
    // jumps at 1/τ = 0 on that line (no derivative, no path for the fit) while the line
    // next to it carries the same static information.
    let mut sigma = sigma;
    let dc: Vec<usize> = (0..nl).filter(|&l| frf.frequency_hz[l] == 0.0).collect();
    let mut n_dc = 0;
    for &l in &dc {
        for fi in 0..nex * nch {
            if sigma[fi * nl + l] > 0.0 {
                sigma[fi * nl + l] = 0.0;
                n_dc += 1;
            }
        }
    }
    if n_dc > 0 {
        warnings.push(format!(
            "the 0 Hz line is left out ({n_dc} values): a high-pass (AC coupling) makes it 0 whatever its time constant, so it cannot be fitted continuously; the next line carries the same static information"
        ));
    }
    let used: Vec<usize> = (0..y.len()).filter(|&i| sigma[i] > 0.0).collect();
    let n_excluded = y.len() - used.len() - n_dc;
    if n_excluded > 0 {
        warnings.push(format!("{n_excluded} values carry no noise information (σ = 0, e.g. accelerance at 0 Hz) and are left out"));
    }
    // Side information: known sensor masses become a fixed effect.
    let mut fixed_effects: Vec<Box<dyn Effect>> = spec
        .effects
        .iter()
        .map(|e| rbprops_sim::effects::parse_effect_in(e, spec).map_err(CheckError::Model))
        .collect::<Result<_, _>>()?;
    if !options.sensor_masses_kg.is_empty() {
        let (pids, _) = point_ids(&layout.spec_geometry);
        let mut vals = vec![0.0; pids.len()];
        for (pid, m) in &options.sensor_masses_kg {
            let k = pids.iter().position(|p| p == pid).ok_or_else(|| {
                CheckError::Mismatch(format!(
                    "sensor mass given for unknown point '{pid}' (points: {})",
                    pids.join(", ")
                ))
            })?;
            vals[k] = *m;
        }
        fixed_effects.push(local_effect("sensor_mass", spec, &vals).map_err(CheckError::Model)?);
    }
    warnings.extend(crate::candidates::free_direction_note(
        spec,
        &layout.spec_geometry,
    ));
    let (mut cands, notes) = candidates(spec, &layout.spec_geometry);
    method.extend(notes);
    warnings.extend(crate::candidates::vertical_axis_doubt(spec));
    if let Some(only) = &options.only {
        cands.retain(|c| only.contains(&c.id));
    }
    if !options.sensor_masses_kg.is_empty() {
        cands.retain(|c| c.id != "sensor_mass");
    }
    let p = Problem {
        baseline: Baseline::new(spec),
        layout: &layout,
        y,
        sigma: &sigma,
        used,
        fixed_effects,
        cands,
        fixed_mass: options.weighed_mass_kg,
    };
    let n_real = p.n_real();
    let theta_nom = p.baseline.initial();
    // χ² of the nominal spec as given.
    let r_nom = p.residual(&theta_nom, &[])?;
    let chi2_nominal = lm::chi2(&r_nom);
    let nominal_pred = p.model(&theta_nom, &[])?;
    // Stage 1: baseline fit. Start from the nominal, with the weighed mass if given.
    let mut theta0 = theta_nom.clone();
    if let Some(m) = options.weighed_mass_kg {
        theta0[0] = m.ln();
    }
    options.progress.say(|| {
        format!(
            "{} candidates; χ²/ν of the nominal model {:.3}; fitting its parameters",
            p.cands.len(),
            chi2_nominal / n_real
        )
    });
    let base = p.fit("baseline", &theta0, &[], options.max_iterations)?;
    if !base.converged {
        warnings.push(format!(
            "baseline fit stopped after {} iterations without converging",
            base.iterations
        ));
    }
    let nb = p.n_base();
    let free_base = nb - usize::from(options.weighed_mass_kg.is_some());
    let nu_base = n_real - free_base as f64;
    let base_pred = p.model(&base.theta, &[])?;
    // Stages 3–4: forward selection with backward checks.
    let mut active: Vec<Act> = Vec::new();
    let mut cur = base.clone();
    let mut screening = Vec::new();
    let mut not_observable: Vec<NotObservable> = Vec::new();
    let mut ambiguous: Vec<AmbiguousFamily> = Vec::new();
    let mut accepted_stats: Vec<(usize, f64, usize, f64, f64, Vec<RelativeChange>)> = Vec::new();
    let n_cand = p.cands.len().max(1) as f64;
    let ln_n = n_real.ln();
    let mut excluded: Vec<usize> = Vec::new();
    let folds = crate::cv::folds_of(&p.used, nl, crate::cv::FOLDS);
    let exc_folds = crate::cv::excitation_folds_of(&p.used, nch * nl);
    let loeo = options.cross_validation && nex >= 3;
    let mut accepted_cv: Vec<Option<HeldOutCheck>> = Vec::new();
    let mut accepted_practical: Vec<f64> = Vec::new();
    let mut accepted_loeo: Vec<Option<HeldOutCheck>> = Vec::new();
    let in_prior = |c: usize| prior.is_some_and(|pr| pr.phi(&p.cands[c].id).is_some());
    for step in 1..=options.max_effects {
        let (q0, _) = span_basis(&cur.jacobian, 1e-10);
        let todo: Vec<usize> = (0..p.cands.len())
            .filter(|c| !active.iter().any(|a| a.c == *c) && !excluded.contains(c))
            .collect();
        let r0_len = cur.residual.len();
        let scores: Vec<(usize, Result<Score, CheckError>)> = todo
            .par_iter()
            .map(|&c| {
                let s = match &p.cands[c].screening {
                    Screening::RigidMassGauge if p.fixed_mass.is_none() => {
                        Ok(rigid_mass_gauge(r0_len))
                    }
                    Screening::Score | Screening::RigidMassGauge => {
                        score_candidate(&p, &cur, &active, c, &q0)
                    }
                    Screening::Profile { grid, delay_scan } => {
                        grid_candidate(&p, &cur, &active, c, &q0, grid, *delay_scan)
                    }
                    Screening::Resonance => resonance_candidate(&p, &cur, &active, c, &q0),
                };
                (c, s)
            })
            .collect();
        let mut significant: Vec<(usize, Score, f64)> = Vec::new();
        for (c, s) in scores {
            let cand = &p.cands[c];
            match s {
                Err(e) => {
                    warnings.push(format!("candidate '{}' cannot be evaluated: {e}", cand.id));
                    excluded.push(c);
                }
                Ok(s) if s.rank == 0 => {
                    let by: Vec<String> = s
                        .absorbed_by
                        .iter()
                        .filter(|(_, f)| *f > 0.999)
                        .map(|(n, _)| n.clone())
                        .collect();
                    not_observable.push(NotObservable {
                        id: cand.id.clone(),
                        title: cand.title.clone(),
                        reason: if by.is_empty() {
                            let joint: Vec<String> = s
                                .absorbed_by
                                .iter()
                                .filter(|(_, f)| *f > 0.01)
                                .map(|(n, _)| n.clone())
                                .collect();
                            format!(
                                "absorbed without trace by the free {} together",
                                joint.join(" and ")
                            )
                        } else {
                            format!("absorbed without trace by the free {}", by.join(" and "))
                        },
                        would_reveal: cand.reveal.to_string(),
                    });
                    screening.push(ScreenEntry {
                        step,
                        id: cand.id.clone(),
                        rank: 0,
                        n_parameters: cand.neutral.len(),
                        score: 0.0,
                        threshold: f64::INFINITY,
                        refit_delta_chi2: None,
                        refit_delta_bic: None,
                        decision: "not observable (absorbed)".into(),
                    });
                    excluded.push(c);
                }
                Ok(s) => {
                    let thr = chi2_isf(options.alpha / (n_cand * s.n_tests as f64), s.rank as f64);
                    screening.push(ScreenEntry {
                        step,
                        id: cand.id.clone(),
                        rank: s.rank,
                        n_parameters: cand.neutral.len(),
                        score: s.score,
                        threshold: thr,
                        refit_delta_chi2: None,
                        refit_delta_bic: None,
                        decision: if s.score > thr {
                            "significant score".into()
                        } else if in_prior(c) {
                            "not significant; refitted as accepted in the first pass".into()
                        } else {
                            "not significant".into()
                        },
                    });
                    if s.score > thr || in_prior(c) {
                        let gain = s.score - s.rank as f64 * ln_n;
                        significant.push((c, s, gain));
                    }
                }
            }
        }
        options.progress.say(|| {
            format!(
                "step {step}: χ²/ν {:.3}; {} candidates screened, {} significant",
                cur.chi2 / (n_real - (free_base + active_dims(&active)) as f64),
                todo.len(),
                significant.len()
            )
        });
        if significant.is_empty() {
            break;
        }
        significant.sort_by(|a, b| b.2.total_cmp(&a.2).then(a.0.cmp(&b.0)));
        let gmax = significant[0].2;
        let parsimonious = top_by_score_per_parameter(&significant, options.refit_top);
        let refit: Vec<&(usize, Score, f64)> = significant
            .iter()
            .enumerate()
            // Profile-screened candidates are refitted from a tenth of the best gain:
            // their statistic (chord-refined at a coarse grid point) is a lower bound
            // when the effect is far from its neutral point, not quite comparable
            // with local scores.
            .filter(|(i, s)| {
                *i < options.refit_top
                    || s.2 >= 0.5 * gmax
                    || (s.1.n_tests > 1 && s.2 >= 0.1 * gmax)
                    || parsimonious.contains(&s.0)
                    || in_prior(s.0)
            })
            .map(|(_, s)| s)
            .collect();
        let fits: Vec<(usize, Result<Fit, CheckError>, Vec<usize>)> = refit
            .par_iter()
            .map(|(c, s, _)| {
                let mut act = active.clone();
                act.push(Act {
                    c: *c,
                    kept: s.kept.clone(),
                    gauge: Vec::new(),
                });
                // The Gauss–Newton start can overshoot when the effect is strongly
                // non-linear: halve it until it is no worse than the current model.
                let cand = &p.cands[*c];
                let neutral: Vec<f64> = s.kept.iter().map(|&j| cand.neutral[j]).collect();
                let mut alpha = s.start.clone();
                let mut t0 = cur.theta.clone();
                t0.extend_from_slice(&alpha);
                if let Some(ts) = &s.theta_start {
                    // Profile start: the current parameters re-adjusted at the best
                    // grid point, if that is better than leaving them.
                    let mut t1 = ts.clone();
                    t1.extend_from_slice(&alpha);
                    let c0 = p.residual(&t0, &act).map(|r| lm::chi2(&r));
                    let c1 = p.residual(&t1, &act).map(|r| lm::chi2(&r));
                    if let (Ok(c0), Ok(c1)) = (c0, c1) {
                        if c1 < c0 {
                            t0 = t1;
                        }
                    }
                }
                let halvings = if s.theta_start.is_some() { 0 } else { 40 };
                for _ in 0..halvings {
                    match p.residual(&t0, &act) {
                        Ok(r) if lm::chi2(&r) <= cur.chi2 => break,
                        _ => {
                            alpha
                                .iter_mut()
                                .zip(&neutral)
                                .for_each(|(a, n)| *a = n + 0.5 * (*a - n));
                            t0.truncate(cur.theta.len());
                            t0.extend_from_slice(&alpha);
                        }
                    }
                }
                // A profile start is far from the neutral point and often from the
                // optimum too: allow more iterations.
                let iterations = if s.n_tests > 1 {
                    4 * options.max_iterations
                } else {
                    options.max_iterations
                };
                let stage = format!("refit {}", p.cands[*c].id);
                let mut fit = p.fit(&stage, &t0, &act, iterations);
                // With nothing accepted yet, the baseline may have drifted far to stand in
                // for the missing physics (a hanging body's mass doubled without its
                // pendulum stiffness), into a basin the true effect cannot leave. The
                // nominal parameters are the user's prior: refit from them too, keep the
                // better.
                let mut restarts = Vec::new();
                if active.is_empty() {
                    let mut tn = theta_nom.clone();
                    tn.extend_from_slice(&s.start);
                    restarts.push(tn);
                }
                if let Some(pr) = prior.filter(|_| in_prior(*c)) {
                    restarts.push(pr.start(&p, &act, &cur.theta, &s.start));
                }
                for t in restarts {
                    if let Ok(f_r) = p.fit(&stage, &t, &act, iterations) {
                        if fit.as_ref().map_or(true, |f| f_r.chi2 < f.chi2) {
                            fit = Ok(f_r);
                        }
                    }
                }
                match fit {
                    Ok(f) => {
                        let (f, kept) =
                            reopen_dropped(&p, f, &active, *c, &s.kept, &stage, iterations);
                        (*c, Ok(f), kept)
                    }
                    Err(e) => (*c, Err(e), s.kept.clone()),
                }
            })
            .collect();
        // Evaluate each refit.
        struct Eval {
            c: usize,
            fit: Fit,
            dchi2: f64,
            dbic: f64,
            rank: usize,
            ok: bool,
            why: String,
            held_out: Option<HeldOutCheck>,
            held_out_exc: Option<HeldOutCheck>,
            practical: f64,
        }
        let cur_pred = p.model(&cur.theta, &active)?;
        let cv_without = if options.cross_validation {
            crate::cv::held_out_residuals(&cur.residual, &cur.jacobian, &folds, crate::cv::FOLDS)
        } else {
            Default::default()
        };
        let loeo_without = if loeo {
            crate::cv::held_out_residuals(&cur.residual, &cur.jacobian, &exc_folds, nex)
        } else {
            Default::default()
        };
        let mut evals: Vec<Eval> = Vec::new();
        let mut refit_kept: Vec<(usize, Vec<usize>)> = Vec::new();
        for (c, f, kept) in fits {
            let s = &refit.iter().find(|x| x.0 == c).expect("refitted").1;
            let cand = &p.cands[c];
            let f = match f {
                Ok(f) => f,
                Err(e) => {
                    warnings.push(format!("refit of '{}' failed: {e}", cand.id));
                    continue;
                }
            };
            let dchi2 = cur.chi2 - f.chi2;
            let d = kept.len();
            let dbic = dchi2 - d as f64 * ln_n;
            let thr = chi2_isf(options.alpha / (n_cand * s.n_tests as f64), d as f64);
            let (k0, phi) = last_effect_phi(&p, &f.theta, c, &kept);
            let alpha = &f.theta[k0..];
            let infos = cand.effect.parameters();
            let mut why = Vec::new();
            if !(dchi2 > thr) {
                why.push(format!("LR {dchi2:.1} ≤ {thr:.1}"));
            }
            if !(dbic > options.min_delta_bic) {
                why.push(format!("ΔBIC {dbic:.1} ≤ {}", options.min_delta_bic));
            }
            for ((v, pi), n0) in phi.iter().zip(&infos).zip(&cand.neutral) {
                let tol = 1e-6 * (pi.upper - pi.lower).abs().min(1e6).max(1e-9);
                let at_lo = (v - pi.lower).abs() <= tol && (n0 - pi.lower).abs() > tol;
                let at_hi = (v - pi.upper).abs() <= tol && (n0 - pi.upper).abs() > tol;
                if at_lo || at_hi {
                    why.push(format!("{} pinned at its bound {v:.4}", pi.name));
                }
            }
            // Wald test on the candidate's parameters (pseudo-inverse over its identifiable part).
            let nu = n_real - (free_base + active_dims(&active) + d) as f64;
            let cov = fit_covariance(&f, nu);
            // In α coordinates (identifiable directions only).
            let np = d;
            let cphi = cov.view((k0, k0), (np, np)).into_owned();
            let dphi = nalgebra::DVector::from_iterator(
                np,
                alpha.iter().zip(&kept).map(|(a, &j)| a - cand.neutral[j]),
            );
            let eig = cphi.symmetric_eigen();
            let emax = eig.eigenvalues.max().max(f64::MIN_POSITIVE);
            let mut wald = 0.0;
            for k in 0..np {
                if eig.eigenvalues[k] > 1e-10 * emax {
                    let v = eig.eigenvectors.column(k).dot(&dphi);
                    wald += v * v / eig.eigenvalues[k];
                }
            }
            let wthr = rbprops_core::stats::chi2_quantile(options.wald_level, d.max(1) as f64);
            if !(wald > wthr) {
                why.push(format!("Wald {wald:.1} ≤ {wthr:.1}"));
            }
            // Practical significance: the fitted change to the FRFs against the
            // precision floor (see `PRACTICAL_MARGIN`).
            let mut act = active.clone();
            act.push(Act {
                c,
                kept: kept.clone(),
                gauge: Vec::new(),
            });
            let practical = p.model(&f.theta, &act).map_or(0.0, |m| {
                p.change_over_floor(&m, &cur_pred, &sigma_precision)
            });
            if !(practical >= PRACTICAL_MARGIN) {
                why.push(format!(
                    "fitted FRF change {practical:.2} × the precision floor (RMS), needs ≥ {PRACTICAL_MARGIN}"
                ));
            }
            // Held-out check (A2), only where the other evidence holds (it is cheap,
            // but its verdict matters only then).
            let held_out = if options.cross_validation && why.is_empty() {
                let with = crate::cv::held_out_residuals(
                    &f.residual,
                    &f.jacobian,
                    &folds,
                    crate::cv::FOLDS,
                );
                let h = crate::cv::compare(&cv_without, &with, &folds, crate::cv::FOLDS);
                if !h.passed {
                    why.push(format!(
                        "held-out χ² decrease {:.1} ± {:.1} in {}/{} folds (needs > 2 SE and ≥ 80 %)",
                        h.delta_chi2, h.standard_error, h.folds_improved, h.folds
                    ));
                }
                Some(h)
            } else {
                None
            };
            // Leave-one-excitation-out, only once the candidate's fit is near-adequate
            // (χ²/ν < LOEO_MAX_CHI2_NU): its one-step refit linearises about the fit with
            // every excitation, and while the model still misfits grossly the held-out
            // prediction is outside that linear regime and measures the physics still
            // missing, not over-fitting (it vetoed a true gravity stiffness at χ²/ν ≈ 10³
            // on the hanging probe of scripts/model_check_probe.py). Over-fitting is the
            // danger near the noise floor, where the check applies.
            let chi2_nu_with = f.chi2 / nu.max(1.0);
            let held_out_exc = if loeo && why.is_empty() && chi2_nu_with < LOEO_MAX_CHI2_NU {
                let with = crate::cv::held_out_residuals(&f.residual, &f.jacobian, &exc_folds, nex);
                let h = crate::cv::compare_excitations(&loeo_without, &with, &exc_folds, nex);
                if !h.passed {
                    why.push(format!(
                        "a held-out excitation gets worse (held-out χ² change / SE per excitation: {})",
                        h.fold_z
                            .iter()
                            .map(|z| format!("{z:.1}"))
                            .collect::<Vec<_>>()
                            .join(", ")
                    ));
                }
                Some(h)
            } else {
                None
            };
            for e in screening.iter_mut().rev() {
                if e.step == step && e.id == cand.id {
                    e.refit_delta_chi2 = Some(dchi2);
                    e.refit_delta_bic = Some(dbic);
                    break;
                }
            }
            refit_kept.push((c, kept));
            evals.push(Eval {
                c,
                fit: f,
                dchi2,
                dbic,
                rank: d,
                ok: why.is_empty(),
                why: why.join("; "),
                held_out,
                held_out_exc,
                practical,
            });
        }
        evals.sort_by(|a, b| b.dbic.total_cmp(&a.dbic).then(a.c.cmp(&b.c)));
        let Some(best_i) = evals.iter().position(|e| e.ok) else {
            for e in &evals {
                set_decision(
                    &mut screening,
                    step,
                    &p.cands[e.c].id,
                    format!("rejected: {}", e.why),
                );
            }
            break;
        };
        let best = &evals[best_i];
        options.progress.say(|| {
            format!(
                "step {step}: accepted {} (Δχ² {:.1})",
                p.cands[best.c].id, best.dchi2
            )
        });
        let best_basis = &refit
            .iter()
            .find(|x| x.0 == best.c)
            .expect("refitted")
            .1
            .basis;
        // Distinctness (A5): rivals within the ΔBIC margin and strongly correlated.
        let mut family = vec![best.c];
        let mut family_bic = vec![best.dbic];
        let mut corr_max: f64 = 0.0;
        for e in &evals {
            if e.c == best.c
                || !(e.dbic > options.min_delta_bic)
                || e.dbic < best.dbic - options.min_delta_bic
            {
                continue;
            }
            let b2 = &refit.iter().find(|x| x.0 == e.c).expect("refitted").1.basis;
            let cc = best_basis
                .tr_mul(b2)
                .svd(false, false)
                .singular_values
                .max();
            if cc > options.max_correlation {
                family.push(e.c);
                family_bic.push(e.dbic);
                corr_max = corr_max.max(cc);
            }
        }
        for e in &evals {
            let d = if e.c == best.c {
                if family.len() > 1 {
                    "accepted as member of an ambiguous family".to_string()
                } else {
                    "accepted".to_string()
                }
            } else if family.contains(&e.c) {
                "ambiguous with the accepted effect".to_string()
            } else if e.ok {
                "significant but weaker".to_string()
            } else {
                format!("rejected: {}", e.why)
            };
            set_decision(&mut screening, step, &p.cands[e.c].id, d);
        }
        let before_inertia = inertia_report("", &cur.theta, &fit_covariance(&cur, 1.0));
        let after_inertia = inertia_report("", &best.fit.theta, &fit_covariance(&best.fit, 1.0));
        let change = inertia_change(&before_inertia, &after_inertia);
        if family.len() > 1 {
            ambiguous.push(AmbiguousFamily {
                ids: family.iter().map(|&c| p.cands[c].id.clone()).collect(),
                delta_bic: family_bic,
                canonical_correlation: corr_max,
                separating_measurement: family
                    .iter()
                    .map(|&c| format!("{}: {}", p.cands[c].id, p.cands[c].reveal))
                    .collect::<Vec<_>>()
                    .join("; "),
            });
            excluded.extend(family.iter().filter(|&&c| c != best.c));
        }
        let best_tests = refit
            .iter()
            .find(|x| x.0 == best.c)
            .expect("refitted")
            .1
            .n_tests;
        accepted_cv.push(best.held_out.clone());
        accepted_practical.push(best.practical);
        accepted_loeo.push(best.held_out_exc.clone());
        accepted_stats.push((
            best.c,
            best.dchi2,
            best.rank,
            chi2_isf(
                options.alpha / (n_cand * best_tests as f64),
                best.rank as f64,
            ),
            best.dbic,
            change,
        ));
        let best_score = &refit.iter().find(|x| x.0 == best.c).expect("refitted").1;
        let kept = refit_kept
            .iter()
            .find(|x| x.0 == best.c)
            .map_or_else(|| best_score.kept.clone(), |x| x.1.clone());
        // Gauges of the neutral point that the refit found identifiable are gauges no more.
        let reopened: Vec<usize> = kept
            .iter()
            .copied()
            .filter(|j| !best_score.kept.contains(j))
            .collect();
        let gauge = best_score
            .gauge
            .iter()
            .filter(|g| reopened.iter().map(|&j| g[j] * g[j]).sum::<f64>() < 0.5)
            .cloned()
            .collect();
        active.push(Act {
            c: best.c,
            kept,
            gauge,
        });
        cur = best.fit.clone();
        // Backward check: drop an earlier effect whose removal no longer costs significance.
        if active.len() > 1 {
            let mut k = 0;
            while k + 1 < active.len() {
                let without: Vec<Act> = active
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| *i != k)
                    .map(|(_, a)| a.clone())
                    .collect();
                let theta_wo = drop_params(&p, &cur.theta, &active, k);
                let f_wo = p.fit("backward", &theta_wo, &without, options.max_iterations)?;
                let (_, _, d, thr, _, _) = accepted_stats[k];
                if f_wo.chi2 - cur.chi2 < thr.max(d as f64 * ln_n) {
                    set_decision(
                        &mut screening,
                        step,
                        &p.cands[active[k].c].id,
                        "dropped in the backward check".into(),
                    );
                    accepted_stats.remove(k);
                    accepted_cv.remove(k);
                    accepted_practical.remove(k);
                    accepted_loeo.remove(k);
                    active = without;
                    cur = f_wo;
                } else {
                    k += 1;
                }
            }
        }
    }
    // Final numbers, with the accepted effects' gauges centred.
    let cur = centre_gauges(&p, cur, &mut active, options.max_iterations);
    let free_final = free_base + active_dims(&active);
    let nu_after = n_real - free_final as f64;
    let final_pred = p.model(&cur.theta, &active)?;
    let cov_base = fit_covariance(&base, nu_base);
    let cov_final = fit_covariance(&cur, nu_after);
    let inertia_nominal = inertia_report("nominal spec", &theta_nom, &DMatrix::zeros(nb, nb));
    let inertia_before = inertia_report("baseline fit (nominal physics)", &base.theta, &cov_base);
    let inertia_after = inertia_report(
        "final fit (FRF-level estimate with accepted effects)",
        &cur.theta,
        &cov_final,
    );
    let change = inertia_change(&inertia_before, &inertia_after);
    // Corrected parameters of the nominal model: from the final fit, where the accepted
    // effects no longer bias them (without accepted effects it is the baseline fit).
    let (th, cov) = (&cur.theta, &cov_final);
    let mut corrected = Vec::new();
    let qn = quantities(&inertia_nominal);
    let qb = quantities(&inertia_after);
    for i in 0..10 {
        let se = inertia_after.standard_errors[i];
        let z = if se > 0.0 { (qb[i] - qn[i]) / se } else { 0.0 };
        corrected.push(CorrectedParameter {
            name: INERTIA_NAMES[i].to_string(),
            nominal: qn[i],
            fitted: qb[i],
            standard_error: se,
            z,
            significant: z.abs() > 3.0,
        });
    }
    for (k, kind) in p.baseline.kinds.iter().enumerate() {
        let (name, nom, fit, se) = match kind {
            ParamKind::Inertia(_) => continue,
            ParamKind::StiffnessScale { .. } => (
                p.baseline.names[k].replace("ln_stiffness_scale", "stiffness_factor"),
                1.0,
                th[k].exp(),
                th[k].exp() * cov[(k, k)].max(0.0).sqrt(),
            ),
            ParamKind::ModalDampingLog(_) => (
                p.baseline.names[k].replace("ln_ratio", "ratio"),
                theta_nom[k].exp(),
                th[k].exp(),
                th[k].exp() * cov[(k, k)].max(0.0).sqrt(),
            ),
            _ => (
                p.baseline.names[k].clone(),
                theta_nom[k],
                th[k],
                cov[(k, k)].max(0.0).sqrt(),
            ),
        };
        let z = if se > 0.0 { (fit - nom) / se } else { 0.0 };
        corrected.push(CorrectedParameter {
            name,
            nominal: nom,
            fitted: fit,
            standard_error: se,
            z,
            significant: z.abs() > 3.0,
        });
    }
    // Accepted effects with standard errors.
    let mut accepted = Vec::new();
    let mut offset = nb;
    let mut improved_effects = Vec::new();
    let mut final_effects = Vec::new();
    for (k, a) in active.iter().enumerate() {
        let cand = &p.cands[a.c];
        let d = a.dim();
        let infos = cand.effect.parameters();
        // φ = neutral + B α, Cov φ = B Cov α Bᵀ.
        let phi = a.phi(&cand.neutral, &cur.theta[offset..offset + d]);
        final_effects.push((cand.id.clone(), phi.clone()));
        let ca = cov_final.view((offset, offset), (d, d)).into_owned();
        let mut cphi = DMatrix::zeros(phi.len(), phi.len());
        for (r, &i) in a.kept.iter().enumerate() {
            for (c, &j) in a.kept.iter().enumerate() {
                cphi[(i, j)] = ca[(r, c)];
            }
        }
        let params = (0..phi.len())
            .map(|j| FittedParameter {
                name: infos[j].name.clone(),
                unit: infos[j].unit.to_string(),
                value: phi[j],
                standard_error: cphi[(j, j)].max(0.0).sqrt(),
            })
            .collect();
        let eff = cand.effect.with_values(&phi).map_err(CheckError::Model)?;
        match effect_spec(eff.as_ref(), spec) {
            Ok(e) => improved_effects.push(e),
            Err(e) => warnings.push(format!(
                "'{}' is not written to the improved spec: {e}",
                cand.id
            )),
        }
        offset += d;
        let (_, dchi2, d, thr, dbic, ch) = accepted_stats[k].clone();
        if ambiguous.iter().any(|a| a.ids[0] == cand.id) {
            continue;
        }
        accepted.push(AcceptedEffect {
            id: cand.id.clone(),
            title: cand.title.clone(),
            source: cand.source.to_string(),
            parameters: params,
            delta_chi2: dchi2,
            dof: d,
            lr_threshold: thr,
            delta_bic: dbic,
            inertia_change: ch,
            gauge_directions: a.gauge.clone(),
            held_out: accepted_cv[k].clone(),
            held_out_excitations: accepted_loeo[k].clone(),
            change_over_precision_floor: accepted_practical[k],
        });
    }
    let (mut improved_spec, fx) = p.build(&cur.theta, &[])?;
    drop(fx);
    improved_spec.effects.extend(improved_effects);
    if !options.sensor_masses_kg.is_empty() {
        let (pids, _) = point_ids(&layout.spec_geometry);
        let mut vals = vec![0.0; pids.len()];
        for (pid, m) in &options.sensor_masses_kg {
            if let Some(k) = pids.iter().position(|p| p == pid) {
                vals[k] = *m;
            }
        }
        let e = local_effect("sensor_mass", spec, &vals).map_err(CheckError::Model)?;
        improved_spec.effects.push(effect_spec(e.as_ref(), spec)?);
    }
    for e in &improved_spec.effects {
        if rbprops_sim::effects::parse_effect(e).is_err() {
            warnings.push(format!(
                "the improved spec switches on '{}', which this rbprops-sim version does not know yet: frf-sim will reject it until the catalogue has it",
                e.id
            ));
        }
    }
    // Localisation maps.
    let (spec_b, eff_b) = p.build(&base.theta, &[])?;
    let (f_lo, f_hi) = model_modes_band(&spec_b, &layout, &eff_b);
    let bnds = bands(f_lo, f_hi, &layout.frequency_hz);
    let residuals_before = residual_map(&layout, y, &base_pred, &sigma, bnds.clone());
    let residuals_after = residual_map(&layout, y, &final_pred, &sigma, bnds);
    let band = noise_band(nu_after, noise_model.variance_scale_se);
    let chi2_nu_after = cur.chi2 / nu_after;
    // With no fitted noise (a = b = 0 on every channel) σ is the precision floor alone,
    // and its computation-floor part is a bound on the agreement of two exact
    // computations, not a variance: a χ²/ν below the band means agreement within it.
    let precision_only = noise_model
        .relative
        .iter()
        .chain(&noise_model.floor)
        .all(|x| *x == 0.0);
    let noise_floor_reached = (chi2_nu_after >= band[0] || precision_only)
        && chi2_nu_after <= band[1]
        && residuals_after.flagged.is_empty();
    let mut report = ModelCheckReport {
        campaign: spec.name.clone(),
        verdict: String::new(),
        accepted,
        ambiguous,
        not_observable,
        chi2_nu_nominal: chi2_nominal / n_real,
        chi2_nu_before: base.chi2 / nu_base,
        chi2_nu_after,
        nu_before: nu_base,
        nu_after,
        noise_band: band,
        noise_floor_reached,
        noise: noise_model,
        n_values: p.used.len(),
        corrected_parameters: corrected,
        inertia_nominal,
        inertia_before,
        inertia_after,
        inertia_change: change,
        screening,
        residuals_before,
        residuals_after,
        method: std::mem::take(&mut method),
        warnings,
    };
    report.verdict = verdict(&report);
    let prior = Prior {
        base: cur.theta[..nb].to_vec(),
        effects: final_effects,
    };
    Ok(CheckOutcome {
        prior,
        report,
        improved_spec,
        measured: y.clone(),
        nominal: nominal_pred,
        baseline: base_pred,
        improved: final_pred,
        sigma,
        layout,
    })
}

/// Smallest upper end of the noise band: χ²/ν within 5 % of 1 counts as the floor even
/// where ν is so large that the statistical band is narrower, since a noise model given
/// as side information (repeats, a data sheet) is not known better than that.
pub const MIN_BAND_UPPER: f64 = 1.05;

/// The band of χ²/ν consistent with noise: the central 99.73 % interval (the ±3 sd of a
/// normal) of χ²/ν with ν degrees of freedom when the noise variance is estimated with
/// relative standard error `se`, i.e. of F(ν, 2/se²) ([`rbprops_core::stats::chi2_nu_band`];
/// χ²_ν/ν when se = 0), with its upper end at least [`MIN_BAND_UPPER`]. Both ends are
/// positive.
pub fn noise_band(nu: f64, se: f64) -> [f64; 2] {
    let [lo, hi] = rbprops_core::stats::chi2_nu_band(nu, se, rbprops_core::stats::BAND_TAIL);
    [lo, hi.max(MIN_BAND_UPPER)]
}

fn set_decision(screening: &mut [ScreenEntry], step: usize, id: &str, d: String) {
    if let Some(e) = screening
        .iter_mut()
        .rev()
        .find(|e| e.step <= step && e.id == id)
    {
        e.decision = d;
    }
}

/// Largest relative residual signature ‖J_θ Δθ + J_φ g‖/‖J_φ g‖ of a reported gauge
/// direction g, once the other parameters compensate, for it to be re-centred. Only a
/// pre-filter: the linearised compensation misses an exact gauge by ~2 % (a common
/// excitation gain on the standing probe), the χ² test after the move decides.
const GAUGE_CENTRING: f64 = 0.1;

/// Re-centres each accepted effect along its gauge directions (a common gain the mass
/// absorbs, a common sensor shift the centre of mass absorbs) and fixes them there.
/// The data cannot say where on a gauge the truth lies: the fit stops wherever its
/// path left it (usually near the baseline, which absorbed the effect as a
/// compromise), and the covariance along it is unbounded (a mass SE of 50 kg). The
/// median rule of [`gauge_pivots`] picks the convention: move along g, with the other
/// parameters following (Δθ = −J_θ⁺ J_φ g), until the median coordinate is neutral;
/// hold that coordinate there (standard errors are then conditional on it) and polish.
/// Kept only if χ² stays within `0.1 + 1e-9 χ²` (a gauge move).
fn centre_gauges(p: &Problem, cur: Fit, active: &mut [Act], max_iter: usize) -> Fit {
    let nb = p.baseline.kinds.len();
    let mut cur = cur;
    let mut offset = nb;
    for i in 0..active.len() {
        let gauges = active[i].gauge.clone();
        for g in &gauges {
            let Some((theta, fixed)) = gauge_move(p, &cur, &active[i], offset, g) else {
                continue;
            };
            let mut trial = active.to_vec();
            trial[i].kept.retain(|&j| j != fixed);
            if let Ok(f) = p.fit("gauge centring", &theta, &trial, max_iter) {
                if f.chi2 <= cur.chi2 + 0.1 + 1e-9 * cur.chi2 {
                    cur = f;
                    active[i] = trial.swap_remove(i);
                }
            }
        }
        offset += active[i].dim();
    }
    cur
}

/// The parameters moved along the gauge `g` of the active effect `a` (its kept
/// coordinates start at `offset` in θ) to where the median coordinate is neutral, with
/// that coordinate removed, and its φ index; `None` when g is no gauge at this fit.
fn gauge_move(
    p: &Problem,
    cur: &Fit,
    a: &Act,
    offset: usize,
    g: &[f64],
) -> Option<(Vec<f64>, usize)> {
    let cand = &p.cands[a.c];
    let d = a.dim();
    let gk: Vec<f64> = a.kept.iter().map(|&j| g[j]).collect();
    let gmax = gk.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if gmax < 1e-12 {
        return None;
    }
    let j = &cur.jacobian;
    let jg = (0..d).fold(DVector::zeros(j.nrows()), |acc, k| {
        acc + j.column(offset + k) * gk[k]
    });
    let others: Vec<usize> = (0..j.ncols())
        .filter(|c| !(offset..offset + d).contains(c))
        .collect();
    // Columns normalised for the solve (parameters of very different units).
    let mut jt = j.select_columns(&others);
    let norms: Vec<f64> = jt.column_iter().map(|c| c.norm()).collect();
    for (k, n) in norms.iter().enumerate() {
        if *n > 0.0 {
            jt.column_mut(k).scale_mut(1.0 / n);
        }
    }
    let mut dt = jt.clone().svd(true, true).solve(&jg, 1e-12).ok()?;
    if (&jt * &dt - &jg).norm() > GAUGE_CENTRING * jg.norm() {
        return None;
    }
    for (x, n) in dt.iter_mut().zip(&norms) {
        *x = if *n > 0.0 { *x / n } else { 0.0 };
    }
    let x: Vec<f64> = (0..d)
        .map(|k| cur.theta[offset + k] - cand.neutral[a.kept[k]])
        .collect();
    let (beta, k_fixed) = median_pivot(&gk, &x, |_| true)?;
    let mut theta = cur.theta.clone();
    for k in 0..d {
        theta[offset + k] += beta * gk[k];
    }
    for (r, &c) in others.iter().enumerate() {
        theta[c] -= beta * dt[r];
    }
    theta.remove(offset + k_fixed);
    Some((theta, a.kept[k_fixed]))
}

fn active_dims(active: &[Act]) -> usize {
    active.iter().map(Act::dim).sum()
}

/// θ without the parameters of the k-th active effect.
fn drop_params(p: &Problem, theta: &[f64], active: &[Act], k: usize) -> Vec<f64> {
    let mut out = theta[..p.n_base()].to_vec();
    let mut off = p.n_base();
    for (i, a) in active.iter().enumerate() {
        let n = a.dim();
        if i != k {
            out.extend_from_slice(&theta[off..off + n]);
        }
        off += n;
    }
    out
}

/// The `k` significant candidates with the largest score per fitted parameter.
///
/// The gain ranking (score − rank·ln n) favours many-parameter candidates, which can
/// take up any shape of residual, while the score of a strong few-parameter effect is a
/// linearisation that understates it when the baseline has bent to stand in for it (a
/// bungee's pendulum stiffness absorbed into 2.7× lateral spring factors). These get a
/// refit too, so an effect that explains the most per parameter is always tried.
fn top_by_score_per_parameter(significant: &[(usize, Score, f64)], k: usize) -> Vec<usize> {
    let mut v: Vec<(usize, f64)> = significant
        .iter()
        .map(|(c, s, _)| (*c, s.score / s.rank.max(1) as f64))
        .collect();
    v.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    v.into_iter().take(k).map(|(c, _)| c).collect()
}

fn point_ids(g: &Geometry) -> (Vec<String>, ()) {
    let mut ids: Vec<String> = Vec::new();
    for c in &g.channels {
        if !ids.contains(&c.point) {
            ids.push(c.point.clone());
        }
    }
    (ids, ())
}

fn effect_spec(
    e: &dyn Effect,
    spec: &CampaignSpec,
) -> Result<rbprops_sim::spec::EffectSpec, CheckError> {
    crate::candidates::catalogue_entry(e, spec).map_err(CheckError::Model)
}

/// `x` with `n` significant digits.
fn sig(x: f64, n: i32) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let e = x.abs().log10().floor() as i32;
    if (-3..6).contains(&e) {
        format!("{:.*}", (n - 1 - e).max(0) as usize, x)
    } else {
        format!("{:.*e}", (n - 1) as usize, x)
    }
}

fn pct(x: f64) -> String {
    format!("{:+.1} %", 100.0 * x)
}

/// The short human verdict.
pub fn verdict(r: &ModelCheckReport) -> String {
    let mut parts = Vec::new();
    if r.accepted.is_empty() && r.ambiguous.is_empty() {
        parts.push("no missing physics found".to_string());
    } else {
        for a in &r.accepted {
            let ps: Vec<String> = a
                .parameters
                .iter()
                .filter(|p| p.standard_error > 0.0 && (p.value / p.standard_error).abs() > 3.0)
                .take(4)
                .map(|p| {
                    format!(
                        "{} = {} ± {} {}",
                        p.name,
                        sig(p.value, 4),
                        sig(p.standard_error, 2),
                        p.unit
                    )
                })
                .collect();
            parts.push(format!(
                "missing: {} [{}] ({})",
                a.title,
                a.id,
                ps.join(", ")
            ));
        }
        for f in &r.ambiguous {
            parts.push(format!(
                "missing: one of {} (indistinguishable here; to separate: {})",
                f.ids.join(" / "),
                f.separating_measurement
            ));
        }
    }
    let sig: Vec<String> = r
        .corrected_parameters
        .iter()
        .filter(|c| c.significant)
        .take(4)
        .map(|c| format!("{} {} → {}", c.name, sig(c.nominal, 4), sig(c.fitted, 4)))
        .collect();
    if !sig.is_empty() {
        parts.push(format!("corrected: {}", sig.join(", ")));
    }
    let floor = if r.noise_floor_reached {
        "noise floor reached".to_string()
    } else {
        let cells: Vec<String> = r.residuals_after.flagged.iter().take(3).cloned().collect();
        if cells.is_empty() {
            "not at the noise floor".to_string()
        } else {
            format!(
                "not at the noise floor; remaining residual in {}",
                cells.join(", ")
            )
        }
    };
    parts.push(format!(
        "χ²/ν {:.3} (nominal {:.3}) → {:.3}, {floor}",
        r.chi2_nu_before, r.chi2_nu_nominal, r.chi2_nu_after
    ));
    if !r.accepted.is_empty() || !r.ambiguous.is_empty() {
        let mut ch: Vec<&RelativeChange> = r.inertia_change.iter().collect();
        let mass = ch[0];
        ch.sort_by(|a, b| b.relative.abs().total_cmp(&a.relative.abs()));
        let top: Vec<String> = ch
            .iter()
            .filter(|c| c.quantity != "mass_kg")
            .take(2)
            .map(|c| format!("{} {}", c.quantity, pct(c.relative)))
            .collect();
        parts.push(format!(
            "inertia change: mass {}, {}",
            pct(mass.relative),
            top.join(", ")
        ));
    }
    for n in &r.not_observable {
        if n.id == "global_gain" || n.id == "sensor_mass" {
            parts.push(format!(
                "cannot be seen: {} ({}; would need {})",
                n.title, n.reason, n.would_reveal
            ));
        }
    }
    parts.join("; ")
}
