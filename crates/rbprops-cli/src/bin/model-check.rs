//! `model-check`: why do a simulation and a recording differ? Locates the mismatch,
//! names the missing physics, fits it and shows the fit improve against the noise
//! (the numerics are in `rbprops-check`).

use anyhow::{bail, Context, Result};
use clap::{Parser, ValueEnum};
use rbprops_check::{CheckOptions, CheckOutcome, Progress, RecordingNoise};
use rbprops_formats::topics;
use rbprops_sim::CampaignSpec;
use std::io::IsTerminal;
use std::path::PathBuf;

#[derive(Clone, Copy, ValueEnum)]
enum OutFormat {
    /// The short verdict and the main numbers.
    Text,
    /// The full report as JSON.
    Json,
    /// The input run plus the report topic, as MCAP on stdout.
    Mcap,
}

/// Check a recording against the nominal simulation: noise floor, baseline fit of the
/// nominal parameters, residual maps, missing-physics screening and refit.
#[derive(Parser)]
#[command(name = "model-check", version, about)]
struct Args {
    /// The nominal campaign spec (TOML, as frf-sim reads it). Omit with --example.
    spec: Option<PathBuf>,
    /// The recording: MCAP file, CSV directory, UFF file (.uff/.unv/.58b), or `-`/absent
    /// for MCAP on stdin.
    #[arg(short, long)]
    input: Option<PathBuf>,
    #[command(flatten)]
    checks: rbprops_cli::InputChecks,
    /// Use a built-in campaign as the nominal spec.
    #[arg(long, conflicts_with = "spec")]
    example: Option<String>,
    /// Output format (default: text on a terminal or with -o, else MCAP).
    #[arg(long, value_enum)]
    format: Option<OutFormat>,
    /// Write the run with the report topic: FILE.mcap, or a directory for CSV.
    #[arg(short, long)]
    output: Option<PathBuf>,
    #[command(flatten)]
    uff: rbprops_cli::UffArgs,
    #[command(flatten)]
    averages: rbprops_cli::AveragesArg,
    /// Write the improved campaign spec (fitted parameters, accepted effects) here.
    #[arg(long)]
    improved_spec: Option<PathBuf>,
    /// Write measured/nominal/improved FRF overlays and residual maps (SVG) here.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Weighed mass (kg): fixes the mass, which makes a global gain error observable.
    #[arg(long, value_parser = rbprops_cli::args::mass_kg)]
    weighed_mass: Option<f64>,
    /// Known sensor mass: `POINT=KG` (repeatable) or `KG` for every sensor point.
    #[arg(long)]
    sensor_mass: Vec<String>,
    /// Known noise, relative part (fraction of |H|), instead of estimating it.
    #[arg(long, value_parser = rbprops_cli::args::non_negative)]
    noise_relative: Option<f64>,
    /// Known noise, absolute floor (FRF units).
    #[arg(long, requires = "noise_relative", value_parser = rbprops_cli::args::non_negative)]
    noise_floor: Option<f64>,
    /// Family-wise false-positive rate per selection step (0 < α ≤ 0.5).
    #[arg(long, default_value_t = 0.01, value_parser = rbprops_cli::args::alpha)]
    alpha: f64,
    /// Safety cap on the selection steps (one effect each); the selection ends when
    /// nothing significant is left, and reaching the cap is reported.
    #[arg(long, default_value_t = 10, value_parser = rbprops_cli::args::steps)]
    max_effects: usize,
    /// Screen only these effect ids (comma-separated).
    #[arg(long, value_delimiter = ',')]
    only: Vec<String>,
    /// Replace an output path that is not a previous rbprops output (never an input).
    #[arg(long)]
    force: bool,
}

