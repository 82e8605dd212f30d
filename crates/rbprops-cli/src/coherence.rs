//! The measured coherence topic (`/rbprops/coherence`): written by the UFF import, read by
//! `modal-fit --weight coherence`.

use anyhow::{bail, Result};
use rbprops_core::{c64, Geometry};
use rbprops_formats::wire::{decode_values, encode_values, CoherenceMsg};
use rbprops_formats::{topics, RunRecord};

/// Coherence per excitation and channel (`None` where the file had none), geometry order.
pub type CoherenceGrid = Vec<Vec<Option<Vec<f64>>>>;

/// Stores a matched coherence set as the coherence topic.
pub fn set(rec: &mut RunRecord, geometry: &Geometry, coh: &rbprops_uff::CoherenceSet) {
    let mut msgs = Vec::new();
    for (e, row) in geometry.excitations.iter().zip(&coh.values) {
        let mut channels = Vec::new();
        let mut values: Vec<c64> = Vec::new();
        for (c, v) in geometry.channels.iter().zip(row) {
            if let Some(v) = v {
                channels.push(c.id.clone());
                values.extend(v.iter().map(|&g| c64::new(g, 0.0)));
            }
        }
        if !channels.is_empty() {
            msgs.push(CoherenceMsg {
                excitation: e.id.clone(),
                channels,
                values_f64le: encode_values(&values),
            });
        }
    }
    rec.set(topics::COHERENCE, &msgs);
}

/// The coherence topic of a record on its FRF set's ids; `None` when there is none.
pub fn get(rec: &RunRecord) -> Result<Option<CoherenceGrid>> {
    let msgs: Vec<CoherenceMsg> = rec.get(topics::COHERENCE)?;
    if msgs.is_empty() {
        return Ok(None);
    }
    let (geometry, frf) = rec.require_geometry_and_frf()?;
    let n = frf.n_lines();
    let mut grid: CoherenceGrid = vec![vec![None; frf.n_channels]; frf.n_excitations];
    for m in &msgs {
        let Some(e) = geometry
            .excitations
            .iter()
            .position(|x| x.id == m.excitation)
        else {
            bail!(
                "coherence topic: excitation '{}' is not in the geometry",
                m.excitation
            );
        };
        let values = decode_values(&m.values_f64le, n * m.channels.len())
            .map_err(|e| anyhow::anyhow!("coherence topic, excitation '{}': {e}", m.excitation))?;
        for (k, id) in m.channels.iter().enumerate() {
            let Some(c) = geometry.channels.iter().position(|x| &x.id == id) else {
                bail!("coherence topic: channel '{id}' is not in the geometry");
            };
            grid[e][c] = Some(values[k * n..(k + 1) * n].iter().map(|v| v.re).collect());
        }
    }
    Ok(Some(grid))
}
