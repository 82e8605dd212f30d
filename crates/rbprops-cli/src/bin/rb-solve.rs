//! `rb-solve`: the ten inertia properties from the selected modes (and the FRFs).

use anyhow::{bail, Context, Result};
use clap::{Parser, ValueEnum};
use rbprops_cli::stages::UncertaintyChoice;
use rbprops_core::records::{InertiaEstimate, PropertiesRecord};
use rbprops_inertia::{Estimator, OriginChoice, SolveOptions};
use std::path::PathBuf;

#[derive(Clone, Copy, ValueEnum, PartialEq)]
enum OutFormat {
    /// Human-readable table (default when stdout is a terminal).
    Table,
    /// JSON array of estimates (the stable interface for scripts).
    Json,
    /// The run record as MCAP (default when stdout is not a terminal).
    Mcap,
}

/// Estimate mass, centre of mass and inertia tensor (Bretl–Conti, Toivola–Nuutila, mass
/// line) with standard errors, from `modal-fit` + `ni-select` output.
#[derive(Parser)]
// The output is optional here (the estimates go to stdout), hence its own help text.
#[command(name = "rb-solve", version, about, mut_arg("output", |a| a.help(
    "Write the run record (with the estimates topic) here: FILE.mcap or a CSV directory"
)))]
struct Args {
    #[command(flatten)]
    io: rbprops_cli::StageIo,
    /// What to print on stdout.
    #[arg(long, value_enum)]
    format: Option<OutFormat>,
    /// Estimators to run (default: all three).
    #[arg(long, value_enum, value_delimiter = ',')]
    method: Vec<Estimator>,
    /// Origin: `x,y,z` in metres, or a channel / measurement-point id (e.g. an accelerometer).
    #[arg(long)]
    origin: Option<String>,
    /// Reference properties (JSON `{mass_kg, com_m, inertia_cm_kg_m2}`); default: the truth topic if present.
    #[arg(long)]
    reference: Option<PathBuf>,
    /// Do not compare with the truth topic even if present.
    #[arg(long)]
    no_reference: bool,
    /// Known mass (kg), imposed as side information.
    #[arg(long, value_parser = rbprops_cli::args::mass_kg)]
    known_mass: Option<f64>,
    /// Nominal properties (JSON like --reference): regularise only what the data leave undetermined.
    #[arg(long)]
    nominal: Option<PathBuf>,
    /// Mass-line band FMIN:FMAX in Hz (default: automatic).
    #[arg(long, value_parser = rbprops_cli::args::band)]
    mass_line_band: Option<(f64, f64)>,
    /// How the modal estimators' standard errors are obtained (the mass line always
    /// propagates its own). The FRF-level bootstrap is the calibrated one (see rbprops-uq
    /// and docs/results.md); linearised propagation is faster but under-covers J.
    #[arg(long, value_enum, default_value = "bootstrap")]
    uncertainty: UncertaintyChoice,
    /// Bootstrap replicates (with --uncertainty bootstrap; the seed is --seed).
    #[arg(long, default_value_t = 100, value_parser = rbprops_cli::args::replicates)]
    bootstrap: usize,
    /// Monte Carlo draws for the linearised uncertainty (0 = linearised propagation).
    #[arg(long, default_value_t = 0, value_parser = rbprops_cli::args::draws)]
    monte_carlo: usize,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Write a figure of the estimates with 95 % error bars into this directory.
    #[arg(long)]
    plot: Option<PathBuf>,
}

fn read_props(p: &PathBuf) -> Result<PropertiesRecord> {
    let text = rbprops_cli::read_text(p)?;
    serde_json::from_str(&text).with_context(|| {
        format!(
            "{}: expected JSON {{mass_kg, com_m, inertia_cm_kg_m2}}",
            p.display()
        )
    })
}

