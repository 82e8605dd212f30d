//! The CSV directory format: one table per topic and one per list inside it (see
//! [`crate::flatten`]), plus
//! - `manifest.csv`: `table,topic,parent,field,parent_key,key,schema` — every table, in
//!   topic order, parents first; `parent_key` names the columns holding the parent
//!   row's key, `key` the table's own key columns (space separated);
//! - `schemas/<table>.json`: the JSON schema of each topic's messages;
//! - `frf_info.csv`: `quantity,unit` and `frf.csv`: `excitation,channel,frequency_hz,re,im`
//!   (long format, rows grouped by excitation then channel, lines ascending).
//!
//! Floats are written in shortest round-trip form, so MCAP ↔ CSV is bit-exact.
//!
//! The last provenance row records the directory's content digest (see [`crate::digest`]).

use crate::flatten::{self, Table};
use crate::{atomic, FormatError, JsonTopic, RunRecord};
use rbprops_core::{c64, FrfSet, Quantity};
use std::path::Path;

pub(crate) const MANIFEST: &str = "manifest.csv";
const MANIFEST_HEADER: [&str; 7] = [
    "table",
    "topic",
    "parent",
    "field",
    "parent_key",
    "key",
    "schema",
];

/// Table name of a topic: the topic without its `/rbprops/` prefix, `/` → `_`.
pub fn table_name(topic: &str) -> String {
    topic
        .trim_start_matches("/rbprops/")
        .trim_start_matches('/')
        .replace('/', "_")
}

fn io(path: &Path, e: impl std::fmt::Display) -> FormatError {
    FormatError::other(&path.display().to_string(), e)
}

fn write_table(dir: &Path, t: &Table) -> Result<(), FormatError> {
    let path = dir.join(format!("{}.csv", t.name));
    let mut w = csv::Writer::from_path(&path).map_err(|e| io(&path, e))?;
    w.write_record(&t.header).map_err(|e| io(&path, e))?;
    for r in &t.rows {
        w.write_record(r).map_err(|e| io(&path, e))?;
    }
    w.flush().map_err(|e| io(&path, e))
}

fn read_table(
    dir: &Path,
    name: &str,
    parent: Option<(String, String)>,
    (parent_key, key): (&str, &str),
) -> Result<Table, FormatError> {
    let path = dir.join(format!("{name}.csv"));
    let mut r = csv::ReaderBuilder::new()
        .has_headers(true)
        .from_path(&path)
        .map_err(|e| io(&path, e))?;
    let header: Vec<String> = r
        .headers()
        .map_err(|e| io(&path, e))?
        .iter()
        .map(String::from)
        .collect();
    let mut rows = Vec::new();
    for rec in r.records() {
        let rec = rec.map_err(|e| io(&path, e))?;
        rows.push(rec.iter().map(String::from).collect());
    }
    let inherited: Vec<String> = parent_key.split_whitespace().map(String::from).collect();
    let n_in = inherited.len();
    let mut key_cols = inherited;
    key_cols.extend(key.split_whitespace().map(String::from));
    Ok(Table {
        name: name.into(),
        parent,
        key: key_cols,
        inherited: n_in,
        header,
        rows,
    })
}

