//! The sensor chain beyond geometry (docs/physics.md, E2, E11):
//!
//! - `transducer_highpass`: the IEPE discharge / AC coupling of a response channel is a
//!   first-order high-pass, so the channel's FRF is multiplied by `iωτ/(1 + iωτ)`
//!   (evaluated at `s = iω + σ` under an exponential window, like every factor). The
//!   force channel is taken as unfiltered (a quartz gauge, τ ≥ 100 s); a common filter
//!   on force and response would cancel.
//! - `sensor_tilt_gravity`: an accelerometer senses specific force. A small body
//!   rotation θ turns gravity `−g ẑ` (ẑ up) in body axes into `−g(ẑ − θ×ẑ)`, so the
//!   sensed specific force is `a + g ẑ − g θ×ẑ = a + g ẑ + g [ẑ]×θ`; without the static
//!   part, channel c reads `s_cᵀ(a + g [ẑ]×θ)`, i.e. the row gains the term
//!   `g s_cᵀ [0 | [ẑ]×]` in accelerance (`/s²` for mobility and receptance, obtained by
//!   integrating the accelerometer signal). Horizontal channels see it, only through
//!   rotation about horizontal axes; poles do not move. `s_c` is the row's current
//!   translational part (gains and misorientation compose), so this effect applies
//!   after the other output effects.
//! - `channel_delay`: the acquisition chain delays channel c's signal by τ_c
//!   (multiplexed-ADC skew, mismatched anti-alias filter group delays, a digital
//!   sensor's latency) and excitation e's force by τ_e, so the measured FRF is
//!   `H_ce(ω) e^{−iω(τ_c − τ_e)}`. Only the differences τ_c − τ_e are seen: a common
//!   delay of every signal cancels. Under an exponential window (applied to the delayed
//!   records) the exact factor is `e^{−(iω+σ)(τ_c − τ_e)}`; its extra real part
//!   `e^{−σ(τ_c − τ_e)}` is a channel gain within σ|τ_c − τ_e| (3·10⁻⁴ for σ = 0.3/s,
//!   1 ms) of 1, and is left out.

use super::screening::{
    Build, Reciprocal, Screened, ScreeningForm, ScreeningKind, ScreeningResult,
};
use super::{BuildContext, Effect, OutputBlock, ParamInfo};
use crate::model::DynamicModel;
use crate::spec::CampaignSpec;
use nalgebra::RowVector6;
use rbprops_core::c64;
use rbprops_core::{cross_matrix, Geometry, Vec3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// `transducer_highpass`: a response channel's first-order high-pass `iωτ/(1 + iωτ)` (IEPE, AC coupling).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransducerHighpass {
    /// Time constant τ (s) of every response channel.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_constant_s: Option<f64>,
    /// Time constant τ (s) per channel id; overrides `time_constant_s` for those listed.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub time_constants_s: BTreeMap<String, f64>,
}

impl TransducerHighpass {
    fn all(&self) -> Vec<f64> {
        super::common_and_map_values(self.time_constant_s, &self.time_constants_s)
    }
}

impl TransducerHighpass {
    /// The catalogue id (the spec's `id = "transducer_highpass"`).
    pub const ID: &'static str = "transducer_highpass";
}

impl Effect for TransducerHighpass {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        super::common_and_map_info(
            "time_constant_s",
            self.time_constant_s,
            "time_constants_s",
            &self.time_constants_s,
            "s",
            (0.5, 10.0),
        )
    }
    fn values(&self) -> Vec<f64> {
        self.all()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let (time_constant_s, time_constants_s) =
            super::replace_common_and_map(self.time_constant_s, &self.time_constants_s, values)?;
        let e = TransducerHighpass {
            time_constant_s,
            time_constants_s,
        };
        super::checked(e)
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check_values(&self) -> Result<(), String> {
        if self.time_constant_s.is_none() && self.time_constants_s.is_empty() {
            return Err(
                "give time_constant_s (all channels) and/or time_constants_s (per channel)".into(),
            );
        }
        if let Some(t) = self.all().iter().find(|t| !(t.is_finite() && **t > 0.0)) {
            return Err(format!(
                "time constants must be positive and finite, got {t}"
            ));
        }
        Ok(())
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_values()?;
        super::check_channels_defined(spec, "time_constants_s", self.time_constants_s.keys())
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        let n = ctx.geometry.channels.len();
        let hp = &mut model.observation.highpass_time_constants_s;
        hp.resize(n, Vec::new());
        for (c, ch) in ctx.geometry.channels.iter().enumerate() {
            if let Some(t) = self
                .time_constants_s
                .get(&ch.id)
                .copied()
                .or(self.time_constant_s)
            {
                hp[c].push(t);
            }
        }
        Ok(())
    }
}

