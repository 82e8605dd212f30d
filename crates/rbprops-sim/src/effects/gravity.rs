//! `gravity_stiffness`: the pendulum (geometric) stiffness of a cord suspension.
//!
//! Each spring of the set-up is read as a vertical cord: its lower end at the spring's
//! attachment point `a_i`, its upper end at a fixed anchor `a_i + ℓ_i ẑ` (ẑ = `up`), its
//! axial stiffness `k_i = ẑᵀ k ẑ` taken from the spring. Static equilibrium under the
//! weight `W = −m g ẑ` (m, c from the model's current mass matrix, so attached masses
//! count) fixes the tensions: `Σ T_i = m g`, `Σ T_i a_i,h = m g c_h` (horizontal parts).
//! With more than three cords the tensions follow the cords' stiffness (a rigid tilt
//! `T_i = k_i (w0 + w·a_i,h)`, the elastic static solution). Linearising the exact
//! potential (elastic + gravitational) about that equilibrium adds
//!
//! `K_geo = Σ_i T(a_i)ᵀ (T_i/ℓ_i)(I − ẑẑᵀ) T(a_i) + blockdiag(0, K_θθ)`,
//! `K_θθ = −(Σ_i T_i [ẑ]×[a_i]× + [W]×[c]×)`
//!
//! (lateral pendulum stiffness of each cord, and the moments of the tensions and of
//! the weight about arms that rotate with the body; research note E1, Griffis & Duffy).
//! `K_θθ` is symmetric exactly when the moments balance. Checked in the tests against a
//! simple pendulum `ω² = g/ℓ`, the trifilar yaw `ω² = m g ρ²/(ℓ J)` and a
//! finite-difference Hessian of the exact potential.

use super::{BuildContext, Effect, ParamInfo};
use crate::model::DynamicModel;
use crate::spec::CampaignSpec;
use rbprops_core::{cross_matrix, rigid_transform, MassMatrix6, Mat3, Mat6, Vec3};
use serde::{Deserialize, Serialize};

/// Standard gravity (m/s²).
pub const STANDARD_GRAVITY: f64 = 9.80665;

/// Spec parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GravityStiffness {
    /// Set-up whose springs are cords; all set-ups when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub setup: Option<String>,
    /// Cord length per spring (m), or one value for all.
    pub cord_length_m: Vec<f64>,
    #[serde(default = "super::default_g")]
    pub g_m_per_s2: f64,
    /// Upward unit vector in the geometry frame.
    #[serde(default = "super::default_up")]
    pub up: [f64; 3],
}

/// A vertical cord: attachment point, length (m), axial stiffness (N/m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cord {
    pub at: Vec3,
    pub length: f64,
    pub axial_stiffness: f64,
}

/// Equilibrium tensions (N) of vertical cords holding mass `m` with CoM `c`.
pub fn cord_tensions(
    cords: &[Cord],
    m: f64,
    c: &Vec3,
    g: f64,
    up: &Vec3,
) -> Result<Vec<f64>, String> {
    // Horizontal basis ⟂ up.
    let h1 = if up.x.abs() < 0.9 {
        Vec3::x()
    } else {
        Vec3::y()
    };
    let h1 = (h1 - h1.dot(up) * up).normalize();
    let h2 = up.cross(&h1);
    let coord = |p: &Vec3| Vec3::new(1.0, p.dot(&h1), p.dot(&h2));
    // Σ_i k_i coord_i coord_iᵀ w = m g coord(c)
    let mut a = Mat3::zeros();
    for cd in cords {
        let v = coord(&cd.at);
        a += cd.axial_stiffness * v * v.transpose();
    }
    let rhs = m * g * coord(c);
    let w = a
        .svd(true, true)
        .solve(&rhs, 1e-12 * a.norm())
        .map_err(|e| e.to_string())?;
    let t: Vec<f64> = cords
        .iter()
        .map(|cd| cd.axial_stiffness * coord(&cd.at).dot(&w))
        .collect();
    // Equilibrium must hold (fails when the CoM is off the cords' line or plane).
    let mut f = Vec3::zeros();
    for (cd, ti) in cords.iter().zip(&t) {
        f += *ti * coord(&cd.at);
    }
    if (f - rhs).norm() > 1e-9 * rhs.norm() {
        return Err(format!(
            "the cords cannot hold the body in equilibrium (CoM {:?} is not over their support)",
            c.as_slice()
        ));
    }
    for (i, ti) in t.iter().enumerate() {
        if !(*ti > 0.0) {
            return Err(format!(
                "cord {i} at {:?} would be slack (tension {ti:.4} N): the CoM lies outside the cords' support polygon",
                cords[i].at.as_slice()
            ));
        }
    }
    Ok(t)
}

