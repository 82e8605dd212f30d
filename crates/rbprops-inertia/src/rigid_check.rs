//! Rigid-body consistency of the identified modes with the geometry, and the
//! systematic-error (jackknife) interval.
//!
//! # The check
//! Every mode r seen by excitation k has modal constants `A_ikr = (s_iᵀT(p_i)φ_r)(f_kᵀφ_r)`
//! for a rigid body: per (k, r) the channel vector is a rigid motion `q_kr = φ_r L_kr`
//! (paper Eq. 5), and the participations are `L_kr = f_kᵀφ_r` with the nominal force
//! columns. Two residuals measure how far the data are from that, each relative to the
//! noise the modal fit reports (`residue_std`, with a precision floor so that exact data
//! do not turn rounding into structure):
//! 1. **Shapes.** Noise-weighted least squares `q = (S̃ᵀS̃)⁻¹S̃ᵀã` (`S̃ = W S`, `ã = W A`,
//!    `W = diag(1/σ_i)`); its residual `r̃ = (I − H)ã` has covariance `I − H` under noise
//!    alone, so `χ² = ‖r̃‖²` has `n − 6` degrees of freedom. Leaving a group g of channels
//!    out (a channel, or the channels of one sensor) lowers it by `r̃_gᵀ (I − H)_gg⁺ r̃_g`
//!    (the deletion identity of least squares; the pseudo-inverse also covers groups
//!    without which the rest cannot see all six motions) with `rank (I − H)_gg` dof.
//!    Misoriented or misplaced sensors and wrong channel gains show here.
//! 2. **Participations.** For each mode seen by several excitations,
//!    `min_φ Σ_k (q_k − φ f_kᵀφ)ᵀ G_k (q_k − φ f_kᵀφ)` (Gauss–Newton, `G_k = S̃ᵀS̃` the
//!    inverse covariance of `q_k`) has `6K − 6` dof; leaving excitation k out lowers it by
//!    the deletion statistic of k. Wrong force directions or positions show here (they
//!    leave every shape rigid and change only the scale `f_kᵀφ`).
//!
//! The data are consistent when `χ²/dof` of both together stays below
//! [`NOISE_ALLOWANCE`] × the 99.9 % point of `χ²_dof/dof`. The allowance admits residue
//! standard errors that are too small by up to √2 (the linearised LSFD errors ignore the
//! poles' own uncertainty), so a warning means a misfit well beyond noise.
//! An item is a suspect when leaving it out brings the rest below the threshold.
//!
//! # The systematic interval
//! A systematic error in one sensor or one excitation biases every noise replicate the
//! same way, so no resampling of the noise sees it. Leaving one sensor (or, when the
//! others cannot see all six motions without it, one channel) out, and separately one
//! excitation out (its modes re-normalised by the next excitation that sees them), and
//! re-estimating gives the delete-one jackknife variances `(n−1)/n Σ(θ_(i) − θ̄)²`; their sum
//! is the systematic variance reported next to the noise variance.

use crate::shapes::RigidFrame;
use nalgebra::{DMatrix, DVector, Matrix6};
use rbprops_core::records::{
    ConsistencyItemRecord, ModalFitRecord, ModeEstimate, RigidBodyCheckRecord, SelectedMode,
};
use rbprops_core::{real_modal_constants, Geometry, Vec6};

/// Relative precision floor of a modal constant (fraction of the mode's largest one):
/// a noise-free modal fit reproduces modal constants to about 1e-8 of the largest (its
/// model truncation); below this a residual is not evidence of anything.
pub const PRECISION_FLOOR: f64 = 1e-6;
/// Factor on the noise-only threshold admitting residue standard errors up to √2× small
/// (measured on the demo campaign, 1 % noise: χ²/dof = 1.07, shapes 1.03, participations
/// 1.12, so the linearised residue errors are calibrated to a few %).
pub const NOISE_ALLOWANCE: f64 = 2.0;
/// A mode of another excitation is the same physical mode when its frequency is within
/// this many half-power bandwidths and its channel shape has MAC ≥ [`MATCH_MAC`].
pub const MATCH_BANDWIDTHS: f64 = 3.0;
/// Minimum MAC for a mode of another excitation to count as the same physical mode.
pub const MATCH_MAC: f64 = 0.9;

