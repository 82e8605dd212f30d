//! `nonproportional_damping`: viscous dashpots at the suspension attachment points
//! (research note E5), added to the nominal damping:
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
//! `hysteretic_damping`: the loss of rubber mounts and bungee cords (research note E5),
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
use rbprops_core::{rigid_transform, Mat3, Vec3};
use serde::{Deserialize, Serialize};

fn default_axis() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NonproportionalDamping {
    /// Set-up with the dashpots; all set-ups when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub setup: Option<String>,
    /// Axial coefficient (N s/m) per spring, or one value for all.
    pub axial_n_s_per_m: Vec<f64>,
    /// Lateral coefficient (N s/m) per spring, or one value for all (default 0).
    #[serde(default)]
    pub lateral_n_s_per_m: Vec<f64>,
    /// Cord axis (unit vector, geometry frame).
    #[serde(default = "default_axis")]
    pub axis: [f64; 3],
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
    fn check_values(&self) -> Result<(), String> {
        if self.axial_n_s_per_m.is_empty() {
            return Err("axial_n_s_per_m: give one coefficient per spring or one for all".into());
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
        let n = Vec3::from(self.axis).norm();
        if !n.is_finite() || (n - 1.0).abs() > 1e-6 {
            return Err(format!("axis: not a unit vector (|d| = {n:.6})"));
        }
        Ok(())
    }
}

impl Effect for NonproportionalDamping {
    fn id(&self) -> &'static str {
        "nonproportional_damping"
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        let info = |name: String| ParamInfo {
            name,
            unit: "N s/m",
            lower: 0.0,
            upper: f64::INFINITY,
            plausible: (0.0, 20.0),
        };
        (0..self.axial_n_s_per_m.len())
            .map(|i| info(format!("axial_n_s_per_m[{i}]")))
            .chain(
                (0..self.lateral_n_s_per_m.len()).map(|i| info(format!("lateral_n_s_per_m[{i}]"))),
            )
            .collect()
    }
    fn values(&self) -> Vec<f64> {
        self.axial_n_s_per_m
            .iter()
            .chain(&self.lateral_n_s_per_m)
            .copied()
            .collect()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let (axial, lateral) = super::split_values(
            values,
            self.axial_n_s_per_m.len(),
            self.lateral_n_s_per_m.len(),
        )?;
        let e = NonproportionalDamping {
            axial_n_s_per_m: axial.to_vec(),
            lateral_n_s_per_m: lateral.to_vec(),
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
        if self.setup.as_ref().is_some_and(|id| id != &model.setup) {
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
        Ok(())
    }
}

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
}

impl Effect for HystereticDamping {
    fn id(&self) -> &'static str {
        "hysteretic_damping"
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
        e.check_values()?;
        Ok(Box::new(e))
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
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
        if self.setup.as_ref().is_some_and(|id| id != &model.setup) {
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
