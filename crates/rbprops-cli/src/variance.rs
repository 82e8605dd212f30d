//! The line-variance topic (`/rbprops/frf_variance`): each FRF line's noise variance as
//! the estimator knows it. Written by `frf-est` (H1 over its accepted hits); read by
//! `model-check` as its noise model, by `rb-solve`'s bootstrap as the noise of its
//! replicates (their method texts say so), and by `modal-fit`, which weights its least
//! squares by it ([`weight_fit`]; `--weight none` for the default relative weights).

use anyhow::{bail, Result};
use rbprops_core::{FrfSet, Geometry};
use rbprops_formats::wire::{ForceNoiseMsg, FrfVarianceMsg};
use rbprops_formats::{topics, RunRecord};
use rbprops_sim::effects::processing::ExponentialWindow;
use rbprops_sim::effects::processing::RecordTruncation;

/// Lines whose noise power is pooled on each side of a line (docs/conventions.md, FRF
/// estimation): 9 in all, 72 real degrees of freedom from five hits on independent lines,
/// fewer under an exponential window (the topic carries the number).
pub const POOL_HALF_WIDTH: usize = 4;

/// σ² per FRF value, the FRF layout `[excitation][channel][line]`; NaN where unknown.
#[derive(Debug, Clone, PartialEq)]
pub struct LineVarianceSet {
    /// σ² = E|ε|² (FRF units squared).
    pub sigma2: Vec<f64>,
    /// Real χ² degrees of freedom of the σ² of each excitation (∞ where none is known).
    pub degrees_of_freedom: Vec<f64>,
    /// Per excitation, the force noise's error common to its FRFs, when the estimator
    /// knows it (`frf-est`; its ρ² on the FRF set's axis). σ² holds its part too, as each
    /// channel sees it.
    pub common: Vec<Option<rbprops_core::CommonRelativeError>>,
}

impl LineVarianceSet {
    /// σ² scaled so that a χ² over many values has about its nominal mean: a variance
    /// estimated with `d` degrees of freedom reads `E[σ²/σ̂²] = 1 + 2/d` to first order
    /// (the delta method; `d/(d − 2)` exactly for a χ²_d independent of the error). The
    /// first-order factor, not the exact one: the pooled σ̂² shares its neighbourhood of
    /// lines with the errors it weighs (a window correlates them), which lowers
    /// `E[|ε|²/σ̂²]` below the independent value. Measured on Test Case II impact tests of
    /// the independent generator (d = 7–15): χ²/ν 1.08–1.10 uncorrected, 0.80–0.94 with
    /// d/(d − 2). [`Self::correction_se`] carries what is left unknown.
    pub fn calibrated_for_chi2(&self) -> Vec<f64> {
        let per = self.sigma2.len() / self.degrees_of_freedom.len().max(1);
        self.sigma2
            .iter()
            .enumerate()
            .map(|(i, v)| v * (1.0 + 2.0 / self.degrees_of_freedom[i / per.max(1)]))
            .collect()
    }

    /// The relative uncertainty of the correction's scale: half the largest correction
    /// (`1/d` at the smallest d), for the noise band.
    pub fn correction_se(&self) -> f64 {
        let d = self
            .degrees_of_freedom
            .iter()
            .fold(f64::INFINITY, |m, &d| m.min(d));
        1.0 / d
    }

    /// The smallest degrees of freedom over the excitations.
    pub fn min_degrees_of_freedom(&self) -> f64 {
        self.degrees_of_freedom
            .iter()
            .fold(f64::INFINITY, |m, &d| m.min(d))
    }
}

/// Stores a variance set as the topic (channels with any finite value;
/// `crate::channel_table`).
pub fn set(rec: &mut RunRecord, geometry: &Geometry, frf: &FrfSet, v: &LineVarianceSet) {
    let n = frf.n_lines();
    let msgs: Vec<FrfVarianceMsg> = crate::channel_table::encode(geometry, |e, c| {
        let at = (e * frf.n_channels + c) * n;
        let s = &v.sigma2[at..at + n];
        s.iter().any(|x| x.is_finite()).then_some(s)
    })
    .into_iter()
    .map(|r| FrfVarianceMsg {
        degrees_of_freedom: v.degrees_of_freedom[r.index],
        force_noise: v.common[r.index].as_ref().map(force_noise_msg),
        excitation: r.excitation,
        channels: r.channels,
        values_f64le: r.values_f64le,
    })
    .collect();
    rec.set(topics::FRF_VARIANCE, &msgs);
}

