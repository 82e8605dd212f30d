//! Best-mode selection across excitations (the paper's Section 2 and Figs. 4/11–13).

use crate::consolidate::{consolidate, estimate_quality, Evidence, RIGID_BODY_MODES};
use crate::indicators::{
    hybrid_mif, local_spacing, norm_indicator, power_db, prf_mif_from, principal_responses,
    window_lines, DEFAULT_PRF_RANK_TOLERANCE,
};
use crate::manual::ManualSet;
use crate::matching::{mac, match_candidates, reference_member, Candidate, MatchTolerances};
use crate::peaks::find_peaks;
use crate::{diagnostic, NiError};
use rbprops_core::records::{Diagnostic, DiagnosticKind, DiagnosticSubject, Severity};
use rbprops_core::records::{
    MissingMode, ModalFitRecord, SelectedMode, SelectionCriterion, SelectionRecord,
};
use rbprops_core::{real_modal_constants, FrfSet, Geometry, Mat6, Quantity, RigidBasis, Vec6};
use serde::{Deserialize, Serialize};

/// Which indicator ranks the excitations at a mode.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum Criterion {
    /// Highest Norm Indicator at the mode (paper Eq. 12): the most excited mode.
    #[default]
    Ni,
    /// Deepest hybrid-MIF dip at the mode: the purest normal-mode response.
    HybridMif,
    /// Deepest PRF-MIF dip at the mode.
    PrfMif,
}

impl Criterion {
    /// The criterion names parsing accepts, for messages.
    pub const NAMES: &'static str = "ni, hybrid_mif, prf_mif";
    /// The name written in `SelectedMode::criterion`.
    pub fn name(self) -> &'static str {
        self.record_name().as_str()
    }

    /// The value written in `SelectedMode::criterion`.
    pub fn record_name(self) -> SelectionCriterion {
        match self {
            Criterion::Ni => SelectionCriterion::Ni,
            Criterion::HybridMif => SelectionCriterion::HybridMif,
            Criterion::PrfMif => SelectionCriterion::PrfMif,
        }
    }
}

impl std::str::FromStr for Criterion {
    type Err = NiError;
    fn from_str(s: &str) -> Result<Self, NiError> {
        match s.trim().to_ascii_lowercase().replace('-', "_").as_str() {
            "ni" | "norm_indicator" => Ok(Criterion::Ni),
            "hybrid_mif" | "hybrid" => Ok(Criterion::HybridMif),
            "prf_mif" | "prf" => Ok(Criterion::PrfMif),
            _ => Err(NiError::Options(format!(
                "unknown criterion '{s}' (expected one of: {})",
                Criterion::NAMES
            ))),
        }
    }
}

/// Options of [`select_modes`]. `Default` gives the documented defaults.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct SelectOptions {
    /// Ranking criterion (default NI).
    pub criterion: Criterion,
    /// A manual set overrides the criterion (it is still compared with NI's choice).
    pub manual: Option<ManualSet>,
    /// Match and select across suspension set-ups as if they were one (default false:
    /// each set-up is processed on its own and a manual set spanning set-ups is refused).
    pub force_mixed_setups: bool,
    /// Process only this set-up (default: every set-up of the geometry).
    pub setup: Option<String>,
    /// Least MAC for two well-excited estimates to be the same mode (default 0.8).
    pub mac_threshold: f64,
    /// Largest relative frequency difference of one mode across excitations (default 0.05).
    pub frequency_tolerance: f64,
    /// An estimate counts as excited "above the noise" only if its strength `f_kᵀq` is at
    /// most this many dB below the strongest (mode, excitation) of the set-up (default 40).
    pub min_strength_db: f64,
    /// … and its strength is at least this many standard errors (propagated from the
    /// residue standard errors) above zero (default 3). Ignored when no residue_std is given.
    pub min_snr: f64,
    /// An excitation "excites mostly" the modes within this many dB of its own strongest
    /// mode (default 20), the paper's "F0x excites mostly modes 1, 4 and 6".
    pub mostly_db: f64,
    /// Least prominence of an NI peak to be reported (default 3 dB).
    pub peak_prominence_db: f64,
    /// Relative singular-value threshold of the PRFs kept in the PRF MIF (default 1e-4).
    pub prf_rank_tolerance: f64,
    /// An estimate whose modal-fit confidence is below this (default 0.5) is used for a
    /// mode only when no excitation gives an eligible estimate at or above it: a split
    /// pole's halves share the true residue and have low confidence.
    #[serde(default = "default_min_confidence")]
    pub min_confidence: f64,
}

fn default_min_confidence() -> f64 {
    0.5
}

impl Default for SelectOptions {
    fn default() -> Self {
        Self {
            criterion: Criterion::Ni,
            manual: None,
            force_mixed_setups: false,
            setup: None,
            mac_threshold: 0.8,
            frequency_tolerance: 0.05,
            min_strength_db: 40.0,
            min_snr: 3.0,
            mostly_db: 20.0,
            peak_prominence_db: 3.0,
            prf_rank_tolerance: DEFAULT_PRF_RANK_TOLERANCE,
            min_confidence: default_min_confidence(),
        }
    }
}

