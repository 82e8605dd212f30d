//! Shared plumbing of the rbprops executables: input/output selection, provenance,
//! progress on stderr and error reporting. Numerics live in the library crates.

use anyhow::{bail, Context, Result};
use rbprops_core::records::StageProvenance;
use rbprops_formats::{mcap_file, RunRecord};
use std::io::{IsTerminal, Read, Write};
use std::path::{Path, PathBuf};

pub mod campaign;
pub mod init_spec;
pub mod plots;
pub mod report;
pub mod stages;
pub mod summary;
pub mod table;

/// The MCAP magic bytes, to recognise a stream on stdin.
const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// An input as read: the record and the digest of its bytes (for provenance).
pub struct Input {
    pub record: RunRecord,
    pub sha256: String,
    pub name: String,
}

/// Reads a run from a path, or MCAP from stdin when the path is absent or `-`.
pub fn read_input(path: Option<&Path>) -> Result<Input> {
    match path {
        None => read_stdin(),
        Some(p) if p.as_os_str() == "-" => read_stdin(),
        Some(p) => {
            let name = p.display().to_string();
            if campaign::is_uff(p) {
                return uff_input(p);
            }
            let record = rbprops_formats::read_path(p)?;
            let sha256 = if p.is_dir() {
                digest_dir(p)?
            } else {
                rbprops_formats::sha256_hex(&std::fs::read(p).with_context(|| name.clone())?)
            };
            Ok(Input {
                record,
                sha256,
                name,
            })
        }
    }
}

/// A UFF file (datasets 58/58b with 15/2411 nodes) as a run record: geometry and FRFs.
fn uff_input(p: &Path) -> Result<Input> {
    let name = p.display().to_string();
    let bytes = std::fs::read(p).with_context(|| name.clone())?;
    let uff = rbprops_uff::parse(&bytes, &name)?;
    let (geometry, frf) = rbprops_uff::to_campaign(&uff)?;
    let mut record = RunRecord::default();
    record.set_geometry(&geometry);
    record.frf = Some(frf);
    Ok(Input {
        record,
        sha256: rbprops_formats::sha256_hex(&bytes),
        name,
    })
}

/// A UFF recording whose nodes and coordinate systems are in a separate UFF file
/// `geometry` (an analyser export with datasets 58 only, and the test geometry exported
/// once). The one place the campaign passes a geometry file to the UFF reader.
pub fn read_uff_with_geometry(data: &Path, geometry: &Path) -> Result<Input> {
    uff_geometry_supported(geometry)?;
    bail!(
        "{}: reading with the geometry of {} is not implemented",
        data.display(),
        geometry.display()
    )
}

/// Whether the UFF reader can take a separate geometry file: not yet (this build's
/// reader combines nodes and functions only within one file).
pub fn uff_geometry_supported(geometry: &Path) -> Result<()> {
    bail!(
        "{}: a separate UFF geometry file is not supported yet by this build's UFF reader; \
         put the nodes (dataset 15 or 2411) into each recording, or remove the `geometry` option",
        geometry.display()
    )
}

/// Writes the geometry and FRFs of a run as UFF: datasets 164, 2411 and 58 (ASCII, complex
/// double) for `.uff`/`.unv`, binary 58b for `.58b`. Other topics are not carried.
fn uff_output(rec: &RunRecord, p: &Path, binary: bool) -> Result<()> {
    let (geometry, frf) = rec.require_geometry_and_frf()?;
    let opts = rbprops_uff::WriteOptions {
        binary,
        ..Default::default()
    };
    let bytes = rbprops_uff::from_campaign(&geometry, frf, &opts)?;
    Ok(rbprops_formats::atomic::write_file(p, &bytes)?)
}

fn digest_dir(p: &Path) -> Result<String> {
    let mut names: Vec<PathBuf> = std::fs::read_dir(p)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file())
        .collect();
    names.sort();
    let mut all = Vec::new();
    for n in names {
        all.extend_from_slice(n.file_name().unwrap().to_string_lossy().as_bytes());
        all.extend_from_slice(&std::fs::read(&n)?);
    }
    Ok(rbprops_formats::sha256_hex(&all))
}

