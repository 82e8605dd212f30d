use super::problem::{project_out, span_basis, Act, Problem};
use super::screening::ABSORBED;
use crate::lm;
use crate::lm::Fit;
use nalgebra::{DMatrix, DVector};

/// The coordinates held at neutral to fix the exact gauges `null` (rows of `vt`), one
/// per gauge, by pivoted elimination. Among the coordinates that can serve as pivot
/// (|v_j| ≥ ½ max), the one whose neutral value puts the gauge shift at the median of
/// the shifts −δ_j/v_j is chosen: for a gauge such as a common gain, that keeps half
/// of the fitted gains above and half below neutral, so one faulty channel or force
/// gauge among many is reported as that one (1.05), not as all the others reading low
/// (0.988 each) with the mass moved by the difference. `delta` is the minimum-norm
/// Gauss–Newton step in the same normalised coordinates.
pub(super) fn gauge_pivots(null: &[usize], vt: &DMatrix<f64>, delta: &[f64]) -> Vec<usize> {
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
pub(super) fn median_pivot(
    v: &[f64],
    x: &[f64],
    eligible: impl Fn(usize) -> bool,
) -> Option<(f64, usize)> {
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

/// Smallest residual signature, in noise units, of a dropped coordinate moved over
/// half its plausible range once the fitted parameters compensate, for
/// [`reopen_dropped`] to free it: a move that changes χ² by less than 9 cannot be
/// told from noise.
pub(super) const REOPEN_SIGNATURE: f64 = 3.0;

/// The refit of candidate `c` with the coordinates [`score_candidate`] dropped as
/// exact gauges at the neutral point freed where they have become identifiable at the
/// fitted point. A coordinate bilinear with a kept one has no signature at neutral and
/// one once its partner moves: the tilt of the cords has none without their gravity
/// stiffness, the frequency of a residual mode none without its residues. Such a
/// coordinate is freed and the refit repeated from the fitted point (kept if better);
/// the exact gauges (a common gain the mass absorbs) stay dropped.
pub(super) fn reopen_dropped(
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
    act.push(Act::new(c, kept2.clone()));
    match p.fit(stage, &theta, &act, max_iter) {
        Ok(f2) if f2.chi2 < fit.chi2 => (f2, kept2),
        _ => (fit, kept.to_vec()),
    }
}

/// Candidate `c`'s full φ from θ whose last entries are its `kept` coordinates (the
/// others at neutral), and the index in θ where those entries start.
pub(super) fn last_effect_phi(
    p: &Problem,
    theta: &[f64],
    c: usize,
    kept: &[usize],
) -> (usize, Vec<f64>) {
    let k0 = theta.len() - kept.len();
    let act = Act::new(c, kept.to_vec());
    (k0, act.phi(&p.cands[c].neutral, &theta[k0..]))
}

/// The coordinates of candidate `c` outside `kept` whose signature at the fit `fit`
/// (its last parameters are `c`'s kept ones), with the fitted parameters compensating,
/// reaches [`REOPEN_SIGNATURE`] over half their plausible range and is not a
/// combination of the fitted parameters' (relative size above [`ABSORBED`]). Taken
/// greedily, strongest first, each against the ones already taken.
pub(super) fn identifiable_at(
    p: &Problem,
    fit: &Fit,
    active: &[Act],
    c: usize,
    kept: &[usize],
) -> Vec<usize> {
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
    let half_range: Vec<f64> = dropped.iter().map(|&j| cand.half_range(j)).collect();
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

/// Largest relative residual signature ‖J_θ Δθ + J_φ g‖/‖J_φ g‖ of a reported gauge
/// direction g, once the other parameters compensate, for it to be re-centred. Only a
/// pre-filter: the linearised compensation misses an exact gauge by ~2 % (a common
/// excitation gain on the standing probe), the χ² test after the move decides.
pub(super) const GAUGE_CENTRING: f64 = 0.1;

/// Re-centres each accepted effect along its gauge directions (a common gain the mass
/// absorbs, a common sensor shift the centre of mass absorbs) and fixes them there.
/// The data cannot say where on a gauge the truth lies: the fit stops wherever its
/// path left it (usually near the baseline, which absorbed the effect as a
/// compromise), and the covariance along it is unbounded (a mass SE of 50 kg). The
/// median rule of [`gauge_pivots`] picks the convention: move along g, with the other
/// parameters following (Δθ = −J_θ⁺ J_φ g), until the median coordinate is neutral;
/// hold that coordinate there (standard errors are then conditional on it) and polish.
/// Kept only if χ² stays within `0.1 + 1e-9 χ²` (a gauge move).
pub(super) fn centre_gauges(p: &Problem, cur: Fit, active: &mut [Act], max_iter: usize) -> Fit {
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
pub(super) fn gauge_move(
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
