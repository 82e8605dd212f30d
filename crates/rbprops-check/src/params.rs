//! The nominal model's own parameters θ (what a baseline fit may correct without
//! calling anything "missing physics"): inertia, suspension stiffness scales, damping.
//!
//! Inertia is parametrised so that every θ is a physically consistent body
//! (Wensing, Kim & Slotine 2017): θ = (ln m, c, ln l₀₀, l₁₀, ln l₁₁, l₂₀, l₂₁, ln l₂₂)
//! with the second moment of mass about the CoM `Σ_c = ∫(r−c)(r−c)ᵀdm = L Lᵀ`
//! (L lower triangular, positive diagonal) and `J_c = tr(Σ_c) I − Σ_c`. Σ_c positive
//! definite is exactly "J_c positive definite with strict triangle inequalities".
//!
//! Stiffness: per set-up and global axis d a log scale s_d, applied to every spring as
//! `k' = D k D`, `D = diag(e^{s/2})` (keeps full 3×3 springs symmetric PSD; a diagonal
//! spring's `k_d` is multiplied by `e^{s_d}`). An axis no spring of the set-up resists
//! gets no parameter.
//!
//! Damping follows the spec's model: `modal` → six `ln ζ_r` (by ascending mode),
//! `proportional` → α, β (linear, clamped at 0).

use rbprops_core::{InertiaProperties, Mat3, RigidBodyProperties, Vec3};
use rbprops_sim::spec::{BodySpec, DampingModel, DampingSpec};
use rbprops_sim::CampaignSpec;

/// Which quantity one baseline parameter is.
#[derive(Debug, Clone, PartialEq)]
pub enum ParamKind {
    /// One of the ten inertia parameters of θ (`ln m`, `c`, the Cholesky factor `L` of `Σ_c`), by index.
    Inertia(usize),
    /// The log scale `s_d` of one set-up's springs along a global axis (module docs).
    StiffnessScale {
        /// Index of the set-up.
        setup: usize,
        /// Global axis d (0 = x, 1 = y, 2 = z).
        axis: usize,
    },
    /// `ln ζ_r` of one mode (ascending order) under the `modal` damping model.
    ModalDampingLog(usize),
    /// Mass-proportional coefficient α of `C = αM + βK` (1/s).
    RayleighAlpha,
    /// Stiffness-proportional coefficient β of `C = αM + βK` (s).
    RayleighBeta,
}

/// The baseline parametrisation of a nominal spec.
#[derive(Debug, Clone)]
pub struct Baseline {
    /// The nominal spec the parameters perturb.
    pub nominal: CampaignSpec,
    /// What each parameter is, in θ order.
    pub kinds: Vec<ParamKind>,
    /// Each parameter's name for reports (`mass_kg`, `setup.A.ln_stiffness_scale_x`, …).
    pub names: Vec<String>,
    /// Typical magnitude of each parameter (finite-difference steps, LM scaling).
    pub scales: Vec<f64>,
}

const AXES: [&str; 3] = ["x", "y", "z"];

/// θ_inertia (10) of a body.
pub fn inertia_to_theta(p: &RigidBodyProperties) -> [f64; 10] {
    let j = p.inertia_cm;
    let sigma = Mat3::identity() * (0.5 * j.trace()) - j;
    let l = sigma.cholesky().map(|c| c.l()).unwrap_or_else(|| {
        Mat3::from_diagonal(&sigma.diagonal().map(|x| x.abs().max(1e-12).sqrt()))
    });
    [
        p.mass.ln(),
        p.com.x,
        p.com.y,
        p.com.z,
        l[(0, 0)].ln(),
        l[(1, 0)],
        l[(1, 1)].ln(),
        l[(2, 0)],
        l[(2, 1)],
        l[(2, 2)].ln(),
    ]
}

/// The body of θ_inertia.
pub fn theta_to_inertia(t: &[f64]) -> RigidBodyProperties {
    let l = Mat3::new(
        t[4].exp(),
        0.0,
        0.0,
        t[5],
        t[6].exp(),
        0.0,
        t[7],
        t[8],
        t[9].exp(),
    );
    let sigma = l * l.transpose();
    let j = Mat3::identity() * sigma.trace() - sigma;
    RigidBodyProperties {
        mass: t[0].exp(),
        com: Vec3::new(t[1], t[2], t[3]),
        inertia_cm: (j + j.transpose()) * 0.5,
    }
}

