//! The planning model: a campaign spec's rigid body, suspension modes, frequency axis,
//! measured quantity and noise model, and the layout (sensors and hits) being judged.

use crate::PlanError;
use nalgebra::RowVector6;
use rbprops_core::modal::RigidMode;
use rbprops_core::noise::NoiseModel;
use rbprops_core::{rigid_transform, Quantity, Vec3, Vec6};
use rbprops_sim::CampaignSpec;

/// One suspension set-up's true rigid-body modes (mass-normalised, about the geometry
/// origin), as `frf-sim` builds them.
#[derive(Debug, Clone)]
pub struct SetupModes {
    /// Set-up id of the spec.
    pub id: String,
    /// The six modes, ascending frequency.
    pub modes: Vec<RigidMode>,
}

/// Everything the covariance of a layout depends on besides the layout itself.
#[derive(Debug, Clone)]
pub struct PlanModel {
    /// Measured quantity of the FRFs (the noise model applies to it).
    pub quantity: Quantity,
    /// Angular frequency of every line the modal fit sees (rad/s): the spec's axis
    /// without a 0 Hz line (a line where every FRF of the measured quantity is 0 or a
    /// free direction's infinity carries nothing a fit can use).
    pub omega: Vec<f64>,
    /// True when the spec's axis starts above 0 Hz (the fit then carries the lower
    /// residual term, `rbprops_modal::lsfd::Residuals::for_band`).
    pub lower_residual: bool,
    /// The FRF noise `E|ε|² = a²|H|² + b²` (docs/conventions.md §8).
    pub noise: NoiseModel,
    /// The set-ups' modes.
    pub setups: Vec<SetupModes>,
    /// The true ten properties (m, c, J about the CoM; docs/conventions.md §3).
    pub truth: [f64; 10],
    /// Property scales for the relative criteria: `m`, a length `ℓ = √(tr J/m)` for the
    /// centre of mass and `tr J/3` for the moments and products.
    pub scales: [f64; 10],
}

impl PlanModel {
    /// The model of a spec: its nominal rigid body on its suspension, modal damping as
    /// the spec says, its axis and noise. Real-test effects (`[[effect]]`) are not part of
    /// the plan: the plan is made on the nominal model.
    pub fn from_spec(spec: &CampaignSpec) -> Result<Self, PlanError> {
        let geometry = spec
            .geometry()
            .map_err(|e| PlanError::Spec(e.to_string()))?;
        let models = rbprops_sim::build_models(spec, &geometry, &[])
            .map_err(|e| PlanError::Spec(e.to_string()))?;
        let mut setups = Vec::new();
        for m in models {
            if let Some(free) = m.modes.iter().position(|r| r.is_free()) {
                return Err(PlanError::Spec(format!(
                    "set-up '{}': mode {} is a free direction (0 Hz): the modal estimators need six suspension modes",
                    m.model.setup,
                    free + 1
                )));
            }
            setups.push(SetupModes {
                id: m.model.setup.clone(),
                modes: m.modes,
            });
        }
        let hz = spec.frequency_axis();
        let omega: Vec<f64> = hz
            .iter()
            .filter(|f| **f > 0.0)
            .map(|f| 2.0 * std::f64::consts::PI * f)
            .collect();
        if omega.len() < 16 {
            return Err(PlanError::Spec(format!(
                "the frequency axis has {} lines above 0 Hz; a modal fit needs many more",
                omega.len()
            )));
        }
        let props = spec.properties();
        let truth = rbprops_inertia::property_vector(&props);
        Ok(Self {
            quantity: spec.quantity,
            omega,
            lower_residual: hz.first().is_some_and(|f| *f > 0.0),
            noise: NoiseModel::new(spec.noise.relative, spec.noise.floor),
            setups,
            scales: property_scales(&truth),
            truth,
        })
    }

    /// A coarser model for the selection's search: the lines within ±10 half-power
    /// half-bandwidths of every mode of every set-up (2 per half-bandwidth) and a 64-line
    /// skeleton. It ranks layouts as the full model does at a fraction of the cost; the
    /// planned layout's reported prediction always uses the full model.
    pub fn search_model(&self) -> PlanModel {
        let band = rbprops_modal::band::BandData {
            quantity: self.quantity,
            frequency_hz: self
                .omega
                .iter()
                .map(|w| w / (2.0 * std::f64::consts::PI))
                .collect(),
            omega: self.omega.clone(),
            channels: Vec::new(),
            first_line: 0,
            line_quality: None,
        };
        let poles: Vec<rbprops_modal::Pole> = self
            .setups
            .iter()
            .flat_map(|s| s.modes.iter())
            .map(|m| rbprops_modal::Pole::from_modal(m.frequency_hz, m.damping_ratio))
            .collect();
        let keep = band.focus_indices(&poles, 10.0, 2.0, 64);
        let mut m = self.clone();
        m.omega = keep.iter().map(|&k| self.omega[k]).collect();
        m
    }

