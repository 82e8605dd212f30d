//! The physics catalogue: effects that modify the nominal model (see
//! docs/physics.md). Each effect is switched on in the spec as
//! `[[effect]] id = "..."` with its parameters.
//!
//! Implemented: `gravity_stiffness`, `sensor_mass`, `added_mass` ([`mass`]), `channel_gain`, `excitation_gain`,
//! `global_gain`, `sensor_misorientation` (structure and rows); `elastic_mode`
//! ([`elastic`]); `nonproportional_damping`, `hysteretic_damping` ([`damping`]); `exponential_window`,
//! `record_truncation` ([`processing`]); `sensor_position`, `force_direction`,
//! `force_location`, `force_gauge_mass` ([`placement`]); `transducer_highpass`,
//! `sensor_tilt_gravity`, `channel_delay` ([`sensors`]); `suspension_coupling`, `suspension_drift`, `stinger_stiffness` ([`mounts`]); `cord_mass`
//! ([`cords`]). Each effect is a plain struct deserialised from
//! its spec table (unknown parameters are refused) that implements [`Effect`].

pub mod cords;
pub mod damping;
pub mod elastic;
pub mod gains;
pub mod gravity;
pub mod mass;
pub mod mounts;
pub mod orientation;
pub mod placement;
pub mod processing;
pub mod sensors;

use crate::model::DynamicModel;
use crate::spec::{CampaignSpec, EffectSpec};
use rbprops_core::records::EffectRecord;
use rbprops_core::{c64, Geometry, RigidBodyProperties};

/// Description of one effect parameter, for fitters and for documentation.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamInfo {
    pub name: String,
    pub unit: &'static str,
    /// Hard bounds: values outside make the effect unphysical.
    pub lower: f64,
    pub upper: f64,
    /// Plausible range in real tests (for priors and starting values).
    pub plausible: (f64, f64),
}

/// What an effect may need to know about the campaign while it modifies a model.
pub struct BuildContext<'a> {
    pub spec: &'a CampaignSpec,
    pub properties: &'a RigidBodyProperties,
    pub geometry: &'a Geometry,
    /// Index of the set-up whose model is being built.
    pub setup_index: usize,
}

/// One block of FRFs (all channels of one excitation, `[channel][line]`, receptance)
/// handed to [`Effect::transform_output`].
pub struct OutputBlock<'a> {
    /// The campaign's geometry (channel and excitation ids, in the block's order).
    pub geometry: &'a Geometry,
    pub excitation: usize,
    pub frequency_hz: &'a [f64],
    pub n_channels: usize,
    pub values: &'a mut [c64],
}

/// An effect of the physics catalogue. Effects act in three places, in this order:
/// on the structure (M, K, outputs, inputs, extra modes) before the nominal damping is
/// assembled from the resulting modes; on the damping after it; and on the computed
/// receptance FRFs (before quantity conversion and noise). `transform_output` must act
/// as a per-line, per-channel gain (it then commutes with the quantity conversion): for
/// inputs observed through [`crate::observe`] it receives values already in the
/// campaign's quantity.
pub trait Effect: Send + Sync + std::fmt::Debug {
    /// Stable snake_case id, as written in the spec.
    fn id(&self) -> &'static str;
    /// The effect's numeric parameters with bounds, in [`Self::values`] order.
    fn parameters(&self) -> Vec<ParamInfo>;
    /// Current numeric parameter values.
    fn values(&self) -> Vec<f64>;
    /// The same effect with other numeric parameter values (for fitting).
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String>;
    /// The parameters as a JSON object, for `TruthRecord.effects`.
    fn parameters_json(&self) -> serde_json::Value;
    /// Checks the parameters against the campaign (ids exist, counts match, bounds).
    fn check(&self, _spec: &CampaignSpec) -> Result<(), String> {
        Ok(())
    }
    /// Effects apply in ascending order (stable in spec order): masses (0) before
    /// everything else (1), so that gravity sees the loaded body; gravity in the sensor
    /// equation (2) last, so that it sees the final output rows; `cord_mass` (2) reduces
    /// the final M and K and reads the final rows and columns; `suspension_drift` (2)
    /// scales the stiffness built before it.
    fn order(&self) -> u8 {
        1
    }
    fn modify_structure(
        &self,
        _ctx: &BuildContext,
        _model: &mut DynamicModel,
    ) -> Result<(), String> {
        Ok(())
    }
    fn modify_damping(&self, _ctx: &BuildContext, _model: &mut DynamicModel) -> Result<(), String> {
        Ok(())
    }
    fn transform_output(&self, _block: &mut OutputBlock) {}
    fn record(&self) -> EffectRecord {
        EffectRecord {
            id: self.id().to_string(),
            parameters: self.parameters_json(),
        }
    }
}

