//! `nonproportional_damping`: viscous dashpots at the suspension attachment points
//! (docs/physics.md, E5), added to the nominal damping:
//!
//! `ΔC = Σ_i T(a_i)ᵀ [c_a,i e eᵀ + c_l,i (I − e eᵀ)] T(a_i)`
//!
//! with `a_i` the spring attachment points of the set-up, `e` the cord axis (`axis`,
//! default +z), `c_a` axial and `c_l` lateral damping coefficients (N s/m). A dashpot
//! dissipates `½ q̇ᵀ T(a)ᵀ c T(a) q̇`, hence the form. In general `ΦᵀΔCΦ` is not diagonal:
//! the modes become complex (checked against a state-space eigen-solution in the tests),
//! and the simulator's modal solve refuses the model; the truth record's damping ratios
//! are then the diagonal approximation `φ_rᵀCφ_r/(2ω_r)`.
//!
//! General viscous damping (`modal_coupling`, 15 values): the damping C of the model so
//! far (the nominal modal or proportional damping plus the dashpots above) is read in
//! the mass-normalised undamped modes Φ of (M, K) (ΦᵀMΦ = I, so C = MΦ C_m ΦᵀM), its
//! modal diagonal `d_r = φ_rᵀCφ_r = 2ζ_rω_r` kept, and the modes coupled:
//!
//! `C' = C + MΦ D^{1/2} (R(N) − I) D^{1/2} ΦᵀM`, `R(N) = ℓℓᵀ`, `ℓ_i = L_i/|L_i|`,
//! `L = I + N` (N strictly lower triangular, the 15 values row by row).
//!
//! R(N) is a correlation matrix (unit diagonal, positive semi-definite: a Gram matrix of
//! unit vectors), so for classical C the result `MΦ D^{1/2} R D^{1/2} ΦᵀM` is positive
//! semi-definite by construction, and every positive definite 6×6 C is reached (R's
//! Cholesky factor L_R has rows of unit norm; `N = diag(L_R)⁻¹ L_R − I`,
//! [`modal_coupling_of`]). With the six modal ratios ζ_r this is the general viscous
//! damping a rigid body shows: 6 + 15 = 21 numbers, the symmetric 6×6 C. Point dashpots
//! with full 3×3 matrices at the mounts, `C = Σ_i T(a_i)ᵀ C_i T(a_i)`, are one such C,
//! but not an identifiable parametrisation of it (6 numbers per mount, 24 or more for
//! four mounts, onto at most 21). At N = 0 the change is `D^{1/2}(N + Nᵀ)D^{1/2}` to
//! first order: a score test sees it. The modes' sign convention (largest component
//! positive) makes R continuous in (M, K) except where modes cross.
//!
//! `hysteretic_damping`: the loss of rubber mounts and bungee cords (docs/physics.md, E5),
//! a loss factor η_i per spring, frequency-independent:
//!
//! `D = Σ_i η_i T(a_i)ᵀ k_i T(a_i)`, in `Z(ω) = K + iD + iωC − ω²M`,
//!
//! so spring i's stiffness is `k_i(1 + iη_i)`. A suspension mode r gets the equivalent
//! ratio `ζ_r ≈ φ_rᵀDφ_r/(2ω_r²)` at resonance; off resonance the loss is constant in
//! frequency where a dashpot's grows as ω, and loss factors that differ between
//! mounts make the modes complex. Rubber: η 0.05–0.2.

use super::{BuildContext, Effect, ParamInfo};
use crate::model::DynamicModel;
use crate::spec::CampaignSpec;
use crate::suspension::spring_stiffness;
use rbprops_core::{rigid_body_modes, rigid_transform, Mat3, Mat6, Vec3};
use serde::{Deserialize, Serialize};

fn default_axis() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

/// `nonproportional_damping`: viscous dashpots at the suspension attachment points (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NonproportionalDamping {
    /// Set-up with the dashpots; all set-ups when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub setup: Option<String>,
    /// Axial coefficient (N s/m) per spring, or one value for all.
    #[serde(default)]
    pub axial_n_s_per_m: Vec<f64>,
    /// Lateral coefficient (N s/m) per spring, or one value for all (default 0).
    #[serde(default)]
    pub lateral_n_s_per_m: Vec<f64>,
    /// Cord axis (unit vector, geometry frame).
    #[serde(default = "default_axis")]
    pub axis: [f64; 3],
    /// Coupling of the undamped modes by the damping: the 15 values of the strictly lower
    /// triangle of N, row by row ((1,0), (2,0), (2,1), (3,0), …), see the module docs;
    /// empty: none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub modal_coupling: Vec<f64>,
}