impl SelectOptions {
    fn validate(&self) -> Result<(), NiError> {
        let check = |name: &str, v: f64, lo: f64, hi: f64| {
            if !(v >= lo && v <= hi) {
                Err(NiError::Options(format!(
                    "{name} = {v} is outside [{lo}, {hi}]"
                )))
            } else {
                Ok(())
            }
        };
        check("mac_threshold", self.mac_threshold, 0.0, 1.0)?;
        check("frequency_tolerance", self.frequency_tolerance, 1e-9, 1.0)?;
        check("min_strength_db", self.min_strength_db, 0.0, 1000.0)?;
        check("min_snr", self.min_snr, 0.0, 1e12)?;
        check("mostly_db", self.mostly_db, 0.0, 1000.0)?;
        check("peak_prominence_db", self.peak_prominence_db, 0.0, 1000.0)?;
        check("prf_rank_tolerance", self.prf_rank_tolerance, 0.0, 1.0)?;
        check("min_confidence", self.min_confidence, 0.0, 1.0)
    }
}

/// How one excitation does at one physical mode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ModeExcitation {
    /// 1-based physical mode number within the set-up.
    #[schemars(description = "")]
    pub mode: usize,
    /// Natural frequency of the mode's reference estimate (Hz).
    #[schemars(description = "")]
    pub frequency_hz: f64,
    /// The excitation this row is about.
    #[schemars(description = "")]
    pub excitation: String,
    /// Its mode number in `modal-fit`'s output, when it identified this mode.
    pub excitation_mode: Option<usize>,
    /// `modal-fit` flagged the estimate weak.
    pub weak: bool,
    /// Highest NI within the mode's half-power band (dB).
    pub ni_db: f64,
    /// Lowest hybrid MIF / PRF MIF within the same band (0 = pure normal-mode response).
    pub hybrid_mif: f64,
    /// Lowest PRF MIF within the band (0 = pure normal-mode response).
    #[schemars(description = "")]
    pub prf_mif: f64,
    /// Measured strength `f_kᵀq` (1/kg) of its own estimate, and its standard error
    /// (None without residue standard errors).
    pub strength: Option<f64>,
    /// Standard error of `strength` (1/kg).
    #[schemars(description = "")]
    pub strength_std: Option<f64>,
    /// `10 log10(f_kᵀq)` (dB re 1/kg) when positive.
    pub strength_db: Option<f64>,
    /// `(f_kᵀφ_ref)²` with `φ_ref` the mode's mass-normalised reference shape (from its
    /// best estimate): what this excitation should put into the mode, identified or not.
    pub predicted_strength: Option<f64>,
    /// Rigid-body residual `‖A − Sq‖/‖A‖` of its estimate.
    pub rigid_residual: Option<f64>,
    /// MAC of its estimate with the reference shape.
    pub mac_to_reference: Option<f64>,
    /// modal-fit's confidence in its estimate.
    pub confidence: Option<f64>,
    /// Estimate quality `confidence · cos²α · 1/(1 + (r/0.1)²)`
    /// ([`crate::estimate_quality`]).
    pub quality: Option<f64>,
    /// Usable for the selection (identified, not weak, above the noise).
    pub eligible: bool,
    /// Why it is not eligible.
    pub reason: Option<String>,
}

/// One physical mode of a set-up: its estimates across excitations and their ranking.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ModeGroup {
    /// The suspension set-up the mode belongs to.
    #[schemars(description = "")]
    pub setup: String,
    /// 1-based, ascending frequency within the set-up.
    pub mode: usize,
    /// Natural frequency of the reference estimate (Hz).
    #[schemars(description = "")]
    pub frequency_hz: f64,
    /// Damping ratio of the reference estimate (fraction of critical).
    #[schemars(description = "")]
    pub damping_ratio: f64,
    /// Excitation whose estimate gives the reference shape.
    pub reference_excitation: String,
    /// Every excitation of the set-up: eligible ones first in the order of the criterion
    /// used, then the others by NI.
    pub ranking: Vec<ModeExcitation>,
    /// The choice each criterion would make (None: nothing eligible).
    pub choice_ni: Option<String>,
    /// The hybrid MIF's choice (deepest dip).
    #[schemars(description = "")]
    pub choice_hybrid_mif: Option<String>,
    /// The PRF MIF's choice (deepest dip).
    #[schemars(description = "")]
    pub choice_prf_mif: Option<String>,
    /// Largest measured strength `f_kᵀq`.
    pub choice_strength: Option<String>,
}

/// An NI peak.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct NiPeak {
    /// Frequency of the peak's line (Hz).
    #[schemars(description = "")]
    pub frequency_hz: f64,
    /// NI at the peak (dB).
    #[schemars(description = "")]
    pub level_db: f64,
    /// Topographic prominence of the peak (dB).
    #[schemars(description = "")]
    pub prominence_db: f64,
    /// The physical mode it belongs to, if any.
    pub mode: Option<usize>,
}

