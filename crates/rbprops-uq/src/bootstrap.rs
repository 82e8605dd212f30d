//! The bootstrap driver: replicates in parallel, statistics, and their transfer into the
//! [`InertiaEstimate`] records.

use crate::error::UqError;
use crate::model::{Draws, FittedModel, LineVariance};
use crate::reidentify::{full_refit, refine_group, MatchTolerances, Reidentify, ReplicateModes};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use rbprops_core::noise::NoiseModel;
use rbprops_core::records::{Diagnostic, DiagnosticKind, DiagnosticSubject, Severity};
use rbprops_core::records::{
    EstimateMethod, InertiaEstimate, ModalFitRecord, SelectionRecord, UncertaintyMethod,
};
use rbprops_core::{c64, FrfSet, FrfSource, Geometry, InertiaProperties};
use rbprops_inertia::{solve, Estimator, SolveOptions, SolveOutput};
use rbprops_modal::PoleMode;

/// Number of properties: the ten-vector of [`InertiaProperties`] (m, c, moments and
/// products of inertia about the CoM, geometry frame; docs/conventions.md §3).
pub const N_PROPS: usize = InertiaProperties::LEN;

/// Names of the properties in [`N_PROPS`] order.
pub const PROPERTY_NAMES: [&str; N_PROPS] = InertiaProperties::SYMBOLS;

/// Options of [`bootstrap`].
#[derive(Debug, Clone, PartialEq)]
pub struct BootstrapOptions {
    /// Number of replicates B (default 100).
    pub replicates: usize,
    /// Replicate b draws its noise from a ChaCha8 stream seeded by `(seed, b)`.
    pub seed: u64,
    /// Default [`Reidentify::Refine`].
    pub reidentify: Reidentify,
    /// Whether the modal fit carried residual terms (the modal-fit default, true).
    pub residual_terms: bool,
    /// Poles per excitation or per set-up; `None` (default) infers it from the record.
    pub pole_mode: Option<PoleMode>,
    /// How a replicate's modes are matched to the measured ones (frequency, MAC).
    pub tolerances: MatchTolerances,
    /// Warn when more than this fraction of the replicates fail (default 0.05).
    pub failure_warning_fraction: f64,
    /// Draw and refit the replicates on every q-th line of the fit's band (default true;
    /// `rbprops_uq::decimation`, docs/results.md): the same spread at a q-th of the cost.
    /// Only with [`Reidentify::Refine`] (a full refit takes every line).
    pub decimate: bool,
    /// The line weighting the modal fit used (`modal-fit --weight variance|coherence`,
    /// recorded in its processing topic), which the model's residues and every
    /// replicate's refit take too: the bootstrap then spreads the estimator that made
    /// the record. `None`: the default relative weights.
    pub fit_weighting: Option<std::sync::Arc<rbprops_modal::CoherenceWeighting>>,
    /// Where the model's grids and each replicate's draws go when they are larger than
    /// it holds (issue 41's memory bound); `None` (default): held in memory.
    pub scratch: Option<crate::Scratch>,
}

impl Default for BootstrapOptions {
    fn default() -> Self {
        Self {
            replicates: 100,
            seed: 0,
            reidentify: Reidentify::Refine,
            residual_terms: true,
            pole_mode: None,
            tolerances: MatchTolerances::default(),
            failure_warning_fraction: 0.05,
            decimate: true,
            fit_weighting: None,
            scratch: None,
        }
    }
}

/// Bootstrap distribution of one estimate (one modal estimator on one set-up).
#[derive(Debug, Clone, PartialEq)]
pub struct BootstrapEstimate {
    /// The estimator.
    pub method: EstimateMethod,
    /// Suspension set-up.
    pub setup: String,
    /// The estimate from the measured data.
    pub estimate: [f64; N_PROPS],
    /// Standard error: the sample standard deviation of the replicates.
    pub std: [f64; N_PROPS],
    /// Replicate mean minus the estimate (the bootstrap's bias estimate).
    pub bias: [f64; N_PROPS],
    /// Percentile 95 % interval `[q2.5, q97.5]` of the replicates.
    pub percentile_95: [[f64; 2]; N_PROPS],
    /// The successful replicates' property vectors, in replicate order.
    pub samples: Vec<[f64; N_PROPS]>,
    /// Number of replicates whose estimate failed.
    pub failed: usize,
    /// Distinct failure reasons (at most five).
    pub failure_reasons: Vec<String>,
}

