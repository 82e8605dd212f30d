//! `elastic_mode`: an elastic mode of the article (docs/physics.md, E13), above or inside
//! the band, as an extra mode of the model:
//!
//! `H_ce(ω) += ψ_c ψ_e / (ω_m² − ω² + 2iζ_m ω_m ω)`
//!
//! with `ψ_c` the mass-normalised modal displacement along channel c (1/√kg) and `ψ_e`
//! that along excitation e's force. An elastic degree of freedom η with unit modal mass,
//! stiffness ω_m² and damping 2ζ_m ω_m, uncoupled from the rigid coordinates (the
//! suspension is soft), read as `y_c = S_c q + ψ_c η` and forced by `ψ_e f`, gives
//! exactly this term (tested with the augmented 7-DOF model). Channels and excitations
//! not listed have zero participation. Below ω_m it is the residual flexibility
//! `ψ_c ψ_e/ω_m²` (an accelerance growing as ω²).
//!
//! Its shapes are bilinear, with no first-order signature at ψ = 0, so the model check
//! screens it in its in-band form [`InBandResonance`] (one pole, a free residue per
//! channel and excitation) by a resonance profile.
//!
//! `residual_flexibility` ([`ResidualFlexibility`], E13): elastic modes above the band
//! seen as a general residual flexibility matrix R (channels × excitations, m/N): one
//! mode at f_e per excitation, `H += R_ce ω_e²/(ω_e² − ω² + 2iζ_e ω_e ω)`, with
//! q = (f_top/f_e)² (f_top the top of the band) and ζ_e the last two parameters (neutral
//! 1/16 and 0: an undamped mode at 4× the top of the band). Both are bilinear with R (no
//! signature while R = 0), so the model check frees them after a refit has moved R; they
//! then reach a mode just above the band, whose damping shows where the rigid part of an
//! FRF nearly cancels and the mode's tail dominates. It is linear in R with R = 0
//! absent: screened by a score test.

use super::screening::{Screened, ScreeningForm, ScreeningKind, ScreeningResult};
use super::{BuildContext, Effect, ParamInfo, Reach};
use crate::model::{DynamicModel, ExtraMode};
use crate::spec::CampaignSpec;
use nalgebra::DMatrix;
use rbprops_core::Geometry;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// `elastic_mode`: an elastic mode of the article added to the receptance (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ElasticMode {
    /// Set-up in which the mode is seen; all set-ups when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub setup: Option<String>,
    /// Natural frequency `ω_m/2π` of the elastic mode (Hz).
    pub frequency_hz: f64,
    /// Its damping ratio `ζ_m` (fraction of critical).
    pub damping_ratio: f64,
    /// Mass-normalised shape along each channel (1/√kg), by channel id.
    #[serde(default)]
    pub channels: BTreeMap<String, f64>,
    /// Mass-normalised shape along each excitation's force (1/√kg), by excitation id.
    #[serde(default)]
    pub excitations: BTreeMap<String, f64>,
}

impl ElasticMode {
    /// The catalogue id (the spec's `id = "elastic_mode"`).
    pub const ID: &'static str = "elastic_mode";
}

