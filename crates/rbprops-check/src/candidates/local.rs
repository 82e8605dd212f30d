//! The catalogue effects the check screens through its own local implementation
//! (of rbprops-sim's [`Effect`] trait).
//!
//! Local effects (equations; all neutral at 0):
//! - `channel_gain` (E10): channel i reads (1+ε_i)·H_i.
//! - `excitation_gain` (E12 sensitivity): excitation e's FRFs scaled by (1+δ_e).
//! - `global_gain` (E10 global): every FRF scaled by (1+κ). Absorbed by the free mass.
//! - `sensor_misorientation` (E8): the channels at a point sense along R(ψ) s, with
//!   `R(ψ) = exp([ψ]×)` (Rodrigues), three angles per sensor point.
//! - `sensor_mass` (E7): point mass m_p at each sensor point, M += m_p T(p)ᵀT(p).
//!   Absorbed by the free inertia.
//! - `gravity_stiffness` (E1): rbprops-sim's cord geometric stiffness (every spring read
//!   as a vertical cord of length ℓ) reparametrised so that "absent" is a point of the
//!   parameter space: `K(φ) = φ₁·lateral(ℓ = 1) + φ₂·load term`, φ₁ = 1/ℓ (1/m), φ₂ the
//!   load-term factor (physical value 1). The catalogue's own parameter (ℓ, with ℓ → ∞
//!   still leaving the load term) has no neutral value, so a score test needs this form.
//!   Two tilts of the vertical and φ₅, the fraction by which springs (rather than cords)
//!   turn with the sagged body, complete it (see `gravity_stiffness`).
//! - `nonproportional_damping` (E5): dashpots at the spring points,
//!   C += Σ_i T(a_i)ᵀ diag(c_x, c_y, c_z) T(a_i), per set-up. Only a recording-side
//!   helper ([`local_effect`]): the candidate screened is the catalogue's general
//!   viscous damping (`modal_coupling`, see `neutral_entry` and docs/physics.md, E5).
//! - `residual_flexibility` (E13): elastic modes above the band seen as a general
//!   residual flexibility matrix R (channels × excitations, m/N): one mode at f_e per
//!   excitation, `H += R_ce ω_e²/(ω_e² − ω² + 2iζ_e ω_e ω)`, with q =
//!   (f_top/f_e)² and ζ_e the last two parameters (neutral 1/16 and 0: an undamped mode
//!   at 4× the top of the band). Both are bilinear with R (no signature while R = 0),
//!   so the model check frees them after a refit has moved R; they then reach a mode
//!   just above the band, whose damping shows where the rigid part of an FRF nearly
//!   cancels and the mode's tail dominates. (The catalogue's `elastic_mode` is bilinear
//!   in its shapes, with no usable neutral point.)
//! - `force_direction` (E12): excitation e pushes along normalise(d + β₁u₁ + β₂u₂),
//!   u₁, u₂ ⟂ d.

use super::gravity::{free_direction_note, gravity_profile, gravity_stiffness, springs_can_sag};
use super::{describe, Candidate, Screening};
use rbprops_core::geometry::cross_matrix;
use rbprops_core::{rigid_transform, Geometry, Mat3, Vec3};
use rbprops_sim::effects::{BuildContext, Effect, OutputBlock, ParamInfo, Reach};
use rbprops_sim::model::DynamicModel;
use rbprops_sim::CampaignSpec;

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Kind {
    ChannelGain,
    ExcitationGain,
    GlobalGain,
    SensorMisorientation,
    SensorMass,
    GravityStiffness,
    MountDashpots,
    ForceDirection,
    ResidualFlexibility,
}

pub(super) const ALL: [Kind; 9] = [
    Kind::ResidualFlexibility,
    Kind::GravityStiffness,
    Kind::SensorMisorientation,
    Kind::ChannelGain,
    Kind::ExcitationGain,
    Kind::ForceDirection,
    Kind::MountDashpots,
    Kind::SensorMass,
    Kind::GlobalGain,
];

impl Kind {
    pub(super) fn id(self) -> &'static str {
        match self {
            Kind::ChannelGain => "channel_gain",
            Kind::ExcitationGain => "excitation_gain",
            Kind::GlobalGain => "global_gain",
            Kind::SensorMisorientation => "sensor_misorientation",
            Kind::SensorMass => "sensor_mass",
            Kind::GravityStiffness => "gravity_stiffness",
            Kind::MountDashpots => "nonproportional_damping",
            Kind::ForceDirection => "force_direction",
            Kind::ResidualFlexibility => "residual_flexibility",
        }
    }
    fn title(self) -> &'static str {
        describe(self.id()).0
    }
    fn reveal(self) -> &'static str {
        describe(self.id()).1
    }
}

