//! From parsed datasets to an rbprops campaign: SI geometry and one FRF set.
//! The mapping rules are documented at the crate root.

mod collect;
mod frames;
mod nodes;
mod scaling;

use crate::dof::{dofs_from_names, ChannelMap, DofSource, NodeDof};
use crate::error::{DatasetLocation, UffError};
use crate::model::*;
use collect::{match_coherence, FrfCollector};
use frames::{CsEntry, Frames};
use nodes::{add_file_nodes, NodeEntry, NodeTable};
use rbprops_core::{FrfSet, Geometry, Point, Vec3};
use scaling::{abscissa_factor, scaling};
use std::collections::HashMap;

/// Set-up id used when a dataset 58 carries no `setup=` tag in ID line 4.
pub const DEFAULT_SETUP: &str = "A";
/// Relative tolerance within which two records' abscissae count as the same axis.
pub const ABSCISSA_TOLERANCE: f64 = 1e-9;
/// Tolerance on the orthonormality of a dataset 2420 rotation (same as core's unit check).
pub const ORTHONORMAL_TOLERANCE: f64 = 1e-6;

/// The letter of a translation direction code 1..3.
pub(crate) fn axis_letter(k: usize) -> char {
    ['x', 'y', 'z'][k]
}

/// Reversible DOF name: node label then `x`, `-x`, `y`, … (`12-y` = node 12, −Y).
pub fn dof_name(node: i64, direction: i64) -> String {
    let k = (direction.unsigned_abs() as usize).clamp(1, 3) - 1;
    let sign = if direction < 0 { "-" } else { "" };
    format!("{node}{sign}{}", axis_letter(k))
}

/// Tags our writer puts in the ID lines (see the crate docs).
#[derive(Default)]
pub(crate) struct Tags {
    pub(crate) setup: Option<String>,
    pub(crate) setup_description: String,
    pub(crate) channel: Option<String>,
    pub(crate) channel_point: Option<String>,
    pub(crate) excitation: Option<String>,
    pub(crate) excitation_point: Option<String>,
}

pub(crate) fn read_tags(f: &Function) -> Tags {
    let mut t = Tags::default();
    let id4 = f.id_lines[3].trim();
    if let Some(rest) = id4.strip_prefix("setup=") {
        let (id, desc) = rest.split_once(char::is_whitespace).unwrap_or((rest, ""));
        if !id.is_empty() {
            t.setup = Some(id.to_string());
            t.setup_description = desc.trim().to_string();
        }
    }
    if let Some(rest) = f.id_lines[4].trim().strip_prefix("rbprops ") {
        for tok in rest.split_whitespace() {
            if let Some((k, v)) = tok.split_once('=') {
                if v.is_empty() {
                    continue;
                }
                let v = Some(v.to_string());
                match k {
                    "ch" => t.channel = v,
                    "cp" => t.channel_point = v,
                    "ex" => t.excitation = v,
                    "ep" => t.excitation_point = v,
                    _ => {}
                }
            }
        }
    }
    t
}

/// Where the node coordinates and coordinate systems come from.
#[derive(Debug, Clone, Copy, Default)]
pub enum GeometrySource<'a> {
    /// The data file's own datasets 15/2411/18/2420 (and its 164).
    #[default]
    InFile,
    /// A separate universal file (datasets 15, 18, 164, 2411, 2420; its other datasets
    /// are ignored), in addition to any nodes of the data file. Each file's coordinate
    /// systems and units apply to its own nodes.
    Uff(&'a UffFile),
    /// Points given by a campaign spec: point id = node label (ids that are not integers
    /// cannot be named by a dataset 58), SI positions, global axes.
    Points(&'a [Point]),
}

/// Options of [`read_campaign`].
#[derive(Debug, Clone, Copy, Default)]
pub struct ReadOptions<'a> {
    /// Where node coordinates come from: the file's own datasets or a campaign spec's points.
    pub geometry: GeometrySource<'a>,
    /// DOFs of datasets whose record 6 leaves them out (node 0 or direction 0).
    pub channels: Option<&'a ChannelMap>,
}

/// Coherence (function type 6) matched to the FRFs: `values[e][c]` is the ordinary
/// coherence γ² on the FRF set's frequency axis for excitation `e` and channel `c`, or
/// `None` when the file holds none for that pair.
#[derive(Debug, Clone, PartialEq)]
pub struct CoherenceSet {
    /// `values[excitation][channel]`: γ² per FRF line, or `None`.
    pub values: Vec<Vec<Option<Vec<f64>>>>,
}

