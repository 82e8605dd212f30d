//! The model check: noise floor → baseline fit → localisation → screening (score test)
//! → refit and acceptance (likelihood ratio with Bonferroni, ΔBIC, plausible and
//! significant parameters, distinctness) → forward–backward selection → report.
//! Follows docs/physics.md (M1–M8), with the deviations listed in
//! the report's `method` field.

use crate::candidates::{candidates, Candidate};
use crate::correlation::LineCorrelation;
use crate::error::CheckError;
use crate::lm;
use crate::noise::{self, RecordingNoise};
use crate::params::Baseline;
use crate::predict::Layout;
use crate::report::{diagnostic, ModelCheckReport};
use acceptance::LOEO_MAX_CHI2_NU;
use problem::{Prior, Problem};
use rbprops_core::records::{Diagnostic, DiagnosticKind, Severity};
use rbprops_core::{c64, DataPrecision, FrfSet, Geometry};
use rbprops_sim::effects::mass::SensorMass;
use rbprops_sim::effects::processing::ExponentialWindow;
use rbprops_sim::effects::Effect;
use rbprops_sim::CampaignSpec;
use selection::{Selection, Start, REFIT_ROUND, SCORE_REACH, WALD_DECISIVE};
use verdict::{at_noise_floor, Finish, Finished};

mod acceptance;
mod gauges;
mod holds;
mod items;
mod problem;
mod restart;
mod screening;
mod selection;
mod take_back;
mod verdict;

pub use acceptance::{PRACTICAL_MARGIN, RESOLUTION};
pub use verdict::{noise_band, verdict, MIN_BAND_UPPER};

/// Options of [`check`]. `Default` gives the documented defaults.
#[derive(Debug, Clone)]
pub struct CheckOptions {
    /// Noise model from side information (repeats, coherence); `None`: from the data.
    pub noise: Option<RecordingNoise>,
    /// Each value's variance from the FRF estimator; takes precedence over `noise`.
    pub line_variance: Option<noise::GivenLineVariance>,
    /// The smallest relative change an effect must make to some excitation's FRFs taken
    /// together (its own change: the fit with the effect against the same fit with the
    /// effect at neutral) when the FRF estimator says its force-channel noise makes a
    /// common error of this size on every channel of an excitation (a multiple of it).
    /// Besides [`RESOLUTION`], which applies per FRF whatever is given.
    pub estimator_resolution: Option<f64>,
    /// Family-wise false-positive rate per selection step (Bonferroni over candidates).
    pub alpha: f64,
    /// Safety cap on the number of selection steps (each accepts one effect); the
    /// selection normally ends earlier, when nothing significant is left. Reaching it
    /// is reported in the warnings.
    pub max_effects: usize,
    /// Significant candidates refitted with full NLS per step.
    pub refit_top: usize,
    /// ΔBIC an effect must exceed (and the margin under which rivals are ambiguous).
    pub min_delta_bic: f64,
    /// Largest canonical correlation under which two candidates count as distinct.
    pub max_correlation: f64,
    /// Iteration cap of each Levenberg–Marquardt fit.
    pub max_iterations: usize,
    /// Weighed mass (side information): fixes m, which makes a global gain observable.
    pub weighed_mass_kg: Option<f64>,
    /// Known masses at sensor points (point id, kg): added to the model as a known
    /// correction, so the reported inertia is the body's without the sensors.
    pub sensor_masses_kg: Vec<(String, f64)>,
    /// Restrict screening to these candidate ids (`None`: the whole catalogue).
    pub only: Option<Vec<String>>,
    /// Quantile of χ²_d the Wald statistic of an effect's parameters must exceed.
    pub wald_level: f64,
    /// Require the held-out check (cross-validation, [`crate::cv`]) for acceptance.
    pub cross_validation: bool,
    /// Receives one line per stage (noise, baseline, each selection step): a check
    /// takes seconds to minutes, and a person at a terminal wants to see it move.
    pub progress: Progress,
}

/// A sink for progress lines ([`CheckOptions::progress`]); silent by default.
#[derive(Clone, Default)]
pub struct Progress(Option<std::sync::Arc<dyn Fn(&str) + Send + Sync>>);

impl Progress {
    /// Progress reported through `f` (one line of text per step).
    pub fn new(f: impl Fn(&str) + Send + Sync + 'static) -> Self {
        Progress(Some(std::sync::Arc::new(f)))
    }
    fn say(&self, line: impl FnOnce() -> String) {
        if let Some(f) = &self.0 {
            f(&line());
        }
    }
}

impl std::fmt::Debug for Progress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.0.is_some() {
            "Progress(on)"
        } else {
            "Progress(off)"
        })
    }
}

impl Default for CheckOptions {
    fn default() -> Self {
        CheckOptions {
            noise: None,
            line_variance: None,
            estimator_resolution: None,
            alpha: 0.01,
            max_effects: 10,
            refit_top: 3,
            min_delta_bic: 10.0,
            max_correlation: 0.9,
            max_iterations: 60,
            weighed_mass_kg: None,
            sensor_masses_kg: Vec::new(),
            only: None,
            wald_level: 0.999,
            cross_validation: true,
            progress: Progress::default(),
        }
    }
}

