//! Recorded time histories in the two formats besides UFF 58 type 1 — the MCAP topic
//! `/rbprops/time_history` ([`rbprops_formats::wire::TimeHistoryMsg`]) and a directory of
//! CSV files — read into one model, [`TimeRecording`], which [`TimeRecording::to_uff`]
//! turns into the datasets 58 (function type 1) an analyser would have exported. So
//! `frf-est` has one path from any of the three formats to its FRFs: the same hit
//! sorting ([`crate::timehist`]), the same units and DOF mapping, the same output bytes.
//! The layouts are documented in docs/formats.md (Time histories). No I/O here: the CSV
//! reader is given a function that reads a file of the directory by name.
//!
//! Every record is checked before it becomes a dataset (the errors name the file, the
//! excitation, the record and the channel): a first channel that is not a force, a
//! response that is, channels of different length, a record of a different length or
//! sampling than the others, a non-uniform time column, a truncated or corrupted sample
//! block, a non-finite sample, a doubled DOF or hit.

use crate::error::{DatasetLocation, UffError};
use crate::model::{
    AxisInfo, Dataset, Function, Node, NodeFormat, NodeSet, OrdinateType, Record, UffFile, Units,
};
use crate::timehist::{self, HitLayout, TimeHistoryIndex};
use rbprops_formats::wire::{
    decode_samples, encode_samples, TimeChannelMsg, TimeHistoryMsg, TimeRecordMsg,
};

/// What a channel measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimeQuantity {
    /// The excitation force (the first channel of an excitation, and only it).
    Force,
    /// Acceleration.
    Acceleration,
    /// Velocity.
    Velocity,
    /// Displacement.
    Displacement,
}

impl TimeQuantity {
    /// The quantity a word names (`force`, `acceleration`, `velocity`, `displacement`).
    pub fn parse(s: &str) -> Option<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "force" => Some(Self::Force),
            "acceleration" => Some(Self::Acceleration),
            "velocity" => Some(Self::Velocity),
            "displacement" => Some(Self::Displacement),
            _ => None,
        }
    }

    /// Its word.
    pub fn name(self) -> &'static str {
        match self {
            Self::Force => "force",
            Self::Acceleration => "acceleration",
            Self::Velocity => "velocity",
            Self::Displacement => "displacement",
        }
    }

    /// UFF record 9 specific data type and (length, force) exponents.
    fn uff_axis(self) -> (i64, i64, i64) {
        match self {
            Self::Force => (13, 0, 1),
            Self::Acceleration => (12, 1, 0),
            Self::Velocity => (11, 1, 0),
            Self::Displacement => (8, 1, 0),
        }
    }

    fn from_data_type(t: i64) -> Option<Self> {
        match t {
            9 | 13 => Some(Self::Force),
            12 => Some(Self::Acceleration),
            11 => Some(Self::Velocity),
            8 => Some(Self::Displacement),
            _ => None,
        }
    }
}

/// One channel: where it measures, what, in which unit.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeChannel {
    /// Channel id ("" to let the DOF name it).
    pub id: String,
    /// Point id ("" to let the node name it).
    pub point: String,
    /// Node number.
    pub node: i64,
    /// ±1..±3.
    pub direction: i64,
    /// What it measures.
    pub quantity: TimeQuantity,
    /// Units label ("" for SI).
    pub unit: String,
    /// Node position (m), when the recording carries its geometry.
    pub position_m: Option<[f64; 3]>,
}

/// One record: every channel's samples, in the excitation's channel order.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeRecord {
    /// Hit number (≥ 1), or 0 for a throughput record.
    pub hit: usize,
    /// `samples[channel][k]`.
    pub samples: Vec<Vec<f64>>,
    /// Where it came from, for errors (`message 2 record 3`, `force1-hit3.csv`).
    pub source: String,
}

/// One excitation's recording.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeExcitation {
    /// Excitation id ("" to let the force DOF name it).
    pub id: String,
    /// Set-up id ("" for the default).
    pub setup: String,
    /// Set-up description.
    pub setup_description: String,
    /// Sampling rate (Hz).
    pub sample_rate_hz: f64,
    /// One continuous record holding every hit (else one record per hit).
    pub throughput: bool,
    /// The force channel first, then the responses.
    pub channels: Vec<TimeChannel>,
    /// The records in hit order.
    pub records: Vec<TimeRecord>,
    /// Where it came from, for errors (`message 1`, `records.csv`).
    pub source: String,
}

/// A recording in any of the formats.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeRecording {
    /// The file (or directory) name, for errors.
    pub file_name: String,
    /// The excitations.
    pub excitations: Vec<TimeExcitation>,
}

fn err(file: &str, problem: String) -> UffError {
    UffError::Campaign {
        file: file.to_string(),
        problem,
    }
}

