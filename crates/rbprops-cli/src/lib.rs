//! Shared plumbing of the rbprops executables: input/output selection, provenance,
//! progress on stderr and error reporting. Numerics live in the library crates.

#![warn(missing_docs)]

use anyhow::{bail, Context, Result};
use rbprops_core::records::StageProvenance;
use rbprops_formats::digest::DigestCheck;
use rbprops_formats::{mcap_file, RunRecord};
use std::io::{IsTerminal, Read, Write};
use std::path::{Path, PathBuf};

pub mod args;
pub mod campaign;
pub mod channel_table;
pub mod coherence;
pub mod frf_est;
pub mod html;
pub mod init_spec;
pub mod plan;
pub mod plots;
pub mod report;
pub mod samples;
pub mod shard;
pub mod stages;
pub mod summary;
pub mod table;
pub mod validate;
pub mod variance;
pub mod warnings;

/// `eprintln!` that never panics: a failed write to stderr (closed, full device) is
/// ignored, so the program still ends with its own status.
#[macro_export]
macro_rules! say {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($t)*);
    }};
}

/// Writes `text` to stdout, returning the error (a full device, a closed pipe) instead of
/// panicking as `print!` does.
pub fn out(text: &str) -> Result<()> {
    let mut o = std::io::stdout().lock();
    o.write_all(text.as_bytes()).context("writing stdout")?;
    o.flush().context("writing stdout")
}

/// Reads a whole input file once (a FIFO or `<(zcat …)` works), recording it as an input
/// of the run so that no output is written over it.
pub fn read_file(p: &Path) -> Result<Vec<u8>> {
    rbprops_formats::atomic::register_input(p);
    std::fs::read(p).with_context(|| p.display().to_string())
}

/// [`read_file`] as UTF-8 text.
pub fn read_text(p: &Path) -> Result<String> {
    String::from_utf8(read_file(p)?).map_err(|_| anyhow::anyhow!("{}: not UTF-8 text", p.display()))
}

/// The MCAP magic bytes, to recognise a stream on stdin.
const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// An input as read: the record and the digest of its bytes (for provenance).
pub struct Input {
    /// The run it holds (geometry, FRFs, earlier stages' records).
    pub record: RunRecord,
    /// SHA-256 (hex) of the input bytes, for the next stage's provenance.
    pub sha256: String,
    /// The input's name as given (path, or `-` for stdin).
    pub name: String,
    /// What the integrity check could not verify (printed under `-v`).
    pub notes: Vec<String>,
    /// What the reader noticed in the input (a UFF export's oddities, how FRFs were
    /// estimated), printed by [`read_stage_input`]; kept here by [`read_stage_input_quiet`].
    pub warnings: Vec<warnings::Diagnostic>,
}

/// How a UFF input is read: a separate geometry file (`--geometry`: UFF with datasets
/// 15/18/164/2411/2420, or a campaign spec whose point ids are the node numbers) and a
/// channel map (`--channels`) for datasets whose record 6 gives node 0.
#[derive(Debug, Clone, Default)]
pub struct UffInputOptions {
    /// `--geometry`: the separate geometry file.
    pub geometry: Option<PathBuf>,
    /// `--channels`: the channel map (CSV).
    pub channels: Option<PathBuf>,
    /// How time histories are made into FRFs (frf-est's defaults unless a campaign file's
    /// `[frf_est]` table says otherwise).
    pub estimation: frf_est::EstimationOptions,
}

/// The `--geometry`/`--channels` options of the stages that read UFF inputs.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct UffArgs {
    /// UFF input: the geometry in a separate file (UFF with datasets 15/18/164/2411/2420,
    /// or a campaign spec whose point ids are the node numbers).
    #[arg(long)]
    pub geometry: Option<PathBuf>,
    /// UFF input: channel map (CSV) for datasets whose record 6 has node 0 or direction 0
    /// (`rbprops convert FILE --channel-template map.csv` writes one to fill in).
    #[arg(long)]
    pub channels: Option<PathBuf>,
}

impl UffArgs {
    /// The reading options these arguments name.
    pub fn options(&self) -> UffInputOptions {
        UffInputOptions {
            geometry: self.geometry.clone(),
            channels: self.channels.clone(),
            ..Default::default()
        }
    }
}

/// `--averages N` of the stages that read FRF exports with coherence (docs/formats.md,
/// Coherence): the number of averages the FRFs were estimated over, so that each line's
/// variance follows from its coherence ([`variance::from_coherence`]).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct AveragesArg {
    /// FRF export with coherence (UFF function type 6): the number of averages behind
    /// the FRFs; each line's variance |H|²(1 − γ²)/(n γ²) then goes to the line-variance
    /// topic, which model-check uses as its noise model.
    #[arg(long, value_name = "N", value_parser = crate::args::averages)]
    pub averages: Option<usize>,
}