/// What the NI and the identified modes say about one excitation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ExcitationSummary {
    /// The excitation.
    #[schemars(description = "")]
    pub excitation: String,
    /// Its suspension set-up.
    #[schemars(description = "")]
    pub setup: String,
    /// NI peaks with at least the requested prominence, no more than `min_strength_db`
    /// below the excitation's highest NI.
    pub peaks: Vec<NiPeak>,
    /// Physical modes it excites above the noise (eligible).
    pub modes_excited: Vec<usize>,
    /// The subset within `mostly_db` of its strongest mode (the paper's "mostly").
    pub modes_mostly_excited: Vec<usize>,
    /// Modes of the set-up it does not excite above the noise.
    pub modes_not_excited: Vec<usize>,
    /// Per physical mode of the set-up.
    pub modes: Vec<ModeExcitation>,
}

/// Indicator curves of one excitation over the frequency axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ExcitationCurves {
    /// The excitation.
    #[schemars(description = "")]
    pub excitation: String,
    /// Its suspension set-up.
    #[schemars(description = "")]
    pub setup: String,
    /// Norm Indicator per line in dB (paper Eq. 12).
    #[schemars(description = "")]
    pub ni_db: Vec<f64>,
    /// Hybrid MIF per line (Rades 1994), in [0, 1].
    #[schemars(description = "")]
    pub hybrid_mif: Vec<f64>,
    /// PRF MIF per line (Rades & Ewins 2000), in [0, 1].
    #[schemars(description = "")]
    pub prf_mif: Vec<f64>,
    /// Singular values of the principal responses (descending) and how many are kept.
    pub prf_singular_values: Vec<f64>,
    /// Number of principal responses kept.
    #[schemars(description = "")]
    pub prf_rank: usize,
    /// `20 log10 |PRF_j(ω)|` of the kept principal response functions.
    pub prf_db: Vec<Vec<f64>>,
}

/// Plot data: the NI (Figs. 4/11), hybrid MIF (Fig. 12) and PRF MIF (Fig. 13) curves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct IndicatorCurves {
    /// Frequency of every line (Hz), shared by all curves.
    #[schemars(description = "")]
    pub frequency_hz: Vec<f64>,
    /// Receptance, mobility or accelerance: the FRFs the curves come from.
    #[schemars(description = "")]
    pub quantity: Quantity,
    /// One set of curves per excitation, in geometry order.
    #[schemars(description = "")]
    pub excitations: Vec<ExcitationCurves>,
}

/// Mode × excitation matrices of one set-up, for a heat map. Indexed `[mode][excitation]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct StrengthMatrix {
    /// The suspension set-up.
    #[schemars(description = "")]
    pub setup: String,
    /// Physical mode numbers, one per row.
    #[schemars(description = "")]
    pub modes: Vec<usize>,
    /// Natural frequency of each mode (Hz).
    #[schemars(description = "")]
    pub frequency_hz: Vec<f64>,
    /// Excitation ids, one per column.
    #[schemars(description = "")]
    pub excitations: Vec<String>,
    /// `10 log10(f_kᵀq)` of the excitation's own estimate (None: not identified or ≤ 0).
    pub measured_db: Vec<Vec<Option<f64>>>,
    /// `10 log10((f_kᵀφ_ref)²)` from the reference shape (None: not excited at all).
    pub predicted_db: Vec<Vec<Option<f64>>>,
    /// NI at the mode (dB).
    pub ni_db: Vec<Vec<f64>>,
}

/// Everything [`select_modes`] finds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct SelectionOutput {
    /// The selected set with provenance, the missing modes and warnings.
    pub record: SelectionRecord,
    /// NI peaks and excited modes per excitation.
    #[schemars(description = "")]
    pub excitation_summaries: Vec<ExcitationSummary>,
    /// The matched physical modes, set-up by set-up.
    pub matches: Vec<ModeGroup>,
    /// The indicator curves for plots.
    #[schemars(description = "")]
    pub curves: IndicatorCurves,
    /// One matrix per processed set-up.
    pub strength_db: Vec<StrengthMatrix>,
    /// Modes where NI, hybrid MIF, PRF MIF, the strength ranking (or the manual set)
    /// choose different excitations.
    pub criterion_disagreements: Vec<String>,
    /// Estimates left out of the physical modes (split poles, copies of a neighbour's
    /// shape, candidates beyond the six rigid-body modes), each with its reason.
    pub rejected: Vec<RejectedEstimate>,
}

/// An estimate of the modal record that is not part of any physical mode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct RejectedEstimate {
    /// The suspension set-up.
    #[schemars(description = "")]
    pub setup: String,
    /// The excitation whose modal record holds it.
    #[schemars(description = "")]
    pub excitation: String,
    /// Its mode number in `modal-fit`'s output.
    pub excitation_mode: usize,
    /// Its natural frequency (Hz).
    #[schemars(description = "")]
    pub frequency_hz: f64,
    /// Frequency of the candidate mode it was matched into.
    pub group_frequency_hz: f64,
    /// Why it was left out.
    #[schemars(description = "")]
    pub reason: String,
}