fn main() -> std::process::ExitCode {
    rbprops_cli::run("model-check", || {
        let args = Args::parse();
        rbprops_formats::atomic::set_force(args.force);
        rbprops_cli::args::check_effect_ids(&args.only)?;
        let (text, source) = match (&args.spec, &args.example) {
            (Some(p), _) => (rbprops_cli::read_text(p)?, p.display().to_string()),
            (None, Some(name)) => match rbprops_sim::example(name) {
                Some(t) => (t.to_string(), format!("example '{name}'")),
                None => bail!(
                    "unknown example '{name}' (available: {})",
                    rbprops_sim::example_names().join(", ")
                ),
            },
            (None, None) => bail!("give the nominal campaign spec (TOML) or --example NAME"),
        };
        let mut spec = CampaignSpec::from_toml_str(&text).map_err(|e| {
            anyhow::anyhow!(
                "{source}: {e}{}",
                rbprops_cli::init_spec::placeholder_hint(&text)
            )
        })?;
        let input = rbprops_cli::read_stage_input(
            "model-check",
            args.input.as_deref(),
            &args.checks,
            &args.uff.options(),
        )?;
        let mut rec = input.record;
        rbprops_cli::variance::declare_averages(&mut rec, args.averages.averages, &input.name)?;
        let (geometry, frf) = rec
            .require_geometry_and_frf()
            .with_context(|| input.name.clone())?;
        let frf = frf.clone();
        let known = rbprops_cli::variance::for_model_check(&rec, &mut spec)
            .with_context(|| input.name.clone())?;
        let estimator_notes = known.notes;
        let mut opts = CheckOptions {
            line_variance: known
                .line_variance
                .filter(|_| args.noise_relative.is_none()),
            estimator_resolution: known.resolution,
            alpha: args.alpha,
            max_effects: args.max_effects,
            weighed_mass_kg: args.weighed_mass,
            sensor_masses_kg: sensor_masses(&args.sensor_mass, &geometry)?,
            only: (!args.only.is_empty()).then(|| args.only.clone()),
            ..Default::default()
        };
        if args.checks.verbose || std::io::stderr().is_terminal() {
            let t0 = std::time::Instant::now();
            opts.progress = Progress::new(move |line| {
                rbprops_cli::say!("model-check [{:6.1} s] {line}", t0.elapsed().as_secs_f64())
            });
        }
        if let Some(a) = args.noise_relative {
            let n = frf.n_channels;
            let mut given =
                RecordingNoise::given(vec![a; n], vec![args.noise_floor.unwrap_or(0.0); n]);
            given.source = "given (--noise-relative/--noise-floor)".into();
            opts.noise = Some(given);
        }
        let out = rbprops_check::check(&spec, &geometry, &frf, &opts)
            .map_err(|e| rbprops_cli::init_spec::mismatch_hint(e, &input.name))
            .with_context(|| format!("{} against {source}", input.name))?;
        let mut warnings = rbprops_cli::warnings::Collector::default();
        for n in &estimator_notes {
            warnings.add(rbprops_cli::warnings::note_of(
                "model-check",
                rbprops_cli::warnings::DiagnosticKind::CheckProcedure,
                Default::default(),
                n,
            ));
        }
        warnings.extend(out.report.diagnostics.iter().cloned());
        warnings.print(args.checks.verbose);
        if let Some(p) = &args.improved_spec {
            let mut s = out.improved_spec.clone();
            s.description = format!(
                "{} [improved by model-check: {}]",
                s.description, out.report.verdict
            );
            rbprops_cli::write_text(p, &s.to_toml_string())?;
        }
        if let Some(dir) = &args.plot {
            rbprops_cli::write_plots(dir, &rbprops_cli::plots::model_check(&out, &geometry)?)?;
        }
        rec.push_provenance(rbprops_cli::provenance("model-check", &input.sha256))?;
        rec.set(topics::MODEL_CHECK, &[out.report.clone()]);
        if let Some(p) = &args.output {
            rbprops_cli::write_output(&rec, Some(p))?;
        }
        let format = args.format.unwrap_or(
            if rbprops_cli::stdout_is_terminal() || args.output.is_some() {
                OutFormat::Text
            } else {
                OutFormat::Mcap
            },
        );
        match format {
            OutFormat::Text => rbprops_cli::out(&summary(&out))?,
            OutFormat::Json => {
                rbprops_cli::out(&format!("{}\n", serde_json::to_string_pretty(&out.report)?))?
            }
            OutFormat::Mcap => rbprops_cli::write_output(&rec, None)?,
        }
        Ok(())
    })
}