/// Title and "what would reveal it" of the one local candidate the catalogue does not
/// have (the catalogue's own come from its registry).
pub(super) const RESIDUAL_FLEXIBILITY_TEXT: (&str, &str) = (
    "elastic modes above the band (residual flexibility)",
    "data closer to the first elastic mode, or its measured frequency",
);

/// A locally implemented catalogue effect (see the module docs for the equations).
#[derive(Debug, Clone)]
pub struct LocalEffect {
    kind: Kind,
    names: Vec<String>,
    values: Vec<f64>,
    /// Channel index → point index (sensor groups), for misorientation.
    groups: Vec<Vec<usize>>,
    /// Point positions (sensor points), for sensor_mass.
    points: Vec<Vec3>,
    /// Top of the band (Hz): the residual flexibility's modes sit at f_top/√q.
    band_top_hz: f64,
}

/// Name of the gravity candidate's fifth parameter φ₅ (see [`gravity_stiffness`]).
const SPRING_TURN: &str = "spring_turn_fraction";

/// Name of the residual flexibility's frequency parameter q = (f_top/f_e)².
const RESIDUAL_MODE_Q: &str = "band_top_over_mode_frequency_squared";

/// Its neutral value: the modes at 4× the top of the band, where their ω² growth is
/// what an elastic mode above the band shows.
const RESIDUAL_MODE_Q_NEUTRAL: f64 = 1.0 / 16.0;

/// Name of the residual flexibility's modal damping ratio (neutral 0).
const RESIDUAL_MODE_DAMPING: &str = "mode_damping_ratio";

fn sensor_groups(g: &Geometry) -> (Vec<String>, Vec<Vec<usize>>, Vec<Vec3>) {
    let mut ids: Vec<String> = Vec::new();
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut pos = Vec::new();
    for (i, c) in g.channels.iter().enumerate() {
        match ids.iter().position(|p| *p == c.point) {
            Some(k) => groups[k].push(i),
            None => {
                ids.push(c.point.clone());
                groups.push(vec![i]);
                pos.push(c.position);
            }
        }
    }
    (ids, groups, pos)
}

impl LocalEffect {
    fn neutral(kind: Kind, spec: &CampaignSpec, g: &Geometry) -> LocalEffect {
        let (pids, groups, points) = sensor_groups(g);
        let names: Vec<String> = match kind {
            Kind::ChannelGain => g
                .channels
                .iter()
                .map(|c| format!("{}.gain_error", c.id))
                .collect(),
            Kind::ExcitationGain => g
                .excitations
                .iter()
                .map(|e| format!("{}.gain_error", e.id))
                .collect(),
            Kind::GlobalGain => vec!["gain_error".into()],
            Kind::SensorMisorientation => pids
                .iter()
                .flat_map(|p| ["rx", "ry", "rz"].map(|a| format!("{p}.{a}_rad")))
                .collect(),
            Kind::SensorMass => pids.iter().map(|p| format!("{p}.mass_kg")).collect(),
            Kind::GravityStiffness => {
                let mut v: Vec<String> = vec![
                    "inverse_cord_length_per_m".into(),
                    "load_term_factor".into(),
                    "up_tilt1_rad".into(),
                    "up_tilt2_rad".into(),
                ];
                if springs_can_sag(spec, g) {
                    v.push(SPRING_TURN.into());
                }
                v
            }
            Kind::MountDashpots => spec
                .setups
                .iter()
                .flat_map(|s| ["x", "y", "z"].map(|a| format!("{}.dashpot_{a}_n_s_per_m", s.id)))
                .collect(),
            Kind::ResidualFlexibility => g
                .excitations
                .iter()
                .flat_map(|e| {
                    g.channels
                        .iter()
                        .map(move |c| format!("{}.{}.receptance_m_per_n", c.id, e.id))
                })
                .chain([RESIDUAL_MODE_Q, RESIDUAL_MODE_DAMPING].map(String::from))
                .collect(),
            Kind::ForceDirection => g
                .excitations
                .iter()
                .flat_map(|e| ["tilt1", "tilt2"].map(|a| format!("{}.{a}_rad", e.id)))
                .collect(),
        };
        let mut values = vec![0.0; names.len()];
        if kind == Kind::ResidualFlexibility {
            values[names.len() - 2] = RESIDUAL_MODE_Q_NEUTRAL;
        }
        LocalEffect {
            kind,
            values,
            names,
            groups,
            points,
            band_top_hz: spec.frequency.stop_hz,
        }
    }