/// The run a pipeline stage reads and the run it writes (flattened into its arguments).
#[derive(clap::Args, Debug, Clone, Default)]
pub struct StageIo {
    /// Input run (MCAP, CSV directory); default MCAP on stdin.
    pub input: Option<PathBuf>,
    /// The input's integrity options.
    #[command(flatten)]
    pub checks: InputChecks,
    /// Output: FILE.mcap or a CSV directory; default MCAP on stdout.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Replace an output path that is not a previous rbprops output (a non-empty
    /// directory that is not a CSV run, a file of another kind). Never an input.
    #[arg(long)]
    pub force: bool,
}

impl StageIo {
    /// Reads the input of the stage `tool` ([`read_stage_input`]) with the options of a
    /// UFF input.
    pub fn read(&self, tool: &str, uff: &UffInputOptions) -> Result<Input> {
        rbprops_formats::atomic::set_force(self.force);
        read_stage_input(tool, self.input.as_deref(), &self.checks, uff)
    }

    /// Writes the stage's run record to the output ([`write_output`]).
    pub fn write(&self, rec: &RunRecord) -> Result<()> {
        rbprops_formats::atomic::set_force(self.force);
        write_output(rec, self.output.as_deref())
    }

    /// [`Self::read`] for a stage that works one excitation at a time: a regular MCAP
    /// file's FRF set is left in the file ([`mcap_file::read_file_deferred`]) and given
    /// by the [`mcap_file::DeferredFrf`], and so is MCAP on stdin once copied to a
    /// temporary file; any other input (a named FIFO, CSV, UFF) is read whole, its set in
    /// the record (issue 41).
    pub fn read_deferring(
        &self,
        tool: &str,
        uff: &UffInputOptions,
    ) -> Result<(Input, Option<mcap_file::DeferredFrf>)> {
        rbprops_formats::atomic::set_force(self.force);
        let plain = self.input.as_deref().filter(|p| p.as_os_str() != "-");
        match plain {
            None if uff.geometry.is_none() && uff.channels.is_none() => {
                // A pipe cannot be read twice: its bytes go to an unnamed temporary file
                // (removed once open), which is then read like any MCAP file; without a
                // writable temporary directory stdin is read whole, as before.
                let Some(spool) = spool_stdin()? else {
                    return Ok((self.read(tool, uff)?, None));
                };
                let (record, deferred, notes, sha256) =
                    mcap_file::read_file_deferred(spool.path(), "<stdin>")?;
                drop(spool);
                let input = Input {
                    record,
                    sha256,
                    name: "<stdin>".into(),
                    notes,
                    warnings: Vec::new(),
                };
                Ok((finish(tool, input, &self.checks)?, deferred))
            }
            Some(p) if is_mcap_file(p) && uff.geometry.is_none() && uff.channels.is_none() => {
                let name = p.display().to_string();
                rbprops_formats::atomic::register_input(p);
                let (record, deferred, notes, sha256) = mcap_file::read_file_deferred(p, &name)?;
                let input = Input {
                    record,
                    sha256,
                    name,
                    notes,
                    warnings: Vec::new(),
                };
                Ok((finish(tool, input, &self.checks)?, deferred))
            }
            _ => Ok((self.read(tool, uff)?, None)),
        }
    }

    /// [`Self::write`] with the FRF set of a [`Self::read_deferring`] input, copied through
    /// one excitation at a time to an MCAP output (a CSV or UFF output takes it whole).
    pub fn write_with(
        &self,
        rec: &RunRecord,
        deferred: Option<&mcap_file::DeferredFrf>,
    ) -> Result<()> {
        rbprops_formats::atomic::set_force(self.force);
        let deferred = deferred.map(|d| d as &dyn rbprops_core::FrfSource);
        write_output_with(rec, deferred, self.output.as_deref())
    }
}

/// [`write_output`] of a record whose FRF set, when `deferred` is given, comes from that
/// source (an input left in its file, [`StageIo::read_deferring`], or a simulation made
/// excitation by excitation): copied through one excitation at a time to MCAP.
pub fn write_output_with(
    rec: &RunRecord,
    deferred: Option<&dyn rbprops_core::FrfSource>,
    path: Option<&Path>,
) -> Result<()> {
    let Some(d) = deferred else {
        return write_output(rec, path);
    };
    let res = write_deferred(rec, d, path);
    if res.is_err() {
        rbprops_formats::atomic::remove_temporaries();
    }
    res
}

