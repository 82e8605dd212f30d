//! `rbprops`: utilities around the pipeline (format conversion).

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
    },
}

fn main() -> std::process::ExitCode {
    rbprops_cli::run("rbprops", || match Args::parse().command {
        Command::Convert { input, output } => {
            let inp = rbprops_cli::read_input(input.as_deref())?;
            rbprops_cli::write_output(&inp.record, output.as_deref())
        }
    })
}