impl Effect for ElasticMode {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        let shape = |name: String| super::unbounded_info(name, "1/sqrt(kg)", (-0.5, 0.5));
        let mut v = vec![
            super::positive_info("frequency_hz".into(), "Hz", (10.0, 500.0)),
            ParamInfo {
                name: "damping_ratio".into(),
                unit: "1",
                lower: 0.0,
                upper: 1.0,
                plausible: (0.001, 0.05),
            },
        ];
        v.extend(self.channels.keys().map(|k| shape(format!("channels.{k}"))));
        v.extend(
            self.excitations
                .keys()
                .map(|k| shape(format!("excitations.{k}"))),
        );
        v
    }
    fn values(&self) -> Vec<f64> {
        let mut v = vec![self.frequency_hz, self.damping_ratio];
        v.extend(self.channels.values());
        v.extend(self.excitations.values());
        v
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let n = 2 + self.channels.len() + self.excitations.len();
        if values.len() != n {
            return Err(format!("expected {n} values, got {}", values.len()));
        }
        let mut e = self.clone();
        e.frequency_hz = values[0];
        e.damping_ratio = values[1];
        let mut it = values[2..].iter();
        for v in e.channels.values_mut().chain(e.excitations.values_mut()) {
            *v = *it.next().expect("length checked");
        }
        super::checked(e)
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check_values(&self) -> Result<(), String> {
        if !(self.frequency_hz.is_finite() && self.frequency_hz > 0.0) {
            return Err(format!(
                "frequency_hz must be positive and finite, got {}",
                self.frequency_hz
            ));
        }
        if !(self.damping_ratio.is_finite() && (0.0..1.0).contains(&self.damping_ratio)) {
            return Err(format!(
                "damping_ratio must be in [0, 1), got {}",
                self.damping_ratio
            ));
        }
        for (what, map) in [
            ("channels", &self.channels),
            ("excitations", &self.excitations),
        ] {
            if let Some((k, v)) = map.iter().find(|(_, v)| !v.is_finite()) {
                return Err(format!("{what}.{k}: shape value {v} is not finite"));
            }
        }
        if self.channels.is_empty() || self.excitations.is_empty() {
            return Err(
                "give the shape at one channel and one excitation at least (channels, excitations)"
                    .into(),
            );
        }
        Ok(())
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_values()?;
        super::check_channels_defined(spec, "channels", self.channels.keys())?;
        super::check_excitations_defined(spec, "excitations", self.excitations.keys())?;
        super::check_setup(spec, self.setup.as_deref())
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        if !super::acts_in_setup(self.setup.as_deref(), &model.setup) {
            return Ok(());
        }
        let g = ctx.geometry;
        model.extra_modes.push(ExtraMode {
            frequency_hz: self.frequency_hz,
            damping_ratio: self.damping_ratio,
            at_channels: g
                .channels
                .iter()
                .map(|c| self.channels.get(&c.id).copied().unwrap_or(0.0))
                .collect(),
            at_excitations: g
                .excitations
                .iter()
                .map(|e| self.excitations.get(&e.id).copied().unwrap_or(0.0))
                .collect(),
        });
        Ok(())
    }
}

/// One in-band mode: `Δ H_ce(ω) = A_ce / (ω_m² − ω² + 2iζ_m ω_m ω)` (receptance, before
/// the other output effects and the quantity conversion), spec channels × excitations.
#[derive(Debug, Clone)]
pub struct InBandResonance {
    channels: Vec<String>,
    excitations: Vec<String>,
    /// `[f_m (Hz), ζ_m, A_ce …]` with `A` channel-major (1/kg).
    values: Vec<f64>,
    /// Finite-difference scale of the residues (1/kg).
    residue_scale: f64,
}

impl InBandResonance {
    /// The neutral resonance (all residues zero) of `spec`, at mid-band.
    pub fn neutral(spec: &CampaignSpec) -> Self {
        let channels: Vec<String> = spec.channels().iter().map(|c| c.id.clone()).collect();
        let excitations: Vec<String> = spec.excitations.iter().map(|e| e.id.clone()).collect();
        let fr = &spec.frequency;
        let mut values = vec![0.5 * (fr.start_hz + fr.stop_hz).max(1e-3), 0.01];
        values.resize(2 + channels.len() * excitations.len(), 0.0);
        Self {
            channels,
            excitations,
            values,
            residue_scale: 1e-3 / spec.body.mass_kg.max(1e-9),
        }
    }

    /// Finite-difference scales, in [`Effect::values`] order.
    pub fn scales(&self) -> Vec<f64> {
        let mut s = vec![0.01 * self.values[0], 1e-3];
        s.resize(self.values.len(), self.residue_scale);
        s
    }

    fn residue(&self, c: usize, e: usize) -> f64 {
        self.values[2 + c * self.excitations.len() + e]
    }

    /// Rank-1 factors of `A` (ψ_c, ψ_e) and the fraction of ‖A‖²_F they carry.
    pub fn rank_one(&self) -> (Vec<f64>, Vec<f64>, f64) {
        let (nc, ne) = (self.channels.len(), self.excitations.len());
        let a = DMatrix::from_fn(nc, ne, |c, e| self.residue(c, e));
        let total = a.norm_squared();
        let svd = a.svd(true, true);
        let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
        let k = svd.singular_values.imax();
        let s = svd.singular_values[k];
        // Sign: the largest channel entry positive (ψ → −ψ on both sides is no change).
        let col = u.column(k);
        let sign = if col[col.iamax()] < 0.0 { -1.0 } else { 1.0 };
        let root = s.sqrt();
        let psi_c = col.iter().map(|x| sign * root * x).collect();
        let psi_e = vt.row(k).iter().map(|x| sign * root * x).collect();
        let fraction = if total > 0.0 { s * s / total } else { 0.0 };
        (psi_c, psi_e, fraction)
    }
}