/// Everything a front end needs: the report, the improved spec and the FRFs for plots.
#[derive(Debug)]
pub struct CheckOutcome {
    /// The machine-readable report and its verdict.
    pub report: ModelCheckReport,
    /// The nominal spec with fitted parameters and the accepted effects switched on.
    pub improved_spec: CampaignSpec,
    /// How the recording maps onto the spec (the order of the vectors below).
    pub layout: Layout,
    /// `[exc][ch][line]` in the recording's layout.
    pub measured: Vec<c64>,
    /// The nominal spec's prediction, same layout.
    pub nominal: Vec<c64>,
    /// The baseline (nominal physics, fitted parameters), same layout.
    pub baseline: Vec<c64>,
    /// The improved model (accepted effects on), same layout.
    pub improved: Vec<c64>,
    /// σ per value (0: excluded).
    pub sigma: Vec<f64>,
    /// The final model's parameters, a start for the noise rerun of [`check`].
    prior: Prior,
    /// Noise correlated from line to line, as found in this pass, if any.
    correlation: Option<LineCorrelation>,
}

/// Runs the model check of a recording (`geometry`, `frf`) against a nominal spec.
/// With the noise estimated from the data, the noise is re-estimated from the final
/// model's residual and, if that moves the final χ²/ν out of its noise band, the check
/// is run once more with it (see [`noise::estimate_from_residual`]).
pub fn check(
    spec: &CampaignSpec,
    geometry: &Geometry,
    frf: &FrfSet,
    options: &CheckOptions,
) -> Result<CheckOutcome, CheckError> {
    options.progress.say(|| "estimating the noise floor".into());
    let first = check_with(spec, geometry, frf, options, None, None)?;
    if options.noise.is_some() || options.line_variance.is_some() {
        return Ok(first);
    }
    // Second pass: the noise re-estimated from the residual of the first pass's final
    // model ([`noise::estimate_from_residual`]), which no longer reads the structure the
    // accepted effects explain (a leakage ripple) as noise, nor, with nothing accepted,
    // the curvature the local polynomial cannot follow on data without noise (a
    // recording in single precision is then weighed by its quantisation alone).
    let (nex, nch, nl) = (frf.n_excitations, frf.n_channels, frf.n_lines());
    let mut nf = noise::estimate_from_residual(&first.measured, &first.improved, nex, nch, nl)?;
    // A line correlation found in the data is looked for again in the final residual,
    // with that residual's noise model, which no longer reads the FRF's own curvature as
    // noise (on exact data the data's local residual is that curvature, smooth, and
    // reads as correlated); c from the final model's window when it has one.
    let correlation = first.correlation.as_ref().and_then(|_| {
        let residual: Vec<c64> = first
            .measured
            .iter()
            .zip(&first.improved)
            .map(|(y, m)| y - m)
            .collect();
        correlated_noise(
            &first.improved,
            &residual,
            &nf.model,
            &nf.sigma,
            nex * nch,
            nl,
        )
        .map(|c| c.with_window_decay(window_decay(&first.improved_spec), line_spacing(frf)))
    });
    let inflation = correlation.as_ref().and_then(|c| c.inflation());
    let kappa = inflation.map_or(1.0, |inf| {
        // The level from the median of |r|²/σ² over the values: each residual value is
        // circular normal whatever the correlation between lines (|r|²/σ² exponential,
        // median ln 2), where the local polynomial reads σ² low by L(c), steep in c;
        // the median ignores misfit left at up to half the values. Then κ.
        let level = median_level(&first.measured, &first.improved, &nf.sigma);
        scale_noise(&mut nf.model, &mut nf.sigma, (level * inf.kappa).sqrt());
        inf.kappa
    });
    // The rerun is needed when the final χ²/ν, re-expressed in the re-estimated noise
    // (χ²/ν · ρ), moves by more than the half-width of that noise's band on its side
    // (see `noise_band`): only then can it change the verdict.
    let rho = chi2_ratio(&first, &nf.sigma);
    let [lo, hi] = rbprops_core::stats::chi2_nu_band(
        first.report.nu_after / kappa,
        nf.model.variance_scale_se,
        rbprops_core::stats::BAND_TAIL,
    );
    let note = format!(
        "noise re-estimated from the residual of the final model: its χ² changes by the factor ρ = {rho:.3} (band half-widths −{:.3}/+{:.3})",
        1.0 - lo,
        hi - 1.0
    );
    if rho >= lo && rho <= hi {
        let mut first = first;
        first
            .report
            .method
            .push(format!("{note}: within it, the data-only estimate is kept"));
        if !first.report.noise_floor_reached
            && first.report.chi2_nu_after < first.report.noise_band[0]
        {
            restate_in_residual_noise(&mut first, nf);
        }
        return Ok(first);
    }
    options.progress.say(|| {
        format!("noise re-estimated from the final residual (χ² factor {rho:.3}): rerunning")
    });
    let mut second = check_with(
        spec,
        geometry,
        frf,
        options,
        Some((nf.model, nf.sigma, correlation)),
        Some(&first.prior),
    )?;
    second.report.method.push(format!(
        "{note}: beyond it, so the check was rerun with it (first pass: {})",
        first.report.verdict
    ));
    Ok(second)
}

/// ρ = χ²(σ')/χ²(σ) of the final model's residual of `o` under the noise `sigma2`
/// instead of the σ it was fitted with (values where both are positive).
fn chi2_ratio(o: &CheckOutcome, sigma2: &[f64]) -> f64 {
    chi2_ratio_of(o, &o.improved, sigma2)
}

