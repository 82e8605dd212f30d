//! MCAP: one channel per topic, `json` message encoding with `jsonschema` schemas.

use crate::wire::{self, FrfAxisMsg, FrfMsg};
use crate::{topics, FormatError, JsonTopic, RawTopic, RunRecord};
use rbprops_core::{FrfSet, FrfSource};
use std::collections::BTreeMap;
use std::io::{Cursor, Seek, Write};

mod deferred;
pub use deferred::{read_file_deferred, DeferredFrf};

/// Profile written in the MCAP header.
pub const PROFILE: &str = "rbprops";

fn mcap_err(e: mcap::McapError) -> FormatError {
    FormatError::Mcap {
        file: "<output>".into(),
        detail: e.to_string(),
    }
}

struct Out<W: Write + Seek> {
    w: mcap::Writer<W>,
    seq: u32,
}

impl<W: Write + Seek> Out<W> {
    fn channel(
        &mut self,
        topic: &str,
        schema_name: &str,
        schema_encoding: &str,
        schema: &[u8],
        msg_encoding: &str,
    ) -> Result<u16, FormatError> {
        let sid = self
            .w
            .add_schema(schema_name, schema_encoding, schema)
            .map_err(mcap_err)?;
        self.w
            .add_channel(sid, topic, msg_encoding, &BTreeMap::new())
            .map_err(mcap_err)
    }
    fn message(&mut self, channel_id: u16, data: &[u8]) -> Result<(), FormatError> {
        // Log time is the sequence number: runs must be byte-identical, so no clocks.
        let header = mcap::records::MessageHeader {
            channel_id,
            sequence: self.seq,
            log_time: self.seq as u64,
            publish_time: self.seq as u64,
        };
        self.seq += 1;
        self.w
            .write_to_known_channel(&header, data)
            .map_err(mcap_err)
    }
    fn json_topic(&mut self, t: &JsonTopic) -> Result<(), FormatError> {
        let schema = serde_json::to_vec(&t.schema).expect("schema serialises");
        let id = self.channel(&t.name, &t.schema_name, "jsonschema", &schema, "json")?;
        for m in &t.messages {
            self.message(id, &serde_json::to_vec(m).expect("json serialises"))?;
        }
        self.end_topic()
    }
    /// Closes the chunk after each topic, so that a chunk holds one topic and a chunk's
    /// CRC error names the topic that was corrupted.
    fn end_topic(&mut self) -> Result<(), FormatError> {
        self.w.flush().map_err(mcap_err)
    }
    /// The FRF topic one excitation at a time: each message's JSON is written straight
    /// ([`wire::frf_message_json`]) and handed to the chunk before the next is made,
    /// instead of all of them at once as JSON values (two more copies of the whole set). The bytes are those of
    /// [`Out::typed`]: the schema through a JSON value, each message's fields in order.
    fn frf_topic(
        &mut self,
        frf: &dyn FrfSource,
        g: &rbprops_core::Geometry,
    ) -> Result<(), FormatError> {
        let schema =
            serde_json::to_value(schemars::schema_for!(FrfMsg)).expect("schema serialises");
        let schema = serde_json::to_vec(&schema).expect("schema serialises");
        let id = self.channel(
            topics::FRF,
            &crate::schema_title::<FrfMsg>(),
            "jsonschema",
            &schema,
            "json",
        )?;
        for e in 0..frf.n_excitations() {
            let x = frf
                .excitation(e)
                .map_err(|err| FormatError::other("<output>", err))?;
            let msg = wire::frf_message_json(&g.excitations[e].id, x.block());
            drop(x);
            self.message(id, &msg)?;
        }
        self.end_topic()
    }
    fn typed<T: serde::Serialize + schemars::JsonSchema>(
        &mut self,
        topic: &str,
        msgs: &[T],
    ) -> Result<(), FormatError> {
        let mut tmp = RunRecord::default();
        tmp.set(topic, msgs);
        self.json_topic(&tmp.topics[0])
    }
}

/// Serialises a run to MCAP bytes (zstd chunks, one or more per topic, compressed
/// single-threaded so output is reproducible).
///
/// Every chunk carries the CRC-32 of its uncompressed records, the `DataEnd` record the
/// CRC-32 of the whole data section (record headers, chunk headers and message indexes
/// included) and the footer that of the summary section; [`read`] verifies all three.
/// (These are the `mcap` crate's defaults, stated here so that they cannot silently go.)
pub fn write(rec: &RunRecord) -> Result<Vec<u8>, FormatError> {
    Ok(write_to(rec, Cursor::new(Vec::new()))?.into_inner())
}

/// [`write`] into `sink` (a file: the run is never held as bytes beside the record),
/// returned when the MCAP is finished.
pub fn write_to<W: Write + Seek>(rec: &RunRecord, sink: W) -> Result<W, FormatError> {
    write_to_with(rec, rec.frf.as_ref().map(|f| f as &dyn FrfSource), sink)
}