/// `sensor_tilt_gravity`: accelerometers sense specific force, so a rotating body tilts gravity into them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorTiltGravity {
    /// Gravitational acceleration (m/s²).
    #[serde(default = "super::default_g")]
    pub g_m_per_s2: f64,
    /// Upward unit vector in the geometry frame.
    #[serde(default = "super::default_up")]
    pub up: [f64; 3],
}

impl SensorTiltGravity {
    /// The catalogue id (the spec's `id = "sensor_tilt_gravity"`).
    pub const ID: &'static str = "sensor_tilt_gravity";
}

impl Effect for SensorTiltGravity {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn order(&self) -> u8 {
        2
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        vec![super::positive_info(
            "g_m_per_s2".into(),
            "m/s2",
            (9.78, 9.84),
        )]
    }
    fn values(&self) -> Vec<f64> {
        vec![self.g_m_per_s2]
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let e = SensorTiltGravity {
            g_m_per_s2: super::single_value(values)?,
            ..self.clone()
        };
        super::checked(e)
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check_values(&self) -> Result<(), String> {
        if !(self.g_m_per_s2.is_finite() && self.g_m_per_s2 >= 0.0) {
            return Err(format!(
                "g_m_per_s2 must be finite and ≥ 0, got {}",
                self.g_m_per_s2
            ));
        }
        super::check_unit_vector("up", self.up)
    }
    fn modify_structure(
        &self,
        _ctx: &BuildContext,
        model: &mut DynamicModel,
    ) -> Result<(), String> {
        let zx = self.g_m_per_s2 * cross_matrix(&Vec3::from(self.up));
        let rows = &mut model.observation.gravity_rows;
        rows.resize(model.outputs.len(), RowVector6::zeros());
        for (g, row) in rows.iter_mut().zip(&model.outputs) {
            let s = Vec3::new(row[0], row[1], row[2]);
            let t = s.transpose() * zx;
            for i in 0..3 {
                g[3 + i] += t[i];
            }
        }
        Ok(())
    }
}

/// `channel_delay` (see the module docs): H_ce(ω) × e^{−iω(τ_c − τ_e)}.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChannelDelay {
    /// Delay τ_c (s) per response channel id; channels not listed are not delayed.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub channels_s: BTreeMap<String, f64>,
    /// Delay τ_e (s) of the force per excitation id.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub excitations_s: BTreeMap<String, f64>,
}

/// Delays beyond a second are not an acquisition chain's (and alias the phase on any
/// line spacing a rigid-body test uses).
const MAX_DELAY_S: f64 = 1.0;

impl ChannelDelay {
    /// The catalogue id (the spec's `id = "channel_delay"`).
    pub const ID: &'static str = "channel_delay";
}