/// The geometric stiffness `K_geo` (see the module docs) and the tensions.
pub fn geometric_stiffness(
    mass: &Mat6,
    cords: &[Cord],
    g: f64,
    up: &Vec3,
) -> Result<(Mat6, Vec<f64>), String> {
    let mm = MassMatrix6(*mass);
    let (m, c) = (mm.mass(), mm.com());
    let t = cord_tensions(cords, m, &c, g, up)?;
    let lateral = Mat3::identity() - up * up.transpose();
    let zx = cross_matrix(up);
    let w = -m * g * up;
    let mut k = Mat6::zeros();
    let mut kth = -(cross_matrix(&w) * cross_matrix(&c));
    for (cd, ti) in cords.iter().zip(&t) {
        let tr = rigid_transform(&cd.at);
        k += tr.transpose() * ((*ti / cd.length) * lateral) * tr;
        kth -= *ti * zx * cross_matrix(&cd.at);
    }
    let asym = (kth - kth.transpose()).norm();
    if asym > 1e-9 * kth.norm().max(f64::MIN_POSITIVE) {
        return Err(format!("moments do not balance (asymmetry {asym:.3e})"));
    }
    let mut block = k.fixed_view_mut::<3, 3>(3, 3);
    block += (kth + kth.transpose()) / 2.0;
    Ok((k, t))
}

impl GravityStiffness {
    fn up(&self) -> Vec3 {
        Vec3::from(self.up)
    }
    fn lengths(&self, n: usize) -> Vec<f64> {
        if self.cord_length_m.len() == 1 {
            vec![self.cord_length_m[0]; n]
        } else {
            self.cord_length_m.clone()
        }
    }
    pub fn check_self(&self) -> Result<(), String> {
        if self.cord_length_m.is_empty() {
            return Err("cord_length_m: give one length per spring or one for all".into());
        }
        if let Some(l) = self
            .cord_length_m
            .iter()
            .find(|l| !(l.is_finite() && **l > 0.0))
        {
            return Err(format!(
                "cord_length_m: lengths must be positive and finite, got {l}"
            ));
        }
        if !(self.g_m_per_s2.is_finite() && self.g_m_per_s2 > 0.0) {
            return Err(format!(
                "g_m_per_s2 must be positive, got {}",
                self.g_m_per_s2
            ));
        }
        let n = self.up().norm();
        if !n.is_finite() || (n - 1.0).abs() > 1e-6 {
            return Err(format!("up: not a unit vector (|d| = {n:.6})"));
        }
        Ok(())
    }
}

impl Effect for GravityStiffness {
    fn id(&self) -> &'static str {
        "gravity_stiffness"
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        super::list_info("cord_length_m", "m", self.cord_length_m.len(), (0.2, 3.0))
    }
    fn values(&self) -> Vec<f64> {
        self.cord_length_m.clone()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let e = GravityStiffness {
            cord_length_m: super::replace_list(self.cord_length_m.len(), values)?,
            ..self.clone()
        };
        e.check_self()?;
        Ok(Box::new(e))
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_self()?;
        for (i, s) in spec.setups.iter().enumerate() {
            if self.setup.as_ref().is_some_and(|id| id != &s.id) {
                continue;
            }
            let n = self.lengths(s.springs.len()).len();
            if n != s.springs.len() {
                return Err(format!(
                    "cord_length_m has {n} lengths but set-up '{}' (setup[{i}]) has {} springs",
                    s.id,
                    s.springs.len()
                ));
            }
        }
        if let Some(id) = &self.setup {
            if !spec.setups.iter().any(|s| &s.id == id) {
                return Err(format!("set-up '{id}' is not defined"));
            }
        }
        Ok(())
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        if self.setup.as_ref().is_some_and(|id| id != &model.setup) {
            return Ok(());
        }
        let springs = ctx.spec.springs(ctx.setup_index);
        let up = self.up();
        let cords: Vec<Cord> = springs
            .iter()
            .zip(self.lengths(springs.len()))
            .map(|(s, l)| Cord {
                at: s.at,
                length: l,
                axial_stiffness: (up.transpose() * s.stiffness * up)[0],
            })
            .collect();
        if let Some(i) = cords.iter().position(|c| !(c.axial_stiffness > 0.0)) {
            return Err(format!(
                "set-up '{}': spring {i} has no stiffness along `up`, so it cannot be a cord",
                model.setup
            ));
        }
        let (k, _) = geometric_stiffness(&model.mass, &cords, self.g_m_per_s2, &up)
            .map_err(|e| format!("set-up '{}': {e}", model.setup))?;
        model.stiffness += k;
        Ok(())
    }
}
