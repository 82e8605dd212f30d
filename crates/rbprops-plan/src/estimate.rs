//! From the modal constants' covariance to the covariance of the ten properties, through
//! the Norm-Indicator selection, the rigid transform and the estimator `rb-solve` runs.
//!
//! For mode `r` the Norm Indicator picks the hit `k(r)` with the largest
//! `NI_k(ω_r)² = Σ_i |H_ik(ω_r)|²` (paper Eq. 12). Its real modal constants `a_r` give
//! `q_r = (SᵀS)⁻¹Sᵀa_r` (Eq. 5) and `φ_r = q_r/√s_r`, `s_r = f_kᵀq_r`
//! (docs/conventions.md §5), so to first order
//!
//! ```text
//!   dφ_r = D_r da_r,   D_r = s_r^{-1/2} (I − q_r f_kᵀ/(2 s_r)) (SᵀS)⁻¹Sᵀ
//! ```
//!
//! Modes taken from one hit share its fit (their constants are correlated,
//! [`crate::fitcov`]); different hits are independent. The estimator's Jacobian
//! `G = ∂p/∂φ` (Toivola–Nuutila, Eq. 10, or Bretl–Conti, Eq. 2, then Eqs. 7–9 to the
//! centre of mass) is taken by central differences of `rbprops_inertia`'s own functions
//! at the true shapes, and
//!
//! ```text
//!   Cov p̂ = G Cov(φ̂) Gᵀ.
//! ```
//!
//! This is the linear propagation `G Σ Gᵀ` of the actual estimator's errors, not a
//! Cramér–Rao bound: the pipeline uses one excitation per mode and an unweighted
//! orthogonality fit, so it is not efficient, and its spread is what a tester sees.

use crate::fitcov::ExcitationCovariance;
use crate::model::{Hit, PlanModel};
use nalgebra::RowVector6;
use nalgebra::{DMatrix, SMatrix};
use rbprops_core::Vec6;
use rbprops_inertia::{bretl_conti, describe_null_space, property_vector, toivola_nuutila};

/// The modal estimator whose spread is predicted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Estimator {
    /// Toivola–Nuutila (paper Eq. 10): four or more modes.
    #[default]
    ToivolaNuutila,
    /// Bretl–Conti (paper Eq. 2): all six modes.
    BretlConti,
}

impl Estimator {
    /// The method name of `rb-solve`'s records.
    pub fn name(self) -> &'static str {
        match self {
            Estimator::ToivolaNuutila => "toivola_nuutila",
            Estimator::BretlConti => "bretl_conti",
        }
    }
}

/// The ten properties of an estimator applied to mass-normalised shapes.
pub fn properties_of_shapes(est: Estimator, phi: &[Vec6]) -> Result<[f64; 10], String> {
    let m0 = match est {
        Estimator::ToivolaNuutila => {
            let sol = toivola_nuutila(phi, &[], None).map_err(|e| e.to_string())?;
            if sol.rank < 10 {
                return Err(format!(
                    "the modes leave {} combination(s) of the properties undetermined: {}",
                    10 - sol.rank,
                    describe_null_space(&sol, phi)
                ));
            }
            sol.mass_matrix
        }
        Estimator::BretlConti => bretl_conti(phi).map_err(|e| e.to_string())?.mass_matrix,
    };
    Ok(property_vector(&m0.properties()))
}

/// `∂p/∂φ` (10 × 6n, φ stacked mode by mode) by central differences with a step of
/// `1e-6 · max|φ_r|` per mode (the estimators are smooth; the truncation error is
/// ~1e-12 relative, far below anything the plan reports).
pub fn shape_jacobian(est: Estimator, phi: &[Vec6]) -> Result<DMatrix<f64>, String> {
    properties_of_shapes(est, phi)?;
    let n = phi.len();
    let mut jac = DMatrix::<f64>::zeros(10, 6 * n);
    for r in 0..n {
        let h = 1e-6 * phi[r].amax();
        for c in 0..6 {
            let mut plus = phi.to_vec();
            let mut minus = phi.to_vec();
            plus[r][c] += h;
            minus[r][c] -= h;
            let a = properties_of_shapes(est, &plus)?;
            let b = properties_of_shapes(est, &minus)?;
            for k in 0..10 {
                jac[(k, 6 * r + c)] = (a[k] - b[k]) / (2.0 * h);
            }
        }
    }
    Ok(jac)
}