impl Effect for InBandResonance {
    fn id(&self) -> &'static str {
        ElasticMode::ID
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        let mut v = vec![
            ParamInfo {
                name: "frequency_hz".into(),
                unit: "Hz",
                lower: 1e-6,
                upper: f64::INFINITY,
                plausible: (0.0, f64::INFINITY),
            },
            ParamInfo {
                name: "damping_ratio".into(),
                unit: "1",
                // A resonance, not a broadband correction: beyond ζ = 0.25 the pole
                // would only soak up misfit of other origin (pinned there = rejected).
                lower: 1e-5,
                upper: 0.25,
                plausible: (0.001, 0.1),
            },
        ];
        for c in &self.channels {
            for e in &self.excitations {
                v.push(ParamInfo {
                    name: format!("residues.{c}.{e}"),
                    unit: "1/kg",
                    lower: f64::NEG_INFINITY,
                    upper: f64::INFINITY,
                    plausible: (f64::NEG_INFINITY, f64::INFINITY),
                });
            }
        }
        v
    }
    fn values(&self) -> Vec<f64> {
        self.values.clone()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        if values.len() != self.values.len() {
            return Err(format!(
                "elastic_mode expects {} values, got {}",
                self.values.len(),
                values.len()
            ));
        }
        if let Some(v) = values.iter().find(|v| !v.is_finite()) {
            return Err(format!("elastic_mode: non-finite value {v}"));
        }
        if !(values[0] > 0.0 && (0.0..1.0).contains(&values[1])) {
            return Err(format!(
                "elastic_mode: need f > 0 and 0 ≤ ζ < 1, got f = {}, ζ = {}",
                values[0], values[1]
            ));
        }
        let mut e = self.clone();
        e.values = values.to_vec();
        Ok(Box::new(e))
    }
    /// The catalogue's rank-1 form (what the improved spec receives).
    fn parameters_json(&self) -> serde_json::Value {
        let (psi_c, psi_e, _) = self.rank_one();
        let map = |ids: &[String], v: &[f64]| -> serde_json::Map<String, serde_json::Value> {
            ids.iter()
                .zip(v)
                .map(|(k, x)| (k.clone(), (*x).into()))
                .collect()
        };
        serde_json::json!({
            "frequency_hz": self.values[0],
            "damping_ratio": self.values[1],
            "channels": map(&self.channels, &psi_c),
            "excitations": map(&self.excitations, &psi_e),
        })
    }
    /// One catalogue extra mode per excitation (`ψ_e` a unit vector, `ψ_c = A_{·e}`):
    /// their sum is the full residue matrix, through the simulator's own extra-mode path
    /// (so windows and record truncation act on it as on any mode).
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        let g = ctx.geometry;
        let index = |ids: &[String], id: &str| ids.iter().position(|x| x == id);
        for (e, _) in self.excitations.iter().enumerate() {
            let at_channels = g
                .channels
                .iter()
                .map(|c| index(&self.channels, &c.id).map_or(0.0, |ci| self.residue(ci, e)))
                .collect();
            let at_excitations = g
                .excitations
                .iter()
                .map(|x| f64::from(x.id == self.excitations[e]))
                .collect();
            model.extra_modes.push(ExtraMode {
                frequency_hz: self.values[0],
                damping_ratio: self.values[1],
                at_channels,
                at_excitations,
            });
        }
        Ok(())
    }
    /// A residue `A_ce` reaches the FRF of channel c and excitation e alone: it is
    /// `at_channels[c]` of the extra mode driven by excitation e only
    /// ([`Self::modify_structure`]); the pole (f_m, ζ_m) reaches every FRF.
    fn parameter_reach(&self, g: &rbprops_core::Geometry) -> Vec<Reach> {
        let mut v = vec![Reach::Any; 2];
        for c in &self.channels {
            let channel = g.channels.iter().position(|x| &x.id == c);
            for e in &self.excitations {
                let mut at = g.excitations.iter().enumerate().filter(|(_, x)| &x.id == e);
                v.push(match (channel, at.next(), at.next()) {
                    (Some(channel), Some((excitation, _)), None) => Reach::Cell {
                        channel,
                        excitation,
                    },
                    _ => Reach::Any,
                });
            }
        }
        v
    }
}