fn force_noise_msg(c: &rbprops_core::CommonRelativeError) -> ForceNoiseMsg {
    let values: Vec<rbprops_core::c64> = c
        .relative_variance
        .iter()
        .map(|&v| rbprops_core::c64::new(v, 0.0))
        .collect();
    ForceNoiseMsg {
        relative_variance_f64le: rbprops_formats::wire::encode_values(&values),
        window_times_s: c.times_s.clone(),
        window_weights: c.weights.clone(),
    }
}

/// The common error of one message (`at` names it in errors): ρ² finite and ≥ 0 on
/// every line, one weight per time, the weights ≥ 0 summing to 1.
fn common_error(
    m: &ForceNoiseMsg,
    n_lines: usize,
    at: &str,
) -> Result<rbprops_core::CommonRelativeError> {
    let values = rbprops_formats::wire::decode_values(&m.relative_variance_f64le, n_lines)
        .map_err(|e| anyhow::anyhow!("{at}, force_noise.relative_variance_f64le: {e}"))?;
    let relative_variance: Vec<f64> = values.iter().map(|v| v.re).collect();
    if let Some((l, v)) = relative_variance
        .iter()
        .enumerate()
        .find(|(_, v)| !(v.is_finite() && **v >= 0.0))
    {
        bail!("{at}, force_noise, line {l}: relative variance {v} (must be finite and ≥ 0)");
    }
    let total: f64 = m.window_weights.iter().sum();
    if m.window_times_s.len() != m.window_weights.len()
        || m.window_weights.is_empty()
        || m.window_weights
            .iter()
            .any(|w| !(w.is_finite() && *w >= 0.0))
        || m.window_times_s.iter().any(|t| !t.is_finite())
        || (total - 1.0).abs() > 1e-9
    {
        bail!(
            "{at}, force_noise: {} window times and {} weights summing to {total} (one finite time per weight, weights ≥ 0 summing to 1)",
            m.window_times_s.len(),
            m.window_weights.len()
        );
    }
    Ok(rbprops_core::CommonRelativeError {
        relative_variance,
        times_s: m.window_times_s.clone(),
        weights: m.window_weights.clone(),
    })
}

/// The topic on the record's FRF layout; `None` when the record has none. Errors name the
/// excitation or channel that does not fit the geometry, and a variance that is negative.
pub fn get(rec: &RunRecord) -> Result<Option<LineVarianceSet>> {
    let msgs: Vec<FrfVarianceMsg> = rec.get(topics::FRF_VARIANCE)?;
    if msgs.is_empty() {
        return Ok(None);
    }
    let (geometry, frf) = rec.require_geometry_and_frf()?;
    let n = frf.n_lines();
    let mut sigma2 = vec![f64::NAN; frf.values.len()];
    let mut dof = vec![f64::INFINITY; frf.n_excitations];
    let mut common = vec![None; frf.n_excitations];
    for m in &msgs {
        let what = format!("{} topic", topics::FRF_VARIANCE);
        let at = format!("{what}, excitation '{}'", m.excitation);
        let (e, channels) = crate::channel_table::decode(
            &geometry,
            n,
            &what,
            &m.excitation,
            &m.channels,
            &m.values_f64le,
        )?;
        if !(m.degrees_of_freedom > 2.0) {
            bail!(
                "{at}: degrees_of_freedom {} (must exceed 2 for a variance a χ² can use)",
                m.degrees_of_freedom
            );
        }
        dof[e] = m.degrees_of_freedom;
        if let Some(f) = &m.force_noise {
            common[e] = Some(common_error(f, n, &at)?);
        }
        for (c, values) in channels {
            let id = &geometry.channels[c].id;
            for (l, &v) in values.iter().enumerate() {
                if v < 0.0 || v.is_infinite() {
                    bail!(
                        "{at}, channel '{id}', line {l}: variance {v} (must be ≥ 0 and finite, or NaN for unknown)"
                    );
                }
                sigma2[(e * frf.n_channels + c) * n + l] = v;
            }
        }
    }
    Ok(Some(LineVarianceSet {
        sigma2,
        degrees_of_freedom: dof,
        common,
    }))
}