/// [`write_output`] of a record whose FRF set is `d`'s.
fn write_deferred(
    rec: &RunRecord,
    d: &dyn rbprops_core::FrfSource,
    path: Option<&Path>,
) -> Result<()> {
    let src = Some(d);
    match path.filter(|p| p.as_os_str() != "-") {
        Some(p) if rbprops_formats::Format::from_path(p)? == rbprops_formats::Format::Mcap => {
            Ok(rbprops_formats::atomic::write_file_with(p, |w| {
                mcap_file::write_to_with(rec, src, w).map(drop)
            })?)
        }
        Some(p) => {
            let mut whole = rec.clone();
            whole.frf = Some(rbprops_core::FrfSet::from_source(d)?);
            write_output_inner(&whole, Some(p))
        }
        None => write_mcap_stdout(rec, src),
    }
}

/// Stdout for binary MCAP: refused when it is a terminal.
fn mcap_stdout() -> Result<std::io::Stdout> {
    let stdout = std::io::stdout();
    if stdout.is_terminal() {
        bail!("stdout is a terminal: name an output with -o FILE.mcap or -o DIR (CSV), or pipe into the next stage");
    }
    Ok(stdout)
}

/// The run as MCAP on stdout (refused when stdout is a terminal), its FRFs from `frf`:
/// written as it is made, chunk by chunk, never held whole (the bytes are a file's,
/// `mcap_file::write_stream_with`).
fn write_mcap_stdout(rec: &RunRecord, frf: Option<&dyn rbprops_core::FrfSource>) -> Result<()> {
    let stdout = mcap_stdout()?;
    let sink = std::io::BufWriter::with_capacity(1 << 16, stdout.lock());
    let mut sink = mcap_file::write_stream_with(rec, frf, sink).context("writing stdout")?;
    sink.flush().context("writing stdout")?;
    Ok(())
}

/// The integrity options of every stage that reads a run (flattened into its arguments).
#[derive(clap::Args, Debug, Clone, Default)]
pub struct InputChecks {
    /// Read a CSV directory or UFF file whose content no longer matches the digest recorded
    /// when it was written (after editing it by hand, knowingly). MCAP CRCs are always checked.
    #[arg(long)]
    pub ignore_digest: bool,
    /// Notes on stderr: what the input's integrity check could not verify (another
    /// writer's MCAP without CRCs, a CSV directory or UFF file without a digest).
    #[arg(short, long)]
    pub verbose: bool,
}

/// Reads a run from a path, or MCAP from stdin when the path is absent or `-`, with every
/// integrity check and no notes printed (the campaign and summary tools).
pub fn read_input(path: Option<&Path>) -> Result<Input> {
    read_input_checked("rbprops", path, &InputChecks::default())
}

/// [`read_input`] for the stage `tool` with its [`InputChecks`]: every MCAP CRC is
/// verified; a CSV directory's or UFF file's content digest is verified unless
/// `--ignore-digest` (then a mismatch is a warning); `-v` prints what could not be verified.
pub fn read_input_checked(tool: &str, path: Option<&Path>, checks: &InputChecks) -> Result<Input> {
    read_stage_input(tool, path, checks, &UffInputOptions::default())
}

/// [`read_input_checked`] with the options of a UFF input (`--geometry`, `--channels`; an
/// error for other inputs).
pub fn read_stage_input(
    tool: &str,
    path: Option<&Path>,
    checks: &InputChecks,
    uff: &UffInputOptions,
) -> Result<Input> {
    let input = read_stage_input_quiet(tool, path, checks, uff)?;
    let mut w = warnings::Collector::default();
    for d in &input.warnings {
        w.add_from(tool, d.clone());
    }
    w.print(checks.verbose);
    Ok(input)
}

