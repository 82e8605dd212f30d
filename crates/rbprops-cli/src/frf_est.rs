//! `frf-est`: FRFs from impact time histories (UFF 58, function type 1), with each hit
//! checked, each line's variance and the processing recorded for the stages after it.
//! The numerics are `rbprops-frfest`'s; this module sorts the records
//! (`rbprops_uff::timehist`), runs the chain per excitation and builds the run record
//! through the same UFF mapping an FRF export takes (units, DOFs, set-ups).

use crate::samples::SampleSource;
use anyhow::{bail, Context, Result};
use rayon::prelude::*;
use rbprops_core::records::{
    ExcitationAveragesRecord, ForceWindowRecord, FrfEstimationRecord, HitRecord, ProcessingRecord,
    PROCESSING_TOPIC,
};
use rbprops_core::{c64, FrfSet};
use rbprops_formats::RunRecord;
use rbprops_frfest::{
    ConditioningOptions, Estimator, ForceNoiseBins, ForceWindow, HitCheckOptions, HitReport,
    HitWindows, RejectReason, ResponseWindow, SpectralSums, TriggerLevel, TriggerOptions,
};
use rbprops_uff::timehist::{self, EstimatedFrfs, HitLayout, TimeHistoryIndex};
use rbprops_uff::UffFile;
use std::borrow::Cow;

/// Lines pooled on each side for each line's variance (only the noise power is pooled;
/// the line's own force spectrum divides it: `rbprops_frfest::smoothed_variance`).
pub const POOL_HALF_WIDTH: usize = crate::variance::POOL_HALF_WIDTH;

/// Retriggers within this time of a hit are not counted when the hit spacing sets the
/// record length of throughput records (double hits come 0.5–20 ms after the first).
const HIT_SPACING_HOLDOFF_S: f64 = 0.25;

/// The response window asked for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum WindowChoice {
    /// Rectangular (none).
    None,
    /// Exponential with this τ (s), from the trigger.
    Exponential(f64),
    /// Exponential with the τ that brings the slowest-decaying response to about 1 % of
    /// its peak at the record's end (`rbprops_frfest::auto_tau`, the smallest over every
    /// accepted hit and channel); none when every response has decayed already.
    Auto,
}

/// Options of [`estimate_uff`]; `Default` gives the documented defaults.
#[derive(Debug, Clone)]
pub struct EstimationOptions {
    /// H1 (default), H2 or Hv.
    pub estimator: Estimator,
    /// Trigger level on |force| (default 10 % of the record's largest).
    pub trigger: TriggerLevel,
    /// Throughput records: time kept before each trigger (s; default 0.05 of the record).
    pub pretrigger_s: Option<f64>,
    /// Throughput records: the hit record's length (s; default: the shortest spacing of
    /// consecutive triggers).
    pub record_s: Option<f64>,
    /// Force window: time kept before the trigger and after the pulse's end (s), taper (s).
    pub force_window: Option<ForceWindow>,
    /// The response window.
    pub response_window: WindowChoice,
    /// The exponential window on the force as well (so `H_w(ω) = H(iω + 1/τ)`).
    pub exponential_on_force: bool,
    /// The force channel's ADC range (± file units), if known; else flat tops are looked for.
    pub force_range: Option<f64>,
    /// The response channels' ADC range (± file units), if known.
    pub response_range: Option<f64>,
    /// Fewest accepted hits per excitation (≥ 2: a variance needs two).
    pub min_hits: usize,
    /// The band kept (Hz); default from the force spectrum (module docs of [`band_lines`]).
    pub band_hz: Option<(f64, f64)>,
    /// Average rejected hits anyway (their reasons stay in the table).
    pub keep_rejected: bool,
    /// Force DOFs `(node, direction)` named by the user.
    pub force_dofs: Vec<(i64, i64)>,
}

impl Default for EstimationOptions {
    fn default() -> Self {
        EstimationOptions {
            estimator: Estimator::H1,
            trigger: TriggerLevel::FractionOfMax(0.1),
            pretrigger_s: None,
            record_s: None,
            force_window: Some(ForceWindow {
                pre_s: 0.01,
                post_s: 0.05,
                taper_s: 0.0,
            }),
            response_window: WindowChoice::Auto,
            exponential_on_force: true,
            force_range: None,
            response_range: None,
            min_hits: 2,
            band_hz: None,
            keep_rejected: false,
            force_dofs: Vec::new(),
        }
    }
}

/// One hit: where its samples are and what the checks found. The samples are read from
/// the [`SampleSource`] when they are needed (the checks, then the average) and let go,
/// so the recording is held at most a hit per thread beside the spectral sums.
struct Hit {
    number: usize,
    /// `None` for a hit cut by the record's edge (no samples to average).
    records: Option<HitRecords>,
    report: HitReport,
    /// The smallest `rbprops_frfest::auto_tau` over the hit's responses (when the window
    /// is `auto`).
    tau_bound: Option<f64>,
}

impl Hit {
    fn accepted(&self, keep_rejected: bool) -> bool {
        keep_rejected || self.report.accepted()
    }
}

/// A hit's records: dataset indices of the force and the responses, and the hit's
/// stretch of them (`None`: the whole record, the per-hit layout).
struct HitRecords {
    force: usize,
    responses: Vec<usize>,
    range: Option<std::ops::Range<usize>>,
}