/// Relative size below which `(f_kᵀφ_r)²` counts as "this hit does not excite mode r"
/// (relative to the largest over every mode and hit of the set-up): the fit would not
/// find the mode there, and the Norm Indicator never selects it.
pub const UNEXCITED: f64 = 1e-6;

/// Relative size of the smallest eigenvalue of `SᵀS` (channel rows scaled to the body)
/// below which a rigid motion counts as unseen by the sensors.
pub const UNSEEN: f64 = 1e-9;

/// The predicted spread of one set-up's estimate.
#[derive(Debug, Clone)]
pub struct SetupPrediction {
    /// Set-up index.
    pub setup: usize,
    /// For each mode (ascending frequency), the index of the hit the NI selects.
    pub selected_hits: Vec<Option<usize>>,
    /// Covariance of the ten properties (docs/conventions.md §3 order).
    pub cov: SMatrix<f64, 10, 10>,
    /// Why the prediction may not describe the pipeline on this set-up, when it may not
    /// ([`prediction_limit`]).
    pub limit: Option<String>,
}

/// When the plan's model of the fit does not hold for a set-up: two of its modes closer
/// than `modal-fit`'s "near one frequency" (`rbprops_modal::evidence::NEAR_BANDWIDTHS`
/// half-power half-bandwidths) with two or more hits. Such pairs make the pipeline refit
/// the set-up with the poly-reference estimator, which takes each mode shape from every
/// excitation at once, while the plan linearises the per-excitation fit and the Norm
/// Indicator's single excitation per mode. On the `close-modes` example (0.75
/// half-bandwidths, every seed refitted poly-reference) the prediction overstates the
/// spread 3–13×.
pub fn prediction_limit(model: &PlanModel, setup: usize, n_hits: usize) -> Option<String> {
    let (r, t, d) = model.closest_modes(setup)?;
    let near = rbprops_modal::evidence::NEAR_BANDWIDTHS;
    (n_hits >= 2 && d < near).then(|| {
        let m = &model.setups[setup].modes;
        format!(
            "modes {} ({:.4} Hz) and {} ({:.4} Hz) are {d:.2} half-bandwidths apart (below {near}): modal-fit will refit this set-up with the poly-reference estimator, which the plan does not model; the predicted spreads overstate the pipeline's, several-fold",
            r + 1,
            m[r].frequency_hz,
            t + 1,
            m[t].frequency_hz
        )
    })
}

impl SetupPrediction {
    /// Standard deviation of every property.
    pub fn std(&self) -> [f64; 10] {
        std::array::from_fn(|k| self.cov[(k, k)].max(0.0).sqrt())
    }
}

/// Why a layout cannot determine the properties, with the unobservable combination.
#[derive(Debug, Clone, PartialEq)]
pub struct Unobservable {
    /// One sentence: what is missing and the null vector.
    pub reason: String,
}

/// Null vector of `SᵀS` as words: a rigid motion (translation of the origin `u`,
/// rotation `θ`) no channel sees.
pub fn describe_rigid_motion(v: &Vec6) -> String {
    let u = v.fixed_rows::<3>(0).into_owned();
    let t = v.fixed_rows::<3>(3).into_owned();
    if t.norm() > 1e-6 * u.norm().max(1e-300) && t.norm() > 0.0 {
        // The axis' sense is arbitrary: largest component positive.
        let k = t.iamax();
        let axis = t / t.norm() * t[k].signum();
        let point = t.cross(&u) / t.norm_squared();
        format!(
            "a rotation about the axis through ({:.4}, {:.4}, {:.4}) m along ({:.3}, {:.3}, {:.3}) (null vector of SᵀS: u = ({:.3}, {:.3}, {:.3}), θ = ({:.3}, {:.3}, {:.3}))",
            point.x, point.y, point.z, axis.x, axis.y, axis.z, u.x, u.y, u.z, t.x, t.y, t.z
        )
    } else {
        let d = u / u.norm();
        format!(
            "a translation along ({:.3}, {:.3}, {:.3}) (null vector of SᵀS)",
            d.x, d.y, d.z
        )
    }
}

