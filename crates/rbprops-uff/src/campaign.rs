//! From parsed datasets to an rbprops campaign: SI geometry and one FRF set.
//! The mapping rules are documented at the crate root.

use crate::dof::{dofs_from_names, ChannelMap, DofSource, NodeDof};
use crate::error::{DatasetLocation, UffError};
use crate::model::*;
use crate::units::{is_unset, parse_label, system_units, Unit};
use rbprops_core::{
    c64, Channel, Excitation, FrfSet, Geometry, Point, Quantity, SuspensionSetup, Vec3,
};
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

/// A resolved Cartesian frame: `rows` are the local axes in global coordinates (SI).
#[derive(Debug, Clone, Copy)]
struct Frame {
    rows: [Vec3; 3],
    origin: Vec3,
}

impl Frame {
    fn global() -> Self {
        Frame {
            rows: [Vec3::x(), Vec3::y(), Vec3::z()],
            origin: Vec3::zeros(),
        }
    }
    /// Global position of a point given in this frame (SI).
    fn to_global(self, p: Vec3) -> Vec3 {
        self.origin + self.rows[0] * p.x + self.rows[1] * p.y + self.rows[2] * p.z
    }
}

struct CsEntry<'a> {
    cs: &'a CoordinateSystem,
    length_si: f64,
    at: &'a DatasetLocation,
}

struct Frames<'a> {
    file: &'a str,
    defs: HashMap<i64, CsEntry<'a>>,
    resolved: HashMap<i64, Frame>,
}

impl<'a> Frames<'a> {
    fn err(&self, at: &DatasetLocation, field: String, problem: String) -> UffError {
        UffError::Field {
            file: self.file.to_string(),
            at: at.clone(),
            field,
            problem,
        }
    }

    /// The Cartesian frame of system `label` (0 = global). `user` names who asks.
    fn frame(
        &mut self,
        label: i64,
        user: &DatasetLocation,
        field: &str,
        depth: usize,
    ) -> Result<Frame, UffError> {
        if label == 0 {
            return Ok(Frame::global());
        }
        if let Some(f) = self.resolved.get(&label) {
            return Ok(*f);
        }
        let Some(e) = self.defs.get(&label) else {
            return Err(self.err(
                user,
                field.to_string(),
                format!("coordinate system {label} is not defined by any dataset 2420 or 18"),
            ));
        };
        let (cs, l, at) = (e.cs, e.length_si, e.at.clone());
        let what = format!("coordinate system {label}");
        if cs.kind != CsKind::Cartesian {
            return Err(self.err(
                user,
                field.to_string(),
                format!(
                    "{what} is {:?}; only Cartesian systems are supported",
                    cs.kind
                ),
            ));
        }
        if depth > 64 {
            return Err(self.err(&at, what, "reference systems form a cycle".into()));
        }
        let frame = match &cs.definition {
            CsDefinition::Matrix { rows, origin } => {
                let r = rows.map(Vec3::from);
                for i in 0..3 {
                    for j in 0..3 {
                        let d = r[i].dot(&r[j]) - if i == j { 1.0 } else { 0.0 };
                        if d.abs() > ORTHONORMAL_TOLERANCE || !d.is_finite() {
                            return Err(self.err(
                                &at,
                                format!("{what} records 5-7 (transformation matrix)"),
                                format!(
                                    "rows {} and {} are not orthonormal (error {d:.3e})",
                                    i + 1,
                                    j + 1
                                ),
                            ));
                        }
                    }
                }
                Frame {
                    rows: r,
                    origin: Vec3::from(*origin) * l,
                }
            }
            CsDefinition::ThreePoints {
                reference_cs,
                method,
                origin,
                x_point,
                xz_point,
            } => {
                if *method != 1 && *method != 0 {
                    return Err(self.err(
                        &at,
                        format!("{what} record 1 field 5 (method of definition)"),
                        format!("unknown method {method} (1 = origin, +x axis, +xz plane)"),
                    ));
                }
                let reference = self.frame(
                    *reference_cs,
                    &at,
                    &format!("{what} record 1 field 3 (reference system)"),
                    depth + 1,
                )?;
                let o = reference.to_global(Vec3::from(*origin) * l);
                let px = reference.to_global(Vec3::from(*x_point) * l);
                let pxz = reference.to_global(Vec3::from(*xz_point) * l);
                let x = px - o;
                let v = pxz - o;
                let z = v - x * (x.dot(&v) / x.norm_squared());
                let (nx, nz) = (x.norm(), z.norm());
                if !(nx > 0.0 && nz > 1e-9 * v.norm().max(nx) && nx.is_finite()) {
                    return Err(self.err(
                        &at,
                        format!("{what} record 3 (definition points)"),
                        "origin, +x point and +xz point are coincident or collinear".into(),
                    ));
                }
                let (x, z) = (x / nx, z / nz);
                Frame {
                    rows: [x, z.cross(&x), z],
                    origin: o,
                }
            }
        };
        self.resolved.insert(label, frame);
        Ok(frame)
    }
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

/// Conversion of one FRF record to SI and its quantity.
struct Scaling {
    quantity: Quantity,
    value: f64,
    abscissa: f64,
}

fn data_type_name(t: i64) -> &'static str {
    match t {
        0 => "unknown",
        1 => "general",
        8 => "displacement",
        9 => "reaction force",
        11 => "velocity",
        12 => "acceleration",
        13 => "excitation force",
        17 => "time",
        18 => "frequency",
        _ => "other",
    }
}