/// Number of modal coupling values (the strict lower triangle of a 6×6 matrix).
pub const MODAL_COUPLINGS: usize = 15;

/// The correlation matrix `R(N) = ℓℓᵀ`, `ℓ_i = L_i/|L_i|`, `L = I + N` (module docs).
pub fn coupling_correlation(lower: &[f64]) -> Result<Mat6, String> {
    if lower.len() != MODAL_COUPLINGS {
        return Err(format!(
            "modal_coupling: expected {MODAL_COUPLINGS} values, got {}",
            lower.len()
        ));
    }
    let mut l = Mat6::identity();
    let mut k = 0;
    for i in 1..6 {
        for j in 0..i {
            l[(i, j)] = lower[k];
            k += 1;
        }
    }
    for i in 0..6 {
        let n = l.row(i).norm();
        l.row_mut(i).unscale_mut(n);
    }
    Ok(l * l.transpose())
}

/// General viscous damping: `C' = C + MΦ D^{1/2}(R(N) − I)D^{1/2} ΦᵀM` with Φ the
/// mass-normalised undamped modes of (M, K) and `D = diag(φ_rᵀCφ_r)` (module docs).
pub fn coupled_damping(
    mass: &Mat6,
    stiffness: &Mat6,
    damping: &Mat6,
    lower: &[f64],
) -> Result<Mat6, String> {
    let r = coupling_correlation(lower)?;
    let modes = rigid_body_modes(mass, stiffness).map_err(|e| e.to_string())?;
    let phi = Mat6::from_columns(&modes.iter().map(|m| m.1).collect::<Vec<_>>());
    let d = (phi.transpose() * damping * phi).diagonal();
    // An undamped mode (a free direction, a hanging body's pendulum) comes out of the
    // product as ±1e-17 rounding: only a negative value beyond the rounding of the
    // largest modal damping is an error.
    let rounding = 1e-12 * d.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if let Some(x) = d.iter().find(|x| !(**x >= -rounding)) {
        return Err(format!(
            "modal_coupling: a mode has negative damping φᵀCφ = {x:e}"
        ));
    }
    let sd = d.map(|x| x.max(0.0).sqrt());
    let mut cm = r - Mat6::identity();
    for i in 0..6 {
        for j in 0..6 {
            cm[(i, j)] *= sd[i] * sd[j];
        }
    }
    let mp = mass * phi;
    let out = damping + mp * cm * mp.transpose();
    Ok((out + out.transpose()) * 0.5)
}

/// The inverse of [`coupled_damping`] for a positive definite C: the modal couplings N
/// whose correlation matrix is `R = D^{-1/2} ΦᵀCΦ D^{-1/2}` (Cholesky `R = L_R L_Rᵀ`,
/// `N = diag(L_R)⁻¹ L_R − I`). For tests and for reading a fitted C back.
pub fn modal_coupling_of(
    mass: &Mat6,
    stiffness: &Mat6,
    damping: &Mat6,
) -> Result<Vec<f64>, String> {
    let modes = rigid_body_modes(mass, stiffness).map_err(|e| e.to_string())?;
    let phi = Mat6::from_columns(&modes.iter().map(|m| m.1).collect::<Vec<_>>());
    let cm = phi.transpose() * damping * phi;
    let sd = cm.diagonal().map(|x| x.max(0.0).sqrt());
    let mut r = cm;
    for i in 0..6 {
        for j in 0..6 {
            r[(i, j)] /= sd[i] * sd[j];
        }
    }
    let l = r
        .cholesky()
        .ok_or("the damping is not positive definite in the modes")?
        .l();
    let mut out = Vec::with_capacity(MODAL_COUPLINGS);
    for i in 1..6 {
        for j in 0..i {
            out.push(l[(i, j)] / l[(i, i)]);
        }
    }
    Ok(out)
}

