//! Records from another writer (or edited by hand) checked on read: a physically
//! impossible modal record or selection is an error naming the record (topic, index) and
//! the field, before any stage computes with it.

use anyhow::{bail, Result};
use rbprops_core::records::{ModalFitRecord, SelectionRecord};
use rbprops_formats::topics;

/// Checks the modal-fit record a later stage reads: the residue convention is the one
/// `modal-fit` writes; every mode has a finite frequency > 0, a damping ratio in [0, 1),
/// finite residues with as many standard errors (finite, ≥ 0) as residues, and as many
/// residues as the geometry has channels (`n_channels`).
pub fn modal_fit(m: &ModalFitRecord, n_channels: usize) -> Result<()> {
    let at = format!("topic {}, message 0", topics::MODAL_FIT);
    if m.residue_convention != rbprops_modal::RESIDUE_CONVENTION {
        bail!(
            "{at}: field residue_convention: unknown sign convention '{}' (expected the one modal-fit writes: '{}')",
            m.residue_convention,
            rbprops_modal::RESIDUE_CONVENTION
        );
    }
    for (i, e) in m.modes.iter().enumerate() {
        let at = format!(
            "{at}, modes[{i}] (excitation {}, mode {})",
            e.excitation, e.mode
        );
        if !(e.frequency_hz.is_finite() && e.frequency_hz > 0.0) {
            bail!(
                "{at}: field frequency_hz: {} (need a finite frequency > 0 Hz)",
                e.frequency_hz
            );
        }
        if !(e.frequency_std_hz.is_finite() && e.frequency_std_hz >= 0.0) {
            bail!(
                "{at}: field frequency_std_hz: {} (need finite, ≥ 0)",
                e.frequency_std_hz
            );
        }
        if !(e.damping_ratio.is_finite() && (0.0..1.0).contains(&e.damping_ratio)) {
            bail!(
                "{at}: field damping_ratio: {} (need 0 ≤ ζ < 1)",
                e.damping_ratio
            );
        }
        if !(e.damping_std.is_finite() && e.damping_std >= 0.0) {
            bail!(
                "{at}: field damping_std: {} (need finite, ≥ 0)",
                e.damping_std
            );
        }
        if e.residues.len() != n_channels {
            bail!(
                "{at}: field residues: {} values for the geometry's {n_channels} channels",
                e.residues.len()
            );
        }
        if e.residue_std.len() != e.residues.len() {
            bail!(
                "{at}: field residue_std: {} standard errors for {} residues",
                e.residue_std.len(),
                e.residues.len()
            );
        }
        if let Some(k) = e
            .residues
            .iter()
            .position(|r| !(r.re.is_finite() && r.im.is_finite()))
        {
            bail!("{at}: field residues[{k}]: not finite");
        }
        if let Some(k) = e
            .residue_std
            .iter()
            .position(|s| !(s.is_finite() && *s >= 0.0))
        {
            bail!(
                "{at}: field residue_std[{k}]: {} (need finite, ≥ 0)",
                e.residue_std[k]
            );
        }
    }
    Ok(())
}

/// Checks the selection record `rb-solve` reads: at least one selected mode, each with a
/// finite frequency > 0 and an excitation mode that exists in the modal fit.
pub fn selection(s: &SelectionRecord, m: &ModalFitRecord) -> Result<()> {
    let at = format!("topic {}, message 0", topics::SELECTION);
    if s.selected.is_empty() {
        bail!("{at}: field selected: empty (no mode was selected; see ni-select's warnings)");
    }
    for (i, x) in s.selected.iter().enumerate() {
        let at = format!("{at}, selected[{i}] (mode {})", x.mode);
        if !(x.frequency_hz.is_finite() && x.frequency_hz > 0.0) {
            bail!(
                "{at}: field frequency_hz: {} (need a finite frequency > 0 Hz)",
                x.frequency_hz
            );
        }
        if !m
            .modes
            .iter()
            .any(|e| e.excitation == x.excitation && e.mode == x.excitation_mode)
        {
            bail!(
                "{at}: fields excitation/excitation_mode: no mode {} of excitation '{}' in the modal fit",
                x.excitation_mode,
                x.excitation
            );
        }
    }
    Ok(())
}
