//! Fit options and their defaults.

/// Which estimator provides the poles (and, for `Circle`, the modal parameters).
/// (Variants in the order `modal-fit --help` lists them.)
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Method {
    /// Least-squares complex frequency-domain estimator (common denominator, real
    /// coefficients, z-domain basis), stabilisation diagram, then pole refinement and
    /// LSFD residues. Works on any frequency axis (uniform or not, baseband or zoom).
    #[cfg_attr(
        feature = "clap",
        value(
            help = "Least-squares complex frequency domain poles + LSFD residues, per excitation only. Without --method: these fits, and the poly-reference fit of a set-up when they show a repeated or near-repeated root (kept when it loses no mode and fits as well)"
        )
    )]
    Lscf,
    /// Poly-reference LSCF (PolyMAX): one matrix-polynomial denominator over every
    /// excitation of a set-up, poles with modal participation vectors, stabilisation
    /// diagram and selection, then poly-reference LSFD for the mode shapes (residues
    /// `ψ_r l_rᵀ`). Separates repeated and nearly repeated roots that single-reference
    /// fits merge. Always per set-up.
    #[cfg_attr(
        feature = "clap",
        value(
            alias = "polymax",
            help = "Poly-reference LSCF (PolyMAX): one fit over every excitation of a set-up, with participation factors; separates repeated and nearly repeated roots"
        )
    )]
    Plscf,
    /// Least-squares complex exponential: poles from the impulse responses (inverse DFT
    /// of the band-limited FRFs), then the same selection, refinement and LSFD as LSCF.
    /// Needs a uniform axis starting at 0 Hz (no zoom band, no gaps).
    #[cfg_attr(
        feature = "clap",
        value(
            help = "Least-squares complex exponential (time domain; needs a uniform baseband axis)"
        )
    )]
    Lsce,
    /// Kennedy–Pancu circle fit per mode and channel (modes located by LSCF), neighbours'
    /// contributions subtracted iteratively with their own circle-fit models. Only for
    /// modes separated by several half-power bandwidths.
    #[cfg_attr(
        feature = "clap",
        value(help = "Kennedy–Pancu circle fit per mode and channel (well-separated modes only)")
    )]
    Circle,
}

impl Method {
    /// The method's name as `modal-fit --method` takes it.
    pub fn name(self) -> &'static str {
        self.record_name().as_str()
    }

    /// The name written in `ExcitationFitRecord::method`.
    pub fn record_name(self) -> rbprops_core::records::FitMethod {
        use rbprops_core::records::FitMethod;
        match self {
            Method::Lscf => FitMethod::Lscf,
            Method::Lsce => FitMethod::Lsce,
            Method::Circle => FitMethod::Circle,
            Method::Plscf => FitMethod::Plscf,
        }
    }
}

impl std::str::FromStr for Method {
    type Err = crate::ModalError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "lscf" => Ok(Method::Lscf),
            "plscf" | "polymax" => Ok(Method::Plscf),
            "lsce" => Ok(Method::Lsce),
            "circle" | "circle-fit" | "kennedy-pancu" => Ok(Method::Circle),
            _ => Err(crate::ModalError::Options(format!(
                "unknown method '{s}' (expected lscf, plscf, lsce or circle)"
            ))),
        }
    }
}

/// Whose FRFs the poles are estimated from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum PoleMode {
    /// Each excitation gets its own poles (independent SIMO fits).
    #[cfg_attr(
        feature = "clap",
        value(name = "excitation", help = "Poles estimated per excitation")
    )]
    PerExcitation,
    /// One pole set per suspension set-up from all its excitations' channels (the
    /// poles are global properties of the set-up); residues still per excitation.
    #[cfg_attr(
        feature = "clap",
        value(
            name = "setup",
            help = "One consistent pole set per suspension set-up, from all its excitations"
        )
    )]
    PerSetup,
}

/// Stabilisation-diagram and pole-selection tolerances. All are relative: frequency and
/// damping relative to the pole's own values, clustering distance in units of the
/// pole's half-power half-bandwidth `ζω_r` (so close modes are never merged by a fixed
/// window).
#[derive(Debug, Clone, PartialEq)]
pub struct StabilisationTolerances {
    /// |Δf|/f between consecutive orders for a pole to be frequency-stable.
    pub frequency: f64,
    /// |Δζ|/ζ between consecutive orders for damping stability.
    pub damping: f64,
    /// 1 − MAC between consecutive orders for shape stability.
    pub shape: f64,
    /// Poles with damping above this are computational (or not of interest).
    pub max_damping: f64,
    /// Two stable poles belong to the same mode when they are closer than this many
    /// half-power half-bandwidths (and their shapes agree within `shape`).
    pub cluster_bandwidths: f64,
    /// A cluster is a physical mode when it holds at least this fraction of the
    /// orders from its first appearance to the maximum order.
    pub min_presence: f64,
}

