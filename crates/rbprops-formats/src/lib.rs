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

pub mod atomic;
pub mod csv_dir;
pub mod digest;
pub mod flatten;
pub mod mcap_file;
pub mod wire;

use rbprops_core::records::StageProvenance;
use rbprops_core::{FrfSet, Geometry};
use schemars::JsonSchema;
use serde::{de::DeserializeOwned, Serialize};
use std::path::Path;

/// Topic names (MCAP topics; CSV tables drop the `/rbprops/` prefix).
pub mod topics {
    pub const PROVENANCE: &str = "/rbprops/provenance";
    pub const GEOMETRY: &str = "/rbprops/geometry";
    pub const FRF: &str = "/rbprops/frf";
    pub const FRF_AXIS: &str = "/rbprops/frf_axis";
    pub const TRUTH: &str = "/rbprops/truth";
    pub const MODAL_FIT: &str = "/rbprops/modal_fit";
    pub const SELECTION: &str = "/rbprops/selection";
    pub const ESTIMATES: &str = "/rbprops/estimates";
    pub const MODEL_CHECK: &str = "/rbprops/model_check";
    /// Ordinary coherence γ² per FRF line, from the measurement (UFF import).
    pub const COHERENCE: &str = "/rbprops/coherence";
}

/// Errors of the format layer. Each names the file and, where known, the record.
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    #[error("{file}: {source}")]
    Io {
        file: String,
        source: std::io::Error,
    },
    #[error("{file}: not a valid MCAP file: {detail}")]
    Mcap { file: String, detail: String },
    #[error("{file}: {record}: {detail}")]
    Record {
        file: String,
        record: String,
        detail: String,
    },
    #[error("{file}: {detail}")]
    Other { file: String, detail: String },
}

impl FormatError {
    pub fn record(file: &str, record: impl Into<String>, detail: impl std::fmt::Display) -> Self {
        FormatError::Record {
            file: file.into(),
            record: record.into(),
            detail: detail.to_string(),
        }
    }
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
    pub name: String,
    pub schema_name: String,
    /// JSON schema (draft 2020-12) of one message.
    pub schema: serde_json::Value,
    pub messages: Vec<serde_json::Value>,
}

/// A topic in a foreign encoding, passed through MCAP untouched (CSV cannot hold it).
#[derive(Debug, Clone, PartialEq)]
pub struct RawTopic {
    pub name: String,
    pub schema_name: String,
    pub schema_encoding: String,
    pub schema_data: Vec<u8>,
    pub message_encoding: String,
    pub messages: Vec<Vec<u8>>,
}

/// Everything one pipeline run knows, in topic order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RunRecord {
    /// The FRFs; excitation/channel order is the geometry's.
    pub frf: Option<FrfSet>,
    pub topics: Vec<JsonTopic>,
    pub raw_topics: Vec<RawTopic>,
}

impl RunRecord {
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

    /// Appends a stage's provenance to the provenance topic.
    pub fn push_provenance(&mut self, p: StageProvenance) -> Result<(), FormatError> {
        let mut all: Vec<StageProvenance> = self.get(topics::PROVENANCE)?;
        all.push(p);
        self.set(topics::PROVENANCE, &all);
        Ok(())
    }

    pub fn geometry(&self) -> Result<Option<Geometry>, FormatError> {
        self.get_one::<wire::GeometryMsg>(topics::GEOMETRY)?
            .map(|g| g.to_geometry())
            .transpose()
    }

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
    Mcap,
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
    use sha2::Digest;
    let d = sha2::Sha256::digest(bytes);
    d.iter().map(|b| format!("{b:02x}")).collect()
}

/// Reads a run from a path (MCAP file or CSV directory).
pub fn read_path(path: &Path) -> Result<RunRecord, FormatError> {
    match Format::from_path(path)? {
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
        Format::Mcap => {
            let bytes = mcap_file::write(rec)?;
            atomic::write_file(path, &bytes)
        }
        Format::CsvDir => csv_dir::write(rec, path),
    }
}
