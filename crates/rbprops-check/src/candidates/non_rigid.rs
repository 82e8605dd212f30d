//! `added_mass` screened through its non-rigid part ([`NonRigidMass`]): of a symmetric 6×6
//!   `M_a = [[A, B], [Bᵀ, C]]`, the rigid-structured part (A ∝ I, B antisymmetric, any
//!   C: 10 directions) is exactly what the free inertia absorbs, so only the rest is
//!   fitted: A traceless, B symmetric, C = 0 (11 parameters). The rigid part stays in the
//!   reported inertia, which is then that of the body with it.

use super::{describe, Candidate, Screening};
use rbprops_sim::effects::mass::AddedMass;
use rbprops_sim::effects::{BuildContext, Effect, ParamInfo};
use rbprops_sim::model::DynamicModel;

/// The added mass's non-rigid part (its rigid part is absorbed by the free inertia),
/// screened by a score.
pub(super) fn added_mass_candidate() -> Candidate {
    let (title, reveal) = describe(AddedMass::ID);
    let e = NonRigidMass { values: [0.0; 11] };
    Candidate {
        id: AddedMass::ID.into(),
        title: title.into(),
        neutral: e.values(),
        scales: [vec![0.05; 5], vec![0.01; 6]].concat(),
        effect: Box::new(e),
        source: "rbprops-sim (its non-rigid part; the rigid part is the free inertia's)",
        reveal,
        screening: Screening::Score,
        follows: None,
    }
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
    fn catalogue(&self) -> rbprops_sim::effects::mass::AddedMass {
        let v = &self.values;
        let a = [
            [v[0], v[2], v[3]],
            [v[2], v[1], v[4]],
            [v[3], v[4], -v[0] - v[1]],
        ];
        let b = [[v[5], v[8], v[9]], [v[8], v[6], v[10]], [v[9], v[10], v[7]]];
        rbprops_sim::effects::mass::AddedMass {
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
