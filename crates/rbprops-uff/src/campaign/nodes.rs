//! The node table: every node of the data file (datasets 15 and 2411, their coordinate
//! systems and units applied) and of a separate geometry source.

use super::{CsEntry, Frames};
use crate::error::{DatasetLocation, UffError};
use crate::model::*;
use crate::units::system_units;
use rbprops_core::Vec3;
use std::collections::HashMap;

/// A node in global SI coordinates with the axes its direction codes refer to.
pub(super) struct NodeEntry {
    pub(super) position: Vec3,
    /// Axes of the node's displacement system (an error only matters when a DOF uses it).
    pub(super) axes: Result<[Vec3; 3], UffError>,
    pub(super) file: String,
}

#[derive(Default)]
pub(super) struct NodeTable {
    pub(super) order: Vec<i64>,
    pub(super) nodes: HashMap<i64, NodeEntry>,
}

impl NodeTable {
    pub(super) fn insert(
        &mut self,
        label: i64,
        e: NodeEntry,
        at: &DatasetLocation,
    ) -> Result<(), UffError> {
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
pub(super) fn add_file_nodes(
    uff: &UffFile,
    table: &mut NodeTable,
) -> Result<Vec<(f64, f64)>, UffError> {
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
