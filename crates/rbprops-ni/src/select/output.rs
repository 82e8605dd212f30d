//! What the selection returns: the record, and the tables and curves behind it (plot-ready).

use rbprops_core::records::SelectionRecord;
use rbprops_core::Quantity;
use serde::{Deserialize, Serialize};

/// How one excitation does at one physical mode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ModeExcitation {
    /// 1-based physical mode number within the set-up.
    pub mode: usize,
    /// Natural frequency of the mode's reference estimate (Hz).
    pub frequency_hz: f64,
    /// The excitation this row is about.
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
    pub prf_mif: f64,
    /// Measured strength `f_kᵀq` (1/kg) of its own estimate, and its standard error
    /// (None without residue standard errors).
    pub strength: Option<f64>,
    /// Standard error of `strength` (1/kg).
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
    pub setup: String,
    /// 1-based, ascending frequency within the set-up.
    pub mode: usize,
    /// Natural frequency of the reference estimate (Hz).
    pub frequency_hz: f64,
    /// Damping ratio of the reference estimate (fraction of critical).
    pub damping_ratio: f64,
    /// Excitation whose estimate gives the reference shape.
    pub reference_excitation: String,
    /// Every excitation of the set-up: eligible ones first in the order of the criterion
    /// used, then the others by NI.
    pub ranking: Vec<ModeExcitation>,
    /// The choice each criterion would make (None: nothing eligible).
    pub choice_ni: Option<String>,
    /// The hybrid MIF's choice (deepest dip).
    pub choice_hybrid_mif: Option<String>,
    /// The PRF MIF's choice (deepest dip).
    pub choice_prf_mif: Option<String>,
    /// Largest measured strength `f_kᵀq`.
    pub choice_strength: Option<String>,
}

/// An NI peak.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct NiPeak {
    /// Frequency of the peak's line (Hz).
    pub frequency_hz: f64,
    /// NI at the peak (dB).
    pub level_db: f64,
    /// Topographic prominence of the peak (dB).
    pub prominence_db: f64,
    /// The physical mode it belongs to, if any.
    pub mode: Option<usize>,
}

/// What the NI and the identified modes say about one excitation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ExcitationSummary {
    /// The excitation.
    pub excitation: String,
    /// Its suspension set-up.
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
    pub excitation: String,
    /// Its suspension set-up.
    pub setup: String,
    /// Norm Indicator per line in dB (paper Eq. 12).
    pub ni_db: Vec<f64>,
    /// Hybrid MIF per line (Rades 1994), in [0, 1].
    pub hybrid_mif: Vec<f64>,
    /// PRF MIF per line (Rades & Ewins 2000), in [0, 1].
    pub prf_mif: Vec<f64>,
    /// Singular values of the principal responses (descending) and how many are kept.
    pub prf_singular_values: Vec<f64>,
    /// Number of principal responses kept.
    pub prf_rank: usize,
    /// `20 log10 |PRF_j(ω)|` of the kept principal response functions (empty unless
    /// `SelectOptions::principal_response_curves`).
    pub prf_db: Vec<Vec<f64>>,
}

/// Plot data: the NI (Figs. 4/11), hybrid MIF (Fig. 12) and PRF MIF (Fig. 13) curves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct IndicatorCurves {
    /// Frequency of every line (Hz), shared by all curves.
    pub frequency_hz: Vec<f64>,
    /// Receptance, mobility or accelerance: the FRFs the curves come from.
    pub quantity: Quantity,
    /// One set of curves per excitation, in geometry order.
    pub excitations: Vec<ExcitationCurves>,
}

/// Mode × excitation matrices of one set-up, for a heat map. Indexed `[mode][excitation]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct StrengthMatrix {
    /// The suspension set-up.
    pub setup: String,
    /// Physical mode numbers, one per row.
    pub modes: Vec<usize>,
    /// Natural frequency of each mode (Hz).
    pub frequency_hz: Vec<f64>,
    /// Excitation ids, one per column.
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
    pub excitation_summaries: Vec<ExcitationSummary>,
    /// The matched physical modes, set-up by set-up.
    pub matches: Vec<ModeGroup>,
    /// The indicator curves for plots.
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
    pub setup: String,
    /// The excitation whose modal record holds it.
    pub excitation: String,
    /// Its mode number in `modal-fit`'s output.
    pub excitation_mode: usize,
    /// Its natural frequency (Hz).
    pub frequency_hz: f64,
    /// Frequency of the candidate mode it was matched into.
    pub group_frequency_hz: f64,
    /// Why it was left out.
    pub reason: String,
}
