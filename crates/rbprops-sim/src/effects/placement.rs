//! Where the sensors and forces really are (docs/physics.md, E9, E12):
//!
//! - `sensor_position`: sensor j sits at `p_j + δp_j`. A row `rᵀ = sᵀT(p)` becomes
//!   `sᵀT(p + δp) = rᵀ + [0 | −sᵀ[δp]×]` (T is affine in p), with `s` the row's current
//!   translational part, so gains and misorientations compose.
//! - `force_direction`: excitation e pushes along `R(β_e) d_e` (β a rotation vector,
//!   `R = exp([β]×)`) through its point p (where `force_location` put it): the column
//!   `[f; p×f]` becomes `[R f; p × R f]`.
//! - `force_location`: excitation e acts at `p_e + δr_e`: the column's moment part
//!   gains `δr × f` (a shift along the force changes nothing).
//!   Both act before the effects at the driving point (order 0), so the two compose
//!   exactly in either order and a gauge's mass or a stinger sits where the force acts,
//!   along the direction it acts (as on the test article).
//! - `force_gauge_mass`: a mass m_b between the force gauge and the structure, moving
//!   with the driving point p (the force's point, moved by `force_location`). The gauge measures `f_g`, the structure receives
//!   `f_g d − m_b ü(p)`, so `Z(s) q = T(p)ᵀ d f_g − s² m_b T(p)ᵀT(p) q`: for that
//!   excitation only the model is `Z(s) + s² m_b T(p)ᵀT(p)` (a point mass present while
//!   it is measured). In terms of the nominal FRFs (Woodbury, tested):
//!   `y = H d + ω² m_b H₃ (I − ω² m_b D)⁻¹ D d`, with H₃ the channels' receptances to unit
//!   forces along x, y, z at p and D the 3×3 driving-point receptance.

use super::{BuildContext, Effect, IdKind, ParamInfo, Vec3MapParam};
use crate::model::DynamicModel;
use crate::spec::CampaignSpec;
use rbprops_core::{cross_matrix, rigid_transform, Vec3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Largest position error accepted (m).
const MAX_OFFSET_M: f64 = 1.0;

/// `sensor_position`'s parameter: the offset of each sensor.
const SENSOR_OFFSETS: Vec3MapParam = Vec3MapParam {
    name: "offsets_m",
    unit: "m",
    bound: MAX_OFFSET_M,
    plausible: 0.005,
    ids: IdKind::Sensor,
};

/// `force_direction`'s parameter: the rotation vector of each excitation's direction.
const FORCE_ROTATIONS: Vec3MapParam = Vec3MapParam {
    name: "rotations_rad",
    unit: "rad",
    bound: std::f64::consts::PI,
    plausible: 0.17,
    ids: IdKind::Excitation,
};

/// `force_location`'s parameter: the offset of each excitation's point.
const FORCE_OFFSETS: Vec3MapParam = Vec3MapParam {
    name: "offsets_m",
    unit: "m",
    bound: MAX_OFFSET_M,
    plausible: 0.005,
    ids: IdKind::Excitation,
};

/// `sensor_position`: sensors not where the geometry says.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorPosition {
    /// Position error δp (m) per sensor id.
    pub offsets_m: BTreeMap<String, [f64; 3]>,
}

impl SensorPosition {
    /// The catalogue id (the spec's `id = "sensor_position"`).
    pub const ID: &'static str = "sensor_position";
}

impl Effect for SensorPosition {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        SENSOR_OFFSETS.info(&self.offsets_m)
    }
    fn values(&self) -> Vec<f64> {
        SENSOR_OFFSETS.values(&self.offsets_m)
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        super::checked(SensorPosition {
            offsets_m: super::replace_vec3_map(&self.offsets_m, values)?,
        })
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check_values(&self) -> Result<(), String> {
        SENSOR_OFFSETS.check_values(&self.offsets_m)
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_values()?;
        SENSOR_OFFSETS.check_ids(spec, &self.offsets_m)
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        for (c, ch) in ctx.geometry.channels.iter().enumerate() {
            if let Some(d) = self.offsets_m.get(&ch.point) {
                let row = &mut model.outputs[c];
                let s = Vec3::new(row[0], row[1], row[2]);
                let dm = -(s.transpose() * cross_matrix(&Vec3::from(*d)));
                for i in 0..3 {
                    row[3 + i] += dm[i];
                }
            }
        }
        Ok(())
    }
    /// A sensor's offset reaches its channels' FRFs (their output rows).
    fn parameter_reach(&self, geometry: &rbprops_core::Geometry) -> Vec<super::Reach> {
        super::channel_reach(self.offsets_m.keys(), 3, geometry, |c| &c.point)
    }
}

