//! What is selected from: the estimates checked against the geometry, and the pools of
//! excitations processed together (set-ups, the manual set, forced mixing).

use super::{Pool, SelectOptions};
use crate::{diagnostic, NiError};
use rbprops_core::records::ModalFitRecord;
use rbprops_core::records::{Diagnostic, DiagnosticKind, DiagnosticSubject, Severity};
use rbprops_core::{FrfSource, Geometry};

/// Checks every estimate against the geometry; returns each one's excitation index.
pub(super) fn validate_estimates(
    geometry: &Geometry,
    frf: &dyn FrfSource,
    modal: &ModalFitRecord,
) -> Result<Vec<usize>, NiError> {
    let mut out = Vec::with_capacity(modal.modes.len());
    let mut seen = std::collections::BTreeSet::new();
    for est in &modal.modes {
        let bad = |message: String| NiError::BadEstimate {
            excitation: est.excitation.clone(),
            mode: est.mode,
            message,
        };
        let k = geometry
            .excitation_index(&est.excitation)
            .ok_or_else(|| bad("the geometry has no such excitation".into()))?;
        let setup = &geometry.excitations[k].setup;
        if &est.setup != setup {
            return Err(bad(format!(
                "the record puts it in set-up '{}', the geometry in '{setup}'",
                est.setup
            )));
        }
        if !seen.insert((k, est.mode)) {
            return Err(bad("appears twice in the modal record".into()));
        }
        if est.residues.len() != frf.n_channels() {
            return Err(bad(format!(
                "{} residues for {} channels",
                est.residues.len(),
                frf.n_channels()
            )));
        }
        if !(est.frequency_hz.is_finite() && est.frequency_hz > 0.0) {
            return Err(bad(format!(
                "frequency {} Hz is not positive",
                est.frequency_hz
            )));
        }
        if !(est.damping_ratio.is_finite() && est.damping_ratio >= 0.0) {
            return Err(bad(format!(
                "damping ratio {} is not a finite non-negative number",
                est.damping_ratio
            )));
        }
        if est
            .residues
            .iter()
            .any(|z| !(z.re.is_finite() && z.im.is_finite()))
        {
            return Err(bad("a residue is not finite".into()));
        }
        if !est.residue_std.is_empty()
            && (est.residue_std.len() != frf.n_channels()
                || est
                    .residue_std
                    .iter()
                    .any(|s| !(s.is_finite() && *s >= 0.0)))
        {
            return Err(bad(format!(
                "residue_std must be empty or {} finite non-negative values",
                frf.n_channels()
            )));
        }
        out.push(k);
    }
    Ok(out)
}

/// Which excitations are processed together, honouring `setup`, the manual set and
/// `force_mixed_setups`.
pub(super) fn plan_pools(
    geometry: &Geometry,
    opts: &SelectOptions,
) -> Result<(Vec<Pool>, Vec<Diagnostic>), NiError> {
    let mut warnings = Vec::new();
    let known = || {
        geometry
            .setups
            .iter()
            .map(|s| s.id.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut scope: Vec<String> = match &opts.setup {
        Some(s) => {
            if !geometry.setups.iter().any(|x| &x.id == s) {
                return Err(NiError::UnknownSetup {
                    setup: s.clone(),
                    known: known(),
                });
            }
            vec![s.clone()]
        }
        None => geometry
            .setups
            .iter()
            .filter(|s| geometry.excitations.iter().any(|e| e.setup == s.id))
            .map(|s| s.id.clone())
            .collect(),
    };
    if let Some(manual) = &opts.manual {
        let mut setups: Vec<(String, Vec<String>)> = Vec::new();
        for e in &manual.entries {
            let Some(k) = geometry.excitation_index(&e.excitation) else {
                return Err(NiError::Manual(format!(
                    "mode {} names excitation '{}', which the geometry does not define (known: {})",
                    e.mode,
                    e.excitation,
                    geometry
                        .excitations
                        .iter()
                        .map(|x| x.id.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                )));
            };
            let s = &geometry.excitations[k].setup;
            match setups.iter_mut().find(|(id, _)| id == s) {
                Some((_, list)) => list.push(e.excitation.clone()),
                None => setups.push((s.clone(), vec![e.excitation.clone()])),
            }
        }
        if let Some(only) = &opts.setup {
            if let Some((s, list)) = setups.iter().find(|(s, _)| s != only) {
                return Err(NiError::Manual(format!(
                    "excitation(s) {} belong to set-up '{s}', not to the requested set-up '{only}'",
                    list.join(", ")
                )));
            }
        }
        if setups.len() > 1 && !opts.force_mixed_setups {
            return Err(NiError::MixedSetups(format!(
                "the manual set takes modes from {}; a different suspension gives different modes",
                setups
                    .iter()
                    .map(|(s, l)| format!("set-up '{s}' ({})", l.join(", ")))
                    .collect::<Vec<_>>()
                    .join(" and ")
            )));
        }
        scope = setups.into_iter().map(|(s, _)| s).collect();
    }
    let excitations_of = |ids: &[String]| -> Vec<usize> {
        (0..geometry.excitations.len())
            .filter(|&k| ids.contains(&geometry.excitations[k].setup))
            .collect()
    };
    let pools = if opts.force_mixed_setups && scope.len() > 1 {
        let label = scope.join("+");
        warnings.push(diagnostic(
            DiagnosticKind::SetupsForced,
            Severity::Note,
            DiagnosticSubject::setup(&label),
            format!(
                "set-ups {} were forced together: their modes are matched as one suspension's",
                scope.join(", ")
            ),
        ));
        vec![Pool {
            label,
            excitations: excitations_of(&scope),
        }]
    } else {
        scope
            .iter()
            .map(|s| Pool {
                label: s.clone(),
                excitations: excitations_of(std::slice::from_ref(s)),
            })
            .collect()
    };
    Ok((pools, warnings))
}
