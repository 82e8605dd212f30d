//! `suspension_coupling`: stiffness the springs of the spec leave out (research note
//! E4): per mount a rotational stiffness (bending and torsion of a rubber mount or a
//! clamped cord end), `k_rot` (N m/rad, frame axes). A rotational spring resists the
//! body rotation θ whatever the point it acts at, so
//!
//! `ΔK = Σ_i blockdiag(0₃, diag(k_rot,i))`,
//!
//! and with `lateral_n_per_m` an extra isotropic lateral (⟂ `axis`) stiffness at each
//! attachment point a_i, `ΔK += Σ_i T(a_i)ᵀ k_l,i (I − e eᵀ) T(a_i)` (mount shear).
//!
//! `suspension_drift` (research note E15, non-stationarity between runs): rubber creep
//! or temperature changes the suspension between the excitations' runs. During the run
//! of excitation e the stiffness is `f_e K` (K the set-up's stiffness as built by the
//! effects before it: springs, and the gravity stiffness when listed first), while the
//! damping matrix stays the set-up's: every pole of that run moves by about
//! `Δω_r/ω_r = (f_e − 1)/2`, the residues hardly. A set-up measured in one run cannot
//! show it (its stiffness is what was measured).

use super::{BuildContext, Effect, ParamInfo};
use crate::model::DynamicModel;
use crate::spec::CampaignSpec;
use rbprops_core::{rigid_transform, Mat3, Vec3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

fn default_axis() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SuspensionCoupling {
    /// Set-up of the mounts; all set-ups when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub setup: Option<String>,
    /// Rotational stiffness (N m/rad) about x, y, z, the same at every mount.
    #[serde(default = "zero3")]
    pub rotational_n_m_per_rad: [f64; 3],
    /// Extra lateral stiffness (N/m) ⟂ `axis` at every mount.
    #[serde(default)]
    pub lateral_n_per_m: f64,
    #[serde(default = "default_axis")]
    pub axis: [f64; 3],
}

fn zero3() -> [f64; 3] {
    [0.0; 3]
}

impl SuspensionCoupling {
    fn check_values(&self) -> Result<(), String> {
        if let Some(k) = self
            .rotational_n_m_per_rad
            .iter()
            .chain([&self.lateral_n_per_m])
            .find(|k| !(k.is_finite() && **k >= 0.0))
        {
            return Err(format!("stiffness must be finite and ≥ 0, got {k}"));
        }
        let n = Vec3::from(self.axis).norm();
        if !n.is_finite() || (n - 1.0).abs() > 1e-6 {
            return Err(format!("axis: not a unit vector (|d| = {n:.6})"));
        }
        Ok(())
    }
}

impl Effect for SuspensionCoupling {
    fn id(&self) -> &'static str {
        "suspension_coupling"
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        let mut v: Vec<ParamInfo> = ["x", "y", "z"]
            .iter()
            .map(|a| ParamInfo {
                name: format!("rotational_n_m_per_rad.{a}"),
                unit: "N m/rad",
                lower: 0.0,
                upper: f64::INFINITY,
                plausible: (0.0, 5.0),
            })
            .collect();
        v.push(ParamInfo {
            name: "lateral_n_per_m".into(),
            unit: "N/m",
            lower: 0.0,
            upper: f64::INFINITY,
            plausible: (0.0, 100.0),
        });
        v
    }
    fn values(&self) -> Vec<f64> {
        let r = self.rotational_n_m_per_rad;
        vec![r[0], r[1], r[2], self.lateral_n_per_m]
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let [a, b, c, l] = values else {
            return Err(format!("expected 4 values, got {}", values.len()));
        };
        let e = SuspensionCoupling {
            rotational_n_m_per_rad: [*a, *b, *c],
            lateral_n_per_m: *l,
            ..self.clone()
        };
        e.check_values()?;
        Ok(Box::new(e))
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_values()?;
        super::check_setup(spec, self.setup.as_deref())
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        if self.setup.as_ref().is_some_and(|id| id != &model.setup) {
            return Ok(());
        }
        let e = Vec3::from(self.axis);
        let lateral = self.lateral_n_per_m * (Mat3::identity() - e * e.transpose());
        let krot = Mat3::from_diagonal(&Vec3::from(self.rotational_n_m_per_rad));
        for s in ctx.spec.springs(ctx.setup_index) {
            let t = rigid_transform(&s.at);
            model.stiffness += t.transpose() * lateral * t;
            let mut b = model.stiffness.fixed_view_mut::<3, 3>(3, 3);
            b += krot;
        }
        Ok(())
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SuspensionDrift {
    /// Factor f_e on the set-up's stiffness during excitation e's run; excitations not
    /// listed see the set-up's stiffness.
    pub stiffness_factors: BTreeMap<String, f64>,
}

impl SuspensionDrift {
    fn check_values(&self) -> Result<(), String> {
        match self
            .stiffness_factors
            .iter()
            .find(|(_, f)| !(f.is_finite() && **f > 0.0))
        {
            Some((k, f)) => Err(format!(
                "stiffness_factors.{k}: must be positive and finite, got {f}"
            )),
            None => Ok(()),
        }
    }
}

impl Effect for SuspensionDrift {
    fn id(&self) -> &'static str {
        "suspension_drift"
    }
    /// After the effects that build the stiffness it scales.
    fn order(&self) -> u8 {
        2
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        super::map_info(
            "stiffness_factors",
            &self.stiffness_factors,
            "1",
            (0.95, 1.05),
        )
    }
    fn values(&self) -> Vec<f64> {
        self.stiffness_factors.values().copied().collect()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let e = SuspensionDrift {
            stiffness_factors: super::replace_map(&self.stiffness_factors, values)?,
        };
        e.check_values()?;
        Ok(Box::new(e))
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_values()?;
        super::placement::excitations_exist(
            spec,
            "stiffness_factors",
            self.stiffness_factors.keys().cloned(),
        )
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        for input in &mut model.inputs {
            let id = &ctx.geometry.excitations[input.excitation].id;
            if let Some(f) = self.stiffness_factors.get(id) {
                input.attached_stiffness += (f - 1.0) * model.stiffness;
            }
        }
        Ok(())
    }
}