/// Checks that the channel rows resolve all six rigid motions; otherwise names the
/// unseen motion (the null vector of the information matrix `SᵀS` of a rigid shape).
pub fn check_sensors(rows: &[RowVector6<f64>], length: f64) -> Result<(), Unobservable> {
    // Rotations scaled by the body's length so that the eigenvalues compare.
    let mut g = nalgebra::Matrix6::<f64>::zeros();
    for r in rows {
        let mut s = *r;
        for c in 3..6 {
            s[c] /= length;
        }
        g += s.transpose() * s;
    }
    let eig = g.symmetric_eigen();
    let (kmin, lmin) = eig
        .eigenvalues
        .iter()
        .enumerate()
        .fold(
            (0, f64::INFINITY),
            |a, (k, &l)| if l < a.1 { (k, l) } else { a },
        );
    let lmax = eig.eigenvalues.amax();
    if !(lmin > UNSEEN * lmax) {
        let mut v: Vec6 = eig.eigenvectors.column(kmin).into_owned();
        for c in 3..6 {
            v[c] /= length;
        }
        return Err(Unobservable {
            reason: format!(
                "the sensors cannot resolve the six rigid motions (they lie on one line or are too few): unseen motion: {}",
                describe_rigid_motion(&v)
            ),
        });
    }
    Ok(())
}