/// `force_direction`: forces along rotated directions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForceDirection {
    /// Rotation vector β (rad) of the force direction, per excitation id.
    pub rotations_rad: BTreeMap<String, [f64; 3]>,
}

impl ForceDirection {
    /// The catalogue id (the spec's `id = "force_direction"`).
    pub const ID: &'static str = "force_direction";
}

impl Effect for ForceDirection {
    fn id(&self) -> &'static str {
        Self::ID
    }
    /// Before the effects at the driving point, which read where the force acts.
    fn order(&self) -> u8 {
        0
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        FORCE_ROTATIONS.info(&self.rotations_rad)
    }
    fn values(&self) -> Vec<f64> {
        FORCE_ROTATIONS.values(&self.rotations_rad)
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        super::checked(ForceDirection {
            rotations_rad: super::replace_vec3_map(&self.rotations_rad, values)?,
        })
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check_values(&self) -> Result<(), String> {
        FORCE_ROTATIONS.check_values(&self.rotations_rad)
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_values()?;
        FORCE_ROTATIONS.check_ids(spec, &self.rotations_rad)
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        for input in &mut model.inputs {
            let ex = &ctx.geometry.excitations[input.excitation];
            if let Some(b) = self.rotations_rad.get(&ex.id) {
                let r = super::orientation::rotation(&Vec3::from(*b));
                let f = Vec3::new(input.column[0], input.column[1], input.column[2]);
                let df = r * f - f;
                let dm = input.point.cross(&df);
                for i in 0..3 {
                    input.column[i] += df[i];
                    input.column[3 + i] += dm[i];
                }
                input.direction = r * input.direction;
            }
        }
        Ok(())
    }
    /// An excitation's rotation reaches its FRFs (its input column).
    fn parameter_reach(&self, geometry: &rbprops_core::Geometry) -> Vec<super::Reach> {
        super::excitation_reach(self.rotations_rad.keys(), 3, geometry)
    }
}

/// `force_location`: forces applied away from their nominal points.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForceLocation {
    /// Position error δr (m) of the force point, per excitation id.
    pub offsets_m: BTreeMap<String, [f64; 3]>,
}

impl ForceLocation {
    /// The catalogue id (the spec's `id = "force_location"`).
    pub const ID: &'static str = "force_location";
}

impl Effect for ForceLocation {
    fn id(&self) -> &'static str {
        Self::ID
    }
    /// Before the effects at the driving point, which read where the force acts.
    fn order(&self) -> u8 {
        0
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        FORCE_OFFSETS.info(&self.offsets_m)
    }
    fn values(&self) -> Vec<f64> {
        FORCE_OFFSETS.values(&self.offsets_m)
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        super::checked(ForceLocation {
            offsets_m: super::replace_vec3_map(&self.offsets_m, values)?,
        })
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check_values(&self) -> Result<(), String> {
        FORCE_OFFSETS.check_values(&self.offsets_m)
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_values()?;
        FORCE_OFFSETS.check_ids(spec, &self.offsets_m)
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        for input in &mut model.inputs {
            let ex = &ctx.geometry.excitations[input.excitation];
            if let Some(d) = self.offsets_m.get(&ex.id) {
                let f = Vec3::new(input.column[0], input.column[1], input.column[2]);
                let dm = Vec3::from(*d).cross(&f);
                for i in 0..3 {
                    input.column[3 + i] += dm[i];
                }
                input.point += Vec3::from(*d);
            }
        }
        Ok(())
    }
    /// An excitation's offset reaches its FRFs (its input column).
    fn parameter_reach(&self, geometry: &rbprops_core::Geometry) -> Vec<super::Reach> {
        super::excitation_reach(self.offsets_m.keys(), 3, geometry)
    }
}

/// `force_gauge_mass`: mass between the force gauge and the structure, whose inertia force the gauge does not see.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForceGaugeMass {
    /// Mass below the force gauge (kg), per excitation id.
    pub masses_kg: BTreeMap<String, f64>,
}

