//! Records that cross stage boundaries. They are plain data (arrays, not nalgebra
//! types) with `serde` + `schemars` derives so that `rbprops-formats` can write them as
//! JSON messages with a JSON schema (MCAP) and as CSV tables.
//!
//! Field names carry their units. Complex numbers are `[re, im]` pairs.

use crate::c64;
pub use crate::methods::{
    DiagnosticKind, EstimateMethod, FitMethod, SelectionCriterion, Severity, UncertaintyMethod,
};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Which program produced a part of the record, with what, from what.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct StageProvenance {
    /// Program name (`frf-sim`, `modal-fit`, …).
    pub tool: String,
    /// rbprops version.
    pub version: String,
    /// Command-line arguments after the program name.
    pub args: Vec<String>,
    /// SHA-256 (hex) of the input bytes, or of the spec for a simulation.
    pub input_sha256: String,
}

/// Products of inertia `{xy, xz, yz}` in the docs/conventions.md sense (`J_xy = ∫xy dm`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema, Default)]
pub struct Products {
    /// `J_xy = ∫xy dm` about the centre of mass (kg m²).
    pub xy: f64,
    /// `J_xz = ∫xz dm` about the centre of mass (kg m²).
    pub xz: f64,
    /// `J_yz = ∫yz dm` about the centre of mass (kg m²).
    pub yz: f64,
}

/// Mass, CoM and inertia at the CoM.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct PropertiesRecord {
    /// Mass `m` (kg).
    pub mass_kg: f64,
    /// Centre of mass in the geometry's frame (m).
    pub com_m: [f64; 3],
    /// Inertia tensor about the CoM (row-major; off-diagonals are minus the products).
    pub inertia_cm_kg_m2: [[f64; 3]; 3],
}

impl PropertiesRecord {
    /// The record of in-memory properties (the tensor copied entry by entry).
    pub fn from_properties(p: &crate::RigidBodyProperties) -> Self {
        let j = &p.inertia_cm;
        Self {
            mass_kg: p.mass,
            com_m: [p.com.x, p.com.y, p.com.z],
            inertia_cm_kg_m2: [
                [j[(0, 0)], j[(0, 1)], j[(0, 2)]],
                [j[(1, 0)], j[(1, 1)], j[(1, 2)]],
                [j[(2, 0)], j[(2, 1)], j[(2, 2)]],
            ],
        }
    }
    /// The in-memory properties this record holds.
    pub fn to_properties(&self) -> crate::RigidBodyProperties {
        let j = &self.inertia_cm_kg_m2;
        crate::RigidBodyProperties {
            mass: self.mass_kg,
            com: crate::Vec3::from(self.com_m),
            inertia_cm: crate::Mat3::from_fn(|r, c| j[r][c]),
        }
    }
}

/// A true (simulated) real mode about the geometry's origin.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct TrueModeRecord {
    /// 1-based mode number within its set-up, ascending frequency.
    pub mode: usize,
    /// Natural frequency (Hz). Exactly 0 for a free rigid-body direction (the suspension
    /// gives it no stiffness), whose damping ratio is then 0 and whose shape is one of a
    /// mass-orthonormal basis of the free directions ([`crate::rigid_body_modes`]).
    pub frequency_hz: f64,
    /// Viscous damping ratio `ζ` (0 for a free direction).
    pub damping_ratio: f64,
    /// Mass-normalised shape `[u_x, u_y, u_z, θ_x, θ_y, θ_z]` about the origin.
    pub shape: [f64; 6],
}

/// The true modes of one suspension set-up.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct TrueSetupRecord {
    /// Id of the suspension set-up.
    pub setup: String,
    /// Mount stiffness about the origin, 6×6 row-major (N/m, N, N m/rad).
    pub stiffness: [[f64; 6]; 6],
    /// Its real modes, ascending frequency.
    pub modes: Vec<TrueModeRecord>,
}

/// One effect of the physics catalogue that a simulation switched on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct EffectRecord {
    /// Stable snake_case id (`gravity_stiffness`, `sensor_mass`, …).
    pub id: String,
    /// Its parameters as given in the spec (free-form JSON object).
    pub parameters: serde_json::Value,
}

/// Ground truth written by `frf-sim`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct TruthRecord {
    /// Campaign name from the spec.
    pub campaign: String,
    /// The body's true inertia properties.
    pub properties: PropertiesRecord,
    /// True modes and mount stiffness per suspension set-up.
    pub setups: Vec<TrueSetupRecord>,
    /// Effects of the physics catalogue the simulation switched on.
    pub effects: Vec<EffectRecord>,
    /// Seed of the noise stream.
    pub seed: u64,
    /// Relative noise level (fraction of |H|) and absolute floor (FRF units).
    pub noise_relative: f64,
    /// Absolute noise floor `b` of `σ² = a²|H|² + b²` (FRF units; docs/conventions.md §8).
    pub noise_floor: f64,
}

