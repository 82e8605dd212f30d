//! `rbprops`: utilities around the pipeline — format conversion, campaigns, summaries
//! and reports.

use anyhow::{bail, Context};
use clap::{Parser, Subcommand};
use std::path::PathBuf;

#[derive(Parser)]
#[command(name = "rbprops", version, about = "rbprops utilities")]
struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Convert a run between MCAP, a CSV directory and UFF (format from the paths;
    /// `-` or no input reads MCAP from stdin, no output writes MCAP to stdout).
    Convert {
        input: Option<PathBuf>,
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// UFF input: list what the file holds (datasets, function types, nodes, units,
        /// frequency axes) instead of converting it.
        #[arg(long, requires = "input")]
        list: bool,
        #[command(flatten)]
        uff: rbprops_cli::UffArgs,
        /// UFF input: write a channel map template (one row per dataset 58, known DOFs
        /// filled in) to this file instead of converting.
        #[arg(long, requires = "input")]
        channel_template: Option<PathBuf>,
        #[command(flatten)]
        checks: rbprops_cli::InputChecks,
    },
    /// Run every campaign spec (*.toml) or recording (*.mcap, CSV run directory) under DIR
    /// through modal-fit | ni-select | rb-solve with default options, in parallel, and write
    /// one summary table (CSV; stdout unless -o).
    Campaign {
        dir: PathBuf,
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// Standard errors as rb-solve computes them: `bootstrap` (default, 100 replicates,
        /// seed 0, as rb-solve) or `linearised` (faster).
        #[arg(long, default_value = "bootstrap")]
        uncertainty: String,
    },
    /// Summary rows (the campaign table's columns) of finished runs.
    Summary {
        /// Runs holding an estimates topic (MCAP or CSV directories).
        runs: Vec<PathBuf>,
        /// Campaign label (default: the file name).
        #[arg(long)]
        campaign: Option<String>,
        /// Mode-set label.
        #[arg(long, default_value = "ni")]
        set: String,
        /// Origin label.
        #[arg(long, default_value = "geometry")]
        origin: String,
    },
    /// A Markdown report with figures (errors per set, method and origin — the paper's
    /// Figs. 5–8 and 14–17) from summary tables.
    Report {
        /// Summary CSV files (from `campaign` or `summary`).
        summaries: Vec<PathBuf>,
        /// Output directory (report.md and SVG figures).
        #[arg(short, long)]
        output: PathBuf,
        #[arg(long, default_value = "rbprops report")]
        title: String,
        /// Extra figures (SVG files already written) to link in the report.
        #[arg(long)]
        figure: Vec<PathBuf>,
    },
}

fn main() -> std::process::ExitCode {
    rbprops_cli::run("rbprops", || match Args::parse().command {
        Command::Convert {
            input,
            output,
            list,
            uff,
            channel_template,
            checks,
        } => {
            if list || channel_template.is_some() {
                let path = input.as_deref().expect("clap requires the input");
                let uff = rbprops_cli::parse_uff(path)?;
                if let Some(t) = &channel_template {
                    rbprops_cli::write_text(t, &rbprops_uff::channel_map_template(&uff))?;
                }
                if list {
                    println!("{}", rbprops_uff::inventory(&uff));
                }
                return Ok(());
            }
            let inp = rbprops_cli::read_stage_input(
                "rbprops convert",
                input.as_deref(),
                &checks,
                &uff.options(),
            )?;
            rbprops_cli::write_output(&inp.record, output.as_deref())
        }
        Command::Campaign {
            dir,
            output,
            uncertainty,
        } => {
            let uncertainty = match uncertainty.as_str() {
                "bootstrap" => rbprops_cli::stages::Uncertainty::Bootstrap(Default::default()),
                "linearised" => rbprops_cli::stages::Uncertainty::Linearised,
                other => bail!("--uncertainty {other}: expected bootstrap or linearised"),
            };
            let items = rbprops_cli::campaign::discover(&dir)?;
            if items.is_empty() {
                bail!(
                    "{}: no campaign specs (*.toml) or recordings (*.mcap, CSV runs) found",
                    dir.display()
                );
            }
            let pb = rbprops_cli::progress(items.len() as u64, "campaign");
            let (rows, failed) = rbprops_cli::campaign::run_all(&items, &dir, &uncertainty, &pb);
            pb.finish_and_clear();
            let csv = rbprops_cli::summary::to_csv(&rows)?;
            match &output {
                Some(p) => rbprops_cli::write_text(p, &csv)?,
                None => print!("{csv}"),
            }
            eprintln!(
                "rbprops: campaign: {} items, {} rows, {failed} failed",
                items.len(),
                rows.len()
            );
            if failed > 0 {
                bail!(
                    "{failed} of {} items failed (rows with method 'error' say why)",
                    items.len()
                );
            }
            Ok(())
        }
        Command::Summary {
            runs,
            campaign,
            set,
            origin,
        } => {
            let mut rows = Vec::new();
            for r in &runs {
                let inp = rbprops_cli::read_input(Some(r))?;
                let label = campaign.clone().unwrap_or_else(|| {
                    r.file_name()
                        .map(|n| n.to_string_lossy().into_owned())
                        .unwrap_or_default()
                });
                rows.extend(
                    rbprops_cli::summary::rows(&inp.record, &label, &set, &origin)
                        .with_context(|| r.display().to_string())?,
                );
            }
            print!("{}", rbprops_cli::summary::to_csv(&rows)?);
            Ok(())
        }
        Command::Report {
            summaries,
            output,
            title,
            figure,
        } => {
            let mut rows = Vec::new();
            for s in &summaries {
                let text = std::fs::read_to_string(s).with_context(|| s.display().to_string())?;
                rows.extend(
                    rbprops_cli::summary::from_csv(&text)
                        .with_context(|| s.display().to_string())?,
                );
            }
            rbprops_cli::report::write(&output, &title, &rows, &figure)
        }
    })
}