impl CoherenceSet {
    /// Number of (excitation, channel) pairs with a coherence.
    pub fn count(&self) -> usize {
        self.values.iter().flatten().filter(|v| v.is_some()).count()
    }
}

/// A campaign read from a universal file.
#[derive(Debug, Clone)]
pub struct UffCampaign {
    /// SI geometry: one point per node used, one channel per response DOF, one excitation per reference DOF.
    pub geometry: Geometry,
    /// The FRFs in SI receptance, mobility or accelerance, on one frequency axis (Hz).
    pub frf: FrfSet,
    /// `None` when the file holds no coherence that matches an FRF.
    pub coherence: Option<CoherenceSet>,
    /// The dataset each FRF came from, `[excitation][channel]` (the FRF layout).
    pub frf_locations: Vec<DatasetLocation>,
    /// What was read differently from what the file says, or skipped (one line each;
    /// the same message for several datasets is given once with a count).
    pub warnings: Vec<String>,
}

/// Builds the campaign (geometry in SI and one FRF set) from the datasets of a file.
/// See the crate documentation for the mapping rules.
pub fn to_campaign(uff: &UffFile) -> Result<(Geometry, FrfSet), UffError> {
    read_campaign(uff, &ReadOptions::default()).map(|c| (c.geometry, c.frf))
}

/// The data file `data` read with its geometry in the separate universal file
/// `geometry` (datasets 15/18/164/2411/2420): the call `--geometry FILE` makes.
pub fn read_with_geometry(
    data: &UffFile,
    geometry: &UffFile,
    channels: Option<&ChannelMap>,
) -> Result<UffCampaign, UffError> {
    read_campaign(
        data,
        &ReadOptions {
            geometry: GeometrySource::Uff(geometry),
            channels,
        },
    )
}

/// Warnings gathered while reading, each message once with the datasets it concerns.
#[derive(Default)]
struct Warnings {
    list: Vec<(String, DatasetLocation, usize)>,
}

impl Warnings {
    fn add(&mut self, at: &DatasetLocation, msgs: Vec<String>) {
        for m in msgs {
            match self.list.iter_mut().find(|(x, _, _)| *x == m) {
                Some(e) => e.2 += 1,
                None => self.list.push((m, at.clone(), 1)),
            }
        }
    }
    fn finish(self, file: &str) -> Vec<String> {
        self.list
            .into_iter()
            .map(|(m, at, n)| {
                if n > 1 {
                    format!("{file}: {at} and {} more: {m}", n - 1)
                } else {
                    format!("{file}: {at}: {m}")
                }
            })
            .collect()
    }
}

fn direction_text(d: i64) -> String {
    format!("{}{}", if d < 0 { "-" } else { "+" }, {
        let k = (d.unsigned_abs() as usize).clamp(1, 3) - 1;
        axis_letter(k)
    })
}

/// The response and reference DOFs of a dataset 58: a channel map row when one matches
/// (the user's word wins), else record 6, else a naming pattern (see [`crate::dof`]).
fn resolve_dofs(
    index: usize,
    f: &Function,
    map: Option<&ChannelMap>,
) -> [Result<(NodeDof, DofSource), String>; 2] {
    let row = map.and_then(|m| m.row_for(index, &f.id_lines[0]));
    let named = dofs_from_names(f);
    let side = |k: usize| -> Result<(NodeDof, DofSource), String> {
        let (node, direction, role) = if k == 0 {
            (f.response_node, f.response_direction, "response")
        } else {
            (f.reference_node, f.reference_direction, "reference")
        };
        if let Some(d) = row.and_then(|r| if k == 0 { r.response } else { r.reference }) {
            return Ok((d, DofSource::ChannelMap));
        }
        if node != 0 && direction != 0 {
            return Ok((NodeDof { node, direction }, DofSource::Record6));
        }
        if let Some((d, src)) = &named[k] {
            return Ok((*d, src.clone()));
        }
        Err(format!(
            "{role} node {node} direction {direction}, and neither the entity name '{}' nor the ID lines (line 1: '{}') name the DOF in a known pattern (e.g. 'Point3:+Z'): give it in a channel map (--channels; `rbprops convert --channel-template` writes one)",
            if k == 0 { &f.response_entity } else { &f.reference_entity },
            f.id_lines[0]
        ))
    };
    [side(0), side(1)]
}

/// A [`UffError::Campaign`] of `file`.
fn campaign_error(file: &str, problem: String) -> UffError {
    UffError::Campaign {
        file: file.to_string(),
        problem,
    }
}