fn direction_name(d: i64) -> String {
    let axis = ["X", "Y", "Z"].get((d.unsigned_abs() as usize).wrapping_sub(1));
    match axis {
        Some(a) => format!("{}{a}", if d < 0 { "-" } else { "+" }),
        None => d.to_string(),
    }
}

/// An excitation's channels: the force first (and only there), then at least one
/// response, each at a node ≥ 1 and a direction ±1..±3, no response DOF twice. Returns
/// the force channel; errors through `at`.
fn check_channels<'e>(
    ex: &'e TimeExcitation,
    at: &dyn Fn(String) -> UffError,
) -> Result<&'e TimeChannel, UffError> {
    let Some(force) = ex.channels.first() else {
        return Err(at("no channels".into()));
    };
    if force.quantity != TimeQuantity::Force {
        return Err(at(format!(
            "no recognisable force channel: the first channel '{}' is {} (the force must come first, quantity force)",
            force.id,
            force.quantity.name()
        )));
    }
    if ex.channels.len() < 2 {
        return Err(at("a force channel and no response channel".into()));
    }
    let mut dofs: Vec<(i64, i64)> = Vec::new();
    for (k, c) in ex.channels.iter().enumerate() {
        if k > 0 && c.quantity == TimeQuantity::Force {
            return Err(at(format!(
                "channel '{}' is a second force: one force channel per excitation (its first)",
                c.id
            )));
        }
        if c.node < 1 || !(1..=3).contains(&c.direction.abs()) {
            return Err(at(format!(
                "channel '{}': node {} direction {} (need a node ≥ 1 and a direction ±1..±3)",
                c.id, c.node, c.direction
            )));
        }
        if k > 0 {
            if dofs.contains(&(c.node, c.direction)) {
                return Err(at(format!(
                    "channel '{}': a second response at node {} {}",
                    c.id,
                    c.node,
                    direction_name(c.direction)
                )));
            }
            dofs.push((c.node, c.direction));
        }
    }
    Ok(force)
}

/// An excitation's records: distinct hit numbers from 1 (per-hit layout), one sample
/// vector per declared channel, `n` finite samples each. Errors through `at`.
fn check_records(
    ex: &TimeExcitation,
    n: usize,
    at: &dyn Fn(String) -> UffError,
) -> Result<(), UffError> {
    let mut hits: Vec<usize> = Vec::new();
    for r in &ex.records {
        let rat = |what: String| at(format!("{}: {what}", r.source));
        if !ex.throughput {
            if r.hit == 0 || hits.contains(&r.hit) {
                return Err(rat(format!(
                    "hit {}: hit numbers must be 1, 2, … and distinct",
                    r.hit
                )));
            }
            hits.push(r.hit);
        }
        if r.samples.len() != ex.channels.len() {
            return Err(rat(format!(
                "{} channels of samples, {} channels declared",
                r.samples.len(),
                ex.channels.len()
            )));
        }
        for (c, s) in ex.channels.iter().zip(&r.samples) {
            if s.len() != n {
                return Err(rat(format!(
                    "channel '{}' has {} samples, the first record {n}: every record and channel must have one length",
                    c.id,
                    s.len()
                )));
            }
            if let Some(k) = s.iter().position(|v| !v.is_finite()) {
                return Err(rat(format!(
                    "channel '{}', sample {}: {} is not a finite number",
                    c.id,
                    k + 1,
                    s[k]
                )));
            }
        }
    }
    Ok(())
}

/// One finite position per node over every excitation's channels.
fn check_positions(file: &str, excitations: &[TimeExcitation]) -> Result<(), UffError> {
    let mut nodes: Vec<(i64, [f64; 3])> = Vec::new();
    for c in excitations.iter().flat_map(|e| &e.channels) {
        if let Some(p) = c.position_m {
            if p.iter().any(|x| !x.is_finite()) {
                return Err(err(
                    file,
                    format!("channel '{}': position {p:?} is not finite", c.id),
                ));
            }
            match nodes.iter().find(|(n, _)| *n == c.node) {
                Some((_, q)) if *q != p => {
                    return Err(err(
                        file,
                        format!(
                            "node {}: two positions, {q:?} and {p:?} (channel '{}')",
                            c.node, c.id
                        ),
                    ))
                }
                Some(_) => {}
                None => nodes.push((c.node, p)),
            }
        }
    }
    Ok(())
}