impl BootstrapEstimate {
    /// The std-based 95 % interval `estimate ± 1.96 std`.
    pub fn normal_95(&self) -> [[f64; 2]; N_PROPS] {
        std::array::from_fn(|k| {
            let h = rbprops_inertia::Z95 * self.std[k];
            [self.estimate[k] - h, self.estimate[k] + h]
        })
    }
}

/// The noise model of one excitation (per channel, geometry order).
#[derive(Debug, Clone, PartialEq)]
pub struct ExcitationNoise {
    /// Excitation id.
    pub excitation: String,
    /// Noise model `σ² = a²|H|² + b²` per channel (docs/conventions.md §8).
    pub channels: Vec<NoiseModel>,
}

/// Everything [`bootstrap`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct BootstrapOutput {
    /// One distribution per estimator and set-up.
    pub estimates: Vec<BootstrapEstimate>,
    /// The noise model of every excitation, estimated from the fit residuals.
    pub noise: Vec<ExcitationNoise>,
    /// Replicates drawn.
    pub replicates: usize,
    /// The pole mode used (given or inferred).
    pub pole_mode: PoleMode,
    /// What the bootstrap noticed, typed (stage `rb-solve`).
    pub diagnostics: Vec<Diagnostic>,
    /// Lines of the fit's band per line the replicates were drawn and refitted on (the
    /// largest over the excitations; 1: every line).
    pub decimation: usize,
    /// What the replicates' noise was drawn from, for the estimates' method text.
    pub noise_source: String,
}

/// The property vector of an estimate ([`InertiaProperties::to_vector`]).
pub fn estimate_vector(e: &InertiaEstimate) -> [f64; N_PROPS] {
    InertiaProperties::of_estimate(e).to_vector()
}

struct Target {
    method: EstimateMethod,
    setup: String,
    modes_used: Vec<usize>,
    estimate: [f64; N_PROPS],
}

/// Seed of replicate `b`: the run's seed, the replicate index and a tag.
fn replicate_rng(seed: u64, b: usize) -> ChaCha8Rng {
    let mut s = [0u8; 32];
    s[..8].copy_from_slice(&seed.to_le_bytes());
    s[8..16].copy_from_slice(&(b as u64).to_le_bytes());
    s[16..28].copy_from_slice(b"rbprops-uq:b");
    ChaCha8Rng::from_seed(s)
}