/// Upper 0.1 % point of χ² with `nu` dof, Wilson–Hilferty (relative error 1.8 % at ν = 3,
/// < 0.6 % for ν ≥ 10; ample for a threshold that carries a factor 2 allowance).
pub fn chi2_quantile_999(nu: usize) -> f64 {
    // z: the standard-normal upper 0.1 % point.
    rbprops_core::stats::chi2_isf_wilson_hilferty(3.090_232_306_167_813, nu.max(1) as f64).max(0.0)
}

/// Threshold on `χ²/dof` for `dof` degrees of freedom.
pub fn threshold(dof: usize) -> f64 {
    NOISE_ALLOWANCE * chi2_quantile_999(dof) / dof.max(1) as f64
}

/// One excitation's view of one selected mode.
#[derive(Debug, Clone, PartialEq)]
pub struct Observation {
    /// Geometry index of the excitation.
    pub excitation: usize,
    /// The mode estimate of that excitation.
    pub estimate: ModeEstimate,
    /// Real modal constants and their standard errors (with the precision floor).
    pub a: Vec<f64>,
    /// Standard errors of `a` (same units, 1/kg).
    pub sigma: Vec<f64>,
}

/// For each selected mode (in order), the selected excitation's estimate first, then every
/// other excitation of the set-up with the same physical mode (see [`MATCH_BANDWIDTHS`]),
/// not weakly excited.
pub fn matched_observations(
    frame: &RigidFrame,
    modal: &ModalFitRecord,
    selected: &[SelectedMode],
) -> Vec<Vec<Observation>> {
    let n = frame.channel_ids.len();
    let obs_of = |k: usize, m: &ModeEstimate| -> Option<Observation> {
        if m.residues.len() != n || m.residue_std.len() != n {
            return None;
        }
        let (a, _) = real_modal_constants(&m.residues);
        if a.iter().any(|x| !x.is_finite()) {
            return None;
        }
        let amax = a.iter().fold(0.0f64, |s, x| s.max(x.abs()));
        let floor = PRECISION_FLOOR * amax;
        let sigma: Vec<f64> = m
            .residue_std
            .iter()
            .map(|s| (s * s + floor * floor).sqrt())
            .collect();
        if sigma.iter().any(|s| !(*s > 0.0) || !s.is_finite()) {
            return None;
        }
        Some(Observation {
            excitation: k,
            estimate: m.clone(),
            a,
            sigma,
        })
    };
    let response = |o: &Observation| -> Option<Vec<f64>> {
        frame.basis.fit(&o.a).ok().map(|f| {
            o.a.iter()
                .zip(&f.residual)
                .map(|(a, r)| a - r)
                .collect::<Vec<f64>>()
        })
    };
    let mut out = Vec::new();
    for sel in selected {
        let mut list = Vec::new();
        let Some(k0) = frame.excitation_index(&sel.excitation) else {
            out.push(list);
            continue;
        };
        let Some(m0) = modal
            .modes
            .iter()
            .find(|m| m.excitation == sel.excitation && m.mode == sel.excitation_mode)
        else {
            out.push(list);
            continue;
        };
        let Some(o0) = obs_of(k0, m0) else {
            out.push(list);
            continue;
        };
        let Some(y0) = response(&o0) else {
            out.push(list);
            continue;
        };
        list.push(o0);
        for (k, id) in frame.excitation_ids.iter().enumerate() {
            if k == k0 {
                continue;
            }
            let best = modal
                .modes
                .iter()
                .filter(|m| &m.excitation == id && m.setup == sel.setup && !m.weak)
                .min_by(|a, b| {
                    (a.frequency_hz - m0.frequency_hz)
                        .abs()
                        .total_cmp(&(b.frequency_hz - m0.frequency_hz).abs())
                });
            let Some(m) = best else { continue };
            let bw = (m.damping_ratio * m.frequency_hz)
                .max(m0.damping_ratio * m0.frequency_hz)
                .max(3.0 * m.frequency_std_hz.max(m0.frequency_std_hz));
            if (m.frequency_hz - m0.frequency_hz).abs() > MATCH_BANDWIDTHS * bw {
                continue;
            }
            let Some(o) = obs_of(k, m) else { continue };
            let Some(y) = response(&o) else { continue };
            if mac(&y, &y0) >= MATCH_MAC {
                list.push(o);
            }
        }
        out.push(list);
    }
    out
}

