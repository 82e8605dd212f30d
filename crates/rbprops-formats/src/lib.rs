//! The one way rbprops reads and writes its formats, shared by every stage.
//!
//! A run is a [`RunRecord`]: the FRF set (bulk data) plus named JSON topics (geometry,
//! truth, modal fit, selection, estimates, provenance, …). It is stored as
//! - **MCAP** (`*.mcap`, or stdin/stdout): one channel per topic, message encoding `json`,
//!   schema encoding `jsonschema`, so any MCAP reader can decode it. FRF values travel as
//!   base64 little-endian f64 (bit-exact, compact);
//! - **CSV** (a directory): one table per topic (see [`csv_dir`]), spreadsheet-friendly,
//!   bit-exact for floats (shortest round-trip decimal form).
//!
//! See `docs/formats.md` for the byte-level description.

#![warn(missing_docs)]

pub mod atomic;
pub mod csv_dir;
pub mod digest;
pub mod flatten;
pub mod mcap_file;
pub mod scratch;
pub mod wire;

use rbprops_core::records::StageProvenance;
use rbprops_core::{FrfSet, Geometry};
use schemars::JsonSchema;
use serde::{de::DeserializeOwned, Serialize};
use std::path::Path;

/// Topic names (MCAP topics; CSV tables drop the `/rbprops/` prefix).
pub mod topics {
    /// Provenance of every stage that wrote to the run ([`rbprops_core::records::StageProvenance`], one message per stage).
    pub const PROVENANCE: &str = "/rbprops/provenance";
    /// The test geometry ([`crate::wire::GeometryMsg`], one message).
    pub const GEOMETRY: &str = "/rbprops/geometry";
    /// FRF values ([`crate::wire::FrfMsg`], one message per excitation).
    pub const FRF: &str = "/rbprops/frf";
    /// Frequency axis, quantity and layout of the FRFs ([`crate::wire::FrfAxisMsg`], one message).
    pub const FRF_AXIS: &str = "/rbprops/frf_axis";
    /// True properties and modes of a simulated campaign (absent for measured data).
    pub const TRUTH: &str = "/rbprops/truth";
    /// Modes identified per excitation by `modal-fit`.
    pub const MODAL_FIT: &str = "/rbprops/modal_fit";
    /// Best excitation per mode chosen by `ni-select`.
    pub const SELECTION: &str = "/rbprops/selection";
    /// Rigid-body property estimates from `rb-solve`.
    pub const ESTIMATES: &str = "/rbprops/estimates";
    /// What `rb-solve` noticed about the whole solve rather than one estimate (a missing
    /// mode, a set-up's rigid-body inconsistency, an estimator that failed), one
    /// [`rbprops_core::records::Diagnostic`] per message; absent when there is none.
    pub const SOLVE_DIAGNOSTICS: &str = "/rbprops/solve_diagnostics";
    /// Verdict of the model check: which effects the recording shows beyond the nominal model.
    pub const MODEL_CHECK: &str = "/rbprops/model_check";
    /// Ordinary coherence γ² per FRF line, from the measurement (UFF import).
    pub const COHERENCE: &str = "/rbprops/coherence";
    /// Each FRF line's noise variance `σ² = E|ε|²` from the estimator
    /// ([`crate::wire::FrfVarianceMsg`], one message per excitation that has any).
    pub const FRF_VARIANCE: &str = "/rbprops/frf_variance";
    /// Recorded time histories, the input of `frf-est` ([`crate::wire::TimeHistoryMsg`],
    /// one message per excitation). Read by `frf-est`, not passed on.
    pub const TIME_HISTORY: &str = "/rbprops/time_history";
}

/// Errors of the format layer. Each names the file and, where known, the record.
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    /// Reading or writing the file failed.
    #[error("{file}: {source}")]
    Io {
        /// The file, as the caller named it.
        file: String,
        /// The underlying I/O error.
        source: std::io::Error,
    },
    /// The file is not MCAP or its structure is broken.
    #[error("{file}: not a valid MCAP file: {detail}")]
    Mcap {
        /// The file.
        file: String,
        /// What the MCAP reader refused.
        detail: String,
    },
    /// A record (topic message, CSV row) does not decode.
    #[error("{file}: {record}: {detail}")]
    Record {
        /// The file.
        file: String,
        /// Which record: topic and message index, or table and row.
        record: String,
        /// What is wrong with it.
        detail: String,
    },
    /// Anything else, e.g. a required topic missing.
    #[error("{file}: {detail}")]
    Other {
        /// The file.
        file: String,
        /// What is wrong.
        detail: String,
    },
}

