//! Writing a campaign as a universal file: dataset 164 (SI), 2420 (displacement
//! systems for directions off the global axes), 2411 or 15 (nodes) and one dataset 58
//! (or 58b) per (excitation, channel) pair.

use crate::campaign::DEFAULT_SETUP;
use crate::error::UffError;
use crate::fortran::{fmt_e, fmt_exactish};
use crate::model::NodeFormat;
use rbprops_core::{c64, Channel, Excitation, FrfSet, Geometry, Quantity, SuspensionSetup, Vec3};
use std::fmt::Write as _;

/// Options of [`from_campaign`].
#[derive(Debug, Clone, PartialEq)]
pub struct WriteOptions {
    /// Write FRFs as binary 58b (little-endian IEEE doubles, bit-exact) instead of ASCII
    /// 58 (20-column `E` fields, 13 significant digits). Default: false.
    pub binary: bool,
    /// Node dataset: 2411 (double precision, exact; default) or 15 (`E13.5` fields,
    /// about 7 significant digits).
    pub nodes: NodeFormat,
    /// Write the `rbprops` tags (ID lines 4 and 5) that make ids round-trip. Default: true.
    pub tags: bool,
    /// ID line 2 of every dataset 58 (run identification); "NONE" if empty.
    pub run_id: String,
}

impl Default for WriteOptions {
    fn default() -> Self {
        Self {
            binary: false,
            nodes: NodeFormat::D2411,
            tags: true,
            run_id: String::new(),
        }
    }
}

/// Orthogonality tolerance for directions to share one node's displacement system.
const SHARE_TOLERANCE: f64 = 1e-12;

/// One node of the file: a point (or a point's share of directions) and its frame.
struct NodePlan {
    label: i64,
    point: String,
    position: Vec3,
    /// Distinct directions (up to sign) the node must express, in first-use order.
    dirs: Vec<Vec3>,
    /// Rows = local axes in global coordinates; None = global system (code 0).
    frame: Option<[Vec3; 3]>,
    cs_label: i64,
}

impl NodePlan {
    fn has(&self, d: &Vec3) -> bool {
        self.dirs.iter().any(|e| e == d || *e == -d)
    }
    fn accepts(&self, d: &Vec3) -> bool {
        self.has(d)
            || (self.dirs.len() < 3 && self.dirs.iter().all(|e| e.dot(d).abs() <= SHARE_TOLERANCE))
    }
    fn finish(&mut self) {
        let axes = [Vec3::x(), Vec3::y(), Vec3::z()];
        if self
            .dirs
            .iter()
            .all(|d| axes.iter().any(|a| a == d || *a == -d))
        {
            return; // global system
        }
        let d = &self.dirs;
        let x = d[0];
        let y = if d.len() > 1 {
            d[1]
        } else {
            // Any unit vector perpendicular to x: cross with the axis least aligned to it.
            let a = axes
                .iter()
                .min_by(|a, b| a.dot(&x).abs().total_cmp(&b.dot(&x).abs()))
                .copied()
                .unwrap_or(Vec3::z());
            x.cross(&a).normalize()
        };
        let z = if d.len() > 2 {
            // Keep the frame right-handed: use the third direction or its negative.
            if d[2].dot(&x.cross(&y)) >= 0.0 {
                d[2]
            } else {
                -d[2]
            }
        } else {
            x.cross(&y)
        };
        self.frame = Some([x, y, z]);
    }
    /// Direction code of `d` in this node's system (exact by construction).
    fn code(&self, d: &Vec3) -> i64 {
        let rows = self.frame.unwrap_or([Vec3::x(), Vec3::y(), Vec3::z()]);
        for (k, r) in rows.iter().enumerate() {
            if r == d {
                return k as i64 + 1;
            }
            if *r == -d {
                return -(k as i64 + 1);
            }
        }
        unreachable!("every direction of a node is an axis of its frame")
    }
}

fn canonical_label(id: &str) -> Option<i64> {
    let v: i64 = id.parse().ok()?;
    (v > 0 && v <= 99_999_999 && v.to_string() == id).then_some(v)
}

fn tag_value_ok(s: &str) -> bool {
    !s.is_empty() && !s.contains(char::is_whitespace) && !s.contains('=')
}

fn line80(s: &str) -> String {
    let t: String = s.replace(['\n', '\r'], " ").chars().take(80).collect();
    if t.trim().is_empty() {
        "NONE".into()
    } else {
        t
    }
}