/// [`write_to`] with the FRFs from `frf` instead of the record's (a [`DeferredFrf`]: the
/// input's set copied through one excitation at a time, never held whole; issue 41).
pub fn write_to_with<W: Write + Seek>(
    rec: &RunRecord,
    frf: Option<&dyn FrfSource>,
    sink: W,
) -> Result<W, FormatError> {
    let w = write_options().create(sink).map_err(mcap_err)?;
    write_records(rec, frf, w)
}

/// [`write_to_with`] into a sink that cannot seek (stdout on a pipe): each chunk is
/// finished in memory, then written whole, so the bytes are a file's, and they leave as
/// they are made: a stage on a pipe passes its FRFs on excitation by excitation (issue
/// 41; `frf-sim` simulates each as it is written). A failure midway leaves the reader a
/// file without its footer, which it refuses.
pub fn write_stream_with<W: Write>(
    rec: &RunRecord,
    frf: Option<&dyn FrfSource>,
    sink: W,
) -> Result<W, FormatError> {
    let w = write_options()
        .disable_seeking(true)
        .create(mcap::write::NoSeek::new(sink))
        .map_err(mcap_err)?;
    Ok(write_records(rec, frf, w)?.into_inner())
}

/// The options of every MCAP rbprops writes.
fn write_options() -> mcap::WriteOptions {
    mcap::WriteOptions::new()
        .profile(PROFILE)
        .library(format!("rbprops {}", env!("CARGO_PKG_VERSION")))
        .compression(Some(mcap::Compression::Zstd))
        .compression_threads(0)
        .use_chunks(true)
        .calculate_chunk_crcs(true)
        .calculate_data_section_crc(true)
        .calculate_summary_section_crc(true)
}

/// The run's topics (the FRFs from `frf`) through the MCAP writer `w`, finished.
fn write_records<W: Write + Seek>(
    rec: &RunRecord,
    frf: Option<&dyn FrfSource>,
    w: mcap::Writer<W>,
) -> Result<W, FormatError> {
    let mut out = Out { w, seq: 0 };
    let geometry = if frf.is_some() { rec.geometry()? } else { None };
    let mut frf_written = false;
    let write_frf = |out: &mut Out<W>, frf: &dyn FrfSource| -> Result<(), FormatError> {
        let g = geometry.as_ref().ok_or_else(|| {
            FormatError::other("<output>", "an FRF set needs a geometry topic for its ids")
        })?;
        out.typed(topics::FRF_AXIS, &[wire::frf_axis(frf, g)])?;
        out.frf_topic(frf, g)
    };
    for t in &rec.topics {
        out.json_topic(t)?;
        if t.name == topics::GEOMETRY {
            if let Some(frf) = frf {
                write_frf(&mut out, frf)?;
                frf_written = true;
            }
        }
    }
    if let (Some(frf), false) = (frf, frf_written) {
        write_frf(&mut out, frf)?;
    }
    for r in &rec.raw_topics {
        let id = out.channel(
            &r.name,
            &r.schema_name,
            &r.schema_encoding,
            &r.schema_data,
            &r.message_encoding,
        )?;
        for m in &r.messages {
            out.message(id, m)?;
        }
        out.end_topic()?;
    }
    out.w.finish().map_err(mcap_err)?;
    Ok(out.w.into_inner())
}

/// Parses MCAP bytes, verifying every CRC they carry. `file` names the source in errors.
pub fn read(bytes: &[u8], file: &str) -> Result<RunRecord, FormatError> {
    read_checked(bytes, file).map(|(rec, _)| rec)
}

/// [`read`], also returning the notes of the integrity check: which parts of the file
/// carry no CRC (another writer's file with CRC fields 0) and so could not be verified.
///
/// Each message is taken as the reader yields it (no copy of the file's messages is
/// held), and each FRF message's values are decoded as it arrives once the FRF axis is
/// known (it precedes them in rbprops' files): the set's base64 text, a third more than
/// the set, is never held whole (issue 41).
pub fn read_checked(bytes: &[u8], file: &str) -> Result<(RunRecord, Vec<String>), FormatError> {
    read_source(&Source::Bytes(bytes), file)
}

/// [`read_checked`] of the MCAP file at `path`, read as it is parsed: its bytes are never
/// held whole (issue 41; a 42 MB record at 3 excitations × 102,401 lines). Also returns
/// the file's SHA-256, taken in the same reading (the file must not change meanwhile).
pub fn read_file_checked(
    path: &std::path::Path,
    file: &str,
) -> Result<(RunRecord, Vec<String>, String), FormatError> {
    let ((rec, notes), sha256, _) = with_file_source(path, file, |src| read_source(src, file))?;
    Ok((rec, notes, sha256))
}

