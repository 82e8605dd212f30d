//! `sensor_mass`: point masses at sensor points (accelerometers, cable share).
//!
//! `ΔM = Σ_j m_j T(p_j)ᵀ T(p_j)` (research note E7): a point mass at `p_j` adds kinetic
//! energy `½ m_j |T(p_j) q̇|²`. The truth properties stay those of the bare body.

use super::{BuildContext, Effect, ParamInfo};
use crate::model::DynamicModel;
use crate::spec::CampaignSpec;
use rbprops_core::{rigid_transform, Vec3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorMass {
    /// Same mass (kg) on every sensor.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass_kg: Option<f64>,
    /// Mass (kg) per sensor id; overrides `mass_kg` for the sensors listed.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub masses_kg: BTreeMap<String, f64>,
}

impl SensorMass {
    /// Sensor ids and masses, in sensor order (sensors without a mass are skipped).
    fn masses(&self, spec: &CampaignSpec) -> Vec<(String, Vec3, f64)> {
        spec.sensors
            .iter()
            .filter_map(|s| {
                let m = self.masses_kg.get(&s.id).copied().or(self.mass_kg)?;
                Some((s.id.clone(), Vec3::from(s.at_m), m))
            })
            .collect()
    }
    fn all(&self) -> Vec<f64> {
        self.mass_kg
            .iter()
            .chain(self.masses_kg.values())
            .copied()
            .collect()
    }
}

impl Effect for SensorMass {
    fn id(&self) -> &'static str {
        "sensor_mass"
    }
    fn order(&self) -> u8 {
        0
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        let mut v: Vec<ParamInfo> = self
            .mass_kg
            .iter()
            .map(|_| "mass_kg".to_string())
            .chain(self.masses_kg.keys().map(|k| format!("masses_kg.{k}")))
            .map(|name| ParamInfo {
                name,
                unit: "kg",
                lower: 0.0,
                upper: f64::INFINITY,
                plausible: (0.001, 0.05),
            })
            .collect();
        v.shrink_to_fit();
        v
    }
    fn values(&self) -> Vec<f64> {
        self.all()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let n = self.all().len();
        if values.len() != n {
            return Err(format!("expected {n} values, got {}", values.len()));
        }
        let mut e = self.clone();
        let mut it = values.iter();
        if e.mass_kg.is_some() {
            e.mass_kg = it.next().copied();
        }
        for v in e.masses_kg.values_mut() {
            *v = *it.next().unwrap();
        }
        e.check_values()?;
        Ok(Box::new(e))
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_values()?;
        for id in self.masses_kg.keys() {
            if !spec.sensors.iter().any(|s| &s.id == id) {
                return Err(format!("masses_kg: sensor '{id}' is not defined"));
            }
        }
        Ok(())
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        for (_, p, m) in self.masses(ctx.spec) {
            let t = rigid_transform(&p);
            model.mass += m * t.transpose() * t;
        }
        Ok(())
    }
}

impl SensorMass {
    fn check_values(&self) -> Result<(), String> {
        if self.mass_kg.is_none() && self.masses_kg.is_empty() {
            return Err("give mass_kg (all sensors) and/or masses_kg (per sensor)".into());
        }
        if let Some(m) = self.all().iter().find(|m| !(m.is_finite() && **m >= 0.0)) {
            return Err(format!("sensor masses must be finite and ≥ 0, got {m}"));
        }
        Ok(())
    }
}