/// A [`UffError::Field`] of `file`.
fn field_error(file: &str, at: &DatasetLocation, field: &str, problem: String) -> UffError {
    UffError::Field {
        file: file.to_string(),
        at: at.clone(),
        field: field.to_string(),
        problem,
    }
}

/// The location of a summary warning, which concerns no single dataset.
fn no_dataset(number: i64) -> DatasetLocation {
    DatasetLocation {
        index: 0,
        number,
        line: 0,
    }
}

/// Builds the campaign from `data` with the geometry and channel map of `opts`: the node
/// table, every function's DOFs (pass 1), the FRFs (pass 2), the coherence matched to
/// them (pass 3), then the geometry and the FRF set.
pub fn read_campaign(data: &UffFile, opts: &ReadOptions) -> Result<UffCampaign, UffError> {
    let file = data.file_name.as_str();
    let mut warnings = Warnings::default();
    let mut table = NodeTable::default();
    let geometry_name = add_geometry_source(opts.geometry, &mut table)?;
    let units_at = add_file_nodes(data, &mut table)?;
    let (dofs, skipped) = resolve_function_dofs(data, opts.channels, &mut warnings)?;
    check_nodes_exist(file, &dofs, &table, geometry_name.as_deref())?;
    let mut frfs = FrfCollector::new(file);
    for (di, (d, &units)) in data.datasets.iter().zip(&units_at).enumerate() {
        match &d.record {
            Record::Function(f) if f.function_type == 4 => {
                frfs.add(&d.location, f, &dofs[&di].1, units, &mut warnings)?
            }
            _ => {}
        }
    }
    let (Some((frequency_hz, _)), Some((quantity, _))) = (frfs.axis.take(), frfs.quantity.take())
    else {
        return Err(campaign_error(
            file,
            format!(
                "no FRF datasets (dataset 58 with function type 4) in the file. It holds:\n{}",
                crate::inventory::inventory(data)
            ),
        ));
    };
    if !skipped.is_empty() {
        warnings
            .list
            .push((skipped_functions_note(&skipped), no_dataset(58), 1));
    }
    let coherence = match_coherence(data, &dofs, &frfs, &frequency_hz, &mut warnings);
    let geometry = frfs.geometry(&table, geometry_name.is_some(), &mut warnings)?;
    let (frf, frf_locations) = frfs.into_frf_set(quantity, frequency_hz)?;
    geometry
        .validate()
        .map_err(|e| campaign_error(file, format!("geometry: {e}")))?;
    frf.validate()
        .map_err(|e| campaign_error(file, e.to_string()))?;
    let mut warnings = warnings.finish(file);
    for w in &mut warnings {
        // Summary warnings carry no dataset: drop the placeholder location.
        *w = w.replace(" dataset #0 (type 58, starting at line 0):", "");
        *w = w.replace(" dataset #0 (type 0, starting at line 0):", "");
    }
    Ok(UffCampaign {
        geometry,
        frf,
        coherence: (coherence.count() > 0).then_some(coherence),
        frf_locations,
        warnings,
    })
}

/// Adds the nodes of a separate geometry (a universal file or the spec's points) to
/// `table`; returns its name for messages (`None`: the data file's own nodes only).
fn add_geometry_source(
    source: GeometrySource,
    table: &mut NodeTable,
) -> Result<Option<String>, UffError> {
    match source {
        GeometrySource::InFile => Ok(None),
        GeometrySource::Uff(g) => {
            add_file_nodes(g, table)?;
            Ok(Some(g.file_name.clone()))
        }
        GeometrySource::Points(points) => {
            for p in points {
                let Ok(label) = p.id.trim().parse::<i64>() else {
                    continue;
                };
                let entry = NodeEntry {
                    position: p.position,
                    axes: Ok([Vec3::x(), Vec3::y(), Vec3::z()]),
                    file: "the spec".into(),
                };
                table.insert(label, entry, &no_dataset(0))?;
            }
            Ok(Some("the spec's points".to_string()))
        }
    }
}

/// The response and reference DOFs of one function, with where each came from.
type FunctionDofs = [(NodeDof, DofSource); 2];

/// Pass 1: the DOFs of every FRF and coherence, keyed by dataset index with its location,
/// and the number of other functions per function type (listed, not read). A coherence
/// whose DOFs cannot be resolved is skipped with a warning; an FRF's is an error.
#[allow(clippy::type_complexity)]
fn resolve_function_dofs(
    data: &UffFile,
    channels: Option<&ChannelMap>,
    warnings: &mut Warnings,
) -> Result<
    (
        HashMap<usize, (DatasetLocation, FunctionDofs)>,
        std::collections::BTreeMap<i64, usize>,
    ),
    UffError,