/// ρ of [`chi2_ratio`] for the residual of the prediction `model`.
fn chi2_ratio_of(o: &CheckOutcome, model: &[c64], sigma2: &[f64]) -> f64 {
    let (mut a, mut b) = (0.0, 0.0);
    for i in 0..o.measured.len() {
        let (s1, s2) = (o.sigma[i], sigma2[i]);
        if s1 > 0.0 && s2 > 0.0 {
            let e = (o.measured[i] - model[i]).norm_sqr();
            a += e / (s2 * s2);
            b += e / (s1 * s1);
        }
    }
    a / b
}

/// A kept first pass whose final χ²/ν fell below its band and is not at the floor (with a
/// precision-only noise below the band already is, see `at_noise_floor`): the data-only noise is too
/// high there (the local quartic also reads the curvature it cannot follow as noise),
/// and the re-estimate from the final residual, which agrees with it within its own
/// band, is the better yardstick (see [`noise::estimate_from_residual`]). The final
/// statistics — χ²/ν of the nominal, baseline and final models, the noise band, the
/// noise model, σ and the floor decision — are restated in it; the selection, which the
/// re-estimate could not change, stays. Below the band is never read as missing physics.
fn restate_in_residual_noise(o: &mut CheckOutcome, nf: noise::NoiseFloor) {
    let sigma: Vec<f64> = nf
        .sigma
        .iter()
        .zip(&o.sigma)
        .map(|(s2, s1)| if *s1 > 0.0 { *s2 } else { 0.0 })
        .collect();
    let (old, old_band) = (o.report.chi2_nu_after, o.report.noise_band);
    let ratios = [&o.improved, &o.baseline, &o.nominal].map(|m| chi2_ratio_of(o, m, &sigma));
    let r = &mut o.report;
    r.chi2_nu_after *= ratios[0];
    r.chi2_nu_before *= ratios[1];
    r.chi2_nu_nominal *= ratios[2];
    let kappa = o
        .correlation
        .as_ref()
        .and_then(|c| c.inflation())
        .map_or(1.0, |i| i.kappa);
    r.noise_band = noise_band(r.nu_after / kappa, nf.model.variance_scale_se);
    r.noise_floor_reached = at_noise_floor(
        r.chi2_nu_after,
        r.noise_band,
        &nf.model,
        &r.residuals_after.flagged,
    );
    r.noise = nf.model;
    r.method.push(format!(
        "the final χ²/ν {old:.3} was below its band [{:.3}, {:.3}] in the data-only noise: the final statistics are stated in the noise re-estimated from the final residual (χ²/ν {:.3}, band [{:.3}, {:.3}])",
        old_band[0], old_band[1], r.chi2_nu_after, r.noise_band[0], r.noise_band[1]
    ));
    r.verdict = verdict(r);
    o.sigma = sigma;
}

/// The methods text of the report that does not depend on the data, stated with the
/// options and thresholds this run used.
fn method_text(options: &CheckOptions) -> Vec<String> {
    let noise = if let Some(lv) = &options.line_variance {
        format!("each value's σ² given by the FRF estimator ({}), with its window's line-to-line correlation known", lv.source)
    } else if options.noise.is_some() {
        "per-channel σ² = a²|H|² + b², given (side information: repeats or coherence)".to_string()
    } else {
        format!(
            "per-channel σ² = a²|H|² + b², from a {} (data only), re-estimated from the final model's residual (the check is rerun with it if that moves χ²/ν out of the noise band)",
            noise::local_fit_text()
        )
    };
    let held_out = if options.cross_validation {
        format!(
            "held-out χ² ({} interleaved frequency-block folds, one-step refit without each fold) lower by > {} SE and in ≥ {:.0} % of folds, with ≥ 3 excitations and the candidate's fit at χ²/ν < {LOEO_MAX_CHI2_NU} no held-out excitation (leave one out) worse by > 2 SE, ",
            crate::cv::FOLDS,
            crate::cv::MIN_SE,
            100.0 * crate::cv::MIN_FRACTION
        )
    } else {
        "no held-out check (cross-validation switched off), ".to_string()
    };
    let mass = match options.weighed_mass_kg {
        Some(m) => format!("; the mass fixed at the weighed {m} kg"),
        None => String::new(),
    };
    vec![
        format!("noise: {noise}; |H| at least half its local median over 11 lines (no runaway weight at a zero of the FRF); the 0 Hz line left out; lines independent, unless the noise is found correlated from line to line (then weighed as below)"),
        format!("baseline: Levenberg–Marquardt (at most {} iterations) on inertia (pseudo-inertia Cholesky, always physical), per-set-up axis stiffness scales, damping of the spec's model{mass}", options.max_iterations),
        format!("screening: score test on the candidate Jacobian with the current model's Jacobian projected out; threshold χ²_{{d,1−α/N}} with α = {}{}", options.alpha, match &options.only {
            Some(only) => format!("; candidates restricted to {}", only.join(", ")),
            None => String::new(),
        }),
        format!(
            "acceptance (of the significant candidates, the {} strongest, those within half the best gain and the most parsimonious refitted, {REFIT_ROUND} at a time, strongest first, while one left could still win: {SCORE_REACH} times its score, twice that for a profile, less its BIC charge, within the ΔBIC margin of the best refit that passed; at most {} steps): likelihood ratio > χ²_{{d,1−α/N}} (Bonferroni), ΔBIC > {}, Wald χ² > χ²_{{d,{}}}, parameters not pinned at a bound, {held_out}distinct from rivals (canonical correlation ≤ {} or ΔBIC margin > {}), and practically significant: its fitted change to the FRFs at least {PRACTICAL_MARGIN} times the precision floor (RMS over the values) and at least {RESOLUTION:.0e} of some FRF (relative RMS: what a calibration resolves); backward elimination after each acceptance and a final re-test of each effect given the others (an effect whose Wald statistic is {WALD_DECISIVE} times what its removal must cost, with plausible values, is kept without the refit)",
            options.refit_top,
            options.max_effects,
            options.min_delta_bic,
            options.wald_level,
            options.max_correlation,
            options.min_delta_bic
        ),
        "not implemented: bootstrap calibration of the screening threshold".to_string(),
    ]
}