/// Plans nodes: one per point (label = the point id if it is a canonical positive
/// integer, else a running number), plus extra nodes at the same place when a point's
/// directions cannot share one orthonormal system.
fn plan_nodes(geometry: &Geometry) -> Vec<NodePlan> {
    let mut plans: Vec<NodePlan> = Vec::new();
    let all_integer = geometry
        .points
        .iter()
        .all(|p| canonical_label(&p.id).is_some());
    let mut next_label = if all_integer {
        geometry
            .points
            .iter()
            .filter_map(|p| canonical_label(&p.id))
            .max()
            .unwrap_or(0)
            + 1
    } else {
        1
    };
    for p in &geometry.points {
        let label = if all_integer {
            canonical_label(&p.id).expect("checked")
        } else {
            let l = next_label;
            next_label += 1;
            l
        };
        plans.push(NodePlan {
            label,
            point: p.id.clone(),
            position: p.position,
            dirs: Vec::new(),
            frame: None,
            cs_label: 0,
        });
    }
    let uses = geometry
        .channels
        .iter()
        .map(|c| (&c.point, c.position, c.direction))
        .chain(
            geometry
                .excitations
                .iter()
                .map(|e| (&e.point, e.position, e.direction)),
        );
    for (point, position, d) in uses {
        let found = plans
            .iter_mut()
            .find(|n| &n.point == point && n.position == position && n.accepts(&d));
        match found {
            Some(n) => {
                if !n.has(&d) {
                    n.dirs.push(d);
                }
            }
            None => {
                plans.push(NodePlan {
                    label: next_label,
                    point: point.clone(),
                    position,
                    dirs: vec![d],
                    frame: None,
                    cs_label: 0,
                });
                next_label += 1;
            }
        }
    }
    let mut cs = 0;
    for n in plans.iter_mut() {
        if !n.dirs.is_empty() {
            n.finish();
        }
        if n.frame.is_some() {
            cs += 1;
            n.cs_label = cs;
        }
    }
    plans
}

fn node_for<'a>(plans: &'a [NodePlan], point: &str, position: Vec3, d: &Vec3) -> &'a NodePlan {
    plans
        .iter()
        .find(|n| n.point == point && n.position == position && n.has(d))
        .expect("planned")
}

fn delimiter(out: &mut Vec<u8>) {
    out.extend_from_slice(b"    -1\n");
}

fn fmt_i(v: i64, w: usize) -> String {
    format!("{v:>w$}")
}

/// Writes a campaign as a universal file (bytes). See the crate docs for the layout and
/// the tags; [`crate::parse`] + [`crate::to_campaign`] read it back exactly (ASCII:
/// values to 13 significant digits; binary: bit-exact; frequencies: see the crate docs).
pub fn from_campaign(
    geometry: &Geometry,
    frf: &FrfSet,
    opts: &WriteOptions,
) -> Result<Vec<u8>, UffError> {
    check_campaign(geometry, frf)?;
    let plans = plan_nodes(geometry);
    let mut s = String::new();
    write_units(&mut s);
    write_frames(&mut s, &plans);
    write_nodes(&mut s, &plans, opts.nodes);
    let mut out: Vec<u8> = s.into_bytes();
    // 58: one per (excitation, channel).
    let axis = AbscissaHeader::new(&frf.frequency_hz, opts.binary);
    let mut function_id = 0;
    for (ei, e) in geometry.excitations.iter().enumerate() {
        let en = node_for(&plans, &e.point, e.position, &e.direction);
        for (ci, c) in geometry.channels.iter().enumerate() {
            function_id += 1;
            let cn = node_for(&plans, &c.point, c.position, &c.direction);
            let setup = geometry.setups.iter().find(|s| s.id == e.setup);
            let dofs = [(cn, c.direction), (en, e.direction)];
            let h = function_header(c, e, setup, dofs, function_id, frf, &axis, opts);
            out.extend_from_slice(h.as_bytes());
            write_ordinates(
                &mut out,
                &frf.frequency_hz,
                frf.frf(ei, ci),
                &axis,
                opts.binary,
            );
            delimiter(&mut out);
        }
    }
    Ok(out)
}

/// The geometry and the FRF set must be valid and agree in shape.
fn check_campaign(geometry: &Geometry, frf: &FrfSet) -> Result<(), UffError> {
    let werr = |m: String| UffError::Write(m);
    geometry
        .validate()
        .map_err(|e| werr(format!("geometry: {e}")))?;
    frf.validate().map_err(|e| werr(e.to_string()))?;
    if frf.n_channels != geometry.channels.len() || frf.n_excitations != geometry.excitations.len()
    {
        return Err(werr(format!(
            "FRF set has {} excitations × {} channels, the geometry {} × {}",
            frf.n_excitations,
            frf.n_channels,
            geometry.excitations.len(),
            geometry.channels.len()
        )));
    }
    Ok(())
}

