//! `modal-fit`: modal identification of every excitation (SIMO), in parallel.

use anyhow::{bail, Context};
use clap::{Parser, ValueEnum};
use rbprops_modal::{FitOptions, Method, PoleMode};
use std::path::PathBuf;

#[derive(Clone, Copy, ValueEnum, PartialEq)]
enum WeightArg {
    /// Relative weights 1/|H| on every line (the default without line variances).
    None,
    /// 1/|H| times √(γ²/(1 − γ²)) from the recording's coherence: a line's weight is
    /// 1/σ with the H1 noise σ²/|H|² ≈ (1 − γ²)/(n_d γ²) (lscf and lsce).
    Coherence,
    /// 1/σ from the estimator's line variances (topic /rbprops/frf_variance: frf-est
    /// output, or an export's coherence with --averages); the default when the input
    /// carries them (lscf and lsce).
    Variance,
}

/// Identify natural frequencies, damping ratios and residues (modal constants, 1/kg) with
/// standard errors, for every excitation. Adds the `modal_fit` topic.
#[derive(Parser)]
#[command(name = "modal-fit", version, about)]
struct Args {
    #[command(flatten)]
    io: rbprops_cli::StageIo,
    #[command(flatten)]
    uff: rbprops_cli::UffArgs,
    #[command(flatten)]
    averages: rbprops_cli::AveragesArg,
    /// Force one method (default: per-excitation lscf fits, and the poly-reference fit of
    /// a set-up kept instead when the evidence calls for it and it fits better).
    #[arg(long, value_enum)]
    method: Option<Method>,
    /// Band FMIN:FMAX in Hz (default: the whole axis).
    #[arg(long, value_parser = rbprops_cli::args::band)]
    band: Option<(f64, f64)>,
    /// Number of modes in the band (default: from the stabilisation diagram).
    #[arg(long, value_parser = rbprops_cli::args::modes)]
    modes: Option<usize>,
    /// Highest model order of the stabilisation diagram.
    #[arg(long, value_parser = rbprops_cli::args::model_order)]
    max_order: Option<usize>,
    #[arg(long, value_enum, default_value = "excitation")]
    poles: PoleMode,
    /// Line weights of the least-squares fits (default: variance when the input carries
    /// line variances and the method is lscf or lsce, else none).
    #[arg(long, value_enum)]
    weight: Option<WeightArg>,
    /// With --method lscf or lsce: still choose the poly-reference fit by evidence, as the
    /// default does.
    #[arg(long)]
    auto_poly: bool,
    /// Leave out the lower/upper residual terms of the residue fit.
    #[arg(long)]
    no_residuals: bool,
    /// Time constant τ (s) of an exponential window e^{−t/τ} on the responses: the poles are
    /// corrected for its damping (overrides the recording's processing topic).
    #[arg(long, value_name = "TAU", value_parser = rbprops_cli::args::seconds)]
    exp_window: Option<f64>,
    /// Write stabilisation diagrams and measured-vs-synthesised FRF overlays here.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// In the --plot overlays, shade the lines whose measured coherence γ² is below this
    /// (when the recording has coherence).
    #[arg(long, value_name = "GAMMA2", value_parser = rbprops_cli::args::fraction, default_value_t = rbprops_cli::plots::LOW_COHERENCE)]
    low_coherence: f64,
}