    fn info(&self, i: usize) -> ParamInfo {
        let (unit, lo, hi, pl) = match self.kind {
            Kind::ChannelGain | Kind::ExcitationGain | Kind::GlobalGain => {
                ("1", -0.5, 0.5, (-0.05, 0.05))
            }
            Kind::SensorMisorientation | Kind::ForceDirection => ("rad", -0.5, 0.5, (-0.1, 0.1)),
            Kind::ResidualFlexibility if i + 1 == self.values.len() => ("1", 0.0, 0.5, (0.0, 0.05)),
            Kind::ResidualFlexibility if i + 2 == self.values.len() => {
                ("1", 1e-4, 0.95, (0.0, 0.5))
            }
            Kind::ResidualFlexibility => ("m/N", f64::NEG_INFINITY, f64::INFINITY, (-1e-4, 1e-4)),
            Kind::SensorMass => ("kg", 0.0, f64::INFINITY, (0.0, 0.5)),
            Kind::GravityStiffness if i == 0 => ("1/m", 0.0, 100.0, (0.2, 10.0)),
            Kind::GravityStiffness if i == 1 => ("1", 0.0, 3.0, (0.5, 1.5)),
            // 0: the springs' stiffness stays along the spec's axes (cords); 1: it turns
            // with the sagged body (linear springs to the ground). Bounds wide enough
            // that neither end is pinned.
            Kind::GravityStiffness if i == 4 => ("1", -2.0, 3.0, (-0.5, 1.5)),
            Kind::GravityStiffness => ("rad", -0.5, 0.5, (-0.1, 0.1)),
            Kind::MountDashpots => ("N s/m", 0.0, f64::INFINITY, (0.0, 100.0)),
        };
        ParamInfo {
            name: self.names[i].clone(),
            unit,
            lower: lo,
            upper: hi,
            plausible: pl,
        }
    }

    fn scale(&self, spec: &CampaignSpec) -> Vec<f64> {
        let m = spec.body.mass_kg;
        (0..self.values.len())
            .map(|i| match self.kind {
                Kind::ChannelGain | Kind::ExcitationGain | Kind::GlobalGain => 0.01,
                Kind::SensorMisorientation | Kind::ForceDirection => 0.01,
                Kind::ResidualFlexibility if i + 1 == self.values.len() => 0.001,
                Kind::ResidualFlexibility if i + 2 == self.values.len() => 0.01,
                Kind::ResidualFlexibility => {
                    let w = std::f64::consts::TAU * spec.frequency.stop_hz.max(1e-3);
                    1e-3 / (m * w * w)
                }
                Kind::SensorMass => 0.01 * m,
                Kind::GravityStiffness => {
                    if i < 2 || i == 4 {
                        1.0
                    } else {
                        0.01
                    }
                }
                Kind::MountDashpots => {
                    // 1 % critical damping of the stiffest spring of the set-up, roughly.
                    let k = spec
                        .setups
                        .iter()
                        .flat_map(|s| s.springs.iter())
                        .map(|s| {
                            s.stiffness_n_per_m
                                .map(|k| k[0].max(k[1]).max(k[2]))
                                .unwrap_or(100.0)
                        })
                        .fold(1.0, f64::max);
                    0.02 * (k * m).sqrt()
                }
            })
            .collect()
    }
}

fn rodrigues(psi: &Vec3) -> Mat3 {
    let t = psi.norm();
    let k = cross_matrix(psi);
    if t < 1e-12 {
        return Mat3::identity() + k;
    }
    Mat3::identity() + k * (t.sin() / t) + k * k * ((1.0 - t.cos()) / (t * t))
}