/// Above this rigid-body residual an estimate gets a warning: its shape is far from
/// rigid motion (sensor error, flexibility, a spurious mode).
const RIGID_RESIDUAL_WARNING: f64 = 0.1;

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
    frf: &FrfSet,
    modal: &ModalFitRecord,
    opts: &SelectOptions,
) -> Result<SelectionOutput, NiError> {
    opts.validate()?;
    geometry.validate()?;
    frf.validate()?;
    if frf.n_excitations != geometry.excitations.len() {
        return Err(NiError::Inconsistent(format!(
            "the FRF set has {} excitations, the geometry {}",
            frf.n_excitations,
            geometry.excitations.len()
        )));
    }
    if frf.n_channels != geometry.channels.len() {
        return Err(NiError::Inconsistent(format!(
            "the FRF set has {} channels, the geometry {}",
            frf.n_channels,
            geometry.channels.len()
        )));
    }
    let rows = geometry.channel_matrix();
    let basis = RigidBasis::new(rows.clone())?;
    let gram: Mat6 = rows.iter().map(|r| r.transpose() * r).sum();
    let gram_inv = basis.gram_inverse();
    let columns: Vec<Vec6> = geometry.excitations.iter().map(|e| e.column()).collect();
    let estimate_excitations = validate_estimates(geometry, frf, modal)?;

    let (pools, mut warnings) = plan_pools(geometry, opts)?;

    // Indicator curves of every excitation in scope.
    let in_scope: Vec<usize> = pools.iter().flat_map(|p| p.excitations.clone()).collect();
    let mut curves = IndicatorCurves {
        frequency_hz: frf.frequency_hz.clone(),
        quantity: frf.quantity,
        excitations: Vec::new(),
    };
    let mut curve_of = vec![usize::MAX; geometry.excitations.len()];
    for &k in &in_scope {
        curve_of[k] = curves.excitations.len();
        curves
            .excitations
            .push(excitation_curves(geometry, frf, k, opts));
    }

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

/// The rigid-body reduction of the estimates: the channel basis `S`, `(SᵀS)⁻¹` and the
/// excitation columns `f_k` (geometry order).
struct RigidReduction<'a> {
    basis: &'a RigidBasis,
    gram_inv: &'a Mat6,
    columns: &'a [Vec6],
}