/// A hit's force and response samples.
type HitSamples<'a> = (Cow<'a, [f64]>, Vec<Cow<'a, [f64]>>);

impl HitRecords {
    fn load<'a>(&self, data: &'a UffFile, src: &'a dyn SampleSource) -> Result<HitSamples<'a>> {
        let force = src.record(data, self.force, self.range.clone())?;
        Ok((force, self.responses(data, src)?))
    }

    /// The responses only (the throughput checks hold the force record already).
    fn responses<'a>(
        &self,
        data: &'a UffFile,
        src: &'a dyn SampleSource,
    ) -> Result<Vec<Cow<'a, [f64]>>> {
        self.responses
            .iter()
            .map(|&i| src.record(data, i, self.range.clone()))
            .collect()
    }
}

/// The outcome of [`estimate_uff`].
pub struct Estimated {
    /// The run: geometry, FRFs, coherence, line variances, processing.
    pub record: RunRecord,
    /// One line for stderr.
    pub summary: String,
    /// Notes from the UFF mapping and the estimation.
    pub warnings: Vec<String>,
    /// Bytes of the side files read (geometry, channel map), for the input's digest.
    pub side_digest: Vec<u8>,
}

/// Wall time of each phase of [`estimate_uff_timed`], in order (for the phase bench,
/// `benches/frfest_phases.rs`).
#[derive(Debug, Default)]
pub struct PhaseTimes {
    /// `(phase, seconds)`.
    pub phases: Vec<(&'static str, f64)>,
    last: Option<std::time::Instant>,
}

impl PhaseTimes {
    /// Ends the phase running since the last call (or since `start`).
    pub fn lap(&mut self, phase: &'static str) {
        let now = std::time::Instant::now();
        let since = self.last.unwrap_or(now);
        self.phases.push((phase, (now - since).as_secs_f64()));
        self.last = Some(now);
    }
    /// Starts timing.
    pub fn start(&mut self) {
        self.last = Some(std::time::Instant::now());
    }
}

/// FRFs from the time histories of a parsed universal file (module docs), each record's
/// samples read from `samples` (the file itself, or where the reader set them aside) a
/// hit at a time. Samples held in `data` are let go once the hits are averaged (`data`
/// keeps every header), so the output is not built beside the recording.
pub fn estimate_uff(
    data: &mut UffFile,
    samples: &dyn SampleSource,
    uff_opts: &crate::UffInputOptions,
    opts: &EstimationOptions,
) -> Result<Estimated> {
    estimate_uff_timed(data, samples, uff_opts, opts, &mut PhaseTimes::default())
}

/// [`estimate_uff`], timing its phases into `times`. The excitations are independent
/// until the band is chosen: their hit checks, spectral sums and estimates run in
/// parallel (rayon), each excitation's own arithmetic in a fixed order, so the output is
/// the same whatever the number of threads.
pub fn estimate_uff_timed(
    data: &mut UffFile,
    samples: &dyn SampleSource,
    uff_opts: &crate::UffInputOptions,
    opts: &EstimationOptions,
    times: &mut PhaseTimes,
) -> Result<Estimated> {
    times.start();
    let index = timehist::index_time_histories(
        data,
        &timehist::TimeOptions {
            force_dofs: opts.force_dofs.clone(),
        },
    )?;
    let fs = index.sample_rate_hz;
    times.lap("index");
    let (hits, n) = checked_hits(&*data, samples, &index, opts)?;
    times.lap("hit checks");
    let tau = match opts.response_window {
        WindowChoice::None => None,
        WindowChoice::Exponential(t) => Some(t),
        WindowChoice::Auto => auto_tau(&hits, fs, n, opts.keep_rejected),
    };
    let response_window = tau.map_or(ResponseWindow::None, |tau_s| ResponseWindow::Exponential {
        tau_s,
    });
    times.lap("window τ");
    let averaged: Vec<Averaged> = hits
        .par_iter()
        .map(|hs| average(hs, (&*data, samples), (fs, n), opts, &response_window))
        .collect::<Result<_>>()?;
    times.lap("windows, FFT, spectral sums");
    // The samples are no longer needed (only the records' headers are), and the output's
    // buffers should not sit beside a recording held in memory.
    release_samples(data);
    let data = &*data;
    let sums: Vec<&SpectralSums> = averaged.iter().map(|a| &a.sums).collect();
    let band = band_lines(&sums, opts.band_hz, fs)?;
    let gamma = line_correlation(tau, fs, n);
    let per_excitation: Vec<ExcitationEstimate> = averaged
        .par_iter()
        .zip(&hits)
        .zip(&index.excitations)
        .map(|((s, hs), ex)| {
            let chain = Chain {
                band: band.clone(),
                gamma: &gamma,
                opts,
            };
            estimate_excitation(s, hs, &chain).with_context(|| {
                format!(
                    "{}: excitation {}:{}",
                    data.file_name,
                    ex.force_dof.0,
                    dir_name(ex.force_dof.1)
                )
            })
        })
        .collect::<Result<_>>()?;
    drop(averaged);
    times.lap("H1, coherence, variances");
    let Split {
        frfs: estimates,
        variances,
        dof,
        common,
        mut averages,
    } = split_estimates(per_excitation);
    let step = fs / n as f64;
    let synthetic = timehist::frf_file(data, &index, estimates, band.start as f64 * step, step);
    let (campaign, side_digest) = crate::uff_campaign_of(&synthetic, uff_opts)?;
    let sigma2 = variance_in_si((data, &synthetic), &index, &variances, &campaign)?;
    // The output is built from here on: what it no longer needs is let go first.
    drop((synthetic, variances));
    times.lap("UFF mapping to SI");
    let mut record = RunRecord::default();
    record.set_geometry(&campaign.geometry);
    if let Some(coh) = &campaign.coherence {
        crate::coherence::set(&mut record, &campaign.geometry, coh);
    }
    // The campaign's excitation ids (tags, set-ups) replace the force DOFs in the tables.
    let names = campaign_ids(data, &index, &campaign);
    let min_dof = dof.iter().fold(f64::INFINITY, |m: f64, &d| m.min(d));
    if min_dof.is_finite() {
        let set = crate::variance::LineVarianceSet {
            sigma2,
            degrees_of_freedom: in_campaign_order(&dof, &names, &campaign.geometry, f64::INFINITY),
            common: in_campaign_order(&common, &names, &campaign.geometry, None),
        };
        crate::variance::set(&mut record, &campaign.geometry, &campaign.frf, &set);
    }
    for (a, id) in averages.iter_mut().zip(&names) {
        a.excitation = id.clone();
    }
    let processing = processing_record(
        &hits,
        &names,
        &averages,
        &Processed {
            fs,
            n,
            tau,
            gamma: &gamma,
            min_dof,
        },
        opts,
    );
    record.set(PROCESSING_TOPIC, std::slice::from_ref(&processing));
    let summary = summary_line(&hits, &averages, tau, opts, &campaign.frf);
    record.frf = Some(campaign.frf);
    times.lap("run record");
    Ok(Estimated {
        record,
        summary,
        warnings: campaign.warnings,
        side_digest,
    })
}

/// What the estimate settled that the processing topic records: the sampling, the hit
/// record's length, τ, the window's line correlation and the fewest degrees of freedom.
struct Processed<'a> {
    fs: f64,
    n: usize,
    tau: Option<f64>,
    gamma: &'a [c64],
    min_dof: f64,
}