/// Ids of the effects this version knows.
pub const KNOWN_EFFECTS: &[&str] = &[
    "gravity_stiffness",
    "sensor_mass",
    "channel_gain",
    "excitation_gain",
    "global_gain",
    "sensor_misorientation",
    "elastic_mode",
    "nonproportional_damping",
    "exponential_window",
    "record_truncation",
    "sensor_position",
    "force_direction",
    "force_location",
    "force_gauge_mass",
    "transducer_highpass",
    "sensor_tilt_gravity",
    "suspension_coupling",
    "cord_mass",
    "channel_delay",
    "suspension_drift",
    "added_mass",
    "stinger_stiffness",
    "hysteretic_damping",
];

/// Serde default of `g_m_per_s2` for the gravity-related effects (standard gravity).
pub(crate) fn default_g() -> f64 {
    gravity::STANDARD_GRAVITY
}

/// Serde default of `up`: the geometry's +z axis points up.
pub(crate) fn default_up() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

/// Parameter descriptions of a per-spring (or per-cord) list `name[i]`.
pub(crate) fn list_info(
    name: &str,
    unit: &'static str,
    n: usize,
    plausible: (f64, f64),
) -> Vec<ParamInfo> {
    (0..n)
        .map(|i| ParamInfo {
            name: format!("{name}[{i}]"),
            unit,
            lower: 0.0,
            upper: f64::INFINITY,
            plausible,
        })
        .collect()
}

/// Parameter descriptions of a per-id map parameter, `name.{id}` in key order.
pub(crate) fn map_info(
    name: &str,
    map: &std::collections::BTreeMap<String, f64>,
    unit: &'static str,
    plausible: (f64, f64),
) -> Vec<ParamInfo> {
    map.keys()
        .map(|k| ParamInfo {
            name: format!("{name}.{k}"),
            unit,
            lower: 0.0,
            upper: f64::INFINITY,
            plausible,
        })
        .collect()
}

/// `values` (a fitter's new values, in key order) as a replacement of a per-id map.
pub(crate) fn replace_map(
    map: &std::collections::BTreeMap<String, f64>,
    values: &[f64],
) -> Result<std::collections::BTreeMap<String, f64>, String> {
    if values.len() != map.len() {
        return Err(format!(
            "expected {} values, got {}",
            map.len(),
            values.len()
        ));
    }
    Ok(map.keys().cloned().zip(values.iter().copied()).collect())
}

/// `values` (three per id, in key order) as a replacement of a per-id map of 3-vectors.
pub(crate) fn replace_vec3_map(
    map: &std::collections::BTreeMap<String, [f64; 3]>,
    values: &[f64],
) -> Result<std::collections::BTreeMap<String, [f64; 3]>, String> {
    if values.len() != 3 * map.len() {
        return Err(format!(
            "expected {} values, got {}",
            3 * map.len(),
            values.len()
        ));
    }
    Ok(map
        .keys()
        .zip(values.chunks_exact(3))
        .map(|(k, v)| (k.clone(), [v[0], v[1], v[2]]))
        .collect())
}

/// `values` split into two concatenated lists of lengths `na` and `nb` (a fitter's new
/// values for an effect with two parameter lists).
pub(crate) fn split_values(
    values: &[f64],
    na: usize,
    nb: usize,
) -> Result<(&[f64], &[f64]), String> {
    if values.len() != na + nb {
        return Err(format!("expected {} values, got {}", na + nb, values.len()));
    }
    Ok(values.split_at(na))
}

/// `values` as a replacement of a list parameter of length `n` (a fitter's new values).
pub(crate) fn replace_list(n: usize, values: &[f64]) -> Result<Vec<f64>, String> {
    if values.len() != n {
        return Err(format!("expected {n} values, got {}", values.len()));
    }
    Ok(values.to_vec())
}

/// Checks that an optional set-up id names a set-up of the spec.
pub(crate) fn check_setup(spec: &CampaignSpec, setup: Option<&str>) -> Result<(), String> {
    match setup {
        Some(id) if !spec.setups.iter().any(|s| s.id == id) => {
            Err(format!("setup: set-up '{id}' is not defined"))
        }
        _ => Ok(()),
    }
}