/// `elastic_mode`'s screening form: [`InBandResonance`] at its neutral point (all
/// residues zero), screened by the resonance profile; nothing without channels.
fn screen_elastic_mode(spec: &CampaignSpec, _g: &Geometry) -> ScreeningResult {
    if spec.channels().is_empty() {
        return Ok(None);
    }
    let e = InBandResonance::neutral(spec);
    Ok(Some(ScreeningForm {
        neutral: e.values(),
        scales: e.scales(),
        effect: Box::new(e),
        source: "rbprops-sim (in-band form: one pole, a residue per channel and excitation; screened by a profile)",
        screening: ScreeningKind::Resonance,
    }))
}

/// One entry `R_ce` of the residual flexibility matrix.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FlexibilityEntry {
    /// Channel id.
    pub channel: String,
    /// Excitation id.
    pub excitation: String,
    /// `R_ce` (m/N): the receptance the modes above the band add at low frequency.
    pub value: f64,
}

/// `residual_flexibility`: elastic modes above the band as a residual flexibility
/// matrix (see the module docs). Entries not listed are zero.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResidualFlexibility {
    /// The entries `R_ce` (m/N), in the order given (the parameters' order).
    pub receptance_m_per_n: Vec<FlexibilityEntry>,
    /// `q = (f_top/f_e)²`: the modes sit at `f_e = f_top/√q`, f_top the top of the
    /// campaign's band (default 1/16: 4× the top).
    #[serde(default = "default_mode_q")]
    pub band_top_over_mode_frequency_squared: f64,
    /// The modes' damping ratio ζ_e (default 0).
    #[serde(default)]
    pub mode_damping_ratio: f64,
    /// The top of the band (Hz) the form was built for; the spec's when absent.
    #[serde(skip)]
    band_top_hz: Option<f64>,
}

/// Name of the residual flexibility's frequency parameter q = (f_top/f_e)².
const RESIDUAL_MODE_Q: &str = "band_top_over_mode_frequency_squared";

/// Its neutral value: the modes at 4× the top of the band, where their ω² growth is
/// what an elastic mode above the band shows.
const RESIDUAL_MODE_Q_NEUTRAL: f64 = 1.0 / 16.0;

/// Name of the residual flexibility's modal damping ratio (neutral 0).
const RESIDUAL_MODE_DAMPING: &str = "mode_damping_ratio";

fn default_mode_q() -> f64 {
    RESIDUAL_MODE_Q_NEUTRAL
}

impl ResidualFlexibility {
    /// The catalogue id (the spec's `id = "residual_flexibility"`).
    pub const ID: &'static str = "residual_flexibility";

    /// The neutral form for a spec and its geometry: every channel and excitation (the
    /// excitations outer), R = 0, q = 1/16, ζ = 0, at the spec's band top.
    pub fn neutral(spec: &CampaignSpec, g: &Geometry) -> Self {
        ResidualFlexibility {
            receptance_m_per_n: g
                .excitations
                .iter()
                .flat_map(|e| {
                    g.channels.iter().map(move |c| FlexibilityEntry {
                        channel: c.id.clone(),
                        excitation: e.id.clone(),
                        value: 0.0,
                    })
                })
                .collect(),
            band_top_over_mode_frequency_squared: RESIDUAL_MODE_Q_NEUTRAL,
            mode_damping_ratio: 0.0,
            band_top_hz: Some(spec.frequency.stop_hz),
        }
    }

    /// Finite-difference scales, in [`Effect::values`] order: an entry of 1e-3 of the
    /// body's mass line at the band top, q by 0.01, ζ by 0.001.
    pub fn scales(&self, spec: &CampaignSpec) -> Vec<f64> {
        let m = spec.body.mass_kg;
        let w = std::f64::consts::TAU * spec.frequency.stop_hz.max(1e-3);
        let mut s = vec![1e-3 / (m * w * w); self.receptance_m_per_n.len()];
        s.extend([0.01, 0.001]);
        s
    }

    /// `R_ce` of channel `c` and excitation `e` (0 when not listed).
    fn entry(&self, c: &str, e: &str) -> f64 {
        self.receptance_m_per_n
            .iter()
            .find(|r| r.channel == c && r.excitation == e)
            .map_or(0.0, |r| r.value)
    }
}

