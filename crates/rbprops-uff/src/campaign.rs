//! From parsed datasets to an rbprops campaign: SI geometry and one FRF set.
//! The mapping rules are documented at the crate root.

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

struct NodeInfo<'a> {
    position: Vec3,
    displacement_cs: i64,
    at: &'a DatasetLocation,
}

/// Tags our writer puts in the ID lines (see the crate docs).
#[derive(Default)]
struct Tags {
    setup: Option<String>,
    setup_description: String,
    channel: Option<String>,
    channel_point: Option<String>,
    excitation: Option<String>,
    excitation_point: Option<String>,
}

fn read_tags(f: &Function) -> Tags {
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

fn scaling(
    file: &str,
    at: &DatasetLocation,
    f: &Function,
    length_si: f64,
    force_si: f64,
) -> Result<Scaling, UffError> {
    let err = |field: &str, problem: String| UffError::Field {
        file: file.to_string(),
        at: at.clone(),
        field: field.to_string(),
        problem,
    };
    let label_unit = |axis: &AxisInfo, field: &str| -> Result<Option<Unit>, UffError> {
        if is_unset(&axis.units_label) {
            return Ok(None);
        }
        parse_label(&axis.units_label).map(Some).ok_or_else(|| {
            err(
                field,
                format!(
                    "units label '{}' is not understood (known: m mm cm um in ft, N mN kN lbf kgf, s ms Hz rad, g; combined with / * ^)",
                    axis.units_label
                ),
            )
        })
    };
    let force = Unit {
        factor: 1.0,
        length: 0,
        force: 1,
        time: 0,
    };
    let motion = |order: i32| Unit {
        factor: 1.0,
        length: 1,
        force: 0,
        time: -order,
    };
    // Numerator: quantity from the specific data type, else from the label's dimension.
    let num_field = "record 9 (ordinate numerator)";
    let num_label = label_unit(&f.numerator, &format!("{num_field} field 6 (units label)"))?;
    let by_type = match f.numerator.data_type {
        8 => Some(Quantity::Receptance),
        11 => Some(Quantity::Mobility),
        12 => Some(Quantity::Accelerance),
        0 | 1 => None,
        t => {
            return Err(err(
                &format!("{num_field} field 1 (specific data type)"),
                format!(
                    "data type {t} is not displacement (8), velocity (11) or acceleration (12)"
                ),
            ))
        }
    };
    let quantities = [
        Quantity::Receptance,
        Quantity::Mobility,
        Quantity::Accelerance,
    ];
    let (quantity, num_factor, whole) = match (by_type, num_label) {
        (Some(q), None) => (q, length_si, false),
        (q, Some(u)) => {
            let hit = quantities.iter().find_map(|&cand| {
                let m = motion(cand.order());
                let full = m.times(force.powi(-1));
                if u.same_dimension(&m) {
                    Some((cand, false))
                } else if u.same_dimension(&full) {
                    Some((cand, true))
                } else {
                    None
                }
            });
            match hit {
                Some((cand, whole)) if q.is_none_or(|q| q == cand) => (cand, u.factor, whole),
                _ => {
                    return Err(err(
                        &format!("{num_field} field 6 (units label)"),
                        format!(
                            "units label '{}' ({}) does not fit data type {}",
                            f.numerator.units_label,
                            u.dimension(),
                            f.numerator.data_type
                        ),
                    ))
                }
            }
        }
        (None, None) => {
            return Err(err(
                &format!("{num_field} field 1 (specific data type)"),
                format!(
                    "data type {} (unknown/general) without a units label: cannot tell displacement, velocity or acceleration",
                    f.numerator.data_type
                ),
            ))
        }
    };
    let den_factor = if whole {
        1.0
    } else {
        let den_field = "record 10 (ordinate denominator)";
        let label = label_unit(
            &f.denominator,
            &format!("{den_field} field 6 (units label)"),
        )?;
        match (f.denominator.data_type, label) {
            (9 | 13 | 0 | 1, Some(u)) if u.same_dimension(&force) => u.factor,
            (9 | 13, None) => force_si,
            (t, Some(u)) => {
                return Err(err(
                    &format!("{den_field} field 6 (units label)"),
                    format!(
                        "units label '{}' ({}) is not a force (data type {t})",
                        f.denominator.units_label,
                        u.dimension()
                    ),
                ))
            }
            (t, None) => {
                return Err(err(
                    &format!("{den_field} field 1 (specific data type)"),
                    format!("data type {t} is not an excitation force (13) or reaction force (9)"),
                ))
            }
        }
    };
    let ab_field = "record 8 (abscissa)";
    let ab_label = label_unit(
        &f.abscissa_axis,
        &format!("{ab_field} field 6 (units label)"),
    )?;
    let abscissa = match (f.abscissa_axis.data_type, ab_label) {
        (18 | 0, None) => 1.0,
        (18 | 0 | 1, Some(u)) if u.length == 0 && u.force == 0 && u.time == -1 => u.factor,
        (t, _) => {
            return Err(err(
                &format!("{ab_field} field 1 (specific data type)"),
                format!(
                    "abscissa data type {t} (with units '{}') is not a frequency (18) in Hz",
                    f.abscissa_axis.units_label
                ),
            ))
        }
    };
    Ok(Scaling {
        quantity,
        value: num_factor / den_factor,
        abscissa,
    })
}

/// Builds the campaign (geometry in SI and one FRF set) from the datasets of a file.
/// See the crate documentation for the mapping rules.
pub fn to_campaign(uff: &UffFile) -> Result<(Geometry, FrfSet), UffError> {
    let file = uff.file_name.as_str();
    let campaign = |problem: String| UffError::Campaign {
        file: file.to_string(),
        problem,
    };
    let field_err = |at: &DatasetLocation, field: &str, problem: String| UffError::Field {
        file: file.to_string(),
        at: at.clone(),
        field: field.to_string(),
        problem,
    };
    // Pass 1: units in force at each dataset, coordinate systems.
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
    // Pass 2: nodes in global SI coordinates.
    let mut nodes: HashMap<i64, NodeInfo> = HashMap::new();
    let mut node_order: Vec<i64> = Vec::new();
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
            if let Some(prev) = nodes.get(&n.label) {
                if prev.position != position || prev.displacement_cs != n.displacement_cs {
                    return Err(field_err(
                        &d.location,
                        &format!("node {}", n.label),
                        format!(
                            "node {} is also defined, differently, in {}",
                            n.label, prev.at
                        ),
                    ));
                }
                continue;
            }
            node_order.push(n.label);
            nodes.insert(
                n.label,
                NodeInfo {
                    position,
                    displacement_cs: n.displacement_cs,
                    at: &d.location,
                },
            );
        }
    }
    // Pass 3: FRFs.
    struct Dof {
        id: String,
        node: i64,
        direction: i64,
        point: String,
        setup: String,
        at: DatasetLocation,
    }
    let mut channels: Vec<Dof> = Vec::new();
    let mut excitations: Vec<Dof> = Vec::new();
    let mut setups: Vec<SuspensionSetup> = Vec::new();
    let mut point_of_node: HashMap<i64, String> = HashMap::new();
    let mut cells: HashMap<(usize, usize), (usize, Vec<c64>, DatasetLocation)> = HashMap::new();
    let mut axis: Option<(Vec<f64>, DatasetLocation)> = None;
    let mut quantity: Option<(Quantity, DatasetLocation)> = None;
    let mut n_frf = 0usize;
    for (di, (d, &(length_si, force_si))) in uff.datasets.iter().zip(&units_at).enumerate() {
        let Record::Function(f) = &d.record else {
            continue;
        };
        if f.function_type != 4 {
            continue; // coherence, auto spectra, … travel alongside FRFs; they are not FRFs.
        }
        n_frf += 1;
        let at = &d.location;
        let s = scaling(file, at, f, length_si, force_si)?;
        match &quantity {
            None => quantity = Some((s.quantity, at.clone())),
            Some((q, first)) if *q != s.quantity => {
                return Err(campaign(format!(
                    "{first} holds {} but {at} holds {}: one FRF set has one quantity",
                    q.name(),
                    s.quantity.name()
                )))
            }
            _ => {}
        }
        let hz: Vec<f64> = f.abscissa.iter().map(|x| x * s.abscissa).collect();
        match &axis {
            None => axis = Some((hz, at.clone())),
            Some((first, first_at)) => {
                let scale = first
                    .iter()
                    .fold(0.0f64, |m, x| m.max(x.abs()))
                    .max(f64::MIN_POSITIVE);
                let same = first.len() == hz.len()
                    && first
                        .iter()
                        .zip(&hz)
                        .all(|(a, b)| (a - b).abs() <= ABSCISSA_TOLERANCE * scale);
                if !same {
                    return Err(campaign(format!(
                        "{first_at} and {at} have different abscissae ({} lines from {} to {} Hz vs {} lines from {} to {} Hz): all FRFs must share one frequency axis",
                        first.len(), first[0], first[first.len() - 1], hz.len(), hz[0], hz[hz.len() - 1]
                    )));
                }
            }
        }
        let tags = read_tags(f);
        let setup = tags
            .setup
            .clone()
            .unwrap_or_else(|| DEFAULT_SETUP.to_string());
        if !setups.iter().any(|s| s.id == setup) {
            setups.push(SuspensionSetup {
                id: setup.clone(),
                description: tags.setup_description.clone(),
            });
        }
        let mut locate = |role: &str,
                          node: i64,
                          direction: i64,
                          field: &str,
                          id: Option<String>,
                          point: Option<String>,
                          list: &mut Vec<Dof>,
                          setup: &str|
         -> Result<usize, UffError> {
            if !nodes.contains_key(&node) {
                return Err(field_err(
                    at,
                    &format!("record 6 {field}"),
                    format!(
                        "{role} node {node} has no coordinates (no dataset 15 or 2411 defines it)"
                    ),
                ));
            }
            if direction == 0 || direction.abs() > 3 {
                return Err(field_err(
                    at,
                    &format!("record 6 {field}"),
                    format!("{role} direction {direction} is not a translation (±1, ±2, ±3); scalar and rotational DOFs are not supported"),
                ));
            }
            let default_id = if role == "reference" && setup != DEFAULT_SETUP {
                format!("{}@{setup}", dof_name(node, direction))
            } else {
                dof_name(node, direction)
            };
            let id = id.unwrap_or(default_id);
            let point = point.unwrap_or_else(|| node.to_string());
            let mapped = point_of_node.entry(node).or_insert_with(|| point.clone());
            if *mapped != point {
                return Err(field_err(
                    at,
                    "ID line 5 (rbprops tags)",
                    format!("node {node} is named point '{point}' here but '{mapped}' elsewhere"),
                ));
            }
            if let Some(k) = list.iter().position(|c| c.id == id) {
                let c = &list[k];
                if c.node != node || c.direction != direction || c.setup != setup {
                    return Err(field_err(
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
        };
        let ci = locate(
            "response",
            f.response_node,
            f.response_direction,
            "field 6-7 (response node, direction)",
            tags.channel,
            tags.channel_point,
            &mut channels,
            DEFAULT_SETUP,
        )?;
        let ei = locate(
            "reference",
            f.reference_node,
            f.reference_direction,
            "field 9-10 (reference node, direction)",
            tags.excitation,
            tags.excitation_point,
            &mut excitations,
            &setup,
        )?;
        let values: Vec<c64> = f.ordinate.iter().map(|v| v * s.value).collect();
        if let Some((_, _, prev)) = cells.get(&(ei, ci)) {
            return Err(campaign(format!(
                "{prev} and {at} both hold the FRF of channel '{}' for excitation '{}'",
                channels[ci].id, excitations[ei].id
            )));
        }
        cells.insert((ei, ci), (di, values, at.clone()));
    }
    let (Some((frequency_hz, _)), Some((quantity, _))) = (axis, quantity) else {
        return Err(campaign(
            "no FRF datasets (dataset 58 with function type 4) in the file".into(),
        ));
    };
    let _ = n_frf;
    // Geometry.
    let mut points: Vec<Point> = Vec::new();
    for label in &node_order {
        let id = point_of_node
            .get(label)
            .cloned()
            .unwrap_or_else(|| label.to_string());
        if !points.iter().any(|p| p.id == id) {
            points.push(Point {
                id,
                position: nodes[label].position,
            });
        }
    }
    let mut direction_of = |dof: &Dof| -> Result<Vec3, UffError> {
        let node = &nodes[&dof.node];
        let field = format!("node {} field 3 (displacement coordinate system)", dof.node);
        let frame = frames.frame(node.displacement_cs, node.at, &field, 0)?;
        let k = dof.direction.unsigned_abs() as usize - 1;
        Ok(frame.rows[k] * dof.direction.signum() as f64)
    };
    let mut geometry = Geometry {
        points,
        setups,
        ..Default::default()
    };
    for c in &channels {
        geometry.channels.push(Channel {
            id: c.id.clone(),
            point: c.point.clone(),
            position: nodes[&c.node].position,
            direction: direction_of(c)?,
        });
    }
    for e in &excitations {
        geometry.excitations.push(Excitation {
            id: e.id.clone(),
            point: e.point.clone(),
            position: nodes[&e.node].position,
            direction: direction_of(e)?,
            setup: e.setup.clone(),
        });
    }
    let mut frf = FrfSet::zeros(quantity, frequency_hz, excitations.len(), channels.len());
    for (ei, e) in excitations.iter().enumerate() {
        for (ci, c) in channels.iter().enumerate() {
            let Some((_, values, _)) = cells.remove(&(ei, ci)) else {
                return Err(campaign(format!(
                    "no FRF for channel '{}' (node {} direction {}) and excitation '{}' (node {} direction {}, set-up {}): every excitation needs every channel",
                    c.id, c.node, c.direction, e.id, e.node, e.direction, e.setup
                )));
            };
            frf.frf_mut(ei, ci).copy_from_slice(&values);
        }
    }
    geometry
        .validate()
        .map_err(|e| campaign(format!("geometry: {e}")))?;
    frf.validate().map_err(|e| campaign(e.to_string()))?;
    Ok((geometry, frf))
}