/// Runs `read` on the MCAP file at `path` as a [`Source`] that is read at offsets as it
/// is parsed; returns its result, the file's SHA-256 (the bytes the linear reading did
/// not reach hashed after it) and the open file.
fn with_file_source<T>(
    path: &std::path::Path,
    file: &str,
    read: impl FnOnce(&Source) -> Result<T, FormatError>,
) -> Result<(T, String, std::fs::File), FormatError> {
    let io = |source| FormatError::Io {
        file: file.into(),
        source,
    };
    let f = std::fs::File::open(path).map_err(io)?;
    let len = f.metadata().map_err(io)?.len() as usize;
    let src = Source::File {
        file: std::cell::RefCell::new(f),
        len,
        digest: std::cell::RefCell::new((0, crate::Sha256Stream::default())),
    };
    let out = read(&src)?;
    let Source::File {
        digest, file: f, ..
    } = src
    else {
        unreachable!("a file source")
    };
    // The bytes the linear reading did not reach (none for a well-formed file).
    let (mut at, mut h) = digest.into_inner();
    let mut f = f.into_inner();
    let mut buf = vec![0u8; 1 << 16];
    while at < len {
        let n = (len - at).min(buf.len());
        read_exact_at(&mut f, at, &mut buf[..n]).map_err(io)?;
        h.update(&buf[..n]);
        at += n;
    }
    Ok((out, h.hex(), f))
}

/// `buf.len()` bytes of `f` from `offset`.
fn read_exact_at(f: &mut std::fs::File, offset: usize, buf: &mut [u8]) -> std::io::Result<()> {
    use std::io::{Read, Seek, SeekFrom};
    f.seek(SeekFrom::Start(offset as u64))?;
    f.read_exact(buf)
}

/// Where the MCAP bytes come from: memory, or a file read at offsets as they are needed
/// (its digest taken as the linear reading goes: `(bytes hashed, state)`).
enum Source<'a> {
    Bytes(&'a [u8]),
    File {
        file: std::cell::RefCell<std::fs::File>,
        len: usize,
        digest: std::cell::RefCell<(usize, crate::Sha256Stream)>,
    },
}

impl Source<'_> {
    fn len(&self) -> usize {
        match self {
            Source::Bytes(b) => b.len(),
            Source::File { len, .. } => *len,
        }
    }

    /// Bytes `offset..offset + len`, `None` past the end (or when the file cannot be
    /// read: the reading then stops at a truncated record, named as such).
    fn get(&self, offset: usize, len: usize) -> Option<std::borrow::Cow<'_, [u8]>> {
        let end = offset.checked_add(len)?;
        if end > self.len() {
            return None;
        }
        match self {
            Source::Bytes(b) => Some(std::borrow::Cow::Borrowed(&b[offset..end])),
            Source::File { file, .. } => {
                let mut buf = vec![0u8; len];
                read_exact_at(&mut file.borrow_mut(), offset, &mut buf).ok()?;
                Some(std::borrow::Cow::Owned(buf))
            }
        }
    }

    /// The linear reading's next bytes `pos..pos + out.len()` into `out` (hashed in
    /// order for a file).
    fn read_linear(&self, pos: usize, out: &mut [u8]) -> Result<(), String> {
        match self {
            Source::Bytes(b) => {
                out.copy_from_slice(&b[pos..pos + out.len()]);
                Ok(())
            }
            Source::File { file, digest, .. } => {
                read_exact_at(&mut file.borrow_mut(), pos, out)
                    .map_err(|e| format!("byte {pos}: {e}"))?;
                let mut d = digest.borrow_mut();
                if d.0 == pos {
                    d.1.update(out);
                    d.0 += out.len();
                }
                Ok(())
            }
        }
    }
}

/// [`read_checked`] from either source.
fn read_source(src: &Source, file: &str) -> Result<(RunRecord, Vec<String>), FormatError> {
    let (mut rec, mut frf, notes) = walk(src, file, false)?;
    if let Some(axis) = frf.axis.take() {
        rec.frf = Some(assemble_frf(&rec, axis, frf, file)?);
    }
    Ok((rec, notes))
}

/// Every message of `src` into a record, the FRF messages into [`FrfMessages`] (their
/// values decoded and checked, and kept unless `defer`).
fn walk(
    src: &Source,
    file: &str,
    defer: bool,
) -> Result<(RunRecord, FrfMessages, Vec<String>), FormatError> {
    let mut rec = RunRecord::default();
    let mut frf = FrfMessages {
        defer,
        ..Default::default()
    };
    let mut i = 0usize;
    let notes = messages(src, |m| {
        let r = take_message(&mut rec, &mut frf, i, m, file);
        i += 1;
        r
    })
    .map_err(|e| match e {
        Stop::Mcap(detail) => FormatError::Mcap {
            file: file.into(),
            detail,
        },
        Stop::Record(e) => e,
    })?;
    if frf.axis.is_none() && !frf.pending.is_empty() {
        return Err(FormatError::record(
            file,
            topics::FRF,
            "FRF messages without an FRF axis message",
        ));
    }
    Ok((rec, frf, notes))
}