impl FormatError {
    /// A [`FormatError::Record`] in `file`.
    pub fn record(file: &str, record: impl Into<String>, detail: impl std::fmt::Display) -> Self {
        FormatError::Record {
            file: file.into(),
            record: record.into(),
            detail: detail.to_string(),
        }
    }
    /// A [`FormatError::Other`] in `file`.
    pub fn other(file: &str, detail: impl std::fmt::Display) -> Self {
        FormatError::Other {
            file: file.into(),
            detail: detail.to_string(),
        }
    }
}

/// One JSON topic: schema plus messages (as JSON values, so unknown topics pass through).
#[derive(Debug, Clone, PartialEq)]
pub struct JsonTopic {
    /// Topic name, e.g. [`topics::GEOMETRY`].
    pub name: String,
    /// Schema title, `rbprops.` followed by the record type's name.
    pub schema_name: String,
    /// JSON schema (draft 2020-12) of one message.
    pub schema: serde_json::Value,
    /// The messages in file order.
    pub messages: Vec<serde_json::Value>,
}

/// A topic in a foreign encoding, passed through MCAP untouched (CSV cannot hold it).
#[derive(Debug, Clone, PartialEq)]
pub struct RawTopic {
    /// Topic name as the writer gave it.
    pub name: String,
    /// Schema name as the writer gave it.
    pub schema_name: String,
    /// Schema encoding, e.g. `protobuf` or `ros2msg`.
    pub schema_encoding: String,
    /// Schema bytes, untouched.
    pub schema_data: Vec<u8>,
    /// Message encoding, e.g. `protobuf` or `cdr`.
    pub message_encoding: String,
    /// Message bytes in log order, untouched.
    pub messages: Vec<Vec<u8>>,
}

/// Everything one pipeline run knows, in topic order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RunRecord {
    /// The FRFs; excitation/channel order is the geometry's.
    pub frf: Option<FrfSet>,
    /// The JSON topics in the order they were written or set.
    pub topics: Vec<JsonTopic>,
    /// Topics in foreign encodings (MCAP only), written back as they came.
    pub raw_topics: Vec<RawTopic>,
}

impl RunRecord {
    /// The JSON topic of this name, if present.
    pub fn topic(&self, name: &str) -> Option<&JsonTopic> {
        self.topics.iter().find(|t| t.name == name)
    }

    /// Messages of a topic decoded as `T`; empty when the topic is absent.
    pub fn get<T: DeserializeOwned>(&self, name: &str) -> Result<Vec<T>, FormatError> {
        let Some(t) = self.topic(name) else {
            return Ok(Vec::new());
        };
        t.messages
            .iter()
            .enumerate()
            .map(|(i, m)| {
                serde_json::from_value(m.clone()).map_err(|e| {
                    FormatError::record("<record>", format!("topic {name}, message {i}"), e)
                })
            })
            .collect()
    }

    /// The single message of a topic, if present.
    pub fn get_one<T: DeserializeOwned>(&self, name: &str) -> Result<Option<T>, FormatError> {
        let mut v = self.get::<T>(name)?;
        match v.len() {
            0 => Ok(None),
            1 => Ok(v.pop()),
            n => Err(FormatError::record(
                "<record>",
                format!("topic {name}"),
                format!("expected one message, found {n}"),
            )),
        }
    }

    /// Replaces (or appends) a topic with these messages, its schema generated from `T`.
    pub fn set<T: Serialize + JsonSchema>(&mut self, name: &str, messages: &[T]) {
        let schema = serde_json::to_value(schemars::schema_for!(T)).expect("schema serialises");
        let schema_name = schema_title::<T>();
        let messages = messages
            .iter()
            .map(|m| serde_json::to_value(m).expect("record serialises"))
            .collect();
        let topic = JsonTopic {
            name: name.into(),
            schema_name,
            schema,
            messages,
        };
        match self.topics.iter_mut().find(|t| t.name == name) {
            Some(t) => *t = topic,
            None => self.topics.push(topic),
        }
    }

    /// Removes a topic (nothing when it is absent): a stage that has nothing to say in a
    /// topic it owns removes what an earlier run of it wrote there.
    pub fn remove(&mut self, name: &str) {
        self.topics.retain(|t| t.name != name);
    }

    /// Appends a stage's provenance to the provenance topic.
    pub fn push_provenance(&mut self, p: StageProvenance) -> Result<(), FormatError> {
        let mut all: Vec<StageProvenance> = self.get(topics::PROVENANCE)?;
        all.push(p);
        self.set(topics::PROVENANCE, &all);
        Ok(())
    }

