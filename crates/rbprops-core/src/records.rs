//! Records that cross stage boundaries. They are plain data (arrays, not nalgebra
//! types) with `serde` + `schemars` derives so that `rbprops-formats` can write them as
//! JSON messages with a JSON schema (MCAP) and as CSV tables.
//!
//! Field names carry their units. Complex numbers are `[re, im]` pairs.

use crate::c64;
pub use crate::methods::{EstimateMethod, FitMethod, SelectionCriterion, UncertaintyMethod};
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
    pub xy: f64,
    pub xz: f64,
    pub yz: f64,
}

/// Mass, CoM and inertia at the CoM.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct PropertiesRecord {
    pub mass_kg: f64,
    /// Centre of mass in the geometry's frame (m).
    pub com_m: [f64; 3],
    /// Inertia tensor about the CoM (row-major; off-diagonals are minus the products).
    pub inertia_cm_kg_m2: [[f64; 3]; 3],
}

impl PropertiesRecord {
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
    // Exactly 0 for a free rigid-body direction (the suspension gives it no stiffness),
    // whose damping ratio is then 0 and whose shape is one of a mass-orthonormal basis
    // of the free directions (`rigid_body_modes`). A plain comment, not a doc comment:
    // the record's JSON schema stays as published.
    pub frequency_hz: f64,
    pub damping_ratio: f64,
    /// Mass-normalised shape `[u_x, u_y, u_z, θ_x, θ_y, θ_z]` about the origin.
    pub shape: [f64; 6],
}

/// The true modes of one suspension set-up.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct TrueSetupRecord {
    pub setup: String,
    /// Mount stiffness about the origin, 6×6 row-major (N/m, N, N m/rad).
    pub stiffness: [[f64; 6]; 6],
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
    pub campaign: String,
    pub properties: PropertiesRecord,
    pub setups: Vec<TrueSetupRecord>,
    pub effects: Vec<EffectRecord>,
    pub seed: u64,
    /// Relative noise level (fraction of |H|) and absolute floor (FRF units).
    pub noise_relative: f64,
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
    pub excitation: String,
    pub setup: String,
    /// 1-based mode number within this excitation, ascending frequency.
    pub mode: usize,
    pub frequency_hz: f64,
    pub frequency_std_hz: f64,
    pub damping_ratio: f64,
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
    pub warnings: Vec<String>,
}

/// Per-excitation summary of the identification.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ExcitationFitRecord {
    pub excitation: String,
    pub setup: String,
    /// `lsce`, `lscf` or `circle`.
    // Also `plscf`: the names are those of [`FitMethod`]. A plain comment, not a doc
    // comment: the record's JSON schema stays as published.
    #[schemars(with = "String")]
    pub method: FitMethod,
    /// Model order chosen (number of modes in the band).
    pub model_order: usize,
    pub band_hz: [f64; 2],
    pub n_lines: usize,
    /// Normalised fit error per channel: ‖H_meas − H_synth‖² / ‖H_meas‖² over the band.
    pub fit_error: Vec<f64>,
    pub warnings: Vec<String>,
}

/// Output of `modal-fit`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, Default)]
pub struct ModalFitRecord {
    pub residue_convention: String,
    pub excitations: Vec<ExcitationFitRecord>,
    pub modes: Vec<ModeEstimate>,
    /// Present when the poles were corrected for an exponential window on the responses:
    /// the frequencies and damping ratios are the physical ones, the window's damping
    /// removed. Later stages must not correct again (and a resampling of the measured
    /// FRFs must put the window back).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window_correction: Option<WindowCorrectionRecord>,
}

/// The exponential-window correction `modal-fit` applied (see
/// [`crate::modal::ExponentialWindow`]): every pole moved from `λ − 1/τ` back to `λ`.
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
}

/// A measured-quality weighting of the FRF lines in `modal-fit` (`--weight coherence`):
/// every line's least-squares weight is multiplied by `√(γ²/(1 − γ²))`, `γ²` the
/// coherence of the line (averaged over the channels as relative variances, see
/// `rbprops_core::CoherenceNoise`), with `1 − γ²` floored at `one_minus_coherence_floor`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct LineWeightingRecord {
    /// `coherence`.
    pub weight: String,
    /// Floor of `1 − γ²` (the precision the coherence is trusted to).
    pub one_minus_coherence_floor: f64,
    /// Excitations with no coherence in the recording, fitted with the default weights.
    #[serde(default)]
    pub unweighted_excitations: usize,
}

/// Topic name of [`ProcessingRecord`].
pub const PROCESSING_TOPIC: &str = "/rbprops/processing";

