//! `sensor_misorientation`: each listed sensor is mounted rotated by a small rotation
//! vector ψ (rad) (docs/physics.md, E8). Its true sensing axes are `R(ψ) s_k`, with
//! `R(ψ) = exp([ψ]×)` (Rodrigues), so channel k reads `(R s_k)ᵀ u(p) = s_kᵀ Rᵀ u(p)`:
//! a triaxial sensor reports its point's motion rotated by `Rᵀ`. Output rows become
//! `(R s_k)ᵀ T(p)`.

use super::{BuildContext, Effect, IdKind, ParamInfo, Vec3MapParam};
use crate::model::DynamicModel;
use crate::spec::CampaignSpec;
use rbprops_core::{rigid_transform, Mat3, Vec3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// `sensor_misorientation`: sensors mounted rotated by a small rotation vector.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorMisorientation {
    /// Rotation vector (rad) per sensor id.
    pub rotations_rad: BTreeMap<String, [f64; 3]>,
}

/// `sensor_misorientation`'s parameter: the rotation vector of each sensor.
const SENSOR_ROTATIONS: Vec3MapParam = Vec3MapParam {
    name: "rotations_rad",
    unit: "rad",
    bound: std::f64::consts::PI,
    plausible: 0.09,
    ids: IdKind::Sensor,
};

/// `exp([ψ]×)` by Rodrigues' formula.
pub fn rotation(psi: &Vec3) -> Mat3 {
    nalgebra::Rotation3::new(*psi).into_inner()
}

impl SensorMisorientation {
    /// The catalogue id (the spec's `id = "sensor_misorientation"`).
    pub const ID: &'static str = "sensor_misorientation";
}

impl Effect for SensorMisorientation {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        SENSOR_ROTATIONS.info(&self.rotations_rad)
    }
    fn values(&self) -> Vec<f64> {
        SENSOR_ROTATIONS.values(&self.rotations_rad)
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let rotations_rad = super::replace_vec3_map(&self.rotations_rad, values)?;
        let e = SensorMisorientation { rotations_rad };
        super::checked(e)
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check_values(&self) -> Result<(), String> {
        for (k, v) in &self.rotations_rad {
            if v.iter().any(|x| !x.is_finite()) || Vec3::from(*v).norm() > std::f64::consts::PI {
                return Err(format!(
                    "rotations_rad.{k}: need a finite rotation vector of at most π rad, got {v:?}"
                ));
            }
        }
        Ok(())
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_values()?;
        SENSOR_ROTATIONS.check_ids(spec, &self.rotations_rad)
    }
    /// The row becomes `(R s)ᵀ T(p)` plus whatever effects applied before it added to the
    /// nominal row `sᵀ T(p)` (a channel gain's `(g − 1) sᵀ T(p)`, a sensor offset's
    /// `−sᵀ [d×]`): so a misorientation at its neutral point leaves the model as it was,
    /// and with both a rotation ψ and such a change the row is right to first order in
    /// each (their product, e.g. ψ·d, is left out, as it is when the offset comes after).
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        for (c, ch) in ctx.geometry.channels.iter().enumerate() {
            if let Some(psi) = self.rotations_rad.get(&ch.point) {
                let s = rotation(&Vec3::from(*psi)) * ch.direction;
                let added = model.outputs[c] - ch.row();
                let rotated = s.transpose() * rigid_transform(&ch.position);
                // Added only when there is something: a model without earlier row changes
                // keeps the rotated row to the bit.
                model.outputs[c] = if added.iter().any(|x| *x != 0.0) {
                    rotated + added
                } else {
                    rotated
                };
            }
        }
        Ok(())
    }
    /// A sensor's rotation reaches its channels' FRFs (their output rows).
    fn parameter_reach(&self, geometry: &rbprops_core::Geometry) -> Vec<super::Reach> {
        super::channel_reach(self.rotations_rad.keys(), 3, geometry, |c| &c.point)
    }
}

/// This module's effects in the physics catalogue ([`super::registry`]).
/// Plausible: each sensor turned by at most 10°. A triaxial accelerometer glued or screwed
/// to a face by hand is aligned to a few degrees; 10° is visible by eye on the set-up.
fn plausible_misorientation(
    entry: &crate::spec::EffectSpec,
    _spec: &CampaignSpec,
) -> Result<Vec<super::Plausible>, String> {
    let e: SensorMisorientation = super::params(entry)?;
    Ok(super::angles_deg("sensor", &e.rotations_rad, 10.0))
}

pub(crate) const DESCRIPTORS: &[super::EffectDescriptor] = &[super::EffectDescriptor {
    id: SensorMisorientation::ID,
    rank: 5,
    title: "sensor misorientation",
    reveal: "a rotation check of each triaxial sensor",
    docs: "E8: a small rotation vector per sensor, `rotations_rad`",
    parse: super::parse_as::<SensorMisorientation>,
    neutral: super::NeutralForm::Table(|spec, _| {
        super::per_sensor_table(spec, "rotations_rad", super::zero3_value())
    }),
    follows_spec_up: false,
    repeatable: false,
    example: include_str!("../../../../fixtures/specs/effects/sensor_misorientation.toml"),
    plausible: Some(plausible_misorientation),
}];