/// Parametric FRF-level bootstrap of the modal estimates (Bretl–Conti and
/// Toivola–Nuutila) in `original` (the output of `rbprops_inertia::solve` on the
/// measured data with `solve_opts`); see the crate documentation for the procedure.
/// Mass-line and `_projected` estimates are not bootstrapped themselves (the latter get
/// their base estimate's errors in [`apply`]). With `line_variance` (the FRF estimator's
/// variance of each line), the replicates' noise is drawn from it on every channel it
/// covers, instead of from the noise model fitted to the residuals.
#[allow(clippy::too_many_arguments)]
pub fn bootstrap(
    geometry: &Geometry,
    frf: &dyn FrfSource,
    modal: &ModalFitRecord,
    selection: &SelectionRecord,
    solve_opts: &SolveOptions,
    original: &[InertiaEstimate],
    opts: &BootstrapOptions,
    line_variance: Option<&LineVariance>,
) -> Result<BootstrapOutput, UqError> {
    if opts.replicates < 2 {
        return Err(UqError::Options(format!(
            "{} replicates: at least 2 are needed for a standard deviation",
            opts.replicates
        )));
    }
    if let Some(v) = line_variance {
        check_line_variance(v, frf)?;
    }
    let targets = modal_targets(original)?;
    // A record whose poles were corrected for an exponential window describes the physical
    // modes, not the measured (windowed) FRFs: resample the prefiltered windowed data with
    // the windowed poles, and correct each replicate's poles as modal-fit did.
    let windowed = rbprops_core::WindowCorrection::windowed_modal_fit(modal);
    let prefiltered;
    let (frf, modal) = match &windowed {
        None => (frf, modal),
        Some((w, m)) => {
            // Each excitation prefiltered as it is read.
            prefiltered = rbprops_core::Prefiltered { window: w, frf };
            (&prefiltered as &dyn FrfSource, m)
        }
    };
    let model = FittedModel::new(
        geometry,
        frf,
        modal,
        selection,
        opts.residual_terms,
        opts.pole_mode,
        &Draws {
            line_variance,
            window: windowed.as_ref().map(|(w, _)| w),
            // A full refit runs the modal fit on the whole FRF set: every line.
            decimate: opts.decimate && opts.reidentify == Reidentify::Refine,
            fit_weighting: opts.fit_weighting.as_deref(),
            scratch: opts.scratch.as_ref(),
        },
    )?;
    let replication = Replication {
        geometry,
        whole: match opts.reidentify {
            Reidentify::Full(_) => Some(FrfSet::from_source(frf).map_err(UqError::Source)?),
            Reidentify::Refine => None,
        },
        modal,
        selection,
        model: &model,
        windowed: &windowed,
        window_source: modal_source(&windowed),
        solve_opts: replicate_solve_options(solve_opts),
        required: selection
            .selected
            .iter()
            .map(|s| (s.excitation.clone(), s.excitation_mode))
            .collect(),
        targets: &targets,
        opts,
    };
    // Collected in replicate order whatever the thread count: the statistics below are
    // sequential sums over that order, so the output is bit-identical.
    let results: Vec<ReplicateResult> = (0..opts.replicates)
        .into_par_iter()
        .map(|b| replication.run(b))
        .collect();

    let mut warnings = misfit_warnings(&model, geometry);
    let mut estimates = Vec::new();
    for (t_idx, t) in targets.iter().enumerate() {
        if let Some(e) = target_statistics(t, t_idx, &results, opts, &mut warnings) {
            estimates.push(e);
        }
    }
    if estimates.is_empty() {
        return Err(UqError::Nothing(
            warnings.iter().map(Diagnostic::line).collect(),
        ));
    }
    Ok(BootstrapOutput {
        estimates,
        noise: model
            .excitations
            .iter()
            .map(|e| ExcitationNoise {
                excitation: e.id.clone(),
                channels: e.noise.clone(),
            })
            .collect(),
        replicates: opts.replicates,
        pole_mode: model.pole_mode,
        diagnostics: warnings,
        decimation: model
            .excitations
            .iter()
            .map(|e| e.decimation)
            .max()
            .unwrap_or(1),
        noise_source: noise_source(&model, line_variance),
    })
}

/// The line variances against the FRFs' layout: one per value, and a correlation
/// factor that is finite and at least 1.
fn check_line_variance(v: &LineVariance, frf: &dyn FrfSource) -> Result<(), UqError> {
    let values = frf.n_excitations() * frf.n_channels() * frf.frequency_hz().len();
    if v.sigma2.len() != values {
        return Err(UqError::Options(format!(
            "{} line variances for {values} FRF values",
            v.sigma2.len(),
        )));
    }
    if !(v.correlation_factor >= 1.0 && v.correlation_factor.is_finite()) {
        return Err(UqError::Options(format!(
            "line-variance correlation factor {} (must be finite and ≥ 1)",
            v.correlation_factor
        )));
    }
    Ok(())
}