/// A mode chosen for the inertia estimate: which excitation's shape is used.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SelectedMode {
    pub setup: String,
    /// 1-based physical mode number within the set-up (matched across excitations).
    pub mode: usize,
    pub frequency_hz: f64,
    pub excitation: String,
    /// The mode number within that excitation's `ModeEstimate`s.
    pub excitation_mode: usize,
    /// NI of the chosen excitation at the mode (dB re 1 FRF unit).
    pub ni_db: f64,
    /// NI margin over the runner-up excitation (dB); NaN-free: 0 when there is none.
    pub margin_db: f64,
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
    pub setup: String,
    pub mode: usize,
    pub frequency_hz: f64,
    pub tried: Vec<String>,
    pub reason: String,
}

/// Output of `ni-select`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, Default)]
pub struct SelectionRecord {
    pub selected: Vec<SelectedMode>,
    pub missing: Vec<MissingMode>,
    pub warnings: Vec<String>,
}

/// One estimator's result (output of `rb-solve`); the JSON interface of `--format json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct InertiaEstimate {
    /// `bretl_conti`, `toivola_nuutila`, `mass_line`, `model_fit`.
    // The names are those of [`EstimateMethod`] (`model_fit` is not produced; `_projected`
    // versions are). A plain comment: the record's JSON schema stays as published.
    #[schemars(with = "String")]
    pub method: EstimateMethod,
    pub setup: String,
    /// Origin the estimator worked about, geometry frame (m).
    pub origin_m: [f64; 3],
    pub mass_kg: f64,
    pub mass_std_kg: f64,
    pub com_m: [f64; 3],
    pub com_std_m: [f64; 3],
    pub inertia_cm_kg_m2: [[f64; 3]; 3],
    pub inertia_cm_std_kg_m2: [[f64; 3]; 3],
    pub products_of_inertia_kg_m2: Products,
    pub products_of_inertia_std_kg_m2: Products,
    /// Principal moments (ascending) and their axes (columns of the 3×3).
    pub principal_moments_kg_m2: [f64; 3],
    pub principal_axes: [[f64; 3]; 3],
    /// Mount stiffness about the origin `K0 = Φ0⁻ᵀΩ²Φ0⁻¹` when six modes exist.
    pub mount_stiffness: Option<[[f64; 6]; 6]>,
    /// Estimator residual (dimensionless, defined per method).
    pub residual: f64,
    /// How the standard errors were obtained (`linearised`, `monte_carlo`, `none`).
    // Also `bootstrap` ([`UncertaintyMethod`]); plain comment, the schema stays as published.
    #[schemars(with = "String")]
    pub uncertainty_method: UncertaintyMethod,
    pub modes_used: Vec<usize>,
    pub excitations_used: Vec<String>,
    /// Relative errors vs reference values when given: mass, com, inertia, sum.
    pub errors: Option<ErrorsRecord>,
    pub physically_consistent: bool,
    pub warnings: Vec<String>,
    /// Whether the modes the estimate used are rigid-body consistent with the geometry
    /// (sensor rows and force columns) within their noise; see `rigid_body_check`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rigid_body_consistent: Option<bool>,
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
    pub rigid_body_consistent: bool,
    /// What `statistic` is.
    pub statistic_definition: String,
    /// Residual χ² per degree of freedom, shapes and participations together.
    pub statistic: f64,
    /// The statistic's upper limit for noise alone.
    pub threshold: f64,
    pub dof: usize,
    /// χ²/dof of the rigid-body transform residuals (paper Eq. 5), per channel noise.
    pub shape_statistic: f64,
    pub shape_dof: usize,
    /// χ²/dof of the modal participations across excitations (force geometry).
    pub participation_statistic: f64,
    pub participation_dof: usize,
    pub channels: Vec<ConsistencyItemRecord>,
    pub sensors: Vec<ConsistencyItemRecord>,
    pub excitations: Vec<ConsistencyItemRecord>,
}

/// Systematic-error standard errors (jackknife) and the 95 % interval that combines them
/// with the noise standard errors: `estimate ± 1.96 √(σ²_noise + σ²_systematic)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SystematicIntervalRecord {
    /// How the units were left out (`sensor`, `channel`, `excitation` counts).
    pub method: String,
    pub mass_std_kg: f64,
    pub com_std_m: [f64; 3],
    pub inertia_cm_std_kg_m2: [[f64; 3]; 3],
    pub mass_95_kg: [f64; 2],
    pub com_95_m: [[f64; 2]; 3],
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
    pub mass: f64,
    pub com: f64,
    pub inertia: f64,
    pub sum: f64,
}