fn mac(a: &[f64], b: &[f64]) -> f64 {
    let ab: f64 = a.iter().zip(b).map(|(x, y)| x * y).sum();
    let aa: f64 = a.iter().map(|x| x * x).sum();
    let bb: f64 = b.iter().map(|x| x * x).sum();
    if aa > 0.0 && bb > 0.0 {
        ab * ab / (aa * bb)
    } else {
        0.0
    }
}

/// The noise-weighted rigid-body fit of one observation.
struct WeightedFit {
    /// Whitened residual `r̃`.
    r: DVector<f64>,
    /// `I − H`.
    m: DMatrix<f64>,
    q: Vec6,
    /// `S̃ᵀS̃`, the inverse covariance of `q`.
    gram: Matrix6<f64>,
}

fn weighted_fit(frame: &RigidFrame, o: &Observation) -> Option<WeightedFit> {
    let rows = frame.basis.rows();
    let n = rows.len();
    let s = DMatrix::from_fn(n, 6, |i, j| rows[i][j] / o.sigma[i]);
    let a = DVector::from_fn(n, |i, _| o.a[i] / o.sigma[i]);
    let g = s.transpose() * &s;
    let gram = Matrix6::from_fn(|i, j| g[(i, j)]);
    let chol = nalgebra::Cholesky::new(gram)?;
    let ginv = chol.inverse();
    let ginv_d = DMatrix::from_fn(6, 6, |i, j| ginv[(i, j)]);
    let qd = &ginv_d * (s.transpose() * &a);
    let r = &a - &s * &qd;
    let m = DMatrix::identity(n, n) - &s * &ginv_d * s.transpose();
    Some(WeightedFit {
        r,
        m,
        q: Vec6::from_fn(|i, _| qd[i]),
        gram,
    })
}

/// `r_gᵀ (M_gg)⁺ r_g` and `rank M_gg`: the drop of χ² when the rows `g` are left out.
fn deletion(fit: &WeightedFit, g: &[usize]) -> (f64, usize) {
    let k = g.len();
    let mgg = DMatrix::from_fn(k, k, |i, j| fit.m[(g[i], g[j])]);
    let rg = DVector::from_fn(k, |i, _| fit.r[g[i]]);
    let eig = mgg.symmetric_eigen();
    let mut chi = 0.0;
    let mut rank = 0;
    for (j, &lam) in eig.eigenvalues.iter().enumerate() {
        if lam > 1e-9 {
            let c = eig.eigenvectors.column(j).dot(&rg);
            chi += c * c / lam;
            rank += 1;
        }
    }
    (chi, rank)
}

/// `Σ_k (q_k − φ f_kᵀφ)ᵀ G_k (q_k − φ f_kᵀφ)` minimised over φ (Gauss–Newton from the first
/// observation's mass-normalised shape). `None` when it cannot start (`f_kᵀq_k ≤ 0`).
fn participation_chi2(frame: &RigidFrame, fits: &[(usize, Vec6, Matrix6<f64>)]) -> Option<f64> {
    let (k0, q0, _) = fits.first()?;
    let s = frame.forces[*k0].dot(q0);
    if !(s > 0.0) {
        return None;
    }
    let mut phi = q0 / s.sqrt();
    let chi = |phi: &Vec6| -> f64 {
        fits.iter()
            .map(|(k, q, g)| {
                let e = q - phi * frame.forces[*k].dot(phi);
                (e.transpose() * g * e)[0]
            })
            .sum()
    };
    let mut best = chi(&phi);
    for _ in 0..50 {
        let mut jtj = Matrix6::zeros();
        let mut jte = Vec6::zeros();
        for (k, q, g) in fits {
            let f = frame.forces[*k];
            let l = f.dot(&phi);
            let e = q - phi * l;
            let j = Matrix6::identity() * l + phi * f.transpose();
            jtj += j.transpose() * g * j;
            jte += j.transpose() * g * e;
        }
        let Some(step) = jtj.lu().solve(&jte) else {
            break;
        };
        let next = phi + step;
        let c = chi(&next);
        if !(c < best) {
            break;
        }
        let done = best - c <= 1e-12 * best.max(1e-300);
        phi = next;
        best = c;
        if done {
            break;
        }
    }
    Some(best)
}