/// What a units label says, or why it says nothing usable.
fn read_label(axis: &AxisInfo) -> Option<Result<Unit, String>> {
    if is_unset(&axis.units_label) {
        return None;
    }
    Some(parse_label(&axis.units_label).map_err(|e| e.0))
}

/// Scale factors of one dataset 58 to SI, by the precedence documented in
/// `docs/formats.md`: the units label of an axis when it parses and agrees in dimension
/// with the specific data type of records 8–10; otherwise the data type with the file's
/// dataset 164 units (a label that cannot be read, or that contradicts the data type, is a
/// warning naming both); an error only when neither determines the unit.
fn scaling(
    file: &str,
    at: &DatasetLocation,
    f: &Function,
    length_si: f64,
    force_si: f64,
    warn: &mut Vec<String>,
) -> Result<Scaling, UffError> {
    let err = |field: &str, problem: String| UffError::Field {
        file: file.to_string(),
        at: at.clone(),
        field: field.to_string(),
        problem,
    };
    let force = Unit::base(1.0, 0, 1, 0);
    let motion = |q: Quantity| Unit::base(1.0, 1, 0, -q.order());
    let quantities = [
        Quantity::Receptance,
        Quantity::Mobility,
        Quantity::Accelerance,
    ];
    // Numerator (record 9).
    let num_field = "record 9 (ordinate numerator)";
    let t = f.numerator.data_type;
    let by_type = match t {
        8 => Some(Quantity::Receptance),
        11 => Some(Quantity::Mobility),
        12 => Some(Quantity::Accelerance),
        _ => None,
    };
    // The label's reading: (quantity, factor, label is the whole FRF).
    let by_label = read_label(&f.numerator).map(|r| {
        r.and_then(|u| {
            quantities
                .iter()
                .find_map(|&q| {
                    if u.same_dimension(&motion(q)) {
                        Some((q, u.factor, false))
                    } else if u.same_dimension(&motion(q).times(force.powi(-1))) {
                        Some((q, u.factor, true))
                    } else {
                        None
                    }
                })
                .ok_or_else(|| {
                    format!(
                        "{} is not a displacement, velocity or acceleration, nor one per force",
                        u.dimension()
                    )
                })
        })
    });
    let label = &f.numerator.units_label;
    let (quantity, num_factor, whole) = match (by_type, by_label) {
        (Some(q), None) => (q, length_si, false),
        (Some(q), Some(Ok((lq, factor, whole)))) if lq == q => (q, factor, whole),
        (Some(q), Some(Ok((lq, _, _)))) => {
            warn.push(format!(
                "{num_field}: units label '{label}' ({}) contradicts data type {t} ({}): the data type is used, with the file's units",
                lq.name(),
                data_type_name(t)
            ));
            (q, length_si, false)
        }
        (Some(q), Some(Err(why))) => {
            warn.push(format!(
                "{num_field}: units label '{label}' is not used ({why}): data type {t} ({}) with the file's units instead",
                data_type_name(t)
            ));
            (q, length_si, false)
        }
        (None, Some(Ok((lq, factor, whole)))) if matches!(t, 0 | 1) => (lq, factor, whole),
        (None, Some(Ok((lq, _, _)))) => {
            return Err(err(
                &format!("{num_field} field 1 (specific data type)"),
                format!(
                    "data type {t} ({}) is not displacement (8), velocity (11) or acceleration (12), though the units label '{label}' reads as {}",
                    data_type_name(t),
                    lq.name()
                ),
            ))
        }
        (None, Some(Err(why))) => {
            return Err(err(
                &format!("{num_field} field 6 (units label)"),
                format!(
                    "units label '{label}' is not understood ({why}) and data type {t} ({}) does not say displacement (8), velocity (11) or acceleration (12): nothing determines the unit",
                    data_type_name(t)
                ),
            ))
        }
        (None, None) => {
            return Err(err(
                &format!("{num_field} field 1 (specific data type)"),
                format!(
                    "data type {t} ({}) without a units label: nothing says displacement, velocity or acceleration",
                    data_type_name(t)
                ),
            ))
        }
    };
    // Denominator (record 10), unless the numerator label already holds the whole FRF.
    let den_factor = if whole {
        1.0
    } else {
        let den_field = "record 10 (ordinate denominator)";
        let t = f.denominator.data_type;
        let label = &f.denominator.units_label;
        let typed_force = matches!(t, 9 | 13);
        match read_label(&f.denominator) {
            Some(Ok(u)) if u.same_dimension(&force) && (typed_force || matches!(t, 0 | 1)) => {
                u.factor
            }
            Some(Ok(u)) if typed_force => {
                warn.push(format!(
                    "{den_field}: units label '{label}' ({}) contradicts data type {t} ({}): the data type is used, with the file's units",
                    u.dimension(),
                    data_type_name(t)
                ));
                force_si
            }
            Some(Err(why)) if typed_force => {
                warn.push(format!(
                    "{den_field}: units label '{label}' is not used ({why}): data type {t} ({}) with the file's units instead",
                    data_type_name(t)
                ));
                force_si
            }
            None if typed_force => force_si,
            // Type 0/1 and no usable label: the function type (4, FRF) says force.
            None if matches!(t, 0 | 1) => {
                warn.push(format!(
                    "{den_field}: data type {t} ({}) without a units label: taken as a force in the file's units (function type 4 is an FRF)",
                    data_type_name(t)
                ));
                force_si
            }
            other => {
                let why = match other {
                    Some(Ok(u)) => format!("units label '{label}' is {}", u.dimension()),
                    Some(Err(why)) => format!("units label '{label}' is not understood ({why})"),
                    None => "no units label".to_string(),
                };
                return Err(err(
                    &format!("{den_field} field 1 (specific data type)"),
                    format!(
                        "data type {t} ({}) is not an excitation force (13) or reaction force (9), and {why}",
                        data_type_name(t)
                    ),
                ));
            }
        }
    };
    let abscissa = abscissa_factor(file, at, f, warn)?;
    Ok(Scaling {
        quantity,
        value: num_factor / den_factor,
        abscissa,
    })
}