/// [`read_stage_input`] without printing the reader's warnings (they are in
/// [`Input::warnings`]; the campaign gathers them per item).
pub fn read_stage_input_quiet(
    tool: &str,
    path: Option<&Path>,
    checks: &InputChecks,
    uff: &UffInputOptions,
) -> Result<Input> {
    let plain = path.filter(|p| p.as_os_str() != "-");
    if (uff.geometry.is_some() || uff.channels.is_some()) && !plain.is_some_and(campaign::is_uff) {
        bail!("--geometry and --channels apply to UFF inputs (.uff/.unv/.58/.58b) only");
    }
    let input = match plain {
        None => read_stdin()?,
        Some(p) => {
            let name = p.display().to_string();
            rbprops_formats::atomic::register_input(p);
            if p.is_dir() {
                let check = rbprops_formats::digest::check_csv(p)?;
                let notes = digest_verdict(tool, &name, check, checks)?;
                Input {
                    record: rbprops_formats::read_path(p)?,
                    sha256: digest_dir(p)?,
                    name,
                    notes,
                    warnings: Vec::new(),
                }
            } else if is_mcap_file(p) {
                // A regular MCAP file is parsed as it is read, never held whole (issue 41).
                let (record, notes, sha256) = mcap_file::read_file_checked(p, &name)?;
                Input {
                    record,
                    sha256,
                    name,
                    notes,
                    warnings: Vec::new(),
                }
            } else {
                // Read once (a FIFO or `<(zcat …)` cannot be opened twice); the format
                // from the bytes first, then the name.
                let bytes = read_file(p)?;
                if !bytes.starts_with(MCAP_MAGIC) && (campaign::is_uff(p) || looks_like_uff(&bytes))
                {
                    return finish(tool, uff_input(tool, p, bytes, checks, uff)?, checks);
                }
                let (record, notes) = if bytes.starts_with(MCAP_MAGIC) {
                    mcap_file::read_checked(&bytes, &name)?
                } else if bytes.is_empty() {
                    bail!("{name}: empty file")
                } else {
                    match rbprops_formats::Format::from_path(p)? {
                        rbprops_formats::Format::Mcap => mcap_file::read_checked(&bytes, &name)?,
                        rbprops_formats::Format::CsvDir => bail!(
                            "{name}: neither MCAP nor UFF, and not a directory (a CSV run is a directory)"
                        ),
                    }
                };
                Input {
                    record,
                    sha256: rbprops_formats::sha256_hex(&bytes),
                    name,
                    notes,
                    warnings: Vec::new(),
                }
            }
        }
    };
    finish(tool, input, checks)
}

/// True for a regular file (not a FIFO, which cannot be read twice) that begins with
/// the MCAP magic bytes.
fn is_mcap_file(p: &Path) -> bool {
    use std::io::Read;
    if !std::fs::metadata(p).is_ok_and(|m| m.is_file()) {
        return false;
    }
    let mut head = [0u8; 8];
    std::fs::File::open(p)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok()
        && head[..] == *MCAP_MAGIC
}

fn finish(tool: &str, input: Input, checks: &InputChecks) -> Result<Input> {
    if checks.verbose {
        for n in &input.notes {
            say!("{tool}: note: {}: {n}", input.name);
        }
    }
    Ok(input)
}

/// A universal file begins with a `-1` delimiter line.
fn looks_like_uff(bytes: &[u8]) -> bool {
    let head = &bytes[..bytes.len().min(256)];
    String::from_utf8_lossy(head)
        .lines()
        .find(|l| !l.trim().is_empty())
        .is_some_and(|l| l.trim() == "-1")
}

/// What a content-digest check means for the run: an error on a mismatch (a warning with
/// `--ignore-digest`), a note when there is no digest to check.
fn digest_verdict(
    tool: &str,
    name: &str,
    check: DigestCheck,
    checks: &InputChecks,
) -> Result<Vec<String>> {
    match check {
        DigestCheck::Matches { .. } => Ok(Vec::new()),
        DigestCheck::Unclaimed => Ok(vec![
            "no content digest recorded (not written by rbprops): contents not verified".into(),
        ]),
        DigestCheck::Mismatch {
            tool: writer,
            recorded,
            found,
        } => {
            let what = format!(
                "{name}: content does not match the digest {writer} recorded when writing it (sha256 {}…, now {}…): it was changed after writing",
                &recorded[..recorded.len().min(12)],
                &found[..found.len().min(12)]
            );
            if checks.ignore_digest {
                say!("{tool}: warning: {what}; proceeding (--ignore-digest)");
                Ok(Vec::new())
            } else {
                bail!("{what} (if you edited it on purpose, rerun with --ignore-digest)")
            }
        }
    }
}

/// Reads and parses a universal file.
pub fn parse_uff(p: &Path) -> Result<rbprops_uff::UffFile> {
    let name = p.display().to_string();
    let bytes = read_file(p)?;
    Ok(rbprops_uff::parse(&bytes, &name)?)
}

/// Whether `p` names time histories in a format besides UFF: a directory holding
/// `records.csv` (the CSV layout) or an MCAP file.
pub fn is_time_history_recording(p: &Path) -> bool {
    p.join("records.csv").is_file() || p.extension().and_then(|e| e.to_str()) == Some("mcap")
}