/// Dataset 164: SI units.
fn write_units(s: &mut String) {
    s.push_str("    -1\n   164\n");
    let _ = writeln!(s, "{:>10}{:<20}{:>10}", 1, "SI: meter (newton)", 2);
    let _ = writeln!(
        s,
        "{}{}{}",
        fmt_e(1.0, 25, 17),
        fmt_e(1.0, 25, 17),
        fmt_e(1.0, 25, 17)
    );
    let _ = writeln!(s, "{}", fmt_e(273.15, 25, 17));
    s.push_str("    -1\n");
}

/// Dataset 2420: the displacement systems of the nodes whose directions are not the
/// global axes (none: no dataset).
fn write_frames(s: &mut String, plans: &[NodePlan]) {
    if !plans.iter().any(|n| n.frame.is_some()) {
        return;
    }
    s.push_str("    -1\n  2420\n");
    let _ = writeln!(s, "{:>10}", 1);
    s.push_str("rbprops sensor and force directions\n");
    for n in plans.iter().filter(|n| n.frame.is_some()) {
        let rows = n.frame.expect("filtered");
        let _ = writeln!(
            s,
            "{}{}{}",
            fmt_i(n.cs_label, 10),
            fmt_i(0, 10),
            fmt_i(8, 10)
        );
        let _ = writeln!(s, "node {} directions", n.label);
        for r in rows.iter().chain([Vec3::zeros()].iter()) {
            let _ = writeln!(
                s,
                "{}{}{}",
                fmt_e(r.x, 25, 17),
                fmt_e(r.y, 25, 17),
                fmt_e(r.z, 25, 17)
            );
        }
    }
    s.push_str("    -1\n");
}

/// The nodes as dataset 2411 (double precision) or 15 (`E13.5`).
fn write_nodes(s: &mut String, plans: &[NodePlan], format: NodeFormat) {
    match format {
        NodeFormat::D2411 => {
            s.push_str("    -1\n  2411\n");
            for n in plans {
                let _ = writeln!(
                    s,
                    "{}{}{}{}",
                    fmt_i(n.label, 10),
                    fmt_i(0, 10),
                    fmt_i(n.cs_label, 10),
                    fmt_i(8, 10)
                );
                let p = n.position;
                let _ = writeln!(
                    s,
                    "{}{}{}",
                    fmt_e(p.x, 25, 17),
                    fmt_e(p.y, 25, 17),
                    fmt_e(p.z, 25, 17)
                );
            }
        }
        NodeFormat::D15 => {
            s.push_str("    -1\n    15\n");
            for n in plans {
                let p = n.position;
                let _ = writeln!(
                    s,
                    "{}{}{}{}{}{}{}",
                    fmt_i(n.label, 10),
                    fmt_i(0, 10),
                    fmt_i(n.cs_label, 10),
                    fmt_i(8, 10),
                    fmt_exactish(p.x, 13),
                    fmt_exactish(p.y, 13),
                    fmt_exactish(p.z, 13)
                );
            }
        }
    }
    s.push_str("    -1\n");
}

/// Record 7's abscissa fields: the axis is written as even (start and step) when the
/// fields reproduce it — bit for bit in binary (else the abscissa travels as doubles),
/// to 1e-12 of its span in ASCII.
struct AbscissaHeader {
    even: bool,
    min_field: String,
    inc_field: String,
}

impl AbscissaHeader {
    fn new(hz: &[f64], binary: bool) -> Self {
        let n = hz.len();
        let (min, inc) = (hz[0], if n > 1 { hz[1] - hz[0] } else { 0.0 });
        let (min_field, inc_field) = (fmt_exactish(min, 13), fmt_exactish(inc, 13));
        let (min_back, inc_back) = (
            crate::fortran::parse_real(&min_field).unwrap_or(f64::NAN),
            crate::fortran::parse_real(&inc_field).unwrap_or(f64::NAN),
        );
        let span = hz
            .iter()
            .fold(0.0f64, |m, x| m.max(x.abs()))
            .max(f64::MIN_POSITIVE);
        let tol = if binary { 0.0 } else { 1e-12 };
        let even = hz
            .iter()
            .enumerate()
            .all(|(k, &f)| (min_back + k as f64 * inc_back - f).abs() <= tol * span);
        AbscissaHeader {
            even,
            min_field,
            inc_field,
        }
    }
}

/// ID lines 4 and 5 of a function: the set-up and the `rbprops` tags that make ids
/// round-trip (left empty when tags are off or a value cannot be a tag).
fn tag_lines(
    c: &Channel,
    e: &Excitation,
    setup: Option<&SuspensionSetup>,
    tags: bool,
) -> (String, String) {
    let tags = tags
        && tag_value_ok(&e.setup)
        && [&c.id, &c.point, &e.id, &e.point]
            .iter()
            .all(|v| tag_value_ok(v));
    let id4 = if tags {
        let desc = setup.map(|s| s.description.as_str()).unwrap_or("");
        format!("setup={} {}", e.setup, desc)
    } else if e.setup != DEFAULT_SETUP {
        format!("setup={}", e.setup)
    } else {
        String::new()
    };
    let id5 = format!(
        "rbprops ch={} cp={} ex={} ep={}",
        c.id, c.point, e.id, e.point
    );
    let id5 = if tags && id5.len() <= 80 {
        id5
    } else {
        String::new()
    };
    (id4, id5)
}

