//! `ni-select`: Norm Indicator, mode matching across excitations, best-mode sets.

use anyhow::{Context, Result};
use clap::Parser;
use rbprops_core::records::{Diagnostic, DiagnosticKind, DiagnosticSubject, Severity};
use rbprops_ni::{Criterion, ManualSet, SelectOptions};
use std::path::PathBuf;

/// For every rigid-body mode, choose the excitation that gives its best shape (NI, Eq. 12),
/// after matching modes across excitations of a set-up by frequency and MAC.
#[derive(Parser)]
#[command(name = "ni-select", version, about)]
struct Args {
    #[command(flatten)]
    io: rbprops_cli::StageIo,
    /// Selection criterion.
    #[arg(long, value_enum, default_value = "ni")]
    criterion: Criterion,
    /// Manual set, e.g. `1:F2,2:F2,3:F3,4:F3,5:F1,6:F1` (mode:excitation), or @FILE (TOML or CSV).
    #[arg(long)]
    set: Option<String>,
    /// Only this suspension set-up.
    #[arg(long)]
    setup: Option<String>,
    /// Combine modes across set-ups (wrong physics: a different suspension gives different modes).
    #[arg(long)]
    force_mixed_setups: bool,
    /// Least MAC for two estimates to be the same mode.
    #[arg(long, value_parser = rbprops_cli::args::fraction)]
    mac_threshold: Option<f64>,
    /// Print the per-excitation summary ("F0x excites mostly modes 1, 4, 6") on stderr.
    #[arg(long)]
    summary: bool,
    /// Write NI, hybrid MIF, PRF MIF curves and the strength heat map into this directory.
    #[arg(long)]
    plot: Option<PathBuf>,
}

fn manual(s: &str) -> Result<ManualSet> {
    if let Some(path) = s.strip_prefix('@') {
        let text = rbprops_cli::read_text(std::path::Path::new(path))?;
        let r = if path.ends_with(".csv") {
            ManualSet::from_csv(&text)
        } else {
            ManualSet::from_toml(&text)
        };
        return r.with_context(|| path.to_string());
    }
    Ok(rbprops_ni::parse_manual_set(s)?)
}

fn main() -> std::process::ExitCode {
    rbprops_cli::return_large_buffers();
    rbprops_cli::run("ni-select", || {
        let args = Args::parse();
        // The FRFs stay in the input file and are read one excitation at a time.
        let (input, deferred) = args.io.read_deferring("ni-select", &Default::default())?;
        let mut rec = input.record;
        let mut opts = SelectOptions {
            criterion: args.criterion,
            setup: args.setup.clone(),
            force_mixed_setups: args.force_mixed_setups,
            ..Default::default()
        };
        if let Some(s) = &args.set {
            opts.manual = Some(manual(s)?);
        }
        if let Some(m) = args.mac_threshold {
            opts.mac_threshold = m;
        }
        let frf = deferred.as_ref().map(|d| d as &dyn rbprops_core::FrfSource);
        let out = rbprops_cli::stages::ni_select_from(&mut rec, frf, &opts, &input.sha256)
            .with_context(|| input.name.clone())?;
        let mut warnings = rbprops_cli::warnings::Collector::default();
        warnings.extend(out.record.diagnostics.iter().cloned());
        for m in &out.record.missing {
            warnings.add(Diagnostic::new(
                "ni-select",
                DiagnosticKind::ModeMissing,
                Severity::ChangesAnswer,
                DiagnosticSubject::setup(&m.setup).mode(m.mode, m.frequency_hz),
                format!("not excited above the noise by {:?}: {}", m.tried, m.reason),
            ));
        }
        for d in &out.criterion_disagreements {
            warnings.add(rbprops_cli::warnings::note_of(
                "ni-select",
                DiagnosticKind::CriteriaDisagree,
                Default::default(),
                d,
            ));
        }
        warnings.print(args.io.checks.verbose);
        if args.summary {
            for s in &out.excitation_summaries {
                rbprops_cli::say!(
                    "{} (set-up {}): excites modes {:?}, mostly {:?}; not {:?}",
                    s.excitation,
                    s.setup,
                    s.modes_excited,
                    s.modes_mostly_excited,
                    s.modes_not_excited
                );
            }
        }
        if let Some(dir) = &args.plot {
            rbprops_cli::write_plots(dir, &rbprops_cli::plots::indicators(&out)?)?;
        }
        // The indicator curves (several values per line and excitation) are not written:
        // freed before the output is encoded (issue 41's memory bound).
        drop(out);
        args.io.write_with(&rec, deferred.as_ref())
    })
}
