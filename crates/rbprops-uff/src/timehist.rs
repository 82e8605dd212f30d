//! Time histories (dataset 58, function type 1) as analysers export them, sorted into
//! excitations and hits for FRF estimation, and the FRFs estimated from them turned back
//! into datasets 58 so that [`crate::read_campaign`] maps them to SI geometry and FRFs
//! exactly as it maps an analyser's FRF export (units, DOFs, set-ups, tags).
//!
//! # What is recognised
//! - **Force records**: record 9 (ordinate) data type 13 (excitation force) or 9
//!   (reaction force), or data type 0/1 with a force units label (`N`, `lbf`, `kN`);
//!   or the DOFs named by the caller ([`TimeOptions::force_dofs`]).
//! - **Response records**: every other function type 1 record.
//! - **Excitation of a response**: the force record whose response DOF is the response
//!   record's reference DOF (record 6 fields 9–10); when the reference is node 0, the
//!   nearest force record before it in the file (the one after it for records before the
//!   first force record).
//! - **Hits**: in the per-hit layout (several records per excitation and DOF, or a load
//!   case ≥ 1 in record 6 field 4) each record is one hit, numbered by its load case when
//!   the load cases of an excitation's force records are distinct and positive, else by
//!   file order. Otherwise (one record per excitation and DOF) the records are
//!   continuous throughput records whose hits the estimator finds by trigger.
//! - **Sampling**: an evenly spaced abscissa (record 7 field 3), one increment and one
//!   length per layout for every record (so all FRFs share one frequency axis).

use crate::error::{DatasetLocation, UffError};
use crate::model::{AxisInfo, Dataset, Function, OrdinateType, Record, UffFile};
use rbprops_core::c64;

/// Options of [`index_time_histories`].
#[derive(Debug, Clone, Default)]
pub struct TimeOptions {
    /// Force DOFs `(node, direction)` named by the user, when the records' data types and
    /// units do not say which records are forces.
    pub force_dofs: Vec<(i64, i64)>,
}

/// How an excitation's records hold its hits.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum HitLayout {
    /// One record per hit and channel: `hits[h]` are the dataset indices of hit `h`'s
    /// force record and of its response records in [`TimeHistoryIndex::responses`] order.
    PerHit(Vec<HitDatasets>),
    /// One continuous record per channel with every hit in it.
    Throughput(HitDatasets),
}

/// The dataset indices (into [`UffFile::datasets`]) of one hit or one throughput record set.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HitDatasets {
    /// Hit number (1-based; 0 for a throughput record).
    pub hit: usize,
    /// The force record.
    pub force: usize,
    /// One response record per response DOF of the excitation, in the excitation's
    /// [`ExcitationRecords::responses`] order.
    pub responses: Vec<usize>,
}

/// The records of one excitation (one force DOF).
#[derive(Debug, Clone, PartialEq)]
pub struct ExcitationRecords {
    /// Force node and direction (record 6 fields 6–7 of its force records).
    pub force_dof: (i64, i64),
    /// Response DOFs `(node, direction)` in first-appearance order.
    pub responses: Vec<(i64, i64)>,
    /// Where the hits are.
    pub layout: HitLayout,
}

impl ExcitationRecords {
    /// The records of the first hit (per-hit layout) or the throughput records: the
    /// datasets whose DOFs, units and ID lines the estimated FRFs take.
    pub fn template(&self) -> &HitDatasets {
        match &self.layout {
            HitLayout::PerHit(h) => &h[0],
            HitLayout::Throughput(h) => h,
        }
    }
}

/// Time histories of a file sorted for FRF estimation.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeHistoryIndex {
    /// Sampling rate (Hz) of every record.
    pub sample_rate_hz: f64,
    /// Samples per record (per hit record, or per throughput record).
    pub record_samples: usize,
    /// Excitations in the order their force records first appear.
    pub excitations: Vec<ExcitationRecords>,
}

/// True when the file holds time histories (dataset 58, function type 1).
pub fn has_time_histories(uff: &UffFile) -> bool {
    uff.datasets
        .iter()
        .any(|d| matches!(&d.record, Record::Function(f) if f.function_type == 1))
}

/// The function of dataset `i` (the caller indexes only function datasets).
pub fn function(uff: &UffFile, i: usize) -> &Function {
    match &uff.datasets[i].record {
        Record::Function(f) => f,
        _ => unreachable!("time-history index points at a function dataset"),
    }
}

