//! `frf-est`: FRFs from impact time histories, the head of the pipeline for real tests
//! (the numerics are in `rbprops-frfest`, the orchestration in `rbprops_cli::frf_est`).

use anyhow::bail;
use clap::Parser;
use rbprops_cli::args::ForceWindowSpan;
use rbprops_cli::frf_est::{EstimationOptions, WindowChoice};
use rbprops_frfest::{Estimator, ForceWindow, TriggerLevel};
use std::path::PathBuf;

/// Estimate FRFs from impact time histories (UFF 58 function type 1: one record per hit
/// and channel, or continuous throughput records): trigger, double-hit and overload
/// checks with each hit's verdict, force and exponential windows, H1/H2/Hv over the
/// accepted hits, coherence and each line's variance. Writes the run (MCAP on stdout, or
/// -o FILE.mcap | DIR | FILE.uff) for modal-fit, model-check and the other stages.
#[derive(Parser)]
#[command(name = "frf-est", version, about)]
struct Args {
    /// The time histories: a universal file (.uff/.unv/.58/.58b), an MCAP file with the
    /// /rbprops/time_history topic, or a CSV directory (records.csv, channels.csv and one
    /// file per record; docs/formats.md).
    input: PathBuf,
    /// Output: FILE.mcap, FILE.uff, or a directory for CSV; default MCAP on stdout.
    #[arg(short, long)]
    output: Option<PathBuf>,
    #[command(flatten)]
    uff: rbprops_cli::UffArgs,
    /// The force channel's DOF, NODE:DIR (e.g. 201:-X or 201:-1), when record 9 does not
    /// say which records are forces (repeatable).
    #[arg(long = "force-dof", value_name = "NODE:DIR", value_parser = rbprops_cli::args::dof)]
    force_dofs: Vec<(i64, i64)>,
    #[arg(long, value_enum, default_value = "h1")]
    estimator: Estimator,
    /// Response window: `auto` (exponential decaying the slowest response to about 1 % at
    /// the record's end, or none if it has decayed), `none`, or τ in seconds.
    #[arg(long, default_value = "auto", value_parser = rbprops_cli::args::response_window)]
    window: WindowChoice,
    /// Apply the exponential window to the response only (default: force too, so the
    /// FRF is the transfer function at s = iω + 1/τ).
    #[arg(long)]
    window_response_only: bool,
    /// Force window PRE:POST (s before the trigger, s after the pulse's end), or `none`.
    #[arg(long, default_value = "0.01:0.05", value_parser = rbprops_cli::args::force_window)]
    force_window: ForceWindowSpan,
    /// Cosine taper outside the force window (s).
    #[arg(long, default_value_t = 0.0, value_parser = rbprops_cli::args::non_negative)]
    taper: f64,
    /// Trigger level as a fraction of the record's largest |force| (0–1).
    #[arg(long, default_value_t = 0.1, value_parser = rbprops_cli::args::trigger_fraction)]
    trigger: f64,
    /// Throughput records: time kept before each trigger (s; default 5 % of the record).
    #[arg(long, value_parser = rbprops_cli::args::duration)]
    pretrigger: Option<f64>,
    /// Throughput records: each hit's record length (s; default the shortest spacing of
    /// consecutive hits).
    #[arg(long, value_parser = rbprops_cli::args::duration)]
    record_s: Option<f64>,
    /// The force channel's ADC range (± in the file's unit); default: flat tops are looked for.
    #[arg(long, value_parser = rbprops_cli::args::positive)]
    force_range: Option<f64>,
    /// The response channels' ADC range (± in the file's unit).
    #[arg(long, value_parser = rbprops_cli::args::positive)]
    response_range: Option<f64>,
    /// Fewest accepted hits per excitation (at least 2: a variance needs two).
    #[arg(long, default_value_t = 2, value_parser = rbprops_cli::args::min_hits)]
    min_hits: usize,
    /// Band FMIN:FMAX (Hz) of the FRFs written (default: up to where the force spectrum
    /// has fallen 20 dB, at most 0.4 × the sampling rate; 0 Hz left out).
    #[arg(long, value_parser = rbprops_cli::args::band)]
    band: Option<(f64, f64)>,
    /// Average rejected hits as well (their reasons stay in the hit table).
    #[arg(long)]
    keep_rejected: bool,
    /// Write FRF magnitude plots (one SVG per excitation) into this directory.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// List every note on stderr (default: one summary line).
    #[arg(short, long)]
    verbose: bool,
    /// Write over an output path that is not a previous output of ours (never an input).
    #[arg(long)]
    force: bool,
}

fn main() -> std::process::ExitCode {
    rbprops_cli::return_large_buffers();
    rbprops_cli::run("frf-est", || {
        let args = Args::parse();
        rbprops_formats::atomic::set_force(args.force);
        let opts = options(&args);
        let name = args.input.display().to_string();
        let rbprops_cli::TimeHistories {
            mut data,
            samples,
            mut digest,
        } = rbprops_cli::read_time_histories(&args.input)?;
        if !rbprops_uff::timehist::has_time_histories(&data) {
            bail!(
                "{name}: no time histories (dataset 58 with function type 1). It holds:\n{}",
                rbprops_uff::inventory(&data)
            );
        }
        let est = rbprops_cli::frf_est::estimate_uff(
            &mut data,
            samples.as_ref(),
            &args.uff.options(),
            &opts,
        )?;
        digest.update(&est.side_digest);
        let mut rec = est.record;
        rec.push_provenance(rbprops_cli::provenance("frf-est", &digest.hex()))?;
        let mut notes = rbprops_cli::warnings::Collector::default();
        for d in rbprops_cli::input_notes(&est.warnings) {
            notes.add_from("frf-est", d);
        }
        notes.print(args.verbose);
        rbprops_cli::say!("{}", est.summary);
        if let Some(dir) = &args.plot {
            let (geometry, frf) = rec.require_geometry_and_frf()?;
            rbprops_cli::write_plots(dir, &rbprops_cli::plots::frf_magnitudes(&geometry, frf)?)?;
        }
        rbprops_cli::write_output(&rec, args.output.as_deref())
    })
}

fn options(a: &Args) -> EstimationOptions {
    EstimationOptions {
        estimator: a.estimator,
        trigger: TriggerLevel::FractionOfMax(a.trigger),
        pretrigger_s: a.pretrigger,
        record_s: a.record_s,
        force_window: a.force_window.0.map(|(pre_s, post_s)| ForceWindow {
            pre_s,
            post_s,
            taper_s: a.taper,
        }),
        response_window: a.window,
        exponential_on_force: !a.window_response_only,
        force_range: a.force_range,
        response_range: a.response_range,
        min_hits: a.min_hits,
        band_hz: a.band,
        keep_rejected: a.keep_rejected,
        force_dofs: a.force_dofs.clone(),
    }
}
