//! The stable, machine-readable model-check report (`--format json`, MCAP topic
//! `/rbprops/model_check`) and its one-paragraph human verdict.

use crate::locate::ResidualMap;
use crate::noise::RecordingNoise;
use rbprops_core::records::{Diagnostic, DiagnosticKind, DiagnosticSubject, Severity};
use serde::{Deserialize, Serialize};

/// A fitted parameter with its standard error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct FittedParameter {
    /// Parameter name as the effect declares it.
    pub name: String,
    /// Its unit (`m`, `rad`, `1`, …).
    pub unit: String,
    /// Fitted value.
    pub value: f64,
    /// Standard error of the value (from the fit's information matrix).
    pub standard_error: f64,
}

/// An effect accepted with statistical evidence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct AcceptedEffect {
    /// Physics-catalogue id (`gravity_stiffness`, ...).
    pub id: String,
    /// One-line title.
    pub title: String,
    /// "rbprops-sim" or "rbprops-check (local)".
    pub source: String,
    /// The effect's fitted parameters.
    pub parameters: Vec<FittedParameter>,
    /// χ² decrease when the effect was added, and its degrees of freedom (identifiable rank).
    pub delta_chi2: f64,
    /// Degrees of freedom of `delta_chi2`.
    pub dof: usize,
    /// Likelihood-ratio threshold χ²_{d, 1−α/N_candidates}.
    pub lr_threshold: f64,
    /// `ΔBIC` of adding the effect (positive favours it).
    pub delta_bic: f64,
    /// Relative change of each inertia quantity caused by adding this effect.
    pub inertia_change: Vec<RelativeChange>,
    /// Unit directions in parameter space the data cannot see (e.g. a common gain,
    /// which the mass absorbs): the parameters are determined only up to adding any
    /// multiple of these, and the values reported have no component along them
    /// relative to the neutral values (exact gauges) or an arbitrary one (first-order).
    pub gauge_directions: Vec<Vec<f64>>,
    /// Held-out check (cross-validation) of the effect when it was accepted; `None`
    /// when the check was switched off.
    pub held_out: Option<HeldOutCheck>,
    /// Leave-one-excitation-out check (recordings with ≥ 3 excitations; `None`
    /// otherwise or when the check was switched off).
    pub held_out_excitations: Option<HeldOutCheck>,
    /// Practical significance: RMS over the values of the effect's fitted change to the
    /// FRFs divided by the precision floor (storage quantisation and computation floor);
    /// an effect is claimed only above `check::PRACTICAL_MARGIN`.
    #[serde(default)]
    pub change_over_precision_floor: f64,
    /// The effect's physical quantities as a tester reads them (degrees, millimetres,
    /// percent, grams), each beside the range a tester finds plausible (docs/physics.md,
    /// "Plausible values"); an effect is claimed only inside them.
    #[serde(default)]
    pub plausible: Vec<PlausibleValue>,
}

/// A physical quantity of a fitted effect and the range a tester would find plausible.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct PlausibleValue {
    /// What it is, with the item it belongs to (`sensor 2: angle`).
    pub quantity: String,
    /// Its unit (`deg`, `mm`, `%`, `g`, `Hz`).
    pub unit: String,
    /// The fitted value in that unit.
    pub value: f64,
    /// The plausible range `[lower, upper]` in that unit.
    pub range: [f64; 2],
}

/// What the catalogue does not explain: the residual left above the noise floor once no
/// catalogue effect with plausible values explains more (docs/physics.md, M7).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Unexplained {
    /// One sentence: where the remaining residual sits and its signature.
    pub summary: String,
    /// Sensor points, excitations and bands whose residual stands out (z > 5), strongest first.
    pub groups: Vec<String>,
    /// Fraction of the remaining χ² that is not rigid-body motion of the sensors.
    pub non_rigid_fraction: f64,
    /// Fraction of the remaining χ² in quadrature with the model FRF.
    pub quadrature_fraction: f64,
    /// Candidates that would have reduced the residual but only with values outside
    /// their plausible range, with the value that failed.
    pub implausible: Vec<String>,
}