/// What the replicates' noise was drawn from, in words: the estimator's line variances,
/// the fit's residuals, or each on the channels it covered.
fn noise_source(model: &FittedModel, line_variance: Option<&LineVariance>) -> String {
    let flags: Vec<bool> = model
        .excitations
        .iter()
        .flat_map(|e| e.given_variance.iter().copied())
        .collect();
    let residuals =
        "a noise model σ² = a²|S|² + b² per channel fitted to the modal fit's residuals";
    let given = |v: &LineVariance| {
        if v.correlation_factor > 1.0 {
            format!(
                "the FRF estimator's line variances ({}) times {:.3} for the window's line-to-line correlation",
                v.source, v.correlation_factor
            )
        } else {
            format!("the FRF estimator's line variances ({})", v.source)
        }
    };
    let text = match line_variance {
        Some(v) if flags.iter().all(|f| *f) => given(v),
        Some(v) if flags.iter().any(|f| *f) => format!(
            "{} on {} of {} channels, elsewhere {residuals}",
            given(v),
            flags.iter().filter(|f| **f).count(),
            flags.len()
        ),
        _ => residuals.to_string(),
    };
    let common = model
        .excitations
        .iter()
        .filter(|e| e.common.is_some())
        .count();
    if common == 0 {
        return text;
    }
    format!(
        "{text}; on {common} of {} excitations also the force noise's error common to their channels (Ĥ = H(1 + ε), ε drawn once per replicate with the force window's line correlation)",
        model.excitations.len()
    )
}

/// The estimates' method text of a bootstrap: replicates, lines, noise source.
pub fn method_text(boot: &BootstrapOutput) -> String {
    let lines = if boot.decimation > 1 {
        format!(
            "drawn and refitted on every {}th line of the fit's band (each with the noise of its {} lines)",
            boot.decimation, boot.decimation
        )
    } else {
        "drawn and refitted on every line of the fit's band".to_string()
    };
    format!(
        "FRF-level parametric bootstrap: {} replicates {lines}, noise from {}",
        boot.replicates, boot.noise_source
    )
}

/// One replicate's outcome: an error that sank the whole replicate (its re-identification
/// or solve failed), else per target (in target order) its property vector or why it has none.
type ReplicateResult = Result<Vec<Result<[f64; N_PROPS], String>>, String>;

/// The estimates to bootstrap: the modal estimators' (Bretl–Conti, Toivola–Nuutila) in
/// `original`, in their order, with the modes each used (a replicate must use the same).
fn modal_targets(original: &[InertiaEstimate]) -> Result<Vec<Target>, UqError> {
    let modal = [
        Estimator::BretlConti.method(),
        Estimator::ToivolaNuutila.method(),
    ];
    let targets: Vec<Target> = original
        .iter()
        .filter(|e| modal.contains(&e.method))
        .map(|e| Target {
            method: e.method,
            setup: e.setup.clone(),
            modes_used: e.modes_used.clone(),
            estimate: estimate_vector(e),
        })
        .collect();
    if targets.is_empty() {
        return Err(UqError::Nothing(vec![
            "no Bretl–Conti or Toivola–Nuutila estimate to bootstrap".into(),
        ]));
    }
    Ok(targets)
}

/// The solve options of a replicate: the measured data's, without what a replicate does not
/// need (the mass line, which is not bootstrapped; the reference comparison; the Monte
/// Carlo errors, which the bootstrap replaces; the rigid-body check).
fn replicate_solve_options(solve_opts: &SolveOptions) -> SolveOptions {
    let mut ropts = solve_opts.clone();
    ropts.estimators.retain(|e| *e != Estimator::MassLine);
    ropts.reference = None;
    ropts.monte_carlo_samples = 0;
    ropts.rigid_body_check = false;
    ropts
}

/// What every replicate shares: the (possibly windowed) measured records, the fitted noise
/// model to draw from, and the targets to re-estimate.
struct Replication<'a> {
    geometry: &'a Geometry,
    /// The (prefiltered) FRF set whole, for [`Reidentify::Full`] only: a refinement
    /// replicate reads only the model.
    whole: Option<FrfSet>,
    modal: &'a ModalFitRecord,
    selection: &'a SelectionRecord,
    model: &'a FittedModel,
    windowed: &'a Option<(rbprops_core::WindowCorrection, ModalFitRecord)>,
    window_source: String,
    solve_opts: SolveOptions,
    /// The selected (excitation, mode) pairs a full refit must find again.
    required: Vec<(String, usize)>,
    targets: &'a [Target],
    opts: &'a BootstrapOptions,
}