/// The FRF topic as it is read: the axis, the excitation ids and values of the messages
/// decoded so far (in file order, the values appended to one buffer that becomes the
/// set's) and the messages that came before the axis (decoded at the end).
#[derive(Default)]
struct FrfMessages {
    axis: Option<FrfAxisMsg>,
    decoded_ids: Vec<String>,
    decoded: Vec<rbprops_core::c64>,
    pending: Vec<FrfMsg>,
    /// Decode and check the values, then drop them: the set stays in the file
    /// ([`DeferredFrf`]) and `places` says where each message lies.
    defer: bool,
    /// Where each decoded message lies (file order).
    places: Vec<FrfPlace>,
}

/// Where an FRF message lies in the file: the top-level record holding it, its channel
/// and how many messages of that channel come before it in the record.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct FrfPlace {
    record: usize,
    channel: u16,
    ordinal: usize,
}

impl FrfMessages {
    /// Values per FRF message of `axis` (channels × lines), `None` when not addressable.
    fn values_per_message(axis: &FrfAxisMsg) -> Option<usize> {
        axis.channels
            .len()
            .checked_mul(axis.frequency_hz.len())
            .filter(|n| n.checked_mul(16 * axis.excitations.len().max(1)).is_some())
    }

    /// Message `k` of the topic: its base64 text's length is checked against the axis
    /// before it is decoded (a small file declaring a huge set is an error, not an
    /// allocation failure), then the text is dropped.
    fn decode(
        axis: &FrfAxisMsg,
        k: usize,
        excitation: String,
        text: &str,
        file: &str,
    ) -> Result<(String, Vec<rbprops_core::c64>), FormatError> {
        let n = Self::values_per_message(axis);
        let want = n.map(|n| (n * 16).div_ceil(3) * 4);
        if want != Some(text.len()) {
            return Err(FormatError::record(
                file,
                format!("{} message {k}", topics::FRF),
                format!(
                    "{} base64 characters of values, but {} channels × {} lines need {}",
                    text.len(),
                    axis.channels.len(),
                    axis.frequency_hz.len(),
                    want.map_or("more than addressable".into(), |w| w.to_string())
                ),
            ));
        }
        let v = wire::decode_values(text, n.unwrap_or(0)).map_err(|e| {
            FormatError::record(
                file,
                format!("{} excitation '{}'", topics::FRF, excitation),
                e,
            )
        })?;
        Ok((excitation, v))
    }

    /// An FRF message: decoded now when the axis is known, else kept for the end.
    fn take(
        &mut self,
        excitation: String,
        text: &str,
        file: &str,
        (record, channel): (usize, u16),
    ) -> Result<(), FormatError> {
        match &self.axis {
            Some(axis) if self.defer => {
                let ordinal = match self.places.last() {
                    Some(p) if p.record == record && p.channel == channel => p.ordinal + 1,
                    _ => 0,
                };
                let k = self.decoded_ids.len();
                let (id, v) = Self::decode(axis, k, excitation, text, file)?;
                check_finite(&v, &id, axis, file)?;
                self.places.push(FrfPlace {
                    record,
                    channel,
                    ordinal,
                });
                self.decoded_ids.push(id);
            }
            Some(axis) => {
                let k = self.decoded_ids.len();
                let (id, v) = Self::decode(axis, k, excitation, text, file)?;
                if k == 0 {
                    // The declared set's room at once (pages are only touched as they are
                    // filled), so that growing it never copies it: the values are held
                    // once plus one message (issue 41). A declared size the system
                    // refuses falls back to growing.
                    let n = Self::values_per_message(axis).unwrap_or(0);
                    let declared = n.saturating_mul(axis.excitations.len());
                    let _ = self.decoded.try_reserve_exact(declared);
                }
                self.decoded.extend_from_slice(&v);
                self.decoded_ids.push(id);
            }
            None => self.pending.push(FrfMsg {
                excitation,
                values_f64le: text.to_owned(),
            }),
        }
        Ok(())
    }
}

/// [`FrfMsg`] with its values' text borrowed from the message where it has no escapes.
#[derive(serde::Deserialize)]
struct FrfMsgText<'a> {
    excitation: String,
    #[serde(borrow)]
    values_f64le: std::borrow::Cow<'a, str>,
}