impl RigidReduction<'_> {
    /// Reduces every estimate of the pool's excitations to its rigid motion
    /// `q = (SᵀS)⁻¹SᵀA` (paper Eq. 5) and its strength `f_kᵀq`, with the standard error of
    /// the strength propagated from the residue standard errors, and decides whether it is
    /// reliable (not weak, `f_kᵀq` > 0, at least `min_snr` standard errors). Warns of a
    /// shape far from rigid motion.
    fn pool_members(
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

/// Checks every estimate against the geometry; returns each one's excitation index.
fn validate_estimates(
    geometry: &Geometry,
    frf: &FrfSet,
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
        if est.residues.len() != frf.n_channels {
            return Err(bad(format!(
                "{} residues for {} channels",
                est.residues.len(),
                frf.n_channels
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
            && (est.residue_std.len() != frf.n_channels
                || est
                    .residue_std
                    .iter()
                    .any(|s| !(s.is_finite() && *s >= 0.0)))
        {
            return Err(bad(format!(
                "residue_std must be empty or {} finite non-negative values",
                frf.n_channels
            )));
        }
        out.push(k);
    }
    Ok(out)
}

/// Which excitations are processed together, honouring `setup`, the manual set and
/// `force_mixed_setups`.
fn plan_pools(
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

fn excitation_curves(
    geometry: &Geometry,
    frf: &FrfSet,
    k: usize,
    opts: &SelectOptions,
) -> ExcitationCurves {
    let prf = principal_responses(frf, k);
    let rank = prf.rank(opts.prf_rank_tolerance);
    ExcitationCurves {
        excitation: geometry.excitations[k].id.clone(),
        setup: geometry.excitations[k].setup.clone(),
        ni_db: norm_indicator(frf, k),
        hybrid_mif: hybrid_mif(frf, k),
        prf_mif: prf_mif_from(frf, &prf, opts.prf_rank_tolerance),
        prf_db: prf.responses[..rank]
            .iter()
            .map(|p| p.iter().map(|h| power_db(h.norm_sqr())).collect())
            .collect(),
        prf_singular_values: prf.singular_values,
        prf_rank: rank,
    }
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

fn db10(x: f64) -> Option<f64> {
    (x > 0.0 && x.is_finite()).then(|| 10.0 * x.log10())
}

/// Index of the best entry by `key` (larger is better) among `items`; ties go to the
/// higher NI, then to geometry order.
fn best_by(items: &[&ModeExcitation], key: impl Fn(&ModeExcitation) -> f64) -> Option<usize> {
    (0..items.len()).max_by(|&a, &b| {
        key(items[a])
            .total_cmp(&key(items[b]))
            .then(items[a].ni_db.total_cmp(&items[b].ni_db))
            .then(b.cmp(&a))
    })
}

fn criterion_key(c: Criterion) -> impl Fn(&ModeExcitation) -> f64 {
    move |m: &ModeExcitation| match c {
        Criterion::Ni => m.ni_db,
        Criterion::HybridMif => -m.hybrid_mif,
        Criterion::PrfMif => -m.prf_mif,
    }
}

/// What every stage of one pool reads: the pool, the inputs and the rigid-body reductions
/// of the pool's estimates.
struct PoolInputs<'a> {
    pool: &'a Pool,
    geometry: &'a Geometry,
    frf: &'a FrfSet,
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

/// Processes one pool: (1) pool building and matching, (2) consolidation into at most six
/// physical modes ([`physical_modes`]); then for each mode (3) the excitation table with
/// eligibility ([`mode_table`]) and (4) the choice ([`choose`]); finally the
/// per-excitation summaries and the strength matrix.
fn process_pool(p: &PoolInputs) -> Result<PoolResult, NiError> {
    let mut warnings = Vec::new();
    let modes = physical_modes(p, &mut warnings);
    let floor_db = noise_floor_db(p, &modes.groups);
    let mut mode_groups = Vec::with_capacity(modes.groups.len());
    let mut choices = PoolChoices::default();
    let mut per_excitation: Vec<Vec<ModeExcitation>> = vec![Vec::new(); p.pool.excitations.len()];
    for (gi, group) in modes.groups.iter().enumerate() {
        let mode = gi + 1;
        let rm = &p.members[reference_member(group, &modes.cands)];
        let table = mode_table(p, mode, group, rm, floor_db);
        let by = CriterionChoices::of(&table);
        let g = ModeGroup {
            setup: p.pool.label.clone(),
            mode,
            frequency_hz: p.estimate(rm).frequency_hz,
            damping_ratio: p.estimate(rm).damping_ratio,
            reference_excitation: p.excitation_id(rm.excitation),
            ranking: ranking(&table, p.opts.criterion),
            choice_ni: by.ni.clone(),
            choice_hybrid_mif: by.hybrid_mif.clone(),
            choice_prf_mif: by.prf_mif.clone(),
            choice_strength: by.strength.clone(),
        };
        if let Some(d) = by.disagreement(&p.pool.label, mode, g.frequency_hz) {
            choices.disagreements.push(d);
        }
        choose(p, &g, group, &table, &by, &mut choices)?;
        for (slot, row) in per_excitation.iter_mut().zip(&table) {
            slot.push(row.clone());
        }
        mode_groups.push(g);
    }
    check_manual_modes(p, mode_groups.len())?;
    warnings.append(&mut choices.warnings);
    let summaries = excitation_summaries(p, per_excitation, &mode_groups, &mut warnings);
    let matrix = strength_matrix(p, &mode_groups, &summaries);
    Ok(PoolResult {
        rejected: modes.rejected,
        selected: choices.selected,
        missing: choices.missing,
        diagnostics: warnings,
        summaries,
        groups: mode_groups,
        matrix,
        disagreements: choices.disagreements,
    })
}

/// Pool building, matching and consolidation: the members become matcher candidates,
/// are matched across excitations by frequency and MAC ([`match_candidates`]) and
/// consolidated into at most six rigid-body modes ([`consolidate`]). Warns when more than
/// six or fewer than six modes come out.
fn physical_modes(p: &PoolInputs, warnings: &mut Vec<Diagnostic>) -> PhysicalModes {
    let cands: Vec<Candidate> = p
        .members
        .iter()
        .map(|m| Candidate {
            excitation: m.excitation,
            frequency_hz: p.estimate(m).frequency_hz,
            q: m.q,
            strength: m.strength,
            reliable: m.reliable,
        })
        .collect();
    let evidence: Vec<Evidence> = p
        .members
        .iter()
        .map(|m| {
            let est = p.estimate(m);
            Evidence {
                label: format!(
                    "{} mode {} ({:.4} Hz)",
                    est.excitation, est.mode, est.frequency_hz
                ),
                confidence: est.confidence,
                phase: m.phase,
                rigid_residual: m.relative_residual,
                weak: est.weak,
                quality: estimate_quality(est.confidence, m.phase, m.relative_residual),
            }
        })
        .collect();
    let matched = match_candidates(&cands, p.gram, p.tol);
    let n_matched = matched.len();
    let consolidated = consolidate(matched, &cands, &evidence, p.gram, p.tol, &p.pool.label);
    let n_modes = consolidated.groups.len();
    if n_matched > RIGID_BODY_MODES {
        // The surplus is set aside by evidence (each rejection its own note): a note.
        warnings.push(diagnostic(
            DiagnosticKind::ExtraModes,
            Severity::Note,
            DiagnosticSubject::setup(&p.pool.label),
            format!(
                "{n_matched} distinct modes matched, more than the six rigid-body modes \
                 (split, leakage, noise or elastic poles in the modal record); {n_modes} kept"
            ),
        ));
    }
    warnings.extend(consolidated.diagnostics);
    let rejected = consolidated
        .rejected
        .iter()
        .map(|r| {
            let est = p.estimate(&p.members[r.candidate]);
            RejectedEstimate {
                setup: p.pool.label.clone(),
                excitation: est.excitation.clone(),
                excitation_mode: est.mode,
                frequency_hz: est.frequency_hz,
                group_frequency_hz: r.group_frequency_hz,
                reason: r.reason.clone(),
            }
        })
        .collect();
    if n_modes < RIGID_BODY_MODES {
        warnings.push(diagnostic(
            DiagnosticKind::ModeMissing,
            Severity::ChangesAnswer,
            DiagnosticSubject::setup(&p.pool.label),
            format!("only {n_modes} of the six rigid-body modes were identified by any excitation"),
        ));
    }
    PhysicalModes {
        cands,
        groups: consolidated.groups,
        rejected,
    }
}

/// The set-up's noise floor: `min_strength_db` below its strongest reliable estimate kept
/// in a mode (dB re 1/kg). Rejected estimates (a split pole's halves can be "stronger" than
/// the mode) do not set it.
fn noise_floor_db(p: &PoolInputs, groups: &[Vec<usize>]) -> Option<f64> {
    let strongest = groups
        .iter()
        .flatten()
        .map(|&i| &p.members[i])
        .filter(|m| m.reliable)
        .map(|m| m.strength)
        .fold(0.0f64, f64::max);
    db10(strongest).map(|d| d - p.opts.min_strength_db)
}

/// Half-width of a mode's band on the frequency axis: its half-power half-width `2ζf_r`,
/// but at least 1.5 line spacings (`spacing`, the local line spacing) so that a lightly
/// damped mode still spans a line.
fn mode_half_width(f_r: f64, zeta: f64, spacing: f64) -> f64 {
    (2.0 * zeta * f_r).max(1.5 * spacing)
}

/// How every excitation of the pool does at one physical mode (`group`, with reference
/// member `rm`): the indicators within the mode's band, its own estimate's strength and
/// quality, and whether it is eligible (identified, reliable, above the noise floor, and
/// confident when another excitation is).
fn mode_table(
    p: &PoolInputs,
    mode: usize,
    group: &[usize],
    rm: &Member,
    floor_db: Option<f64>,
) -> Vec<ModeExcitation> {
    let rest = p.estimate(rm);
    let (f_r, zeta) = (rest.frequency_hz, rest.damping_ratio);
    let phi_ref = (rm.strength > 0.0).then(|| rm.q / rm.strength.sqrt());
    let half_width = mode_half_width(f_r, zeta, local_spacing(&p.frf.frequency_hz, f_r));
    let lines = window_lines(&p.frf.frequency_hz, f_r, half_width);
    let mut table: Vec<ModeExcitation> = Vec::with_capacity(p.pool.excitations.len());
    for &k in &p.pool.excitations {
        let c = p.curves_of(k);
        let mut row = ModeExcitation {
            mode,
            frequency_hz: f_r,
            excitation: p.excitation_id(k),
            excitation_mode: None,
            weak: false,
            ni_db: c.ni_db[lines.clone()]
                .iter()
                .copied()
                .fold(f64::NEG_INFINITY, f64::max),
            hybrid_mif: c.hybrid_mif[lines.clone()]
                .iter()
                .copied()
                .fold(f64::INFINITY, f64::min),
            prf_mif: c.prf_mif[lines.clone()]
                .iter()
                .copied()
                .fold(f64::INFINITY, f64::min),
            strength: None,
            strength_std: None,
            strength_db: None,
            predicted_strength: phi_ref.map(|phi| p.columns[k].dot(&phi).powi(2)),
            rigid_residual: None,
            mac_to_reference: None,
            confidence: None,
            quality: None,
            eligible: false,
            reason: None,
        };
        let member = group
            .iter()
            .map(|&i| &p.members[i])
            .find(|m| m.excitation == k);
        match member {
            None => row.reason = Some(format!("no mode identified near {f_r:.4} Hz")),
            Some(m) => describe_estimate(p, &mut row, m, rm, floor_db),
        }
        table.push(row);
    }
    demote_low_confidence(&mut table, p.opts.min_confidence);
    table
}

/// Fills `row` from the excitation's own estimate `m` of the mode and decides its
/// eligibility: reliable (not weak, `f_kᵀq` > 0 and above `min_snr` standard errors) and
/// no more than `min_strength_db` below the set-up's strongest.
fn describe_estimate(
    p: &PoolInputs,
    row: &mut ModeExcitation,
    m: &Member,
    rm: &Member,
    floor_db: Option<f64>,
) {
    let est = p.estimate(m);
    row.excitation_mode = Some(est.mode);
    row.weak = est.weak;
    row.strength = Some(m.strength);
    row.strength_std = m.strength_std;
    row.strength_db = db10(m.strength);
    row.rigid_residual = Some(m.relative_residual);
    row.mac_to_reference = Some(mac(&m.q, &rm.q, p.gram));
    row.confidence = Some(est.confidence);
    row.quality = Some(estimate_quality(
        est.confidence,
        m.phase,
        m.relative_residual,
    ));
    row.reason = m.why.clone();
    if row.reason.is_none() {
        if let (Some(s_db), Some(floor)) = (row.strength_db, floor_db) {
            if s_db < floor {
                row.reason = Some(format!(
                    "fᵀq = {:.3e} is {:.1} dB below the set-up's strongest (limit {} dB)",
                    m.strength,
                    floor + p.opts.min_strength_db - s_db,
                    p.opts.min_strength_db
                ));
            }
        }
    }
    row.eligible = row.reason.is_none();
}

/// A low-confidence estimate (typically half of a split pole) gives way to any confident
/// one of the same mode: when some eligible row has confidence ≥ `min_confidence`, the
/// eligible rows below it become ineligible.
fn demote_low_confidence(table: &mut [ModeExcitation], min_confidence: f64) {
    if table
        .iter()
        .any(|r| r.eligible && r.confidence.is_some_and(|c| c >= min_confidence))
    {
        for row in table.iter_mut().filter(|r| r.eligible) {
            if let Some(c) = row.confidence.filter(|&c| c < min_confidence) {
                row.eligible = false;
                row.reason = Some(format!(
                    "modal-fit confidence {c:.2} is below {min_confidence} and another excitation \
                     gives a confident estimate of this mode"
                ));
            }
        }
    }
}

impl CriterionChoices {
    /// The best eligible excitation of `table` by each criterion and by strength.
    fn of(table: &[ModeExcitation]) -> Self {
        let eligible: Vec<&ModeExcitation> = table.iter().filter(|m| m.eligible).collect();
        let pick = |c: Criterion| {
            best_by(&eligible, criterion_key(c)).map(|i| eligible[i].excitation.clone())
        };
        Self {
            ni: pick(Criterion::Ni),
            hybrid_mif: pick(Criterion::HybridMif),
            prf_mif: pick(Criterion::PrfMif),
            strength: best_by(&eligible, |m| m.strength.unwrap_or(0.0))
                .map(|i| eligible[i].excitation.clone()),
        }
    }

    fn of_criterion(&self, c: Criterion) -> Option<String> {
        match c {
            Criterion::Ni => self.ni.clone(),
            Criterion::HybridMif => self.hybrid_mif.clone(),
            Criterion::PrfMif => self.prf_mif.clone(),
        }
    }

    /// A message when the criteria (and the strength ranking) do not all agree.
    fn disagreement(&self, setup: &str, mode: usize, f_r: f64) -> Option<String> {
        let choices = [&self.ni, &self.hybrid_mif, &self.prf_mif, &self.strength];
        choices.iter().any(|c| *c != choices[0]).then(|| {
            format!(
                "set-up '{setup}' mode {mode} ({f_r:.4} Hz): NI picks {}, hybrid MIF {}, PRF MIF {}, strength fᵀq {}",
                describe_choice(&self.ni),
                describe_choice(&self.hybrid_mif),
                describe_choice(&self.prf_mif),
                describe_choice(&self.strength)
            )
        })
    }
}

fn describe_choice(c: &Option<String>) -> String {
    c.clone().unwrap_or_else(|| "none".into())
}

/// The table ordered for the report: eligible rows first, in the order of `criterion`;
/// then the others by NI.
fn ranking(table: &[ModeExcitation], criterion: Criterion) -> Vec<ModeExcitation> {
    let key = criterion_key(criterion);
    let mut ranking = table.to_vec();
    ranking.sort_by(|a, b| {
        b.eligible
            .cmp(&a.eligible)
            .then_with(|| {
                if a.eligible {
                    key(b).total_cmp(&key(a))
                } else {
                    std::cmp::Ordering::Equal
                }
            })
            .then(b.ni_db.total_cmp(&a.ni_db))
    });
    ranking
}

/// The choice at mode `g`: the manual set's excitation when one is given, otherwise the
/// criterion's. Records the selected mode (with its runner-up and margin) or a
/// `MissingMode` naming every excitation tried and why it failed.
fn choose(
    p: &PoolInputs,
    g: &ModeGroup,
    group: &[usize],
    table: &[ModeExcitation],
    by: &CriterionChoices,
    out: &mut PoolChoices,
) -> Result<(), NiError> {
    let (label, mode, f_r) = (&p.pool.label, g.mode, g.frequency_hz);
    let manual_choice = p
        .opts
        .manual
        .as_ref()
        .map(|m| m.excitation_for(mode).map(str::to_string));
    let (chosen, criterion): (Option<String>, SelectionCriterion) = match &manual_choice {
        Some(Some(ex)) => (Some(ex.clone()), SelectionCriterion::Manual),
        Some(None) => (None, SelectionCriterion::Manual),
        None => (
            by.of_criterion(p.opts.criterion),
            p.opts.criterion.record_name(),
        ),
    };
    match (&manual_choice, chosen) {
        (Some(None), _) => out.warnings.push(diagnostic(
            DiagnosticKind::ManualSelection,
            Severity::ChangesAnswer,
            DiagnosticSubject::setup(label).mode(mode, f_r),
            "not in the manual set: not selected",
        )),
        (Some(Some(ex)), _) if !table.iter().any(|m| &m.excitation == ex) => {
            return Err(NiError::Manual(format!(
                "mode {mode}: excitation '{ex}' is not in set-up '{label}'"
            )));
        }
        (Some(Some(ex)), _)
            if table
                .iter()
                .any(|m| &m.excitation == ex && m.excitation_mode.is_none()) =>
        {
            out.missing.push(MissingMode {
                setup: label.clone(),
                mode,
                frequency_hz: f_r,
                tried: vec![ex.clone()],
                reason: format!(
                    "the manual set takes mode {mode} ({f_r:.4} Hz) from '{ex}', which did not identify it"
                ),
            });
        }
        (_, None) => {
            let why_each = table
                .iter()
                .map(|m| {
                    format!(
                        "{}: {}",
                        m.excitation,
                        m.reason.as_deref().unwrap_or("eligible")
                    )
                })
                .collect::<Vec<_>>()
                .join("; ");
            out.missing.push(MissingMode {
                setup: label.clone(),
                mode,
                frequency_hz: f_r,
                tried: table.iter().map(|m| m.excitation.clone()).collect(),
                reason: format!(
                    "mode {mode} ({f_r:.4} Hz) is not excited above the noise by any excitation of set-up '{label}': {why_each}"
                ),
            })
        }
        (_, Some(ex)) => {
            let row = table
                .iter()
                .find(|m| m.excitation == ex)
                .expect("checked above");
            if !row.eligible {
                out.warnings.push(diagnostic(
                    DiagnosticKind::ManualSelection,
                    Severity::Warning,
                    DiagnosticSubject::setup(label)
                        .excitation(&ex)
                        .mode(mode, f_r),
                    format!(
                        "the manual choice '{ex}' is not reliable ({})",
                        row.reason.as_deref().unwrap_or("")
                    ),
                ));
            }
            let manual = criterion == SelectionCriterion::Manual;
            if manual && by.ni.as_ref().is_some_and(|c| c != &ex) {
                out.disagreements.push(format!(
                    "set-up '{label}' mode {mode} ({f_r:.4} Hz): the manual set takes {ex}, NI picks {}",
                    describe_choice(&by.ni)
                ));
            }
            // Runner-up: the best other eligible excitation under the same criterion
            // (NI for a manual choice).
            let rk = criterion_key(if manual {
                Criterion::Ni
            } else {
                p.opts.criterion
            });
            let others: Vec<&ModeExcitation> = table
                .iter()
                .filter(|m| m.eligible && m.excitation != ex)
                .collect();
            let runner = best_by(&others, rk).map(|i| others[i]);
            let member = group
                .iter()
                .map(|&i| &p.members[i])
                .find(|m| p.excitation_id(m.excitation) == ex)
                .expect("a row with an excitation mode has a member");
            let est = p.estimate(member);
            out.selected.push(SelectedMode {
                setup: label.clone(),
                mode,
                frequency_hz: est.frequency_hz,
                excitation: ex.clone(),
                excitation_mode: est.mode,
                ni_db: row.ni_db,
                margin_db: runner.map_or(0.0, |r| row.ni_db - r.ni_db),
                runner_up: runner.map(|r| r.excitation.clone()),
                strength: member.strength,
                criterion,
            });
        }
    }
    Ok(())
}

/// A manual set naming a mode beyond the pool's matched modes is refused.
fn check_manual_modes(p: &PoolInputs, n_modes: usize) -> Result<(), NiError> {
    if let Some(manual) = &p.opts.manual {
        for e in &manual.entries {
            if e.mode > n_modes {
                return Err(NiError::Manual(format!(
                    "mode {} (from '{}') does not exist: set-up '{}' has {n_modes} matched modes",
                    e.mode, e.excitation, p.pool.label
                )));
            }
        }
    }
    Ok(())
}

/// The mode a peak of the NI at `f` belongs to: the nearest mode whose band contains it.
fn mode_of_peak(mode_groups: &[ModeGroup], f: f64, spacing: f64) -> Option<usize> {
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
fn excitation_summaries(
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
                let f = p.frf.frequency_hz[pk.line];
                let spacing = local_spacing(&p.frf.frequency_hz, f);
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
fn strength_matrix(
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