/// The real samples of a time record (its ordinate's real parts).
pub fn samples(uff: &UffFile, i: usize) -> &[f64] {
    &function(uff, i).samples
}

fn field_error(uff: &UffFile, at: &DatasetLocation, field: &str, problem: String) -> UffError {
    UffError::Field {
        file: uff.file_name.clone(),
        at: at.clone(),
        field: field.to_string(),
        problem,
    }
}

fn campaign_error(uff: &UffFile, problem: String) -> UffError {
    UffError::Campaign {
        file: uff.file_name.clone(),
        problem,
    }
}

/// Is this record's ordinate a force (module docs), or at one of `force_dofs`?
pub fn is_force_record(f: &Function, force_dofs: &[(i64, i64)]) -> bool {
    if force_dofs.contains(&(f.response_node, f.response_direction)) {
        return true;
    }
    match f.numerator.data_type {
        9 | 13 => true,
        0 | 1 => {
            let u = f.numerator.units_label.trim().to_ascii_lowercase();
            matches!(
                u.as_str(),
                "n" | "lbf" | "kn" | "newton" | "newtons" | "lb" | "kgf"
            )
        }
        _ => false,
    }
}

/// Sorts the file's time records into excitations and hits (module docs). Errors name the
/// dataset: an unevenly spaced or empty record, records of different sampling or length,
/// no force record, a response whose excitation cannot be told, a missing or doubled
/// (hit, DOF) record.
pub fn index_time_histories(
    uff: &UffFile,
    opts: &TimeOptions,
) -> Result<TimeHistoryIndex, UffError> {
    let records: Vec<usize> = (0..uff.datasets.len())
        .filter(|&i| matches!(&uff.datasets[i].record, Record::Function(f) if f.function_type == 1))
        .collect();
    if records.is_empty() {
        return Err(campaign_error(
            uff,
            "no time histories (dataset 58 with function type 1) in the file".into(),
        ));
    }
    let (dt, n) = sampling(uff, &records)?;
    let forces: Vec<usize> = records
        .iter()
        .copied()
        .filter(|&i| is_force_record(function(uff, i), &opts.force_dofs))
        .collect();
    if forces.is_empty() {
        return Err(campaign_error(
            uff,
            "no force channel among the time histories: none has record 9 data type 13 (excitation force) or 9 (reaction force) or a force units label; name it with frf-est --force-dof NODE:DIR".into(),
        ));
    }
    let mut excitations = excitations_of(uff, &forces);
    for &i in records.iter().filter(|i| !forces.contains(i)) {
        let f = function(uff, i);
        let e = excitation_of_response(uff, i, &forces, &excitations)?;
        let dof = (f.response_node, f.response_direction);
        let ex = &mut excitations[e];
        let k = match ex.0.responses.iter().position(|d| *d == dof) {
            Some(k) => k,
            None => {
                ex.0.responses.push(dof);
                ex.2.push(Vec::new());
                ex.0.responses.len() - 1
            }
        };
        ex.2[k].push(i);
    }
    let per_hit = excitations.iter().any(|e| e.1.len() > 1)
        || forces.iter().any(|&i| function(uff, i).load_case > 0);
    let mut out = Vec::new();
    for (mut ex, force_records, response_records) in excitations {
        if ex.responses.is_empty() {
            return Err(field_error(
                uff,
                &uff.datasets[force_records[0]].location,
                "record 6 fields 6-7 (response node, direction)",
                format!(
                    "force {} {} has no response records",
                    ex.force_dof.0, ex.force_dof.1
                ),
            ));
        }
        ex.layout = layout(uff, &ex, &force_records, &response_records, per_hit)?;
        out.push(ex);
    }
    Ok(TimeHistoryIndex {
        sample_rate_hz: 1.0 / dt,
        record_samples: n,
        excitations: out,
    })
}

/// An excitation being gathered: its records, its force records, and its response
/// records per response DOF (in [`ExcitationRecords::responses`] order).
type Gathered = (ExcitationRecords, Vec<usize>, Vec<Vec<usize>>);