/// Writes a run as a CSV directory, atomically.
pub fn write(rec: &RunRecord, path: &Path) -> Result<(), FormatError> {
    if let Some(raw) = rec.raw_topics.first() {
        return Err(FormatError::other(
            &path.display().to_string(),
            format!(
                "topic {} is {}-encoded; only MCAP can carry it (write an .mcap file instead)",
                raw.name, raw.message_encoding
            ),
        ));
    }
    let geometry = if rec.frf.is_some() {
        rec.geometry()?
    } else {
        None
    };
    atomic::write_dir(path, |dir| {
        std::fs::create_dir_all(dir.join("schemas")).map_err(|e| io(dir, e))?;
        let mut manifest = csv::Writer::from_path(dir.join(MANIFEST)).map_err(|e| io(dir, e))?;
        manifest
            .write_record(MANIFEST_HEADER)
            .map_err(|e| io(dir, e))?;
        for t in &rec.topics {
            let mut tables = Vec::new();
            flatten::to_tables(&table_name(&t.name), &t.messages, &t.schema, &mut tables);
            let schema_file = dir
                .join("schemas")
                .join(format!("{}.json", table_name(&t.name)));
            std::fs::write(&schema_file, serde_json::to_vec_pretty(&t.schema).unwrap())
                .map_err(|e| io(&schema_file, e))?;
            for tb in &tables {
                let (p, f) = tb.parent.clone().unwrap_or_default();
                let parent_key = tb.key[..tb.inherited].join(" ");
                let key = tb.key[tb.inherited..].join(" ");
                manifest
                    .write_record([
                        tb.name.as_str(),
                        t.name.as_str(),
                        &p,
                        &f,
                        &parent_key,
                        &key,
                        &t.schema_name,
                    ])
                    .map_err(|e| io(dir, e))?;
                write_table(dir, tb)?;
            }
        }
        manifest.flush().map_err(|e| io(dir, e))?;
        drop(manifest);
        if let Some(frf) = &rec.frf {
            let g = geometry.as_ref().ok_or_else(|| {
                FormatError::other(&dir.display().to_string(), "an FRF set needs a geometry")
            })?;
            write_frf(dir, frf, g)?;
        }
        stamp_digest(rec, dir)
    })
}

/// Records the directory's content digest in the last provenance row (rewriting only the
/// provenance tables, which the digest leaves out). A run without provenance gets none.
fn stamp_digest(rec: &RunRecord, dir: &Path) -> Result<(), FormatError> {
    let Some(prov) = rec.topic(crate::topics::PROVENANCE) else {
        return Ok(());
    };
    let mut messages = prov.messages.clone();
    let Some(serde_json::Value::Object(last)) = messages.last_mut() else {
        return Ok(());
    };
    let digest = crate::digest::csv_content_sha256(dir)?;
    last.insert(
        crate::digest::CONTENT_FIELD.into(),
        serde_json::Value::String(digest),
    );
    let mut tables = Vec::new();
    flatten::to_tables(
        &table_name(&prov.name),
        &messages,
        &prov.schema,
        &mut tables,
    );
    for tb in &tables {
        write_table(dir, tb)?;
    }
    Ok(())
}

/// The manifest's rows: `[table, topic, parent, field, parent_key, key, schema]`.
pub(crate) fn read_manifest(path: &Path) -> Result<Vec<[String; 7]>, FormatError> {
    let mpath = path.join(MANIFEST);
    let mut m = csv::Reader::from_path(&mpath).map_err(|e| io(&mpath, e))?;
    let mut entries: Vec<[String; 7]> = Vec::new();
    for (i, r) in m.records().enumerate() {
        let r = r.map_err(|e| io(&mpath, e))?;
        if r.len() != MANIFEST_HEADER.len() {
            return Err(FormatError::record(
                &mpath.display().to_string(),
                format!("line {}", i + 2),
                format!(
                    "expected {} columns: {}",
                    MANIFEST_HEADER.len(),
                    MANIFEST_HEADER.join(",")
                ),
            ));
        }
        entries.push(std::array::from_fn(|k| r[k].to_string()));
    }
    Ok(entries)
}

/// The messages of one topic of a CSV directory (empty when the topic is absent).
pub(crate) fn read_topic_messages(
    path: &Path,
    topic: &str,
) -> Result<Vec<serde_json::Value>, FormatError> {
    let entries = read_manifest(path)?;
    let mut tables = Vec::new();
    let mut top = None;
    for [table, t, parent, field, parent_key, key, _] in &entries {
        if t != topic {
            continue;
        }
        let p = (!parent.is_empty()).then(|| (parent.clone(), field.clone()));
        if p.is_none() {
            top = Some(table.clone());
        }
        tables.push(read_table(path, table, p, (parent_key, key))?);
    }
    let Some(table) = top else {
        return Ok(Vec::new());
    };
    let sfile = path.join("schemas").join(format!("{table}.json"));
    let schema = match std::fs::read(&sfile) {
        Ok(b) => serde_json::from_slice(&b).map_err(|e| io(&sfile, e))?,
        Err(_) => serde_json::Value::Bool(true),
    };
    flatten::from_tables(&table, &tables, &schema)
        .map_err(|e| FormatError::record(&path.display().to_string(), format!("{table}.csv"), e))
}