/// The processing topic of an estimate: estimator, sampling, record, windows, averages,
/// line correlation, the variance's method and every hit's verdict.
fn processing_record(
    hits: &[Vec<Hit>],
    names: &[String],
    averages: &[ExcitationAveragesRecord],
    p: &Processed,
    opts: &EstimationOptions,
) -> ProcessingRecord {
    ProcessingRecord {
        exponential_window_s: p.tau,
        line_weighting: None,
        frf_estimation: Some(FrfEstimationRecord {
            estimator: format!("{:?}", opts.estimator),
            sample_rate_hz: p.fs,
            record_samples: p.n,
            pretrigger_s: pretrigger_s(hits, p.fs, opts.keep_rejected),
            force_window: opts.force_window.map(|w| ForceWindowRecord {
                start_s: -w.pre_s,
                end_s: w.post_s,
                taper_s: w.taper_s,
            }),
            exponential_window_s: p.tau,
            exponential_on_force: opts.exponential_on_force,
            averages: averages.to_vec(),
            line_correlation: p.gamma.iter().map(|g| [g.re, g.im]).collect(),
            variance_method: format!(
                "{:?}: noise power R = S_xx(1 − γ²) pooled over ±{POOL_HALF_WIDTH} lines, over (n_d − 1) S_ff of the line; {:.0} degrees of freedom at least",
                opts.estimator, p.min_dof
            ),
            hits: hit_records(hits, names, p.fs, p.n, opts),
        }),
    }
}

/// Every excitation's hits, checked, and the record length; an excitation with fewer
/// than `min_hits` accepted is an error listing its rejections.
fn checked_hits(
    data: &UffFile,
    samples: &dyn SampleSource,
    index: &TimeHistoryIndex,
    opts: &EstimationOptions,
) -> Result<(Vec<Vec<Hit>>, usize)> {
    if opts.min_hits < 2 {
        bail!(
            "--min-hits {}: at least 2 hits are needed for a variance",
            opts.min_hits
        );
    }
    let fs = index.sample_rate_hz;
    let (n, pre) = record_samples(data, samples, index, opts)?;
    let hits: Vec<Vec<Hit>> = index
        .excitations
        .par_iter()
        .map(|ex| excitation_hits((data, samples), ex, fs, (n, pre), opts))
        .collect::<Result<_>>()?;
    for (hs, ex) in hits.iter().zip(&index.excitations) {
        let ok = hs.iter().filter(|h| h.accepted(opts.keep_rejected)).count();
        if ok < opts.min_hits {
            bail!(
                "{}: excitation {}:{}: {ok} of {} hits accepted, {} needed: {}",
                data.file_name,
                ex.force_dof.0,
                dir_name(ex.force_dof.1),
                hs.len(),
                opts.min_hits,
                rejections(hs)
            );
        }
    }
    Ok((hits, n))
}

/// What the estimate of every excitation shares: the band, the window's line
/// correlation, the sampling, the options.
struct Chain<'a> {
    band: std::ops::Range<usize>,
    gamma: &'a [c64],
    opts: &'a EstimationOptions,
}