/// One excitation per force DOF, in the order its force records first appear, with its
/// force records; responses still empty.
fn excitations_of(uff: &UffFile, forces: &[usize]) -> Vec<Gathered> {
    let mut excitations: Vec<Gathered> = Vec::new();
    for &i in forces {
        let f = function(uff, i);
        let dof = (f.response_node, f.response_direction);
        match excitations.iter_mut().find(|e| e.0.force_dof == dof) {
            Some(e) => e.1.push(i),
            None => excitations.push((
                ExcitationRecords {
                    force_dof: dof,
                    responses: Vec::new(),
                    layout: HitLayout::Throughput(HitDatasets {
                        hit: 0,
                        force: i,
                        responses: Vec::new(),
                    }),
                },
                vec![i],
                Vec::new(),
            )),
        }
    }
    excitations
}

/// The excitation of response record `i`: the one at its reference DOF, or, when the
/// reference is node 0, the nearest force record before it in the file (after it for
/// records before the first force). An error names a reference that is no force's DOF.
fn excitation_of_response(
    uff: &UffFile,
    i: usize,
    forces: &[usize],
    excitations: &[Gathered],
) -> Result<usize, UffError> {
    let f = function(uff, i);
    let by_reference = (f.reference_node != 0)
        .then(|| {
            excitations
                .iter()
                .position(|e| e.0.force_dof == (f.reference_node, f.reference_direction))
        })
        .flatten();
    if let Some(e) = by_reference {
        return Ok(e);
    }
    let before = forces.iter().rev().find(|&&fi| fi < i);
    let near = before.or_else(|| forces.iter().find(|&&fi| fi > i));
    let fdof = near.map(|&fi| {
        let g = function(uff, fi);
        (g.response_node, g.response_direction)
    });
    match fdof.and_then(|d| excitations.iter().position(|e| e.0.force_dof == d)) {
        Some(e) if f.reference_node == 0 => Ok(e),
        _ => Err(field_error(
            uff,
            &uff.datasets[i].location,
            "record 6 fields 9-10 (reference node, direction)",
            format!(
                "reference {} {} is no force record's DOF (forces: {})",
                f.reference_node,
                f.reference_direction,
                excitations
                    .iter()
                    .map(|e| format!("{} {}", e.0.force_dof.0, e.0.force_dof.1))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        )),
    }
}

/// One increment and one length for every record; evenly spaced, non-empty, finite.
fn sampling(uff: &UffFile, records: &[usize]) -> Result<(f64, usize), UffError> {
    let first = function(uff, records[0]);
    for &i in records {
        let f = function(uff, i);
        let at = &uff.datasets[i].location;
        if !f.even {
            return Err(field_error(
                uff,
                at,
                "record 7 field 3 (abscissa spacing)",
                "uneven abscissa: time histories must be evenly sampled".into(),
            ));
        }
        if f.ordinate_type.is_complex() {
            return Err(field_error(
                uff,
                at,
                "record 7 field 1 (ordinate data type)",
                format!("{:?}: time histories must be real", f.ordinate_type),
            ));
        }
        if !(f.abscissa_increment.is_finite() && f.abscissa_increment > 0.0) {
            return Err(field_error(
                uff,
                at,
                "record 7 field 5 (abscissa increment)",
                format!("{} s is not a sampling interval", f.abscissa_increment),
            ));
        }
        let rel =
            (f.abscissa_increment - first.abscissa_increment).abs() / first.abscissa_increment;
        if rel > 1e-9 {
            return Err(field_error(
                uff,
                at,
                "record 7 field 5 (abscissa increment)",
                format!(
                    "sampled at {} s, dataset #{} at {} s: every channel must share one sampling rate",
                    f.abscissa_increment, uff.datasets[records[0]].location.index, first.abscissa_increment
                ),
            ));
        }
        if f.len() != first.len() {
            return Err(field_error(
                uff,
                at,
                "record 7 field 2 (number of values)",
                format!(
                    "{} samples, dataset #{} has {}: every record must have one length",
                    f.len(),
                    uff.datasets[records[0]].location.index,
                    first.len()
                ),
            ));
        }
        if let Some(k) = f.samples.iter().position(|v| !v.is_finite()) {
            return Err(field_error(
                uff,
                at,
                &format!("record 12 value {}", k + 1),
                "not a finite number".into(),
            ));
        }
    }
    if first.len() < 16 {
        return Err(field_error(
            uff,
            &uff.datasets[records[0]].location,
            "record 7 field 2 (number of values)",
            format!("{} samples: too short a record", first.len()),
        ));
    }
    Ok((first.abscissa_increment, first.len()))
}

/// The hits of one excitation from its force records and its response records per DOF.
fn layout(
    uff: &UffFile,
    ex: &ExcitationRecords,
    forces: &[usize],
    responses: &[Vec<usize>],
    per_hit: bool,
) -> Result<HitLayout, UffError> {
    let n_hits = forces.len();
    for (k, r) in responses.iter().enumerate() {
        if r.len() != n_hits {
            let (node, dir) = ex.responses[k];
            return Err(field_error(
                uff,
                &uff.datasets[r[0]].location,
                "record 6 fields 6-7 (response node, direction)",
                format!(
                    "response {node} {dir} of force {} {} has {} record(s), the force {n_hits}: every hit needs one record per channel",
                    ex.force_dof.0,
                    ex.force_dof.1,
                    r.len()
                ),
            ));
        }
    }
    // Hit numbers: the force records' load cases when distinct and positive, else order.
    let cases: Vec<i64> = forces.iter().map(|&i| function(uff, i).load_case).collect();
    let mut sorted = cases.clone();
    sorted.sort_unstable();
    sorted.dedup();
    let by_case = sorted.len() == n_hits && sorted[0] > 0;
    let hit_of = |j: usize, i: usize| -> Result<usize, UffError> {
        if !by_case {
            return Ok(j);
        }
        let case = function(uff, i).load_case;
        cases.iter().position(|&c| c == case).ok_or_else(|| {
            field_error(
                uff,
                &uff.datasets[i].location,
                "record 6 field 4 (load case: the hit number)",
                format!("hit {case} has no force record"),
            )
        })
    };
    let mut hits: Vec<HitDatasets> = forces
        .iter()
        .enumerate()
        .map(|(j, &f)| HitDatasets {
            hit: if by_case { cases[j] as usize } else { j + 1 },
            force: f,
            responses: vec![usize::MAX; responses.len()],
        })
        .collect();
    for (k, r) in responses.iter().enumerate() {
        for (j, &i) in r.iter().enumerate() {
            let h = hit_of(j, i)?;
            if hits[h].responses[k] != usize::MAX {
                return Err(field_error(
                    uff,
                    &uff.datasets[i].location,
                    "record 6 field 4 (load case: the hit number)",
                    format!("a second record for hit {} and this DOF", hits[h].hit),
                ));
            }
            hits[h].responses[k] = i;
        }
    }
    hits.sort_by_key(|h| h.hit);
    if per_hit {
        Ok(HitLayout::PerHit(hits))
    } else {
        Ok(HitLayout::Throughput(hits.remove(0)))
    }
}

/// What a file's time histories are, in a few lines (`rbprops convert --list`): the
/// sampling rate, samples and length of a record, the layout, and per excitation its force
/// DOF and unit, its response DOFs with their units and its number of hits (per-hit
/// records) or records (throughput); `None` without time histories, the reason when they
/// cannot be sorted.
pub fn describe(uff: &UffFile) -> Option<String> {
    if !has_time_histories(uff) {
        return None;
    }
    let index = match index_time_histories(uff, &TimeOptions::default()) {
        Ok(i) => i,
        Err(e) => return Some(format!("time histories: cannot be sorted into hits: {e}")),
    };
    let dof = |(n, d): (i64, i64)| {
        let axis = ["X", "Y", "Z"].get((d.unsigned_abs() as usize).wrapping_sub(1));
        match axis {
            Some(a) => format!("{n}:{}{a}", if d < 0 { "-" } else { "+" }),
            None => format!("{n}:{d}"),
        }
    };
    let unit = |i: usize| {
        let l = &function(uff, i).numerator.units_label;
        if crate::units::is_unset(l) {
            "(no label)".to_string()
        } else {
            l.trim().to_string()
        }
    };
    let mut out = format!(
        "time histories: {} excitation(s), sampled at {} Hz, {} samples per record ({} s), {}",
        index.excitations.len(),
        index.sample_rate_hz,
        index.record_samples,
        index.record_samples as f64 / index.sample_rate_hz,
        if index
            .excitations
            .iter()
            .all(|e| matches!(e.layout, HitLayout::PerHit(_)))
        {
            "one record per hit and channel"
        } else {
            "continuous throughput records (hits found by trigger)"
        }
    );
    for ex in &index.excitations {
        let t = ex.template();
        let count = match &ex.layout {
            HitLayout::PerHit(h) => format!("{} hits", h.len()),
            HitLayout::Throughput(_) => "1 throughput record".into(),
        };
        let responses: Vec<String> = ex
            .responses
            .iter()
            .zip(&t.responses)
            .map(|(&d, &i)| format!("{} {}", dof(d), unit(i)))
            .collect();
        out.push_str(&format!(
            "\n  force {} {}: {count}; {} response channel(s): {}",
            dof(ex.force_dof),
            unit(t.force),
            responses.len(),
            responses.join(", ")
        ));
    }
    Some(out)
}

/// One excitation's estimated FRFs and coherences, in its response order.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimatedFrfs {
    /// `frf[k][line]` of response k (file units: response over force).
    pub frf: Vec<Vec<c64>>,
    /// `coherence[k][line]` of response k; `None` when not known (a single average).
    pub coherence: Option<Vec<Vec<f64>>>,
}