/// One identified mode of one excitation (output of `modal-fit`).
///
/// Residues are *modal constants* in the receptance form of docs/conventions.md:
/// `H_i(ω) = Σ_r A_ir / (ω_r² − ω² + 2iζ_r ω_r ω)` with `A_ir` in 1/kg, whatever quantity
/// the input FRFs were. For a proportionally damped rigid body `A_ir = (s_iᵀφ_r)(f_kᵀφ_r)`,
/// real; the imaginary part measures modal complexity.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ModeEstimate {
    /// Excitation id the fit is of.
    pub excitation: String,
    /// Its suspension set-up.
    pub setup: String,
    /// 1-based mode number within this excitation, ascending frequency.
    pub mode: usize,
    /// Natural frequency `f_r` (Hz).
    pub frequency_hz: f64,
    /// Standard error of `frequency_hz` (Hz).
    pub frequency_std_hz: f64,
    /// Viscous damping ratio `ζ_r`.
    pub damping_ratio: f64,
    /// Standard error of `damping_ratio`.
    pub damping_std: f64,
    /// Modal constants per channel (geometry channel order), `[re, im]`, 1/kg.
    #[schemars(with = "Vec<[f64; 2]>")]
    pub residues: Vec<c64>,
    /// Standard error of each residue (same for re and im), 1/kg.
    pub residue_std: Vec<f64>,
    /// 0..1: how sure the pole selection is that this is one physical mode.
    pub confidence: f64,
    /// Mode phase collinearity (1 = real mode).
    pub mpc: f64,
    /// True when the excitation barely excites this mode: its numbers are unreliable.
    pub weak: bool,
    /// Notes on this mode (a close pair, a weak excitation, …), human-readable.
    pub warnings: Vec<String>,
}

/// Per-excitation summary of the identification.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ExcitationFitRecord {
    /// Excitation id.
    pub excitation: String,
    /// Its suspension set-up.
    pub setup: String,
    /// `lsce`, `lscf`, `plscf` or `circle` (the names of [`FitMethod`]).
    #[schemars(with = "String")]
    pub method: FitMethod,
    /// Model order chosen (number of modes in the band).
    pub model_order: usize,
    /// Frequency band fitted, `[low, high]` (Hz).
    pub band_hz: [f64; 2],
    /// Number of spectral lines in the band.
    pub n_lines: usize,
    /// Normalised fit error per channel: ‖H_meas − H_synth‖² / ‖H_meas‖² over the band.
    pub fit_error: Vec<f64>,
    /// Notes on the fit, human-readable.
    pub warnings: Vec<String>,
}

/// Output of `modal-fit`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, Default)]
pub struct ModalFitRecord {
    /// How residues are scaled (the receptance modal-constant form above).
    pub residue_convention: String,
    /// One summary per excitation, geometry order.
    pub excitations: Vec<ExcitationFitRecord>,
    /// Every identified mode of every excitation.
    pub modes: Vec<ModeEstimate>,
    /// Present when the poles were corrected for an exponential window on the responses:
    /// the frequencies and damping ratios are the physical ones, the window's damping
    /// removed. Later stages must not correct again (and a resampling of the measured
    /// FRFs must put the window back).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window_correction: Option<WindowCorrectionRecord>,
    /// What the fit noticed, typed: one diagnostic per fact (a repeated root is one
    /// diagnostic naming its modes and every excitation where it shows). Absent in
    /// records written before diagnostics were typed (the `warnings` strings remain).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub diagnostics: Vec<Diagnostic>,
}

/// One fact a stage noticed while computing, typed: what it is about (`kind`), how much it
/// matters (`severity`), whom it concerns (`subject`), a message with the numbers and what
/// to do about it. One fact is one diagnostic, however many excitations or modes it
/// concerns.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Diagnostic {
    /// The stage that raised it (`modal-fit`, …).
    pub stage: String,
    /// What it is about; [`DiagnosticKind::sentence`] explains it.
    #[schemars(with = "String")]
    pub kind: DiagnosticKind,
    /// How much it matters.
    #[schemars(with = "String")]
    pub severity: Severity,
    /// Whom it concerns.
    pub subject: DiagnosticSubject,
    /// The fact, with its numbers (one sentence, no subject prefix needed).
    pub message: String,
    /// What to do about it (empty when nothing is to be done).
    #[serde(default)]
    pub advice: String,
}