/// Why the walk over a file's messages stopped: the MCAP itself (a CRC, a record), or
/// a message the run cannot take.
enum Stop {
    Mcap(String),
    Record(FormatError),
}

/// Message `i` of the file into `rec` (FRF messages into `frf`).
fn take_message(
    rec: &mut RunRecord,
    frf: &mut FrfMessages,
    i: usize,
    m: RawMsg<'_>,
    file: &str,
) -> Result<(), FormatError> {
    let topic = m.topic;
    if m.encoding == "json" && topic == topics::FRF {
        // The values' text borrowed from the message, not copied into a JSON value; any
        // message this does not take (a duplicate key, invalid JSON) goes the general way
        // below, which names its error.
        if let Ok(msg) = serde_json::from_slice::<FrfMsgText>(m.data) {
            return frf.take(msg.excitation, &msg.values_f64le, file, m.place);
        }
    }
    let schema = m.schema;
    if m.encoding != "json" {
        let pos = rec
            .raw_topics
            .iter()
            .position(|t| t.name == topic)
            .unwrap_or_else(|| {
                rec.raw_topics.push(RawTopic {
                    name: topic.clone(),
                    schema_name: schema.as_ref().map(|s| s.name.clone()).unwrap_or_default(),
                    schema_encoding: schema
                        .as_ref()
                        .map(|s| s.encoding.clone())
                        .unwrap_or_default(),
                    schema_data: schema.as_ref().map(|s| s.data.clone()).unwrap_or_default(),
                    message_encoding: m.encoding.clone(),
                    messages: Vec::new(),
                });
                rec.raw_topics.len() - 1
            });
        rec.raw_topics[pos].messages.push(m.data.to_vec());
        return Ok(());
    }
    let value: serde_json::Value = serde_json::from_slice(m.data).map_err(|e| {
        FormatError::record(
            file,
            format!("topic {topic}, message {i}"),
            format!("invalid JSON: {e}"),
        )
    })?;
    let ctx = || format!("topic {topic}, message {i}");
    match topic.as_str() {
        topics::FRF_AXIS => {
            if frf.axis.is_some() {
                return Err(FormatError::record(
                    file,
                    ctx(),
                    "a second FRF axis message",
                ));
            }
            frf.axis = Some(
                serde_json::from_value(value).map_err(|e| FormatError::record(file, ctx(), e))?,
            );
        }
        topics::FRF => {
            let msg: FrfMsg =
                serde_json::from_value(value).map_err(|e| FormatError::record(file, ctx(), e))?;
            frf.take(msg.excitation, &msg.values_f64le, file, m.place)?;
        }
        _ => {
            let pos = rec
                .topics
                .iter()
                .position(|t| t.name == topic)
                .unwrap_or_else(|| {
                    let schema_json = schema
                        .as_ref()
                        .filter(|s| s.encoding == "jsonschema")
                        .and_then(|s| serde_json::from_slice(&s.data).ok())
                        .unwrap_or(serde_json::Value::Bool(true));
                    rec.topics.push(JsonTopic {
                        name: topic.clone(),
                        schema_name: schema.as_ref().map(|s| s.name.clone()).unwrap_or_default(),
                        schema: schema_json,
                        messages: Vec::new(),
                    });
                    rec.topics.len() - 1
                });
            rec.topics[pos].messages.push(value);
        }
    }
    Ok(())
}

fn assemble_frf(
    rec: &RunRecord,
    axis: FrfAxisMsg,
    frf: FrfMessages,
    file: &str,
) -> Result<FrfSet, FormatError> {
    let FrfMessages {
        decoded_ids,
        decoded,
        pending,
        ..
    } = frf;
    check_message_count(rec, &axis, pending.len() + decoded_ids.len(), file)?;
    let count = pending.len() + decoded_ids.len();
    let n = FrfMessages::values_per_message(&axis).unwrap_or(0);
    // Messages before the axis (another writer's order) in file order, then the rest;
    // only then is the set copied once.
    let mut ids = Vec::with_capacity(count);
    let values = if pending.is_empty() {
        decoded
    } else {
        let mut values = Vec::with_capacity(n * count);
        for (k, m) in pending.into_iter().enumerate() {
            let (id, v) = FrfMessages::decode(&axis, k, m.excitation, &m.values_f64le, file)?;
            values.extend_from_slice(&v);
            ids.push(id);
        }
        values.extend_from_slice(&decoded);
        values
    };
    ids.extend(decoded_ids);
    check_message_order(&axis, &ids, file)?;
    let frf = FrfSet {
        quantity: axis.quantity,
        frequency_hz: axis.frequency_hz,
        n_excitations: axis.excitations.len(),
        n_channels: axis.channels.len(),
        values,
    };
    frf.validate()
        .map_err(|e| FormatError::record(file, topics::FRF, e))?;
    Ok(frf)
}

