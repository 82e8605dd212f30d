//! Processing-induced effects (docs/physics.md, E6).
//!
//! - `exponential_window`: force and response records multiplied by `w(t) = e^{−σt}`
//!   (σ = 1/τ). For a transient inside the record the windowed transform of any signal
//!   is its Laplace transform at `s = iω + σ`, and the force's window cancels, so every
//!   measured FRF is its transfer function at `s = iω + σ`:
//!   `A_w(ω) = A(iω + σ)`. For a modal model every pole λ_r moves to `λ_r − σ`
//!   (`ζ'_r ω'_r = ζ_r ω_r + σ`, the modes stay real), and the accelerance mass line
//!   `s² S Z(s)⁻¹ F → S M⁻¹ F` is unchanged. The accelerance factor is `(iω + σ)²`,
//!   not `−ω²`.
//! - `record_truncation`: records of length T without a window. The FRF is the finite
//!   transform `∫_0^T y(t) e^{−iωt} dt` of the impulse response; for a modal model
//!   `H_T(ω) = Σ_r R_r (1 − e^{(λ_r − iω)T})/(iω − λ_r) + c.c.`, which at the DFT bins
//!   `ω_k = 2πk/T` scales each residue by `(1 − e^{λ_r T})`. Computed for any damping by
//!   [`crate::observe`] from the state at T.
//!
//! Both change how the data are observed, not the structure: the truth modes stay the
//! physical ones.

use super::screening::{
    Build, Reciprocal, Screened, ScreeningForm, ScreeningKind, ScreeningResult,
};
use super::{BuildContext, Effect, ParamInfo};
use crate::model::DynamicModel;
use crate::spec::CampaignSpec;
use rbprops_core::Geometry;
use serde::{Deserialize, Serialize};

/// `exponential_window`: records multiplied by `e^{−σt}`, so every FRF is its transfer function at `s = iω + σ`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExponentialWindow {
    /// Decay rate σ (1/s); or give `time_constant_s` τ = 1/σ instead.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub decay_per_s: Option<f64>,
    /// Time constant τ = 1/σ (s), instead of `decay_per_s`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_constant_s: Option<f64>,
}

impl ExponentialWindow {
    /// σ (1/s).
    pub fn sigma(&self) -> f64 {
        match (self.decay_per_s, self.time_constant_s) {
            (Some(s), _) => s,
            (None, Some(t)) => 1.0 / t,
            (None, None) => f64::NAN,
        }
    }
}

impl ExponentialWindow {
    /// The catalogue id (the spec's `id = "exponential_window"`).
    pub const ID: &'static str = "exponential_window";
}

impl Effect for ExponentialWindow {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        vec![if self.time_constant_s.is_some() {
            super::positive_info("time_constant_s".into(), "s", (1.5, 10.0))
        } else {
            super::positive_info("decay_per_s".into(), "1/s", (0.0, 0.7))
        }]
    }
    fn values(&self) -> Vec<f64> {
        vec![self
            .decay_per_s
            .or(self.time_constant_s)
            .unwrap_or(f64::NAN)]
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let v = super::single_value(values)?;
        let mut e = self.clone();
        if e.time_constant_s.is_some() {
            e.time_constant_s = Some(v);
        } else {
            e.decay_per_s = Some(v);
        }
        super::checked(e)
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check_values(&self) -> Result<(), String> {
        match (self.decay_per_s, self.time_constant_s) {
            (Some(s), None) if s.is_finite() && s >= 0.0 => Ok(()),
            (Some(s), None) => Err(format!("decay_per_s must be finite and ≥ 0, got {s}")),
            (None, Some(t)) if t.is_finite() && t > 0.0 => Ok(()),
            (None, Some(t)) => Err(format!("time_constant_s must be positive, got {t}")),
            _ => Err("give exactly one of decay_per_s (σ) and time_constant_s (τ = 1/σ)".into()),
        }
    }
    fn modify_structure(
        &self,
        _ctx: &BuildContext,
        model: &mut DynamicModel,
    ) -> Result<(), String> {
        model.observation.window_decay_per_s += self.sigma();
        Ok(())
    }
}

/// `record_truncation`: records of length T without a window (the FRF of the finite record).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordTruncation {
    /// Record length T (s).
    pub record_length_s: f64,
}

impl RecordTruncation {
    /// The catalogue id (the spec's `id = "record_truncation"`).
    pub const ID: &'static str = "record_truncation";
}

impl Effect for RecordTruncation {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        vec![super::positive_info(
            "record_length_s".into(),
            "s",
            (4.0, 64.0),
        )]
    }
    fn values(&self) -> Vec<f64> {
        vec![self.record_length_s]
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let e = RecordTruncation {
            record_length_s: super::single_value(values)?,
        };
        super::checked(e)
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check_values(&self) -> Result<(), String> {
        if self.record_length_s.is_finite() && self.record_length_s > 0.0 {
            Ok(())
        } else {
            Err(format!(
                "record_length_s must be positive and finite, got {}",
                self.record_length_s
            ))
        }
    }
    fn modify_structure(
        &self,
        _ctx: &BuildContext,
        model: &mut DynamicModel,
    ) -> Result<(), String> {
        if model.observation.record_length_s.is_some() {
            return Err("record_truncation is given twice".into());
        }
        model.observation.record_length_s = Some(self.record_length_s);
        Ok(())
    }
}