impl Default for StabilisationTolerances {
    fn default() -> Self {
        Self {
            frequency: 0.01,
            damping: 0.05,
            shape: 0.02,
            max_damping: 0.2,
            cluster_bandwidths: 0.5,
            min_presence: 0.4,
        }
    }
}

/// The thresholds of the pole search in [`crate::fit_excitation`] that decide how many
/// modes a fit finds: the sweep plan (which sub-band the stabilisation diagram is drawn
/// on), the lower-band safety sweeps, the refinement's sanity check and the χ²
/// model-order tests. Distances are in half-power half-bandwidths `ζω_r` of the pole
/// (see [`crate::Pole::distance_in_bandwidths`]). `Default` gives the documented defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct PoleSearchParams {
    /// Sweep plan: polynomial (z-domain) estimators need an order that grows with the band
    /// relative to where the modes are, so the diagram is drawn again on the lines up to
    /// this multiple of the highest stable mode (default 2) …
    pub sub_band_margin: f64,
    /// … when that is below this fraction of the current band's top (default 0.6) …
    pub sub_band_max_fraction: f64,
    /// … or, when no mode is stable, on this fraction of the band (default 0.5).
    pub sub_band_without_modes: f64,
    /// Safety sweeps: each sweeps the lowest `safety_fraction` of the previous one's band
    /// (default 0.25: the lower quarter, again and again) …
    pub safety_fraction: f64,
    /// … and adds the modes it finds in the lowest `safety_keep_fraction` of its own
    /// sub-band (default 0.6) …
    pub safety_keep_fraction: f64,
    /// … at least this many half-bandwidths from every known mode (default 3).
    pub new_mode_bandwidths: f64,
    /// Refinement is local: a pole it moves more than this many half-bandwidths (or out of
    /// the band, or past the damping limit) is computational and dropped (default 10).
    pub max_refinement_shift_bandwidths: f64,
    /// A rejected cluster tried as an extra mode by the residual model-order test must
    /// refine to within this many half-bandwidths of where the diagram put it (default 3).
    pub candidate_drift_bandwidths: f64,
    /// The χ² model-order tests' false-alarm level, as the standard-normal upper quantile
    /// `z` of their Wilson–Hilferty threshold (default 3.719, upper tail 1e-4).
    pub order_test_z: f64,
    /// Poles closer than this many half-bandwidths are one repeated root: a candidate or
    /// split partner must end farther apart, and a final pair this close is reported
    /// inseparable (default 0.25).
    pub inseparable_bandwidths: f64,
    /// Poles closer than this are a close pair: suspects of the backward model-order test,
    /// and flagged "sensitive to noise" in the result (default 2).
    pub close_bandwidths: f64,
    /// A pole whose diagram confidence is below this is a suspect of the backward
    /// model-order test (default 0.5).
    pub suspect_confidence: f64,
    /// The forward split test places a partner this many half-bandwidths below and above
    /// each pole (default 0.6).
    pub split_offset_bandwidths: f64,
}

impl Default for PoleSearchParams {
    fn default() -> Self {
        Self {
            sub_band_margin: 2.0,
            sub_band_max_fraction: 0.6,
            sub_band_without_modes: 0.5,
            safety_fraction: 0.25,
            safety_keep_fraction: 0.6,
            new_mode_bandwidths: 3.0,
            max_refinement_shift_bandwidths: 10.0,
            candidate_drift_bandwidths: 3.0,
            order_test_z: 3.719,
            inseparable_bandwidths: 0.25,
            close_bandwidths: 2.0,
            suspect_confidence: 0.5,
            split_offset_bandwidths: 0.6,
        }
    }
}