/// The axis's ids are the geometry's and there is one FRF message per excitation.
fn check_message_count(
    rec: &RunRecord,
    axis: &FrfAxisMsg,
    count: usize,
    file: &str,
) -> Result<(), FormatError> {
    let g = rec
        .geometry()
        .map_err(|e| FormatError::other(file, e))?
        .ok_or_else(|| FormatError::record(file, topics::FRF, "FRFs without a geometry topic"))?;
    wire::check_ids_match(axis, &g, file)?;
    if count != axis.excitations.len() {
        return Err(FormatError::record(
            file,
            topics::FRF,
            format!(
                "{} FRF messages for {} excitations",
                count,
                axis.excitations.len()
            ),
        ));
    }
    Ok(())
}

/// The FRF messages come in the axis's excitation order.
fn check_message_order(axis: &FrfAxisMsg, ids: &[String], file: &str) -> Result<(), FormatError> {
    for (k, excitation) in ids.iter().enumerate() {
        if *excitation != axis.excitations[k] {
            return Err(FormatError::record(
                file,
                format!("{} message {k}", topics::FRF),
                format!(
                    "excitation '{}' where '{}' was expected",
                    excitation, axis.excitations[k]
                ),
            ));
        }
    }
    Ok(())
}

/// The values of an FRF message are finite (the check [`FrfSet::validate`] makes of a
/// whole set, for one message whose values are not kept).
fn check_finite(
    v: &[rbprops_core::c64],
    id: &str,
    axis: &FrfAxisMsg,
    file: &str,
) -> Result<(), FormatError> {
    let nl = axis.frequency_hz.len().max(1);
    match v
        .iter()
        .position(|v| !(v.re.is_finite() && v.im.is_finite()))
    {
        None => Ok(()),
        Some(i) => Err(FormatError::record(
            file,
            format!("{} excitation '{id}'", topics::FRF),
            format!(
                "channel {}, line {} ({} Hz): value {} is not finite",
                i / nl,
                i % nl,
                axis.frequency_hz[i % nl],
                v[i]
            ),
        )),
    }
}

/// Largest decompressed chunk accepted (a corrupt size field must not exhaust memory).
const MAX_CHUNK_BYTES: u64 = 1 << 32;
/// Largest ratio of a chunk's declared uncompressed size to its record's length (plus
/// [`CHUNK_SLACK`]): rbprops' own chunks compress JSON and base64 values about 2–20×, so
/// a declared size far beyond that is a corrupt or hostile field, refused before the
/// reader allocates it.
const MAX_CHUNK_RATIO: u64 = 256;
/// Uncompressed bytes any chunk may declare whatever its compressed length.
const CHUNK_SLACK: u64 = 8 << 20;

pub(crate) const MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// Opcodes of the MCAP records the integrity check looks at.
mod op {
    pub const FOOTER: u8 = 0x02;
    pub const CHANNEL: u8 = 0x04;
    pub const CHUNK: u8 = 0x06;
    pub const MESSAGE_INDEX: u8 = 0x07;
    pub const DATA_END: u8 = 0x0F;
}

/// One top-level record: where it starts, its opcode and the length of its body.
#[derive(Clone, Copy)]
struct TopRecord {
    offset: usize,
    opcode: u8,
    len: usize,
}

/// The top-level records of a file, walked before the mcap crate reads it.
struct Layout {
    records: Vec<TopRecord>,
}

impl Layout {
    /// The record holding byte `pos` (the last record when `pos` is past them all).
    fn at(&self, pos: usize) -> Option<TopRecord> {
        let i = self.records.partition_point(|r| r.offset <= pos);
        self.records.get(i.checked_sub(1)?).copied()
    }