/// Held-out (cross-validation) evidence for an effect (docs/physics.md, M1–M8, A2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct HeldOutCheck {
    /// How the values were split into folds (frequency or excitation).
    pub scheme: String,
    /// Number of folds.
    pub folds: usize,
    /// Decrease of the held-out χ² summed over folds (model without − with the effect).
    pub delta_chi2: f64,
    /// Its standard error under the noise model, `√(4 Σ (e − f)²)` over the held-out
    /// residuals without (`e`) and with (`f`) the effect (see `cv`).
    pub standard_error: f64,
    /// Folds in which the held-out χ² decreased.
    pub folds_improved: usize,
    /// Frequency folds: decrease > 2 standard errors and in ≥ 80 % of the folds.
    /// Excitation folds: no held-out excitation worse by > 2 of its standard errors.
    pub passed: bool,
    /// Per fold, the held-out χ² decrease over its own standard error (excitation
    /// folds only; empty for frequency folds).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub fold_z: Vec<f64>,
}

/// Effects that fit about equally well and could not be separated on these data.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct AmbiguousFamily {
    /// The members' ids.
    pub ids: Vec<String>,
    /// ΔBIC of each member relative to the model without it.
    pub delta_bic: Vec<f64>,
    /// Largest canonical correlation between their residual signatures.
    pub canonical_correlation: f64,
    /// The measurement that would separate them.
    pub separating_measurement: String,
}

/// Effects the free parameters absorb completely: they cannot be seen in FRFs alone.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct NotObservable {
    /// Physics-catalogue id.
    pub id: String,
    /// One-line title.
    pub title: String,
    /// Which free parameters absorb it.
    pub reason: String,
    /// What would reveal it.
    pub would_reveal: String,
}

/// Screening statistics of one candidate at one step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ScreenEntry {
    /// Step of the forward selection (1 = the first effect added).
    pub step: usize,
    /// Candidate id.
    pub id: String,
    /// Identifiable rank d_c after projecting out the current model's parameters.
    pub rank: usize,
    /// Number of the candidate's parameters.
    pub n_parameters: usize,
    /// Score statistic S_c and its threshold.
    pub score: f64,
    /// Threshold of the score statistic at this step.
    pub threshold: f64,
    /// χ² decrease of the full refit (when refitted).
    pub refit_delta_chi2: Option<f64>,
    /// ΔBIC of the full refit (when refitted).
    pub refit_delta_bic: Option<f64>,
    /// What the step decided for the candidate, in words.
    pub decision: String,
}

/// A nominal-model parameter as the final fit (with the accepted effects) corrects it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct CorrectedParameter {
    /// Parameter name.
    pub name: String,
    /// Value in the nominal spec.
    pub nominal: f64,
    /// Value after the final fit.
    pub fitted: f64,
    /// Standard error of the fitted value.
    pub standard_error: f64,
    /// (fitted − nominal)/standard error.
    pub z: f64,
    /// |z| > 3.
    pub significant: bool,
}

/// An inertia estimate with standard errors: m, c, moments and CAD products.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct InertiaEstimateReport {
    /// Which fit the estimate comes from (`nominal spec`, `baseline fit …`, …).
    pub label: String,
    /// Mass `m` (kg).
    pub mass_kg: f64,
    /// Centre of mass `c` in the spec's frame (m).
    pub com_m: [f64; 3],
    /// Moments `J_xx, J_yy, J_zz` about the CoM, along the spec's axes (kg m²).
    pub moments_kg_m2: [f64; 3],
    /// Products J_xy, J_xz, J_yz = ∫xy dm, ... (tensor entries are their negatives).
    pub products_kg_m2: [f64; 3],
    /// The tensor about the CoM (off-diagonals = −products).
    pub inertia_cm_kg_m2: [[f64; 3]; 3],
    /// Standard errors in the order m, c_x, c_y, c_z, J_xx, J_yy, J_zz, J_xy, J_xz, J_yz
    /// (0 where a quantity was fixed).
    pub standard_errors: [f64; 10],
}