impl ForceGaugeMass {
    /// The catalogue id (the spec's `id = "force_gauge_mass"`).
    pub const ID: &'static str = "force_gauge_mass";
}

impl Effect for ForceGaugeMass {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        super::map_info("masses_kg", &self.masses_kg, "kg", (0.0, 0.02))
    }
    fn values(&self) -> Vec<f64> {
        self.masses_kg.values().copied().collect()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let e = ForceGaugeMass {
            masses_kg: super::replace_map(&self.masses_kg, values)?,
        };
        super::checked(e)
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check_values(&self) -> Result<(), String> {
        if self.masses_kg.is_empty() {
            return Err("masses_kg: list at least one excitation".into());
        }
        super::check_non_negative_map("masses_kg", &self.masses_kg)
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_values()?;
        super::check_excitations_defined(spec, "masses_kg", self.masses_kg.keys())
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        for input in &mut model.inputs {
            let ex = &ctx.geometry.excitations[input.excitation];
            if let Some(m) = self.masses_kg.get(&ex.id) {
                let t = rigid_transform(&input.point);
                input.attached_mass += *m * t.transpose() * t;
            }
        }
        Ok(())
    }
    /// A gauge's mass reaches its excitation's FRFs (the input's attached mass).
    fn parameter_reach(&self, geometry: &rbprops_core::Geometry) -> Vec<super::Reach> {
        super::excitation_reach(self.masses_kg.keys(), 1, geometry)
    }
}

/// This module's effects in the physics catalogue ([`super::registry`]).
/// Plausible: each sensor at most 25 mm from where the spec puts it. Positions measured
/// with a rule or from a drawing are good to a few millimetres; 25 mm is about the size of
/// the sensor itself, a misplacement a tester would see.
fn plausible_sensor_position(
    entry: &crate::spec::EffectSpec,
    _spec: &CampaignSpec,
) -> Result<Vec<super::Plausible>, String> {
    let e: SensorPosition = super::params(entry)?;
    Ok(super::offsets_mm("sensor", &e.offsets_m, 25.0))
}

/// Plausible: each force at most 15° off its nominal direction. Hammer blows by hand
/// scatter by 5–10°, a stinger is aligned to a few degrees.
fn plausible_force_direction(
    entry: &crate::spec::EffectSpec,
    _spec: &CampaignSpec,
) -> Result<Vec<super::Plausible>, String> {
    let e: ForceDirection = super::params(entry)?;
    Ok(super::angles_deg("excitation", &e.rotations_rad, 15.0))
}

/// Plausible: each force's line of action at most 25 mm from the spec's point (a hammer
/// tip hits within a few millimetres of a marked point; 25 mm is beyond any marked
/// point). Measured across the force's nominal direction: on a rigid body a force moved
/// along its own line has the same moment (eq. 1's input column `[n; r × n]`), so that
/// component is not seen, and a fit free to slide along it says nothing about where the
/// hammer hit.
fn plausible_force_location(
    entry: &crate::spec::EffectSpec,
    spec: &CampaignSpec,
) -> Result<Vec<super::Plausible>, String> {
    let e: ForceLocation = super::params(entry)?;
    e.offsets_m
        .iter()
        .map(|(k, d)| {
            let x = spec
                .excitations
                .iter()
                .find(|x| x.id == *k)
                .ok_or_else(|| format!("force_location: no excitation '{k}' in the spec"))?;
            let across = across_line(Vec3::from(*d), Vec3::from(x.direction));
            Ok(super::Plausible::new(
                format!("excitation {k}: offset across the force line"),
                "mm",
                1e3 * across,
                [0.0, 25.0],
            ))
        })
        .collect()
}

/// The length of `d`'s component across the line along `n` (`n` need not be a unit).
fn across_line(d: Vec3, n: Vec3) -> f64 {
    let n = n.normalize();
    (d - n * d.dot(&n)).norm()
}