impl Effect for ResidualFlexibility {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        let mut v: Vec<ParamInfo> = self
            .receptance_m_per_n
            .iter()
            .map(|r| {
                super::unbounded_info(
                    format!("{}.{}.receptance_m_per_n", r.channel, r.excitation),
                    "m/N",
                    (-1e-4, 1e-4),
                )
            })
            .collect();
        v.push(ParamInfo {
            name: RESIDUAL_MODE_Q.into(),
            unit: "1",
            lower: 1e-4,
            upper: 0.95,
            plausible: (0.0, 0.5),
        });
        v.push(ParamInfo {
            name: RESIDUAL_MODE_DAMPING.into(),
            unit: "1",
            lower: 0.0,
            upper: 0.5,
            plausible: (0.0, 0.05),
        });
        v
    }
    fn values(&self) -> Vec<f64> {
        let mut v: Vec<f64> = self.receptance_m_per_n.iter().map(|r| r.value).collect();
        v.extend([
            self.band_top_over_mode_frequency_squared,
            self.mode_damping_ratio,
        ]);
        v
    }
    /// Any finite values (the fitter keeps them in bounds).
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let n = self.receptance_m_per_n.len() + 2;
        if values.len() != n {
            return Err(format!(
                "{} expects {n} parameters, got {}",
                Self::ID,
                values.len()
            ));
        }
        if let Some(v) = values.iter().find(|v| !v.is_finite()) {
            return Err(format!("{}: parameter {v} is not finite", Self::ID));
        }
        let mut e = self.clone();
        for (r, v) in e.receptance_m_per_n.iter_mut().zip(values) {
            r.value = *v;
        }
        e.band_top_over_mode_frequency_squared = values[n - 2];
        e.mode_damping_ratio = values[n - 1];
        Ok(Box::new(e))
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check_values(&self) -> Result<(), String> {
        if let Some(r) = self
            .receptance_m_per_n
            .iter()
            .find(|r| !r.value.is_finite())
        {
            return Err(format!(
                "receptance_m_per_n: {}.{}: {} is not finite",
                r.channel, r.excitation, r.value
            ));
        }
        let q = self.band_top_over_mode_frequency_squared;
        if !(q.is_finite() && q > 0.0) {
            return Err(format!(
                "{RESIDUAL_MODE_Q} must be positive and finite, got {q}"
            ));
        }
        let z = self.mode_damping_ratio;
        if !(z.is_finite() && (0.0..1.0).contains(&z)) {
            return Err(format!(
                "{RESIDUAL_MODE_DAMPING} must be in [0, 1), got {z}"
            ));
        }
        Ok(())
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_values()?;
        let field = "receptance_m_per_n";
        let entries = &self.receptance_m_per_n;
        super::check_channels_defined(spec, field, entries.iter().map(|r| &r.channel))?;
        super::check_excitations_defined(spec, field, entries.iter().map(|r| &r.excitation))
    }
    /// One undamped mode at f_e per excitation, unit at that excitation's force: the
    /// receptance gains `R_ce ω_e²/(ω_e² − ω²)` ≈ `R_ce (1 + ω²/ω_e²)`, a general (any
    /// rank) residual flexibility matrix R.
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        let g = ctx.geometry;
        let n_ex = g.excitations.len();
        let (q, zeta) = (
            self.band_top_over_mode_frequency_squared,
            self.mode_damping_ratio,
        );
        let band_top_hz = self.band_top_hz.unwrap_or(ctx.spec.frequency.stop_hz);
        let extra_hz = band_top_hz / q.sqrt();
        let we = std::f64::consts::TAU * extra_hz;
        for e in 0..n_ex {
            let ex = &g.excitations[e].id;
            let col: Vec<f64> = g.channels.iter().map(|c| self.entry(&c.id, ex)).collect();
            if col.iter().all(|v| *v == 0.0) {
                continue;
            }
            let mut at_ex = vec![0.0; n_ex];
            at_ex[e] = 1.0;
            model.extra_modes.push(ExtraMode {
                frequency_hz: extra_hz,
                damping_ratio: zeta,
                at_channels: col.iter().map(|r| r * we * we).collect(),
                at_excitations: at_ex,
            });
        }
        Ok(())
    }
    /// An entry `R_ce` reaches the FRF of c and e (the `at_channels[c]` of the mode
    /// driven by e alone); q and ζ reach any FRF.
    fn parameter_reach(&self, g: &Geometry) -> Vec<Reach> {
        let mut v: Vec<Reach> = self
            .receptance_m_per_n
            .iter()
            .map(|r| {
                let channel = g.channels.iter().position(|c| c.id == r.channel);
                let mut at =
                    (0..g.excitations.len()).filter(|&e| g.excitations[e].id == r.excitation);
                match (channel, at.next(), at.next()) {
                    (Some(channel), Some(excitation), None) => Reach::Cell {
                        channel,
                        excitation,
                    },
                    _ => Reach::Any,
                }
            })
            .collect();
        v.extend([Reach::Any, Reach::Any]);
        v
    }
}