fn write_frf(dir: &Path, frf: &FrfSet, g: &rbprops_core::Geometry) -> Result<(), FormatError> {
    let info = dir.join("frf_info.csv");
    std::fs::write(
        &info,
        format!(
            "quantity,unit\n{},{}\n",
            frf.quantity.name(),
            frf.quantity.unit()
        ),
    )
    .map_err(|e| io(&info, e))?;
    let path = dir.join("frf.csv");
    let mut w = csv::Writer::from_path(&path).map_err(|e| io(&path, e))?;
    w.write_record(["excitation", "channel", "frequency_hz", "re", "im"])
        .map_err(|e| io(&path, e))?;
    let mut b = [ryu::Buffer::new(), ryu::Buffer::new(), ryu::Buffer::new()];
    for (e, exc) in g.excitations.iter().enumerate() {
        for (c, ch) in g.channels.iter().enumerate() {
            for (l, v) in frf.frf(e, c).iter().enumerate() {
                let [b0, b1, b2] = &mut b;
                w.write_record([
                    exc.id.as_str(),
                    ch.id.as_str(),
                    b0.format(frf.frequency_hz[l]),
                    b1.format(v.re),
                    b2.format(v.im),
                ])
                .map_err(|e| io(&path, e))?;
            }
        }
    }
    w.flush().map_err(|e| io(&path, e))
}

/// Reads a CSV directory written by [`write()`] (or by another program following it).
pub fn read(path: &Path) -> Result<RunRecord, FormatError> {
    let entries = read_manifest(path)?;
    let mut rec = RunRecord::default();
    let mut tables = Vec::new();
    for [table, _, parent, field, parent_key, key, _] in &entries {
        let p = (!parent.is_empty()).then(|| (parent.clone(), field.clone()));
        tables.push(read_table(path, table, p, (parent_key, key))?);
    }
    for [table, topic, parent, _, _, _, schema_name] in &entries {
        if !parent.is_empty() {
            continue;
        }
        let sfile = path.join("schemas").join(format!("{table}.json"));
        let schema = match std::fs::read(&sfile) {
            Ok(b) => serde_json::from_slice(&b).map_err(|e| io(&sfile, e))?,
            Err(_) => serde_json::Value::Bool(true),
        };
        let mut messages = flatten::from_tables(table, &tables, &schema).map_err(|e| {
            FormatError::record(&path.display().to_string(), format!("{table}.csv"), e)
        })?;
        if topic == crate::topics::PROVENANCE {
            // The content digest belongs to the directory, not to the run (like an MCAP
            // CRC): it is checked by `digest::check_csv` and not carried on.
            for m in &mut messages {
                if let Some(o) = m.as_object_mut() {
                    o.remove(crate::digest::CONTENT_FIELD);
                }
            }
        }
        rec.topics.push(JsonTopic {
            name: topic.clone(),
            schema_name: schema_name.clone(),
            schema,
            messages,
        });
    }
    if path.join("frf.csv").exists() {
        let g = rec.geometry()?.ok_or_else(|| {
            FormatError::other(
                &path.display().to_string(),
                "frf.csv without geometry tables",
            )
        })?;
        rec.frf = Some(read_frf(path, &g)?);
    }
    Ok(rec)
}

