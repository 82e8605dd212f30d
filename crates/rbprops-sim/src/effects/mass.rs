//! `sensor_mass`: point masses at sensor points (accelerometers, cable share).
//!
//! `ΔM = Σ_j m_j T(p_j)ᵀ T(p_j)` (docs/physics.md, E7): a point mass at `p_j` adds kinetic
//! energy `½ m_j |T(p_j) q̇|²`. The truth properties stay those of the bare body.
//!
//! `added_mass` (docs/physics.md, E15: air added mass of large light panels, fluid
//! sloshing at low frequency): a symmetric 6×6 mass about O, `M += M_a` with
//! `M_a = [[A, B], [Bᵀ, C]]`, A and C symmetric. Unlike a rigid body's (or a point
//! mass's) it need not have the rigid structure `A = m I`, `B = −m[c]×`: potential
//! flow adds mass only normal to a large face, about `(8/3)ρR³` for a disc of radius
//! R. Its rigid-structured part is what a free inertia absorbs; the rest (11 of its 21
//! entries) is what a 21-parameter mass sees beyond a 10-parameter rigid one.

use super::screening::{Screened, ScreeningForm, ScreeningKind, ScreeningResult};
use super::{BuildContext, Effect, ParamInfo};
use crate::model::DynamicModel;
use crate::spec::CampaignSpec;
use rbprops_core::{rigid_transform, Mat3, Vec3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// `sensor_mass`: point masses at the sensor points, `ΔM = Σ m_j T(p_j)ᵀ T(p_j)`.
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
        super::common_and_map_values(self.mass_kg, &self.masses_kg)
    }
}

impl SensorMass {
    /// The catalogue id (the spec's `id = "sensor_mass"`).
    pub const ID: &'static str = "sensor_mass";
}

impl Effect for SensorMass {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn order(&self) -> u8 {
        0
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        super::common_and_map_info(
            "mass_kg",
            self.mass_kg,
            "masses_kg",
            &self.masses_kg,
            "kg",
            (0.001, 0.05),
        )
    }
    fn values(&self) -> Vec<f64> {
        self.all()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let (mass_kg, masses_kg) =
            super::replace_common_and_map(self.mass_kg, &self.masses_kg, values)?;
        let e = SensorMass { mass_kg, masses_kg };
        super::checked(e)
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check_values(&self) -> Result<(), String> {
        if self.mass_kg.is_none() && self.masses_kg.is_empty() {
            return Err("give mass_kg (all sensors) and/or masses_kg (per sensor)".into());
        }
        if let Some(m) = self.all().iter().find(|m| !(m.is_finite() && **m >= 0.0)) {
            return Err(format!("sensor masses must be finite and ≥ 0, got {m}"));
        }
        Ok(())
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_values()?;
        super::check_sensors_defined(spec, "masses_kg", self.masses_kg.keys())
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        for (_, p, m) in self.masses(ctx.spec) {
            let t = rigid_transform(&p);
            model.mass += m * t.transpose() * t;
        }
        Ok(())
    }
}

/// `added_mass`: a symmetric 6×6 mass about O added to the model (air or fluid).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AddedMass {
    /// A (kg), symmetric: translational block about O.
    #[serde(default)]
    pub translational_kg: [[f64; 3]; 3],
    /// B (kg m): coupling of translation and rotation.
    #[serde(default)]
    pub coupling_kg_m: [[f64; 3]; 3],
    /// C (kg m²), symmetric: rotational block about O.
    #[serde(default)]
    pub rotational_kg_m2: [[f64; 3]; 3],
}

/// Upper-triangle index pairs of a symmetric 3×3 block, in parameter order.
const UPPER: [(usize, usize); 6] = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];
const AXES: [char; 3] = ['x', 'y', 'z'];

impl AddedMass {
    /// `M_a` about O.
    pub fn matrix(&self) -> rbprops_core::Mat6 {
        let (a, b, c) = (
            Mat3::from_fn(|i, j| self.translational_kg[i][j]),
            Mat3::from_fn(|i, j| self.coupling_kg_m[i][j]),
            Mat3::from_fn(|i, j| self.rotational_kg_m2[i][j]),
        );
        let mut m = rbprops_core::Mat6::zeros();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&a);
        m.fixed_view_mut::<3, 3>(0, 3).copy_from(&b);
        m.fixed_view_mut::<3, 3>(3, 0).copy_from(&b.transpose());
        m.fixed_view_mut::<3, 3>(3, 3).copy_from(&c);
        m
    }
}

impl AddedMass {
    /// The catalogue id (the spec's `id = "added_mass"`).
    pub const ID: &'static str = "added_mass";
}