/// [`super::EffectDescriptor::parse`] of `residual_flexibility`: the table, checked.
fn parse_residual_flexibility(spec: &crate::spec::EffectSpec) -> Result<Box<dyn Effect>, String> {
    let r: ResidualFlexibility = super::params(spec)?;
    r.check_values()?;
    Ok(Box::new(r))
}

/// `residual_flexibility`'s screening form: its neutral point, screened by a score.
fn screen_residual_flexibility(spec: &CampaignSpec, g: &Geometry) -> ScreeningResult {
    let e = ResidualFlexibility::neutral(spec, g);
    Ok(Some(ScreeningForm {
        neutral: e.values(),
        scales: e.scales(spec),
        effect: Box::new(e),
        // The model check's name for it from before it joined the catalogue (it is in
        // the reports).
        source: "rbprops-check (local)",
        screening: ScreeningKind::Score,
    }))
}

/// This module's effects in the physics catalogue ([`super::registry`]).
/// Plausible: with its half-power band clear of the nominal model's highest rigid-body
/// (suspension) mode, `f (1 − ζ) > f_top`, and a damping ratio of at most 10 %. A rigid-body
/// test is set up so that the body's own modes lie above its suspension modes; a mode
/// whose half-power band reaches the top suspension mode cannot be told from that mode
/// bent by misplaced forces or sensors (seed 7056 of the combination study: an "elastic
/// mode" 3 % above the top suspension mode, ζ 7.7 %, stood in for a force location and
/// kept four false effects in). A metal structure's modes are damped 0.1–5 %, a 10 % mode
/// is a mount's, not the body's.
fn plausible_elastic_mode(
    entry: &crate::spec::EffectSpec,
    spec: &CampaignSpec,
) -> Result<Vec<super::Plausible>, String> {
    let e: ElasticMode = super::params(entry)?;
    let lowest = highest_rigid_mode_hz(spec) / (1.0 - e.damping_ratio.clamp(0.0, 0.5));
    Ok(vec![
        super::Plausible::new("frequency", "Hz", e.frequency_hz, [lowest, f64::INFINITY]),
        super::Plausible::new("damping ratio", "%", 100.0 * e.damping_ratio, [0.0, 10.0]),
    ])
}

/// The highest undamped rigid-body frequency (Hz) of the nominal model over its set-ups
/// (mass matrix and suspension stiffness of the spec; 0 with no set-up).
fn highest_rigid_mode_hz(spec: &CampaignSpec) -> f64 {
    let m = spec.properties().mass_matrix().0;
    let Some(ch) = nalgebra::Cholesky::new(m) else {
        return 0.0;
    };
    let l_inv = ch
        .l()
        .try_inverse()
        .unwrap_or_else(rbprops_core::Mat6::zeros);
    (0..spec.setups.len())
        .map(|i| {
            let k = spec.setup_stiffness(i);
            let a = l_inv * k * l_inv.transpose();
            let w2 = ((a + a.transpose()) / 2.0).symmetric_eigenvalues().max();
            w2.max(0.0).sqrt() / std::f64::consts::TAU
        })
        .fold(0.0, f64::max)
}