    /// The two closest modes of set-up `setup` and their distance in half-power
    /// half-bandwidths (`rbprops_modal::Pole::distance_in_bandwidths`, the measure
    /// `modal-fit`'s evidence for a poly-reference fit uses).
    pub fn closest_modes(&self, setup: usize) -> Option<(usize, usize, f64)> {
        let poles: Vec<rbprops_modal::Pole> = self.setups[setup]
            .modes
            .iter()
            .map(|m| rbprops_modal::Pole::from_modal(m.frequency_hz, m.damping_ratio))
            .collect();
        let mut best: Option<(usize, usize, f64)> = None;
        for r in 0..poles.len() {
            for t in r + 1..poles.len() {
                let d = poles[r].distance_in_bandwidths(&poles[t]);
                if best.is_none_or(|b| d < b.2) {
                    best = Some((r, t, d));
                }
            }
        }
        best
    }

    /// Index of a set-up by id.
    pub fn setup_index(&self, id: &str) -> Option<usize> {
        self.setups.iter().position(|s| s.id == id)
    }
}

/// Scales of the ten properties for relative statements: `m` for the mass, the radius of
/// gyration `ℓ = √(tr J/m)` for every centre-of-mass coordinate (a coordinate can be 0),
/// `tr J/3` for every moment and product (a product can be 0).
pub fn property_scales(p: &[f64; 10]) -> [f64; 10] {
    let m = p[0].abs();
    let tr = p[4] + p[5] + p[6];
    let l = (tr / m).abs().sqrt();
    std::array::from_fn(|k| match k {
        0 => m,
        1..=3 => l,
        _ => tr / 3.0,
    })
}

/// A triaxial sensor: three channels along the axes of its frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Sensor {
    /// Id (a point id of the candidates or the spec's sensor id).
    pub id: String,
    /// Position, geometry frame (m).
    pub position: Vec3,
    /// The three channel directions (unit, geometry frame).
    pub axes: [Vec3; 3],
}

impl Sensor {
    /// A sensor along the geometry's axes.
    pub fn triaxial(id: &str, position: Vec3) -> Self {
        Self {
            id: id.to_string(),
            position,
            axes: [Vec3::x(), Vec3::y(), Vec3::z()],
        }
    }

    /// The channel rows `sᵀT(p)` (docs/conventions.md §2).
    pub fn rows(&self) -> [RowVector6<f64>; 3] {
        let t = rigid_transform(&self.position);
        self.axes.map(|s| s.transpose() * t)
    }
}

/// An impact: a unit force direction at a point, on one set-up.
#[derive(Debug, Clone, PartialEq)]
pub struct Hit {
    /// Id (the candidate point's id or the spec's excitation id).
    pub id: String,
    /// Position, geometry frame (m).
    pub position: Vec3,
    /// Unit force direction.
    pub direction: Vec3,
    /// Index of the set-up in [`PlanModel::setups`].
    pub setup: usize,
}

impl Hit {
    /// The force column `T(p)ᵀd` (docs/conventions.md §2).
    pub fn column(&self) -> Vec6 {
        rigid_transform(&self.position).transpose() * self.direction
    }
}

/// A test layout: sensors and hits.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Layout {
    /// Triaxial sensors (every channel of the spec's sensors, grouped by sensor).
    pub sensors: Vec<Sensor>,
    /// Impacts.
    pub hits: Vec<Hit>,
}

impl Layout {
    /// The spec's own layout. The plan works with triaxial sensors: a spec with a
    /// uniaxial sensor is refused, the sensor named.
    pub fn from_spec(spec: &CampaignSpec, model: &PlanModel) -> Result<Self, PlanError> {
        let geometry = spec
            .geometry()
            .map_err(|e| PlanError::Spec(e.to_string()))?;
        let mut sensors: Vec<Sensor> = Vec::new();
        for s in &spec.sensors {
            let chans: Vec<_> = geometry
                .channels
                .iter()
                .filter(|c| c.point == s.id)
                .collect();
            let dirs: Vec<Vec3> = chans.iter().map(|c| c.direction).collect();
            if dirs.len() != 3 {
                return Err(PlanError::Spec(format!(
                    "sensor '{}' has {} channels: the plan works with triaxial sensors",
                    s.id,
                    dirs.len()
                )));
            }
            sensors.push(Sensor {
                id: s.id.clone(),
                position: Vec3::from(s.at_m),
                axes: [dirs[0], dirs[1], dirs[2]],
            });
        }
        let hits = geometry
            .excitations
            .iter()
            .map(|e| {
                let setup = model.setup_index(&e.setup).ok_or_else(|| {
                    PlanError::Spec(format!(
                        "excitation '{}' names set-up '{}', which the spec does not have",
                        e.id, e.setup
                    ))
                })?;
                Ok(Hit {
                    id: e.id.clone(),
                    position: e.position,
                    direction: e.direction,
                    setup,
                })
            })
            .collect::<Result<_, PlanError>>()?;
        Ok(Self { sensors, hits })
    }

    /// All channel rows, sensor by sensor.
    pub fn rows(&self) -> Vec<RowVector6<f64>> {
        self.sensors.iter().flat_map(|s| s.rows()).collect()
    }
}