impl Effect for AddedMass {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn order(&self) -> u8 {
        0
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        let info = |name: String, unit| super::unbounded_info(name, unit, (-1.0, 1.0));
        let sym = |block: &str, unit| {
            UPPER.map(|(i, j)| info(format!("{block}.{}{}", AXES[i], AXES[j]), unit))
        };
        let mut v: Vec<ParamInfo> = sym("translational_kg", "kg").into();
        for i in 0..3 {
            for j in 0..3 {
                v.push(info(
                    format!("coupling_kg_m.{}{}", AXES[i], AXES[j]),
                    "kg m",
                ));
            }
        }
        v.extend(sym("rotational_kg_m2", "kg m2"));
        v
    }
    fn values(&self) -> Vec<f64> {
        let mut v: Vec<f64> = UPPER
            .iter()
            .map(|&(i, j)| self.translational_kg[i][j])
            .collect();
        v.extend(self.coupling_kg_m.iter().flatten());
        v.extend(UPPER.iter().map(|&(i, j)| self.rotational_kg_m2[i][j]));
        v
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        if values.len() != 21 {
            return Err(format!("expected 21 values, got {}", values.len()));
        }
        let sym = |v: &[f64]| {
            let mut b = [[0.0; 3]; 3];
            for (&(i, j), x) in UPPER.iter().zip(v) {
                b[i][j] = *x;
                b[j][i] = *x;
            }
            b
        };
        let mut coupling = [[0.0; 3]; 3];
        for (k, x) in values[6..15].iter().enumerate() {
            coupling[k / 3][k % 3] = *x;
        }
        let e = AddedMass {
            translational_kg: sym(&values[..6]),
            coupling_kg_m: coupling,
            rotational_kg_m2: sym(&values[15..]),
        };
        super::checked(e)
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check_values(&self) -> Result<(), String> {
        for (name, blk, sym) in [
            ("translational_kg", &self.translational_kg, true),
            ("coupling_kg_m", &self.coupling_kg_m, false),
            ("rotational_kg_m2", &self.rotational_kg_m2, true),
        ] {
            if blk.iter().flatten().any(|x| !x.is_finite()) {
                return Err(format!("{name}: entries must be finite"));
            }
            let scale = blk.iter().flatten().fold(0.0f64, |s, x| s.max(x.abs()));
            if sym
                && UPPER
                    .iter()
                    .any(|&(i, j)| (blk[i][j] - blk[j][i]).abs() > 1e-12 * scale)
            {
                return Err(format!("{name}: the block must be symmetric"));
            }
        }
        Ok(())
    }
    /// The total mass matrix must stay positive definite; the model build says so if not.
    fn modify_structure(
        &self,
        _ctx: &BuildContext,
        model: &mut DynamicModel,
    ) -> Result<(), String> {
        model.mass += self.matrix();
        Ok(())
    }
}

/// This module's effects in the physics catalogue ([`super::registry`]).
/// Plausible: 0–200 g per sensor with its cable and mounting (triaxial accelerometers
/// weigh 1–50 g, a mounting block and cable a few tens more).
fn plausible_sensor_mass(
    entry: &crate::spec::EffectSpec,
    _spec: &CampaignSpec,
) -> Result<Vec<super::Plausible>, String> {
    let e: SensorMass = super::params(entry)?;
    let mut v: Vec<super::Plausible> = e
        .masses_kg
        .iter()
        .map(|(k, m)| {
            super::Plausible::new(format!("sensor {k}: mass"), "g", 1e3 * m, [0.0, 200.0])
        })
        .collect();
    if let Some(m) = e.mass_kg {
        v.push(super::Plausible::new(
            "every sensor: mass",
            "g",
            1e3 * m,
            [0.0, 200.0],
        ));
    }
    Ok(v)
}

/// Plausible: a translational added mass (largest eigenvalue of its 3×3 part) of at most
/// 5 % of the body's mass. Air entrained by a compact body is about ρ_air times its
/// volume, well under 1 % of a metal body's mass; a flat face moving normal to itself
/// entrains about ρ_air times the cube of its size, a few times more; 5 % also covers
/// light hollow bodies in air.
fn plausible_added_mass(
    entry: &crate::spec::EffectSpec,
    spec: &CampaignSpec,
) -> Result<Vec<super::Plausible>, String> {
    let e: AddedMass = super::params(entry)?;
    let a = rbprops_core::Mat3::from_fn(|i, j| e.translational_kg[i][j]);
    let largest = a.symmetric_eigenvalues().abs().max();
    let m = spec.body.mass_kg;
    Ok(vec![super::Plausible::new(
        "translational added mass (largest eigenvalue)",
        "g",
        1e3 * largest,
        [0.0, 1e3 * 0.05 * m],
    )])
}

/// `added_mass` restricted to the complement of the rigid-body mass structure (see the
/// module docs): `A = [[a_xx, a_xy, a_xz], [a_xy, a_yy, a_yz], [a_xz, a_yz, −a_xx − a_yy]]`
/// (traceless, kg) and `B` symmetric (kg m), `C = 0`.
#[derive(Debug, Clone)]
pub struct NonRigidMass {
    /// a_xx, a_yy, a_xy, a_xz, a_yz, then b_xx, b_yy, b_zz, b_xy, b_xz, b_yz.
    values: [f64; 11],
}

impl NonRigidMass {
    fn catalogue(&self) -> AddedMass {
        let v = &self.values;
        let a = [
            [v[0], v[2], v[3]],
            [v[2], v[1], v[4]],
            [v[3], v[4], -v[0] - v[1]],
        ];
        let b = [[v[5], v[8], v[9]], [v[8], v[6], v[10]], [v[9], v[10], v[7]]];
        AddedMass {
            translational_kg: a,
            coupling_kg_m: b,
            rotational_kg_m2: [[0.0; 3]; 3],
        }
    }
}

impl Effect for NonRigidMass {
    fn id(&self) -> &'static str {
        AddedMass::ID
    }
    fn order(&self) -> u8 {
        0
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        let info = |name: &str, unit: &'static str| ParamInfo {
            name: name.to_string(),
            unit,
            lower: f64::NEG_INFINITY,
            upper: f64::INFINITY,
            plausible: (-1.0, 1.0),
        };
        let a = ["xx", "yy", "xy", "xz", "yz"]
            .map(|k| info(&format!("translational_deviator_kg.{k}"), "kg"));
        let b = ["xx", "yy", "zz", "xy", "xz", "yz"]
            .map(|k| info(&format!("coupling_symmetric_kg_m.{k}"), "kg m"));
        a.into_iter().chain(b).collect()
    }
    fn values(&self) -> Vec<f64> {
        self.values.to_vec()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let values: [f64; 11] = values
            .try_into()
            .map_err(|_| format!("added_mass expects 11 values, got {}", values.len()))?;
        if values.iter().any(|x| !x.is_finite()) {
            return Err("added_mass: values must be finite".into());
        }
        Ok(Box::new(NonRigidMass { values }))
    }
    /// The catalogue's form (`translational_kg`, `coupling_kg_m`, `rotational_kg_m2`).
    fn parameters_json(&self) -> serde_json::Value {
        self.catalogue().parameters_json()
    }
    fn modify_structure(
        &self,
        _ctx: &BuildContext,
        model: &mut DynamicModel,
    ) -> Result<(), String> {
        model.mass += self.catalogue().matrix();
        Ok(())
    }
}