/// Whom a [`Diagnostic`] concerns: any of a set-up, excitations, modes (with their
/// frequencies), a channel, a sensor, a hit. Empty fields: not specific to one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, Default)]
pub struct DiagnosticSubject {
    /// The recording (a campaign item's label), when gathered over a campaign.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub recording: Option<String>,
    /// Suspension set-up.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub setup: Option<String>,
    /// Excitation ids.
    #[serde(default)]
    pub excitations: Vec<String>,
    /// 1-based mode numbers within the set-up's kept fit.
    #[serde(default)]
    pub modes: Vec<usize>,
    /// The modes' natural frequencies (Hz), as `modes`.
    #[serde(default)]
    pub frequencies_hz: Vec<f64>,
    /// Response channel id.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub channel: Option<String>,
    /// Sensor (point) id.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensor: Option<String>,
    /// Hit number (1-based) within its excitation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hit: Option<usize>,
}

impl DiagnosticSubject {
    /// The subject in words: `set-up A, excitations fx, fy, modes 5 and 6 (0.5030, 0.5045 Hz)`.
    pub fn describe(&self) -> String {
        let mut parts = Vec::new();
        if let Some(r) = &self.recording {
            parts.push(r.clone());
        }
        if let Some(s) = &self.setup {
            parts.push(format!("set-up {s}"));
        }
        match self.excitations.len() {
            0 => {}
            1 => parts.push(format!("excitation {}", self.excitations[0])),
            _ => parts.push(format!("excitations {}", self.excitations.join(", "))),
        }
        if !self.modes.is_empty() {
            let n: Vec<String> = self.modes.iter().map(|m| m.to_string()).collect();
            let mut t = if n.len() == 1 {
                format!("mode {}", n[0])
            } else {
                let (last, rest) = n.split_last().unwrap();
                format!("modes {} and {last}", rest.join(", "))
            };
            if self.frequencies_hz.len() == self.modes.len() {
                let f: Vec<String> = self
                    .frequencies_hz
                    .iter()
                    .map(|f| format!("{f:.4}"))
                    .collect();
                t.push_str(&format!(" ({} Hz)", f.join(", ")));
            }
            parts.push(t);
        } else if !self.frequencies_hz.is_empty() {
            let f: Vec<String> = self
                .frequencies_hz
                .iter()
                .map(|f| format!("{f:.4}"))
                .collect();
            parts.push(format!("at {} Hz", f.join(", ")));
        }
        if let Some(c) = &self.channel {
            parts.push(format!("channel {c}"));
        }
        if let Some(s) = &self.sensor {
            parts.push(format!("sensor {s}"));
        }
        if let Some(h) = self.hit {
            parts.push(format!("hit {h}"));
        }
        parts.join(", ")
    }
}

impl DiagnosticSubject {
    /// Concerning one set-up.
    pub fn setup(setup: impl Into<String>) -> Self {
        DiagnosticSubject {
            setup: Some(setup.into()),
            ..Default::default()
        }
    }

    /// Concerning nothing in particular (the whole run).
    pub fn run() -> Self {
        DiagnosticSubject::default()
    }

    /// … and one excitation.
    pub fn excitation(mut self, excitation: impl Into<String>) -> Self {
        self.excitations.push(excitation.into());
        self
    }

    /// … and one mode (1-based within its set-up) at its frequency.
    pub fn mode(mut self, mode: usize, frequency_hz: f64) -> Self {
        self.modes.push(mode);
        self.frequencies_hz.push(frequency_hz);
        self
    }

    /// … and one mode whose frequency is not at hand.
    pub fn mode_number(mut self, mode: usize) -> Self {
        self.modes.push(mode);
        self
    }

    /// … and frequencies (Hz) with no mode numbers (candidate modes, peaks).
    pub fn at_hz(mut self, frequencies_hz: &[f64]) -> Self {
        self.frequencies_hz.extend_from_slice(frequencies_hz);
        self
    }

    /// … and one channel.
    pub fn channel(mut self, channel: impl Into<String>) -> Self {
        self.channel = Some(channel.into());
        self
    }
}

impl Diagnostic {
    /// A diagnostic with no advice.
    pub fn new(
        stage: &str,
        kind: DiagnosticKind,
        severity: Severity,
        subject: DiagnosticSubject,
        message: impl Into<String>,
    ) -> Self {
        Diagnostic {
            stage: stage.into(),
            kind,
            severity,
            subject,
            message: message.into(),
            advice: String::new(),
        }
    }

