//! What the selection is asked: the criterion that ranks the excitations at a mode and
//! the options of [`super::select_modes`].

use crate::indicators::DEFAULT_PRF_RANK_TOLERANCE;
use crate::manual::ManualSet;
use crate::NiError;
use rbprops_core::records::SelectionCriterion;
use serde::{Deserialize, Serialize};

/// Which indicator ranks the excitations at a mode.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize, schemars::JsonSchema,
)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "snake_case")]
pub enum Criterion {
    // `help = None`: `ni-select --help` lists the names alone (`ni`, `hybrid-mif`,
    // `prf-mif`), as it always has.
    /// Highest Norm Indicator at the mode (paper Eq. 12): the most excited mode.
    #[default]
    #[cfg_attr(feature = "clap", value(help = None))]
    Ni,
    /// Deepest hybrid-MIF dip at the mode: the purest normal-mode response.
    #[cfg_attr(feature = "clap", value(help = None))]
    HybridMif,
    /// Deepest PRF-MIF dip at the mode.
    #[cfg_attr(feature = "clap", value(help = None))]
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
    /// Keep each excitation's principal response curves (`ExcitationCurves::prf_db`,
    /// rank × lines, the bulk of the curves) in the output; default false (no plot or
    /// stage reads them, and at 192 excitations they were 15 MB of ni-select's memory).
    #[serde(default)]
    pub principal_response_curves: bool,
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
            principal_response_curves: false,
        }
    }
}

impl SelectOptions {
    pub(super) fn validate(&self) -> Result<(), NiError> {
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