/// Record `k` (channel `c`, samples `s`) of hit `hit` of `ex` as the dataset 58 function
/// [`TimeRecording::to_uff`] writes (its docs).
fn time_function(
    ex: &TimeExcitation,
    hit: usize,
    k: usize,
    c: &TimeChannel,
    s: &[f64],
    setup_line: &str,
) -> Function {
    let none = || "NONE".to_string();
    let force = &ex.channels[0];
    let dt = 1.0 / ex.sample_rate_hz;
    let mut tags = String::from("rbprops");
    if k > 0 {
        for (key, v) in [("ch", &c.id), ("cp", &c.point)] {
            if !v.is_empty() {
                tags.push_str(&format!(" {key}={v}"));
            }
        }
    }
    for (key, v) in [("ex", &ex.id), ("ep", &force.point)] {
        if !v.is_empty() {
            tags.push_str(&format!(" {key}={v}"));
        }
    }
    tags.push_str(&format!(" hit={hit}"));
    let (data_type, length_exp, force_exp) = c.quantity.uff_axis();
    Function {
        id_lines: [
            format!("{} {} hit {hit}", ex.id, c.id).trim().to_string(),
            none(),
            none(),
            setup_line.to_string(),
            tags,
        ],
        function_type: 1,
        function_id: 0,
        version: 0,
        load_case: hit as i64,
        response_entity: none(),
        response_node: c.node,
        response_direction: c.direction,
        reference_entity: none(),
        reference_node: force.node,
        reference_direction: force.direction,
        ordinate_type: OrdinateType::RealDouble,
        even: true,
        abscissa_min: 0.0,
        abscissa_increment: dt,
        z_value: 0.0,
        abscissa_axis: AxisInfo {
            data_type: 17,
            label: none(),
            units_label: "s".into(),
            ..Default::default()
        },
        numerator: AxisInfo {
            data_type,
            length_exp,
            force_exp,
            temperature_exp: 0,
            label: none(),
            units_label: if c.unit.trim().is_empty() {
                none()
            } else {
                c.unit.trim().to_string()
            },
        },
        denominator: AxisInfo {
            label: none(),
            units_label: none(),
            ..Default::default()
        },
        z_axis: AxisInfo {
            label: none(),
            units_label: none(),
            ..Default::default()
        },
        binary: None,
        abscissa: Vec::new(),
        ordinate: Vec::new(),
        samples: s.to_vec(),
        samples_set_aside: 0,
    }
}

/// A direction `+x`, `-X`, `x`, `2`, `-3`: ±1..±3.
pub fn parse_direction(s: &str) -> Option<i64> {
    let t = s.trim().to_ascii_uppercase();
    let (sign, rest) = match t.strip_prefix('-') {
        Some(r) => (-1, r),
        None => (1, t.strip_prefix('+').unwrap_or(&t)),
    };
    let a = match rest {
        "X" | "1" => 1,
        "Y" | "2" => 2,
        "Z" | "3" => 3,
        _ => return None,
    };
    Some(sign * a)
}

impl TimeRecording {
    /// Checks the recording (module docs); errors name the file, excitation, record and
    /// channel.
    pub fn check(&self) -> Result<(), UffError> {
        let file = &self.file_name;
        let Some(first) = self.excitations.first() else {
            return Err(err(file, "no time histories in the recording".into()));
        };
        let n = first.records.first().map_or(0, |r| r.samples[0].len());
        let mut force_dofs: Vec<(i64, i64)> = Vec::new();
        let mut ids: Vec<&str> = Vec::new();
        for ex in &self.excitations {
            let at = |what: String| {
                err(
                    file,
                    format!(
                        "{}, excitation '{}': {what}",
                        ex.source,
                        if ex.id.is_empty() { "?" } else { &ex.id }
                    ),
                )
            };
            if !ex.id.is_empty() {
                if ids.contains(&ex.id.as_str()) {
                    return Err(at("a second recording of this excitation".into()));
                }
                ids.push(&ex.id);
            }
            if !(ex.sample_rate_hz.is_finite() && ex.sample_rate_hz > 0.0) {
                return Err(at(format!(
                    "sampling rate {} Hz is not a sampling rate",
                    ex.sample_rate_hz
                )));
            }
            let rel = (ex.sample_rate_hz - first.sample_rate_hz).abs() / first.sample_rate_hz;
            if rel > 1e-9 {
                return Err(at(format!(
                    "sampled at {} Hz, excitation '{}' at {} Hz: every channel must share one sampling rate",
                    ex.sample_rate_hz, first.id, first.sample_rate_hz
                )));
            }
            if ex.throughput != first.throughput {
                return Err(at(
                    "one excitation has throughput records and another per-hit records: one layout per recording".into(),
                ));
            }
            let force = check_channels(ex, &at)?;
            let fdof = (force.node, force.direction);
            if force_dofs.contains(&fdof) {
                return Err(at(format!(
                    "force at node {} {} is another excitation's force DOF",
                    fdof.0,
                    direction_name(fdof.1)
                )));
            }
            force_dofs.push(fdof);
            if ex.records.is_empty() {
                return Err(at("no records".into()));
            }
            if ex.throughput && ex.records.len() != 1 {
                return Err(at(format!(
                    "{} throughput records: one continuous record per excitation",
                    ex.records.len()
                )));
            }
            check_records(ex, n, &at)?;
        }
        if n < 16 {
            return Err(err(
                file,
                format!("{n} samples per record: too short a record"),
            ));
        }
        check_positions(file, &self.excitations)
    }

