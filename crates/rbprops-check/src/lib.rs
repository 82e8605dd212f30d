//! **rbprops-check**: the model check. Given a nominal campaign spec
//! (as `frf-sim` reads it) and a recording, it
//! 1. estimates the noise floor from the data alone ([`noise`]);
//! 2. fits the nominal model's own parameters (inertia kept physical, suspension
//!    stiffness scales, damping) by weighted Levenberg–Marquardt ([`params`], [`lm`]), so a
//!    wrong value is reported as a corrected value, not as missing physics;
//! 3. locates the remaining residual by excitation × channel × band, rigid/non-rigid and
//!    in-phase/quadrature ([`locate`]);
//! 4. screens every candidate effect of the physics catalogue with a score test, refits
//!    the strongest and accepts only with statistical evidence ([`check()`]);
//! 5. reports χ²/ν before/after against the noise band, the corrected parameters, the
//!    accepted / ambiguous / not-observable effects and the inertia before/after with
//!    standard errors ([`report`]).
//!
//! Models are evaluated with rbprops-sim's own noise-free simulator ([`predict`]), so the
//! nominal model and each candidate are the code that generates recordings. No I/O.
//!
//! Statistics (docs/physics.md, M1): normalised residual
//! r = √2 (Y − Ŷ)/σ split into real and imaginary parts, χ² = ‖r‖², ν = 2N − p. A
//! candidate c is screened by its score S_c = ‖Q_cᵀ r‖² (Q_c: orthonormal basis of its
//! Jacobian with the current model's Jacobian projected out; rank d_c), significant above
//! χ²_{d_c, 1−α/N_cand}. The strongest are refitted (all parameters free) and one is
//! accepted only if Δχ² > χ²_{d,1−α/N_cand}, ΔBIC = Δχ² − d ln(2N) > 10, its Wald
//! statistic exceeds χ²_{d,0.999}, no parameter is pinned at a bound and its held-out
//! χ² ([`cv`]: 10 interleaved frequency-block folds, one-step refit without each fold)
//! drops by > 2 SE and in ≥ 80 % of the folds, and, with ≥ 3 excitations, no held-out
//! excitation (leave-one-excitation-out folds, `held_out_excitations` in the report) is
//! worse by more than 2 of its standard errors; a rival within
//! ΔBIC 10 whose signature has canonical correlation > 0.9 makes an ambiguous family.
//! After each acceptance a backward check drops earlier effects that no longer pass.
//! Effects with rank 0 (absorbed by the free parameters) are reported not observable,
//! with what would reveal them; exact gauges (a common gain, a common sensor shift) are
//! removed from the refit by holding one coordinate per gauge at its neutral value.
//! An effect is also claimed only when it is practically significant: its fitted change
//! to the FRFs is at least [`check::PRACTICAL_MARGIN`] = 10 times the precision floor
//! (RMS over the values), so rounding is never claimed as physics, and it changes some
//! FRF by at least [`check::RESOLUTION`] = 1e-4 relative, what a calibration resolves.
//! The noise floor is reached when χ²/ν_after lies in the central 99.73 % interval of
//! its distribution under the noise model — χ²_ν/ν with given noise, F(ν, 2/se²) with
//! the noise variance estimated to a relative standard error se — its upper end at
//! least 1.05 ([`check::noise_band`]), and no residual cell has z > 5.
//!
//! Noise and precision ([`noise`]): σ² = a²|H|² + b² per channel (the workspace's one
//! noise model, `rbprops_core::noise`) plus a precision floor: the quantisation
//! variance step²/12 of each stored part, with the storage format detected from the
//! values (single precision when every value is exactly a single-precision number,
//! d ≤ 15 significant decimal digits when every value's shortest exact decimal has at
//! most d, double precision otherwise; `rbprops_core::precision`), and the model's own
//! the precision to which two double-precision computations of an FRF agree (1e-10·|H|,
//! [`noise::COMPUTATION_FLOOR`]). A recording without added noise is thus weighed by its
//! quantisation, and its χ²/ν can reach the band.
//!
//! Effects whose signature vanishes to every order at their neutral point
//! (`record_truncation` as T → ∞, `cord_mass` as μ → 0) cannot be seen by a score test;
//! they are screened by a profile over a parameter grid (chord-refined re-adjustment of
//! the current parameters, Bonferroni over the grid), see [`candidates`]. An elastic
//! mode (in the band or above it) is bilinear in its shapes, so the same holds; it is
//! fitted as one pole with a residue per channel and excitation, started from a profile
//! over (f, ζ) of the linear residue fit to the current residual ([`resonance`]).
//!
//! The data-only noise estimate reads deterministic structure the local polynomial
//! cannot follow (a leakage ripple, or on data without noise the curvature of the FRF)
//! as noise; the noise is re-estimated from the final model's residual and the check
//! rerun with it if that moves χ²/ν out of its band ([`noise::estimate_from_residual`]).
//!
//! Noise correlated from line to line (a window on the time histories) is detected and,
//! when it is an exponential window's, weighed conservatively ([`correlation`]).
//!
//! Not implemented (see the report's `method` field): bootstrap calibration of the
//! screening threshold; noise correlated across channels (the force channel's noise in
//! an H1 estimate is common to an excitation's channels).
//!
//! ```no_run
//! # fn demo(spec: &rbprops_sim::CampaignSpec, g: &rbprops_core::Geometry, frf: &rbprops_core::FrfSet) {
//! let out = rbprops_check::check(spec, g, frf, &rbprops_check::CheckOptions::default()).unwrap();
//! println!("{}", out.report.verdict);
//! # }
//! ```

#![warn(missing_docs)]

pub mod candidates;
pub mod check;
pub mod correlation;
pub mod cv;
pub mod error;
pub mod lm;
pub mod locate;
pub mod noise;
pub mod params;
pub mod predict;
pub mod prof;
pub mod report;
pub mod resonance;

pub use check::{check, CheckOptions, CheckOutcome, Progress};
pub use error::CheckError;
pub use noise::{GivenLineVariance, RecordingNoise};
pub use report::ModelCheckReport;