/// Stage 0's weights of the residual: the noise model, σ per value (0: left out), σ of
/// the precision floor alone (the yardstick of practical significance) and the values
/// used.
struct Weights {
    noise_model: RecordingNoise,
    sigma: Vec<f64>,
    sigma_precision: Vec<f64>,
    used: Vec<usize>,
    correlation: Option<LineCorrelation>,
    /// How the line correlation is weighed (found in the data, or the estimator's window).
    inflation: Option<crate::correlation::Inflation>,
}

/// The noise model and each value's σ (Stage 0), from the first source there is: the
/// second pass's `noise_override`, the estimator's given line variances, a given noise
/// model, or the recording itself; with the line correlation the second pass takes
/// from the first (`Some(None)`: known, not to be detected), `None` when it is to be
/// detected.
#[allow(clippy::type_complexity)]
fn noise_and_sigma(
    frf: &FrfSet,
    options: &CheckOptions,
    noise_override: Option<(RecordingNoise, Vec<f64>, Option<LineCorrelation>)>,
    given_lines: Option<&noise::GivenLineVariance>,
) -> Result<(RecordingNoise, Vec<f64>, Option<Option<LineCorrelation>>), CheckError> {
    let (nex, nch, nl) = (frf.n_excitations, frf.n_channels, frf.n_lines());
    let y = &frf.values;
    let mut rerun_correlation = None;
    let (noise_model, sigma) = match (noise_override, &options.noise) {
        (Some((model, sigma, correlation)), _) => {
            rerun_correlation = Some(correlation);
            (model, sigma)
        }
        (None, _) if given_lines.is_some() => {
            let lv = given_lines.unwrap();
            if lv.sigma2.len() != y.len() {
                return Err(CheckError::Noise(format!(
                    "given line variances: {} values, the recording {}",
                    lv.sigma2.len(),
                    y.len()
                )));
            }
            let mut m = lv.summary(y, nch, nl);
            m.precision = DataPrecision::detect(y);
            // The window's correlation is known: no detection, its inflation below.
            rerun_correlation = Some(None);
            let s = lv
                .sigma2
                .iter()
                .zip(y)
                .map(|(&s2, v)| match s2 > 0.0 {
                    true => (s2 + noise::precision_variance(&m.precision, *v, v.norm())).sqrt(),
                    false => 0.0,
                })
                .collect();
            (m, s)
        }
        (None, Some(m)) => {
            if m.relative.len() != nch || m.floor.len() != nch {
                return Err(CheckError::Noise(format!(
                    "given noise model has {} / {} channel entries, the recording {nch}",
                    m.relative.len(),
                    m.floor.len()
                )));
            }
            let mut m = m.clone();
            m.precision = DataPrecision::detect(y);
            let s = noise::sigma_of(&m, y, y, nex, nch, nl);
            (m, s)
        }
        (None, None) => {
            let nf = noise::estimate(y, nex, nch, nl)?;
            (nf.model, nf.sigma)
        }
    };
    Ok((noise_model, sigma, rerun_correlation))
}

/// Leaves the 0 Hz line out (σ = 0) and returns how many values that removed. An
/// AC-coupled channel reads 0 there whatever its time constant and a DC-coupled one its
/// static value, so a high-pass candidate's model jumps at 1/τ = 0 on that line (no
/// derivative, no path for the fit) while the line next to it carries the same static
/// information.
fn leave_out_dc(frf: &FrfSet, sigma: &mut [f64]) -> usize {
    let (nex, nch, nl) = (frf.n_excitations, frf.n_channels, frf.n_lines());
    let dc: Vec<usize> = (0..nl).filter(|&l| frf.frequency_hz[l] == 0.0).collect();
    let mut n_dc = 0;
    for &l in &dc {
        for fi in 0..nex * nch {
            if sigma[fi * nl + l] > 0.0 {
                sigma[fi * nl + l] = 0.0;
                n_dc += 1;
            }
        }
    }
    n_dc
}