/// Plausible: 0–200 g under each force gauge (a force gauge's structure side with its stud
/// and mounting plate weighs 5–100 g, an impedance head up to about 150 g).
fn plausible_force_gauge_mass(
    entry: &crate::spec::EffectSpec,
    _spec: &CampaignSpec,
) -> Result<Vec<super::Plausible>, String> {
    let e: ForceGaugeMass = super::params(entry)?;
    Ok(e.masses_kg
        .iter()
        .map(|(k, m)| {
            super::Plausible::new(
                format!("excitation {k}: gauge mass"),
                "g",
                1e3 * m,
                [0.0, 200.0],
            )
        })
        .collect())
}

pub(crate) const DESCRIPTORS: &[super::EffectDescriptor] = &[
    super::EffectDescriptor {
        id: SensorPosition::ID,
        rank: 10,
        title: "sensor position error",
        reveal: "a measured sensor layout (or a second sensor layout)",
        docs: "E9: an offset per sensor, `offsets_m`",
        parse: super::parse_as::<SensorPosition>,
        neutral: super::NeutralForm::Table(|spec, _| {
            super::per_sensor_table(spec, "offsets_m", super::zero3_value())
        }),
        follows_spec_up: false,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/sensor_position.toml"),
        plausible: Some(plausible_sensor_position),
    },
    super::EffectDescriptor {
        id: ForceDirection::ID,
        rank: 11,
        title: "force direction error",
        reveal: "more excitations than six, or a force direction check",
        docs: "E12: a small rotation of each excitation's direction, `rotations_rad`",
        parse: super::parse_as::<ForceDirection>,
        neutral: super::NeutralForm::Table(|_, g| {
            super::per_excitation_table(g, "rotations_rad", super::zero3_value())
        }),
        follows_spec_up: false,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/force_direction.toml"),
        plausible: Some(plausible_force_direction),
    },
    super::EffectDescriptor {
        id: ForceLocation::ID,
        rank: 12,
        title: "force location error",
        reveal: "marked impact points, or more excitations than six",
        docs: "E12: an offset of each excitation's point, `offsets_m`",
        parse: super::parse_as::<ForceLocation>,
        neutral: super::NeutralForm::Table(|_, g| {
            super::per_excitation_table(g, "offsets_m", super::zero3_value())
        }),
        follows_spec_up: false,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/force_location.toml"),
        plausible: Some(plausible_force_location),
    },
    super::EffectDescriptor {
        id: ForceGaugeMass::ID,
        rank: 13,
        title: "mass below the force gauge",
        reveal: "a known mass calibration of the hammer or shaker",
        docs: "E12: a mass between the force gauge and the structure per excitation, `masses_kg`, at the point where the force acts (moved by `force_location`; the gauge's mass, a stinger's stiffness and a turned direction compose in any order, since the point and direction effects apply first)",
        parse: super::parse_as::<ForceGaugeMass>,
        neutral: super::NeutralForm::Table(|_, g| {
            super::per_excitation_table(g, "masses_kg", 0.0.into())
        }),
        follows_spec_up: false,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/force_gauge_mass.toml"),
        plausible: Some(plausible_force_gauge_mass),
    },
];

#[cfg(test)]
mod tests {
    use crate::spec::EffectSpec;

    fn offset_entry(ex: &str, d: [f64; 3]) -> EffectSpec {
        let text = format!("id = \"force_location\"\n[offsets_m]\n{ex} = {d:?}\n");
        toml::from_str(&text).expect("entry")
    }

    /// Test Case II's force3 acts along −z at (0.05, 0.16, 0.17): a hit 50 mm along the
    /// line has the nominal moment and is plausible; 30 mm across it is not.
    #[test]
    fn a_force_location_is_judged_across_its_line_of_action() {
        let text = crate::examples::example("test-case-2").expect("example");
        let spec = crate::CampaignSpec::from_toml_str(text).expect("spec");
        let judge = |d| {
            let v = crate::effects::plausibility(&offset_entry("force3", d), &spec).expect("ok");
            assert_eq!(v.len(), 1);
            (v[0].value, v[0].holds())
        };
        let (along, ok) = judge([0.0, 0.0, 0.05]);
        assert!(along.abs() < 1e-12 && ok, "{along}");
        let (across, ok) = judge([0.018, -0.024, 0.05]);
        assert!((across - 30.0).abs() < 1e-9 && !ok, "{across}");
        let (tilted, ok) = judge([0.011, 0.0, -0.049]);
        assert!((tilted - 11.0).abs() < 1e-9 && ok, "{tilted}");
    }
}