/// One excitation's FRFs (file units), pooled variances, their degrees of freedom and
/// its row of the averages table.
struct ExcitationEstimate {
    frfs: EstimatedFrfs,
    variance: Option<Vec<f64>>,
    dof: f64,
    /// The force noise's error common to the responses (with the variance only).
    common: Option<rbprops_core::CommonRelativeError>,
    averages: ExcitationAveragesRecord,
}

fn estimate_excitation(a: &Averaged, hs: &[Hit], c: &Chain) -> Result<ExcitationEstimate> {
    let est = a.sums.estimate(
        c.opts.estimator,
        Some(c.band.clone()),
        &ConditioningOptions::default(),
    )?;
    let pooled = rbprops_frfest::smoothed_variance(&est, POOL_HALF_WIDTH, Some(c.gamma));
    let q = rbprops_frfest::quality(&est);
    let averages = ExcitationAveragesRecord {
        excitation: String::new(),
        accepted: est.n_averages,
        rejected: hs.len() - est.n_averages,
        relative_standard_error: q.map_or(f64::NAN, |q| q.relative_se),
        hits_to_halve: 4 * est.n_averages,
        force_noise_relative_error: force_noise_error(a, c.band.clone()),
    };
    let dof = pooled.as_ref().map_or(f64::INFINITY, |p| {
        p.dof.iter().fold(f64::INFINITY, |m, &d| m.min(d))
    });
    Ok(ExcitationEstimate {
        frfs: EstimatedFrfs {
            frf: (0..est.n_resp).map(|o| est.frf(o, 0).to_vec()).collect(),
            coherence: Some(
                (0..est.n_resp)
                    .map(|o| est.coherence_of(o).to_vec())
                    .collect(),
            ),
        },
        common: pooled
            .as_ref()
            .and_then(|_| common_force_error(a, c.band.clone())),
        variance: pooled.map(|p| p.variance),
        dof,
        averages,
    })
}

/// The excitations' estimates, each part in its own list (moved, not copied).
struct Split {
    frfs: Vec<EstimatedFrfs>,
    variances: Vec<Option<Vec<f64>>>,
    dof: Vec<f64>,
    common: Vec<Option<rbprops_core::CommonRelativeError>>,
    averages: Vec<ExcitationAveragesRecord>,
}

fn split_estimates(per_excitation: Vec<ExcitationEstimate>) -> Split {
    let mut out = Split {
        frfs: Vec::new(),
        variances: Vec::new(),
        dof: Vec::new(),
        common: Vec::new(),
        averages: Vec::new(),
    };
    for e in per_excitation {
        out.frfs.push(e.frfs);
        out.variances.push(e.variance);
        out.dof.push(e.dof);
        out.common.push(e.common);
        out.averages.push(e.averages);
    }
    out
}

/// Per-excitation values (index order, named `names`) in the geometry's excitation order.
/// (`missing` where the index has none).
fn in_campaign_order<T: Clone>(
    values: &[T],
    names: &[String],
    g: &rbprops_core::Geometry,
    missing: T,
) -> Vec<T> {
    let mut out = vec![missing; g.excitations.len()];
    for (v, id) in values.iter().zip(names) {
        if let Some(ce) = g.excitations.iter().position(|x| &x.id == id) {
            out[ce] = v.clone();
        }
    }
    out
}

/// The pretrigger (s): the earliest trigger of an averaged hit.
fn pretrigger_s(hits: &[Vec<Hit>], fs: f64, keep_rejected: bool) -> f64 {
    hits.iter()
        .flatten()
        .filter(|h| h.accepted(keep_rejected))
        .map(|h| h.report.trigger as f64 / fs)
        .fold(f64::INFINITY, f64::min)
}

/// The campaign's id of each excitation of the index (through the dataset of its first
/// response's FRF).
fn campaign_ids(
    data: &UffFile,
    index: &TimeHistoryIndex,
    campaign: &rbprops_uff::UffCampaign,
) -> Vec<String> {
    let nch = campaign.frf.n_channels;
    index
        .excitations
        .iter()
        .map(|ex| {
            let template = ex.template();
            let at = &data.datasets[template.responses[0]].location;
            campaign
                .frf_locations
                .iter()
                .position(|l| l == at)
                .map(|cell| campaign.geometry.excitations[cell / nch].id.clone())
                .unwrap_or_else(|| format!("{}:{}", ex.force_dof.0, dir_name(ex.force_dof.1)))
        })
        .collect()
}

fn dir_name(d: i64) -> String {
    match d {
        1 => "+X".into(),
        -1 => "-X".into(),
        2 => "+Y".into(),
        -2 => "-Y".into(),
        3 => "+Z".into(),
        -3 => "-Z".into(),
        d => d.to_string(),
    }
}