/// `record_truncation` through φ = 1/T (record length T).
fn truncation_build(v: &[f64]) -> Result<Option<Box<dyn Effect>>, String> {
    if v[0] < 0.0 || !v[0].is_finite() {
        return Err(format!("1/T must be finite and ≥ 0, got {}", v[0]));
    }
    if v[0] == 0.0 {
        return Ok(None);
    }
    let mut t = toml::Table::new();
    t.insert("record_length_s".into(), (1.0 / v[0]).into());
    super::parse_effect(&crate::spec::EffectSpec {
        id: RecordTruncation::ID.into(),
        parameters: t,
    })
    .map(Some)
}

/// The catalogue table of a fitted φ = 1/T: `record_length_s = 1/φ`.
fn truncation_entry(v: &[f64]) -> Result<toml::Table, String> {
    if !(v[0] > 0.0) {
        return Err("record_truncation: fitted 1/T is not positive".into());
    }
    let mut t = toml::Table::new();
    t.insert("record_length_s".into(), (1.0 / v[0]).into());
    Ok(t)
}

/// `record_truncation`'s screening form: reparametrised by the inverse record length
/// φ = 1/T (neutral: 0, an endless record, [`Reciprocal`]). Its signature (residues
/// scaled by 1 − e^{λT}, leakage ripple) vanishes faster than any power of 1/T at
/// 1/T = 0, so no score test can see it: it is screened by a profile over the record
/// lengths zero padding can give, T = 1/(kΔf), k = 1..8 (the DFT record of the
/// recording's line spacing Δf, zero-padded k times), completed by the lags where the
/// residual's lag transform rises or peaks (the model check's delay scan): any
/// 1/(8Δf) < T < 1/Δf, the refit then optimises 1/T continuously.
fn screen_record_truncation(spec: &CampaignSpec, _g: &Geometry) -> ScreeningResult {
    // The record length is 1/Δf of the recording's lines, or a fraction of it
    // when the records were zero-padded: T = 1/(kΔf), k = 1..8. The leakage
    // ripple's phase ωT makes χ² oscillate in T on a scale of 1/ω_max, so a
    // record padded by a non-integer factor (to a power of two) is off this grid
    // and outside the refit's reach from it: such a T is located by the lag scan
    // of the residual (`delay_scan`) and added to the profile.
    let fr = &spec.frequency;
    let df = if fr.lines > 1 && fr.stop_hz > fr.start_hz {
        (fr.stop_hz - fr.start_hz) / (fr.lines - 1) as f64
    } else {
        1.0 / 16.0
    };
    let grid: Vec<Vec<f64>> = (1..=8).map(|k| vec![k as f64 * df]).collect();
    let infos = vec![ParamInfo {
        name: "inverse_record_length_per_s".into(),
        unit: "1/s",
        lower: 0.0,
        upper: 10.0,
        plausible: (1.0 / 64.0, 0.25),
    }];
    let build: Build = std::sync::Arc::new(truncation_build);
    Ok(Some(ScreeningForm {
        effect: Box::new(
            Reciprocal::new(RecordTruncation::ID, infos, vec![0.0], build)
                .with_entry(truncation_entry),
        ),
        neutral: vec![0.0],
        scales: vec![0.005],
        source: "rbprops-sim (reparametrised for screening)",
        screening: ScreeningKind::Profile {
            grid,
            delay_scan: true,
        },
    }))
}

/// This module's effects in the physics catalogue ([`super::registry`]).
pub(crate) const DESCRIPTORS: &[super::EffectDescriptor] = &[
    super::EffectDescriptor {
        id: ExponentialWindow::ID,
        rank: 8,
        title: "exponential window (processing damping)",
        reveal: "the window used, or a second record length / window",
        docs: "E6: an exponential window on force and response, `decay_per_s` or `time_constant_s`",
        parse: super::parse_as::<ExponentialWindow>,
        neutral: super::NeutralForm::Table(|_, _| super::table([("decay_per_s", 0.0.into())])),
        follows_spec_up: false,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/exponential_window.toml"),
        plausible: None,
    },
    super::EffectDescriptor {
        id: RecordTruncation::ID,
        rank: 9,
        title: "record truncation (leakage)",
        reveal: "the record length, or a longer record",
        docs: "E6: records of length `record_length_s` without a window (leakage)",
        parse: super::parse_as::<RecordTruncation>,
        neutral: super::NeutralForm::Screened(Screened {
            rank: 3,
            form: screen_record_truncation,
        }),
        follows_spec_up: false,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/record_truncation.toml"),
        plausible: None,
    },
];