fn read_frf(dir: &Path, g: &rbprops_core::Geometry) -> Result<FrfSet, FormatError> {
    let info = dir.join("frf_info.csv");
    let iname = info.display().to_string();
    let mut r = csv::Reader::from_path(&info).map_err(|e| io(&info, e))?;
    let row = r
        .records()
        .next()
        .ok_or_else(|| FormatError::record(&iname, "line 2", "missing"))?
        .map_err(|e| io(&info, e))?;
    let quantity: Quantity = row
        .get(0)
        .unwrap_or("")
        .parse()
        .map_err(|e| FormatError::record(&iname, "line 2, column quantity", e))?;
    let path = dir.join("frf.csv");
    let name = path.display().to_string();
    let mut r = csv::Reader::from_path(&path).map_err(|e| io(&path, e))?;
    let (ne, nc) = (g.excitations.len(), g.channels.len());
    // Each (excitation, channel) needs rows of at least 10 bytes: a geometry declaring more
    // cells than the file can hold is refused before anything is allocated for them.
    let size = std::fs::metadata(&path).map_err(|e| io(&path, e))?.len();
    match ne.checked_mul(nc) {
        Some(cells) if (cells as u64).saturating_mul(10) <= size => {}
        _ => {
            return Err(FormatError::record(
                &name,
                "FRF set",
                format!(
                    "the geometry declares {ne} excitations × {nc} channels, more than the {size} bytes of frf.csv can hold"
                ),
            ))
        }
    }
    let mut axis: Vec<f64> = Vec::new();
    let mut values: Vec<Vec<c64>> = vec![Vec::new(); ne * nc];
    let mut freqs: Vec<Vec<f64>> = vec![Vec::new(); ne * nc];
    for (i, rec) in r.records().enumerate() {
        let line = i + 2;
        let rec = rec.map_err(|e| io(&path, e))?;
        let at = |k: usize| rec.get(k).unwrap_or("");
        let e = g.excitation_index(at(0)).ok_or_else(|| {
            FormatError::record(
                &name,
                format!("line {line}"),
                format!("unknown excitation '{}'", at(0)),
            )
        })?;
        let c = g.channel_index(at(1)).ok_or_else(|| {
            FormatError::record(
                &name,
                format!("line {line}"),
                format!("unknown channel '{}'", at(1)),
            )
        })?;
        let num = |k: usize, col: &str| -> Result<f64, FormatError> {
            let v: f64 = at(k).parse().map_err(|_| {
                FormatError::record(
                    &name,
                    format!("line {line}, column {col}"),
                    format!("'{}' is not a number", at(k)),
                )
            })?;
            if !v.is_finite() {
                return Err(FormatError::record(
                    &name,
                    format!("line {line}, column {col}"),
                    format!("{v} is not finite"),
                ));
            }
            Ok(v)
        };
        freqs[e * nc + c].push(num(2, "frequency_hz")?);
        values[e * nc + c].push(c64::new(num(3, "re")?, num(4, "im")?));
    }
    for (k, f) in freqs.iter().enumerate() {
        let (e, c) = (k / nc, k % nc);
        if f.is_empty() {
            return Err(FormatError::record(
                &name,
                "FRF set",
                format!(
                    "no rows for excitation '{}', channel '{}'",
                    g.excitations[e].id, g.channels[c].id
                ),
            ));
        }
        if k == 0 {
            axis = f.clone();
        } else if *f != axis {
            return Err(FormatError::record(
                &name,
                "FRF set",
                format!(
                    "inconsistent frequency axes: excitation '{}', channel '{}' has {} lines that differ from excitation '{}', channel '{}'",
                    g.excitations[e].id,
                    g.channels[c].id,
                    f.len(),
                    g.excitations[0].id,
                    g.channels[0].id
                ),
            ));
        }
    }
    let mut frf = FrfSet::zeros(quantity, axis, ne, nc);
    for (k, v) in values.into_iter().enumerate() {
        frf.frf_mut(k / nc, k % nc).copy_from_slice(&v);
    }
    frf.validate()
        .map_err(|e| FormatError::record(&name, "FRF set", e))?;
    Ok(frf)
}