    /// Bytes `from..from + len` of the body of `r` (`None` past its end).
    fn field<'a>(
        &self,
        src: &'a Source,
        r: TopRecord,
        from: usize,
        len: usize,
    ) -> Option<std::borrow::Cow<'a, [u8]>> {
        if from + len > r.len {
            return None;
        }
        src.get(r.offset + 9 + from, len)
    }

    /// Topics of the messages in the chunk `chunk`, from the message index records that
    /// follow it and the channel records (the summary repeats them; a chunk's own channel
    /// records are inside it and so not trusted here). Empty when the file has no index.
    fn chunk_topics(&self, src: &Source, chunk: TopRecord) -> Vec<String> {
        let mut channels = BTreeMap::new();
        for r in self.records.iter().filter(|r| r.opcode == op::CHANNEL) {
            let Some(body) = self.field(src, *r, 0, r.len) else {
                continue;
            };
            if let Ok(mcap::records::Record::Channel(c)) = mcap::parse_record(op::CHANNEL, &body) {
                channels.insert(c.id, c.topic);
            }
        }
        let i = self.records.partition_point(|r| r.offset <= chunk.offset);
        let mut topics: Vec<String> = self.records[i..]
            .iter()
            .take_while(|r| r.opcode == op::MESSAGE_INDEX)
            .filter_map(|r| {
                let b = self.field(src, *r, 0, 2)?;
                let id = u16::from_le_bytes(b[..2].try_into().ok()?);
                Some(
                    channels
                        .get(&id)
                        .cloned()
                        .unwrap_or_else(|| format!("channel {id}")),
                )
            })
            .collect();
        topics.dedup();
        topics
    }

    /// Where an error met after reading up to byte `pos` lies: the record, its kind and,
    /// for a chunk, the topics it holds.
    fn describe(&self, src: &Source, pos: usize) -> String {
        let Some(r) = self.at(pos.saturating_sub(1)) else {
            return format!("byte {pos}");
        };
        match r.opcode {
            op::CHUNK => {
                let topics = self.chunk_topics(src, r);
                if topics.is_empty() {
                    format!(
                        "chunk at byte {} (topics unknown: no message index)",
                        r.offset
                    )
                } else {
                    let s = if topics.len() == 1 { "" } else { "s" };
                    format!(
                        "chunk at byte {} (topic{s} {})",
                        r.offset,
                        topics.join(", ")
                    )
                }
            }
            op::DATA_END => format!(
                "data section (bytes {}..{}, closed by the DataEnd record at byte {})",
                MAGIC.len(),
                r.offset,
                r.offset
            ),
            op::FOOTER => format!(
                "summary section (checked by the footer at byte {})",
                r.offset
            ),
            o => format!("record at byte {} (opcode 0x{o:02x})", r.offset),
        }
    }

    /// What the file leaves unverified: chunks and sections whose CRC field is 0 (the MCAP
    /// convention for "not computed", used by some writers).
    fn unverified(&self, src: &Source) -> Vec<String> {
        let mut notes = Vec::new();
        let chunks: Vec<_> = self
            .records
            .iter()
            .filter(|r| r.opcode == op::CHUNK)
            .collect();
        let no_crc = chunks
            .iter()
            .filter(|r| self.field(src, ***r, 24, 4).as_deref() == Some(&[0u8; 4][..]))
            .count();
        if no_crc > 0 {
            notes.push(format!(
                "{no_crc} of {} chunks carry no CRC (0): their records are not verified",
                chunks.len()
            ));
        }
        match self.records.iter().find(|r| r.opcode == op::DATA_END) {
            None => notes.push("no DataEnd record: the data section is not verified".into()),
            Some(r) if self.field(src, *r, 0, 4).as_deref() == Some(&[0u8; 4][..]) => notes.push(
                "data-section CRC is 0 (not computed): record headers and indexes are not verified"
                    .into(),
            ),
            Some(_) => {}
        }
        notes
    }
}

/// Walks the top-level records before the mcap crate does: every length must lie inside
/// the file and chunk sizes must be sane, because a corrupt length field would otherwise
/// make the reader try to allocate exabytes and abort the process.
fn layout(src: &Source) -> Result<Layout, String> {
    if src.len() < 2 * MAGIC.len() || src.get(0, MAGIC.len()).as_deref() != Some(MAGIC) {
        return Err("missing MCAP magic bytes".into());
    }
    let u64_at = |p: usize| -> Option<u64> {
        src.get(p, 8)
            .map(|b| u64::from_le_bytes(b[..].try_into().unwrap()))
    };
    let mut records = Vec::new();
    let mut pos = MAGIC.len();
    let end = src.len() - MAGIC.len();
    while pos < end {
        let op = src
            .get(pos, 1)
            .ok_or_else(|| format!("record at byte {pos}: unreadable"))?[0];
        let len =
            u64_at(pos + 1).ok_or_else(|| format!("record at byte {pos}: truncated header"))?;
        let body = pos + 9;
        if body > end || len > (end - body) as u64 {
            return Err(format!("record at byte {pos} (opcode 0x{op:02x}): length {len} runs past the end of the file"));
        }
        if op == op::CHUNK {
            let unc = u64_at(body + 16).ok_or_else(|| format!("chunk at byte {pos}: truncated"))?;
            let compressed = len.saturating_sub(40);
            if unc > MAX_CHUNK_BYTES
                || unc > CHUNK_SLACK + compressed.saturating_mul(MAX_CHUNK_RATIO)
            {
                return Err(format!(
                    "chunk at byte {pos}: uncompressed size {unc} is implausible"
                ));
            }
        }
        records.push(TopRecord {
            offset: pos,
            opcode: op,
            len: len as usize,
        });
        if op == op::FOOTER {
            // Footer: the rest is the closing magic.
            break;
        }
        pos = body + len as usize;
    }
    Ok(Layout { records })
}