/// The time histories at `p` as datasets 58 of function type 1 (one reader per format,
/// `rbprops_uff::timerec`): a universal file, an MCAP file with the
/// `/rbprops/time_history` topic, or a CSV directory (`records.csv`, `channels.csv` and
/// the record files); and the digest of the bytes read (for provenance).
pub fn read_time_histories(p: &Path) -> Result<TimeHistories> {
    let name = p.display().to_string();
    let mut digest = rbprops_formats::Sha256Stream::default();
    let in_memory = |data, digest| TimeHistories {
        data,
        samples: Box::new(samples::InMemory),
        digest,
    };
    if p.is_dir() {
        let rec = rbprops_uff::timerec::from_csv(&name, |f| {
            let text = std::fs::read_to_string(p.join(f)).map_err(|e| e.to_string())?;
            digest.update(f.as_bytes());
            digest.update(&[0]);
            digest.update(text.as_bytes());
            Ok(text)
        })?;
        return Ok(in_memory(rec.to_uff()?, digest));
    }
    if p.extension().and_then(|e| e.to_str()) == Some("mcap") {
        let bytes = read_file(p)?;
        digest.update(&bytes);
        let (rec, _) = rbprops_formats::mcap_file::read_checked(&bytes, &name)?;
        drop(bytes);
        let msgs: Vec<rbprops_formats::wire::TimeHistoryMsg> =
            rec.get(rbprops_formats::topics::TIME_HISTORY)?;
        if msgs.is_empty() {
            bail!(
                "{name}: no time histories (no {} topic)",
                rbprops_formats::topics::TIME_HISTORY
            );
        }
        let th = rbprops_uff::timerec::from_messages(&name, &msgs)?;
        return Ok(in_memory(th.to_uff()?, digest));
    }
    // A universal file is parsed as it is read, one dataset at a time, and each time
    // record's samples are set aside in a temporary file as soon as they are parsed: the
    // file's bytes and its samples are never all in memory (`samples::SetAside`).
    rbprops_formats::atomic::register_input(p);
    let file = std::fs::File::open(p).with_context(|| name.clone())?;
    let mut store = samples::SetAside::new()?;
    let data = rbprops_uff::parse_reader_each(
        std::io::BufReader::new(file),
        &name,
        |b| digest.update(b),
        |d| store.take(d, &name),
    )?;
    Ok(TimeHistories {
        data,
        samples: Box::new(store),
        digest,
    })
}

/// A time-history recording as [`read_time_histories`] reads it.
pub struct TimeHistories {
    /// Every dataset, time records with or without their samples.
    pub data: rbprops_uff::UffFile,
    /// Where the time records' samples are read from.
    pub samples: Box<dyn samples::SampleSource>,
    /// The digest of every byte read.
    pub digest: rbprops_formats::Sha256Stream,
}

/// A UFF data file read into a campaign, with the geometry file and channel map of
/// `opts`: the call behind `--geometry`/`--channels` (and a campaign file's `geometry`).
/// Returns the campaign and the digest of all the bytes read.
pub fn read_uff_campaign(
    p: &Path,
    opts: &UffInputOptions,
) -> Result<(rbprops_uff::UffCampaign, String)> {
    read_uff_campaign_bytes(p, read_file(p)?, opts)
}

/// [`read_uff_campaign`] of bytes already read from `p`.
pub fn read_uff_campaign_bytes(
    p: &Path,
    bytes: Vec<u8>,
    opts: &UffInputOptions,
) -> Result<(rbprops_uff::UffCampaign, String)> {
    let name = p.display().to_string();
    let data = rbprops_uff::parse(&bytes, &name)?;
    let (campaign, side) = uff_campaign_of(&data, opts)?;
    let mut digest_input = bytes;
    digest_input.extend_from_slice(&side);
    Ok((campaign, rbprops_formats::sha256_hex(&digest_input)))
}

/// The campaign of parsed UFF datasets with the geometry and channel map `opts` name
/// (read here), and the bytes of those side files (for the input's digest).
pub fn uff_campaign_of(
    data: &rbprops_uff::UffFile,
    opts: &UffInputOptions,
) -> Result<(rbprops_uff::UffCampaign, Vec<u8>)> {
    let mut digest_input = Vec::new();
    let map = match &opts.channels {
        Some(m) => {
            let text = read_text(m)?;
            digest_input.extend_from_slice(text.as_bytes());
            Some(
                rbprops_uff::ChannelMap::parse(&text, &m.display().to_string())
                    .map_err(anyhow::Error::msg)?,
            )
        }
        None => None,
    };
    let campaign = match &opts.geometry {
        None => rbprops_uff::read_campaign(
            data,
            &rbprops_uff::ReadOptions {
                geometry: rbprops_uff::GeometrySource::InFile,
                channels: map.as_ref(),
            },
        )?,
        Some(g) if campaign::is_uff(g) => {
            let gbytes = read_file(g)?;
            digest_input.extend_from_slice(&gbytes);
            let geo = rbprops_uff::parse(&gbytes, &g.display().to_string())?;
            rbprops_uff::read_with_geometry(data, &geo, map.as_ref())?
        }
        Some(g) => {
            // A campaign spec: its points (ids = node numbers) in SI, global axes.
            let text = read_text(g)?;
            digest_input.extend_from_slice(text.as_bytes());
            let spec = rbprops_sim::CampaignSpec::from_toml_str(&text)
                .map_err(|e| anyhow::anyhow!("{}: {e}", g.display()))?;
            let geometry = spec
                .geometry()
                .map_err(|e| anyhow::anyhow!("{}: {e}", g.display()))?;
            rbprops_uff::read_campaign(
                data,
                &rbprops_uff::ReadOptions {
                    geometry: rbprops_uff::GeometrySource::Points(&geometry.points),
                    channels: map.as_ref(),
                },
            )?
        }
    };
    Ok((campaign, digest_input))
}