    /// The datasets before the time records: units (164, SI) and, when channels carry
    /// positions, the nodes (15) in the global frame, sorted by label.
    fn units_and_nodes(&self) -> Vec<Dataset> {
        let mut nodes: Vec<Node> = Vec::new();
        for c in self.excitations.iter().flat_map(|e| &e.channels) {
            if let Some(p) = c.position_m {
                if !nodes.iter().any(|n| n.label == c.node) {
                    nodes.push(Node {
                        label: c.node,
                        definition_cs: 0,
                        displacement_cs: 0,
                        color: 8,
                        coordinates: p,
                    });
                }
            }
        }
        let mut datasets = Vec::new();
        nodes.sort_by_key(|n| n.label);
        datasets.push(Dataset {
            location: DatasetLocation {
                index: 1,
                number: 164,
                line: 0,
            },
            record: Record::Units(Units {
                code: 1,
                description: "SI".into(),
                temperature_mode: 2,
                length_factor: 1.0,
                force_factor: 1.0,
                temperature_factor: 1.0,
                temperature_offset: 273.15,
            }),
        });
        if !nodes.is_empty() {
            datasets.push(Dataset {
                location: DatasetLocation {
                    index: 2,
                    number: 15,
                    line: 0,
                },
                record: Record::Nodes(NodeSet {
                    format: NodeFormat::D15,
                    nodes,
                }),
            });
        }
        datasets
    }

    /// The recording as the datasets 58 (function type 1) an analyser exports: per
    /// excitation and record, the force record then the responses, each with its DOF,
    /// load case = hit number (0 for throughput), data type and units label, and the
    /// ids in the ID lines as rbprops writes them (`setup=` in line 4, `rbprops ch= cp=
    /// ex= ep=` in line 5); the nodes with positions as a dataset 15 in the global frame
    /// (with an SI dataset 164). Checks first ([`Self::check`]).
    pub fn to_uff(&self) -> Result<UffFile, UffError> {
        self.check()?;
        let mut datasets = self.units_and_nodes();
        let mut count = datasets.len();
        let mut datasets_len_next = || {
            count += 1;
            count
        };
        let none = || "NONE".to_string();
        for ex in &self.excitations {
            let setup_line = if ex.setup.is_empty() {
                none()
            } else {
                format!("setup={} {}", ex.setup, ex.setup_description)
                    .trim_end()
                    .to_string()
            };
            for r in &ex.records {
                let hit = if ex.throughput { 0 } else { r.hit };
                for (k, (c, s)) in ex.channels.iter().zip(&r.samples).enumerate() {
                    let f = time_function(ex, hit, k, c, s, &setup_line);
                    datasets.push(Dataset {
                        location: DatasetLocation {
                            index: datasets_len_next(),
                            number: 58,
                            line: 0,
                        },
                        record: Record::Function(Box::new(f)),
                    });
                }
            }
        }
        Ok(UffFile {
            file_name: self.file_name.clone(),
            datasets,
        })
    }

    /// The recording as `/rbprops/time_history` messages, samples as f32 (`single`) or f64.
    pub fn to_messages(&self, single: bool) -> Vec<TimeHistoryMsg> {
        self.excitations
            .iter()
            .map(|ex| TimeHistoryMsg {
                excitation: ex.id.clone(),
                setup: ex.setup.clone(),
                setup_description: ex.setup_description.clone(),
                sample_rate_hz: ex.sample_rate_hz,
                record_samples: ex.records.first().map_or(0, |r| r.samples[0].len()),
                layout: if ex.throughput { "throughput" } else { "hits" }.into(),
                sample_format: if single { "f32le" } else { "f64le" }.into(),
                channels: ex
                    .channels
                    .iter()
                    .map(|c| TimeChannelMsg {
                        id: c.id.clone(),
                        point: c.point.clone(),
                        node: c.node,
                        direction: c.direction,
                        quantity: c.quantity.name().into(),
                        unit: c.unit.clone(),
                        position_m: c.position_m,
                    })
                    .collect(),
                records: ex
                    .records
                    .iter()
                    .map(|r| TimeRecordMsg {
                        hit: r.hit,
                        samples: encode_samples(&r.samples, single),
                    })
                    .collect(),
            })
            .collect()
    }

