//! The per-excitation views: indicator curves (NI, Eq. 12; hybrid and PRF MIF), NI peaks
//! attributed to the modes, and the mode × excitation strength matrix.

use super::{
    mode_half_width, ExcitationCurves, ExcitationSummary, ModeExcitation, ModeGroup, NiPeak,
    PoolInputs, SelectOptions, StrengthMatrix,
};
use crate::diagnostic;
use crate::indicators::{
    hybrid_mif, local_spacing, norm_indicator, power_db, prf_mif_from, principal_responses,
};
use crate::peaks::find_peaks;
use rbprops_core::records::{Diagnostic, DiagnosticKind, DiagnosticSubject, Severity};
use rbprops_core::{FrfSet, Geometry};

/// The curves of the geometry's excitation `k`, whose FRFs are excitation `index` of `frf`.
pub(super) fn excitation_curves(
    geometry: &Geometry,
    frf: &FrfSet,
    index: usize,
    k: usize,
    opts: &SelectOptions,
) -> ExcitationCurves {
    let prf = principal_responses(frf, index);
    let rank = prf.rank(opts.prf_rank_tolerance);
    ExcitationCurves {
        excitation: geometry.excitations[k].id.clone(),
        setup: geometry.excitations[k].setup.clone(),
        ni_db: norm_indicator(frf, index),
        hybrid_mif: hybrid_mif(frf, index),
        prf_mif: prf_mif_from(frf, &prf, opts.prf_rank_tolerance),
        prf_db: if opts.principal_response_curves {
            prf.responses[..rank]
                .iter()
                .map(|p| p.iter().map(|h| power_db(h.norm_sqr())).collect())
                .collect()
        } else {
            Vec::new()
        },
        prf_singular_values: prf.singular_values,
        prf_rank: rank,
    }
}

pub(super) fn db10(x: f64) -> Option<f64> {
    (x > 0.0 && x.is_finite()).then(|| 10.0 * x.log10())
}

/// The mode a peak of the NI at `f` belongs to: the nearest mode whose band contains it.
pub(super) fn mode_of_peak(mode_groups: &[ModeGroup], f: f64, spacing: f64) -> Option<usize> {
    mode_groups
        .iter()
        .filter(|g| {
            (f - g.frequency_hz).abs() <= mode_half_width(g.frequency_hz, g.damping_ratio, spacing)
        })
        .min_by(|a, b| {
            (f - a.frequency_hz)
                .abs()
                .total_cmp(&(f - b.frequency_hz).abs())
        })
        .map(|g| g.mode)
}

/// Per-excitation summaries (`per_excitation[j]`: the rows of the pool's j-th excitation,
/// mode by mode), with the NI peaks attributed to the modes; warns of an NI peak where no
/// mode was identified.
pub(super) fn excitation_summaries(
    p: &PoolInputs,
    per_excitation: Vec<Vec<ModeExcitation>>,
    mode_groups: &[ModeGroup],
    warnings: &mut Vec<Diagnostic>,
) -> Vec<ExcitationSummary> {
    let opts = p.opts;
    let mut summaries = Vec::with_capacity(p.pool.excitations.len());
    for (slot, &k) in per_excitation.into_iter().zip(&p.pool.excitations) {
        let c = p.curves_of(k);
        let top = c.ni_db.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let peaks: Vec<NiPeak> = find_peaks(&c.ni_db, opts.peak_prominence_db)
            .into_iter()
            .filter(|pk| c.ni_db[pk.line] >= top - opts.min_strength_db)
            .map(|pk| {
                let f = p.frf.frequency_hz()[pk.line];
                let spacing = local_spacing(p.frf.frequency_hz(), f);
                NiPeak {
                    frequency_hz: f,
                    level_db: c.ni_db[pk.line],
                    prominence_db: pk.prominence,
                    mode: mode_of_peak(mode_groups, f, spacing),
                }
            })
            .collect();
        for pk in peaks.iter().filter(|pk| pk.mode.is_none()) {
            warnings.push(diagnostic(
                DiagnosticKind::UnmatchedPeak,
                Severity::Warning,
                DiagnosticSubject::setup(&p.pool.label)
                    .excitation(&c.excitation)
                    .at_hz(&[pk.frequency_hz]),
                format!(
                    "the NI peaks at {:.4} Hz ({:.1} dB) where no mode was identified",
                    pk.frequency_hz, pk.level_db
                ),
            ));
        }
        let excited: Vec<&ModeExcitation> = slot.iter().filter(|m| m.eligible).collect();
        let own_top = excited
            .iter()
            .filter_map(|m| m.strength)
            .fold(0.0f64, f64::max);
        let mostly: Vec<usize> = excited
            .iter()
            .filter(|m| {
                m.strength
                    .is_some_and(|s| s >= own_top * 10f64.powf(-opts.mostly_db / 10.0))
            })
            .map(|m| m.mode)
            .collect();
        summaries.push(ExcitationSummary {
            excitation: c.excitation.clone(),
            setup: c.setup.clone(),
            peaks,
            modes_excited: excited.iter().map(|m| m.mode).collect(),
            modes_mostly_excited: mostly,
            modes_not_excited: slot
                .iter()
                .filter(|m| !m.eligible)
                .map(|m| m.mode)
                .collect(),
            modes: slot,
        });
    }
    summaries
}

/// The pool's mode × excitation matrices for the heat map.
pub(super) fn strength_matrix(
    p: &PoolInputs,
    mode_groups: &[ModeGroup],
    summaries: &[ExcitationSummary],
) -> StrengthMatrix {
    let n_modes = mode_groups.len();
    let by_mode = |value: &dyn Fn(&ModeExcitation) -> Option<f64>| -> Vec<Vec<Option<f64>>> {
        (0..n_modes)
            .map(|r| summaries.iter().map(|s| value(&s.modes[r])).collect())
            .collect()
    };
    StrengthMatrix {
        setup: p.pool.label.clone(),
        modes: mode_groups.iter().map(|g| g.mode).collect(),
        frequency_hz: mode_groups.iter().map(|g| g.frequency_hz).collect(),
        excitations: p
            .pool
            .excitations
            .iter()
            .map(|&k| p.excitation_id(k))
            .collect(),
        measured_db: by_mode(&|m| m.strength.and_then(db10)),
        predicted_db: by_mode(&|m| m.predicted_strength.and_then(db10)),
        ni_db: (0..n_modes)
            .map(|r| summaries.iter().map(|s| s.modes[r].ni_db).collect())
            .collect(),
    }
}
