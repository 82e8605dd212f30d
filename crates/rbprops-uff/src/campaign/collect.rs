//! Collecting the datasets 58 into one FRF set: the DOFs of each function, one abscissa
//! axis, and the coherences matched to their FRFs.

use super::{
    abscissa_factor, campaign_error, direction_text, dof_name, dof_source_notes, field_error,
    no_dataset, read_tags, scaling, CoherenceSet, FunctionDofs, NodeTable, Warnings,
    ABSCISSA_TOLERANCE, DEFAULT_SETUP,
};
use crate::dof::NodeDof;
use crate::error::{DatasetLocation, UffError};
use crate::model::*;
use rbprops_core::{
    c64, Channel, Excitation, FrfSet, Geometry, Point, Quantity, SuspensionSetup, Vec3,
};
use std::collections::HashMap;

/// A response or reference DOF of the campaign, as pass 2 meets it.
pub(super) struct Dof {
    pub(super) id: String,
    pub(super) node: i64,
    pub(super) direction: i64,
    pub(super) point: String,
    pub(super) setup: String,
    pub(super) at: DatasetLocation,
}

/// Which side of an FRF a DOF is on.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum Side {
    Response,
    Reference,
}

/// Pass 2's state: the channels and excitations in order of appearance, the FRF of each
/// (excitation, channel) cell, and the one axis and quantity they must all share.
pub(super) struct FrfCollector<'a> {
    pub(super) file: &'a str,
    pub(super) channels: Vec<Dof>,
    pub(super) excitations: Vec<Dof>,
    pub(super) setups: Vec<SuspensionSetup>,
    pub(super) point_of_node: HashMap<i64, String>,
    pub(super) cells: HashMap<(usize, usize), (Vec<c64>, DatasetLocation)>,
    pub(super) axis: Option<(Vec<f64>, DatasetLocation)>,
    pub(super) quantity: Option<(Quantity, DatasetLocation)>,
}

impl<'a> FrfCollector<'a> {
    pub(super) fn new(file: &'a str) -> Self {
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
    pub(super) fn add(
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
    pub(super) fn check_shared(
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
    pub(super) fn locate(
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
    pub(super) fn geometry(
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

    pub(super) fn note_unused_nodes(&self, table: &NodeTable, warnings: &mut Warnings) {
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
    pub(super) fn into_frf_set(
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
pub(super) fn match_coherence(
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
pub(super) fn coherence_problem(
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
pub(super) fn same_axis(first: &[f64], other: &[f64]) -> bool {
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