    /// The geometry topic decoded and validated; `None` when the run has none.
    pub fn geometry(&self) -> Result<Option<Geometry>, FormatError> {
        self.get_one::<wire::GeometryMsg>(topics::GEOMETRY)?
            .map(|g| g.to_geometry())
            .transpose()
    }

    /// Replaces the geometry topic with `g`.
    pub fn set_geometry(&mut self, g: &Geometry) {
        self.set(topics::GEOMETRY, &[wire::GeometryMsg::from_geometry(g)]);
    }

    /// Geometry and FRFs together, with their shapes checked against each other.
    pub fn require_geometry_and_frf(&self) -> Result<(Geometry, &FrfSet), FormatError> {
        let g = self
            .geometry()?
            .ok_or_else(|| FormatError::other("<record>", "no geometry topic in the input"))?;
        let f = self
            .frf
            .as_ref()
            .ok_or_else(|| FormatError::other("<record>", "no FRF topic in the input"))?;
        if f.n_excitations != g.excitations.len() || f.n_channels != g.channels.len() {
            return Err(FormatError::other(
                "<record>",
                format!(
                    "FRFs have {} excitations × {} channels but the geometry defines {} × {}",
                    f.n_excitations,
                    f.n_channels,
                    g.excitations.len(),
                    g.channels.len()
                ),
            ));
        }
        Ok((g, f))
    }
}

fn schema_title<T: JsonSchema>() -> String {
    format!("rbprops.{}", T::schema_name())
}

/// On-disk representation, chosen from a path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// An MCAP file (`*.mcap`, or stdin/stdout).
    Mcap,
    /// A directory of CSV tables, one per topic (see [`csv_dir`]).
    CsvDir,
}

impl Format {
    /// `*.mcap` → MCAP; an existing directory or a path without extension / ending in
    /// `.csv` or `/` → CSV directory.
    pub fn from_path(path: &Path) -> Result<Format, FormatError> {
        let s = path.to_string_lossy();
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        match ext.as_deref() {
            Some("mcap") => Ok(Format::Mcap),
            Some("csv") => Ok(Format::CsvDir),
            _ if path.is_dir() || s.ends_with('/') || ext.is_none() => Ok(Format::CsvDir),
            None => Ok(Format::CsvDir),
            Some(e) => Err(FormatError::other(
                &s,
                format!("unknown format '.{e}' (expected .mcap, a CSV directory, or .uff/.unv)"),
            )),
        }
    }
}

/// SHA-256 of some bytes, hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    let mut h = Sha256Stream::default();
    h.update(bytes);
    h.hex()
}

/// SHA-256 fed piece by piece (a large input read as it streams): the same digest as
/// [`sha256_hex`] of the pieces joined.
#[derive(Clone, Default)]
pub struct Sha256Stream(sha2::Sha256);

impl Sha256Stream {
    /// Feeds the next bytes.
    pub fn update(&mut self, bytes: &[u8]) {
        sha2::Digest::update(&mut self.0, bytes);
    }

    /// The digest of everything fed, hex.
    pub fn hex(self) -> String {
        let d = sha2::Digest::finalize(self.0);
        d.iter().map(|b| format!("{b:02x}")).collect()
    }
}

/// Reads a run from a path (MCAP file or CSV directory).
pub fn read_path(path: &Path) -> Result<RunRecord, FormatError> {
    match Format::from_path(path)? {
        Format::Mcap if std::fs::metadata(path).is_ok_and(|m| m.is_file()) => {
            let name = path.display().to_string();
            mcap_file::read_file_checked(path, &name).map(|(rec, _, _)| rec)
        }
        Format::Mcap => {
            let name = path.display().to_string();
            let bytes = std::fs::read(path).map_err(|e| FormatError::Io {
                file: name.clone(),
                source: e,
            })?;
            mcap_file::read(&bytes, &name)
        }
        Format::CsvDir => csv_dir::read(path),
    }
}

/// Writes a run to a path atomically (temp file/dir, then rename).
pub fn write_path(rec: &RunRecord, path: &Path) -> Result<(), FormatError> {
    match Format::from_path(path)? {
        Format::Mcap => atomic::write_file_with(path, |w| mcap_file::write_to(rec, w).map(drop)),
        // A device or FIFO (`-o /dev/null`) cannot hold a directory: it gets the stream.
        Format::CsvDir if is_stream(path) => atomic::write_file(path, &mcap_file::write(rec)?),
        Format::CsvDir => csv_dir::write(rec, path),
    }
}

/// True when `path` is a character device or a FIFO (written straight through, as MCAP).
pub fn is_stream(path: &Path) -> bool {
    use std::os::unix::fs::FileTypeExt;
    std::fs::metadata(path).is_ok_and(|m| m.file_type().is_char_device() || m.file_type().is_fifo())
}