/// A UFF file (datasets 58/58b with 15/2411 nodes) as a run record: geometry, FRFs and,
/// when the file has them, the coherence topic. Warnings go to stderr.
/// A digest written into the file by rbprops is checked first.
fn uff_input(
    tool: &str,
    p: &Path,
    bytes: Vec<u8>,
    checks: &InputChecks,
    opts: &UffInputOptions,
) -> Result<Input> {
    let name = p.display().to_string();
    let notes = digest_verdict(
        tool,
        &name,
        rbprops_formats::digest::check_uff(&bytes),
        checks,
    )?;
    let mut data = rbprops_uff::parse(&bytes, &name)?;
    if is_time_history_export(&data) {
        // Time histories without FRFs: estimated as `frf-est` does (by default, or with a
        // campaign file's `[frf_est]` options), so every stage (and the campaign) takes an
        // analyser's time-data export directly.
        // What the file holds, for the error, before the estimate lets the samples go.
        let holds = rbprops_uff::inventory(&data);
        let est = frf_est::estimate_uff(&mut data, &samples::InMemory, opts, &opts.estimation)
            .map_err(|e| {
                anyhow::anyhow!(
                    "{name}: no FRF datasets (dataset 58 with function type 4), and its time histories could not be made into FRFs ({e:#}; see frf-est --help). It holds:\n{holds}"
                )
            })?;
        let mut digest_input = bytes;
        digest_input.extend_from_slice(&est.side_digest);
        let mut warnings = input_notes(&est.warnings);
        warnings.push(warnings::note_of(
            "",
            warnings::DiagnosticKind::FrfEstimation,
            Default::default(),
            &format!("FRFs estimated from the time histories ({})", est.summary),
        ));
        return Ok(Input {
            record: est.record,
            sha256: rbprops_formats::sha256_hex(&digest_input),
            name,
            notes,
            warnings,
        });
    }
    let (c, side) = uff_campaign_of(&data, opts)?;
    let mut digest_input = bytes;
    digest_input.extend_from_slice(&side);
    let sha256 = rbprops_formats::sha256_hex(&digest_input);
    let mut record = RunRecord::default();
    record.set_geometry(&c.geometry);
    if let Some(coh) = &c.coherence {
        coherence::set(&mut record, &c.geometry, coh);
    }
    record.frf = Some(c.frf);
    let mut texts = c.warnings;
    texts.extend(variance::declared_by_export(&mut record, &data, &name)?);
    Ok(Input {
        record,
        sha256,
        name,
        notes,
        warnings: input_notes(&texts),
    })
}

/// The UFF reader's notes, typed by their source (the stage is the reading tool's,
/// filled in when printed).
pub fn input_notes(texts: &[String]) -> Vec<warnings::Diagnostic> {
    texts
        .iter()
        .map(|t| {
            warnings::note_of(
                "",
                warnings::DiagnosticKind::InputConversion,
                Default::default(),
                t,
            )
        })
        .collect()
}

