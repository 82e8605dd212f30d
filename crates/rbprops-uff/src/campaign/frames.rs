//! Coordinate systems (datasets 18 and 2420) resolved to frames, so that node positions
//! and directions come out in global SI coordinates.

use super::ORTHONORMAL_TOLERANCE;
use crate::error::{DatasetLocation, UffError};
use crate::model::*;
use rbprops_core::Vec3;
use std::collections::HashMap;

/// A resolved Cartesian frame: `rows` are the local axes in global coordinates (SI).
#[derive(Debug, Clone, Copy)]
pub(super) struct Frame {
    pub(super) rows: [Vec3; 3],
    pub(super) origin: Vec3,
}

impl Frame {
    pub(super) fn global() -> Self {
        Frame {
            rows: [Vec3::x(), Vec3::y(), Vec3::z()],
            origin: Vec3::zeros(),
        }
    }
    /// Global position of a point given in this frame (SI).
    pub(super) fn to_global(self, p: Vec3) -> Vec3 {
        self.origin + self.rows[0] * p.x + self.rows[1] * p.y + self.rows[2] * p.z
    }
}

pub(super) struct CsEntry<'a> {
    pub(super) cs: &'a CoordinateSystem,
    pub(super) length_si: f64,
    pub(super) at: &'a DatasetLocation,
}

pub(super) struct Frames<'a> {
    pub(super) file: &'a str,
    pub(super) defs: HashMap<i64, CsEntry<'a>>,
    pub(super) resolved: HashMap<i64, Frame>,
}

impl<'a> Frames<'a> {
    pub(super) fn err(&self, at: &DatasetLocation, field: String, problem: String) -> UffError {
        UffError::Field {
            file: self.file.to_string(),
            at: at.clone(),
            field,
            problem,
        }
    }

    /// The Cartesian frame of system `label` (0 = global). `user` names who asks.
    pub(super) fn frame(
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
