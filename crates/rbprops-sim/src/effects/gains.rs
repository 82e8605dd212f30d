//! Calibration errors (docs/physics.md, E10): real, frequency-independent factors.
//! - `channel_gain`: channel c reads `g_c` times its true value (`S` row c × g_c);
//! - `excitation_gain`: the force of excitation e is `g_e` times what was recorded
//!   (force column × g_e), as with a force-gauge sensitivity error;
//! - `global_gain`: every FRF × g (indistinguishable from 1/mass).

use super::{BuildContext, Effect, ParamInfo};
use crate::model::DynamicModel;
use crate::spec::CampaignSpec;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Plausible range of a calibration gain.
const GAIN_PLAUSIBLE: (f64, f64) = (0.9, 1.1);

fn check_gain(what: &str, g: f64) -> Result<(), String> {
    if g.is_finite() && g > 0.0 {
        Ok(())
    } else {
        Err(format!("{what}: gain must be positive and finite, got {g}"))
    }
}

fn replace_values(
    map: &BTreeMap<String, f64>,
    values: &[f64],
) -> Result<BTreeMap<String, f64>, String> {
    let out = super::replace_map(map, values)?;
    for (k, g) in &out {
        check_gain(k, *g)?;
    }
    Ok(out)
}

/// `channel_gain`: channel calibration errors, channel c reads `g_c` times its true value.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChannelGain {
    /// Gain per channel id (`1x`, `2:3`, …).
    pub gains: BTreeMap<String, f64>,
}

impl ChannelGain {
    /// The catalogue id (the spec's `id = "channel_gain"`).
    pub const ID: &'static str = "channel_gain";
}

impl Effect for ChannelGain {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        super::map_info("gains", &self.gains, "1", GAIN_PLAUSIBLE)
    }
    fn values(&self) -> Vec<f64> {
        self.gains.values().copied().collect()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        Ok(Box::new(ChannelGain {
            gains: replace_values(&self.gains, values)?,
        }))
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        let channels = spec.channels();
        for (k, g) in &self.gains {
            check_gain(k, *g)?;
            if !channels.iter().any(|c| &c.id == k) {
                return Err(format!("gains: channel '{k}' is not defined"));
            }
        }
        Ok(())
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        for (c, ch) in ctx.geometry.channels.iter().enumerate() {
            if let Some(g) = self.gains.get(&ch.id) {
                model.outputs[c] *= *g;
            }
        }
        Ok(())
    }
    /// A gain reaches its channel's FRFs (its output row).
    fn parameter_reach(&self, geometry: &rbprops_core::Geometry) -> Vec<super::Reach> {
        super::channel_reach(self.gains.keys(), 1, geometry, |c| &c.id)
    }
}

/// `excitation_gain`: force calibration errors, the force of excitation e is `g_e` times what was recorded.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExcitationGain {
    /// Gain per excitation id.
    pub gains: BTreeMap<String, f64>,
}

impl ExcitationGain {
    /// The catalogue id (the spec's `id = "excitation_gain"`).
    pub const ID: &'static str = "excitation_gain";
}

impl Effect for ExcitationGain {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        super::map_info("gains", &self.gains, "1", GAIN_PLAUSIBLE)
    }
    fn values(&self) -> Vec<f64> {
        self.gains.values().copied().collect()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        Ok(Box::new(ExcitationGain {
            gains: replace_values(&self.gains, values)?,
        }))
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        for (k, g) in &self.gains {
            check_gain(k, *g)?;
            if !spec.excitations.iter().any(|e| &e.id == k) {
                return Err(format!("gains: excitation '{k}' is not defined"));
            }
        }
        Ok(())
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        for input in &mut model.inputs {
            if let Some(g) = self
                .gains
                .get(&ctx.geometry.excitations[input.excitation].id)
            {
                input.column *= *g;
            }
        }
        Ok(())
    }
    /// A gain reaches its excitation's FRFs (its input column).
    fn parameter_reach(&self, geometry: &rbprops_core::Geometry) -> Vec<super::Reach> {
        super::excitation_reach(self.gains.keys(), 1, geometry)
    }
}

/// `global_gain`: every FRF times `g` (indistinguishable from 1/mass).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GlobalGain {
    /// The common factor `g`.
    pub gain: f64,
}

impl GlobalGain {
    /// The catalogue id (the spec's `id = "global_gain"`).
    pub const ID: &'static str = "global_gain";
}