/// `added_mass`'s screening form: its non-rigid part ([`NonRigidMass`]). Of a symmetric
/// 6×6 `M_a = [[A, B], [Bᵀ, C]]`, the rigid-structured part (A ∝ I, B antisymmetric, any
/// C: 10 directions) is exactly what the free inertia absorbs, so only the rest is
/// fitted: A traceless, B symmetric, C = 0 (11 parameters), screened by a score. The
/// rigid part stays in the reported inertia, which is then that of the body with it.
fn screen_added_mass(_spec: &CampaignSpec, _g: &rbprops_core::Geometry) -> ScreeningResult {
    let e = NonRigidMass { values: [0.0; 11] };
    Ok(Some(ScreeningForm {
        neutral: e.values(),
        scales: [vec![0.05; 5], vec![0.01; 6]].concat(),
        effect: Box::new(e),
        source: "rbprops-sim (its non-rigid part; the rigid part is the free inertia's)",
        screening: ScreeningKind::Score,
    }))
}

pub(crate) const DESCRIPTORS: &[super::EffectDescriptor] = &[
    super::EffectDescriptor {
        id: SensorMass::ID,
        rank: 1,
        title: "sensor mass",
        reveal: "known sensor masses (--sensor-mass) or a run with the sensors moved",
        docs: "E7: a point mass at each listed sensor, `masses_kg` per sensor",
        parse: super::parse_as::<SensorMass>,
        neutral: super::NeutralForm::Table(|spec, _| {
            super::per_sensor_table(spec, "masses_kg", 0.0.into())
        }),
        follows_spec_up: false,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/sensor_mass.toml"),
        plausible: Some(plausible_sensor_mass),
    },
    super::EffectDescriptor {
        id: AddedMass::ID,
        rank: 20,
        title: "added mass without a rigid body's structure (air on large faces, fluid, a loose part)",
        reveal: "a test in a lighter fluid or vacuum, or the article's face areas (potential-flow added mass ≈ (8/3)ρR³ per face)",
        docs: "E15: a symmetric 6×6 mass about the origin without the rigid structure (air on large faces, fluid)",
        parse: super::parse_as::<AddedMass>,
        neutral: super::NeutralForm::Screened(Screened {
            rank: 5,
            form: screen_added_mass,
        }),
        follows_spec_up: false,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/added_mass.toml"),
        plausible: Some(plausible_added_mass),
    },
];