/// A universal file holding time histories (dataset 58, function type 1) and no FRF
/// (function type 4).
pub fn is_time_history_export(data: &rbprops_uff::UffFile) -> bool {
    rbprops_uff::timehist::has_time_histories(data)
        && !data
            .datasets
            .iter()
            .any(|d| matches!(&d.record, rbprops_uff::Record::Function(f) if f.function_type == 4))
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
    let bytes = rbprops_formats::digest::uff_stamp(&bytes);
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

/// Stdin copied to a temporary file (`$TMPDIR`), checked to be a non-empty MCAP stream
/// with the errors [`read_stdin`] gives; `None` (stdin untouched) when no temporary
/// file can be made.
fn spool_stdin() -> Result<Option<tempfile::NamedTempFile>> {
    let stdin = std::io::stdin();
    if stdin.is_terminal() {
        bail!("no input: name an input file, or pipe an MCAP stream into stdin (e.g. `frf-sim --example demo | …`)");
    }
    let Ok(mut spool) = tempfile::NamedTempFile::new() else {
        return Ok(None);
    };
    let n = std::io::copy(&mut stdin.lock(), spool.as_file_mut()).context("reading stdin")?;
    if n == 0 {
        bail!("<stdin>: empty input (did the previous stage fail?)");
    }
    spool
        .as_file_mut()
        .flush()
        .context("a temporary file for stdin")?;
    let mut head = [0u8; 8];
    let magic = std::fs::File::open(spool.path())
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok()
        && head[..] == *MCAP_MAGIC;
    if !magic {
        bail!("<stdin>: not an MCAP stream (stdin carries MCAP; name CSV directories or UFF files as paths)");
    }
    Ok(Some(spool))
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
    let (record, notes) = mcap_file::read_checked(&bytes, "<stdin>")?;
    Ok(Input {
        record,
        sha256: rbprops_formats::sha256_hex(&bytes),
        name: "<stdin>".into(),
        notes,
        warnings: Vec::new(),
    })
}

/// Writes a run to a path (format from the path, atomically) or as MCAP to stdout.
/// Refuses to write binary MCAP to a terminal.
pub fn write_output(rec: &RunRecord, path: Option<&Path>) -> Result<()> {
    let res = write_output_inner(rec, path);
    if res.is_err() {
        rbprops_formats::atomic::remove_temporaries();
    }
    res
}

fn write_output_inner(rec: &RunRecord, path: Option<&Path>) -> Result<()> {
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
        _ => write_mcap_stdout(
            rec,
            rec.frf.as_ref().map(|f| f as &dyn rbprops_core::FrfSource),
        ),
    }
}

/// The command line recorded in provenance instead of the process's own (see
/// [`set_provenance_args`]).
static PROVENANCE_ARGS: std::sync::Mutex<Option<Vec<String>>> = std::sync::Mutex::new(None);

/// Records `args` as the command line in the provenance of every stage this process runs
/// from now on. `rbprops campaign` records the campaign's command line without its output
/// options (`-o`, `--runs`, `--shard`, `-v`), so that an item's run does not depend on
/// where the outputs went or which shard ran it.
pub fn set_provenance_args(args: Vec<String>) {
    *PROVENANCE_ARGS.lock().unwrap_or_else(|p| p.into_inner()) = Some(args);
}

/// Provenance of this run of `tool`.
pub fn provenance(tool: &str, input_sha256: &str) -> StageProvenance {
    let args = PROVENANCE_ARGS
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .clone()
        .unwrap_or_else(|| std::env::args().skip(1).collect());
    StageProvenance {
        tool: tool.into(),
        version: env!("CARGO_PKG_VERSION").into(),
        args,
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

/// Gives every allocation of 256 KiB or more its own mapping, returned to the system when
/// freed (glibc's fixed mmap threshold). glibc otherwise raises the threshold each time a
/// large block is freed, and later large blocks come from the heap, where what is freed
/// stays resident: `frf-est`'s phases (hit records, spectral sums, the output's FRF set
/// and topics) then add up. Measured on Test Case II's 3.07 M samples (docs/results.md):
/// peak RSS 25.3–26.7 MB → 22.7–22.8 MB, wall time unchanged; with 64 KiB the peak is
/// 20 MB but the per-hit records' page faults cost 40 % more time.
///
/// Also `modal-fit` and `ni-select` (issue 41): at 3 excitations × 102,401 lines
/// `modal-fit` peaked at 215 MB resident with 133 MB of live allocations, 114 MB with
/// this, at the same time. `rb-solve` only with its bootstrap, whose model is built
/// one excitation after another at many lines (3 × 102,401: 89 → 60 MB, 1.9 → 2.3 s;
/// 48 × 1,601: 182 → 146 MB, 4.8 → 5.4 s): its linearised propagation at 192
/// excitations allocates many dense matrices of 4–16 MB, whose fresh pages then cost
/// twice the wall time (17.6 → 37 s, 35 s of it in the kernel).
pub fn return_large_buffers() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets an allocator parameter; called before any thread starts.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 256 * 1024);
    }
}

/// Lets a deferred MCAP input keep raw copies of the excitations a stage asks for more
/// than once, in an unnamed temporary file
/// ([`mcap_file::DeferredFrf::keep_values_in`]); without a writable temporary directory
/// they are decoded again.
pub fn keep_reread_values(deferred: &mut Option<mcap_file::DeferredFrf>) {
    if let (Some(d), Ok(scratch)) = (deferred.as_mut(), tempfile::tempfile()) {
        d.keep_values_in(scratch);
    }
}