fn main() -> std::process::ExitCode {
    rbprops_cli::return_large_buffers();
    rbprops_cli::one_malloc_arena();
    rbprops_cli::run("modal-fit", || {
        let args = Args::parse();
        // The FRFs stay in an MCAP input file and each fit reads its own excitation ...
        let (input, mut deferred) = args.io.read_deferring("modal-fit", &args.uff.options())?;
        // The poly-reference fit reads a large set-up's excitations again on every pass.
        rbprops_cli::keep_reread_values(&mut deferred);
        let mut rec = input.record;
        // ... unless line weights are made from the set's values (variances, coherence).
        let method = args.method.unwrap_or(Method::Lscf);
        let variance_weights = match args.weight {
            Some(WeightArg::Variance) => true,
            None => matches!(method, Method::Lscf | Method::Lsce),
            Some(WeightArg::None) | Some(WeightArg::Coherence) => false,
        };
        let weights_from_values = args.averages.averages.is_some()
            || (variance_weights && rec.topic(rbprops_formats::topics::FRF_VARIANCE).is_some())
            || rec.topic(rbprops_formats::topics::COHERENCE).is_some();
        if weights_from_values {
            if let Some(d) = deferred.take() {
                rec.frf = Some(rbprops_core::FrfSet::from_source(&d)?);
            }
        }
        rbprops_cli::variance::declare_averages(&mut rec, args.averages.averages, &input.name)?;
        let mut opts = FitOptions {
            method,
            poles: args.poles,
            n_modes: args.modes,
            residual_terms: !args.no_residuals,
            keep_synthesised: args.plot.is_some(),
            auto_poly_reference: args.method.is_none() || args.auto_poly,
            ..Default::default()
        };
        opts.band_hz = args.band;
        if let Some(o) = args.max_order {
            opts.max_order = o;
        }
        let weights_allowed = matches!(opts.method, Method::Lscf | Method::Lsce);
        match args.weight {
            Some(WeightArg::Coherence) => {
                rbprops_cli::coherence::weight_fit(&mut rec, &mut opts, &input.name)?
            }
            Some(WeightArg::Variance) => {
                if !rbprops_cli::variance::weight_fit(&mut rec, &mut opts, &input.name)? {
                    bail!(
                        "{}: --weight variance, but the run has no line variances (frf-est output, or an export's coherence with --averages N)",
                        input.name
                    );
                }
            }
            None if weights_allowed => {
                rbprops_cli::variance::weight_fit(&mut rec, &mut opts, &input.name)?;
            }
            Some(WeightArg::None) | None => {}
        }
        let frf = deferred.as_ref().map(|d| d as &dyn rbprops_core::FrfSource);
        let out = rbprops_cli::stages::modal_fit_from(
            &mut rec,
            frf,
            &opts,
            args.exp_window,
            &input.sha256,
        )?;
        // One line per fact: the typed diagnostics (grouped by set-up, one per repeated
        // root however many excitations show it); with -v also every note of the records.
        let verbose = args.io.checks.verbose;
        use rbprops_cli::warnings::{note_of, DiagnosticKind, DiagnosticSubject};
        let mut warnings = rbprops_cli::warnings::Collector::default();
        warnings.extend(out.record.diagnostics.iter().cloned());
        if verbose {
            // The per-excitation details the record keeps with each fit and mode.
            for e in &out.record.excitations {
                let subject = DiagnosticSubject::setup(&e.setup).excitation(&e.excitation);
                for w in &e.warnings {
                    warnings.add(note_of(
                        "modal-fit",
                        DiagnosticKind::FitDetail,
                        subject.clone(),
                        w,
                    ));
                }
            }
            for m in &out.record.modes {
                let subject = DiagnosticSubject::setup(&m.setup)
                    .excitation(&m.excitation)
                    .mode(m.mode, m.frequency_hz);
                for w in &m.warnings {
                    warnings.add(note_of(
                        "modal-fit",
                        DiagnosticKind::FitDetail,
                        subject.clone(),
                        w,
                    ));
                }
            }
        }
        warnings.print(verbose);
        if let Some(dir) = &args.plot {
            // The overlays draw every excitation's FRFs: the set is read whole for them.
            let mut whole = None;
            if let Some(d) = &deferred {
                whole = Some(rbprops_core::FrfSet::from_source(d)?);
            }
            let (geometry, frf) = match &whole {
                Some(f) => (rec.geometry()?.context("no geometry topic")?, f),
                None => rec.require_geometry_and_frf()?,
            };
            let coherence = rbprops_cli::coherence::get(&rec)?;
            let shading = coherence.as_ref().map(|g| (g, args.low_coherence));
            rbprops_cli::write_plots(
                dir,
                &rbprops_cli::plots::modal_fit_shaded(&geometry, frf, &out, shading)?,
            )?;
        }
        drop(out); // its plot data is not written: freed before the output is encoded
        args.io.write_with(&rec, deferred.as_ref())
    })
}