/// Samples per hit record and the pretrigger (s): the file's records in the per-hit
/// layout; for throughput records the options, or the shortest spacing of consecutive
/// triggers on any excitation and 5 % of it (less when the first trigger comes earlier).
fn record_samples(
    data: &UffFile,
    samples: &dyn SampleSource,
    index: &TimeHistoryIndex,
    opts: &EstimationOptions,
) -> Result<(usize, f64)> {
    let fs = index.sample_rate_hz;
    let per_hit = index
        .excitations
        .iter()
        .all(|e| matches!(e.layout, HitLayout::PerHit(_)));
    if per_hit {
        return Ok((index.record_samples, 0.0));
    }
    let mut spacing = usize::MAX;
    let mut first = usize::MAX;
    for e in &index.excitations {
        let HitLayout::Throughput(h) = &e.layout else {
            continue;
        };
        let force = samples.record(data, h.force, None)?;
        let t = rbprops_frfest::find_hits(
            &force,
            fs,
            &TriggerOptions {
                level: opts.trigger,
                pretrigger_s: 0.0,
                record_len_samples: 1,
                holdoff_s: Some(HIT_SPACING_HOLDOFF_S),
            },
        );
        first = first.min(t.first().map_or(usize::MAX, |t| t.index));
        for w in t.windows(2) {
            spacing = spacing.min(w[1].index - w[0].index);
        }
    }
    if let Some(t) = opts.record_s {
        spacing = (t * fs).round() as usize;
        if !(t.is_finite() && spacing >= 16 && spacing <= index.record_samples) {
            bail!(
                "--record-s {t}: must give between 16 samples and the throughput record's {:.6} s",
                index.record_samples as f64 / fs
            );
        }
    }
    let pre = opts
        .pretrigger_s
        .unwrap_or_else(|| (0.05 * spacing as f64).min(first as f64).floor() / fs);
    if spacing == usize::MAX {
        bail!(
            "{}: fewer than two hits in every throughput record: give the hit record's length with --record-s",
            data.file_name
        );
    }
    Ok((spacing, pre))
}

/// The hits of one excitation, each checked (its samples read and let go).
fn excitation_hits(
    (data, src): (&UffFile, &dyn SampleSource),
    ex: &timehist::ExcitationRecords,
    fs: f64,
    (n, pre): (usize, f64),
    opts: &EstimationOptions,
) -> Result<Vec<Hit>> {
    let check = HitCheckOptions {
        trigger: opts.trigger,
        force_range: opts.force_range,
        response_ranges: vec![opts.response_range; ex.responses.len()],
        ..Default::default()
    };
    let auto = matches!(opts.response_window, WindowChoice::Auto);
    let inspect =
        |number: usize, records: Option<HitRecords>, force: &[f64], responses: &[Cow<[f64]>]| {
            let refs: Vec<&[f64]> = responses.iter().map(|r| r.as_ref()).collect();
            let report = rbprops_frfest::inspect_hit(force, &refs, fs, &check);
            let tau_bound = refs
                .iter()
                .filter(|_| auto)
                .filter_map(|r| rbprops_frfest::auto_tau(r, fs, report.trigger))
                .reduce(f64::min);
            Hit {
                number,
                records,
                report,
                tau_bound,
            }
        };
    match &ex.layout {
        HitLayout::PerHit(hits) => hits
            .iter()
            .map(|h| {
                let records = HitRecords {
                    force: h.force,
                    responses: h.responses.clone(),
                    range: None,
                };
                let (force, responses) = records.load(data, src)?;
                Ok(inspect(h.hit, Some(records), &force, &responses))
            })
            .collect(),
        HitLayout::Throughput(h) => {
            let force = src.record(data, h.force, None)?;
            let triggers = rbprops_frfest::find_hits(
                &force,
                fs,
                &TriggerOptions {
                    level: opts.trigger,
                    pretrigger_s: pre,
                    record_len_samples: n,
                    holdoff_s: None,
                },
            );
            triggers
                .iter()
                .enumerate()
                .map(|(k, t)| match t.range(n) {
                    Some(r) => {
                        let records = HitRecords {
                            force: h.force,
                            responses: h.responses.clone(),
                            range: Some(r.clone()),
                        };
                        let responses = records.responses(data, src)?;
                        Ok(inspect(k + 1, Some(records), &force[r], &responses))
                    }
                    None => {
                        let zeros = vec![Cow::Owned(vec![0.0; n]); h.responses.len()];
                        let mut hit = inspect(k + 1, None, &vec![0.0; n], &zeros);
                        hit.report.reasons = vec![RejectReason::AtRecordEdge];
                        Ok(hit)
                    }
                })
                .collect()
        }
    }
}

/// Frees the samples of every time record (their headers stay, for the FRF datasets
/// made from them).
fn release_samples(data: &mut UffFile) {
    for d in &mut data.datasets {
        if let rbprops_uff::Record::Function(f) = &mut d.record {
            f.samples = Vec::new();
        }
    }
}

/// The automatic τ: the window itself falls to 1 % by the record's end (τ = T/ln 100,
/// T from the earliest trigger), or faster where a response has not decayed to 1 % of its
/// peak by then (`rbprops_frfest::auto_tau`, the smallest over every accepted hit and
/// channel). Why not "none" when the responses have decayed to 1 % of their peak: an
/// accelerance's peak is the impact's direct response, far above the slow rigid modes'
/// ringing, and the ringing left at the end leaks. Measured on Test Case II through the
/// independent generator (32 s records, five hits): no window 1.6 % mass error, τ = 20 s
/// 0.08 %, τ = 8 s 0.04 %, τ = 4 s 0.01 % (`modal-fit` removes the window's damping).
fn auto_tau(hits: &[Vec<Hit>], fs: f64, n: usize, keep_rejected: bool) -> Option<f64> {
    let accepted = || hits.iter().flatten().filter(|h| h.accepted(keep_rejected));
    let t0 = accepted().map(|h| h.report.trigger).min()?;
    let record = (n - 1).saturating_sub(t0) as f64 / fs;
    Some(
        accepted()
            .filter_map(|h| h.tau_bound)
            .fold(record / 100f64.ln(), f64::min),
    )
    .filter(|t| *t > 0.0)
}