impl Replication<'_> {
    /// Replicate `b`: draws noisy FRFs from the model, re-identifies the modes, swaps them
    /// into copies of the records, and solves again for the targets.
    fn run(&self, b: usize) -> ReplicateResult {
        let mut rng = replicate_rng(self.opts.seed, b);
        let modes = self.reidentify(&mut rng)?;
        let (mut modal_b, selection_b) = replicate_records(self.modal, self.selection, &modes)?;
        if let Some((w, _)) = self.windowed {
            w.correct_modal_fit(&mut modal_b, &self.window_source)
                .map_err(|e| e.to_string())?;
        }
        let out = solve(
            self.geometry,
            &modal_b,
            &selection_b,
            None,
            &self.solve_opts,
        )
        .map_err(|e| e.to_string())?;
        Ok(self
            .targets
            .iter()
            .map(|t| target_vector(t, &out))
            .collect())
    }

    /// The modes of a replicate drawn from `rng`, by the options' [`Reidentify`] method.
    /// The model's excitations are drawn in their order (group by group: the groups
    /// list them in that order), so a replicate's data depend only on its seed.
    fn reidentify(&self, rng: &mut ChaCha8Rng) -> Result<Vec<ReplicateModes>, String> {
        let opts = self.opts;
        match &opts.reidentify {
            Reidentify::Refine => {
                // The draws' order is the excitations' only if the groups list them
                // in order from 0 (as `FittedModel::new` makes them): a held and a
                // stored replicate are then the same bit for bit.
                debug_assert!(
                    self.model
                        .groups
                        .iter()
                        .flatten()
                        .copied()
                        .eq(0..self.model.excitations.len()),
                    "the model's groups list its excitations in order"
                );
                let mut v = Vec::new();
                for g in &self.model.groups {
                    v.extend(refine_group(
                        self.model,
                        g,
                        (&mut *rng, opts.scratch.as_ref()),
                        self.modal,
                        &opts.tolerances,
                    )?);
                }
                Ok(v)
            }
            Reidentify::Full(fo) => full_refit(
                self.geometry,
                self.whole.as_ref().expect("made whole for the full refit"),
                self.model,
                &self.draw_all(rng)?,
                self.modal,
                fo,
                &self.required,
                &opts.tolerances,
            ),
        }
    }

    /// Every model excitation's draws, held (a full refit takes the whole set).
    fn draw_all(&self, rng: &mut ChaCha8Rng) -> Result<Vec<Vec<Vec<c64>>>, String> {
        (0..self.model.excitations.len())
            .map(|i| {
                let grid = self
                    .model
                    .grid(i)
                    .map_err(|e| format!("bootstrap scratch store: {e}"))?;
                Ok(self.model.excitations[i].draw(&grid, rng))
            })
            .collect()
    }
}

/// Copies of the measured modal-fit and selection records with a replicate's modes in place
/// of the re-identified excitations' modes; each selected mode is renumbered through the
/// replicate's mode map and takes its new frequency.
fn replicate_records(
    modal: &ModalFitRecord,
    selection: &SelectionRecord,
    modes: &[ReplicateModes],
) -> Result<(ModalFitRecord, SelectionRecord), String> {
    let mut modal_b = modal.clone();
    modal_b
        .modes
        .retain(|m| !modes.iter().any(|r| r.excitation == m.excitation));
    for r in modes {
        modal_b.modes.extend(r.modes.iter().cloned());
    }
    let mut selection_b = selection.clone();
    for s in &mut selection_b.selected {
        if let Some(r) = modes.iter().find(|r| r.excitation == s.excitation) {
            let n = r
                .mode_map
                .iter()
                .find(|(a, _)| *a == s.excitation_mode)
                .map(|(_, n)| *n)
                .ok_or_else(|| {
                    format!(
                        "excitation '{}' mode {} was not found again",
                        s.excitation, s.excitation_mode
                    )
                })?;
            s.excitation_mode = n;
            if let Some(m) = r.modes.iter().find(|m| m.mode == n) {
                s.frequency_hz = m.frequency_hz;
            }
        }
    }
    Ok((modal_b, selection_b))
}

