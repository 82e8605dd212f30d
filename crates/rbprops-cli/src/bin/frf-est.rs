//! `frf-est`: FRFs from impact time histories, the head of the pipeline for real tests
//! (the numerics are in `rbprops-frfest`, the orchestration in `rbprops_cli::frf_est`).

use anyhow::{bail, Context, Result};
use clap::{Parser, ValueEnum};
use rbprops_cli::frf_est::{EstimationOptions, WindowChoice};
use rbprops_frfest::{Estimator, ForceWindow, TriggerLevel};
use std::path::PathBuf;

#[derive(Clone, Copy, ValueEnum)]
enum EstimatorArg {
    /// S_xf/S_ff: unbiased by response noise (default; impact tests).
    H1,
    /// S_xx/S_fx: unbiased by force noise.
    H2,
    /// Total least squares between the two.
    Hv,
}

/// Estimate FRFs from impact time histories (UFF 58 function type 1: one record per hit
/// and channel, or continuous throughput records): trigger, double-hit and overload
/// checks with each hit's verdict, force and exponential windows, H1/H2/Hv over the
/// accepted hits, coherence and each line's variance. Writes the run (MCAP on stdout, or
/// -o FILE.mcap | DIR | FILE.uff) for modal-fit, model-check and the other stages.
#[derive(Parser)]
#[command(name = "frf-est", version, about)]
struct Args {
    /// The time histories: a universal file (.uff/.unv/.58/.58b).
    input: PathBuf,
    /// Output: FILE.mcap, FILE.uff, or a directory for CSV; default MCAP on stdout.
    #[arg(short, long)]
    output: Option<PathBuf>,
    #[command(flatten)]
    uff: rbprops_cli::UffArgs,
    /// The force channel's DOF, NODE:DIR (e.g. 201:-X or 201:-1), when record 9 does not
    /// say which records are forces (repeatable).
    #[arg(long = "force-dof", value_name = "NODE:DIR")]
    force_dofs: Vec<String>,
    #[arg(long, value_enum, default_value = "h1")]
    estimator: EstimatorArg,
    /// Response window: `auto` (exponential decaying the slowest response to about 1 % at
    /// the record's end, or none if it has decayed), `none`, or τ in seconds.
    #[arg(long, default_value = "auto")]
    window: String,
    /// Apply the exponential window to the response only (default: force too, so the
    /// FRF is the transfer function at s = iω + 1/τ).
    #[arg(long)]
    window_response_only: bool,
    /// Force window PRE:POST (s before the trigger, s after the pulse's end), or `none`.
    #[arg(long, default_value = "0.01:0.05")]
    force_window: String,
    /// Cosine taper outside the force window (s).
    #[arg(long, default_value_t = 0.0)]
    taper: f64,
    /// Trigger level as a fraction of the record's largest |force| (0–1).
    #[arg(long, default_value_t = 0.1)]
    trigger: f64,
    /// Throughput records: time kept before each trigger (s; default 5 % of the record).
    #[arg(long)]
    pretrigger: Option<f64>,
    /// Throughput records: each hit's record length (s; default the shortest spacing of
    /// consecutive hits).
    #[arg(long)]
    record_s: Option<f64>,
    /// The force channel's ADC range (± in the file's unit); default: flat tops are looked for.
    #[arg(long)]
    force_range: Option<f64>,
    /// The response channels' ADC range (± in the file's unit).
    #[arg(long)]
    response_range: Option<f64>,
    /// Fewest accepted hits per excitation.
    #[arg(long, default_value_t = 2)]
    min_hits: usize,
    /// Band FMIN:FMAX (Hz) of the FRFs written (default: up to where the force spectrum
    /// has fallen 20 dB, at most 0.4 × the sampling rate; 0 Hz left out).
    #[arg(long)]
    band: Option<String>,
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
    rbprops_cli::run("frf-est", || {
        let args = Args::parse();
        rbprops_formats::atomic::set_force(args.force);
        let opts = options(&args)?;
        let name = args.input.display().to_string();
        let bytes = rbprops_cli::read_file(&args.input)?;
        let data = rbprops_uff::parse(&bytes, &name)?;
        if !rbprops_uff::timehist::has_time_histories(&data) {
            bail!(
                "{name}: no time histories (dataset 58 with function type 1). It holds:\n{}",
                rbprops_uff::inventory(&data)
            );
        }
        let est = rbprops_cli::frf_est::estimate_uff(&data, &args.uff.options(), &opts)?;
        let mut digest = bytes;
        digest.extend_from_slice(&est.side_digest);
        let mut rec = est.record;
        rec.push_provenance(rbprops_cli::provenance(
            "frf-est",
            &rbprops_formats::sha256_hex(&digest),
        ))?;
        let mut notes = rbprops_cli::warnings::Collector::default();
        notes.extend("frf-est", &est.warnings);
        notes.print(args.verbose);
        rbprops_cli::say!("{}", est.summary);
        if let Some(dir) = &args.plot {
            let (geometry, frf) = rec.require_geometry_and_frf()?;
            rbprops_cli::write_plots(dir, &rbprops_cli::plots::frf_magnitudes(&geometry, frf)?)?;
        }
        rbprops_cli::write_output(&rec, args.output.as_deref())
    })
}