    /// The same with what to do about it.
    pub fn advise(mut self, advice: impl Into<String>) -> Self {
        self.advice = advice.into();
        self
    }

    /// A message of a file written before diagnostics were typed: kind
    /// [`DiagnosticKind::Text`], severity unknown and so shown ([`Severity::Warning`]),
    /// stage unknown until the reader fills it in (empty).
    pub fn from_text(text: impl Into<String>) -> Self {
        Diagnostic::new(
            "",
            DiagnosticKind::Text,
            Severity::Warning,
            DiagnosticSubject::run(),
            text,
        )
    }

    /// The diagnostic as one line: `subject: message (advice)`.
    pub fn line(&self) -> String {
        let subject = self.subject.describe();
        let mut t = if subject.is_empty() {
            self.message.clone()
        } else {
            format!("{subject}: {}", self.message)
        };
        if !self.advice.is_empty() {
            t.push_str(&format!("; {}", self.advice));
        }
        t
    }
}

/// Reads a list of diagnostics, or the list of strings an older file holds in its place
/// (each a [`Diagnostic::from_text`]).
pub fn diagnostics_or_texts<'de, D>(d: D) -> Result<Vec<Diagnostic>, D::Error>
where
    D: serde::Deserializer<'de>,
{
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Item {
        Typed(Diagnostic),
        Text(String),
    }
    Ok(Vec::<Item>::deserialize(d)?
        .into_iter()
        .map(|i| match i {
            Item::Typed(d) => d,
            Item::Text(t) => Diagnostic::from_text(t),
        })
        .collect())
}

/// The exponential-window correction `modal-fit` applied (see
/// [`crate::WindowCorrection`]): every pole moved from `λ − 1/τ` back to `λ`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct WindowCorrectionRecord {
    /// τ of `w(t) = e^{−t/τ}` (s).
    pub time_constant_s: f64,
    /// Where τ came from: `recording` (the processing topic) or `command line`.
    pub source: String,
}

/// How the FRFs of a recording were processed (topic `/rbprops/processing`, one message).
/// Stages read it; a command-line option may override it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, Default)]
pub struct ProcessingRecord {
    /// Time constant τ (s) of an exponential window `e^{−t/τ}` applied to the response
    /// records (force window, if any, short against τ). Absent: no window.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exponential_window_s: Option<f64>,
    /// The line weighting `modal-fit` used for its least-squares fits; absent: the
    /// default (`none`: relative weights `1/|H|`, no measured quality).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub line_weighting: Option<LineWeightingRecord>,
    /// How `frf-est` made the FRFs from time histories (absent: FRFs read as given).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frf_estimation: Option<FrfEstimationRecord>,
}

/// What the FRF estimator did (`frf-est`, docs/conventions.md §FRF estimation): the
/// estimator, sampling and record, windows, averages per excitation, the correlation its
/// windows put between neighbouring lines' noise, and every hit with its verdict.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct FrfEstimationRecord {
    /// `H1`, `H2` or `Hv`.
    pub estimator: String,
    /// Sampling rate of the time histories (Hz).
    pub sample_rate_hz: f64,
    /// Samples per record (the DFT length N; the line spacing is `sample_rate_hz / N`).
    pub record_samples: usize,
    /// Time from the record's start to the trigger (s).
    pub pretrigger_s: f64,
    /// Force window: rectangular from `start_s` to `end_s` after the trigger, with cosine
    /// tapers of `taper_s` at both ends; absent: none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force_window: Option<ForceWindowRecord>,
    /// The exponential window's τ (s), starting at the trigger, on the response and on
    /// the force when `exponential_on_force`; absent: none (the same τ is in
    /// [`ProcessingRecord::exponential_window_s`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exponential_window_s: Option<f64>,
    /// The exponential window is applied to the force as well (so `H_w(ω) = H(iω + 1/τ)`).
    pub exponential_on_force: bool,
    /// Averages (accepted hits) and rejected hits per excitation.
    pub averages: Vec<ExcitationAveragesRecord>,
    /// `γ_m = E[ε_k ε̄_{k−m}] / E|ε|²` for m = 0, 1, … (γ₀ = 1), `[re, im]`: the noise
    /// correlation between lines m apart that the response window implies.
    pub line_correlation: Vec<[f64; 2]>,
    /// How each line's variance (topic `/rbprops/frf_variance`) was obtained.
    pub variance_method: String,
    /// Every hit, accepted or not.
    pub hits: Vec<HitRecord>,
}