/// The unit direction `d` tilted by the angles (a, b) about two axes perpendicular to
/// it: `normalize(d + a e₁ + b e₂)`, with e₁ = normalize(d × h), h the axis x unless d
/// is nearly along it (then y), and e₂ = d × e₁. The vertical of the gravity candidate
/// (a frame off by a few degrees, E15.4) and a force's direction (E12) are tilted so.
pub fn tilted_direction(d: &Vec3, a: f64, b: f64) -> Vec3 {
    let helper = if d.x.abs() < 0.9 {
        Vec3::x()
    } else {
        Vec3::y()
    };
    let e1 = d.cross(&helper).normalize();
    let e2 = d.cross(&e1);
    (d + e1 * a + e2 * b).normalize()
}

impl Effect for LocalEffect {
    fn id(&self) -> &'static str {
        self.kind.id()
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        (0..self.values.len()).map(|i| self.info(i)).collect()
    }
    fn values(&self) -> Vec<f64> {
        self.values.clone()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        if values.len() != self.values.len() {
            return Err(format!(
                "{} expects {} parameters, got {}",
                self.id(),
                self.values.len(),
                values.len()
            ));
        }
        if let Some(v) = values.iter().find(|v| !v.is_finite()) {
            return Err(format!("{}: parameter {v} is not finite", self.id()));
        }
        let mut e = self.clone();
        e.values = values.to_vec();
        Ok(Box::new(e))
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::Value::Object(
            self.names
                .iter()
                .zip(&self.values)
                .map(|(n, v)| (n.clone(), serde_json::json!(v)))
                .collect(),
        )
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        match self.kind {
            Kind::SensorMisorientation => {
                for (k, chans) in self.groups.iter().enumerate() {
                    let psi = Vec3::new(
                        self.values[3 * k],
                        self.values[3 * k + 1],
                        self.values[3 * k + 2],
                    );
                    let r = rodrigues(&psi);
                    for &c in chans {
                        let ch = &ctx.geometry.channels[c];
                        model.outputs[c] =
                            (r * ch.direction).transpose() * rigid_transform(&ch.position);
                    }
                }
            }
            Kind::SensorMass => {
                for (p, m) in self.points.iter().zip(&self.values) {
                    let t = rigid_transform(p);
                    model.mass += (t.transpose() * t) * *m;
                }
            }
            Kind::GravityStiffness => {
                model.stiffness += gravity_stiffness(ctx, model, &self.values)?;
                model.stiffness = (model.stiffness + model.stiffness.transpose()) * 0.5;
            }
            Kind::ResidualFlexibility => {
                // One undamped mode at f_e per excitation, unit at that excitation's
                // force: the receptance gains R_ce ω_e²/(ω_e² − ω²) ≈ R_ce (1 + ω²/ω_e²),
                // a general (any rank) residual flexibility matrix R.
                let n_ch = ctx.geometry.channels.len();
                let n_ex = ctx.geometry.excitations.len();
                let (q, zeta) = (self.values[n_ex * n_ch], self.values[n_ex * n_ch + 1]);
                let extra_hz = self.band_top_hz / q.sqrt();
                let we = std::f64::consts::TAU * extra_hz;
                for e in 0..n_ex {
                    let col = &self.values[e * n_ch..(e + 1) * n_ch];
                    if col.iter().all(|v| *v == 0.0) {
                        continue;
                    }
                    let mut at_ex = vec![0.0; n_ex];
                    at_ex[e] = 1.0;
                    model.extra_modes.push(rbprops_sim::model::ExtraMode {
                        frequency_hz: extra_hz,
                        damping_ratio: zeta,
                        at_channels: col.iter().map(|r| r * we * we).collect(),
                        at_excitations: at_ex,
                    });
                }
            }
            Kind::ForceDirection => {
                for inp in &mut model.inputs {
                    let e = &ctx.geometry.excitations[inp.excitation];
                    let d2 = tilted_direction(
                        &e.direction,
                        self.values[2 * inp.excitation],
                        self.values[2 * inp.excitation + 1],
                    );
                    inp.column = rigid_transform(&e.position).transpose() * d2;
                }
            }
            _ => {}
        }
        Ok(())
    }
    fn modify_damping(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        if self.kind == Kind::MountDashpots {
            let c = Mat3::from_diagonal(&Vec3::new(
                self.values[3 * ctx.setup_index],
                self.values[3 * ctx.setup_index + 1],
                self.values[3 * ctx.setup_index + 2],
            ));
            for s in ctx.spec.springs(ctx.setup_index) {
                let t = rigid_transform(&s.at);
                model.damping += t.transpose() * c * t;
            }
        }
        Ok(())
    }
    /// A channel's gain reaches that channel's FRFs, an excitation's its own
    /// (`transform_output`), a sensor's misorientation its channels' (their output rows),
    /// a residual flexibility `R_ce` the FRF of c and e (the `at_channels[c]` of the
    /// mode driven by e alone); everything else reaches any FRF.
    fn parameter_reach(&self, g: &Geometry) -> Vec<Reach> {
        let n = self.values.len();
        let (n_ch, n_ex) = (g.channels.len(), g.excitations.len());
        (0..n)
            .map(|i| match self.kind {
                Kind::ChannelGain if n == n_ch => Reach::Channels(vec![i]),
                Kind::SensorMisorientation if n == 3 * self.groups.len() => {
                    Reach::Channels(self.groups[i / 3].clone())
                }
                Kind::ExcitationGain if n == n_ex => Reach::Excitation(i),
                Kind::ResidualFlexibility if n == n_ch * n_ex + 2 && i < n - 2 => Reach::Cell {
                    channel: i % n_ch,
                    excitation: i / n_ch,
                },
                _ => Reach::Any,
            })
            .collect()
    }
    fn transform_output(&self, block: &mut OutputBlock) {
        let nl = block.frequency_hz.len();
        match self.kind {
            Kind::ChannelGain => {
                for (c, v) in block.values.chunks_exact_mut(nl).enumerate() {
                    let g = 1.0 + self.values[c];
                    v.iter_mut().for_each(|x| *x *= g);
                }
            }
            Kind::ExcitationGain => {
                let g = 1.0 + self.values[block.excitation];
                block.values.iter_mut().for_each(|x| *x *= g);
            }
            Kind::GlobalGain => {
                let g = 1.0 + self.values[0];
                block.values.iter_mut().for_each(|x| *x *= g);
            }
            _ => {}
        }
    }
}