/// One excitation's accepted hits averaged: the spectral sums of the windowed records and
/// the mean over the hits of `σ_m² Σw_f²`, the force noise's energy through its window
/// (σ_m from each hit's pretrigger).
struct Averaged {
    sums: SpectralSums,
    force_noise_energy: f64,
    /// The force noise's binned window (`rbprops_frfest::ForceNoiseBins`): times from the
    /// pulse centroid and weights.
    force_noise_window: Option<(Vec<f64>, Vec<f64>)>,
}

impl Averaged {
    /// `ρ² = E_N/S_ff` at line k: the variance of the relative error the force noise puts
    /// into every FRF of the excitation (docs/conventions.md, FRF estimation).
    fn force_noise_rho2(&self, k: usize) -> f64 {
        self.force_noise_energy / self.sums.sff(k, 0, 0).re
    }
}

/// A hit cut by the record's edge has no samples and is never averaged, even with
/// `--keep-rejected`.
fn average(
    hits: &[Hit],
    (data, src): (&UffFile, &dyn SampleSource),
    (fs, n): (f64, usize),
    opts: &EstimationOptions,
    response_window: &ResponseWindow,
) -> Result<Averaged> {
    let n_resp = hits
        .iter()
        .find_map(|h| h.records.as_ref())
        .map_or(0, |r| r.responses.len());
    let mut sums = SpectralSums::new(n, fs, 1, n_resp)?;
    let mut w = HitWindows::new(n);
    let mut energy = 0.0;
    let mut bins: Option<ForceNoiseBins> = None;
    for h in hits.iter().filter(|h| h.accepted(opts.keep_rejected)) {
        let Some(records) = &h.records else { continue };
        let (force, responses) = records.load(data, src)?;
        w.set(
            fs,
            h.report.trigger,
            h.report.pulse_end,
            opts.force_window.as_ref(),
            response_window,
            opts.exponential_on_force,
        );
        let refs: Vec<&[f64]> = responses.iter().map(|r| r.as_ref()).collect();
        sums.add_windowed_hit(&[force.as_ref()], &refs, Some(&w.force), Some(&w.response))?;
        let noise_var = h.report.noise_rms.powi(2);
        energy += noise_var * w.force.iter().map(|x| x * x).sum::<f64>();
        if let Some(centroid) = rbprops_frfest::pulse_centroid(&force, &w.force) {
            let bins = bins.get_or_insert_with(|| {
                let first = w.force.iter().position(|&x| x != 0.0).unwrap_or(0);
                let last = w.force.iter().rposition(|&x| x != 0.0).unwrap_or(0);
                ForceNoiseBins::new(fs, (last + 1 - first) as f64 / fs)
            });
            bins.add_hit(&w.force, noise_var, centroid, fs);
        }
    }
    let force_noise_energy = energy / sums.count().max(1) as f64;
    Ok(Averaged {
        sums,
        force_noise_energy,
        force_noise_window: bins.and_then(|b| b.finish()),
    })
}

/// The error the force channel's noise puts into every FRF of the excitation alike over
/// `band` (`rbprops_core::CommonRelativeError`): `ρ² = E_N/S_ff` per line with the hits'
/// mean noise energy through the window, and the window's binned energy. None without
/// force noise (or a single reference: the MIMO error is a matrix, not a common factor).
fn common_force_error(
    a: &Averaged,
    band: std::ops::Range<usize>,
) -> Option<rbprops_core::CommonRelativeError> {
    let (times_s, weights) = a.force_noise_window.clone()?;
    if a.sums.n_refs() != 1 || !(a.force_noise_energy > 0.0) {
        return None;
    }
    Some(rbprops_core::CommonRelativeError {
        relative_variance: band.map(|k| a.force_noise_rho2(k)).collect(),
        times_s,
        weights,
    })
}

/// RMS over `band` of `√(σ_m² Σw_f²/S_ff,k)`: the relative error the force channel's
/// noise puts into H1 at line k (`Σ_d |F_d|² σ_m² Σw² / S_ff²` with the hits' mean noise
/// energy; records.rs, `force_noise_relative_error`).
fn force_noise_error(a: &Averaged, band: std::ops::Range<usize>) -> f64 {
    if band.is_empty() {
        return 0.0;
    }
    let mean: f64 = band.clone().map(|k| a.force_noise_rho2(k)).sum::<f64>() / band.len() as f64;
    mean.sqrt()
}