/// A target's property vector in a replicate's solve output, or why it has none: no
/// estimate (with the solve's warnings that say why), other modes used than on the
/// measured data, or non-finite properties.
fn target_vector(t: &Target, out: &SolveOutput) -> Result<[f64; N_PROPS], String> {
    let e = out
        .estimates
        .iter()
        .find(|e| e.method == t.method && e.setup == t.setup)
        .ok_or_else(|| {
            // What kept the estimator from an estimate: its failure or modes left out.
            let why: Vec<String> = out
                .diagnostics
                .iter()
                .filter(|d| {
                    matches!(
                        d.kind,
                        DiagnosticKind::EstimatorFailed | DiagnosticKind::ModeLeftOut
                    )
                })
                .map(Diagnostic::line)
                .collect();
            format!("{} gave no estimate ({})", t.method, why.join("; "))
        })?;
    if e.modes_used != t.modes_used {
        return Err(format!(
            "{} used modes {:?} instead of {:?}",
            t.method, e.modes_used, t.modes_used
        ));
    }
    let v = estimate_vector(e);
    if v.iter().all(|x| x.is_finite()) {
        Ok(v)
    } else {
        Err(format!("{}: non-finite properties", t.method))
    }
}

/// Warnings on FRF lines the modal model misses: they are not resampled as noise, so the
/// replicates keep the measured values there.
fn misfit_warnings(model: &FittedModel, geometry: &Geometry) -> Vec<Diagnostic> {
    let mut warnings = Vec::new();
    for e in &model.excitations {
        let n: usize = e.misfit_lines.iter().sum();
        if n > 0 {
            let worst = (0..e.misfit_lines.len())
                .max_by_key(|&c| e.misfit_lines[c])
                .unwrap_or(0);
            // Handled (the lines are kept out of the noise model): a note.
            warnings.push(Diagnostic::new(
                "rb-solve",
                DiagnosticKind::UnmodelledLines,
                Severity::Note,
                DiagnosticSubject::run().excitation(&e.id),
                format!(
                    "bootstrap: the modal model misses structure on {n} channel-lines (most on channel '{}': {} lines); they are not counted as noise and every replicate keeps the measured values there",
                    geometry.channels[worst].id, e.misfit_lines[worst]
                ),
            ));
        }
    }
    warnings
}

/// The bootstrap estimate of target `t` (index `t_idx`) from the replicates' `results`, in
/// replicate order; `None` (with a warning) when fewer than two replicates succeeded, and a
/// warning when more than the options' fraction failed.
fn target_statistics(
    t: &Target,
    t_idx: usize,
    results: &[ReplicateResult],
    opts: &BootstrapOptions,
    warnings: &mut Vec<Diagnostic>,
) -> Option<BootstrapEstimate> {
    let mut samples = Vec::new();
    let mut reasons: Vec<String> = Vec::new();
    let mut failed = 0;
    for r in results {
        let one = match r {
            Ok(v) => v[t_idx].clone(),
            Err(e) => Err(e.clone()),
        };
        match one {
            Ok(v) => samples.push(v),
            Err(e) => {
                failed += 1;
                if reasons.len() < 5 && !reasons.contains(&e) {
                    reasons.push(e);
                }
            }
        }
    }
    for (k, reason) in ran_wide(&samples).into_iter().enumerate().rev() {
        let Some(reason) = reason else { continue };
        samples.remove(k);
        failed += 1;
        if reasons.len() < 5 && !reasons.contains(&reason) {
            reasons.push(reason);
        }
    }
    let id = format!("{} (set-up '{}')", t.method, t.setup);
    if samples.len() < 2 {
        warnings.push(uncertainty_incomplete(
            &t.setup,
            format!(
                "bootstrap of {id}: {failed} of {} replicates failed ({}); its standard errors are left as they were",
                opts.replicates,
                reasons.join("; ")
            ),
        ));
        return None;
    }
    if failed as f64 > opts.failure_warning_fraction * opts.replicates as f64 {
        warnings.push(uncertainty_incomplete(
            &t.setup,
            format!(
                "bootstrap of {id}: {failed} of {} replicates failed ({}); the standard errors come from the others and may be too small",
                opts.replicates,
                reasons.join("; ")
            ),
        ));
    }
    Some(statistics(t, samples, failed, reasons))
}