/// Prediction of one set-up from its hits' covariances (`data[k]` for `hits[k]`, only the
/// set-up's hits), the channel rows and the estimator. `jacobians` caches `∂p/∂φ` per set
/// of modes used (bit mask).
pub fn predict_setup(
    model: &PlanModel,
    setup: usize,
    rows: &[RowVector6<f64>],
    hits: &[&Hit],
    data: &[&ExcitationCovariance],
    est: Estimator,
    jacobians: &JacobianCache,
) -> Result<SetupPrediction, Unobservable> {
    let modes = &model.setups[setup].modes;
    let nm = modes.len();
    let nc = rows.len();
    check_sensors(rows, model.scales[1])?;
    if hits.is_empty() {
        return Err(Unobservable {
            reason: format!("set-up '{}' has no hit", model.setups[setup].id),
        });
    }
    let cols: Vec<Vec6> = hits.iter().map(|h| h.column()).collect();
    let strength = |k: usize, r: usize| cols[k].dot(&modes[r].shape).powi(2);
    let top = (0..hits.len())
        .flat_map(|k| (0..nm).map(move |r| (k, r)))
        .map(|(k, r)| strength(k, r))
        .fold(0.0, f64::max);
    let mut selected = vec![None; nm];
    for (r, sel) in selected.iter_mut().enumerate() {
        let mut best: Option<usize> = None;
        for k in 0..hits.len() {
            if strength(k, r) > UNEXCITED * top
                && best.is_none_or(|b| data[k].ni[r] > data[b].ni[r])
            {
                best = Some(k);
            }
        }
        *sel = best;
    }
    let used: Vec<usize> = (0..nm).filter(|&r| selected[r].is_some()).collect();
    let missing: Vec<String> = (0..nm)
        .filter(|&r| selected[r].is_none())
        .map(|r| format!("mode {} ({:.3} Hz)", r + 1, modes[r].frequency_hz))
        .collect();
    let mask: u64 = used.iter().map(|&r| 1u64 << r).sum();
    let phi_true: Vec<Vec6> = used.iter().map(|&r| modes[r].shape).collect();
    let jac = jacobians
        .get(est, setup, mask, &phi_true)
        .map_err(|why| Unobservable {
            reason: if missing.is_empty() {
                why
            } else {
                format!(
                    "no hit excites {} ({}): {why}",
                    missing.join(", "),
                    match est {
                        Estimator::BretlConti => "Bretl–Conti needs all six modes",
                        Estimator::ToivolaNuutila => "Toivola–Nuutila with the other modes",
                    }
                )
            },
        })?;
    // (SᵀS)⁻¹Sᵀ
    let mut g = nalgebra::Matrix6::<f64>::zeros();
    for r in rows {
        g += r.transpose() * r;
    }
    let g_inv = g.try_inverse().ok_or_else(|| Unobservable {
        reason: "the sensors cannot resolve the six rigid motions".into(),
    })?;
    let n_used = used.len();
    let mut d_all: Vec<DMatrix<f64>> = Vec::with_capacity(n_used);
    let mut signs = Vec::with_capacity(n_used);
    for &r in &used {
        let k = selected[r].expect("used modes are selected");
        let c = cols[k].dot(&modes[r].shape);
        let q = modes[r].shape * c;
        let s = c * c;
        let proj =
            (nalgebra::Matrix6::<f64>::identity() - q * cols[k].transpose() / (2.0 * s)) / s.sqrt();
        let m = proj * g_inv;
        let mut d = DMatrix::<f64>::zeros(6, nc);
        for (i, row) in rows.iter().enumerate() {
            let col = m * row.transpose();
            for a in 0..6 {
                d[(a, i)] = col[a];
            }
        }
        d_all.push(d);
        signs.push(c.signum());
    }
    // Cov φ̂ (6n × 6n)
    let mut cov_phi = DMatrix::<f64>::zeros(6 * n_used, 6 * n_used);
    for (a, &r) in used.iter().enumerate() {
        for (b, &t) in used.iter().enumerate() {
            let (ka, kb) = (selected[r].unwrap(), selected[t].unwrap());
            if ka != kb {
                continue;
            }
            let c = &data[ka].cov;
            let blk = c.view((r * nc, t * nc), (nc, nc));
            let m = &d_all[a] * blk * d_all[b].transpose();
            cov_phi.view_mut((6 * a, 6 * b), (6, 6)).copy_from(&m);
        }
    }
    // ∂p/∂φ̂ at φ̂_r = sign(c_r) φ_r: the estimators are even in each shape.
    let mut jac = jac.clone();
    for (a, s) in signs.iter().enumerate() {
        for c in 0..6 {
            for k in 0..10 {
                jac[(k, 6 * a + c)] *= s;
            }
        }
    }
    let cov = &jac * cov_phi * jac.transpose();
    let cov = SMatrix::<f64, 10, 10>::from_fn(|r, c| 0.5 * (cov[(r, c)] + cov[(c, r)]));
    Ok(SetupPrediction {
        setup,
        selected_hits: selected,
        cov,
        limit: prediction_limit(model, setup, hits.len()),
    })
}

type CacheEntries = Vec<((Estimator, usize, u64), Result<DMatrix<f64>, String>)>;

/// `∂p/∂φ` per estimator, set-up and set of modes, computed once (thread-safe).
#[derive(Debug, Default)]
pub struct JacobianCache {
    cache: std::sync::Mutex<CacheEntries>,
}

impl JacobianCache {
    /// The Jacobian for set-up `setup` and `mask` (bit r: mode r used) at the true shapes
    /// `phi` (the used modes, in order), computed on first use.
    pub fn get(
        &self,
        est: Estimator,
        setup: usize,
        mask: u64,
        phi: &[Vec6],
    ) -> Result<DMatrix<f64>, String> {
        let key = (est, setup, mask);
        {
            let c = self.cache.lock().expect("jacobian cache");
            if let Some((_, j)) = c.iter().find(|(k, _)| *k == key) {
                return j.clone();
            }
        }
        let j = shape_jacobian(est, phi);
        self.cache
            .lock()
            .expect("jacobian cache")
            .push((key, j.clone()));
        j
    }
}