/// The force window of [`FrfEstimationRecord`] (times relative to the trigger).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ForceWindowRecord {
    /// Start (s, negative: before the trigger).
    pub start_s: f64,
    /// End (s).
    pub end_s: f64,
    /// Cosine taper at each end (s).
    pub taper_s: f64,
}

/// Averages of one excitation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ExcitationAveragesRecord {
    /// Excitation id.
    pub excitation: String,
    /// Hits averaged (n_d).
    pub accepted: usize,
    /// Hits rejected.
    pub rejected: usize,
    /// Median relative standard error of the FRF lines in the fitted band (σ/|H|).
    pub relative_standard_error: f64,
    /// Accepted hits needed in all to halve it (4 n_d when it falls as 1/√n_d).
    pub hits_to_halve: usize,
    /// RMS over the band of the relative error the force channel's noise puts into every
    /// FRF of this excitation alike: `√(σ_m² Σw_f² / S_ff)` per line, σ_m the force's
    /// pretrigger noise, w_f its window. Common to the channels and smooth over the lines
    /// (the force window is short), it looks like a small gain and delay of the
    /// excitation, which is why the model check does not claim effects below it.
    #[serde(default)]
    pub force_noise_relative_error: f64,
}

/// One hit as the estimator judged it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct HitRecord {
    /// Excitation id.
    pub excitation: String,
    /// Hit number within the excitation (1-based, file order).
    pub hit: usize,
    /// Averaged into the FRFs.
    pub accepted: bool,
    /// Why it was rejected (empty when accepted).
    pub reasons: Vec<String>,
    /// Trigger time from the start of its record (s).
    pub trigger_s: f64,
    /// Peak force (N).
    pub peak_force_n: f64,
    /// The force window's flat part `[start, end)` (s from the start of the hit's record,
    /// a multiple of the sampling interval), when a force window was applied: with the
    /// trigger and the exponential window's τ, what another estimator needs to apply the
    /// same windows.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force_window_s: Option<[f64; 2]>,
    /// Clipped samples per channel (the force first, then the responses in file order).
    pub clipped_samples: Vec<usize>,
    /// Delay of a second contact after the first (s), if one was found.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub double_hit_delay_s: Option<f64>,
    /// Peak of the second contact over the first's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub double_hit_ratio: Option<f64>,
}

/// A measured-quality weighting of the FRF lines in `modal-fit` (`--weight coherence`):
/// every line's least-squares weight is multiplied by `√(γ²/(1 − γ²))`, `γ²` the
/// coherence of the line (averaged over the channels as relative variances, see
/// `rbprops_core::CoherenceNoise`), with `1 − γ²` floored at `one_minus_coherence_floor`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct LineWeightingRecord {
    /// `coherence`, or `variance` (the estimator's line variances, topic
    /// `/rbprops/frf_variance`: relative variance σ²/|H|² in place of (1 − γ²)/γ², the
    /// same floor).
    pub weight: String,
    /// How the weights were made, in words (the method text).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub method: String,
    /// Floor of `1 − γ²` (the precision the coherence is trusted to), or with `variance`
    /// of the relative variance σ²/|H|².
    pub one_minus_coherence_floor: f64,
    /// Excitations with no coherence in the recording, fitted with the default weights.
    #[serde(default)]
    pub unweighted_excitations: usize,
}

impl LineWeightingRecord {
    /// [`LineWeightingRecord::weight`] of a fit weighted by the estimator's line variances.
    pub const VARIANCE: &'static str = "variance";
    /// [`LineWeightingRecord::weight`] of a fit weighted by the measured coherence.
    pub const COHERENCE: &'static str = "coherence";
}

/// Topic name of [`ProcessingRecord`].
pub const PROCESSING_TOPIC: &str = "/rbprops/processing";

/// A mode chosen for the inertia estimate: which excitation's shape is used.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SelectedMode {
    /// Suspension set-up the mode belongs to.
    pub setup: String,
    /// 1-based physical mode number within the set-up (matched across excitations).
    pub mode: usize,
    /// Natural frequency of the chosen estimate (Hz).
    pub frequency_hz: f64,
    /// Excitation whose shape is used.
    pub excitation: String,
    /// The mode number within that excitation's `ModeEstimate`s.
    pub excitation_mode: usize,
    /// NI of the chosen excitation at the mode (dB re 1 FRF unit).
    pub ni_db: f64,
    /// NI margin over the runner-up excitation (dB); NaN-free: 0 when there is none.
    pub margin_db: f64,
    /// The excitation with the next-highest NI, when there is one.
    pub runner_up: Option<String>,
    /// Excitation strength `f_kᵀq` (1/kg); ≤ 0 means not excited.
    pub strength: f64,
    /// `ni`, `hybrid_mif`, `prf_mif` or `manual`.
    #[schemars(with = "String")]
    pub criterion: SelectionCriterion,
}