/// The line variances of an FRF export from its coherence topic and the number of
/// averages `n_d` the export declares (`--averages`):
/// `σ² = |Ĥ|²(1 − γ²)/(n_d γ²)` per line (Bendat & Piersol; `Var|Ĥ| ≈ (1 − γ²)/(2 n_d γ²) |H|²`
/// in each of the real and imaginary parts, `rbprops_frfest::coherence_line_variance`),
/// with `2(n_d − 1)` real degrees of freedom (the line's own averages, not pooled);
/// NaN (unknown) on the channels without coherence. Errors, naming `source`, when the
/// record has no coherence, already has line variances (from `frf-est`), or `n_d < 3`
/// (fewer leave no degrees of freedom for a χ²).
pub fn from_coherence(rec: &RunRecord, n_averages: usize, source: &str) -> Result<LineVarianceSet> {
    if n_averages < 3 {
        bail!("--averages {n_averages}: at least 3 averages for a variance a χ² can use");
    }
    if rec.topic(topics::FRF_VARIANCE).is_some() {
        bail!(
            "{source}: --averages, but the run already has line variances ({}: frf-est's, or from the number of averages the FRF export names in its ID lines)",
            topics::FRF_VARIANCE
        );
    }
    let Some(grid) = crate::coherence::get(rec).map_err(|e| anyhow::anyhow!("{source}: {e}"))?
    else {
        bail!(
            "{source}: --averages, but the recording holds no coherence (a UFF export needs coherence datasets, function type 6, beside its FRFs)"
        );
    };
    let (_, frf) = rec.require_geometry_and_frf()?;
    let n = frf.n_lines();
    let mut sigma2 = vec![f64::NAN; frf.values.len()];
    for (e, row) in grid.iter().enumerate() {
        for (c, coh) in row.iter().enumerate() {
            let Some(coh) = coh else { continue };
            let at = (e * frf.n_channels + c) * n;
            for ((s, h), &g) in sigma2[at..at + n]
                .iter_mut()
                .zip(&frf.values[at..at + n])
                .zip(coh)
            {
                *s = rbprops_frfest::coherence_line_variance(h.norm_sqr(), g, n_averages);
            }
        }
    }
    Ok(LineVarianceSet {
        sigma2,
        degrees_of_freedom: vec![2.0 * (n_averages as f64 - 1.0); frf.n_excitations],
        common: vec![None; frf.n_excitations],
    })
}

/// `--averages N` on a stage reading an FRF export with coherence: the line variances
/// [`from_coherence`] written to the record's variance topic, so that the model check
/// uses them as it uses `frf-est`'s. Nothing without `--averages`.
pub fn declare_averages(
    rec: &mut RunRecord,
    n_averages: Option<usize>,
    source: &str,
) -> Result<()> {
    let Some(n) = n_averages else {
        return Ok(());
    };
    let v = from_coherence(rec, n, source)?;
    let (geometry, frf) = rec.require_geometry_and_frf()?;
    let frf = frf.clone();
    set(rec, &geometry, &frf, &v);
    Ok(())
}

/// The number of averages an FRF export names in its ID lines (`rbprops_uff::averages`),
/// used as `--averages` would be ([`declare_averages`]) when the export holds coherence:
/// the line variances follow from the coherence without the option. Returns the note
/// saying what was read (or why a named count was not used); nothing when no dataset
/// names one.
pub fn declared_by_export(
    rec: &mut RunRecord,
    data: &rbprops_uff::UffFile,
    source: &str,
) -> Result<Option<String>> {
    let d = match rbprops_uff::declared_averages(data) {
        Ok(Some(d)) => d,
        Ok(None) => return Ok(None),
        Err(why) => {
            return Ok(Some(format!(
                "the number of averages is not read from the export: {why}"
            )))
        }
    };
    let named = format!(
        "{} averages named in ID line {} of dataset #{} (line {}) and {} more FRF/coherence dataset(s)",
        d.count,
        d.id_line,
        d.at.index,
        d.at.line,
        d.datasets - 1
    );
    let coherence = crate::coherence::get(rec).map_err(|e| anyhow::anyhow!("{source}: {e}"))?;
    if coherence.is_none() {
        return Ok(Some(format!(
            "{named}: not used (no coherence beside the FRFs, so no line variances)"
        )));
    }
    if d.count < 3 {
        return Ok(Some(format!(
            "{named}: not used (fewer than 3 averages leave no degrees of freedom for a χ²)"
        )));
    }
    declare_averages(rec, Some(d.count), source)?;
    Ok(Some(format!(
        "line variances from the coherence and the {named} ({})",
        topics::FRF_VARIANCE
    )))
}