pub(crate) const DESCRIPTORS: &[super::EffectDescriptor] = &[
    super::EffectDescriptor {
        id: ElasticMode::ID,
        rank: 6,
        title: "elastic mode (a resonance the rigid-body model lacks, in or above the band)",
        reveal: "more sensors or a roving hammer to map its shape, or a band that stops below it",
        docs: "E13: an elastic mode with its own frequency, damping and participations per channel and excitation",
        parse: super::parse_as::<ElasticMode>,
        neutral: super::NeutralForm::Screened(Screened {
            rank: 6,
            form: screen_elastic_mode,
        }),
        follows_spec_up: false,
        repeatable: true,
        example: include_str!("../../../../fixtures/specs/effects/elastic_mode.toml"),
        plausible: Some(plausible_elastic_mode),
    },
    super::EffectDescriptor {
        id: ResidualFlexibility::ID,
        rank: 24,
        title: "elastic modes above the band (residual flexibility)",
        reveal: "data closer to the first elastic mode, or its measured frequency",
        docs: "E13: elastic modes above the band as a residual flexibility matrix, one mode per excitation at `f_top/√q` (f_top the band's top): `receptance_m_per_n` (entries `channel`, `excitation`, `value` in m/N), `band_top_over_mode_frequency_squared` (q, default 1/16), `mode_damping_ratio`",
        parse: parse_residual_flexibility,
        neutral: super::NeutralForm::Screened(Screened {
            rank: 0,
            form: screen_residual_flexibility,
        }),
        follows_spec_up: false,
        repeatable: true,
        example: include_str!("../../../../fixtures/specs/effects/residual_flexibility.toml"),
        plausible: None,
    },
];

#[cfg(test)]
mod tests {
    use super::{highest_rigid_mode_hz, plausible_elastic_mode, ElasticMode, InBandResonance};
    use crate::spec::EffectSpec;

    fn entry(frequency_hz: f64, damping_ratio: f64) -> EffectSpec {
        EffectSpec {
            id: ElasticMode::ID.into(),
            parameters: toml::toml! {
                frequency_hz = frequency_hz
                damping_ratio = damping_ratio
            },
        }
    }

    /// The frequency's plausible range starts where the mode's half-power band clears the
    /// top suspension mode, `f_top/(1 − ζ)`: 5 % above it is a body's lightly damped mode,
    /// and a mount's damping of 7.7 % there (seed 7056) reaches the suspension mode.
    #[test]
    fn half_power_band_clear_of_the_top_suspension_mode() {
        let text = crate::examples::example("test-case-2").expect("built-in");
        let spec = crate::CampaignSpec::from_toml_str(text).expect("valid spec");
        let top = highest_rigid_mode_hz(&spec);
        assert!(top > 1.0 && top < 12.5, "top suspension mode {top} Hz");
        let judge = |f: f64, zeta: f64| {
            let q = plausible_elastic_mode(&entry(f, zeta), &spec).expect("valid entry");
            (q[0].range[0], q[0].holds())
        };
        let (lowest, holds) = judge(1.05 * top, 0.02);
        assert!((lowest - top / 0.98).abs() <= 1e-12 * top && holds);
        let (lowest, holds) = judge(1.05 * top, 0.077);
        assert!((lowest - top / 0.923).abs() <= 1e-12 * top && !holds);
        // Undamped, the bound is the suspension mode itself.
        assert_eq!(judge(top, 0.0).0, top);
        assert!(!judge(0.99 * top, 0.0).1);
    }

    #[test]
    fn rank_one_factors_reproduce_a_rank_one_residue_matrix() {
        let psi_c = [0.1, -0.2, 0.05];
        let psi_e = [0.3, 0.0];
        let mut values = vec![12.0, 0.01];
        for c in psi_c {
            for e in psi_e {
                values.push(c * e);
            }
        }
        let r = InBandResonance {
            channels: vec!["a".into(), "b".into(), "c".into()],
            excitations: vec!["x".into(), "y".into()],
            values,
            residue_scale: 1e-3,
        };
        let (uc, ue, frac) = r.rank_one();
        assert!((frac - 1.0).abs() < 1e-12);
        for c in 0..3 {
            for e in 0..2 {
                assert!((uc[c] * ue[e] - psi_c[c] * psi_e[e]).abs() < 1e-14);
            }
        }
        // Sign convention: the largest channel entry is positive.
        assert!(uc[1] > 0.0);
    }

    /// Test Case II without noise on 201 lines, and its nominal FRFs.
    fn quiet_tc2() -> (crate::CampaignSpec, rbprops_core::FrfSet) {
        let text = crate::examples::example("test-case-2").expect("built-in");
        let mut s = crate::CampaignSpec::from_toml_str(text).expect("valid spec");
        s.noise.relative = 0.0;
        s.noise.floor = 0.0;
        s.frequency.lines = 201;
        let nominal = crate::simulate(&s).expect("nominal").frf;
        (s, nominal)
    }