/// Hz per abscissa unit of a dataset 58 (record 8), by the same precedence.
fn abscissa_factor(
    file: &str,
    at: &DatasetLocation,
    f: &Function,
    warn: &mut Vec<String>,
) -> Result<f64, UffError> {
    let ab_field = "record 8 (abscissa)";
    let t = f.abscissa_axis.data_type;
    let label = &f.abscissa_axis.units_label;
    let is_frequency = |u: &Unit| u.length == 0 && u.force == 0 && u.time == -1;
    match (t, read_label(&f.abscissa_axis)) {
        (18 | 0 | 1, Some(Ok(u))) if is_frequency(&u) => Ok(u.factor),
        (18 | 0, None) => Ok(1.0),
        (18 | 0, Some(Ok(u))) => {
            warn.push(format!(
                "{ab_field}: units label '{label}' ({}) contradicts data type {t} ({}): taken in Hz",
                u.dimension(),
                data_type_name(t)
            ));
            Ok(1.0)
        }
        (18 | 0, Some(Err(why))) => {
            warn.push(format!(
                "{ab_field}: units label '{label}' is not used ({why}): taken in Hz"
            ));
            Ok(1.0)
        }
        (t, _) => Err(UffError::Field {
            file: file.to_string(),
            at: at.clone(),
            field: format!("{ab_field} field 1 (specific data type)"),
            problem: format!(
                "abscissa data type {t} ({}, units label '{label}') is not a frequency (18) in Hz",
                data_type_name(t)
            ),
        }),
    }
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

/// A node in global SI coordinates with the axes its direction codes refer to.
struct NodeEntry {
    position: Vec3,
    /// Axes of the node's displacement system (an error only matters when a DOF uses it).
    axes: Result<[Vec3; 3], UffError>,
    file: String,
}

#[derive(Default)]
struct NodeTable {
    order: Vec<i64>,
    nodes: HashMap<i64, NodeEntry>,
}

impl NodeTable {
    fn insert(&mut self, label: i64, e: NodeEntry, at: &DatasetLocation) -> Result<(), UffError> {
        if let Some(prev) = self.nodes.get(&label) {
            let scale = prev.position.norm().max(e.position.norm()).max(1e-3);
            // Same file: must be identical; another file: equal to single-precision print.
            let tol = if prev.file == e.file {
                0.0
            } else {
                1e-5 * scale
            };
            if (prev.position - e.position).norm() > tol {
                return Err(UffError::Field {
                    file: e.file.clone(),
                    at: at.clone(),
                    field: format!("node {label}"),
                    problem: format!(
                        "node {label} is at ({:.6}, {:.6}, {:.6}) m here but ({:.6}, {:.6}, {:.6}) m in {}",
                        e.position.x,
                        e.position.y,
                        e.position.z,
                        prev.position.x,
                        prev.position.y,
                        prev.position.z,
                        prev.file
                    ),
                });
            }
            return Ok(());
        }
        self.order.push(label);
        self.nodes.insert(label, e);
        Ok(())
    }
}

/// Units in force at each dataset of `uff` (SI per file unit of length and force), and
/// its nodes added to `table`.
fn add_file_nodes(uff: &UffFile, table: &mut NodeTable) -> Result<Vec<(f64, f64)>, UffError> {
    let file = uff.file_name.as_str();
    let field_err = |at: &DatasetLocation, field: &str, problem: String| UffError::Field {
        file: file.to_string(),
        at: at.clone(),
        field: field.to_string(),
        problem,
    };
    let mut units = (1.0, 1.0);
    let mut units_at: Vec<(f64, f64)> = Vec::with_capacity(uff.datasets.len());
    let mut frames = Frames {
        file,
        defs: HashMap::new(),
        resolved: HashMap::new(),
    };
    for d in &uff.datasets {
        match &d.record {
            Record::Units(u) => {
                units = system_units(u.code, u.length_factor, u.force_factor).map_err(|e| {
                    field_err(&d.location, "record 1-2 (units code and factors)", e)
                })?;
            }
            Record::CoordinateSystems(set) => {
                for cs in &set.systems {
                    if cs.label == 0 {
                        return Err(field_err(
                            &d.location,
                            "coordinate system label",
                            "label 0 is the global system and cannot be redefined".into(),
                        ));
                    }
                    if let Some(prev) = frames.defs.get(&cs.label) {
                        if prev.cs != cs {
                            return Err(field_err(
                                &d.location,
                                "coordinate system label",
                                format!(
                                    "system {} is also defined, differently, in {}",
                                    cs.label, prev.at
                                ),
                            ));
                        }
                    }
                    frames.defs.insert(
                        cs.label,
                        CsEntry {
                            cs,
                            length_si: units.0,
                            at: &d.location,
                        },
                    );
                }
            }
            _ => {}
        }
        units_at.push(units);
    }
    for (d, &(length_si, _)) in uff.datasets.iter().zip(&units_at) {
        let Record::Nodes(set) = &d.record else {
            continue;
        };
        for n in &set.nodes {
            let local = Vec3::from(n.coordinates) * length_si;
            let position = match set.format {
                NodeFormat::D15 => frames
                    .frame(
                        n.definition_cs,
                        &d.location,
                        &format!("node {} field 2 (definition coordinate system)", n.label),
                        0,
                    )?
                    .to_global(local),
                NodeFormat::D2411 => local,
            };
            let field = format!("node {} field 3 (displacement coordinate system)", n.label);
            let axes = frames
                .frame(n.displacement_cs, &d.location, &field, 0)
                .map(|f| f.rows);
            table.insert(
                n.label,
                NodeEntry {
                    position,
                    axes,
                    file: file.to_string(),
                },
                &d.location,
            )?;
        }
    }
    Ok(units_at)
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

/// A response or reference DOF of the campaign, as pass 2 meets it.
struct Dof {
    id: String,
    node: i64,
    direction: i64,
    point: String,
    setup: String,
    at: DatasetLocation,
}

/// Which side of an FRF a DOF is on.
#[derive(Clone, Copy, PartialEq)]
enum Side {
    Response,
    Reference,
}

/// Pass 2's state: the channels and excitations in order of appearance, the FRF of each
/// (excitation, channel) cell, and the one axis and quantity they must all share.
struct FrfCollector<'a> {
    file: &'a str,
    channels: Vec<Dof>,
    excitations: Vec<Dof>,
    setups: Vec<SuspensionSetup>,
    point_of_node: HashMap<i64, String>,
    cells: HashMap<(usize, usize), (Vec<c64>, DatasetLocation)>,
    axis: Option<(Vec<f64>, DatasetLocation)>,
    quantity: Option<(Quantity, DatasetLocation)>,
}

impl<'a> FrfCollector<'a> {
    fn new(file: &'a str) -> Self {
        FrfCollector {
            file,
            channels: Vec::new(),
            excitations: Vec::new(),
            setups: Vec::new(),
            point_of_node: HashMap::new(),
            cells: HashMap::new(),
            axis: None,
            quantity: None,
        }
    }

    /// Adds the FRF of dataset `at` (its DOFs resolved, `units` in SI per file unit of
    /// length and force).
    fn add(
        &mut self,
        at: &DatasetLocation,
        f: &Function,
        dofs: &FunctionDofs,
        (length_si, force_si): (f64, f64),
        warnings: &mut Warnings,
    ) -> Result<(), UffError> {
        let mut w = Vec::new();
        let s = scaling(self.file, at, f, length_si, force_si, &mut w)?;
        w.extend(dof_source_notes(dofs));
        warnings.add(at, w);
        let hz: Vec<f64> = f.abscissa.iter().map(|x| x * s.abscissa).collect();
        self.check_shared(at, s.quantity, hz)?;
        let tags = read_tags(f);
        let setup = tags
            .setup
            .clone()
            .unwrap_or_else(|| DEFAULT_SETUP.to_string());
        if !self.setups.iter().any(|s| s.id == setup) {
            self.setups.push(SuspensionSetup {
                id: setup.clone(),
                description: tags.setup_description.clone(),
            });
        }
        let [(resp, _), (refr, _)] = dofs;
        let ci = self.locate(
            Side::Response,
            *resp,
            tags.channel,
            tags.channel_point,
            DEFAULT_SETUP,
            at,
        )?;
        let ei = self.locate(
            Side::Reference,
            *refr,
            tags.excitation,
            tags.excitation_point,
            &setup,
            at,
        )?;
        if let Some((_, prev)) = self.cells.get(&(ei, ci)) {
            return Err(campaign_error(
                self.file,
                format!(
                    "{prev} and {at} both hold the FRF of channel '{}' for excitation '{}'",
                    self.channels[ci].id, self.excitations[ei].id
                ),
            ));
        }
        let values: Vec<c64> = f.ordinate.iter().map(|v| v * s.value).collect();
        self.cells.insert((ei, ci), (values, at.clone()));
        Ok(())
    }

    /// One FRF set has one quantity and one frequency axis: the first FRF sets them.
    fn check_shared(
        &mut self,
        at: &DatasetLocation,
        quantity: Quantity,
        hz: Vec<f64>,
    ) -> Result<(), UffError> {
        match &self.quantity {
            None => self.quantity = Some((quantity, at.clone())),
            Some((q, first)) if *q != quantity => {
                return Err(campaign_error(
                    self.file,
                    format!(
                        "{first} holds {} but {at} holds {}: one FRF set has one quantity",
                        q.name(),
                        quantity.name()
                    ),
                ))
            }
            _ => {}
        }
        match &self.axis {
            None => self.axis = Some((hz, at.clone())),
            Some((first, first_at)) if !same_axis(first, &hz) => {
                return Err(campaign_error(
                    self.file,
                    format!(
                        "{first_at} and {at} have different abscissae ({} lines from {} to {} Hz vs {} lines from {} to {} Hz): all FRFs must share one frequency axis",
                        first.len(), first[0], first[first.len() - 1], hz.len(), hz[0], hz[hz.len() - 1]
                    ),
                ));
            }
            _ => {}
        }
        Ok(())
    }

    /// The index of the channel or excitation at `dof` (added on first sight), checking
    /// that an id and a node keep one meaning across the file.
    fn locate(
        &mut self,
        side: Side,
        dof: NodeDof,
        id: Option<String>,
        point: Option<String>,
        setup: &str,
        at: &DatasetLocation,
    ) -> Result<usize, UffError> {
        let (node, direction) = (dof.node, dof.direction);
        let role = match side {
            Side::Response => "response",
            Side::Reference => "reference",
        };
        let default_id = if side == Side::Reference && setup != DEFAULT_SETUP {
            format!("{}@{setup}", dof_name(node, direction))
        } else {
            dof_name(node, direction)
        };
        let id = id.unwrap_or(default_id);
        let point = point.unwrap_or_else(|| node.to_string());
        let mapped = self
            .point_of_node
            .entry(node)
            .or_insert_with(|| point.clone());
        if *mapped != point {
            return Err(field_error(
                self.file,
                at,
                "ID line 5 (rbprops tags)",
                format!("node {node} is named point '{point}' here but '{mapped}' elsewhere"),
            ));
        }
        let list = match side {
            Side::Response => &mut self.channels,
            Side::Reference => &mut self.excitations,
        };
        if let Some(k) = list.iter().position(|c| c.id == id) {
            let c = &list[k];
            if c.node != node || c.direction != direction || c.setup != setup {
                return Err(field_error(
                    self.file,
                    at,
                    "ID line 5 (rbprops tags)",
                    format!(
                        "{role} '{id}' is node {node} direction {direction} set-up {setup} here but node {} direction {} set-up {} in {}",
                        c.node, c.direction, c.setup, c.at
                    ),
                ));
            }
            return Ok(k);
        }
        list.push(Dof {
            id,
            node,
            direction,
            point,
            setup: setup.to_string(),
            at: at.clone(),
        });
        Ok(list.len() - 1)
    }

    /// The geometry: every node of the table as a point (named as the FRFs name it), the
    /// channels and excitations in order of appearance. With a separate geometry, the
    /// nodes that carry no DOF are listed in a warning (they stay points).
    fn geometry(
        &self,
        table: &NodeTable,
        separate_geometry: bool,
        warnings: &mut Warnings,
    ) -> Result<Geometry, UffError> {
        let mut points: Vec<Point> = Vec::new();
        for label in &table.order {
            let id = self
                .point_of_node
                .get(label)
                .cloned()
                .unwrap_or_else(|| label.to_string());
            if !points.iter().any(|p| p.id == id) {
                points.push(Point {
                    id,
                    position: table.nodes[label].position,
                });
            }
        }
        if separate_geometry {
            self.note_unused_nodes(table, warnings);
        }
        let direction_of = |dof: &Dof| -> Result<Vec3, UffError> {
            let axes = table.nodes[&dof.node].axes.clone()?;
            let k = dof.direction.unsigned_abs() as usize - 1;
            Ok(axes[k] * dof.direction.signum() as f64)
        };
        let mut geometry = Geometry {
            points,
            setups: self.setups.clone(),
            ..Default::default()
        };
        for c in &self.channels {
            geometry.channels.push(Channel {
                id: c.id.clone(),
                point: c.point.clone(),
                position: table.nodes[&c.node].position,
                direction: direction_of(c)?,
            });
        }
        for e in &self.excitations {
            geometry.excitations.push(Excitation {
                id: e.id.clone(),
                point: e.point.clone(),
                position: table.nodes[&e.node].position,
                direction: direction_of(e)?,
                setup: e.setup.clone(),
            });
        }
        Ok(geometry)
    }

    fn note_unused_nodes(&self, table: &NodeTable, warnings: &mut Warnings) {
        let used: std::collections::HashSet<i64> = self
            .channels
            .iter()
            .chain(&self.excitations)
            .map(|c| c.node)
            .collect();
        let mut unused: Vec<i64> = table
            .order
            .iter()
            .copied()
            .filter(|l| !used.contains(l))
            .collect();
        unused.sort_unstable();
        if unused.is_empty() {
            return;
        }
        let shown: Vec<String> = unused.iter().take(20).map(|l| l.to_string()).collect();
        warnings.list.push((
            format!(
                "{} geometry node(s) carry no FRF channel or excitation (kept as points): {}",
                unused.len(),
                shown.join(", ")
            ),
            no_dataset(0),
            1,
        ));
    }

    /// The FRF set: every excitation must have every channel.
    fn into_frf_set(
        mut self,
        quantity: Quantity,
        frequency_hz: Vec<f64>,
    ) -> Result<(FrfSet, Vec<DatasetLocation>), UffError> {
        let (ne, nc) = (self.excitations.len(), self.channels.len());
        // Every cell is checked before the set is allocated: a few datasets naming many
        // excitations and channels must not allocate excitations × channels × lines.
        for (ei, e) in self.excitations.iter().enumerate() {
            for (ci, c) in self.channels.iter().enumerate() {
                if !self.cells.contains_key(&(ei, ci)) {
                    return Err(campaign_error(self.file, format!(
                        "no FRF for channel '{}' (node {} direction {}) and excitation '{}' (node {} direction {}, set-up {}): every excitation needs every channel",
                        c.id, c.node, c.direction, e.id, e.node, e.direction, e.setup
                    )));
                }
            }
        }
        let mut frf = FrfSet::zeros(quantity, frequency_hz, ne, nc);
        let mut locations = Vec::with_capacity(ne * nc);
        for ei in 0..ne {
            for ci in 0..nc {
                if let Some((values, at)) = self.cells.remove(&(ei, ci)) {
                    frf.frf_mut(ei, ci).copy_from_slice(&values);
                    locations.push(at);
                }
            }
        }
        Ok((frf, locations))
    }
}

/// Pass 3: each coherence (function type 6) matched to the FRF of the same response and
/// reference DOF and set-up; one that matches none, lies on another axis, leaves [0, 1]
/// or repeats a pair is skipped with a warning.
fn match_coherence(
    data: &UffFile,
    dofs: &HashMap<usize, (DatasetLocation, FunctionDofs)>,
    frfs: &FrfCollector,
    frequency_hz: &[f64],
    warnings: &mut Warnings,
) -> CoherenceSet {
    let mut values: Vec<Vec<Option<Vec<f64>>>> =
        vec![vec![None; frfs.channels.len()]; frfs.excitations.len()];
    for (di, d) in data.datasets.iter().enumerate() {
        let Record::Function(f) = &d.record else {
            continue;
        };
        if f.function_type != 6 {
            continue;
        }
        let Some((_, [(resp, _), (refr, _)])) = dofs.get(&di) else {
            continue;
        };
        let at = &d.location;
        let setup = read_tags(f)
            .setup
            .unwrap_or_else(|| DEFAULT_SETUP.to_string());
        let ci = frfs
            .channels
            .iter()
            .position(|c| c.node == resp.node && c.direction == resp.direction);
        let ei = frfs
            .excitations
            .iter()
            .position(|e| e.node == refr.node && e.direction == refr.direction && e.setup == setup);
        let (Some(ci), Some(ei)) = (ci, ei) else {
            warnings.add(
                at,
                vec![format!(
                    "coherence of response node {} {} / reference node {} {} has no FRF to go with: skipped",
                    resp.node,
                    direction_text(resp.direction),
                    refr.node,
                    direction_text(refr.direction)
                )],
            );
            continue;
        };
        let mut w = Vec::new();
        let hz_factor = abscissa_factor(data.file_name.as_str(), at, f, &mut w).unwrap_or(1.0);
        warnings.add(at, w);
        let hz: Vec<f64> = f.abscissa.iter().map(|x| x * hz_factor).collect();
        let duplicate = values[ei][ci].is_some().then(|| {
            (
                frfs.channels[ci].id.as_str(),
                frfs.excitations[ei].id.as_str(),
            )
        });
        if let Some(p) = coherence_problem(frequency_hz, &hz, f, duplicate) {
            warnings.add(at, vec![p]);
            continue;
        }
        values[ei][ci] = Some(f.ordinate.iter().map(|v| v.re.clamp(0.0, 1.0)).collect());
    }
    CoherenceSet { values }
}

/// Why a coherence dataset cannot be used for its FRF, or `None`. `duplicate`: the
/// (channel, excitation) ids when that pair already has a coherence.
fn coherence_problem(
    frequency_hz: &[f64],
    hz: &[f64],
    f: &Function,
    duplicate: Option<(&str, &str)>,
) -> Option<String> {
    // γ² lies in [0, 1]; values just outside by rounding of the export are clamped,
    // values clearly outside mean the dataset is not an ordinary coherence.
    const SLACK: f64 = 1e-6;
    if !same_axis(frequency_hz, hz) {
        Some("coherence on another frequency axis than the FRFs: skipped".into())
    } else if f
        .ordinate
        .iter()
        .any(|v| !(-SLACK..=1.0 + SLACK).contains(&v.re))
    {
        Some("coherence values outside [0, 1]: skipped".into())
    } else if let Some((channel, excitation)) = duplicate {
        Some(format!(
            "a second coherence for channel '{channel}' and excitation '{excitation}': skipped"
        ))
    } else {
        None
    }
}

/// Whether two frequency axes are the same to [`ABSCISSA_TOLERANCE`] of their largest value.
fn same_axis(first: &[f64], other: &[f64]) -> bool {
    let scale = first
        .iter()
        .fold(0.0f64, |m, x| m.max(x.abs()))
        .max(f64::MIN_POSITIVE);
    first.len() == other.len()
        && first
            .iter()
            .zip(other)
            .all(|(a, b)| (a - b).abs() <= ABSCISSA_TOLERANCE * scale)
}