/// The consistency check of the selected modes' observations (see the module docs).
/// `sensor_of[i]` names the sensor (measurement point) of channel i.
pub fn rigid_body_check(
    frame: &RigidFrame,
    geometry: &Geometry,
    observations: &[Vec<Observation>],
) -> Option<RigidBodyCheckRecord> {
    let n = frame.channel_ids.len();
    let sensors = sensor_groups(geometry);
    let mut shape_chi = 0.0;
    let mut shape_dof = 0usize;
    let mut ch_drop = vec![(0.0, 0usize); n];
    let mut se_drop = vec![(0.0, 0usize); sensors.len()];
    let mut part_chi = 0.0;
    let mut part_dof = 0usize;
    let nexc = frame.excitation_ids.len();
    let mut ex_drop = vec![(0.0, 0usize); nexc];
    for list in observations {
        let mut qs = Vec::new();
        for o in list {
            let Some(fit) = weighted_fit(frame, o) else {
                continue;
            };
            shape_chi += fit.r.norm_squared();
            shape_dof += n.saturating_sub(6);
            for i in 0..n {
                let (c, d) = deletion(&fit, &[i]);
                ch_drop[i].0 += c;
                ch_drop[i].1 += d;
            }
            for (s, (_, g)) in sensors.iter().enumerate() {
                let (c, d) = deletion(&fit, g);
                se_drop[s].0 += c;
                se_drop[s].1 += d;
            }
            qs.push((o.excitation, fit.q, fit.gram));
        }
        if qs.len() < 2 {
            continue;
        }
        let Some(full) = participation_chi2(frame, &qs) else {
            continue;
        };
        part_chi += full;
        part_dof += 6 * (qs.len() - 1);
        for j in 0..qs.len() {
            let rest: Vec<_> = qs
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != j)
                .map(|(_, x)| *x)
                .collect();
            let without = if rest.len() < 2 {
                Some(0.0)
            } else {
                participation_chi2(frame, &rest)
            };
            if let Some(w) = without {
                ex_drop[qs[j].0].0 += (full - w).max(0.0);
                ex_drop[qs[j].0].1 += 6;
            }
        }
    }
    let dof = shape_dof + part_dof;
    if dof == 0 {
        return None;
    }
    let chi = shape_chi + part_chi;
    let thr = threshold(dof);
    let consistent = chi / dof as f64 <= thr;
    // Leaving an item out makes the rest consistent.
    let explains = |drop: f64, d: usize| -> bool {
        let rest = dof.saturating_sub(d);
        !consistent && drop > 0.0 && (rest == 0 || (chi - drop) / rest as f64 <= threshold(rest))
    };
    let items = |ids: Vec<String>, drops: &[(f64, usize)]| -> Vec<ConsistencyItemRecord> {
        ids.into_iter()
            .zip(drops)
            .map(|(id, &(c, d))| ConsistencyItemRecord {
                id,
                chi2_drop: c,
                dof: d,
                suspect: explains(c, d),
            })
            .collect()
    };
    Some(RigidBodyCheckRecord {
        rigid_body_consistent: consistent,
        statistic_definition: "noise-weighted residual χ²/dof of the rigid-body transforms (paper Eq. 5) and of the modal participations f_kᵀφ across excitations; precision floor 1e-6 of each mode's largest modal constant".into(),
        statistic: chi / dof as f64,
        threshold: thr,
        dof,
        shape_statistic: if shape_dof > 0 { shape_chi / shape_dof as f64 } else { 0.0 },
        shape_dof,
        participation_statistic: if part_dof > 0 { part_chi / part_dof as f64 } else { 0.0 },
        participation_dof: part_dof,
        channels: items(frame.channel_ids.clone(), &ch_drop),
        sensors: items(sensors.iter().map(|(id, _)| id.clone()).collect(), &se_drop),
        excitations: items(frame.excitation_ids.clone(), &ex_drop),
    })
}

