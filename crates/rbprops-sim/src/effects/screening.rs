//! Screening forms: how the model check starts looking for an effect whose own
//! parametrisation has no neutral ("absent") point (docs/physics.md, M5). The effect's
//! descriptor gives its form ([`super::NeutralForm::Screened`]), built in the effect's
//! own module: an [`Effect`] in another parametrisation that is neutral at a point, its
//! neutral values and step scales, and how it is screened ([`ScreeningKind`]).
//!
//! [`Reciprocal`] is the form shared by parameters absent only at infinity (a time
//! constant, a record length, a cord's mass per length): fitted through their
//! reciprocals, 0 meaning "absent".

use super::{BuildContext, Effect, OutputBlock, ParamInfo};
use crate::model::DynamicModel;
use crate::spec::{CampaignSpec, EffectSpec};
use rbprops_core::Geometry;

/// How a candidate is screened: its first-order evidence at the current model.
#[derive(Debug, Clone, PartialEq)]
pub enum ScreeningKind {
    /// Score (Lagrange-multiplier) test at the neutral point.
    Score,
    /// The signature vanishes to every order at the neutral point (a record length →
    /// ∞, a cord mass → 0 whose modes leave the band), so no score exists: a profile
    /// over these parameter points (linearised likelihood ratio with the current
    /// model's parameters re-adjusted). With `delay_scan`, a record length seen through
    /// φ = 1/T: the profile also tries the lags the model check's delay scan finds in
    /// the residual.
    Profile {
        /// Parameter points of the profile, each a full parameter vector of the candidate.
        grid: Vec<Vec<f64>>,
        /// Also try the lags the residual's delay scan finds (a record length via `φ = 1/T`).
        delay_scan: bool,
    },
    /// An in-band resonance, bilinear in its shapes: the model check's profile over
    /// (ω, ζ) of the linear residue fit to the residual proposes its points.
    Resonance,
}

/// An effect's screening form for a campaign (see the module docs).
#[derive(Debug)]
pub struct ScreeningForm {
    /// The effect in its screening parametrisation, at its neutral values.
    pub effect: Box<dyn Effect>,
    /// Parameter values at which the effect vanishes (the nominal model).
    pub neutral: Vec<f64>,
    /// Typical parameter magnitude (finite-difference step scale).
    pub scales: Vec<f64>,
    /// Where the form comes from, as the model check's report names it.
    pub source: &'static str,
    /// How it is screened.
    pub screening: ScreeningKind,
}

/// The screening form of an effect ([`super::NeutralForm::Screened`]): `Ok(None)` when
/// the campaign gives it nothing to screen (no note), `Err(note)` when it is not screened
/// for a reason the model check reports.
pub type ScreeningResult = Result<Option<ScreeningForm>, String>;

/// A descriptor's screening form: its place among the screened effects and its builder.
#[derive(Clone, Copy)]
pub struct Screened {
    /// Place among the screened effects: the model check offers them after every effect
    /// screened from a neutral table, in this order (its determinism depends on it). A
    /// new effect takes the next number.
    pub rank: u16,
    /// Builds the form for a spec and its geometry.
    pub form: fn(&CampaignSpec, &Geometry) -> ScreeningResult,
}

/// Builds the catalogue effect from the reciprocal parameters (`None`: absent).
pub type Build =
    std::sync::Arc<dyn Fn(&[f64]) -> Result<Option<Box<dyn Effect>>, String> + Send + Sync>;

/// A catalogue effect whose parameters (a time constant, a length) are neutral only at
/// infinity, fitted through their reciprocals: φ = 1/τ, with φ = 0 meaning "absent" (no
/// effect at all) and φ > 0 building the catalogue effect with τ = 1/φ.
pub struct Reciprocal {
    id: &'static str,
    infos: Vec<ParamInfo>,
    values: Vec<f64>,
    inner: Option<Box<dyn Effect>>,
    build: Build,
    /// The catalogue's parameter table of the fitted values, when it is not the inner
    /// effect's own ([`Effect::spec_entry`]).
    entry: Option<fn(&[f64]) -> Result<toml::Table, String>>,
}

impl std::fmt::Debug for Reciprocal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Reciprocal")
            .field("id", &self.id)
            .field("values", &self.values)
            .field("inner", &self.inner)
            .finish()
    }
}

impl Reciprocal {
    /// The absent effect `id` with parameters `infos` at `values` (absent there), built
    /// by `build` at other values.
    pub fn new(id: &'static str, infos: Vec<ParamInfo>, values: Vec<f64>, build: Build) -> Self {
        Reciprocal {
            id,
            infos,
            values,
            inner: None,
            build,
            entry: None,
        }
    }
    /// The same, writing its catalogue entry's table with `entry` from the fitted values.
    pub fn with_entry(mut self, entry: fn(&[f64]) -> Result<toml::Table, String>) -> Self {
        self.entry = Some(entry);
        self
    }
}

impl Effect for Reciprocal {
    fn id(&self) -> &'static str {
        self.id
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        self.infos.clone()
    }
    fn values(&self) -> Vec<f64> {
        self.values.clone()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        if values.len() != self.values.len() {
            return Err(format!(
                "{} expects {} values, got {}",
                self.id,
                self.values.len(),
                values.len()
            ));
        }
        if let Some((v, pi)) = values
            .iter()
            .zip(&self.infos)
            .find(|(v, pi)| !(v.is_finite() && **v >= pi.lower && **v <= pi.upper))
        {
            return Err(format!(
                "{}: {} = {v} outside [{}, {}]",
                self.id, pi.name, pi.lower, pi.upper
            ));
        }
        Ok(Box::new(Reciprocal {
            id: self.id,
            infos: self.infos.clone(),
            values: values.to_vec(),
            inner: (self.build)(values)?,
            build: self.build.clone(),
            entry: self.entry,
        }))
    }
    fn parameters_json(&self) -> serde_json::Value {
        match &self.inner {
            Some(e) => e.parameters_json(),
            None => serde_json::json!({}),
        }
    }
    fn spec_entry(&self, _spec: &CampaignSpec) -> Result<EffectSpec, String> {
        match self.entry {
            Some(entry) => Ok(EffectSpec {
                id: self.id.to_string(),
                parameters: entry(&self.values)?,
            }),
            None => super::table_entry(self.id, self.parameters_json()),
        }
    }
    fn order(&self) -> u8 {
        self.inner.as_ref().map_or(1, |e| e.order())
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        match &self.inner {
            Some(e) => e.modify_structure(ctx, model),
            None => Ok(()),
        }
    }
    fn modify_damping(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        match &self.inner {
            Some(e) => e.modify_damping(ctx, model),
            None => Ok(()),
        }
    }
    fn transform_output(&self, block: &mut OutputBlock) {
        if let Some(e) = &self.inner {
            e.transform_output(block);
        }
    }
}