    /// The FRFs of `s` with `e` switched on through its catalogue entry (parsed from
    /// the spec, as frf-sim reads it).
    fn with_entry(s: &crate::CampaignSpec, e: &dyn super::Effect) -> rbprops_core::FrfSet {
        let mut with = s.clone();
        with.effects.push(e.spec_entry(s).expect("an entry"));
        with.validate().expect("the entry validates");
        crate::simulate(&with).expect("simulates").frf
    }

    /// `residual_flexibility` through its spec entry: at its neutral values the FRFs are
    /// exactly the nominal ones; one entry `R_ce` changes only the FRF of channel c and
    /// excitation e, by `Q(ω) R ω_e²/(ω_e² − ω² + 2iζω_eω)` (Q the receptance-to-
    /// accelerance factor, `ω_e = 2π f_top/√q`), and is the one parameter reaching it.
    #[test]
    fn residual_flexibility_is_one_mode_per_excitation_above_the_band() {
        use super::{Effect, Reach, ResidualFlexibility};
        let (s, nominal) = quiet_tc2();
        let g = s.geometry().expect("geometry");
        let neutral = ResidualFlexibility::neutral(&s, &g);
        let (n_ch, n_ex) = (g.channels.len(), g.excitations.len());
        assert_eq!(neutral.values().len(), n_ch * n_ex + 2);
        assert_eq!(with_entry(&s, &neutral).values, nominal.values);
        let (c, e, r, q, zeta) = (1, 2, 2e-6, 0.25, 0.03);
        let mut v = neutral.values();
        v[e * n_ch + c] = r;
        v[n_ch * n_ex] = q;
        v[n_ch * n_ex + 1] = zeta;
        let fitted = neutral.with_values(&v).expect("finite values");
        assert_eq!(fitted.values(), v);
        let reach = fitted.parameter_reach(&g);
        assert_eq!(
            reach[e * n_ch + c],
            Reach::Cell {
                channel: c,
                excitation: e
            }
        );
        assert_eq!(reach[n_ch * n_ex..], [Reach::Any, Reach::Any]);
        let out = with_entry(&s, fitted.as_ref());
        let nl = nominal.frequency_hz.len();
        let we = std::f64::consts::TAU * s.frequency.stop_hz / q.sqrt();
        let mut largest: f64 = 0.0;
        for ei in 0..n_ex {
            for ci in 0..n_ch {
                for (k, f) in nominal.frequency_hz.iter().enumerate() {
                    let i = (ei * n_ch + ci) * nl + k;
                    let got = out.values[i] - nominal.values[i];
                    if (ci, ei) != (c, e) {
                        assert_eq!(got.norm(), 0.0, "channel {ci}, excitation {ei}, line {k}");
                        continue;
                    }
                    let w = std::f64::consts::TAU * f;
                    let mode = rbprops_core::c64::new(we * we - w * w, 2.0 * zeta * we * w);
                    let want = s.quantity.from_receptance_factor(w) * r * we * we / mode;
                    assert!(
                        (got - want).norm() <= 1e-9 * want.norm().max(1e-12),
                        "line {k}: {got} vs {want}"
                    );
                    largest = largest.max(want.norm());
                }
            }
        }
        // The change is far above roundoff (the test can fail).
        assert!(largest > 1e-3, "largest change {largest}");
    }

    /// The spec form refuses what is not a residual flexibility: unknown channels, a
    /// non-positive q.
    #[test]
    fn residual_flexibility_spec_is_checked() {
        let (s, _) = quiet_tc2();
        let parse = |t: toml::Table| {
            super::parse_residual_flexibility(&EffectSpec {
                id: super::ResidualFlexibility::ID.into(),
                parameters: t,
            })
        };
        let ok = parse(toml::toml! {
            receptance_m_per_n = [{ channel = "1x", excitation = "force1", value = 1e-6 }]
        })
        .expect("a valid entry");
        assert_eq!(ok.values(), [1e-6, 1.0 / 16.0, 0.0]);
        ok.check(&s).expect("ids of the spec");
        let bad = parse(toml::toml! {
            receptance_m_per_n = [{ channel = "nope", excitation = "force1", value = 1e-6 }]
        })
        .expect("parses");
        assert!(bad.check(&s).unwrap_err().contains("nope"));
        assert!(parse(toml::toml! {
            receptance_m_per_n = []
            band_top_over_mode_frequency_squared = 0.0
        })
        .is_err());
    }
}