/// Robust standard deviations (`1.4826 × MAD`) from the replicates' median beyond which a
/// replicate is taken to have run wide. Normal replicates reach 8 on one of ten
/// properties of a hundred replicates with probability below 10⁻¹¹; replicates that do are the estimator
/// failing on a draw (a mass line that is unreliable on the recording, a mode that
/// changes partner), and one of them carries the standard deviation of a hundred: one
/// replicate at 10³ σ makes it 100 σ.
pub const RAN_WIDE_SIGMAS: f64 = 8.0;

/// Fewest replicates for a median and MAD to judge the others by.
const RAN_WIDE_MIN_SAMPLES: usize = 20;

/// Per replicate: why it ran wide ([`RAN_WIDE_SIGMAS`] on some property), else None.
fn ran_wide(samples: &[[f64; N_PROPS]]) -> Vec<Option<String>> {
    let mut out = vec![None; samples.len()];
    if samples.len() < RAN_WIDE_MIN_SAMPLES {
        return out;
    }
    for k in 0..N_PROPS {
        let mut v: Vec<f64> = samples.iter().map(|s| s[k]).collect();
        v.sort_by(f64::total_cmp);
        let median = quantile(&v, 0.5);
        let mut dev: Vec<f64> = v.iter().map(|x| (x - median).abs()).collect();
        dev.sort_by(f64::total_cmp);
        let robust_sd = 1.4826 * quantile(&dev, 0.5);
        if !(robust_sd > 0.0) {
            continue;
        }
        for (s, o) in samples.iter().zip(&mut out) {
            let z = (s[k] - median).abs() / robust_sd;
            if o.is_none() && !(z <= RAN_WIDE_SIGMAS) {
                *o = Some(format!(
                    "ran wide: {} beyond {RAN_WIDE_SIGMAS} robust standard deviations of the other replicates",
                    PROPERTY_NAMES[k]
                ));
            }
        }
    }
    out
}

/// The source named in a replicate's window correction (the original record's).
fn modal_source(w: &Option<(rbprops_core::WindowCorrection, ModalFitRecord)>) -> String {
    match w {
        Some(_) => "bootstrap replicate".into(),
        None => String::new(),
    }
}

/// Linear-interpolation quantile (type 7) of sorted values.
fn quantile(sorted: &[f64], p: f64) -> f64 {
    let h = (sorted.len() - 1) as f64 * p;
    let lo = h.floor() as usize;
    let hi = (lo + 1).min(sorted.len() - 1);
    sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo])
}

fn statistics(
    t: &Target,
    samples: Vec<[f64; N_PROPS]>,
    failed: usize,
    failure_reasons: Vec<String>,
) -> BootstrapEstimate {
    let n = samples.len() as f64;
    let mean: [f64; N_PROPS] =
        std::array::from_fn(|k| samples.iter().map(|s| s[k]).sum::<f64>() / n);
    let std = std::array::from_fn(|k| {
        (samples
            .iter()
            .map(|s| (s[k] - mean[k]).powi(2))
            .sum::<f64>()
            / (n - 1.0))
            .sqrt()
    });
    let percentile_95 = std::array::from_fn(|k| {
        let mut v: Vec<f64> = samples.iter().map(|s| s[k]).collect();
        v.sort_by(f64::total_cmp);
        [quantile(&v, 0.025), quantile(&v, 0.975)]
    });
    BootstrapEstimate {
        method: t.method,
        setup: t.setup.clone(),
        estimate: t.estimate,
        std,
        bias: std::array::from_fn(|k| mean[k] - t.estimate[k]),
        percentile_95,
        samples,
        failed,
        failure_reasons,
    }
}

/// Writes the bootstrap standard errors into the matching estimates (same method and
/// set-up; `<method>_projected` takes its base method's) and sets
/// `uncertainty_method = "bootstrap"`. Returns how many estimates were updated.
pub fn apply(estimates: &mut [InertiaEstimate], boot: &BootstrapOutput) -> usize {
    let mut n = 0;
    for e in estimates.iter_mut() {
        let base = e.method.base();
        let Some(b) = boot
            .estimates
            .iter()
            .find(|b| b.method == base && b.setup == e.setup)
        else {
            continue;
        };
        InertiaProperties::from_vector(&b.std).set_standard_errors_of(e);
        e.uncertainty_method = UncertaintyMethod::Bootstrap;
        e.uncertainty_source = Some(method_text(boot));
        e.update_systematic_interval();
        if b.failed > 0 {
            e.diagnostics.push(uncertainty_incomplete(
                &e.setup,
                format!(
                    "bootstrap: {} of {} replicates failed ({}); standard errors from the other {}",
                    b.failed,
                    b.failed + b.samples.len(),
                    b.failure_reasons.join("; "),
                    b.samples.len()
                ),
            ));
        }
        n += 1;
    }
    n
}