/// The header of one dataset 58 (records 1–11): ID lines, the DOFs (record 6), the
/// abscissa (record 7) and the axes (records 8–11).
#[allow(clippy::too_many_arguments)]
fn function_header(
    c: &Channel,
    e: &Excitation,
    setup: Option<&SuspensionSetup>,
    [(cn, cd), (en, ed)]: [(&NodePlan, Vec3); 2],
    function_id: usize,
    frf: &FrfSet,
    axis: &AbscissaHeader,
    opts: &WriteOptions,
) -> String {
    let n = frf.frequency_hz.len();
    let mut h = String::new();
    h.push_str("    -1\n");
    let n_bytes = n * if axis.even { 16 } else { 24 };
    if opts.binary {
        let _ = writeln!(
            h,
            "{:>6}b{:>6}{:>6}{:>12}{:>12}{:>6}{:>6}{:>12}{:>12}",
            58, 1, 2, 11, n_bytes, 0, 0, 0, 0
        );
    } else {
        h.push_str("    58\n");
    }
    let _ = writeln!(h, "{}", line80(&format!("FRF {} / {}", c.id, e.id)));
    let _ = writeln!(h, "{}", line80(&opts.run_id));
    h.push_str("NONE\n");
    let (id4, id5) = tag_lines(c, e, setup, opts.tags);
    let _ = writeln!(h, "{}", line80(id4.trim_end()));
    let _ = writeln!(h, "{}", line80(&id5));
    let _ = writeln!(
        h,
        "{:>5}{:>10}{:>5}{:>10} {:<10}{:>10}{:>4} {:<10}{:>10}{:>4}",
        4,
        function_id,
        1,
        0,
        "NONE",
        cn.label,
        cn.code(&cd),
        "NONE",
        en.label,
        en.code(&ed)
    );
    let zero = fmt_e(0.0, 13, 6);
    let (min, inc) = if axis.even {
        (axis.min_field.as_str(), axis.inc_field.as_str())
    } else {
        (zero.as_str(), zero.as_str())
    };
    let _ = writeln!(
        h,
        "{:>10}{:>10}{:>10}{min}{inc}{zero}",
        6,
        n,
        i32::from(axis.even)
    );
    let (num_type, num_label, num_units) = match frf.quantity {
        Quantity::Receptance => (8, "Displacement", "m"),
        Quantity::Mobility => (11, "Velocity", "m/s"),
        Quantity::Accelerance => (12, "Acceleration", "m/s^2"),
    };
    for (t, l, f, label, units) in [
        (18, 0, 0, "Frequency", "Hz"),
        (num_type, 1, 0, num_label, num_units),
        (13, 0, 1, "Force", "N"),
        (0, 0, 0, "NONE", "NONE"),
    ] {
        let _ = writeln!(
            h,
            "{:>10}{:>5}{:>5}{:>5} {:<20} {:<20}",
            t, l, f, 0, label, units
        );
    }
    h
}

/// Record 12 of one dataset 58: little-endian doubles in binary; in ASCII `4E20.12`
/// (two complex values per line) on an even axis, else `E13.5,2E20.12` per point.
fn write_ordinates(
    out: &mut Vec<u8>,
    hz: &[f64],
    values: &[c64],
    axis: &AbscissaHeader,
    binary: bool,
) {
    if binary {
        for (k, v) in values.iter().enumerate() {
            if !axis.even {
                out.extend_from_slice(&hz[k].to_le_bytes());
            }
            out.extend_from_slice(&v.re.to_le_bytes());
            out.extend_from_slice(&v.im.to_le_bytes());
        }
        return;
    }
    let mut d = String::new();
    if axis.even {
        for pair in values.chunks(2) {
            for v in pair {
                d.push_str(&fmt_e(v.re, 20, 13));
                d.push_str(&fmt_e(v.im, 20, 13));
            }
            d.push('\n');
        }
    } else {
        for (k, v) in values.iter().enumerate() {
            d.push_str(&fmt_exactish(hz[k], 13));
            d.push_str(&fmt_e(v.re, 20, 13));
            d.push_str(&fmt_e(v.im, 20, 13));
            d.push('\n');
        }
    }
    out.extend_from_slice(d.as_bytes());
}
