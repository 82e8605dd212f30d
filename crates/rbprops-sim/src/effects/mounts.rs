//! `suspension_coupling`: stiffness the springs of the spec leave out (docs/physics.md
//! E4): per mount a rotational stiffness (bending and torsion of a rubber mount or a
//! clamped cord end), `k_rot` (N m/rad, frame axes). A rotational spring resists the
//! body rotation θ whatever the point it acts at, so
//!
//! `ΔK = Σ_i blockdiag(0₃, diag(k_rot,i))`,
//!
//! and with `lateral_n_per_m` an extra isotropic lateral (⟂ `axis`) stiffness at each
//! attachment point a_i, `ΔK += Σ_i T(a_i)ᵀ k_l,i (I − e eᵀ) T(a_i)` (mount shear).
//!
//! `suspension_drift` (docs/physics.md, E15, non-stationarity between runs): rubber creep
//! or temperature changes the suspension between the excitations' runs. During the run
//! of excitation e the stiffness is `f_e K` (K the set-up's stiffness as built by the
//! effects before it: springs, and the gravity stiffness when listed first), while the
//! damping matrix stays the set-up's: every pole of that run moves by about
//! `Δω_r/ω_r = (f_e − 1)/2`, the residues hardly. A set-up measured in one run cannot
//! show it (its stiffness is what was measured).
//!
//! `stinger_stiffness` (docs/physics.md, E12, force chain): a shaker's stinger resists
//! motion across its axis. During excitation e's run (the stinger is attached only
//! then) the model gains, with `n` the force direction, `r` the force point and
//! `P = I − n nᵀ`,
//!
//! `K_a = k_l T(r)ᵀ P T(r) + blockdiag(0₃, k_r P)`,
//!
//! a lateral spring `k_l` (N/m, both directions across the axis) at the force point and
//! a bending stiffness `k_r` (N m/rad) about the two axes across it. A fixed–guided
//! stinger of bending stiffness EI and length L has `k_l = 12EI/L³`, `k_r = 4EI/L`
//! (3 mm steel, 100 mm: about 9,500 N/m and 32 N m/rad). The spring along the axis is
//! the force gauge's own path and is measured, so it is not in `K_a`.
//!
//! `stinger_axial_stiffness` (docs/physics.md, E12, force chain): the armature of a
//! shaker hangs in its own suspension (flexures) of axial stiffness `k_a`, and the
//! stinger, stiff along its axis, passes that spring on to the structure while the
//! shaker is attached (its excitation's run only):
//!
//! `K_a = k_a T(r)ᵀ n nᵀ T(r)`,
//!
//! a spring along the force direction `n` at the force point `r`. The FRF sees it when
//! the force is the shaker's drive (from the coil current, `F = Bl i`); a force gauge at
//! the stinger's tip measures the spring's force with the drive, and then `k_a` is not
//! in the FRF (as for the axial spring of `stinger_stiffness`). A rank-one change along
//! the driving point's own direction, so by Sherman–Morrison the driving-point
//! receptance of that run is exactly `1/h' = 1/h + k_a` (tested): below the suspension
//! modes the FRF stiffens, a translational mode along `n` with modal mass `m` moves to
//! `ω² = (k + k_a)/m`. Armature flexures: a few hundred to a few thousand N/m.

use super::{BuildContext, Effect, ParamInfo};
use crate::model::DynamicModel;
use crate::spec::CampaignSpec;
use rbprops_core::{rigid_transform, Mat3, Mat6, Vec3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

fn default_axis() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

/// `suspension_coupling`: rotational (and lateral) mount stiffness the spec's springs leave out.
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
    /// Cord or mount axis that `lateral_n_per_m` acts across; +z by default.
    #[serde(default = "default_axis")]
    pub axis: [f64; 3],
}

fn zero3() -> [f64; 3] {
    [0.0; 3]
}

impl SuspensionCoupling {
    /// The catalogue id (the spec's `id = "suspension_coupling"`).
    pub const ID: &'static str = "suspension_coupling";
}

