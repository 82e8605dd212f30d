//! The measured coherence topic (`/rbprops/coherence`): written by the UFF import, read by
//! `modal-fit --weight coherence`.

use anyhow::{bail, Result};
use rbprops_core::Geometry;
use rbprops_formats::wire::CoherenceMsg;
use rbprops_formats::{topics, RunRecord};

/// Coherence per excitation and channel (`None` where the file had none), geometry order.
pub type CoherenceGrid = Vec<Vec<Option<Vec<f64>>>>;

/// Stores a matched coherence set as the coherence topic (`crate::channel_table`).
pub fn set(rec: &mut RunRecord, geometry: &Geometry, coh: &rbprops_uff::CoherenceSet) {
    let msgs: Vec<CoherenceMsg> =
        crate::channel_table::encode(geometry, |e, c| coh.values.get(e)?.get(c)?.as_deref())
            .into_iter()
            .map(|r| CoherenceMsg {
                excitation: r.excitation,
                channels: r.channels,
                values_f64le: r.values_f64le,
            })
            .collect();
    rec.set(topics::COHERENCE, &msgs);
}

/// The coherence topic of a record on its FRF set's ids; `None` when there is none.
pub fn get(rec: &RunRecord) -> Result<Option<CoherenceGrid>> {
    let msgs: Vec<CoherenceMsg> = rec.get(topics::COHERENCE)?;
    if msgs.is_empty() {
        return Ok(None);
    }
    let (geometry, frf) = rec.require_geometry_and_frf()?;
    let mut grid: CoherenceGrid = vec![vec![None; frf.n_channels]; frf.n_excitations];
    for m in &msgs {
        let (e, channels) = crate::channel_table::decode(
            &geometry,
            frf.n_lines(),
            "coherence topic",
            &m.excitation,
            &m.channels,
            &m.values_f64le,
        )?;
        for (c, v) in channels {
            grid[e][c] = Some(v);
        }
    }
    Ok(Some(grid))
}

/// Sets up `modal-fit --weight coherence` on a record read from `source`: the fit options
/// get the record's coherence as line weights (`rbprops_modal::weighting`, 1 − γ² floored
/// at single precision, `rbprops_core::CoherenceNoise::SINGLE_PRECISION_FLOOR`), and the
/// processing topic records the weighting, so the output says how it was fitted.
/// Errors, naming `source`, when the record has no coherence or a value is not one.
pub fn weight_fit(
    rec: &mut RunRecord,
    opts: &mut rbprops_modal::FitOptions,
    source: &str,
) -> Result<()> {
    use rbprops_core::records::{LineWeightingRecord, ProcessingRecord, PROCESSING_TOPIC};
    let Some(weighting) = weighting(rec, source)? else {
        bail!(
            "{source}: --weight coherence, but the recording holds no coherence (a UFF export needs coherence datasets, function type 6, beside its FRFs; an MCAP or CSV run the {} topic)",
            topics::COHERENCE
        );
    };
    let mut processing: ProcessingRecord = rec.get_one(PROCESSING_TOPIC)?.unwrap_or_default();
    processing.line_weighting = Some(LineWeightingRecord {
        weight: LineWeightingRecord::COHERENCE.into(),
        method: "least squares weighted by 1/σ² with σ²/|H|² ∝ (1 − γ²)/γ² from the measured coherence, averaged over each excitation's channels per line (one weight per line), times 1/|H|² per channel in the pole estimate".into(),
        one_minus_coherence_floor: weighting.floor(),
        unweighted_excitations: weighting.unweighted_excitations(),
    });
    rec.set(PROCESSING_TOPIC, std::slice::from_ref(&processing));
    opts.coherence_weighting = Some(std::sync::Arc::new(weighting));
    Ok(())
}

/// The line weighting of `modal-fit --weight coherence` from a record read from
/// `source` (see [`weight_fit`]); `None` when the record holds no coherence.
pub fn weighting(
    rec: &RunRecord,
    source: &str,
) -> Result<Option<rbprops_modal::CoherenceWeighting>> {
    let Some(grid) = get(rec).map_err(|e| anyhow::anyhow!("{source}: {e}"))? else {
        return Ok(None);
    };
    let (geometry, frf) = rec.require_geometry_and_frf()?;
    rbprops_modal::CoherenceWeighting::new(
        grid,
        frf.n_channels,
        frf.n_lines(),
        rbprops_core::CoherenceNoise::SINGLE_PRECISION_FLOOR,
    )
    .map(Some)
    .map_err(|e| {
        // Name the excitation and channel by their ids, not their indices.
        anyhow::anyhow!("{source}: coherence topic: {}", name_ids(&e, &geometry))
    })
}

/// `excitation E, channel C, …` with the ids of excitation index E and channel index C.
pub(crate) fn name_ids(msg: &str, geometry: &Geometry) -> String {
    let mut out = msg.to_string();
    let mut words = msg.split(", ");
    if let Some(e) = words.next().and_then(|w| w.strip_prefix("excitation ")) {
        if let Some(x) = e
            .parse::<usize>()
            .ok()
            .and_then(|i| geometry.excitations.get(i))
        {
            out = out.replacen(
                &format!("excitation {e}"),
                &format!("excitation '{}'", x.id),
                1,
            );
        }
    }
    if let Some(c) = msg
        .split(", ")
        .find_map(|w| w.strip_prefix("channel "))
        .and_then(|c| c.split(&[',', ':'][..]).next())
    {
        if let Some(x) = c
            .parse::<usize>()
            .ok()
            .and_then(|i| geometry.channels.get(i))
        {
            out = out.replacen(&format!("channel {c}"), &format!("channel '{}'", x.id), 1);
        }
    }
    out
}
