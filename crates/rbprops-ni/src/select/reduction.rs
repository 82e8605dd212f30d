//! The rigid-body reduction of the modal estimates: each estimate's rigid motion
//! `q = (SᵀS)⁻¹SᵀA` (paper Eq. 5), its strength `f_kᵀq = (f_kᵀφ0)²` and whether it is reliable.

use super::{Member, Pool};
use crate::{diagnostic, NiError};
use rbprops_core::records::ModalFitRecord;
use rbprops_core::records::{Diagnostic, DiagnosticKind, DiagnosticSubject, Severity};
use rbprops_core::{real_modal_constants, Mat6, RigidBasis, Vec6};

/// Above this rigid-body residual an estimate gets a warning: its shape is far from
/// rigid motion (sensor error, flexibility, a spurious mode).
pub(super) const RIGID_RESIDUAL_WARNING: f64 = 0.1;

/// The rigid-body reduction of the estimates: the channel basis `S`, `(SᵀS)⁻¹` and the
/// excitation columns `f_k` (geometry order).
pub(super) struct RigidReduction<'a> {
    pub(super) basis: &'a RigidBasis,
    pub(super) gram_inv: &'a Mat6,
    pub(super) columns: &'a [Vec6],
}

impl RigidReduction<'_> {
    /// Reduces every estimate of the pool's excitations to its rigid motion
    /// `q = (SᵀS)⁻¹SᵀA` (paper Eq. 5) and its strength `f_kᵀq`, with the standard error of
    /// the strength propagated from the residue standard errors, and decides whether it is
    /// reliable (not weak, `f_kᵀq` > 0, at least `min_snr` standard errors). Warns of a
    /// shape far from rigid motion.
    pub(super) fn pool_members(
        &self,
        pool: &Pool,
        modal: &ModalFitRecord,
        estimate_excitations: &[usize],
        min_snr: f64,
        warnings: &mut Vec<Diagnostic>,
    ) -> Result<Vec<Member>, NiError> {
        let mut members = Vec::new();
        for (i, est) in modal.modes.iter().enumerate() {
            let k = estimate_excitations[i];
            if !pool.excitations.contains(&k) {
                continue;
            }
            let (re, phase) = real_modal_constants(&est.residues);
            let fit = self.basis.fit(&re)?;
            let f = &self.columns[k];
            let strength = f.dot(&fit.q);
            let strength_std = if est.residue_std.is_empty() {
                None
            } else {
                let ms = est.residue_std.iter().map(|s| s * s).sum::<f64>()
                    / est.residue_std.len() as f64;
                let var = ms * (f.transpose() * self.gram_inv * f)[0];
                (var > 0.0).then(|| var.sqrt())
            };
            let why = if est.weak {
                Some("modal-fit flagged it weak".to_string())
            } else if !(strength > 0.0) {
                Some(format!("fᵀq = {strength:.3e} ≤ 0: not excited"))
            } else {
                strength_std.filter(|sd| strength < min_snr * sd).map(|sd| {
                    format!("fᵀq = {strength:.3e} ± {sd:.1e} is below {min_snr} standard errors")
                })
            };
            if fit.relative_residual > RIGID_RESIDUAL_WARNING {
                // One excitation's estimate: the selection weighs its evidence, and the
                // rigid-body check is the calibrated alarm on what is used: a note.
                warnings.push(diagnostic(
                    DiagnosticKind::ShapeNotRigid,
                    Severity::Note,
                    DiagnosticSubject::setup(&est.setup)
                        .excitation(&est.excitation)
                        .mode(est.mode, est.frequency_hz),
                    format!(
                        "its shape is {:.0}% away from rigid-body motion",
                        100.0 * fit.relative_residual
                    ),
                ));
            }
            members.push(Member {
                estimate: i,
                excitation: k,
                q: fit.q,
                strength,
                strength_std,
                relative_residual: fit.relative_residual,
                phase,
                reliable: why.is_none(),
                why,
            });
        }
        Ok(members)
    }
}