/// A universal file holding the datasets of `uff` that are not functions (nodes,
/// coordinate systems, units) and, per excitation and response, the estimated FRF as a
/// dataset 58 of function type 4 (and, where known, its coherence as type 6), carrying
/// the response record's DOFs, ID lines and numerator axis, the force record's axis as
/// denominator and a frequency abscissa `first_hz + k·step_hz`. Each new dataset keeps
/// the location of the response record it came from, so errors name the time record.
pub fn frf_file(
    uff: &UffFile,
    index: &TimeHistoryIndex,
    estimates: Vec<EstimatedFrfs>,
    first_hz: f64,
    step_hz: f64,
) -> UffFile {
    let mut datasets: Vec<Dataset> = uff
        .datasets
        .iter()
        .filter(|d| !matches!(d.record, Record::Function(_)))
        .cloned()
        .collect();
    // The estimates are moved into the datasets, not copied (a recording's FRFs are
    // megabytes, issue 36's memory bound).
    for (ex, mut est) in index.excitations.iter().zip(estimates) {
        let template = ex.template();
        let force = function(uff, template.force);
        for (k, &ri) in template.responses.iter().enumerate() {
            let resp = function(uff, ri);
            let location = uff.datasets[ri].location.clone();
            let n = est.frf[k].len();
            let mut f = Function {
                function_type: 4,
                load_case: 0,
                reference_node: ex.force_dof.0,
                reference_direction: ex.force_dof.1,
                reference_entity: force.response_entity.clone(),
                ordinate_type: OrdinateType::ComplexDouble,
                even: true,
                abscissa_min: first_hz,
                abscissa_increment: step_hz,
                abscissa_axis: AxisInfo {
                    data_type: 18,
                    length_exp: 0,
                    force_exp: 0,
                    temperature_exp: 0,
                    label: "Frequency".into(),
                    units_label: "Hz".into(),
                },
                denominator: force.numerator.clone(),
                binary: None,
                abscissa: (0..n).map(|l| first_hz + l as f64 * step_hz).collect(),
                ordinate: std::mem::take(&mut est.frf[k]),
                ..resp.header()
            };
            let coherence = est.coherence.as_ref().map(|coh| {
                let axis = AxisInfo {
                    data_type: 0,
                    length_exp: 0,
                    force_exp: 0,
                    temperature_exp: 0,
                    label: "Coherence".into(),
                    units_label: "NONE".into(),
                };
                Function {
                    function_type: 6,
                    ordinate_type: OrdinateType::RealDouble,
                    numerator: axis.clone(),
                    denominator: axis,
                    abscissa: f.abscissa.clone(),
                    ordinate: coh[k].iter().map(|&g| c64::new(g, 0.0)).collect(),
                    ..f.header()
                }
            });
            f.function_id = resp.function_id;
            datasets.push(Dataset {
                location: location.clone(),
                record: Record::Function(Box::new(f)),
            });
            if let Some(c) = coherence {
                datasets.push(Dataset {
                    location,
                    record: Record::Function(Box::new(c)),
                });
            }
        }
    }
    UffFile {
        file_name: uff.file_name.clone(),
        datasets,
    }
}