/// The ten reported inertia quantities of a body: m, c (3), J_xx, J_yy, J_zz and the
/// products J_xy, J_xz, J_yz (CAD sense: minus the tensor entries), the ten-vector of
/// [`InertiaProperties`].
pub fn inertia_quantities(p: &RigidBodyProperties) -> [f64; 10] {
    InertiaProperties::from_rigid_body(p).to_vector()
}

/// Names of the ten inertia properties, docs/conventions.md §3 order.
pub const INERTIA_NAMES: [&str; 10] = InertiaProperties::NAMES;

fn spring_matrix(s: &rbprops_sim::spec::SpringSpec) -> Mat3 {
    match (&s.stiffness_n_per_m, &s.stiffness_matrix_n_per_m) {
        (Some(k), _) => Mat3::from_diagonal(&Vec3::new(k[0], k[1], k[2])),
        (None, Some(k)) => Mat3::from_fn(|r, c| k[r][c]),
        (None, None) => Mat3::zeros(),
    }
}

impl Baseline {
    /// The baseline parameters of `spec`: the inertia parameters first, then damping and stiffness scales.
    pub fn new(spec: &CampaignSpec) -> Baseline {
        let props = spec.properties();
        let mut kinds = Vec::new();
        let mut names = Vec::new();
        let mut scales = Vec::new();
        let size = spec
            .sensors
            .iter()
            .map(|s| Vec3::new(s.at_m[0], s.at_m[1], s.at_m[2]).norm())
            .fold(props.com.norm(), f64::max)
            .max(1e-3);
        let inames = [
            "ln_mass", "com_x", "com_y", "com_z", "ln_l00", "l10", "ln_l11", "l20", "l21", "ln_l22",
        ];
        let t = inertia_to_theta(&props);
        let lsc = (t[4].exp() + t[6].exp() + t[9].exp()) / 3.0;
        for (i, n) in inames.iter().enumerate() {
            kinds.push(ParamKind::Inertia(i));
            names.push(format!("inertia.{n}"));
            scales.push(match i {
                1..=3 => size,
                5 | 7 | 8 => lsc,
                _ => 1.0,
            });
        }
        for (si, s) in spec.setups.iter().enumerate() {
            for axis in 0..3 {
                if s.springs
                    .iter()
                    .any(|sp| spring_matrix(sp)[(axis, axis)] > 0.0)
                {
                    kinds.push(ParamKind::StiffnessScale { setup: si, axis });
                    names.push(format!("setup.{}.ln_stiffness_scale_{}", s.id, AXES[axis]));
                    scales.push(1.0);
                }
            }
        }
        match spec.damping.model {
            DampingModel::Modal => {
                for r in 0..6 {
                    kinds.push(ParamKind::ModalDampingLog(r));
                    names.push(format!("damping.ln_ratio_mode{}", r + 1));
                    scales.push(1.0);
                }
            }
            DampingModel::Proportional => {
                let a = spec.damping.alpha.unwrap_or(0.0);
                let b = spec.damping.beta.unwrap_or(0.0);
                kinds.push(ParamKind::RayleighAlpha);
                names.push("damping.alpha".into());
                scales.push(if a > 0.0 { a } else { 0.01 });
                kinds.push(ParamKind::RayleighBeta);
                names.push("damping.beta".into());
                scales.push(if b > 0.0 { b } else { 1e-4 });
            }
        }
        Baseline {
            nominal: spec.clone(),
            kinds,
            names,
            scales,
        }
    }

    /// Number of parameters.
    pub fn len(&self) -> usize {
        self.kinds.len()
    }