#[derive(Clone)]
struct SchemaInfo {
    name: String,
    encoding: String,
    data: Vec<u8>,
}

/// One message as the reader yields it: its data borrowed from the decompressed chunk
/// (copied only where it is kept as it is).
struct RawMsg<'a> {
    topic: String,
    encoding: String,
    schema: Option<SchemaInfo>,
    data: &'a [u8],
    /// Where the message lies: the top-level record holding it (a chunk, or the
    /// message itself) and its channel, so that it can be read again.
    place: (usize, u16),
}

/// Every message in file order, handed to `each` as it is read; returns the notes of
/// the integrity check.
///
/// Read with the sans-I/O reader, which computes the CRCs as the bytes go in: each chunk's
/// CRC is checked before any of its records is used, the data-section CRC at the
/// `DataEnd` record and the summary CRC at the footer. A mismatch is an error naming the
/// record's byte offset and, for a chunk, its topics. A record-length limit keeps corrupt
/// length fields from causing huge allocations.
fn messages(
    src: &Source,
    mut each: impl FnMut(RawMsg) -> Result<(), FormatError>,
) -> Result<Vec<String>, Stop> {
    use mcap::records::Record;
    use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};
    let layout = layout(src).map_err(Stop::Mcap)?;
    let limit = (256usize << 20).saturating_add(src.len().saturating_mul(16));
    let mut reader = LinearReader::new_with_options(
        LinearReaderOptions::default()
            .with_record_length_limit(limit)
            .with_prevalidate_chunk_crcs(true)
            .with_validate_data_section_crc(true)
            .with_validate_summary_section_crc(true)
            .with_check_finishes_after_end_magic(true),
    );
    let mut pos = 0usize;
    let mut schemas: BTreeMap<u16, SchemaInfo> = BTreeMap::new();
    let mut channels: BTreeMap<u16, (String, String, u16)> = BTreeMap::new();
    let mut count = 0usize;
    let at = |pos: usize, e: &dyn std::fmt::Display| format!("{}: {e}", layout.describe(src, pos));
    while let Some(event) = reader.next_event() {
        match event.map_err(|e| Stop::Mcap(at(pos, &crc_detail(e))))? {
            LinearReadEvent::ReadRequest(need) => {
                let n = need.min(src.len() - pos);
                src.read_linear(pos, reader.insert(n)).map_err(Stop::Mcap)?;
                reader.notify_read(n);
                pos += n;
            }
            LinearReadEvent::Record { opcode, data } => {
                match mcap::parse_record(opcode, data).map_err(|e| Stop::Mcap(at(pos, &e)))? {
                    Record::Schema { header, data } => {
                        schemas.insert(
                            header.id,
                            SchemaInfo {
                                name: header.name,
                                encoding: header.encoding,
                                data: data.into_owned(),
                            },
                        );
                    }
                    Record::Channel(c) => {
                        channels.insert(c.id, (c.topic, c.message_encoding, c.schema_id));
                    }
                    Record::Message { header, data } => {
                        let (topic, encoding, sid) = channels
                            .get(&header.channel_id)
                            .cloned()
                            .ok_or_else(|| {
                                format!(
                                    "message {} refers to channel {} which was never defined",
                                    count, header.channel_id
                                )
                            })
                            .map_err(Stop::Mcap)?;
                        let schema = if sid == 0 {
                            None
                        } else {
                            Some(schemas.get(&sid).cloned().ok_or_else(|| {
                                Stop::Mcap(format!(
                                    "channel '{topic}' refers to undefined schema {sid}"
                                ))
                            })?)
                        };
                        count += 1;
                        // The reader yields a record's messages once it has read the
                        // whole record: the last byte read lies in it.
                        let record = layout.at(pos.saturating_sub(1)).map_or(0, |r| r.offset);
                        each(RawMsg {
                            topic,
                            encoding,
                            schema,
                            data: &data,
                            place: (record, header.channel_id),
                        })
                        .map_err(Stop::Record)?;
                    }
                    _ => {}
                }
            }
        }
    }
    Ok(layout.unverified(src))
}

/// The mcap crate's CRC errors in words (the others as they are).
fn crc_detail(e: mcap::McapError) -> String {
    use mcap::McapError::*;
    match e {
        BadChunkCrc { saved, calculated } => format!(
            "CRC mismatch: the chunk's records changed after writing (stored CRC {saved:#010x}, computed {calculated:#010x})"
        ),
        BadDataCrc { saved, calculated } => format!(
            "CRC mismatch: a record of the data section changed after writing (stored CRC {saved:#010x}, computed {calculated:#010x})"
        ),
        BadSummaryCrc { saved, calculated } => format!(
            "CRC mismatch: the summary section changed after writing (stored CRC {saved:#010x}, computed {calculated:#010x})"
        ),
        e => e.to_string(),
    }
}