    /// The recording as a CSV directory (docs/formats.md): `(file name, text)` of
    /// `channels.csv`, `records.csv` and one file per record, numbers in shortest
    /// round-trip form (exact), times `k / f_s`.
    pub fn to_csv(&self) -> Vec<(String, String)> {
        let mut files = Vec::new();
        let mut channels = String::from("channel,point,node,direction,quantity,unit,x_m,y_m,z_m\n");
        let mut seen: Vec<String> = Vec::new();
        let mut records = String::from("excitation,setup,setup_description,hit,file\n");
        for ex in &self.excitations {
            for c in &ex.channels {
                if seen.contains(&c.id) {
                    continue;
                }
                seen.push(c.id.clone());
                let p = c
                    .position_m
                    .map_or(",,".to_string(), |p| format!("{},{},{}", p[0], p[1], p[2]));
                channels.push_str(&format!(
                    "{},{},{},{},{},{},{p}\n",
                    csv_cell(&c.id),
                    csv_cell(&c.point),
                    c.node,
                    direction_name(c.direction),
                    c.quantity.name(),
                    csv_cell(&c.unit)
                ));
            }
            for r in &ex.records {
                let name = if ex.throughput {
                    format!("{}.csv", file_safe(&ex.id))
                } else {
                    format!("{}-hit{}.csv", file_safe(&ex.id), r.hit)
                };
                records.push_str(&format!(
                    "{},{},{},{},{name}\n",
                    csv_cell(&ex.id),
                    csv_cell(&ex.setup),
                    csv_cell(&ex.setup_description),
                    if ex.throughput {
                        String::new()
                    } else {
                        r.hit.to_string()
                    }
                ));
                let mut text = String::from("time_s");
                for c in &ex.channels {
                    text.push(',');
                    text.push_str(&csv_cell(&c.id));
                }
                text.push('\n');
                let dt = 1.0 / ex.sample_rate_hz;
                for k in 0..r.samples[0].len() {
                    text.push_str(&format!("{}", k as f64 * dt));
                    for s in &r.samples {
                        text.push_str(&format!(",{}", s[k]));
                    }
                    text.push('\n');
                }
                files.push((name, text));
            }
        }
        let mut out = vec![
            ("channels.csv".to_string(), channels),
            ("records.csv".to_string(), records),
        ];
        out.extend(files);
        out
    }
}