/// Stage 0: the noise floor (given, overridden by the second pass, or estimated from
/// the data), with the precision floor of the data's storage format; the 0 Hz line and
/// values without noise information are left out.
fn weights(
    spec: &CampaignSpec,
    frf: &FrfSet,
    options: &CheckOptions,
    noise_override: Option<(RecordingNoise, Vec<f64>, Option<LineCorrelation>)>,
    method: &mut Vec<String>,
    warnings: &mut Vec<Diagnostic>,
) -> Result<Weights, CheckError> {
    let (nex, nch, nl) = (frf.n_excitations, frf.n_channels, frf.n_lines());
    let y = &frf.values;
    // Stage 0: noise floor, with the precision floor of the data's storage format.
    let given_lines = options
        .line_variance
        .as_ref()
        .filter(|_| noise_override.is_none());
    let source = (
        noise_override.is_some(),
        options.noise.is_some() || given_lines.is_some(),
    );
    let (noise_model, sigma, rerun_correlation) =
        noise_and_sigma(frf, options, noise_override, given_lines)?;
    method.push(format!(
        "precision floor: values stored in {} (detected from the values), each σ² includes its quantisation variance (step²/12 per part) and the computation floor of double precision ({:.0e}·|H|)²; an exact recording (no fitted noise) whose χ²/ν is below the band is within that floor, and counts as at the floor",
        noise_model.precision.describe(),
        noise::COMPUTATION_FLOOR
    ));
    // The yardstick of practical significance: σ with no noise but the precision floor.
    let sigma_precision = noise::precision_sigma(&noise_model.precision, y, y, nl);
    let mut sigma = sigma;
    let n_dc = leave_out_dc(frf, &mut sigma);
    if n_dc > 0 {
        warnings.push(diagnostic(DiagnosticKind::NoNoiseInformation, Severity::Note, format!(
            "the 0 Hz line is left out ({n_dc} values): a high-pass (AC coupling) makes it 0 whatever its time constant, so it cannot be fitted continuously; the next line carries the same static information"
        )));
    }
    let mut noise_model = noise_model;
    // The second pass takes the correlation the first found in its residual.
    let found = match rerun_correlation {
        Some(c) => c,
        None => correlated_noise(y, y, &noise_model, &sigma, nex * nch, nl)
            .map(|c| c.with_window_decay(window_decay(spec), line_spacing(frf))),
    };
    let inflation = match given_lines {
        Some(lv) => lv.window_time_constant_s.map(|tau| {
            crate::correlation::Inflation::exponential(
                std::f64::consts::PI * tau * line_spacing(frf),
            )
        }),
        None => found.as_ref().and_then(|d| d.inflation()),
    };
    if let Some(d) = &found {
        let w = d.describe(line_spacing(frf));
        // Said at once: without a calibrated weighting the selection can run long.
        options.progress.say(|| format!("warning: {w}"));
        // Handled when the window is declared (in the model or the line variances: its τ
        // weighs the lines): a note. Undeclared, an exponential window's correlation
        // that fits is a window nobody declared (the message states its τ), and one that
        // does not fit leaves the check uncalibrated: warnings.
        let declared = d.known_c.is_some()
            || given_lines.is_some_and(|lv| lv.window_time_constant_s.is_some());
        let (kind, severity) = match (declared, d.inflation().is_some()) {
            (true, _) => (DiagnosticKind::CorrelatedNoise, Severity::Note),
            (false, true) => (DiagnosticKind::UndeclaredWindow, Severity::Warning),
            (false, false) => (DiagnosticKind::CorrelatedNoise, Severity::Warning),
        };
        warnings.push(diagnostic(kind, severity, w));
    }
    if let Some(inf) = &inflation {
        // From the data σ² is read low by L and smooth signatures vary κ times more; a
        // given σ is right per line; the second pass's is already scaled.
        let (factor, how) = match source {
            (true, _) => (
                1.0,
                format!(
                    "σ from the first pass's residual, its level the median of |r|²/σ² over ln 2 (circular normal values whatever the correlation), times √κ = {:.3}",
                    inf.kappa.sqrt()
                ),
            ),
            (false, true) => (
                inf.kappa.sqrt(),
                format!("the given σ times √κ = {:.3}", inf.kappa.sqrt()),
            ),
            (false, false) => {
                let f = (inf.kappa / inf.level).sqrt();
                (f, format!("the data-only σ times √(κ/L) = {f:.3}"))
            }
        };
        scale_noise(&mut noise_model, &mut sigma, factor);
        method.push(format!(
            "noise correlated from line to line as by an exponential window (c = {:.3}, κ = {:.3}, L = {:.3}): {how}; χ²/ν stated per line (×κ) with a band of ν/κ lines",
            inf.c, inf.kappa, inf.level
        ));
    }
    let used: Vec<usize> = (0..y.len()).filter(|&i| sigma[i] > 0.0).collect();
    let n_excluded = y.len() - used.len() - n_dc;
    if n_excluded > 0 {
        warnings.push(diagnostic(DiagnosticKind::NoNoiseInformation, Severity::Note, format!("{n_excluded} values carry no noise information (σ = 0, e.g. accelerance at 0 Hz) and are left out")));
    }
    Ok(Weights {
        noise_model,
        sigma,
        sigma_precision,
        used,
        correlation: found,
        inflation,
    })
}

/// Noise correlated from line to line ([`crate::correlation`]) in `series` (the
/// recording, or a model's residual; `y` the magnitudes the noise model refers to),
/// tested where the fitted noise (a, b) is most of σ² on most values: an exact or
/// quantised recording's local-polynomial residual is the FRF's own curvature and
/// rounding.
fn correlated_noise(
    y: &[c64],
    series: &[c64],
    noise: &RecordingNoise,
    sigma: &[f64],
    n_frf: usize,
    nl: usize,
) -> Option<crate::correlation::LineCorrelation> {
    let n_ch = noise.relative.len();
    let (mut fitted, mut total) = (0usize, 0usize);
    for (i, s) in sigma.iter().enumerate() {
        if *s > 0.0 {
            total += 1;
            let nm = noise.channel((i / nl) % n_ch);
            fitted += usize::from(nm.variance(y[i]) >= 0.5 * s * s);
        }
    }
    if 2 * fitted <= total {
        return None;
    }
    crate::correlation::detect(series, sigma, n_frf, nl).filter(|d| d.detected())
}