/// A mode no excitation excites above the noise.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct MissingMode {
    /// Suspension set-up.
    pub setup: String,
    /// 1-based physical mode number within the set-up.
    pub mode: usize,
    /// Expected frequency (Hz).
    pub frequency_hz: f64,
    /// Excitations that were considered.
    pub tried: Vec<String>,
    /// Why none was usable, human-readable.
    pub reason: String,
}

/// Output of `ni-select`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, Default)]
pub struct SelectionRecord {
    /// The modes chosen, one per physical mode.
    pub selected: Vec<SelectedMode>,
    /// Modes no excitation excites usably.
    pub missing: Vec<MissingMode>,
    /// What the selection noticed, typed, one diagnostic per fact. Records written before
    /// diagnostics were typed hold `warnings` (strings): they read as [`DiagnosticKind::Text`].
    #[serde(
        default,
        alias = "warnings",
        deserialize_with = "diagnostics_or_texts",
        skip_serializing_if = "Vec::is_empty"
    )]
    pub diagnostics: Vec<Diagnostic>,
}

/// One estimator's result (output of `rb-solve`); the JSON interface of `--format json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct InertiaEstimate {
    /// `bretl_conti`, `toivola_nuutila`, `mass_line`, or one of them with `_projected`
    /// (the names of [`EstimateMethod`]).
    #[schemars(with = "String")]
    pub method: EstimateMethod,
    /// Suspension set-up of the modes used (or a combination of set-ups).
    pub setup: String,
    /// Origin the estimator worked about, geometry frame (m).
    pub origin_m: [f64; 3],
    /// Mass `m` (kg).
    pub mass_kg: f64,
    /// Standard error of `mass_kg` (kg).
    pub mass_std_kg: f64,
    /// Centre of mass `c` in the geometry's frame (m).
    pub com_m: [f64; 3],
    /// Standard errors of `com_m` (m).
    pub com_std_m: [f64; 3],
    /// Inertia tensor `J` about the CoM, row-major (kg m²), docs/conventions.md §3.
    pub inertia_cm_kg_m2: [[f64; 3]; 3],
    /// Standard errors of `inertia_cm_kg_m2` entry by entry (kg m²).
    pub inertia_cm_std_kg_m2: [[f64; 3]; 3],
    /// Products `J_xy, J_xz, J_yz` (kg m²), the negated off-diagonals of the tensor.
    pub products_of_inertia_kg_m2: Products,
    /// Standard errors of the products (kg m²), those of the tensor entries.
    pub products_of_inertia_std_kg_m2: Products,
    /// Principal moments (ascending) and their axes (columns of the 3×3).
    pub principal_moments_kg_m2: [f64; 3],
    /// Principal axes, unit columns matching `principal_moments_kg_m2`.
    pub principal_axes: [[f64; 3]; 3],
    /// Mount stiffness about the origin `K0 = Φ0⁻ᵀΩ²Φ0⁻¹` when six modes exist.
    pub mount_stiffness: Option<[[f64; 6]; 6]>,
    /// Estimator residual (dimensionless, defined per method).
    pub residual: f64,
    /// How the standard errors were obtained (`linearised`, `monte_carlo`, `bootstrap`,
    /// `none`: the names of [`UncertaintyMethod`]).
    #[schemars(with = "String")]
    pub uncertainty_method: UncertaintyMethod,
    /// How the standard errors were obtained, in words, where `uncertainty_method` does not
    /// say it all (the bootstrap: what its replicates' noise was drawn from, on which lines).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uncertainty_source: Option<String>,
    /// Mode numbers (per set-up) the estimator used.
    pub modes_used: Vec<usize>,
    /// Excitations whose shapes were used.
    pub excitations_used: Vec<String>,
    /// Relative errors vs reference values when given: mass, com, inertia, sum.
    pub errors: Option<ErrorsRecord>,
    /// True when the tensor is positive definite and obeys the triangle inequalities.
    pub physically_consistent: bool,
    /// What the estimator noticed, typed, one diagnostic per fact. Records written before
    /// diagnostics were typed hold `warnings` (strings): they read as [`DiagnosticKind::Text`].
    #[serde(
        default,
        alias = "warnings",
        deserialize_with = "diagnostics_or_texts",
        skip_serializing_if = "Vec::is_empty"
    )]
    pub diagnostics: Vec<Diagnostic>,
    /// Whether the modes the estimate used are rigid-body consistent with the geometry
    /// (sensor rows and force columns) within their noise; see `rigid_body_check`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rigid_body_consistent: Option<bool>,
    /// The statistics behind `rigid_body_consistent`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rigid_body_check: Option<RigidBodyCheckRecord>,
    /// Systematic-error interval: leave-one-sensor-out and leave-one-excitation-out
    /// jackknife, combined with the noise standard errors.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub systematic: Option<SystematicIntervalRecord>,
}