fn csv_cell(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn file_safe(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The time histories of `/rbprops/time_history` messages read from `file`; each
/// message's block of samples is checked against its declared channels and samples.
pub fn from_messages(file: &str, msgs: &[TimeHistoryMsg]) -> Result<TimeRecording, UffError> {
    let mut excitations = Vec::new();
    for (m, msg) in msgs.iter().enumerate() {
        let source = format!("message {} of /rbprops/time_history", m + 1);
        let at = |what: String| {
            err(
                file,
                format!("{source}, excitation '{}': {what}", msg.excitation),
            )
        };
        let single = match msg.sample_format.as_str() {
            "f32le" => true,
            "f64le" => false,
            f => return Err(at(format!("sample_format '{f}': f32le or f64le"))),
        };
        let throughput = match msg.layout.as_str() {
            "hits" => false,
            "throughput" => true,
            l => return Err(at(format!("layout '{l}': hits or throughput"))),
        };
        let channels = msg
            .channels
            .iter()
            .map(|c| {
                Ok(TimeChannel {
                    id: c.id.clone(),
                    point: c.point.clone(),
                    node: c.node,
                    direction: c.direction,
                    quantity: TimeQuantity::parse(&c.quantity).ok_or_else(|| {
                        at(format!(
                            "channel '{}': quantity '{}' is not force, acceleration, velocity or displacement",
                            c.id, c.quantity
                        ))
                    })?,
                    unit: c.unit.clone(),
                    position_m: c.position_m,
                })
            })
            .collect::<Result<Vec<_>, UffError>>()?;
        let records = msg
            .records
            .iter()
            .enumerate()
            .map(|(k, r)| {
                let rsource = if throughput {
                    format!("record {}", k + 1)
                } else {
                    format!("record {} (hit {})", k + 1, r.hit)
                };
                let samples =
                    decode_samples(&r.samples, single, channels.len(), msg.record_samples)
                        .map_err(|e| {
                            at(format!("{rsource}: {e} (a truncated or corrupted record)"))
                        })?;
                Ok(TimeRecord {
                    hit: r.hit,
                    samples,
                    source: rsource,
                })
            })
            .collect::<Result<Vec<_>, UffError>>()?;
        excitations.push(TimeExcitation {
            id: msg.excitation.clone(),
            setup: msg.setup.clone(),
            setup_description: msg.setup_description.clone(),
            sample_rate_hz: msg.sample_rate_hz,
            throughput,
            channels,
            records,
            source,
        });
    }
    let rec = TimeRecording {
        file_name: file.to_string(),
        excitations,
    };
    rec.check()?;
    Ok(rec)
}

/// A CSV table: header and rows, each row with its 1-based line number.
struct Table {
    header: Vec<String>,
    rows: Vec<(usize, Vec<String>)>,
}

fn table(file: &str, name: &str, text: &str) -> Result<Table, UffError> {
    let mut r = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(false)
        .from_reader(text.as_bytes());
    let header: Vec<String> = r
        .headers()
        .map_err(|e| err(file, format!("{name}: {e}")))?
        .iter()
        .map(|h| h.trim().to_string())
        .collect();
    let mut rows = Vec::new();
    for (i, row) in r.records().enumerate() {
        let row = row.map_err(|e| err(file, format!("{name}: {e}")))?;
        let line = row.position().map_or(i + 2, |p| p.line() as usize);
        rows.push((line, row.iter().map(|c| c.to_string()).collect()));
    }
    Ok(Table { header, rows })
}

impl Table {
    fn column(
        &self,
        file: &str,
        name: &str,
        col: &str,
        required: bool,
    ) -> Result<Option<usize>, UffError> {
        match self.header.iter().position(|h| h == col) {
            Some(i) => Ok(Some(i)),
            None if required => Err(err(
                file,
                format!(
                    "{name}: no column '{col}' (header: {})",
                    self.header.join(",")
                ),
            )),
            None => Ok(None),
        }
    }
}

/// The time histories of a CSV directory `dir` (docs/formats.md): `records.csv` lists
/// the record files with their excitation, set-up and hit; `channels.csv` describes every
/// channel; each record file has a `time_s` column and one column per channel, the
/// excitation's force first. `read(name)` gives the text of a file of the directory.
/// The sampling rate is `(n − 1)/(t_last − t_first)` of the time column; a step further
/// than 1e-6 of it from the mean step is a non-uniform time column.
pub fn from_csv(
    dir: &str,
    mut read: impl FnMut(&str) -> Result<String, String>,
) -> Result<TimeRecording, UffError> {
    let load = |read: &mut dyn FnMut(&str) -> Result<String, String>, name: &str| {
        read(name).map_err(|e| err(dir, format!("{name}: {e}")))
    };
    let ch_text = load(&mut read, "channels.csv")?;
    let channels = csv_channels(dir, &ch_text)?;
    let col = |t: &Table, name: &str, c: &str, req: bool| t.column(dir, name, c, req);
    let rec_text = load(&mut read, "records.csv")?;
    let rt = table(dir, "records.csv", &rec_text)?;
    let (ei, si, sdi, hi, fi) = (
        col(&rt, "records.csv", "excitation", true)?.unwrap(),
        col(&rt, "records.csv", "setup", false)?,
        col(&rt, "records.csv", "setup_description", false)?,
        col(&rt, "records.csv", "hit", false)?,
        col(&rt, "records.csv", "file", true)?.unwrap(),
    );
    let mut excitations: Vec<TimeExcitation> = Vec::new();
    for (line, row) in &rt.rows {
        let at = |what: String| err(dir, format!("records.csv line {line}: {what}"));
        let cell = |i: Option<usize>| i.map_or("", |i| row[i].trim());
        let name = cell(Some(fi)).to_string();
        let hit_cell = cell(hi);
        let (hit, throughput) = if hit_cell.is_empty() || hit_cell == "0" {
            (0, true)
        } else {
            (
                hit_cell
                    .parse::<usize>()
                    .map_err(|_| at(format!("hit '{hit_cell}' is not a whole number")))?,
                false,
            )
        };
        let text = load(&mut read, &name)?;
        let (cols, samples, fs) = csv_record_file(dir, &name, &text, &channels)?;
        let fat = |what: String| err(dir, format!("{name}: {what}"));
        let ex_id = cell(Some(ei)).to_string();
        let record = TimeRecord {
            hit,
            samples,
            source: name.clone(),
        };
        match excitations.iter_mut().find(|e| e.id == ex_id) {
            Some(e) => {
                if e.channels != cols {
                    return Err(fat(format!(
                        "its channels differ from those of the excitation's first record ({})",
                        e.records[0].source
                    )));
                }
                if (e.sample_rate_hz - fs).abs() > 1e-9 * fs {
                    return Err(fat(format!(
                        "sampled at {fs} Hz, {} at {} Hz: every record must share one sampling rate",
                        e.records[0].source, e.sample_rate_hz
                    )));
                }
                if e.throughput != throughput {
                    return Err(at(
                        "a throughput record beside per-hit records of the same excitation".into(),
                    ));
                }
                e.records.push(record);
            }
            None => excitations.push(TimeExcitation {
                id: ex_id,
                setup: cell(si).to_string(),
                setup_description: cell(sdi).to_string(),
                sample_rate_hz: fs,
                throughput,
                channels: cols,
                records: vec![record],
                source: format!("records.csv line {line}"),
            }),
        }
    }
    for e in &mut excitations {
        e.records.sort_by_key(|r| r.hit);
    }
    let rec = TimeRecording {
        file_name: dir.to_string(),
        excitations,
    };
    rec.check()?;
    Ok(rec)
}

/// The channels of `channels.csv` (docs/formats.md): distinct ids, node, direction,
/// quantity, optional point, unit and position. Errors name the line.
fn csv_channels(dir: &str, ch_text: &str) -> Result<Vec<TimeChannel>, UffError> {
    let ch = table(dir, "channels.csv", ch_text)?;
    let col = |t: &Table, name: &str, c: &str, req: bool| t.column(dir, name, c, req);
    let (ci, pi, ni, di, qi, ui) = (
        col(&ch, "channels.csv", "channel", true)?.unwrap(),
        col(&ch, "channels.csv", "point", false)?,
        col(&ch, "channels.csv", "node", true)?.unwrap(),
        col(&ch, "channels.csv", "direction", true)?.unwrap(),
        col(&ch, "channels.csv", "quantity", true)?.unwrap(),
        col(&ch, "channels.csv", "unit", false)?,
    );
    let xyz = [
        col(&ch, "channels.csv", "x_m", false)?,
        col(&ch, "channels.csv", "y_m", false)?,
        col(&ch, "channels.csv", "z_m", false)?,
    ];
    let mut channels: Vec<TimeChannel> = Vec::new();
    for (line, row) in &ch.rows {
        let at = |what: String| err(dir, format!("channels.csv line {line}: {what}"));
        let cell = |i: Option<usize>| i.map_or("", |i| row[i].trim());
        let id = cell(Some(ci)).to_string();
        if id.is_empty() || channels.iter().any(|c| c.id == id) {
            return Err(at(format!(
                "channel '{id}': ids must be given and distinct"
            )));
        }
        let node: i64 = cell(Some(ni))
            .parse()
            .map_err(|_| at(format!("node '{}' is not an integer", cell(Some(ni)))))?;
        let direction = parse_direction(cell(Some(di))).ok_or_else(|| {
            at(format!(
                "direction '{}' is not ±x, ±y, ±z or ±1..±3",
                cell(Some(di))
            ))
        })?;
        let quantity = TimeQuantity::parse(cell(Some(qi))).ok_or_else(|| {
            at(format!(
                "quantity '{}' is not force, acceleration, velocity or displacement",
                cell(Some(qi))
            ))
        })?;
        let coords: Vec<&str> = xyz.iter().map(|&i| cell(i)).collect();
        let position_m = if coords.iter().all(|c| c.is_empty()) {
            None
        } else {
            let mut p = [0.0; 3];
            for (k, c) in coords.iter().enumerate() {
                p[k] = c
                    .parse()
                    .map_err(|_| at(format!("position '{c}' is not a number")))?;
            }
            Some(p)
        };
        channels.push(TimeChannel {
            id,
            point: cell(pi).to_string(),
            node,
            direction,
            quantity,
            unit: cell(ui).to_string(),
            position_m,
        });
    }
    Ok(channels)
}

/// A record file's channels, samples per channel and sampling rate (Hz).
type RecordFile = (Vec<TimeChannel>, Vec<Vec<f64>>, f64);

/// One record file: `time_s`, the force channel, then the responses (columns named by
/// `channels`), every value finite, the time evenly spaced. Its channels, samples per
/// channel and sampling rate (Hz). Errors name the file and line.
fn csv_record_file(
    dir: &str,
    name: &str,
    text: &str,
    channels: &[TimeChannel],
) -> Result<RecordFile, UffError> {
    let t = table(dir, name, text)?;
    let fat = |what: String| err(dir, format!("{name}: {what}"));
    if t.header.first().map(String::as_str) != Some("time_s") || t.header.len() < 3 {
        return Err(fat(format!(
            "header '{}': time_s, then the force channel, then the responses",
            t.header.join(",")
        )));
    }
    let mut cols = Vec::new();
    for h in &t.header[1..] {
        let Some(c) = channels.iter().find(|c| &c.id == h) else {
            return Err(fat(format!(
                "column '{h}' is not a channel of channels.csv"
            )));
        };
        cols.push(c.clone());
    }
    let mut time = Vec::with_capacity(t.rows.len());
    let mut samples = vec![Vec::with_capacity(t.rows.len()); cols.len()];
    for (l, r) in &t.rows {
        let num = |k: usize| -> Result<f64, UffError> {
            let v: f64 = r[k].trim().parse().map_err(|_| {
                fat(format!(
                    "line {l}, column '{}': '{}' is not a number",
                    t.header[k], r[k]
                ))
            })?;
            if !v.is_finite() {
                return Err(fat(format!(
                    "line {l}, column '{}': {v} is not a finite number",
                    t.header[k]
                )));
            }
            Ok(v)
        };
        time.push(num(0)?);
        for (k, s) in samples.iter_mut().enumerate() {
            s.push(num(k + 1)?);
        }
    }
    if time.len() < 2 {
        return Err(fat(format!("{} samples: too short a record", time.len())));
    }
    let dt = (time[time.len() - 1] - time[0]) / (time.len() - 1) as f64;
    if !(dt > 0.0 && dt.is_finite()) {
        return Err(fat("time_s does not increase".into()));
    }
    for (k, w) in time.windows(2).enumerate() {
        if ((w[1] - w[0]) - dt).abs() > 1e-6 * dt {
            return Err(fat(format!(
                "line {}: non-uniform time column ({} s after {} s, the mean step is {dt} s): time histories must be evenly sampled",
                t.rows[k + 1].0, w[1], w[0]
            )));
        }
    }
    let fs = 1.0 / dt;
    Ok((cols, samples, fs))
}

/// The time histories of a universal file in the model (to write them as MCAP or CSV):
/// ids from the rbprops tags of the ID lines where present, units labels as written,
/// positions from datasets 15/2411 when the file has no dataset 164 or an SI one and the
/// nodes are in the global frame (else none: give `--geometry`).
pub fn from_uff(uff: &UffFile, index: &TimeHistoryIndex) -> Result<TimeRecording, UffError> {
    let mut positions: Vec<(i64, [f64; 3])> = Vec::new();
    let mut si = true;
    for d in &uff.datasets {
        match &d.record {
            Record::Units(u) => si &= u.length_factor == 1.0 && u.force_factor == 1.0,
            Record::Nodes(set) => positions.extend(
                set.nodes
                    .iter()
                    .filter(|n| n.definition_cs == 0 && n.displacement_cs == 0)
                    .map(|n| (n.label, n.coordinates)),
            ),
            _ => {}
        }
    }
    let channel = |i: usize| -> Result<TimeChannel, UffError> {
        let f = timehist::function(uff, i);
        let tags = crate::campaign::read_tags(f);
        let quantity = TimeQuantity::from_data_type(f.numerator.data_type)
            .or_else(|| timehist::is_force_record(f, &[]).then_some(TimeQuantity::Force))
            .ok_or_else(|| {
                err(
                    &uff.file_name,
                    format!(
                        "{}: record 9 data type {}: not force, acceleration, velocity or displacement",
                        uff.datasets[i].location, f.numerator.data_type
                    ),
                )
            })?;
        Ok(TimeChannel {
            id: tags.channel.clone().unwrap_or_default(),
            point: tags.channel_point.clone().unwrap_or_default(),
            node: f.response_node,
            direction: f.response_direction,
            quantity,
            unit: if crate::units::is_unset(&f.numerator.units_label) {
                String::new()
            } else {
                f.numerator.units_label.trim().to_string()
            },
            position_m: si
                .then(|| {
                    positions
                        .iter()
                        .find(|(n, _)| *n == f.response_node)
                        .map(|p| p.1)
                })
                .flatten(),
        })
    };
    let mut excitations = Vec::new();
    for ex in &index.excitations {
        let template = ex.template();
        let ff = timehist::function(uff, template.force);
        let tags = crate::campaign::read_tags(ff);
        let mut force = channel(template.force)?;
        force.quantity = TimeQuantity::Force;
        force.id = tags.excitation.clone().unwrap_or_default();
        force.point = tags.excitation_point.clone().unwrap_or_default();
        let mut channels = vec![force];
        for &r in &template.responses {
            channels.push(channel(r)?);
        }
        let sets: Vec<&timehist::HitDatasets> = match &ex.layout {
            HitLayout::PerHit(h) => h.iter().collect(),
            HitLayout::Throughput(h) => vec![h],
        };
        let records = sets
            .iter()
            .map(|h| TimeRecord {
                hit: h.hit,
                samples: std::iter::once(h.force)
                    .chain(h.responses.iter().copied())
                    .map(|i| timehist::samples(uff, i).to_vec())
                    .collect(),
                source: format!("{}", uff.datasets[h.force].location),
            })
            .collect();
        excitations.push(TimeExcitation {
            id: tags.excitation.clone().unwrap_or_default(),
            setup: tags.setup.clone().unwrap_or_default(),
            setup_description: tags.setup_description.clone(),
            sample_rate_hz: index.sample_rate_hz,
            throughput: matches!(ex.layout, HitLayout::Throughput(_)),
            channels,
            records,
            source: format!("{}", uff.datasets[template.force].location),
        });
    }
    Ok(TimeRecording {
        file_name: uff.file_name.clone(),
        excitations,
    })
}