/// The local effects ([`ALL`], in order) not in the spec and not already offered by the
/// catalogue. The sensor mass is screened by its rigid-mass gauge, gravity stiffness by a
/// cord-length profile when the nominal model has free directions, the others by a score.
pub(super) fn local_candidates(
    spec: &CampaignSpec,
    geometry: &Geometry,
    in_spec: &[&str],
    out: &mut Vec<Candidate>,
    notes: &mut Vec<String>,
) {
    // Free directions in the nominal model: gravity turns zero-frequency modes into
    // in-band pendulum resonances, far from linear in φ at φ = 0, so it is screened by
    // a profile over cord lengths instead of a score (see [`gravity_profile`]).
    let has_free = free_direction_note(spec, geometry).is_some();
    // A free–free body has nothing to hang from: no gravity stiffness.
    let suspended = spec
        .setups
        .iter()
        .any(|s| !s.springs.is_empty() || !s.cords.is_empty());
    for k in ALL {
        if in_spec.contains(&k.id()) || out.iter().any(|c| c.id == k.id()) {
            continue;
        }
        if k == Kind::GravityStiffness && !suspended {
            notes.push("gravity_stiffness is not screened: no set-up has springs or cords".into());
            continue;
        }
        let e = LocalEffect::neutral(k, spec, geometry);
        let n_params = e.values.len();
        out.push(Candidate {
            id: k.id().to_string(),
            title: k.title().to_string(),
            neutral: e.values(),
            scales: e.scale(spec),
            effect: Box::new(e),
            source: if rbprops_sim::effects::descriptor(k.id()).is_some() {
                "rbprops-sim (reparametrised for screening)"
            } else {
                "rbprops-check (local)"
            },
            reveal: k.reveal(),
            screening: if k == Kind::SensorMass {
                Screening::RigidMassGauge
            } else if k == Kind::GravityStiffness && has_free {
                gravity_profile(spec, n_params)
            } else {
                Screening::Score
            },
            follows: None,
        });
    }
}

/// A local effect by id with given values (for fixtures and tests: the recording side).
pub fn local_effect(
    id: &str,
    spec: &CampaignSpec,
    values: &[f64],
) -> Result<Box<dyn Effect>, String> {
    let g = spec.geometry().map_err(|e| e.to_string())?;
    let k = ALL
        .iter()
        .find(|k| k.id() == id)
        .ok_or_else(|| format!("no local effect '{id}'"))?;
    LocalEffect::neutral(*k, spec, &g).with_values(values)
}
