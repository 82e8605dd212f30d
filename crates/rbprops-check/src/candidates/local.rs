//! The catalogue effects the check screens through its own local implementation
//! (of rbprops-sim's [`Effect`] trait).
//!
//! Local forms (equations; all neutral at 0):
//! - `gravity_stiffness` (E1): rbprops-sim's cord geometric stiffness (every spring read
//!   as a vertical cord of length ℓ) reparametrised so that "absent" is a point of the
//!   parameter space: `K(φ) = φ₁·lateral(ℓ = 1) + φ₂·load term`, φ₁ = 1/ℓ (1/m), φ₂ the
//!   load-term factor (physical value 1). The catalogue's own parameter (ℓ, with ℓ → ∞
//!   still leaving the load term) has no neutral value, so a score test needs this form.
//!   Two tilts of the vertical and φ₅, the fraction by which springs (rather than cords)
//!   turn with the sagged body, complete it, and for cords written as axial springs the
//!   pose contrasts of their free lengths (see `gravity_stiffness`).
//! - `residual_flexibility` (E13): elastic modes above the band seen as a general
//!   residual flexibility matrix R (channels × excitations, m/N): one mode at f_e per
//!   excitation, `H += R_ce ω_e²/(ω_e² − ω² + 2iζ_e ω_e ω)`, with q =
//!   (f_top/f_e)² and ζ_e the last two parameters (neutral 1/16 and 0: an undamped mode
//!   at 4× the top of the band). Both are bilinear with R (no signature while R = 0),
//!   so the model check frees them after a refit has moved R; they then reach a mode
//!   just above the band, whose damping shows where the rigid part of an FRF nearly
//!   cancels and the mode's tail dominates. (The catalogue's `elastic_mode` is bilinear
//!   in its shapes, with no usable neutral point.)
//!
//! Every other catalogue effect is screened in the catalogue's own form, from the neutral
//! table its descriptor gives.

use super::gravity::{
    free_direction_note, gravity_names, gravity_profile, gravity_stiffness, ContrastSlot,
    GravityPhi, CONTRAST, SPRING_TURN,
};
use super::{describe, Candidate, Screening};
use rbprops_sim::effects::gravity::GravityStiffness;

use rbprops_core::{Geometry, Vec3};
use rbprops_sim::effects::{BuildContext, Effect, ParamInfo, Reach};
use rbprops_sim::model::DynamicModel;
use rbprops_sim::CampaignSpec;

/// The two local forms (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Kind {
    GravityStiffness,
    ResidualFlexibility,
}

/// The local forms in the order they are offered (the check's determinism depends on it).
pub(super) const ALL: [Kind; 2] = [Kind::ResidualFlexibility, Kind::GravityStiffness];