fn per_spring(v: &[f64], n: usize) -> Vec<f64> {
    match v.len() {
        0 => vec![0.0; n],
        1 => vec![v[0]; n],
        _ => v.to_vec(),
    }
}

/// Checks that the set-up exists and that each per-spring list (name, length) has one
/// value for all springs or one per spring of every set-up it applies to.
fn per_spring_lists_fit(
    spec: &CampaignSpec,
    setup: Option<&str>,
    lists: &[(&str, usize)],
) -> Result<(), String> {
    super::check_setup(spec, setup)?;
    for (i, s) in spec.setups.iter().enumerate() {
        if setup.is_some_and(|id| id != s.id) {
            continue;
        }
        for &(what, n) in lists {
            if n > 1 && n != s.springs.len() {
                return Err(format!(
                    "{what} has {n} values but set-up '{}' (setup[{i}]) has {} springs",
                    s.id,
                    s.springs.len()
                ));
            }
        }
    }
    Ok(())
}

impl NonproportionalDamping {
    /// The catalogue id (the spec's `id = "nonproportional_damping"`).
    pub const ID: &'static str = "nonproportional_damping";
}

impl Effect for NonproportionalDamping {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        let info = |name: String| super::positive_info(name, "N s/m", (0.0, 20.0));
        (0..self.axial_n_s_per_m.len())
            .map(|i| info(format!("axial_n_s_per_m[{i}]")))
            .chain(
                (0..self.lateral_n_s_per_m.len()).map(|i| info(format!("lateral_n_s_per_m[{i}]"))),
            )
            .chain(
                modal_coupling_names(self.modal_coupling.len())
                    .map(|name| super::unbounded_info(name, "1", (-1.0, 1.0))),
            )
            .collect()
    }
    fn values(&self) -> Vec<f64> {
        self.axial_n_s_per_m
            .iter()
            .chain(&self.lateral_n_s_per_m)
            .chain(&self.modal_coupling)
            .copied()
            .collect()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let na = self.axial_n_s_per_m.len();
        let (dashpots, coupling) = super::split_values(
            values,
            na + self.lateral_n_s_per_m.len(),
            self.modal_coupling.len(),
        )?;
        let (axial, lateral) = dashpots.split_at(na);
        let e = NonproportionalDamping {
            axial_n_s_per_m: axial.to_vec(),
            lateral_n_s_per_m: lateral.to_vec(),
            modal_coupling: coupling.to_vec(),
            ..self.clone()
        };
        super::checked(e)
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check_values(&self) -> Result<(), String> {
        if self.axial_n_s_per_m.is_empty() && self.modal_coupling.is_empty() {
            return Err(
                "axial_n_s_per_m: give one coefficient per spring or one for all (or modal_coupling)"
                    .into(),
            );
        }
        if !self.modal_coupling.is_empty() && self.modal_coupling.len() != MODAL_COUPLINGS {
            return Err(format!(
                "modal_coupling: give {MODAL_COUPLINGS} values (the strict lower triangle, row by row), got {}",
                self.modal_coupling.len()
            ));
        }
        if let Some((i, c)) = self
            .modal_coupling
            .iter()
            .enumerate()
            .find(|(_, c)| !c.is_finite())
        {
            return Err(format!("modal_coupling[{i}]: must be finite, got {c}"));
        }
        for (what, v) in [
            ("axial_n_s_per_m", &self.axial_n_s_per_m),
            ("lateral_n_s_per_m", &self.lateral_n_s_per_m),
        ] {
            if let Some((i, c)) = v
                .iter()
                .enumerate()
                .find(|(_, c)| !(c.is_finite() && **c >= 0.0))
            {
                return Err(format!("{what}[{i}]: must be finite and ≥ 0, got {c}"));
            }
        }
        super::check_unit_vector("axis", self.axis)
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_values()?;
        per_spring_lists_fit(
            spec,
            self.setup.as_deref(),
            &[
                ("axial_n_s_per_m", self.axial_n_s_per_m.len()),
                ("lateral_n_s_per_m", self.lateral_n_s_per_m.len()),
            ],
        )
    }
    fn modify_damping(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        if !super::acts_in_setup(self.setup.as_deref(), &model.setup) {
            return Ok(());
        }
        let springs = ctx.spec.springs(ctx.setup_index);
        let e = Vec3::from(self.axis);
        let axial = e * e.transpose();
        let lateral = Mat3::identity() - axial;
        let ca = per_spring(&self.axial_n_s_per_m, springs.len());
        let cl = per_spring(&self.lateral_n_s_per_m, springs.len());
        for ((s, a), l) in springs.iter().zip(ca).zip(cl) {
            let t = rigid_transform(&s.at);
            model.damping += t.transpose() * (a * axial + l * lateral) * t;
        }
        if !self.modal_coupling.is_empty() {
            model.damping = coupled_damping(
                &model.mass,
                &model.stiffness,
                &model.damping,
                &self.modal_coupling,
            )?;
        }
        Ok(())
    }
}