/// The relative change of one inertia quantity between two fits.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct RelativeChange {
    /// The quantity's name (`mass_kg`, `com_x_m`, …: `InertiaProperties::NAMES`).
    pub quantity: String,
    /// (after − before)/|before| (for CoM: change in m divided by the body size).
    pub relative: f64,
}

/// The model-check report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ModelCheckReport {
    /// Campaign name of the spec.
    pub campaign: String,
    /// One-paragraph human verdict.
    pub verdict: String,
    /// Effects accepted with statistical evidence, in order of acceptance.
    pub accepted: Vec<AcceptedEffect>,
    /// Effects that could not be separated from each other.
    pub ambiguous: Vec<AmbiguousFamily>,
    /// The residual the catalogue does not explain with plausible values, where it sits
    /// (`None` at the noise floor).
    #[serde(default)]
    pub unexplained: Option<Unexplained>,
    /// Effects the free parameters absorb completely.
    pub not_observable: Vec<NotObservable>,
    /// χ²/ν of the nominal spec as given (no parameter fitted).
    pub chi2_nu_nominal: f64,
    /// χ²/ν after the baseline fit of the nominal model's own parameters.
    pub chi2_nu_before: f64,
    /// χ²/ν of the final model (baseline + accepted effects).
    pub chi2_nu_after: f64,
    /// Degrees of freedom ν of `chi2_nu_before` (docs/conventions.md §8, `ν = 2N − p`).
    pub nu_before: f64,
    /// Degrees of freedom ν of `chi2_nu_after`.
    pub nu_after: f64,
    /// Band in which χ²/ν is consistent with noise: the central 99.73 % interval of
    /// F(ν, 2/se²) (χ²_ν/ν when the noise is given, se = 0), se the relative standard
    /// error of the noise variance; the upper end at least 1.05 (`check::noise_band`).
    pub noise_band: [f64; 2],
    /// χ²/ν_after inside the noise band (or below it when no noise was fitted and σ is
    /// the precision floor alone) and no residual cell with z > 5.
    pub noise_floor_reached: bool,
    /// The recording's noise model used for the weights.
    pub noise: RecordingNoise,
    /// Values used (complex FRF values with noise information).
    pub n_values: usize,
    /// The nominal parameters as the final fit corrects them.
    pub corrected_parameters: Vec<CorrectedParameter>,
    /// The nominal spec's inertia, with the standard errors of the baseline fit.
    pub inertia_nominal: InertiaEstimateReport,
    /// Baseline fit (nominal physics, fitted parameters).
    pub inertia_before: InertiaEstimateReport,
    /// Final fit (accepted effects included): the FRF-level inertia estimate.
    pub inertia_after: InertiaEstimateReport,
    /// Relative change of each inertia quantity from the baseline to the final fit.
    pub inertia_change: Vec<RelativeChange>,
    /// Screening statistics of every candidate at every step.
    pub screening: Vec<ScreenEntry>,
    /// Where the residual sits after the baseline fit.
    pub residuals_before: ResidualMap,
    /// Where the residual sits after the final fit.
    pub residuals_after: ResidualMap,
    /// Statistical settings and caveats.
    pub method: Vec<String>,
    /// What the check noticed, typed, one diagnostic per fact. Reports written before
    /// diagnostics were typed hold `warnings` (strings): they read as
    /// [`DiagnosticKind::Text`].
    #[serde(
        default,
        alias = "warnings",
        deserialize_with = "rbprops_core::records::diagnostics_or_texts",
        skip_serializing_if = "Vec::is_empty"
    )]
    pub diagnostics: Vec<Diagnostic>,
}

/// A diagnostic of `model-check`.
pub(crate) fn diagnostic(kind: DiagnosticKind, severity: Severity, message: String) -> Diagnostic {
    Diagnostic::new(
        "model-check",
        kind,
        severity,
        DiagnosticSubject::run(),
        message,
    )
}