/// Floor of the relative variance σ²/|H|² when weighting by the line variances: a
/// relative standard error of 1e-6, far below any measurement's (H1 from five hammer
/// hits reads 1e-4 to 1e-2) and above f64 rounding; exact data (σ² = 0) sit on it
/// everywhere, which gives uniform factors and the default fit.
pub const RELATIVE_VARIANCE_FLOOR: f64 = 1e-12;

/// The line weighting of `modal-fit --weight variance` from a record read from `source`
/// (see [`weight_fit`]); `None` when the record has no line variances.
pub fn weighting(
    rec: &RunRecord,
    source: &str,
) -> Result<Option<rbprops_modal::CoherenceWeighting>> {
    let Some(v) = get(rec).map_err(|e| anyhow::anyhow!("{source}: {e}"))? else {
        return Ok(None);
    };
    let (geometry, frf) = rec.require_geometry_and_frf()?;
    let n = frf.n_lines();
    let per_channel = |f: &dyn Fn(usize, usize) -> Vec<f64>| -> Vec<Vec<Option<Vec<f64>>>> {
        (0..frf.n_excitations)
            .map(|e| (0..frf.n_channels).map(|c| Some(f(e, c))).collect())
            .collect()
    };
    let sigma2 = per_channel(&|e, c| {
        let at = (e * frf.n_channels + c) * n;
        v.sigma2[at..at + n].to_vec()
    });
    let floor = RELATIVE_VARIANCE_FLOOR;
    rbprops_modal::CoherenceWeighting::from_variance(sigma2, |e, c| frf.frf(e, c), floor)
        .map(Some)
        .map_err(|e| {
            anyhow::anyhow!(
                "{source}: {} topic: {}",
                topics::FRF_VARIANCE,
                crate::coherence::name_ids(&e, &geometry)
            )
        })
}

/// The line weighting `modal-fit` recorded in `rec`'s processing topic, rebuilt from the
/// record (`variance` or `coherence`); `None` for the default weights.
pub fn fit_weighting(rec: &RunRecord) -> Result<Option<rbprops_modal::CoherenceWeighting>> {
    use rbprops_core::records::{LineWeightingRecord, ProcessingRecord, PROCESSING_TOPIC};
    let processing: ProcessingRecord = rec.get_one(PROCESSING_TOPIC)?.unwrap_or_default();
    match processing
        .line_weighting
        .as_ref()
        .map(|w| w.weight.as_str())
    {
        Some(LineWeightingRecord::VARIANCE) => weighting(rec, "the record"),
        Some(LineWeightingRecord::COHERENCE) => crate::coherence::weighting(rec, "the record"),
        _ => Ok(None),
    }
}