/// Names of the modal coupling values: `modal_coupling[i,j]`, modes i > j (ascending).
fn modal_coupling_names(n: usize) -> impl Iterator<Item = String> {
    (1..6)
        .flat_map(|i| (0..i).map(move |j| format!("modal_coupling[{i},{j}]")))
        .take(n)
}

/// `hysteretic_damping`: structural (loss-factor) damping of the suspension mounts (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HystereticDamping {
    /// Set-up with the lossy mounts; all set-ups when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub setup: Option<String>,
    /// Loss factor η per spring, or one value for all.
    pub loss_factors: Vec<f64>,
}

impl HystereticDamping {
    /// The catalogue id (the spec's `id = "hysteretic_damping"`).
    pub const ID: &'static str = "hysteretic_damping";
}

impl Effect for HystereticDamping {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        (0..self.loss_factors.len())
            .map(|i| ParamInfo {
                name: format!("loss_factors[{i}]"),
                unit: "1",
                lower: 0.0,
                upper: 2.0,
                plausible: (0.0, 0.2),
            })
            .collect()
    }
    fn values(&self) -> Vec<f64> {
        self.loss_factors.clone()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let e = HystereticDamping {
            loss_factors: super::replace_list(self.loss_factors.len(), values)?,
            ..self.clone()
        };
        super::checked(e)
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check_values(&self) -> Result<(), String> {
        if self.loss_factors.is_empty() {
            return Err("loss_factors: give one loss factor per spring or one for all".into());
        }
        match self
            .loss_factors
            .iter()
            .enumerate()
            .find(|(_, e)| !(e.is_finite() && (0.0..=2.0).contains(*e)))
        {
            Some((i, e)) => Err(format!("loss_factors[{i}]: must be in [0, 2], got {e}")),
            None => Ok(()),
        }
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_values()?;
        per_spring_lists_fit(
            spec,
            self.setup.as_deref(),
            &[("loss_factors", self.loss_factors.len())],
        )
    }
    fn modify_damping(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        if !super::acts_in_setup(self.setup.as_deref(), &model.setup) {
            return Ok(());
        }
        let springs = ctx.spec.springs(ctx.setup_index);
        let eta = per_spring(&self.loss_factors, springs.len());
        for (s, e) in springs.iter().zip(eta) {
            model.structural_damping += e * spring_stiffness(s);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rbprops_core::{RigidBodyProperties, Vec6};

    /// Test Case II's body on four anisotropic springs, and point dashpots with full
    /// 3×3 matrices at the mounts (an independent way to write a general PSD C).
    fn body() -> (Mat6, Mat6, Mat6) {
        let p = RigidBodyProperties::from_moments_and_products(
            15.69,
            Vec3::new(0.17725, 0.0304, -0.00535),
            [0.35733194, 0.39469014, 0.31706832],
            rbprops_core::inertia::ProductsOfInertia {
                xy: 0.07722671,
                xz: -0.08736156,
                yz: -0.06919817,
            },
        );
        let m = p.mass_matrix().0;
        let at = [
            Vec3::new(0.02, -0.13, 0.17),
            Vec3::new(0.34, -0.13, 0.17),
            Vec3::new(0.02, 0.20, 0.17),
            Vec3::new(0.34, 0.20, 0.17),
        ];
        let k3 = Mat3::from_diagonal(&Vec3::new(150.0, 220.0, 2500.0));
        let c3 = [
            Mat3::new(2.0, 0.8, 0.0, 0.8, 1.5, 0.3, 0.0, 0.3, 9.0),
            Mat3::new(1.0, 0.0, 0.4, 0.0, 3.0, 0.0, 0.4, 0.0, 4.0),
            Mat3::from_diagonal(&Vec3::new(3.0, 1.0, 12.0)),
            Mat3::new(1.5, -0.5, 0.0, -0.5, 2.5, 0.6, 0.0, 0.6, 6.0),
        ];
        let (mut k, mut c) = (Mat6::zeros(), Mat6::zeros());
        for (a, ci) in at.iter().zip(&c3) {
            let t = rigid_transform(a);
            k += t.transpose() * k3 * t;
            c += t.transpose() * ci * t;
        }
        (m, k, c)
    }

    fn modal_classical(m: &Mat6, k: &Mat6, c: &Mat6) -> Mat6 {
        // The classical part of C: its modal diagonal only.
        let modes = rigid_body_modes(m, k).unwrap();
        let phi = Mat6::from_columns(&modes.iter().map(|x| x.1).collect::<Vec<Vec6>>());
        let d = Mat6::from_diagonal(&(phi.transpose() * c * phi).diagonal());
        m * phi * d * phi.transpose() * m
    }

    /// Any positive definite C (here from point dashpots) is its classical part coupled
    /// by the N that `modal_coupling_of` reads from it: the round trip is exact to
    /// rounding (1e-12 of |C|).
    #[test]
    fn point_dashpots_are_a_classical_damping_coupled_by_n() {
        let (m, k, c) = body();
        let n = modal_coupling_of(&m, &k, &c).unwrap();
        let back = coupled_damping(&m, &k, &modal_classical(&m, &k, &c), &n).unwrap();
        let err = (back - c).abs().max() / c.abs().max();
        assert!(err < 1e-12, "relative error {err:e}");
        // N = 0 changes nothing; the correlation has a unit diagonal and is PSD.
        let c0 = modal_classical(&m, &k, &c);
        let same = coupled_damping(&m, &k, &c0, &[0.0; 15]).unwrap();
        assert!((same - c0).abs().max() <= 1e-14 * c0.abs().max());
    }

    /// An undamped mode whose modal damping comes out as −1e-17 rounding (a hanging
    /// body's pendulum on undamped cords) is accepted as undamped; a mode with damping
    /// clearly below zero is still refused.
    #[test]
    fn an_undamped_mode_is_not_refused_for_its_rounding() {
        let (m, k, c) = body();
        let c0 = modal_classical(&m, &k, &c);
        let modes = rigid_body_modes(&m, &k).unwrap();
        let phi0 = modes[0].1;
        let mp = m * phi0;
        let strip = |x: f64| c0 - mp * mp.transpose() * ((phi0.transpose() * c0 * phi0)[0] + x);
        let n = vec![0.2; MODAL_COUPLINGS];
        let scale = c0.abs().max();
        assert!(coupled_damping(&m, &k, &strip(1e-17 * scale), &n).is_ok());
        assert!(coupled_damping(&m, &k, &strip(1e-3 * scale), &n).is_err());
    }

    /// PSD by construction: for large arbitrary N, every eigenvalue of C' is ≥ −1e-12 of
    /// the largest, and the modal diagonal (the damping ratios) is unchanged.
    #[test]
    fn coupled_damping_is_positive_semidefinite_and_keeps_the_ratios() {
        let (m, k, c) = body();
        let c0 = modal_classical(&m, &k, &c);
        let n: Vec<f64> = (0..15).map(|i| 3.0 * ((i as f64) * 1.7).sin()).collect();
        let c1 = coupled_damping(&m, &k, &c0, &n).unwrap();
        let ev = c1.symmetric_eigen().eigenvalues;
        assert!(ev.min() >= -1e-12 * ev.max(), "eigenvalues {ev}");
        let r = coupling_correlation(&n).unwrap();
        for i in 0..6 {
            assert!((r[(i, i)] - 1.0).abs() < 1e-15);
        }
        let modes = rigid_body_modes(&m, &k).unwrap();
        for (_, phi) in &modes {
            let (a, b) = (
                (phi.transpose() * c0 * phi)[0],
                (phi.transpose() * c1 * phi)[0],
            );
            assert!((a - b).abs() < 1e-12 * a, "{a} vs {b}");
        }
    }

    /// First order at N = 0: ∂C'/∂N_ij = MΦ √(d_i d_j)(E_ij + E_ji) ΦᵀM, so a score test
    /// sees each coupling (central difference, h = 1e-6: error O(h²) relative).
    #[test]
    fn coupling_has_a_first_order_signature_at_zero() {
        let (m, k, c) = body();
        let c0 = modal_classical(&m, &k, &c);
        let modes = rigid_body_modes(&m, &k).unwrap();
        let phi = Mat6::from_columns(&modes.iter().map(|x| x.1).collect::<Vec<Vec6>>());
        let d = (phi.transpose() * c0 * phi).diagonal();
        let h = 1e-6;
        let mut idx = 0;
        for i in 1..6 {
            for j in 0..i {
                let mut np = [0.0; 15];
                np[idx] = h;
                let mut nm = [0.0; 15];
                nm[idx] = -h;
                let dc = (coupled_damping(&m, &k, &c0, &np).unwrap()
                    - coupled_damping(&m, &k, &c0, &nm).unwrap())
                    / (2.0 * h);
                let mut e = Mat6::zeros();
                e[(i, j)] = (d[i] * d[j]).sqrt();
                e[(j, i)] = e[(i, j)];
                let want = m * phi * e * phi.transpose() * m;
                let err = (dc - want).abs().max() / want.abs().max();
                assert!(err < 1e-8, "({i},{j}): {err:e}");
                idx += 1;
            }
        }
    }
}

/// One zero per spring of the set-ups (one in all when set-ups differ in spring count:
/// a coefficient per spring is then not one list for every set-up).
fn per_spring_zeros(spec: &CampaignSpec) -> toml::Value {
    let counts: Vec<usize> = spec.setups.iter().map(|s| s.springs.len()).collect();
    let n = match counts.first() {
        Some(&n) if n > 0 && counts.iter().all(|&c| c == n) => n,
        _ => 1,
    };
    toml::Value::Array(vec![0.0.into(); n])
}

/// This module's effects in the physics catalogue ([`super::registry`]).
/// Plausible: loss factors of at most 0.3 per spring. Metal springs and bungee cords lose
/// a few percent per cycle (η 0.01–0.1), the most dissipative rubber mounts about 0.2–0.3.
fn plausible_hysteretic(
    entry: &crate::spec::EffectSpec,
    _spec: &CampaignSpec,
) -> Result<Vec<super::Plausible>, String> {
    let e: HystereticDamping = super::params(entry)?;
    Ok(e.loss_factors
        .iter()
        .enumerate()
        .map(|(i, eta)| {
            super::Plausible::new(format!("spring {i}: loss factor"), "1", *eta, [0.0, 0.3])
        })
        .collect())
}

pub(crate) const DESCRIPTORS: &[super::EffectDescriptor] = &[
    super::EffectDescriptor {
        id: NonproportionalDamping::ID,
        rank: 7,
        title: "non-proportional damping at the suspension",
        reveal: "a second record length or window (separates processing damping)",
        docs: "E5: dashpots at the mounts and the general viscous damping `modal_coupling` (15 values)",
        parse: super::parse_as::<NonproportionalDamping>,
        neutral: super::NeutralForm::Table(|_, _| super::table([("modal_coupling", toml::Value::Array(vec![0.0.into(); MODAL_COUPLINGS]))])),
        follows_spec_up: false,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/nonproportional_damping.toml"),
        plausible: None,
    },
    super::EffectDescriptor {
        id: HystereticDamping::ID,
        rank: 22,
        title: "hysteretic (loss-factor) damping of the mounts (rubber, bungee)",
        reveal: "data well below the suspension modes (a loss constant in frequency, where a dashpot's vanishes), or the mounts' measured loss factors",
        docs: "E5: a loss factor per spring, `loss_factors`",
        parse: super::parse_as::<HystereticDamping>,
        neutral: super::NeutralForm::Table(|spec, _| super::table([("loss_factors", per_spring_zeros(spec))])),
        follows_spec_up: false,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/hysteretic_damping.toml"),
        plausible: Some(plausible_hysteretic),
    },
];