/// `rbprops_inertia::solve` followed by [`bootstrap`] and [`apply`]: the estimates of the
/// measured data with bootstrap standard errors for the modal estimators (the mass line
/// keeps its own). If the bootstrap cannot run, the solve's linearised errors stay and a
/// warning says why; the second value is then `None`.
pub fn solve_with_bootstrap(
    geometry: &Geometry,
    modal: &ModalFitRecord,
    selection: &SelectionRecord,
    frf: &dyn FrfSource,
    solve_opts: &SolveOptions,
    opts: &BootstrapOptions,
    line_variance: Option<&LineVariance>,
) -> Result<(SolveOutput, Option<BootstrapOutput>), UqError> {
    let mut out = solve(geometry, modal, selection, Some(frf), solve_opts)?;
    match bootstrap(
        geometry,
        frf,
        modal,
        selection,
        solve_opts,
        &out.estimates,
        opts,
        line_variance,
    ) {
        Ok(boot) => {
            apply(&mut out.estimates, &boot);
            out.diagnostics.extend(boot.diagnostics.iter().cloned());
            Ok((out, Some(boot)))
        }
        Err(e) => {
            out.diagnostics.push(uncertainty_incomplete(
                "",
                format!(
                    "bootstrap: {e}; the modal estimates keep their {} standard errors",
                    if solve_opts.monte_carlo_samples > 0 {
                        "Monte Carlo"
                    } else {
                        "linearised"
                    }
                ),
            ));
            Ok((out, None))
        }
    }
}

/// A warning that bootstrap standard errors are incomplete: replicates failed, or the
/// bootstrap did not run (`setup` empty: not one set-up's).
fn uncertainty_incomplete(setup: &str, message: String) -> Diagnostic {
    let subject = if setup.is_empty() {
        DiagnosticSubject::run()
    } else {
        DiagnosticSubject::setup(setup)
    };
    Diagnostic::new(
        "rb-solve",
        DiagnosticKind::UncertaintyIncomplete,
        Severity::Warning,
        subject,
        message,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;
    use rand_distr::StandardNormal;

    /// 100 normal replicates: none runs wide. The same with one replicate's Jzz moved to
    /// 10³ of its spread (as an estimator failing on one draw puts it): that one alone is
    /// named, on Jzz, and without it the standard deviation is the normal one's again
    /// (with it, about 100 times that).
    #[test]
    fn one_replicate_far_out_is_named_and_the_others_keep_their_spread() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut samples: Vec<[f64; N_PROPS]> = (0..100)
            .map(|_| {
                std::array::from_fn(|k| {
                    1.0 + k as f64 + 1e-3 * rng.sample::<f64, _>(StandardNormal)
                })
            })
            .collect();
        assert!(ran_wide(&samples).iter().all(Option::is_none));
        let sd = |s: &[[f64; N_PROPS]], k: usize| {
            let n = s.len() as f64;
            let m = s.iter().map(|x| x[k]).sum::<f64>() / n;
            (s.iter().map(|x| (x[k] - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
        };
        let normal = sd(&samples, 6);
        samples[37][6] += 1.0;
        assert!(sd(&samples, 6) > 50.0 * normal);
        let wide = ran_wide(&samples);
        for (i, w) in wide.iter().enumerate() {
            assert_eq!(w.is_some(), i == 37, "replicate {i}: {w:?}");
        }
        assert!(wide[37].as_ref().unwrap().contains(PROPERTY_NAMES[6]));
        samples.remove(37);
        assert!((sd(&samples, 6) / normal - 1.0).abs() < 0.05);
        // Too few replicates to judge by: nothing is named.
        assert!(ran_wide(&samples[..10]).iter().all(Option::is_none));
    }
}