impl Effect for ChannelDelay {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        let info = |name: String| super::symmetric_info(name, "s", MAX_DELAY_S, 1e-3);
        self.channels_s
            .keys()
            .map(|k| info(format!("channels_s.{k}")))
            .chain(
                self.excitations_s
                    .keys()
                    .map(|k| info(format!("excitations_s.{k}"))),
            )
            .collect()
    }
    fn values(&self) -> Vec<f64> {
        self.channels_s
            .values()
            .chain(self.excitations_s.values())
            .copied()
            .collect()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let (channels, excitations) =
            super::split_values(values, self.channels_s.len(), self.excitations_s.len())?;
        let e = ChannelDelay {
            channels_s: super::replace_map(&self.channels_s, channels)?,
            excitations_s: super::replace_map(&self.excitations_s, excitations)?,
        };
        super::checked(e)
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check_values(&self) -> Result<(), String> {
        for (k, t) in self.channels_s.iter().chain(&self.excitations_s) {
            if !(t.is_finite() && t.abs() <= MAX_DELAY_S) {
                return Err(format!(
                    "delay of '{k}' must be finite and within ±{MAX_DELAY_S} s, got {t}"
                ));
            }
        }
        Ok(())
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_values()?;
        super::check_channels_defined(spec, "channels_s", self.channels_s.keys())?;
        super::check_excitations_defined(spec, "excitations_s", self.excitations_s.keys())
    }
    fn transform_output(&self, block: &mut OutputBlock) {
        let g = block.geometry;
        let tau_e = self
            .excitations_s
            .get(&g.excitations[block.excitation].id)
            .copied()
            .unwrap_or(0.0);
        let nl = block.frequency_hz.len();
        for (c, row) in block.values.chunks_exact_mut(nl).enumerate() {
            let tau = self
                .channels_s
                .get(&g.channels[c].id)
                .copied()
                .unwrap_or(0.0)
                - tau_e;
            if tau != 0.0 {
                for (h, f) in row.iter_mut().zip(block.frequency_hz) {
                    *h *= c64::from_polar(1.0, -std::f64::consts::TAU * f * tau);
                }
            }
        }
    }
}

/// This module's effects in the physics catalogue ([`super::registry`]).
/// Plausible: AC-coupling corners of at most 5 Hz (IEPE accelerometers and AC-coupled
/// inputs have corners of 0.1–3 Hz).
fn plausible_highpass(
    entry: &crate::spec::EffectSpec,
    _spec: &CampaignSpec,
) -> Result<Vec<super::Plausible>, String> {
    let e: TransducerHighpass = super::params(entry)?;
    let mut v: Vec<super::Plausible> = e
        .time_constants_s
        .iter()
        .map(|(k, t)| {
            super::Plausible::new(
                format!("sensor {k}: corner"),
                "Hz",
                1.0 / (std::f64::consts::TAU * t),
                [0.0, 5.0],
            )
        })
        .collect();
    if let Some(t) = e.time_constant_s {
        v.push(super::Plausible::new(
            "every sensor: corner",
            "Hz",
            1.0 / (std::f64::consts::TAU * t),
            [0.0, 5.0],
        ));
    }
    Ok(v)
}

/// Plausible: delays of at most 10 ms either way (sampling skew and anti-alias filter
/// group delays are a few samples, well under a millisecond to a few).
fn plausible_delay(
    entry: &crate::spec::EffectSpec,
    _spec: &CampaignSpec,
) -> Result<Vec<super::Plausible>, String> {
    let e: ChannelDelay = super::params(entry)?;
    Ok(e.channels_s
        .iter()
        .map(|(k, d)| (format!("channel {k}: delay"), d))
        .chain(
            e.excitations_s
                .iter()
                .map(|(k, d)| (format!("excitation {k}: delay"), d)),
        )
        .map(|(q, d)| super::Plausible::new(q, "ms", 1e3 * d, [-10.0, 10.0]))
        .collect())
}

/// The sensors of a geometry: the channels at each point, in first-channel order. The
/// channels of one sensor share its conditioner, so they share a high-pass.
fn sensor_channels(g: &Geometry) -> Vec<(String, Vec<String>)> {
    let mut out: Vec<(String, Vec<String>)> = Vec::new();
    for c in &g.channels {
        match out.iter_mut().find(|(p, _)| *p == c.point) {
            Some((_, ids)) => ids.push(c.id.clone()),
            None => out.push((c.point.clone(), vec![c.id.clone()])),
        }
    }
    out
}