fn params<T: serde::de::DeserializeOwned>(spec: &EffectSpec) -> Result<T, String> {
    toml::Value::Table(spec.parameters.clone())
        .try_into()
        .map_err(|e| format!("effect '{}': {}", spec.id, e.to_string().trim()))
}

/// Builds an effect from its spec entry; the error says what is wrong.
pub fn parse_effect(spec: &EffectSpec) -> Result<Box<dyn Effect>, String> {
    let e: Box<dyn Effect> = match spec.id.as_str() {
        "gravity_stiffness" => {
            let g: gravity::GravityStiffness = params(spec)?;
            g.check_self()?;
            Box::new(g)
        }
        "sensor_mass" => Box::new(params::<mass::SensorMass>(spec)?),
        "channel_gain" => Box::new(params::<gains::ChannelGain>(spec)?),
        "excitation_gain" => Box::new(params::<gains::ExcitationGain>(spec)?),
        "global_gain" => Box::new(params::<gains::GlobalGain>(spec)?),
        "sensor_misorientation" => Box::new(params::<orientation::SensorMisorientation>(spec)?),
        "elastic_mode" => Box::new(params::<elastic::ElasticMode>(spec)?),
        "nonproportional_damping" => Box::new(params::<damping::NonproportionalDamping>(spec)?),
        "exponential_window" => Box::new(params::<processing::ExponentialWindow>(spec)?),
        "record_truncation" => Box::new(params::<processing::RecordTruncation>(spec)?),
        "sensor_position" => Box::new(params::<placement::SensorPosition>(spec)?),
        "force_direction" => Box::new(params::<placement::ForceDirection>(spec)?),
        "force_location" => Box::new(params::<placement::ForceLocation>(spec)?),
        "force_gauge_mass" => Box::new(params::<placement::ForceGaugeMass>(spec)?),
        "transducer_highpass" => Box::new(params::<sensors::TransducerHighpass>(spec)?),
        "sensor_tilt_gravity" => Box::new(params::<sensors::SensorTiltGravity>(spec)?),
        "suspension_coupling" => Box::new(params::<mounts::SuspensionCoupling>(spec)?),
        "channel_delay" => Box::new(params::<sensors::ChannelDelay>(spec)?),
        "suspension_drift" => Box::new(params::<mounts::SuspensionDrift>(spec)?),
        "added_mass" => Box::new(params::<mass::AddedMass>(spec)?),
        "stinger_stiffness" => Box::new(params::<mounts::StingerStiffness>(spec)?),
        "hysteretic_damping" => Box::new(params::<damping::HystereticDamping>(spec)?),
        "cord_mass" => {
            let c: cords::CordMass = params(spec)?;
            c.check_self()
                .map_err(|e| format!("effect 'cord_mass': {e}"))?;
            Box::new(c)
        }
        other => {
            return Err(format!(
                "unknown effect id '{other}' (known: {})",
                KNOWN_EFFECTS.join(", ")
            ))
        }
    };
    Ok(e)
}

/// The effects whose physics depends on the direction of gravity: an entry without its
/// own `up` takes the spec's ([`CampaignSpec::up`]).
pub const GRAVITY_EFFECTS: [&str; 3] = ["gravity_stiffness", "cord_mass", "sensor_tilt_gravity"];

/// Builds an effect from its entry in `spec`: [`parse_effect`], with the spec's `up` as
/// the default `up` of a gravity effect.
pub fn parse_effect_in(entry: &EffectSpec, spec: &CampaignSpec) -> Result<Box<dyn Effect>, String> {
    match spec.up {
        Some(up)
            if GRAVITY_EFFECTS.contains(&entry.id.as_str())
                && !entry.parameters.contains_key("up") =>
        {
            let mut e = entry.clone();
            e.parameters.insert("up".into(), crate::spec::up_value(up));
            parse_effect(&e)
        }
        _ => parse_effect(entry),
    }
}

/// Parses and orders a spec's effects ([`Effect::order`], then spec order).
pub fn parse_effects(spec: &CampaignSpec) -> Result<Vec<Box<dyn Effect>>, (usize, String)> {
    let mut v = Vec::with_capacity(spec.effects.len());
    for (i, e) in spec.effects.iter().enumerate() {
        let eff = parse_effect_in(e, spec).map_err(|p| (i, p))?;
        eff.check(spec).map_err(|p| (i, p))?;
        v.push(eff);
    }
    v.sort_by_key(|e| e.order());
    Ok(v)
}