impl Kind {
    pub(super) fn id(self) -> &'static str {
        match self {
            Kind::GravityStiffness => GravityStiffness::ID,
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

/// A local screening form of a catalogue effect (see the module docs for the equations).
#[derive(Debug, Clone)]
pub struct LocalEffect {
    kind: Kind,
    names: Vec<String>,
    values: Vec<f64>,
    /// Top of the band (Hz): the residual flexibility's modes sit at f_top/√q.
    band_top_hz: f64,
    /// Gravity: where each set-up's cord-length contrasts sit among the contrasts (see
    /// [`gravity_stiffness`]).
    slots: Vec<ContrastSlot>,
}

/// Name of the residual flexibility's frequency parameter q = (f_top/f_e)².
const RESIDUAL_MODE_Q: &str = "band_top_over_mode_frequency_squared";

/// Its neutral value: the modes at 4× the top of the band, where their ω² growth is
/// what an elastic mode above the band shows.
const RESIDUAL_MODE_Q_NEUTRAL: f64 = 1.0 / 16.0;

/// Name of the residual flexibility's modal damping ratio (neutral 0).
const RESIDUAL_MODE_DAMPING: &str = "mode_damping_ratio";

impl LocalEffect {
    fn neutral(kind: Kind, spec: &CampaignSpec, g: &Geometry) -> LocalEffect {
        let (names, slots): (Vec<String>, Vec<ContrastSlot>) = match kind {
            Kind::GravityStiffness => gravity_names(spec, g),
            Kind::ResidualFlexibility => (
                g.excitations
                    .iter()
                    .flat_map(|e| {
                        g.channels
                            .iter()
                            .map(move |c| format!("{}.{}.receptance_m_per_n", c.id, e.id))
                    })
                    .chain([RESIDUAL_MODE_Q, RESIDUAL_MODE_DAMPING].map(String::from))
                    .collect(),
                Vec::new(),
            ),
        };
        let mut values = vec![0.0; names.len()];
        if kind == Kind::ResidualFlexibility {
            values[names.len() - 2] = RESIDUAL_MODE_Q_NEUTRAL;
        }
        LocalEffect {
            kind,
            values,
            names,
            band_top_hz: spec.frequency.stop_hz,
            slots,
        }
    }

    fn info(&self, i: usize) -> ParamInfo {
        let (unit, lo, hi, pl) = match self.kind {
            Kind::ResidualFlexibility if i + 1 == self.values.len() => ("1", 0.0, 0.5, (0.0, 0.05)),
            Kind::ResidualFlexibility if i + 2 == self.values.len() => {
                ("1", 1e-4, 0.95, (0.0, 0.5))
            }
            Kind::ResidualFlexibility => ("m/N", f64::NEG_INFINITY, f64::INFINITY, (-1e-4, 1e-4)),
            Kind::GravityStiffness if i == 0 => ("1/m", 0.0, 100.0, (0.2, 10.0)),
            Kind::GravityStiffness if i == 1 => ("1", 0.0, 3.0, (0.5, 1.5)),
            // 0: the springs' stiffness stays along the spec's axes (cords); 1: it turns
            // with the sagged body (linear springs to the ground). Bounds wide enough
            // that neither end is pinned.
            Kind::GravityStiffness if self.names[i] == SPRING_TURN => ("1", -2.0, 3.0, (-0.5, 1.5)),
            // Cord-length contrasts: a tester measures cords to a few centimetres.
            Kind::GravityStiffness if self.names[i].contains(CONTRAST) => {
                ("m", -0.5, 0.5, (-0.1, 0.1))
            }
            Kind::GravityStiffness => ("rad", -0.5, 0.5, (-0.1, 0.1)),
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
                Kind::ResidualFlexibility if i + 1 == self.values.len() => 0.001,
                Kind::ResidualFlexibility if i + 2 == self.values.len() => 0.01,
                Kind::ResidualFlexibility => {
                    let w = std::f64::consts::TAU * spec.frequency.stop_hz.max(1e-3);
                    1e-3 / (m * w * w)
                }
                Kind::GravityStiffness if i < 2 || self.names[i] == SPRING_TURN => 1.0,
                Kind::GravityStiffness => 0.01,
            })
            .collect()
    }
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
            Kind::GravityStiffness => {
                let phi = GravityPhi::from_named(&self.names, &self.values);
                model.stiffness += gravity_stiffness(ctx, model, &phi, &self.slots)?;
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
        }
        Ok(())
    }
    /// A residual flexibility `R_ce` reaches the FRF of c and e (the `at_channels[c]` of
    /// the mode driven by e alone); everything else reaches any FRF.
    fn parameter_reach(&self, g: &Geometry) -> Vec<Reach> {
        let n = self.values.len();
        let (n_ch, n_ex) = (g.channels.len(), g.excitations.len());
        (0..n)
            .map(|i| match self.kind {
                Kind::ResidualFlexibility if n == n_ch * n_ex + 2 && i < n - 2 => Reach::Cell {
                    channel: i % n_ch,
                    excitation: i / n_ch,
                },
                _ => Reach::Any,
            })
            .collect()
    }
}

/// The local forms ([`ALL`], in order) not in the spec and not already offered by the
/// catalogue. Gravity stiffness is screened by a cord-length profile when the nominal
/// model has free directions, the others by a score.
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
            screening: if k == Kind::GravityStiffness && has_free {
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