/// The lines kept, common to every excitation: `--band`, or from line 1 (0 Hz left out:
/// no rigid-body information an accelerance can carry) to the first line where the mean
/// force autospectrum has fallen 20 dB below its largest value (a hammer's useful band),
/// at most 0.4 f_s (an anti-alias filter's pass band).
pub fn band_lines(
    sums: &[&SpectralSums],
    band_hz: Option<(f64, f64)>,
    fs: f64,
) -> Result<std::ops::Range<usize>> {
    let df = sums[0].line_spacing_hz();
    let lines = sums[0].lines();
    if let Some((lo, hi)) = band_hz {
        // 0 Hz never: no rigid-body information an accelerance carries, and a mean
        // (offset) in the records puts anything there.
        let a = (lo / df).ceil().max(1.0) as usize;
        let b = ((hi / df).floor() as usize + 1).min(lines);
        if !(lo.is_finite() && hi.is_finite() && lo < hi) || b <= a + 8 {
            bail!(
                "--band {lo}:{hi}: must hold more than 8 lines of the {df} Hz spacing within 0–{} Hz",
                (lines - 1) as f64 * df
            );
        }
        return Ok(a..b);
    }
    let top = ((0.4 * fs / df).floor() as usize).min(lines - 1);
    let mut end = top + 1;
    for s in sums {
        let g: Vec<f64> = (0..=top).map(|k| s.sff(k, 0, 0).re).collect();
        let peak = g.iter().fold(0.0f64, |m, &v| m.max(v));
        if let Some(k) = g.iter().position(|&v| v < 0.01 * peak) {
            end = end.min(k);
        }
    }
    if end <= 9 {
        bail!("the force spectrum falls 20 dB below its peak within {} lines: a band cannot be chosen; give --band", end);
    }
    Ok(1..end)
}

/// γ_m (m = 0..=2L) of the exponential window (`rbprops_frfest::exponential_line_correlation`),
/// or independent lines without one.
fn line_correlation(tau: Option<f64>, fs: f64, n: usize) -> Vec<c64> {
    (0..=2 * POOL_HALF_WIDTH)
        .map(|m| match tau {
            Some(t) => rbprops_frfest::exponential_line_correlation(t, fs, n, m),
            None => c64::new(if m == 0 { 1.0 } else { 0.0 }, 0.0),
        })
        .collect()
}

/// The pooled variances (file units) on the campaign's FRF layout in SI: each FRF's SI
/// scale is read off its values (`|H_SI|/|H_file|` at its largest line: the UFF mapping
/// multiplies each record by one real factor), squared.
fn variance_in_si(
    (data, synthetic): (&UffFile, &UffFile),
    index: &TimeHistoryIndex,
    variances: &[Option<Vec<f64>>],
    campaign: &rbprops_uff::UffCampaign,
) -> Result<Vec<f64>> {
    let frf = &campaign.frf;
    let nl = frf.n_lines();
    let mut sigma2 = vec![f64::NAN; frf.values.len()];
    for (cell, at) in campaign.frf_locations.iter().enumerate() {
        let found = index.excitations.iter().enumerate().find_map(|(e, ex)| {
            let template = ex.template();
            template
                .responses
                .iter()
                .position(|&i| data.datasets[i].location == *at)
                .map(|k| (e, k))
        });
        let Some((e, k)) = found else {
            bail!(
                "{}: {at}: estimated FRF without its time record",
                data.file_name
            );
        };
        let Some(v) = &variances[e] else { continue };
        let file = synthetic
            .datasets
            .iter()
            .find_map(|d| match &d.record {
                rbprops_uff::Record::Function(f) if f.function_type == 4 && d.location == *at => {
                    Some(&f.ordinate)
                }
                _ => None,
            })
            .expect("frf_file writes each estimate at its response record's location");
        let si = &frf.values[cell * nl..(cell + 1) * nl];
        let j = (0..nl)
            .max_by(|&a, &b| file[a].norm().total_cmp(&file[b].norm()))
            .unwrap_or(0);
        let scale = if file[j].norm() > 0.0 {
            si[j].norm() / file[j].norm()
        } else {
            0.0
        };
        for l in 0..nl {
            sigma2[cell * nl + l] = v[k * nl + l] * scale * scale;
        }
    }
    Ok(sigma2)
}

fn reason_text(r: &RejectReason) -> String {
    match r {
        RejectReason::DoubleHit { delay_s, ratio } => format!(
            "double hit ({:.1} ms later, {:.0} %)",
            1e3 * delay_s,
            100.0 * ratio
        ),
        RejectReason::Overload { channel, samples } => format!(
            "overload: {samples} samples at the range on {}",
            channel_name(channel)
        ),
        RejectReason::AtRecordEdge => "at the record's edge".into(),
        RejectReason::TooWeak { peak, min } => format!("too weak (peak {peak:.3e} < {min:.3e})"),
        RejectReason::NotFinite { .. } => "a non-finite sample".into(),
        RejectReason::LengthMismatch { .. } => "records of different lengths".into(),
    }
}

/// Why a hit was rejected, its overloads in one clause ("overload: 7 samples at the range
/// on the force, 5 on response 2").
fn hit_reasons(h: &Hit) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut overloads: Vec<String> = Vec::new();
    for r in &h.report.reasons {
        match r {
            RejectReason::Overload { channel, samples } if !overloads.is_empty() => {
                overloads.push(format!("{samples} on {}", channel_name(channel)));
            }
            _ if !matches!(r, RejectReason::Overload { .. }) => parts.push(reason_text(r)),
            _ => overloads.push(reason_text(r)),
        }
    }
    if !overloads.is_empty() {
        parts.push(overloads.join(", "));
    }
    parts.join("; ")
}