fn sensor_masses(items: &[String], g: &rbprops_core::Geometry) -> Result<Vec<(String, f64)>> {
    let mut points: Vec<String> = Vec::new();
    for c in &g.channels {
        if !points.contains(&c.point) {
            points.push(c.point.clone());
        }
    }
    let mut out = Vec::new();
    for it in items {
        match it.split_once('=') {
            Some((p, m)) => out.push((p.trim().to_string(), parse_kg(m)?)),
            None => {
                let m = parse_kg(it)?;
                out.extend(points.iter().map(|p| (p.clone(), m)));
            }
        }
    }
    Ok(out)
}

fn parse_kg(s: &str) -> Result<f64> {
    let m: f64 = s
        .trim()
        .parse()
        .with_context(|| format!("sensor mass '{s}': not a number"))?;
    if !(m.is_finite() && m >= 0.0) {
        bail!("sensor mass {m}: must be finite and ≥ 0 kg");
    }
    Ok(m)
}

fn summary(out: &CheckOutcome) -> String {
    let r = &out.report;
    let mut s = format!("{}\n\n", r.verdict);
    s += &format!(
        "χ²/ν: nominal {:.3}, baseline fit {:.3}, final {:.3} (noise band {:.3}–{:.3}, ν = {:.0})\n",
        r.chi2_nu_nominal, r.chi2_nu_before, r.chi2_nu_after, r.noise_band[0], r.noise_band[1], r.nu_after
    );
    for a in &r.accepted {
        s += &format!(
            "accepted {} (Δχ² {:.1}, ΔBIC {:.1}, {} dof):\n",
            a.id, a.delta_chi2, a.delta_bic, a.dof
        );
        for p in &a.parameters {
            s += &format!(
                "  {:<40} {:>12.6} ± {:.2e} {}\n",
                p.name, p.value, p.standard_error, p.unit
            );
        }
    }
    for f in &r.ambiguous {
        s += &format!(
            "ambiguous: {} — to separate: {}\n",
            f.ids.join(" / "),
            f.separating_measurement
        );
    }
    for n in &r.not_observable {
        s += &format!(
            "not observable: {} — {}; would need {}\n",
            n.id, n.reason, n.would_reveal
        );
    }
    s += "\ninertia              nominal        before (±SE)              after (±SE)\n";
    let q = |e: &rbprops_check::report::InertiaEstimateReport| {
        let [xy, xz, yz] = e.products_kg_m2;
        rbprops_core::InertiaProperties {
            mass: e.mass_kg,
            com: e.com_m.into(),
            moments: e.moments_kg_m2,
            products: rbprops_core::inertia::ProductsOfInertia { xy, xz, yz },
        }
        .to_vector()
    };
    let (n, b, a) = (
        q(&r.inertia_nominal),
        q(&r.inertia_before),
        q(&r.inertia_after),
    );
    for i in 0..10 {
        s += &format!(
            "{:<12} {:>12.6} {:>12.6} ±{:<10.2e} {:>12.6} ±{:<10.2e}\n",
            rbprops_check::params::INERTIA_NAMES[i],
            n[i],
            b[i],
            r.inertia_before.standard_errors[i],
            a[i],
            r.inertia_after.standard_errors[i]
        );
    }
    s += "(products J_xy = ∫xy dm etc.; the tensor's off-diagonal entries are their negatives)\n";
    if !r.residuals_after.flagged.is_empty() {
        s += &format!(
            "remaining flagged cells: {}\n",
            r.residuals_after.flagged.join(", ")
        );
    }
    s
}