    /// θ of the nominal spec itself.
    pub fn initial(&self) -> Vec<f64> {
        let t = inertia_to_theta(&self.nominal.properties());
        let d = &self.nominal.damping;
        self.kinds
            .iter()
            .map(|k| match k {
                ParamKind::Inertia(i) => t[*i],
                ParamKind::StiffnessScale { .. } => 0.0,
                ParamKind::ModalDampingLog(r) => {
                    let z = match (&d.ratios, d.ratio) {
                        (Some(rs), _) => rs.get(*r).copied().unwrap_or(0.0),
                        (None, z) => z.unwrap_or(0.0),
                    };
                    z.max(1e-5).ln()
                }
                ParamKind::RayleighAlpha => d.alpha.unwrap_or(0.0),
                ParamKind::RayleighBeta => d.beta.unwrap_or(0.0),
            })
            .collect()
    }

    /// The spec whose body, springs and damping are those of θ (effects untouched).
    pub fn apply(&self, theta: &[f64]) -> CampaignSpec {
        let mut spec = self.nominal.clone();
        let body = theta_to_inertia(&theta[..10]);
        let j = body.inertia_cm;
        spec.body = BodySpec {
            mass_kg: body.mass,
            com_m: [body.com.x, body.com.y, body.com.z],
            inertia_cm_kg_m2: Some(std::array::from_fn(|r| std::array::from_fn(|c| j[(r, c)]))),
            moments_kg_m2: None,
            products_kg_m2: None,
        };
        let mut scale = vec![[0.0f64; 3]; spec.setups.len()];
        let mut ratios = [0.0f64; 6];
        let mut modal = false;
        let (mut alpha, mut beta) = (None, None);
        for (k, &v) in self.kinds.iter().zip(theta) {
            match k {
                ParamKind::Inertia(_) => {}
                ParamKind::StiffnessScale { setup, axis } => scale[*setup][*axis] = v,
                ParamKind::ModalDampingLog(r) => {
                    modal = true;
                    ratios[*r] = v.exp();
                }
                ParamKind::RayleighAlpha => alpha = Some(v.max(0.0)),
                ParamKind::RayleighBeta => beta = Some(v.max(0.0)),
            }
        }
        for (si, s) in spec.setups.iter_mut().enumerate() {
            let d = Vec3::new(
                (scale[si][0] / 2.0).exp(),
                (scale[si][1] / 2.0).exp(),
                (scale[si][2] / 2.0).exp(),
            );
            for sp in &mut s.springs {
                let k = spring_matrix(sp);
                let k2 = Mat3::from_fn(|r, c| d[r] * k[(r, c)] * d[c]);
                if sp.stiffness_n_per_m.is_some() {
                    sp.stiffness_n_per_m = Some([k2[(0, 0)], k2[(1, 1)], k2[(2, 2)]]);
                } else {
                    sp.stiffness_matrix_n_per_m =
                        Some(std::array::from_fn(|r| std::array::from_fn(|c| k2[(r, c)])));
                }
            }
        }
        spec.damping = if modal {
            DampingSpec {
                model: DampingModel::Modal,
                ratio: None,
                ratios: Some(ratios.to_vec()),
                alpha: None,
                beta: None,
            }
        } else {
            DampingSpec {
                model: DampingModel::Proportional,
                ratio: None,
                ratios: None,
                alpha,
                beta,
            }
        };
        spec
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inertia_parametrisation_round_trips() {
        let spec =
            CampaignSpec::from_toml_str(rbprops_sim::example("test-case-2").unwrap()).unwrap();
        let p = spec.properties();
        let back = theta_to_inertia(&inertia_to_theta(&p));
        assert!((back.mass - p.mass).abs() < 1e-12);
        assert!((back.com - p.com).norm() < 1e-12);
        assert!((back.inertia_cm - p.inertia_cm).norm() < 1e-12);
        // The nominal θ reproduces the nominal model exactly.
        let b = Baseline::new(&spec);
        let s2 = b.apply(&b.initial());
        assert!((s2.properties().inertia_cm - p.inertia_cm).norm() < 1e-12);
        assert_eq!(s2.setup_stiffness(0), spec.setup_stiffness(0));
    }

    #[test]
    fn any_theta_is_a_physical_body() {
        for k in 0..200 {
            let t: Vec<f64> = (0..10)
                .map(|i| ((k * 31 + i * 17) % 23) as f64 / 5.0 - 2.3)
                .collect();
            let p = theta_to_inertia(&t);
            assert!(
                p.consistency_violations().is_empty(),
                "{t:?}: {:?}",
                p.consistency_violations()
            );
        }
    }
}