/// One channel, sensor or excitation of the rigid-body consistency check.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ConsistencyItemRecord {
    /// Id of the channel, sensor (point) or excitation.
    pub id: String,
    /// Drop of the noise-weighted residual χ² when this item is left out.
    pub chi2_drop: f64,
    /// Degrees of freedom of that drop.
    pub dof: usize,
    /// Leaving it out makes the rest consistent (it explains the inconsistency).
    pub suspect: bool,
}

/// The rigid-body consistency of the identified modes with the geometry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct RigidBodyCheckRecord {
    /// True when `statistic ≤ threshold`.
    pub rigid_body_consistent: bool,
    /// What `statistic` is.
    pub statistic_definition: String,
    /// Residual χ² per degree of freedom, shapes and participations together.
    pub statistic: f64,
    /// The statistic's upper limit for noise alone.
    pub threshold: f64,
    /// Degrees of freedom of `statistic`.
    pub dof: usize,
    /// χ²/dof of the rigid-body transform residuals (paper Eq. 5), per channel noise.
    pub shape_statistic: f64,
    /// Degrees of freedom of `shape_statistic`.
    pub shape_dof: usize,
    /// χ²/dof of the modal participations across excitations (force geometry).
    pub participation_statistic: f64,
    /// Degrees of freedom of `participation_statistic`.
    pub participation_dof: usize,
    /// Per response channel.
    pub channels: Vec<ConsistencyItemRecord>,
    /// Per sensor (all channels at one point).
    pub sensors: Vec<ConsistencyItemRecord>,
    /// Per excitation.
    pub excitations: Vec<ConsistencyItemRecord>,
}

/// Systematic-error standard errors (jackknife) and the 95 % interval that combines them
/// with the noise standard errors: `estimate ± 1.96 √(σ²_noise + σ²_systematic)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SystematicIntervalRecord {
    /// How the units were left out (`sensor`, `channel`, `excitation` counts).
    pub method: String,
    /// Jackknife standard error of the mass (kg).
    pub mass_std_kg: f64,
    /// Jackknife standard errors of the CoM (m).
    pub com_std_m: [f64; 3],
    /// Jackknife standard errors of the tensor entries (kg m²).
    pub inertia_cm_std_kg_m2: [[f64; 3]; 3],
    /// 95 % interval of the mass (kg).
    pub mass_95_kg: [f64; 2],
    /// 95 % interval of each CoM coordinate (m).
    pub com_95_m: [[f64; 2]; 3],
    /// 95 % interval of each tensor entry (kg m²).
    pub inertia_cm_95_kg_m2: [[[f64; 2]; 3]; 3],
}

impl InertiaEstimate {
    /// Recomputes the systematic 95 % interval from the current noise standard errors
    /// (after a bootstrap replaced them).
    pub fn update_systematic_interval(&mut self) {
        let Some(s) = self.systematic.as_mut() else {
            return;
        };
        let iv = |v: f64, a: f64, b: f64| {
            let h = 1.96 * (a * a + b * b).sqrt();
            [v - h, v + h]
        };
        s.mass_95_kg = iv(self.mass_kg, self.mass_std_kg, s.mass_std_kg);
        s.com_95_m = std::array::from_fn(|i| iv(self.com_m[i], self.com_std_m[i], s.com_std_m[i]));
        s.inertia_cm_95_kg_m2 = std::array::from_fn(|r| {
            std::array::from_fn(|c| {
                iv(
                    self.inertia_cm_kg_m2[r][c],
                    self.inertia_cm_std_kg_m2[r][c],
                    s.inertia_cm_std_kg_m2[r][c],
                )
            })
        });
    }
}

/// The paper's relative error measures.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ErrorsRecord {
    /// `|m̂ − m|/|m|`.
    pub mass: f64,
    /// `‖ĉ − c‖/‖c‖`.
    pub com: f64,
    /// `‖ĵ − j‖/‖j‖` over `{Jxx Jxy Jxz Jyy Jyz Jzz}`.
    pub inertia: f64,
    /// The sum of the three.
    pub sum: f64,
}

#[cfg(test)]
mod diagnostic_tests {
    use super::*;