/// Channels grouped by sensor (measurement point; a channel without one is its own).
pub fn sensor_groups(geometry: &Geometry) -> Vec<(String, Vec<usize>)> {
    let mut out: Vec<(String, Vec<usize>)> = Vec::new();
    for (i, c) in geometry.channels.iter().enumerate() {
        let id = if c.point.is_empty() { &c.id } else { &c.point };
        match out.iter_mut().find(|(s, _)| s == id) {
            Some((_, v)) => v.push(i),
            None => out.push((id.clone(), vec![i])),
        }
    }
    out
}

/// The warning for an inconsistent check: names the suspects (or the largest
/// contributors when no single item explains it) and suggests `model-check`.
pub fn warning(c: &RigidBodyCheckRecord) -> Option<String> {
    if c.rigid_body_consistent {
        return None;
    }
    let name = |list: &[ConsistencyItemRecord]| -> Vec<String> {
        let mut s: Vec<&ConsistencyItemRecord> = list.iter().filter(|x| x.suspect).collect();
        s.sort_by(|a, b| b.chi2_drop.total_cmp(&a.chi2_drop));
        s.iter().map(|x| format!("'{}'", x.id)).collect()
    };
    let (ch, se, ex) = (name(&c.channels), name(&c.sensors), name(&c.excitations));
    let mut parts = Vec::new();
    if !se.is_empty() {
        parts.push(format!("sensor {}", se.join(" or ")));
    }
    if !ch.is_empty() && ch.len() <= 3 {
        parts.push(format!("channel {}", ch.join(" or ")));
    }
    if !ex.is_empty() {
        parts.push(format!("excitation {}", ex.join(" or ")));
    }
    let suspects = if parts.is_empty() {
        let mut top: Vec<(&str, f64)> = c
            .sensors
            .iter()
            .chain(&c.excitations)
            .map(|x| (x.id.as_str(), x.chi2_drop / x.dof.max(1) as f64))
            .collect();
        top.sort_by(|a, b| b.1.total_cmp(&a.1));
        format!(
            "no single sensor or excitation explains it; largest contributions from {}",
            top.iter()
                .take(3)
                .map(|(id, _)| format!("'{id}'"))
                .collect::<Vec<_>>()
                .join(", ")
        )
    } else {
        format!("suspect {}", parts.join("; "))
    };
    Some(format!(
        "the modes are not rigid-body consistent with the geometry (χ²/dof = {:.3e} > {:.3} for noise alone; shapes {:.3e}, participations {:.3e}): {suspects}. Sensor orientation, position or gain errors, force direction errors, or two close modes fitted as one (participations inconsistent across excitations) bias the estimates beyond their noise intervals (see the systematic interval); run model-check to locate them",
        c.statistic, c.threshold, c.shape_statistic, c.participation_statistic
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi2_quantile_is_close_to_tabulated_values() {
        // Tabulated 99.9 % points: ν = 3: 16.266, 10: 29.588, 50: 86.661, 100: 149.449.
        for (nu, q, tol) in [
            (3, 16.266, 0.02),
            (10, 29.588, 0.007),
            (50, 86.661, 0.002),
            (100, 149.449, 0.001),
        ] {
            let got = chi2_quantile_999(nu);
            assert!((got / q - 1.0).abs() < tol, "ν = {nu}: {got} vs {q}");
        }
    }
}
