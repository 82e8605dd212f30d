//! Best-mode selection across excitations (the paper's Section 2 and Figs. 4/11–13).

mod choice;
mod options;
mod output;
mod pool;
mod reduction;
mod scope;
mod summary;

use crate::matching::{Candidate, MatchTolerances};
use crate::{diagnostic, NiError};
use choice::{check_manual_modes, choose, ranking};
pub use options::{Criterion, SelectOptions};
pub use output::{
    ExcitationCurves, ExcitationSummary, IndicatorCurves, ModeExcitation, ModeGroup, NiPeak,
    RejectedEstimate, SelectionOutput, StrengthMatrix,
};
use pool::{mode_half_width, process_pool};
use rbprops_core::records::{Diagnostic, DiagnosticKind, DiagnosticSubject, Severity};
use rbprops_core::records::{MissingMode, ModalFitRecord, SelectedMode, SelectionRecord};
use rbprops_core::{FrfSource, Geometry, Mat6, RigidBasis, Vec6};
use reduction::RigidReduction;
use scope::{plan_pools, validate_estimates};
use summary::{db10, excitation_curves, excitation_summaries, strength_matrix};

/// One identified mode with its rigid-body reduction.
struct Member {
    estimate: usize,
    excitation: usize,
    q: Vec6,
    strength: f64,
    strength_std: Option<f64>,
    relative_residual: f64,
    /// Rotation of the residues onto the real line (rad).
    phase: f64,
    reliable: bool,
    /// Why not reliable.
    why: Option<String>,
}

/// A set of excitations processed together: one set-up, or several when forced.
struct Pool {
    label: String,
    excitations: Vec<usize>,
}

/// The FRF set and the geometry agree on the numbers of excitations and channels.
fn check_dimensions(geometry: &Geometry, frf: &dyn FrfSource) -> Result<(), NiError> {
    if frf.n_excitations() != geometry.excitations.len() {
        return Err(NiError::Inconsistent(format!(
            "the FRF set has {} excitations, the geometry {}",
            frf.n_excitations(),
            geometry.excitations.len()
        )));
    }
    if frf.n_channels() != geometry.channels.len() {
        return Err(NiError::Inconsistent(format!(
            "the FRF set has {} channels, the geometry {}",
            frf.n_channels(),
            geometry.channels.len()
        )));
    }
    Ok(())
}

/// The indicator curves of every excitation in scope (pool order), and the position of
/// each excitation's curves among them (geometry order; `usize::MAX` out of scope). One
/// excitation's FRFs are asked for at a time: a source that reads them from the file
/// holds one excitation, not the set (issue 41).
fn indicator_curves(
    geometry: &Geometry,
    frf: &dyn FrfSource,
    pools: &[Pool],
    opts: &SelectOptions,
) -> Result<(IndicatorCurves, Vec<usize>), NiError> {
    let mut curves = IndicatorCurves {
        frequency_hz: frf.frequency_hz().to_vec(),
        quantity: frf.quantity(),
        excitations: Vec::new(),
    };
    let mut curve_of = vec![usize::MAX; geometry.excitations.len()];
    for k in pools.iter().flat_map(|p| p.excitations.iter().copied()) {
        curve_of[k] = curves.excitations.len();
        let x = frf.excitation(k)?;
        curves
            .excitations
            .push(excitation_curves(geometry, x.set(), x.index(), k, opts));
    }
    Ok((curves, curve_of))
}