/// Weights `modal-fit`'s least squares by the run's line variances (the topic; `frf-est`
/// output, or an export's coherence with `--averages`): `1/σ²` through the relative
/// variance `σ²/|H|²` of every line and channel (`rbprops_modal::CoherenceWeighting::
/// from_variance`), and says so in the processing topic's `line_weighting`. Returns
/// false, changing nothing, when the run has no line variances.
pub fn weight_fit(
    rec: &mut RunRecord,
    opts: &mut rbprops_modal::FitOptions,
    source: &str,
) -> Result<bool> {
    use rbprops_core::records::{LineWeightingRecord, ProcessingRecord, PROCESSING_TOPIC};
    let Some(weighting) = weighting(rec, source)? else {
        return Ok(false);
    };
    let floor = RELATIVE_VARIANCE_FLOOR;
    let mut processing: ProcessingRecord = rec.get_one(PROCESSING_TOPIC)?.unwrap_or_default();
    processing.line_weighting = Some(LineWeightingRecord {
        weight: LineWeightingRecord::VARIANCE.into(),
        method: format!(
            "least squares weighted by 1/σ², σ² the estimator's variance of every line and channel ({}): its relative variance σ²/|H|² (floored at {floor:e}) averaged over each excitation's channels per line (one weight per line), times 1/|H|² per channel in the pole estimate",
            topics::FRF_VARIANCE
        ),
        one_minus_coherence_floor: floor,
        unweighted_excitations: weighting.unweighted_excitations(),
    });
    rec.set(PROCESSING_TOPIC, std::slice::from_ref(&processing));
    opts.coherence_weighting = Some(std::sync::Arc::new(weighting));
    Ok(true)
}

/// The line variances for `rb-solve`'s bootstrap (`rbprops_uq::LineVariance`); `None`
/// when the record has none. Under `frf-est`'s exponential window neighbouring lines' noise
/// is correlated (`γ_m`, docs/conventions.md "FRF estimation"): a replicate draws
/// independent lines, so each line's variance is scaled by `Σ_{|m|≤2L} Re γ_m`
/// (`L` = [`POOL_HALF_WIDTH`]), which gives the sums over lines the estimators make the
/// noise of the correlated lines while the FRF is smooth over that many lines.
pub fn for_bootstrap(rec: &RunRecord) -> Result<Option<rbprops_uq::LineVariance>> {
    use rbprops_core::records::{ProcessingRecord, PROCESSING_TOPIC};
    let Some(v) = get(rec)? else {
        return Ok(None);
    };
    let processing: ProcessingRecord = rec.get_one(PROCESSING_TOPIC)?.unwrap_or_default();
    let estimation = processing.frf_estimation.as_ref();
    let correlation_factor = match estimation.and_then(|e| e.exponential_window_s.map(|t| (e, t))) {
        Some((e, tau)) => {
            1.0 + 2.0
                * (1..=2 * POOL_HALF_WIDTH)
                    .map(|m| {
                        rbprops_frfest::exponential_line_correlation(
                            tau,
                            e.sample_rate_hz,
                            e.record_samples,
                            m,
                        )
                        .re
                    })
                    .sum::<f64>()
        }
        None => 1.0,
    };
    let source = match estimation {
        Some(_) => format!(
            "{}, frf-est's H1 variance, at least {:.0} degrees of freedom",
            topics::FRF_VARIANCE,
            v.min_degrees_of_freedom()
        ),
        None => format!(
            "{}, from the export's coherence and declared averages",
            topics::FRF_VARIANCE
        ),
    };
    Ok(Some(rbprops_uq::LineVariance {
        sigma2: v.sigma2,
        correlation_factor,
        source,
        common: v.common,
    }))
}

/// Multiple of the estimator's force-noise error (`force_noise_relative_error`, an RMS
/// per excitation) under which an effect's whole change to the FRFs is not claimed: the
/// error is Gaussian, so 4 of its standard deviations are reached by chance in fewer than
/// 1 in 10⁴ lines, and a gain or delay fitted to it over a band averages below that.
pub const FORCE_NOISE_MARGIN: f64 = 4.0;

/// What `model-check` takes from the FRF estimator (see [`for_model_check`]).
#[derive(Debug, Default)]
pub struct EstimatorKnowledge {
    /// The line variances, calibrated for χ², with the window's correlation.
    pub line_variance: Option<rbprops_check::GivenLineVariance>,
    /// [`FORCE_NOISE_MARGIN`] × the largest force-noise error over the excitations.
    pub resolution: Option<f64>,
    /// What was taken, for the notes.
    pub notes: Vec<String>,
}