    /// A `modal_fit` message written before diagnostics were typed still reads (no
    /// `diagnostics` field: none), and an empty list is not written.
    #[test]
    fn old_modal_fit_records_still_read() {
        let old = r#"{"residue_convention":"x","excitations":[],"modes":[]}"#;
        let r: ModalFitRecord = serde_json::from_str(old).unwrap();
        assert!(r.diagnostics.is_empty());
        assert_eq!(serde_json::to_string(&r).unwrap(), old);
    }

    /// A selection or an estimate written before diagnostics were typed still reads: its
    /// strings become [`DiagnosticKind::Text`] diagnostics, shown as warnings; a typed
    /// list round-trips.
    #[test]
    fn old_string_warnings_still_read() {
        let old = r#"{"selected":[],"missing":[],"warnings":["set-up 'A': something"]}"#;
        let r: SelectionRecord = serde_json::from_str(old).unwrap();
        assert_eq!(
            r.diagnostics,
            vec![Diagnostic::from_text("set-up 'A': something")]
        );
        assert_eq!(r.diagnostics[0].kind, DiagnosticKind::Text);
        assert_eq!(r.diagnostics[0].severity, Severity::Warning);
        let new = SelectionRecord {
            diagnostics: vec![Diagnostic::new(
                "ni-select",
                DiagnosticKind::ModeMissing,
                Severity::ChangesAnswer,
                DiagnosticSubject::setup("A").mode(3, 1.25),
                "not excited",
            )],
            ..Default::default()
        };
        let json = serde_json::to_string(&new).unwrap();
        assert!(json.contains("\"diagnostics\":[{"), "{json}");
        assert_eq!(serde_json::from_str::<SelectionRecord>(&json).unwrap(), new);
        let empty = serde_json::to_string(&SelectionRecord::default()).unwrap();
        assert_eq!(empty, r#"{"selected":[],"missing":[]}"#);
    }

    /// The table of kinds in docs/formats.md (section "Diagnostics") is every kind's
    /// sentence, as written here: this pins each kind's text for the reader and the
    /// report. `RBPROPS_BLESS=1` rewrites the table (review the diff).
    #[test]
    fn formats_md_lists_every_kind_with_its_sentence() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/formats.md");
        let doc = std::fs::read_to_string(path).unwrap();
        let (begin, end) = (
            "<!-- diagnostic kinds: begin -->\n",
            "<!-- diagnostic kinds: end -->",
        );
        let i = doc.find(begin).expect("the begin marker") + begin.len();
        let j = doc.find(end).expect("the end marker");
        let mut table = String::from("| kind | what it means for the result |\n|---|---|\n");
        for k in DiagnosticKind::ALL {
            table.push_str(&format!("| `{}` | {} |\n", k.as_str(), k.sentence()));
        }
        if std::env::var_os("RBPROPS_BLESS").is_some() {
            std::fs::write(path, format!("{}{table}{}", &doc[..i], &doc[j..])).unwrap();
            return;
        }
        assert_eq!(
            doc[i..j],
            table,
            "docs/formats.md's table of diagnostic kinds (RBPROPS_BLESS=1 rewrites it)"
        );
    }

    /// Every kind has its own sentence, and the kinds and severities serialise as their
    /// snake_case names.
    #[test]
    fn every_kind_has_its_own_sentence() {
        let mut seen = std::collections::HashSet::new();
        for k in DiagnosticKind::ALL {
            let s = k.sentence();
            assert!(s.len() > 40 && s.ends_with('.'), "{k}: {s}");
            assert!(seen.insert(s), "{k} shares its sentence");
            assert_eq!(
                serde_json::to_string(k).unwrap(),
                format!("\"{}\"", k.as_str())
            );
        }
        assert_eq!(
            serde_json::to_string(&Severity::ChangesAnswer).unwrap(),
            "\"changes_answer\""
        );
        let d = Diagnostic {
            stage: "modal-fit".into(),
            kind: DiagnosticKind::RepeatedRoot,
            severity: Severity::Note,
            subject: DiagnosticSubject {
                setup: Some("A".into()),
                excitations: vec!["fx".into(), "fy".into(), "fz".into()],
                modes: vec![1, 2],
                frequencies_hz: vec![0.50301, 0.50453],
                ..Default::default()
            },
            message: "separated by the poly-reference fit".into(),
            advice: String::new(),
        };
        assert_eq!(
            d.line(),
            "set-up A, excitations fx, fy, fz, modes 1 and 2 (0.5030, 0.5045 Hz): separated by the poly-reference fit"
        );
    }
}