/// The decay rate of the exponential window in `spec`'s effects (nominal, or accepted
/// by a check), if any: its `decay_per_s`, or 1/`time_constant_s`.
fn window_decay(spec: &CampaignSpec) -> Option<f64> {
    let e = spec
        .effects
        .iter()
        .find(|e| e.id == ExponentialWindow::ID)?;
    let number = |k: &str| {
        e.parameters
            .get(k)
            .and_then(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)))
    };
    number("decay_per_s").or_else(|| number("time_constant_s").map(|t| 1.0 / t))
}

/// The median over the values with σ > 0 of |y − m|²/σ², over ln 2: the residual's
/// variance in units of σ² when it is circular normal (|r|²/σ² then exponential).
fn median_level(y: &[c64], m: &[c64], sigma: &[f64]) -> f64 {
    let mut v: Vec<f64> = (0..y.len())
        .filter(|&i| sigma[i] > 0.0)
        .map(|i| (y[i] - m[i]).norm_sqr() / (sigma[i] * sigma[i]))
        .collect();
    if v.is_empty() {
        return 1.0;
    }
    let k = v.len() / 2;
    let (_, med, _) = v.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
    *med / std::f64::consts::LN_2
}

/// Scales a noise model and its σ per value by `factor`.
fn scale_noise(model: &mut RecordingNoise, sigma: &mut [f64], factor: f64) {
    for v in model.relative.iter_mut().chain(model.floor.iter_mut()) {
        *v *= factor;
    }
    for s in sigma.iter_mut() {
        *s *= factor;
    }
}

/// The median spacing of the recording's lines (Hz).
fn line_spacing(frf: &FrfSet) -> f64 {
    let mut d: Vec<f64> = frf.frequency_hz.windows(2).map(|w| w[1] - w[0]).collect();
    d.sort_by(|a, b| a.total_cmp(b));
    d.get(d.len() / 2).copied().unwrap_or(0.0)
}

/// The spec's own effects and, as side information, the known sensor masses (a fixed
/// effect), in the model of every fit.
fn fixed_effects(
    spec: &CampaignSpec,
    layout: &Layout,
    options: &CheckOptions,
) -> Result<Vec<Box<dyn Effect>>, CheckError> {
    // Side information: known sensor masses become a fixed effect.
    let mut fixed_effects: Vec<Box<dyn Effect>> = spec
        .effects
        .iter()
        .map(|e| rbprops_sim::effects::parse_effect_in(e, spec).map_err(CheckError::Model))
        .collect::<Result<_, _>>()?;
    if !options.sensor_masses_kg.is_empty() {
        fixed_effects.push(Box::new(known_sensor_masses(options, layout)?));
    }
    Ok(fixed_effects)
}

/// One pass of the check; `noise` overrides `options.noise` with a noise model and its
/// σ per value, and `prior` is the first pass's final model (the second pass of
/// [`check`]): the effects it accepted are refitted from it, whatever their screening.
fn check_with(
    spec: &CampaignSpec,
    geometry: &Geometry,
    frf: &FrfSet,
    options: &CheckOptions,
    noise_override: Option<(RecordingNoise, Vec<f64>, Option<LineCorrelation>)>,
    prior: Option<&Prior>,
) -> Result<CheckOutcome, CheckError> {
    frf.validate()
        .map_err(|e| CheckError::Data(e.to_string()))?;
    let layout = Layout::new(spec, geometry, frf)?;
    let (nex, nch, nl) = (frf.n_excitations, frf.n_channels, frf.n_lines());
    let y = &frf.values;
    let mut warnings = Vec::new();
    let mut method = method_text(options);
    let Weights {
        noise_model,
        sigma,
        sigma_precision,
        used,
        correlation,
        inflation,
    } = weights(
        spec,
        frf,
        options,
        noise_override,
        &mut method,
        &mut warnings,
    )?;
    let floor = take_back::FloorYardstick {
        kappa: inflation.as_ref().map_or(1.0, |i| i.kappa),
        variance_se: noise_model.variance_scale_se,
    };
    let fixed_effects = fixed_effects(spec, &layout, options)?;
    let cands = screened_candidates(spec, &layout, options, &mut method, &mut warnings);
    let p = Problem {
        baseline: Baseline::new(spec),
        layout: &layout,
        y,
        sigma: &sigma,
        weight: used
            .iter()
            .map(|&i| std::f64::consts::SQRT_2 / sigma[i])
            .collect(),
        used,
        fixed_effects,
        cands,
        fixed_mass: options.weighed_mass_kg,
    };
    let n_real = p.n_real();
    let theta_nom = p.baseline.initial();
    // χ² of the nominal spec as given.
    let r_nom = p.residual(&theta_nom, &[])?;
    let chi2_nominal = lm::chi2(&r_nom);
    let nominal_pred = p.model(&theta_nom, &[])?;
    options.progress.say(|| {
        format!(
            "{} candidates; χ²/ν of the nominal model {:.3}; fitting its parameters",
            p.n_first_instances(),
            chi2_nominal / n_real
        )
    });
    let base = baseline_fit(&p, &theta_nom, options, &mut warnings)?;
    let free_base = p.n_base() - usize::from(options.weighed_mass_kg.is_some());
    let theta_base = base.theta.clone();
    // Stages 3–4: forward selection with backward checks.
    let mut sel = Selection::new(
        &p,
        options,
        Start {
            prior,
            theta_nom: &theta_nom,
            theta_base: &theta_base,
            sigma_precision: &sigma_precision,
        },
        base.clone(),
        (nex, nch, nl),
        free_base,
    );
    run_selection(&mut sel, options.max_effects, floor)?;
    warnings.append(&mut sel.findings.warnings);
    let fin = Finish {
        spec,
        options,
        p: &p,
        noise_model,
        base,
        theta_nom: &theta_nom,
        chi2_nominal,
        free_base,
        inflation,
    };
    let Finished {
        report,
        improved_spec,
        prior,
        final_pred,
        base_pred,
    } = fin.report(sel, warnings, method)?;
    Ok(CheckOutcome {
        prior,
        report,
        improved_spec,
        measured: y.clone(),
        nominal: nominal_pred,
        baseline: base_pred,
        improved: final_pred,
        sigma,
        layout,
        correlation,
    })
}