/// `transducer_highpass` with one time constant τ_j per sensor (the channels at one
/// point), through φ_j = 1/τ_j: mixed sensor types (an IEPE triaxial with τ = 1 s among
/// DC-coupled ones) are as common as one τ for all, which is the case φ_j all equal.
fn highpass_build(sensors: Vec<(String, Vec<String>)>) -> Build {
    std::sync::Arc::new(move |v: &[f64]| {
        if let Some(x) = v.iter().find(|x| !(x.is_finite() && **x >= 0.0)) {
            return Err(format!("1/τ must be finite and ≥ 0, got {x}"));
        }
        let mut per_channel = toml::Table::new();
        for ((_, channels), &phi) in sensors.iter().zip(v) {
            if phi > 0.0 {
                for c in channels {
                    per_channel.insert(c.clone(), (1.0 / phi).into());
                }
            }
        }
        if per_channel.is_empty() {
            return Ok(None);
        }
        let mut t = toml::Table::new();
        t.insert("time_constants_s".into(), per_channel.into());
        super::parse_effect(&crate::spec::EffectSpec {
            id: TransducerHighpass::ID.into(),
            parameters: t,
        })
        .map(Some)
    })
}

/// `transducer_highpass`'s screening form: reparametrised by inverse time constants (one
/// per sensor, [`Reciprocal`]), so that its neutral value, no high-pass, is 0 rather than
/// an infinite time constant; screened by a score.
fn screen_transducer_highpass(_spec: &CampaignSpec, geometry: &Geometry) -> ScreeningResult {
    let groups = sensor_channels(geometry);
    let infos: Vec<ParamInfo> = groups
        .iter()
        .map(|(sensor, _)| ParamInfo {
            name: format!("inverse_time_constant_per_s.{sensor}"),
            unit: "1/s",
            lower: 0.0,
            upper: f64::INFINITY,
            plausible: (0.0, 2.0),
        })
        .collect();
    let n = infos.len();
    Ok(Some(ScreeningForm {
        effect: Box::new(Reciprocal::new(
            TransducerHighpass::ID,
            infos,
            vec![0.0; n],
            highpass_build(groups),
        )),
        neutral: vec![0.0; n],
        scales: vec![0.05; n],
        source: "rbprops-sim (reparametrised for screening)",
        screening: ScreeningKind::Score,
    }))
}

pub(crate) const DESCRIPTORS: &[super::EffectDescriptor] = &[
    super::EffectDescriptor {
        id: TransducerHighpass::ID,
        rank: 14,
        title: "transducer / acquisition high-pass",
        reveal: "the channels' time constants, or data below the suspension modes",
        docs: "E11: a first-order high-pass per channel, `time_constant_s` or `time_constants_s`",
        parse: super::parse_as::<TransducerHighpass>,
        neutral: super::NeutralForm::Screened(Screened {
            rank: 2,
            form: screen_transducer_highpass,
        }),
        follows_spec_up: false,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/transducer_highpass.toml"),
        plausible: Some(plausible_highpass),
    },
    super::EffectDescriptor {
        id: SensorTiltGravity::ID,
        rank: 15,
        title: "gravity seen by tilting accelerometers",
        reveal: "data well below the suspension modes, or a rotation sensor",
        docs: "E2: gravity in the sensor equation of rotating accelerometers, `g_m_per_s2`, `up`",
        parse: super::parse_as::<SensorTiltGravity>,
        neutral: super::NeutralForm::Table(|spec, _| {
            let mut t = super::table([("g_m_per_s2", 0.0.into())]);
            if let Some(up) = spec.up {
                t.insert("up".into(), crate::spec::up_value(up));
            }
            t
        }),
        follows_spec_up: true,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/sensor_tilt_gravity.toml"),
        plausible: None,
    },
    super::EffectDescriptor {
        id: ChannelDelay::ID,
        rank: 18,
        title: "acquisition delay per channel (ADC skew, filter group delay)",
        reveal: "a loop-back calibration of each channel's delay against the force channel",
        docs: "E15: a delay per channel and per force, `channels_s`, `excitations_s` (only differences are seen)",
        parse: super::parse_as::<ChannelDelay>,
        neutral: super::NeutralForm::Table(|_, g| {
            let mut t = super::per_channel_table(g, "channels_s", 0.0.into());
            t.extend(super::per_excitation_table(g, "excitations_s", 0.0.into()));
            t
        }),
        follows_spec_up: false,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/channel_delay.toml"),
        plausible: Some(plausible_delay),
    },
];