/// Decides, for every physical mode, which excitation gives its best shape.
///
/// Steps: (1) validates the inputs against each other; (2) computes NI (Eq. 12), hybrid
/// MIF and PRF MIF of every excitation; (3) reduces every `ModeEstimate` to its rigid
/// motion `q = (SᵀS)⁻¹SᵀA` (Eq. 5) and its strength `f_kᵀq = (f_kᵀφ0)²`; (4) matches the
/// estimates of a set-up's excitations into physical modes by frequency and MAC
/// (see [`crate::matching`]); (5) for each mode ranks the excitations that excite it above
/// the noise by the criterion and selects the best, or follows the manual set; a mode no
/// excitation excites above the noise becomes a `MissingMode` naming the excitations tried
/// and why each failed, and the others are still selected.
pub fn select_modes(
    geometry: &Geometry,
    frf: &dyn FrfSource,
    modal: &ModalFitRecord,
    opts: &SelectOptions,
) -> Result<SelectionOutput, NiError> {
    opts.validate()?;
    geometry.validate()?;
    frf.validate()?;
    check_dimensions(geometry, frf)?;
    let rows = geometry.channel_matrix();
    let basis = RigidBasis::new(rows.clone())?;
    let gram: Mat6 = rows.iter().map(|r| r.transpose() * r).sum();
    let gram_inv = basis.gram_inverse();
    let columns: Vec<Vec6> = geometry.excitations.iter().map(|e| e.column()).collect();
    let estimate_excitations = validate_estimates(geometry, frf, modal)?;

    let (pools, mut warnings) = plan_pools(geometry, opts)?;

    let (curves, curve_of) = indicator_curves(geometry, frf, &pools, opts)?;

    let mut out = SelectionOutput {
        record: SelectionRecord::default(),
        excitation_summaries: Vec::new(),
        matches: Vec::new(),
        curves,
        strength_db: Vec::new(),
        criterion_disagreements: Vec::new(),
        rejected: Vec::new(),
    };
    let tol = MatchTolerances {
        mac_threshold: opts.mac_threshold,
        frequency_tolerance: opts.frequency_tolerance,
    };
    let mut any_modes = false;
    for pool in &pools {
        // (3) rigid-body reduction of the pool's estimates.
        let reduction = RigidReduction {
            basis: &basis,
            gram_inv: &gram_inv,
            columns: &columns,
        };
        let members = reduction.pool_members(
            pool,
            modal,
            &estimate_excitations,
            opts.min_snr,
            &mut warnings,
        )?;
        if members.is_empty() {
            if opts.setup.is_some() || opts.manual.is_some() {
                return Err(NiError::NoModes {
                    setup: pool.label.clone(),
                });
            }
            warnings.push(diagnostic(
                DiagnosticKind::NoModes,
                Severity::ChangesAnswer,
                DiagnosticSubject::setup(&pool.label),
                "no identified modes, nothing selected",
            ));
            continue;
        }
        any_modes = true;
        let result = process_pool(&PoolInputs {
            pool,
            geometry,
            frf,
            modal,
            opts,
            members: &members,
            columns: &columns,
            gram: &gram,
            tol: &tol,
            curves: &out.curves,
            curve_of: &curve_of,
        })?;
        out.record.selected.extend(result.selected);
        out.record.missing.extend(result.missing);
        warnings.extend(result.diagnostics);
        out.excitation_summaries.extend(result.summaries);
        out.matches.extend(result.groups);
        out.strength_db.push(result.matrix);
        out.criterion_disagreements.extend(result.disagreements);
        out.rejected.extend(result.rejected);
    }
    if !any_modes {
        return Err(NiError::NoModes {
            setup: pools
                .iter()
                .map(|p| p.label.as_str())
                .collect::<Vec<_>>()
                .join(", "),
        });
    }
    out.record.diagnostics = warnings;
    Ok(out)
}

struct PoolResult {
    rejected: Vec<RejectedEstimate>,
    selected: Vec<SelectedMode>,
    missing: Vec<MissingMode>,
    diagnostics: Vec<Diagnostic>,
    summaries: Vec<ExcitationSummary>,
    groups: Vec<ModeGroup>,
    matrix: StrengthMatrix,
    disagreements: Vec<String>,
}

/// What every stage of one pool reads: the pool, the inputs and the rigid-body reductions
/// of the pool's estimates.
struct PoolInputs<'a> {
    pool: &'a Pool,
    geometry: &'a Geometry,
    frf: &'a dyn FrfSource,
    modal: &'a ModalFitRecord,
    opts: &'a SelectOptions,
    members: &'a [Member],
    /// Excitation columns `f_k`, in geometry order.
    columns: &'a [Vec6],
    /// Gram matrix `SᵀS` of the channel rows: the MAC weight.
    gram: &'a Mat6,
    tol: &'a MatchTolerances,
    curves: &'a IndicatorCurves,
    /// Position of each excitation's curves in `curves` (geometry order).
    curve_of: &'a [usize],
}

impl PoolInputs<'_> {
    fn excitation_id(&self, k: usize) -> String {
        self.geometry.excitations[k].id.clone()
    }

    fn estimate(&self, m: &Member) -> &rbprops_core::records::ModeEstimate {
        &self.modal.modes[m.estimate]
    }

    fn curves_of(&self, k: usize) -> &ExcitationCurves {
        &self.curves.excitations[self.curve_of[k]]
    }
}

/// The pool's physical modes: the matcher's view of every member and the consolidated
/// groups (indices into the members, ascending frequency, one estimate per excitation).
struct PhysicalModes {
    cands: Vec<Candidate>,
    groups: Vec<Vec<usize>>,
    rejected: Vec<RejectedEstimate>,
}

/// What the criteria would choose at one mode (None: nothing eligible).
struct CriterionChoices {
    ni: Option<String>,
    hybrid_mif: Option<String>,
    prf_mif: Option<String>,
    strength: Option<String>,
}

/// What one pool's modes come to, filled mode by mode.
#[derive(Default)]
struct PoolChoices {
    selected: Vec<SelectedMode>,
    missing: Vec<MissingMode>,
    warnings: Vec<Diagnostic>,
    disagreements: Vec<String>,
}
