//! `frf-sim`: synthetic FRFs of a softly suspended rigid body, from a campaign spec.

use anyhow::bail;
use clap::Parser;
use std::path::PathBuf;

/// Simulate a test campaign: writes geometry, FRFs and the ground truth (MCAP to stdout,
/// or to -o FILE.mcap / -o DIR for CSV).
#[derive(Parser)]
#[command(name = "frf-sim", version, about)]
struct Args {
    /// Campaign spec (TOML). Omit with --example.
    spec: Option<PathBuf>,
    /// Use a built-in campaign (see --list-examples).
    #[arg(long, conflicts_with = "spec")]
    example: Option<String>,
    /// List the built-in campaigns and exit.
    #[arg(long)]
    list_examples: bool,
    /// Print the campaign's TOML (a starting point for your own spec) and exit.
    #[arg(long)]
    print_spec: bool,
    /// Override the spec's noise seed.
    #[arg(long)]
    seed: Option<u64>,
    /// Output: FILE.mcap, or a directory for CSV; default MCAP on stdout.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Write FRF magnitude plots (one SVG per excitation) into this directory.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// List every note on stderr (default: one summary line).
    #[arg(short, long)]
    verbose: bool,
    /// Replace an output path that is not a previous rbprops output (never an input).
    #[arg(long)]
    force: bool,
}

fn main() -> std::process::ExitCode {
    rbprops_cli::run("frf-sim", || {
        let args = Args::parse();
        rbprops_formats::atomic::set_force(args.force);
        if args.list_examples {
            let mut names = String::new();
            for n in rbprops_sim::example_names() {
                names += &format!("{n}\n");
            }
            return rbprops_cli::out(&names);
        }
        let (text, source) = match (&args.spec, &args.example) {
            (Some(p), _) => (rbprops_cli::read_text(p)?, p.display().to_string()),
            (None, Some(name)) => {
                let Some(t) = rbprops_sim::example(name) else {
                    bail!(
                        "unknown example '{name}' (available: {})",
                        rbprops_sim::example_names().join(", ")
                    );
                };
                (t.to_string(), format!("example '{name}'"))
            }
            (None, None) => {
                bail!("give a campaign spec file or --example NAME (--list-examples names them)")
            }
        };
        if args.print_spec {
            return rbprops_cli::out(&text);
        }
        // The FRFs are made one excitation at a time as the output is written.
        let (mut rec, sim) = rbprops_cli::stages::simulate_deferred(&text, &source, args.seed)?;
        let mut notes = rbprops_cli::warnings::Collector::default();
        for note in &sim.notes {
            notes.add(rbprops_cli::warnings::note_of(
                "frf-sim",
                rbprops_cli::warnings::DiagnosticKind::Simulation,
                Default::default(),
                note,
            ));
        }
        notes.print(args.verbose);
        if let Some(dir) = &args.plot {
            // The plots need the whole set: made once, and written as it is (not
            // simulated again for the output).
            let frf = rbprops_core::FrfSet::from_source(&sim)?;
            let plots = rbprops_cli::plots::frf_magnitudes(&sim.geometry, &frf)?;
            rbprops_cli::write_plots(dir, &plots)?;
            rec.frf = Some(frf);
            return rbprops_cli::write_output(&rec, args.output.as_deref());
        }
        rbprops_cli::write_output_with(&rec, Some(&sim), args.output.as_deref())
    })
}
