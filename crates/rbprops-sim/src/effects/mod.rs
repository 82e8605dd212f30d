//! The physics catalogue: effects that modify the nominal model (see
//! `/work/shared/research/missing-physics.md`). Each effect is switched on in the spec as
//! `[[effect]] id = "..."` with its parameters.

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
    pub excitation: usize,
    pub frequency_hz: &'a [f64],
    pub n_channels: usize,
    pub values: &'a mut [c64],
}

/// An effect of the physics catalogue. Effects act in three places, in this order:
/// on the structure (M, K, outputs, inputs, extra modes) before the nominal damping is
/// assembled from the resulting modes; on the damping after it; and on the computed
/// receptance FRFs (before quantity conversion and noise).
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
pub const KNOWN_EFFECTS: &[&str] = &[];

/// Builds an effect from its spec entry; the error says what is wrong.
pub fn parse_effect(spec: &EffectSpec) -> Result<Box<dyn Effect>, String> {
    Err(format!(
        "unknown effect id '{}' (known: {})",
        spec.id,
        if KNOWN_EFFECTS.is_empty() {
            "none in this version".to_string()
        } else {
            KNOWN_EFFECTS.join(", ")
        }
    ))
}