/// Largest factor by which the baseline fit may move the mass from the nominal's and
/// still be a correction of it. A tester's nominal mass (a CAD model, a scale) is never
/// off by half; a baseline that moves it further is standing in for physics the nominal
/// lacks: on cords written as vertical axial springs (three directions free in the
/// nominal) the fit drove the mass to 667–883 kg to flatten the pendulum resonances it
/// cannot represent, and there the cords' static balance, hence the gravity effect,
/// could not even be evaluated (docs/physics.md, M3).
const BASELINE_MASS_FACTOR: f64 = 2.0;

/// Stage 1: the baseline fit (the nominal physics, its parameters free), started from
/// the nominal with the weighed mass if given; one that does not converge is a warning.
/// One that moves the mass beyond [`BASELINE_MASS_FACTOR`] is set aside (a warning):
/// the selection starts from the nominal parameters, which every refit frees again.
fn baseline_fit(
    p: &Problem,
    theta_nom: &[f64],
    options: &CheckOptions,
    warnings: &mut Vec<Diagnostic>,
) -> Result<lm::Fit, CheckError> {
    let mut theta0 = theta_nom.to_vec();
    if let Some(m) = options.weighed_mass_kg {
        theta0[0] = m.ln();
    }
    let base = p.fit("baseline", &theta0, &[], options.max_iterations)?;
    let mass_ratio = (base.theta[0] - theta0[0]).exp();
    if options.weighed_mass_kg.is_none()
        && !(1.0 / BASELINE_MASS_FACTOR..=BASELINE_MASS_FACTOR).contains(&mass_ratio)
    {
        warnings.push(diagnostic(
            DiagnosticKind::CheckProcedure,
            Severity::Warning,
            format!(
                "the baseline fit moved the mass by a factor {mass_ratio:.3} (to {:.4} kg): the nominal physics cannot represent these data and the inertia stood in for what is missing, so the selection starts from the nominal parameters",
                base.theta[0].exp()
            ),
        ));
        return p.fit("baseline", &theta0, &[], 0);
    }
    if !base.converged {
        warnings.push(diagnostic(
            DiagnosticKind::CheckRefitFailed,
            Severity::Warning,
            format!(
                "baseline fit stopped after {} iterations without converging",
                base.iterations
            ),
        ));
    }
    Ok(base)
}

/// The candidates this check screens: the catalogue's and the local forms, less those
/// `options` leave out (`only`; the sensor mass when the masses are given); the notes on
/// effects not screened go to `method`, the spec's blind spots and doubts to `warnings`.
fn screened_candidates(
    spec: &CampaignSpec,
    layout: &Layout,
    options: &CheckOptions,
    method: &mut Vec<String>,
    warnings: &mut Vec<Diagnostic>,
) -> Vec<Candidate> {
    warnings.extend(
        crate::candidates::free_direction_note(spec, &layout.spec_geometry)
            .map(|t| diagnostic(DiagnosticKind::CheckBlindSpot, Severity::Note, t)),
    );
    let (mut cands, notes) = candidates(spec, &layout.spec_geometry);
    method.extend(notes);
    warnings.extend(
        crate::candidates::vertical_axis_doubt(spec)
            .map(|t| diagnostic(DiagnosticKind::CheckProcedure, Severity::Warning, t)),
    );
    if let Some(only) = &options.only {
        // A further instance goes with its first (`elastic_mode` keeps `elastic_mode_2`).
        cands.retain(|c| {
            only.contains(&c.id) || (c.follows.is_some() && only.iter().any(|o| o == c.effect.id()))
        });
    }
    if !options.sensor_masses_kg.is_empty() {
        cands.retain(|c| c.id != SensorMass::ID);
    }
    cands
}