fn origin(s: &str) -> Result<OriginChoice> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() == 3 {
        if let (Ok(x), Ok(y), Ok(z)) = (
            parts[0].trim().parse::<f64>(),
            parts[1].trim().parse::<f64>(),
            parts[2].trim().parse::<f64>(),
        ) {
            if !(x.is_finite() && y.is_finite() && z.is_finite()) {
                bail!("--origin {s}: coordinates must be finite (x,y,z in metres)");
            }
            return Ok(OriginChoice::Point([x, y, z]));
        }
    }
    Ok(OriginChoice::Channel(s.to_string()))
}

fn main() -> std::process::ExitCode {
    let args = Args::parse();
    if args.uncertainty == UncertaintyChoice::Bootstrap {
        rbprops_cli::return_large_buffers();
        rbprops_cli::keep_heap_top();
    }
    rbprops_cli::run("rb-solve", move || {
        // The FRFs stay in an MCAP input file and are read one excitation at a time ...
        let (input, mut deferred) = args.io.read_deferring("rb-solve", &Default::default())?;
        let mut rec = input.record;
        let mut opts = SolveOptions::default();
        if !args.method.is_empty() {
            opts.estimators = args.method.clone();
        }
        if let Some(o) = &args.origin {
            opts.origin = origin(o)?;
        }
        if let Some(p) = &args.reference {
            opts.reference = Some(read_props(p)?);
        }
        opts.side_information.known_mass_kg = args.known_mass;
        if let Some(p) = &args.nominal {
            opts.side_information.nominal = Some(read_props(p)?);
        }
        opts.mass_line.band_hz = args.mass_line_band;
        opts.monte_carlo_samples = args.monte_carlo;
        opts.seed = args.seed;
        let uncertainty = match args.uncertainty {
            UncertaintyChoice::Linearised => rbprops_cli::stages::Uncertainty::Linearised,
            UncertaintyChoice::Bootstrap => {
                rbprops_cli::stages::Uncertainty::Bootstrap(rbprops_uq::BootstrapOptions {
                    replicates: args.bootstrap,
                    seed: args.seed,
                    ..Default::default()
                })
            }
        };
        // ... unless the bootstrap makes line variances from the set's values.
        if rbprops_cli::stages::rb_solve_needs_the_set(&rec, &uncertainty) {
            if let Some(d) = deferred.take() {
                rec.frf = Some(rbprops_core::FrfSet::from_source(&d)?);
            }
        }
        let frf = deferred.as_ref().map(|d| d as &dyn rbprops_core::FrfSource);
        let (out, _) = rbprops_cli::stages::rb_solve_from(
            &mut rec,
            frf,
            &opts,
            &uncertainty,
            !args.no_reference,
            &input.sha256,
        )
        .with_context(|| input.name.clone())?;
        let mut warnings = rbprops_cli::warnings::Collector::default();
        warnings.extend(out.diagnostics.iter().cloned());
        for e in &out.estimates {
            warnings.extend(e.diagnostics.iter().cloned());
        }
        warnings.print(args.io.checks.verbose);
        if out.estimates.is_empty() {
            bail!("no estimator produced an estimate (see the warnings above)");
        }
        if let Some(dir) = &args.plot {
            rbprops_cli::write_plots(dir, &rbprops_cli::plots::estimates(&out.estimates)?)?;
        }
        let format = args.format.unwrap_or(
            if rbprops_cli::stdout_is_terminal() || args.io.output.is_some() {
                OutFormat::Table
            } else {
                OutFormat::Mcap
            },
        );
        if let Some(p) = &args.io.output {
            rbprops_cli::write_output_with(&rec, frf, Some(p))?;
        }
        match format {
            OutFormat::Table => rbprops_cli::out(&rbprops_cli::table::estimates(&out.estimates))?,
            OutFormat::Json => rbprops_cli::out(&format!(
                "{}\n",
                serde_json::to_string_pretty::<Vec<InertiaEstimate>>(&out.estimates)?
            ))?,
            OutFormat::Mcap => rbprops_cli::write_output_with(&rec, frf, None)?,
        }
        Ok(())
    })
}