/// One malloc arena for every thread. glibc gives each thread that allocates its own
/// arena, and memory one arena freed serves no other: `modal-fit`'s poly-reference fit
/// of a set-up, run on whichever pool thread takes it, met fresh pages for what the
/// other thread's per-excitation fits had freed (192 excitations × 1,601 lines: peak
/// RSS 66 → 42 MB, time unchanged, five runs each). Not for `rb-solve`, whose
/// bootstrap replicates allocate on both threads at once (17.8 → 21.6 s, no memory
/// saved).
pub fn one_malloc_arena() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets an allocator parameter; called before any thread starts.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, 1);
    }
}

/// Leaves up to 4 MB free at the top of the heap before glibc returns it to the system.
/// A fixed mmap threshold ([`return_large_buffers`]) also fixes glibc's trim threshold at
/// 128 kB, and `rb-solve`'s bootstrap replicates, which free and take again a few hundred
/// kB each, then met fresh pages every time: 3 × 1,601 lines 0.01 → 0.25 s of system
/// time (0.25 → 0.45 s wall); with this 0.01 s again, and 3 × 102,401 lines peak 59 →
/// 62 MB.
pub fn keep_heap_top() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets an allocator parameter; called before any thread starts.
    unsafe {
        libc::mallopt(libc::M_TRIM_THRESHOLD, 4 << 20);
    }
}

/// Runs a stage's main body, printing `error: …` with its causes and exiting 1 on error.
///
/// A closed stdout (`stage | head -c 100`) ends the stage quietly, as Unix tools do: the
/// default SIGPIPE action is restored, so the write that meets the closed pipe ends the
/// process (status 141 from the shell) with nothing on stderr; elsewhere a broken-pipe
/// error ends it with status 0.
pub fn run(tool: &str, body: impl FnOnce() -> Result<()>) -> std::process::ExitCode {
    #[cfg(unix)]
    // SAFETY: setting a signal disposition to SIG_DFL before any thread starts; Rust's
    // runtime sets SIGPIPE to ignore at start-up, which turns it into EPIPE errors.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    #[cfg(unix)]
    signals::install();
    let res = body();
    rbprops_formats::atomic::remove_temporaries();
    match res {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) if is_broken_pipe(&e) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            say!("{tool}: error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// SIGINT, SIGTERM and SIGHUP: the temporary files of the output being written are
/// removed, then the process exits with 128 + the signal number (the shell's convention).
///
/// The signals are blocked in every thread (set before any thread starts, so the worker
/// threads inherit the mask) and taken by one thread with `sigwait`: the clean-up runs as
/// ordinary code, not in an asynchronous signal handler.
#[cfg(unix)]
mod signals {
    const SIGNALS: [libc::c_int; 3] = [libc::SIGINT, libc::SIGTERM, libc::SIGHUP];

    fn set() -> libc::sigset_t {
        // SAFETY: sigemptyset/sigaddset initialise and fill a local set.
        unsafe {
            let mut s: libc::sigset_t = std::mem::zeroed();
            libc::sigemptyset(&mut s);
            for sig in SIGNALS {
                libc::sigaddset(&mut s, sig);
            }
            s
        }
    }

    pub fn install() {
        let s = set();
        // SAFETY: blocks the signals in the calling (main) thread, before other threads.
        let rc = unsafe { libc::pthread_sigmask(libc::SIG_BLOCK, &s, std::ptr::null_mut()) };
        if rc != 0 {
            return;
        }
        let spawned = std::thread::Builder::new()
            .name("signals".into())
            .spawn(move || loop {
                let mut sig: libc::c_int = 0;
                // SAFETY: waits for one of the blocked signals of `s`.
                if unsafe { libc::sigwait(&s, &mut sig) } != 0 {
                    continue;
                }
                rbprops_formats::atomic::remove_temporaries();
                // SAFETY: ends the process at once with the conventional status.
                unsafe { libc::_exit(128 + sig) };
            });
        if spawned.is_err() {
            // SAFETY: restores the mask: without the thread the default actions apply.
            unsafe { libc::pthread_sigmask(libc::SIG_UNBLOCK, &s, std::ptr::null_mut()) };
        }
    }
}

fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
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

/// Writes a text file (a plot, a report) atomically, creating its directory.
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    if path.as_os_str() == "-" {
        return out(text);
    }
    Ok(rbprops_formats::atomic::write_file(path, text.as_bytes())?)
}

/// Writes named SVG documents into `dir` (created if needed).
pub fn write_plots(dir: &Path, plots: &[(String, String)]) -> Result<()> {
    for (name, svg) in plots {
        write_text(&dir.join(name), svg)?;
    }
    Ok(())
}