/// Options of [`crate::fit_campaign`] / [`crate::fit_excitation`].
#[derive(Debug, Clone, PartialEq)]
pub struct FitOptions {
    /// Pole estimator (LSCF, LSCE, pLSCF or circle fit).
    pub method: Method,
    /// Band to fit (Hz, inclusive); `None` = the whole axis.
    pub band_hz: Option<(f64, f64)>,
    /// Force the number of modes in the band (the strongest stable clusters are kept).
    pub n_modes: Option<usize>,
    /// Highest denominator order of the stabilisation diagram (2 per mode). Reduced
    /// automatically when the band has too few lines.
    pub max_order: usize,
    /// One pole set per excitation, or one per suspension set-up.
    pub poles: PoleMode,
    /// Lower (`1/(iω)²` in receptance, only when the band starts above 0 Hz) and upper
    /// (constant receptance) residual terms in the residue fit.
    pub residual_terms: bool,
    /// Refine poles and residues jointly by Gauss–Newton on the frequency-domain
    /// least-squares error (variable projection). Needed for accuracy beyond ~1e-4.
    pub refine: bool,
    /// Stabilisation criteria between successive model orders.
    pub tolerances: StabilisationTolerances,
    /// A mode whose peak Norm Indicator is more than this many dB below the
    /// excitation's strongest mode is flagged `weak`.
    pub weak_below_db: f64,
    /// Circle fit: warn when another mode is closer than this many half-power bandwidths.
    pub circle_min_separation: f64,
    /// Keep each excitation's synthesised FRFs in [`crate::ExcitationDiagnostics`] (for
    /// the measured-vs-synthesised plots). Off by default: at 9 channels × 4,096 lines
    /// they are 0.6 MB per excitation, 0.6 GB for a 1,000-excitation campaign, and
    /// nothing else reads them (the fit error per channel is in the record).
    pub keep_synthesised: bool,
    /// Single-reference methods with per-excitation poles (default on): also fit a set-up
    /// of two or more excitations with [`Method::Plscf`] when its per-excitation fits show
    /// a repeated or near-repeated root, disagree on the number of modes near one
    /// frequency or fit one excitation far worse than the others, and keep the
    /// poly-reference fit when it loses no mode and explains every excitation as well
    /// ([`crate::evidence`]); one `fit_choice` diagnostic says which was kept and why.
    pub auto_poly_reference: bool,
    /// Weight the lines by the measured coherence (`crate::weighting`) in the LSCF pole
    /// estimate, the pole refinement and the LSFD residues; `None` (default): the
    /// default relative weights `1/|H|`. LSCF and LSCE only (LSCE's time-domain pole
    /// estimate itself is not weighted).
    pub coherence_weighting: Option<std::sync::Arc<crate::weighting::CoherenceWeighting>>,
    /// Thresholds of the pole search: how many modes a fit finds.
    pub search: PoleSearchParams,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            method: Method::Lscf,
            band_hz: None,
            n_modes: None,
            max_order: 40,
            poles: PoleMode::PerExcitation,
            residual_terms: true,
            refine: true,
            tolerances: StabilisationTolerances::default(),
            weak_below_db: 20.0,
            circle_min_separation: 3.0,
            keep_synthesised: false,
            // On: the poly-reference fit is only tried on evidence and only kept when it
            // loses no mode and explains every excitation as well (`crate::evidence`).
            auto_poly_reference: true,
            coherence_weighting: None,
            search: PoleSearchParams::default(),
        }
    }
}

impl FitOptions {
    /// Refuses out-of-range values, naming the option.
    pub fn validate(&self) -> Result<(), crate::ModalError> {
        let bad = |s: String| Err(crate::ModalError::Options(s));
        if let Some((a, b)) = self.band_hz {
            if !(a.is_finite() && b.is_finite() && a >= 0.0 && b > a) {
                return bad(format!("band [{a}, {b}] Hz is empty or not finite"));
            }
        }
        if self.max_order < 2 {
            return bad(format!("max_order {} < 2", self.max_order));
        }
        if self.coherence_weighting.is_some()
            && matches!(self.method, Method::Plscf | Method::Circle)
        {
            return bad(format!(
                "coherence weighting is available with the lscf and lsce methods, not {}",
                self.method.name()
            ));
        }
        if self.n_modes == Some(0) {
            return bad("n_modes = 0".into());
        }
        let t = &self.tolerances;
        for (name, v) in [
            ("frequency", t.frequency),
            ("damping", t.damping),
            ("shape", t.shape),
            ("max_damping", t.max_damping),
            ("cluster_bandwidths", t.cluster_bandwidths),
            ("min_presence", t.min_presence),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(format!("tolerance {name} = {v} must be positive"));
            }
        }
        Ok(())
    }
}