fn read_stdin() -> Result<Input> {
    let stdin = std::io::stdin();
    if stdin.is_terminal() {
        bail!("no input: name an input file, or pipe an MCAP stream into stdin (e.g. `frf-sim --example demo | …`)");
    }
    let mut bytes = Vec::new();
    stdin
        .lock()
        .read_to_end(&mut bytes)
        .context("reading stdin")?;
    if bytes.is_empty() {
        bail!("<stdin>: empty input (did the previous stage fail?)");
    }
    if !bytes.starts_with(MCAP_MAGIC) {
        bail!("<stdin>: not an MCAP stream (stdin carries MCAP; name CSV directories or UFF files as paths)");
    }
    let record = mcap_file::read(&bytes, "<stdin>")?;
    Ok(Input {
        record,
        sha256: rbprops_formats::sha256_hex(&bytes),
        name: "<stdin>".into(),
    })
}

/// Writes a run to a path (format from the path, atomically) or as MCAP to stdout.
/// Refuses to write binary MCAP to a terminal.
pub fn write_output(rec: &RunRecord, path: Option<&Path>) -> Result<()> {
    match path {
        Some(p) if p.as_os_str() != "-" => {
            let ext = p
                .extension()
                .map(|e| e.to_string_lossy().to_ascii_lowercase());
            if matches!(ext.as_deref(), Some("uff") | Some("unv")) {
                return uff_output(rec, p, false);
            }
            if matches!(ext.as_deref(), Some("58b")) {
                return uff_output(rec, p, true);
            }
            Ok(rbprops_formats::write_path(rec, p)?)
        }
        _ => {
            let stdout = std::io::stdout();
            if stdout.is_terminal() {
                bail!("stdout is a terminal: name an output with -o FILE.mcap or -o DIR (CSV), or pipe into the next stage");
            }
            let bytes = mcap_file::write(rec)?;
            let mut lock = stdout.lock();
            lock.write_all(&bytes).context("writing stdout")?;
            lock.flush().context("writing stdout")?;
            Ok(())
        }
    }
}

/// Provenance of this run of `tool`.
pub fn provenance(tool: &str, input_sha256: &str) -> StageProvenance {
    StageProvenance {
        tool: tool.into(),
        version: env!("CARGO_PKG_VERSION").into(),
        args: std::env::args().skip(1).collect(),
        input_sha256: input_sha256.into(),
    }
}

/// A progress bar on stderr, drawn only when stderr is a terminal.
pub fn progress(len: u64, what: &str) -> indicatif::ProgressBar {
    if !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let pb = indicatif::ProgressBar::new(len);
    pb.set_style(
        indicatif::ProgressStyle::with_template(
            "{prefix} [{bar:40}] {pos}/{len} {elapsed_precise} eta {eta}",
        )
        .unwrap()
        .progress_chars("=> "),
    );
    pb.set_prefix(what.to_string());
    pb
}

/// Runs a stage's main body, printing `error: …` with its causes and exiting 1 on error.
pub fn run(tool: &str, body: impl FnOnce() -> Result<()>) -> std::process::ExitCode {
    match body() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{tool}: error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// True when stdout is a terminal (print tables, not data).
pub fn stdout_is_terminal() -> bool {
    std::io::stdout().is_terminal()
}

/// Parses `FMIN:FMAX` (Hz).
pub fn parse_band(s: &str) -> Result<(f64, f64)> {
    let (a, b) = s
        .split_once(':')
        .with_context(|| format!("band '{s}' is not FMIN:FMAX"))?;
    let (a, b): (f64, f64) = (
        a.trim()
            .parse()
            .with_context(|| format!("band '{s}': bad FMIN"))?,
        b.trim()
            .parse()
            .with_context(|| format!("band '{s}': bad FMAX"))?,
    );
    if !(a.is_finite() && b.is_finite() && a >= 0.0 && b > a) {
        bail!("band '{s}': need 0 ≤ FMIN < FMAX");
    }
    Ok((a, b))
}

/// Prints warnings on stderr, prefixed by the tool name.
pub fn warn_all<'a>(tool: &str, warnings: impl IntoIterator<Item = &'a String>) {
    for w in warnings {
        eprintln!("{tool}: warning: {w}");
    }
}

/// Writes a text file (a plot, a report) atomically, creating its directory.
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    Ok(rbprops_formats::atomic::write_file(path, text.as_bytes())?)
}

/// Writes named SVG documents into `dir` (created if needed).
pub fn write_plots(dir: &Path, plots: &[(String, String)]) -> Result<()> {
    for (name, svg) in plots {
        write_text(&dir.join(name), svg)?;
    }
    Ok(())
}