/// What `model-check` takes from the FRF estimator: the line variances (calibrated for
/// χ², with the window's correlation), the size of the common error its force noise
/// makes, and the processing it did, which the nominal spec gets as known effects
/// (`exponential_window` at its τ, `record_truncation` at the record's length after the
/// trigger) so that the check does not look for them.
pub fn for_model_check(
    rec: &RunRecord,
    spec: &mut rbprops_sim::CampaignSpec,
) -> Result<EstimatorKnowledge> {
    let (line_variance, notes) = variance_for_check(rec, spec)?;
    use rbprops_core::records::{ProcessingRecord, PROCESSING_TOPIC};
    let processing: ProcessingRecord = rec.get_one(PROCESSING_TOPIC)?.unwrap_or_default();
    let resolution = processing.frf_estimation.as_ref().map(|e| {
        FORCE_NOISE_MARGIN
            * e.averages
                .iter()
                .map(|a| a.force_noise_relative_error)
                .fold(0.0, f64::max)
    });
    Ok(EstimatorKnowledge {
        line_variance,
        resolution,
        notes,
    })
}

fn variance_for_check(
    rec: &RunRecord,
    spec: &mut rbprops_sim::CampaignSpec,
) -> Result<(Option<rbprops_check::GivenLineVariance>, Vec<String>)> {
    use rbprops_core::records::{ProcessingRecord, PROCESSING_TOPIC};
    let processing: ProcessingRecord = rec.get_one(PROCESSING_TOPIC)?.unwrap_or_default();
    let mut notes = Vec::new();
    let estimation = processing.frf_estimation.as_ref();
    if let Some(est) = estimation {
        let record_s = est.record_samples as f64 / est.sample_rate_hz - est.pretrigger_s;
        let mut known = vec![rbprops_sim::spec::EffectSpec {
            id: RecordTruncation::ID.into(),
            parameters: toml::Table::from_iter([("record_length_s".to_string(), record_s.into())]),
        }];
        if let Some(tau) = est.exponential_window_s {
            if !est.exponential_on_force {
                bail!("the FRFs were estimated with an exponential window on the response only: the model check models a window on force and response (estimate them again with the window on both)");
            }
            known.push(rbprops_sim::spec::EffectSpec {
                id: ExponentialWindow::ID.into(),
                parameters: toml::Table::from_iter([("time_constant_s".to_string(), tau.into())]),
            });
        }
        for k in known {
            if let Some(old) = spec.effects.iter().position(|e| e.id == k.id) {
                notes.push(format!(
                    "the spec's {} is replaced by the estimator's processing",
                    k.id
                ));
                spec.effects.remove(old);
            }
            notes.push(format!(
                "known from the FRF estimator: {} {}",
                k.id,
                toml::Value::Table(k.parameters.clone())
            ));
            spec.effects.push(k);
        }
    }
    let Some(v) = get(rec)? else {
        return Ok((None, notes));
    };
    let used = v.sigma2.iter().filter(|x| **x > 0.0).count().max(1);
    // frf-est pools each variance over 2L + 1 lines; an export's are the lines' own.
    let pool = if estimation.is_some() {
        (2 * POOL_HALF_WIDTH + 1) as f64
    } else {
        1.0
    };
    let given = rbprops_check::GivenLineVariance {
        sigma2: v
            .calibrated_for_chi2()
            .iter()
            .map(|x| if x.is_finite() { *x } else { 0.0 })
            .collect(),
        window_time_constant_s: estimation.and_then(|e| e.exponential_window_s),
        // Each pool's σ² has d degrees (relative SE √(2/d)); the scale of all of them
        // averages over the independent pools.
        variance_scale_se: (2.0 / v.min_degrees_of_freedom() * pool / used as f64)
            .sqrt()
            .hypot(v.correction_se()),
        source: if estimation.is_some() {
            format!(
                "{}: H1 line variance |Ĥ|²(1 − γ²)/((n_d − 1)γ²) pooled over {} lines, at least {:.0} degrees of freedom d, scaled by 1 + 2/d",
                topics::FRF_VARIANCE,
                2 * POOL_HALF_WIDTH + 1,
                v.min_degrees_of_freedom()
            )
        } else {
            format!(
                "{}: line variance |Ĥ|²(1 − γ²)/(n_d γ²) from the export's coherence and its declared averages (Bendat & Piersol), {:.0} degrees of freedom d, scaled by 1 + 2/d",
                topics::FRF_VARIANCE,
                v.min_degrees_of_freedom()
            )
        },
    };
    Ok((Some(given), notes))
}