/// Stages 3–4: forward steps until nothing more is accepted, then the final re-test of
/// every accepted effect given the others; when it drops one, the forward selection
/// resumes from the smaller model (a dropped effect is not screened again, so this
/// ends). Steps are counted over both, under `max_effects`.
///
/// The selection ends when nothing significant is left or nothing passes the acceptance
/// tests (with the residual at the noise floor no candidate is significant);
/// `max_effects` is only a safety cap, and hitting it is reported.
fn run_selection(
    sel: &mut Selection,
    max_effects: usize,
    floor: take_back::FloorYardstick,
) -> Result<(), CheckError> {
    holds::with_hold_timing(sel, floor, |sel| {
        let step = forward(sel, max_effects, 0, true)?;
        // Later stages number their steps after the take-back's, so that each step's
        // screening entries stay apart in the report.
        let step = take_back::take_back(sel, step, floor, |branch, from, steps| {
            forward(branch, steps.min(max_effects), from, false)
        })?;
        restart::fresh_start(sel, step, floor, |sel, from, steps| {
            forward(sel, steps.min(max_effects), from, false)
        })
    })
}

/// The forward steps after step `from`, at most `max_steps` of them (hitting the cap is
/// a warning when `warn_at_cap`); the last step's number.
fn forward(
    sel: &mut Selection,
    max_steps: usize,
    from: usize,
    warn_at_cap: bool,
) -> Result<usize, CheckError> {
    let max_effects = max_steps;
    let mut capped = max_steps > 0;
    let mut step = from;
    while step < from + max_steps {
        step += 1;
        if !sel.step(step)? && !sel.final_retest(step)? && !sel.hold_at_end(step) {
            capped = false;
            break;
        }
    }
    if capped && !warn_at_cap {
        sel.final_retest(step)?;
    } else if capped {
        sel.final_retest(step)?;
        sel.findings.warnings.push(diagnostic(DiagnosticKind::CheckProcedure, Severity::Warning, format!(
            "the selection stopped at its cap of {max_effects} effects (max_effects) while candidates were still accepted: raise it to see whether more is missing"
        )));
    }
    Ok(step)
}

/// The sensor masses the user gave (`CheckOptions::sensor_masses_kg`) as the catalogue's
/// sensor-mass effect, a known correction of the model: an unknown point is an error.
fn known_sensor_masses(
    options: &CheckOptions,
    layout: &Layout,
) -> Result<rbprops_sim::effects::mass::SensorMass, CheckError> {
    let pids = point_ids(&layout.spec_geometry);
    let mut masses_kg = std::collections::BTreeMap::new();
    for (pid, m) in &options.sensor_masses_kg {
        if !pids.contains(pid) {
            return Err(CheckError::Mismatch(format!(
                "sensor mass given for unknown point '{pid}' (points: {})",
                pids.join(", ")
            )));
        }
        masses_kg.insert(pid.clone(), *m);
    }
    Ok(rbprops_sim::effects::mass::SensorMass {
        mass_kg: None,
        masses_kg,
    })
}

/// The sensor points' ids, in the order their first channel appears.
fn point_ids(g: &Geometry) -> Vec<String> {
    let mut ids: Vec<String> = Vec::new();
    for c in &g.channels {
        if !ids.contains(&c.point) {
            ids.push(c.point.clone());
        }
    }
    ids
}

fn effect_spec(
    e: &dyn Effect,
    spec: &CampaignSpec,
) -> Result<rbprops_sim::spec::EffectSpec, CheckError> {
    crate::candidates::catalogue_entry(e, spec).map_err(CheckError::Model)
}

#[cfg(test)]
mod tests {
    use super::{at_noise_floor, method_text, CheckOptions, RecordingNoise};

    /// The floor rule shared by the report and the restatement in the residual's noise:
    /// below the band counts only for a precision-only noise, never past its top or with a
    /// flagged cell.
    #[test]
    fn the_floor_rule_reads_below_the_band_only_for_precision_alone() {
        let fitted = RecordingNoise::given(vec![0.01; 3], vec![0.0; 3]);
        let exact = RecordingNoise::given(vec![0.0; 3], vec![0.0; 3]);
        let band = [0.97, 1.05];
        assert!(at_noise_floor(1.0, band, &fitted, &[]));
        assert!(!at_noise_floor(0.96, band, &fitted, &[]));
        assert!(at_noise_floor(0.96, band, &exact, &[]));
        assert!(!at_noise_floor(1.06, band, &exact, &[]));
        assert!(!at_noise_floor(
            1.0,
            band,
            &fitted,
            &["force1/1x/2–4 Hz (z 6.1)".into()]
        ));
    }

    /// The method text states the thresholds of the run, not the defaults.
    #[test]
    fn method_text_follows_the_options() {
        let joined = |o: &CheckOptions| method_text(o).join("\n");
        let default = joined(&CheckOptions::default());
        assert!(default.contains("α = 0.01"), "{default}");
        assert!(default.contains("ΔBIC > 10,"), "{default}");
        assert!(default.contains("10 interleaved frequency-block folds"));
        assert!(default.contains("local quartic over 11 lines, 0.15-quantile fit"));
        let o = CheckOptions {
            alpha: 0.05,
            min_delta_bic: 6.0,
            cross_validation: false,
            weighed_mass_kg: Some(12.5),
            only: Some(vec!["channel_gain".into()]),
            ..CheckOptions::default()
        };
        let text = joined(&o);
        assert!(text.contains("α = 0.05"), "{text}");
        assert!(text.contains("ΔBIC > 6,") && text.contains("ΔBIC margin > 6)"));
        assert!(text.contains("no held-out check") && !text.contains("folds"));
        assert!(text.contains("weighed 12.5 kg"));
        assert!(text.contains("restricted to channel_gain"));
    }
}