fn options(a: &Args) -> Result<EstimationOptions> {
    let positive = |v: f64, what: &str| -> Result<f64> {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            bail!("{what} {v}: must be a positive number")
        }
    };
    let response_window = match a.window.as_str() {
        "auto" => WindowChoice::Auto,
        "none" => WindowChoice::None,
        t => WindowChoice::Exponential(positive(
            t.parse()
                .with_context(|| format!("--window '{t}': auto, none or τ in seconds"))?,
            "--window",
        )?),
    };
    let force_window = match a.force_window.as_str() {
        "none" => None,
        s => {
            let (pre, post) = s
                .split_once(':')
                .with_context(|| format!("--force-window '{s}': PRE:POST in seconds, or none"))?;
            let parse = |x: &str| -> Result<f64> {
                let v: f64 = x
                    .trim()
                    .parse()
                    .with_context(|| format!("--force-window '{s}': '{x}' is not a number"))?;
                if !(v.is_finite() && v >= 0.0) {
                    bail!("--force-window '{s}': times must be ≥ 0");
                }
                Ok(v)
            };
            Some(ForceWindow {
                pre_s: parse(pre)?,
                post_s: parse(post)?,
                taper_s: a.taper,
            })
        }
    };
    if !(a.taper.is_finite() && a.taper >= 0.0) {
        bail!("--taper {}: must be ≥ 0 s", a.taper);
    }
    if !(a.trigger > 0.0 && a.trigger < 1.0) {
        bail!(
            "--trigger {}: a fraction of the largest |force| in (0, 1)",
            a.trigger
        );
    }
    let band_hz = match &a.band {
        None => None,
        Some(b) => {
            let (lo, hi) = b
                .split_once(':')
                .with_context(|| format!("--band '{b}': FMIN:FMAX in Hz"))?;
            let lo: f64 = lo
                .trim()
                .parse()
                .with_context(|| format!("--band '{b}': FMIN"))?;
            let hi: f64 = hi
                .trim()
                .parse()
                .with_context(|| format!("--band '{b}': FMAX"))?;
            Some((lo, hi))
        }
    };
    let force_dofs = a
        .force_dofs
        .iter()
        .map(|s| parse_dof(s))
        .collect::<Result<_>>()?;
    Ok(EstimationOptions {
        estimator: match a.estimator {
            EstimatorArg::H1 => Estimator::H1,
            EstimatorArg::H2 => Estimator::H2,
            EstimatorArg::Hv => Estimator::Hv,
        },
        trigger: TriggerLevel::FractionOfMax(a.trigger),
        pretrigger_s: a
            .pretrigger
            .map(|v| positive(v, "--pretrigger"))
            .transpose()?,
        record_s: a.record_s.map(|v| positive(v, "--record-s")).transpose()?,
        force_window,
        response_window,
        exponential_on_force: !a.window_response_only,
        force_range: a
            .force_range
            .map(|v| positive(v, "--force-range"))
            .transpose()?,
        response_range: a
            .response_range
            .map(|v| positive(v, "--response-range"))
            .transpose()?,
        min_hits: a.min_hits,
        band_hz,
        keep_rejected: a.keep_rejected,
        force_dofs,
    })
}

/// `NODE:DIR` with DIR one of ±1..±3 or ±X/±Y/±Z.
fn parse_dof(s: &str) -> Result<(i64, i64)> {
    let (node, dir) = s
        .split_once(':')
        .with_context(|| format!("--force-dof '{s}': NODE:DIR, e.g. 201:-X"))?;
    let node: i64 = node
        .trim()
        .parse()
        .with_context(|| format!("--force-dof '{s}': node '{node}' is not an integer"))?;
    let d = dir.trim().to_ascii_uppercase();
    let (sign, axis) = match d.strip_prefix('-') {
        Some(rest) => (-1, rest.to_string()),
        None => (1, d.trim_start_matches('+').to_string()),
    };
    let a = match axis.as_str() {
        "X" | "1" => 1,
        "Y" | "2" => 2,
        "Z" | "3" => 3,
        _ => bail!("--force-dof '{s}': direction '{dir}' is not ±X, ±Y, ±Z or ±1..±3"),
    };
    Ok((node, sign * a))
}