impl Effect for SuspensionCoupling {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        let rotational = ["x", "y", "z"].map(|a| {
            super::positive_info(format!("rotational_n_m_per_rad.{a}"), "N m/rad", (0.0, 5.0))
        });
        let lateral = super::positive_info("lateral_n_per_m".into(), "N/m", (0.0, 100.0));
        rotational.into_iter().chain([lateral]).collect()
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
        super::checked(e)
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check_values(&self) -> Result<(), String> {
        if let Some(k) = self
            .rotational_n_m_per_rad
            .iter()
            .chain([&self.lateral_n_per_m])
            .find(|k| !(k.is_finite() && **k >= 0.0))
        {
            return Err(format!("stiffness must be finite and ≥ 0, got {k}"));
        }
        super::check_unit_vector("axis", self.axis)
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_values()?;
        super::check_setup(spec, self.setup.as_deref())
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        if !super::acts_in_setup(self.setup.as_deref(), &model.setup) {
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

/// `suspension_drift`: the suspension stiffness changes between excitation runs (rubber creep, temperature).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SuspensionDrift {
    /// Factor f_e on the set-up's stiffness during excitation e's run; excitations not
    /// listed see the set-up's stiffness.
    pub stiffness_factors: BTreeMap<String, f64>,
}

impl SuspensionDrift {
    /// The catalogue id (the spec's `id = "suspension_drift"`).
    pub const ID: &'static str = "suspension_drift";
}

impl Effect for SuspensionDrift {
    fn id(&self) -> &'static str {
        Self::ID
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
        super::checked(e)
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
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
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_values()?;
        super::check_excitations_defined(spec, "stiffness_factors", self.stiffness_factors.keys())
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

/// `stinger_stiffness`: a shaker stinger's lateral (and rotational) stiffness acting during its own excitation's run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StingerStiffness {
    /// Lateral stiffness k_l (N/m) of the stinger per excitation id.
    #[serde(default)]
    pub lateral_n_per_m: BTreeMap<String, f64>,
    /// Bending stiffness k_r (N m/rad) per excitation id.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub rotational_n_m_per_rad: BTreeMap<String, f64>,
}

impl StingerStiffness {
    /// `K_a` of a stinger along `n` at `r` (module docs).
    pub fn matrix(r: &Vec3, n: &Vec3, k_lateral: f64, k_rotational: f64) -> Mat6 {
        let n = n.normalize();
        let p = Mat3::identity() - n * n.transpose();
        let t = rigid_transform(r);
        let mut k = k_lateral * t.transpose() * p * t;
        let mut b = k.fixed_view_mut::<3, 3>(3, 3);
        b += k_rotational * p;
        k
    }
}

impl StingerStiffness {
    /// The catalogue id (the spec's `id = "stinger_stiffness"`).
    pub const ID: &'static str = "stinger_stiffness";
}

impl Effect for StingerStiffness {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        let mut v = super::map_info(
            "lateral_n_per_m",
            &self.lateral_n_per_m,
            "N/m",
            (0.0, 5000.0),
        );
        v.extend(super::map_info(
            "rotational_n_m_per_rad",
            &self.rotational_n_m_per_rad,
            "N m/rad",
            (0.0, 50.0),
        ));
        v
    }
    fn values(&self) -> Vec<f64> {
        self.lateral_n_per_m
            .values()
            .chain(self.rotational_n_m_per_rad.values())
            .copied()
            .collect()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let (lateral, rotational) = super::split_values(
            values,
            self.lateral_n_per_m.len(),
            self.rotational_n_m_per_rad.len(),
        )?;
        let e = StingerStiffness {
            lateral_n_per_m: super::replace_map(&self.lateral_n_per_m, lateral)?,
            rotational_n_m_per_rad: super::replace_map(&self.rotational_n_m_per_rad, rotational)?,
        };
        super::checked(e)
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check_values(&self) -> Result<(), String> {
        if self.lateral_n_per_m.is_empty() && self.rotational_n_m_per_rad.is_empty() {
            return Err("give lateral_n_per_m and/or rotational_n_m_per_rad per excitation".into());
        }
        super::check_non_negative_map("lateral_n_per_m", &self.lateral_n_per_m)?;
        super::check_non_negative_map("rotational_n_m_per_rad", &self.rotational_n_m_per_rad)
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_values()?;
        let ids = self
            .lateral_n_per_m
            .keys()
            .chain(self.rotational_n_m_per_rad.keys());
        super::check_excitations_defined(spec, "stinger_stiffness", ids)
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        for input in &mut model.inputs {
            let ex = &ctx.geometry.excitations[input.excitation];
            let kl = self.lateral_n_per_m.get(&ex.id).copied().unwrap_or(0.0);
            let kr = self
                .rotational_n_m_per_rad
                .get(&ex.id)
                .copied()
                .unwrap_or(0.0);
            if kl != 0.0 || kr != 0.0 {
                input.attached_stiffness += Self::matrix(&input.point, &input.direction, kl, kr);
            }
        }
        Ok(())
    }
}

/// `stinger_axial_stiffness`: a shaker armature's suspension spring passed on along the stinger axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StingerAxialStiffness {
    /// Axial stiffness k_a (N/m) of the shaker's armature suspension, per excitation id.
    pub axial_n_per_m: BTreeMap<String, f64>,
}

impl StingerAxialStiffness {
    /// `K_a` of an axial spring `k_a` along `n` at `r` (module docs).
    pub fn matrix(r: &Vec3, n: &Vec3, k_axial: f64) -> Mat6 {
        let n = n.normalize();
        let t = rigid_transform(r);
        k_axial * t.transpose() * (n * n.transpose()) * t
    }
}

impl StingerAxialStiffness {
    /// The catalogue id (the spec's `id = "stinger_axial_stiffness"`).
    pub const ID: &'static str = "stinger_axial_stiffness";
}

impl Effect for StingerAxialStiffness {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        super::map_info("axial_n_per_m", &self.axial_n_per_m, "N/m", (0.0, 5000.0))
    }
    fn values(&self) -> Vec<f64> {
        self.axial_n_per_m.values().copied().collect()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let e = StingerAxialStiffness {
            axial_n_per_m: super::replace_map(&self.axial_n_per_m, values)?,
        };
        super::checked(e)
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check_values(&self) -> Result<(), String> {
        if self.axial_n_per_m.is_empty() {
            return Err("give axial_n_per_m per excitation".into());
        }
        super::check_non_negative_map("axial_n_per_m", &self.axial_n_per_m)
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_values()?;
        super::check_excitations_defined(spec, "axial_n_per_m", self.axial_n_per_m.keys())
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        for input in &mut model.inputs {
            let ex = &ctx.geometry.excitations[input.excitation];
            match self.axial_n_per_m.get(&ex.id) {
                Some(&k) if k != 0.0 => {
                    input.attached_stiffness += Self::matrix(&input.point, &input.direction, k);
                }
                _ => {}
            }
        }
        Ok(())
    }
}

/// `stinger_stiffness` absent: the lateral spring and the bending stiffness per
/// excitation at 0. A steel stinger of 3 mm × 200 mm has 4EI/L ≈ 17 N m/rad, a tenth of
/// a soft suspension's rotational stiffness, and the lateral spring alone cannot stand
/// in for it, so the screened form has both.
const STINGER_NEUTRAL: super::NeutralForm = super::NeutralForm::Table(|_, g| {
    super::table([
        (
            "lateral_n_per_m",
            super::per_id(super::excitation_ids(g), 0.0.into()),
        ),
        (
            "rotational_n_m_per_rad",
            super::per_id(super::excitation_ids(g), 0.0.into()),
        ),
    ])
});

/// This module's effects in the physics catalogue ([`super::registry`]).
/// Plausible: the suspension's stiffness drifting by at most 30 % between runs (rubber
/// stiffens by a few percent per 10 K; cords creep by a few percent).
fn plausible_drift(
    entry: &crate::spec::EffectSpec,
    _spec: &CampaignSpec,
) -> Result<Vec<super::Plausible>, String> {
    let e: SuspensionDrift = super::params(entry)?;
    Ok(e.stiffness_factors
        .iter()
        .map(|(k, f)| {
            super::Plausible::new(
                format!("excitation {k}: stiffness"),
                "%",
                100.0 * (f - 1.0),
                [-30.0, 30.0],
            )
        })
        .collect())
}

pub(crate) const DESCRIPTORS: &[super::EffectDescriptor] = &[
    super::EffectDescriptor {
        id: SuspensionCoupling::ID,
        rank: 16,
        title: "suspension rotational / lateral coupling stiffness",
        reveal: "a second suspension length, or the mount's measured stiffness",
        docs: "E4: rotational and lateral stiffness at each mount, `rotational_n_m_per_rad`, `lateral_n_per_m`",
        parse: super::parse_as::<SuspensionCoupling>,
        neutral: super::NeutralForm::Table(|_, _| super::table([
            ("rotational_n_m_per_rad", super::zero3_value()),
            ("lateral_n_per_m", 0.0.into()),
        ])),
        follows_spec_up: false,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/suspension_coupling.toml"),
        plausible: None,
    },
    super::EffectDescriptor {
        id: SuspensionDrift::ID,
        rank: 19,
        title: "suspension drift between runs (creep, temperature)",
        reveal: "repeated runs of one excitation, or the suspension modes measured before and after each run",
        docs: "E15: a stiffness factor per excitation run, `stiffness_factors`",
        parse: super::parse_as::<SuspensionDrift>,
        neutral: super::NeutralForm::Table(|_, g| {
            super::per_excitation_table(g, "stiffness_factors", 1.0.into())
        }),
        follows_spec_up: false,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/suspension_drift.toml"),
        plausible: Some(plausible_drift),
    },
    super::EffectDescriptor {
        id: StingerStiffness::ID,
        rank: 21,
        title: "lateral stiffness of a shaker stinger (present only while that shaker drives)",
        reveal: "a run of that excitation by hammer, or the stinger's lateral stiffness (12EI/L³)",
        docs: "E12: a stinger's lateral and bending stiffness at the force point during its run, `lateral_n_per_m`, `rotational_n_m_per_rad`",
        parse: super::parse_as::<StingerStiffness>,
        neutral: STINGER_NEUTRAL,
        follows_spec_up: false,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/stinger_stiffness.toml"),
        plausible: None,
    },
    super::EffectDescriptor {
        id: StingerAxialStiffness::ID,
        rank: 23,
        title: "axial stiffness of a shaker's armature suspension, felt through the stinger (present only while that shaker drives)",
        reveal: "a force gauge at the stinger's tip (it measures the spring's force), or a run of that excitation by hammer",
        docs: "E12: the shaker armature's suspension stiffness along the stinger at the force point during its run, `axial_n_per_m` (a force from the coil current)",
        parse: super::parse_as::<StingerAxialStiffness>,
        neutral: super::NeutralForm::Table(|_, g| {
            super::per_excitation_table(g, "axial_n_per_m", 0.0.into())
        }),
        follows_spec_up: false,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/stinger_axial_stiffness.toml"),
        plausible: None,
    },
];