> {
    let file = data.file_name.as_str();
    let mut dofs = HashMap::new();
    let mut skipped: std::collections::BTreeMap<i64, usize> = Default::default();
    for (di, d) in data.datasets.iter().enumerate() {
        let Record::Function(f) = &d.record else {
            continue;
        };
        if f.function_type != 4 && f.function_type != 6 {
            *skipped.entry(f.function_type).or_default() += 1;
            continue;
        }
        let (r, e) = match resolve_dofs(d.location.index, f, channels) {
            [Ok(r), Ok(e)] => (r, e),
            [Err(why), _] | [_, Err(why)] => {
                if f.function_type == 6 {
                    warnings.add(&d.location, vec![format!("coherence skipped: {why}")]);
                    continue;
                }
                let field = if why.starts_with("response") {
                    "record 6 field 6-7 (response node, direction)"
                } else {
                    "record 6 field 9-10 (reference node, direction)"
                };
                return Err(field_error(file, &d.location, field, why));
            }
        };
        for (dof, role) in [(&r.0, "response"), (&e.0, "reference")] {
            if dof.direction.abs() > 3 || dof.direction == 0 {
                return Err(field_error(
                    file,
                    &d.location,
                    &format!("record 6 ({role} direction)"),
                    format!("{role} direction {} is not a translation (±1, ±2, ±3); scalar and rotational DOFs are not supported", dof.direction),
                ));
            }
        }
        dofs.insert(di, (d.location.clone(), [r, e]));
    }
    Ok((dofs, skipped))
}

/// Every node the functions name must have coordinates: one error lists all that do not
/// (the first dataset that names one is its location) and the nodes that are defined.
fn check_nodes_exist(
    file: &str,
    dofs: &HashMap<usize, (DatasetLocation, FunctionDofs)>,
    table: &NodeTable,
    geometry_name: Option<&str>,
) -> Result<(), UffError> {
    let mut missing: Vec<(usize, i64)> = dofs
        .iter()
        .flat_map(|(&di, (_, [r, e]))| [(di, r.0.node), (di, e.0.node)])
        .filter(|(_, node)| !table.nodes.contains_key(node))
        .collect();
    if missing.is_empty() {
        return Ok(());
    }
    missing.sort_unstable();
    let first_at = &dofs[&missing[0].0].0;
    let mut labels: Vec<i64> = missing.iter().map(|m| m.1).collect();
    labels.sort_unstable();
    labels.dedup();
    let mut defined: Vec<i64> = table.order.clone();
    defined.sort_unstable();
    let list = |v: &[i64]| {
        let shown: Vec<String> = v.iter().take(20).map(|l| l.to_string()).collect();
        shown.join(", ")
    };
    let more = if labels.len() > 20 {
        format!(" and {} more", labels.len() - 20)
    } else {
        String::new()
    };
    let source = geometry_name.map_or("the file (datasets 15/2411)".to_string(), |g| {
        format!("{g} with the file")
    });
    let defined_list = if defined.is_empty() {
        " (give the geometry with --geometry FILE)".to_string()
    } else {
        format!(": {}", list(&defined))
    };
    Err(field_error(
        file,
        first_at,
        "record 6 (response/reference node)",
        format!(
            "{} node(s) named by the functions have no coordinates: {}{more}; {source} defines {} node(s){defined_list}",
            labels.len(),
            list(&labels),
            defined.len(),
        ),
    ))
}

/// The warning that lists the functions that are neither FRFs nor coherence.
fn skipped_functions_note(skipped: &std::collections::BTreeMap<i64, usize>) -> String {
    let list: Vec<String> = skipped
        .iter()
        .map(|(t, n)| {
            format!(
                "{n} {} (type {t})",
                crate::inventory::function_type_name(*t)
            )
        })
        .collect();
    format!(
        "datasets 58 that are neither FRFs nor coherence are not read: {}",
        list.join(", ")
    )
}

/// The notes on DOFs that were not taken from record 6 (one rule per message: the node
/// values would make one message per DOF).
fn dof_source_notes(dofs: &FunctionDofs) -> Vec<String> {
    dofs.iter()
        .zip(["response", "reference"])
        .filter_map(|((_, src), role)| match src {
            DofSource::EntityName => Some(format!("{role} DOF taken from the entity name")),
            DofSource::IdLine(k) => Some(format!("{role} DOF taken from ID line {k}")),
            DofSource::Record6 | DofSource::ChannelMap => None,
        })
        .collect()
}