fn channel_name(c: &rbprops_frfest::Channel) -> String {
    match c {
        rbprops_frfest::Channel::Force => "the force".into(),
        rbprops_frfest::Channel::Response(i) => format!("response {}", i + 1),
    }
}

/// Every rejected hit of an excitation and why (the error when too few are left).
fn rejections(hits: &[Hit]) -> String {
    let v: Vec<String> = hits
        .iter()
        .filter(|h| !h.report.accepted())
        .map(|h| format!("hit {}: {}", h.number, hit_reasons(h)))
        .collect();
    if v.is_empty() {
        "none rejected".into()
    } else {
        v.join("; ")
    }
}

/// Hits listed by name in the summary line, per excitation; the rest are counted (the
/// hit table has them all).
const SUMMARY_HITS: usize = 3;

/// An excitation's rejections for the one summary line: how many and of which kind, the
/// first few by name.
fn rejections_brief(hits: &[Hit]) -> String {
    let rejected: Vec<&Hit> = hits.iter().filter(|h| !h.report.accepted()).collect();
    let mut kinds: Vec<(&str, usize)> = Vec::new();
    for h in &rejected {
        let mut seen: Vec<&str> = Vec::new();
        for r in &h.report.reasons {
            let kind = match r {
                RejectReason::DoubleHit { .. } => "double hit",
                RejectReason::Overload { .. } => "overload",
                RejectReason::AtRecordEdge => "at the edge",
                RejectReason::TooWeak { .. } => "too weak",
                _ => "bad samples",
            };
            if !seen.contains(&kind) {
                seen.push(kind);
                match kinds.iter_mut().find(|(k, _)| *k == kind) {
                    Some((_, c)) => *c += 1,
                    None => kinds.push((kind, 1)),
                }
            }
        }
    }
    let named: Vec<String> = rejected
        .iter()
        .take(SUMMARY_HITS)
        .map(|h| format!("hit {}: {}", h.number, hit_reasons(h)))
        .collect();
    let more = rejected.len().saturating_sub(SUMMARY_HITS);
    format!(
        "{} of {} ({}): {}{}",
        rejected.len(),
        hits.len(),
        kinds
            .iter()
            .map(|(k, c)| format!("{c} {k}"))
            .collect::<Vec<_>>()
            .join(", "),
        named.join("; "),
        if more > 0 {
            format!("; {more} more in the hit table (rbprops report)")
        } else {
            String::new()
        }
    )
}

fn hit_records(
    hits: &[Vec<Hit>],
    names: &[String],
    fs: f64,
    n: usize,
    opts: &EstimationOptions,
) -> Vec<HitRecord> {
    let mut out = Vec::new();
    for (hs, name) in hits.iter().zip(names) {
        for h in hs {
            let window = opts.force_window.map(|w| {
                let (a, b) = w.flat_part(fs, h.report.trigger, h.report.pulse_end, n);
                [a as f64 / fs, b as f64 / fs]
            });
            out.push(HitRecord {
                excitation: name.clone(),
                hit: h.number,
                accepted: h.accepted(opts.keep_rejected),
                reasons: h.report.reasons.iter().map(reason_text).collect(),
                trigger_s: h.report.trigger as f64 / fs,
                peak_force_n: h.report.peak_force,
                force_window_s: window,
                clipped_samples: h.report.clipped.clone(),
                double_hit_delay_s: h.report.double_hit.map(|d| d.delay_s),
                double_hit_ratio: h.report.double_hit.map(|d| d.ratio),
            });
        }
    }
    out
}

fn summary_line(
    hits: &[Vec<Hit>],
    averages: &[ExcitationAveragesRecord],
    tau: Option<f64>,
    opts: &EstimationOptions,
    frf: &FrfSet,
) -> String {
    let total: usize = hits.iter().map(|h| h.len()).sum();
    let used: usize = averages.iter().map(|a| a.accepted).sum();
    let worst = averages
        .iter()
        .map(|a| a.relative_standard_error)
        .fold(0.0f64, f64::max);
    let rejected: Vec<String> = hits
        .iter()
        .zip(averages)
        .filter(|(h, _)| h.iter().any(|h| !h.report.accepted()))
        .map(|(h, a)| format!("{} {}", a.excitation, rejections_brief(h)))
        .collect();
    format!(
        "frf-est: {:?} over {used} of {total} hits in {} excitation(s){}; window {}; {} lines {:.4}–{:.4} Hz; relative standard error up to {:.2} % (4× the hits to halve it){}",
        opts.estimator,
        averages.len(),
        if opts.keep_rejected { " (rejected hits kept)" } else { "" },
        match tau {
            Some(t) => format!("exponential τ = {t:.4} s"),
            None => "none".into(),
        },
        frf.n_lines(),
        frf.frequency_hz.first().copied().unwrap_or(0.0),
        frf.frequency_hz.last().copied().unwrap_or(0.0),
        100.0 * worst,
        if rejected.is_empty() {
            String::new()
        } else {
            format!("; rejected: {}", rejected.join("; "))
        }
    )
}