impl Effect for GlobalGain {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        vec![super::positive_info("gain".into(), "1", GAIN_PLAUSIBLE)]
    }
    fn values(&self) -> Vec<f64> {
        vec![self.gain]
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        super::checked(GlobalGain {
            gain: super::single_value(values)?,
        })
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check_values(&self) -> Result<(), String> {
        check_gain("gain", self.gain)
    }
    fn modify_structure(
        &self,
        _ctx: &BuildContext,
        model: &mut DynamicModel,
    ) -> Result<(), String> {
        for row in &mut model.outputs {
            *row *= self.gain;
        }
        Ok(())
    }
}

/// This module's effects in the physics catalogue ([`super::registry`]).
/// Plausible: a gain between 0.8 and 1.25 (−20 % … +25 %, symmetric in log). Calibration
/// sheets hold sensitivities to a few percent, a temperature or cable effect a few more; a
/// wrong sensitivity typed in is usually a factor (×2, ×10, a unit) that a tester sees.
fn plausible_channel_gain(
    entry: &crate::spec::EffectSpec,
    _spec: &CampaignSpec,
) -> Result<Vec<super::Plausible>, String> {
    let e: ChannelGain = super::params(entry)?;
    Ok(gains_pct("channel", &e.gains))
}

/// Plausible: a gain between 0.8 and 1.25 (−20 % … +25 %, symmetric in log). Calibration
/// sheets hold sensitivities to a few percent, a temperature or cable effect a few more; a
/// wrong sensitivity typed in is usually a factor (×2, ×10, a unit) that a tester sees.
fn plausible_excitation_gain(
    entry: &crate::spec::EffectSpec,
    _spec: &CampaignSpec,
) -> Result<Vec<super::Plausible>, String> {
    let e: ExcitationGain = super::params(entry)?;
    Ok(gains_pct("excitation", &e.gains))
}

/// Plausible: a gain between 0.8 and 1.25 (−20 % … +25 %, symmetric in log). Calibration
/// sheets hold sensitivities to a few percent, a temperature or cable effect a few more; a
/// wrong sensitivity typed in is usually a factor (×2, ×10, a unit) that a tester sees.
fn plausible_global_gain(
    entry: &crate::spec::EffectSpec,
    _spec: &CampaignSpec,
) -> Result<Vec<super::Plausible>, String> {
    let e: GlobalGain = super::params(entry)?;
    Ok(vec![gain_pct("all FRFs".into(), e.gain)])
}

/// A gain as a percent deviation from 1 with the range of [`plausible_channel_gain`].
fn gain_pct(what: String, g: f64) -> super::Plausible {
    super::Plausible::new(
        format!("{what}: gain"),
        "%",
        100.0 * (g - 1.0),
        [-20.0, 25.0],
    )
}

fn gains_pct(what: &str, gains: &BTreeMap<String, f64>) -> Vec<super::Plausible> {
    gains
        .iter()
        .map(|(k, g)| gain_pct(format!("{what} {k}"), *g))
        .collect()
}

pub(crate) const DESCRIPTORS: &[super::EffectDescriptor] = &[
    super::EffectDescriptor {
        id: ChannelGain::ID,
        rank: 2,
        title: "per-channel calibration error",
        reveal: "a back-to-back calibration of the channels",
        docs: "E10: a real gain per channel, `gains` per channel id",
        parse: super::parse_as::<ChannelGain>,
        neutral: super::NeutralForm::Table(|_, g| {
            super::table([("gains", super::per_id(super::channel_ids(g), 1.0.into()))])
        }),
        follows_spec_up: false,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/channel_gain.toml"),
        plausible: Some(plausible_channel_gain),
    },
    super::EffectDescriptor {
        id: ExcitationGain::ID,
        rank: 3,
        title: "force-gauge sensitivity error per excitation",
        reveal: "a hammer calibration against a known mass",
        docs:
            "E10: a real gain per excitation (force-gauge sensitivity), `gains` per excitation id",
        parse: super::parse_as::<ExcitationGain>,
        neutral: super::NeutralForm::Table(|_, g| {
            super::table([("gains", super::per_id(super::excitation_ids(g), 1.0.into()))])
        }),
        follows_spec_up: false,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/excitation_gain.toml"),
        plausible: Some(plausible_excitation_gain),
    },
    super::EffectDescriptor {
        id: GlobalGain::ID,
        rank: 4,
        title: "global calibration error",
        reveal: "a weighed mass (--weighed-mass) or a calibration against a known mass",
        docs: "E10: one real gain on every FRF, `gain` (indistinguishable from the mass)",
        parse: super::parse_as::<GlobalGain>,
        neutral: super::NeutralForm::Table(|_, _| super::table([("gain", 1.0.into())])),
        follows_spec_up: false,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/global_gain.toml"),
        plausible: Some(plausible_global_gain),
    },
];
