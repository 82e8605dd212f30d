//! **rbprops-check**: the model check (GitHub issue 9). Given a nominal campaign spec
//! (as `frf-sim` reads it) and a recording, it
//! 1. estimates the noise floor from the data alone ([`noise`]);
//! 2. fits the nominal model's own parameters (inertia kept physical, suspension
//!    stiffness scales, damping) by weighted Levenberg–Marquardt ([`params`], [`lm`]), so a
//!    wrong value is reported as a corrected value, not as missing physics;
//! 3. locates the remaining residual by excitation × channel × band, rigid/non-rigid and
//!    in-phase/quadrature ([`locate`]);
//! 4. screens every candidate effect of the physics catalogue with a score test, refits
//!    the strongest and accepts only with statistical evidence ([`check`]);
//! 5. reports χ²/ν before/after against the noise band, the corrected parameters, the
//!    accepted / ambiguous / not-observable effects and the inertia before/after with
//!    standard errors ([`report`]).
//!
//! Models are evaluated with rbprops-sim's own noise-free simulator ([`predict`]), so the
//! nominal model and each candidate are the code that generates recordings. No I/O.
//!
//! Statistics (research note §6, `missing-physics.md`): normalised residual
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
//! The noise floor is reached when χ²/ν_after ∈ [1 − 3s, 1 + max(3s, 0.05)],
//! s² = 2/ν + (relative SE of the noise variance)², and no residual cell has z > 5.
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
//! cannot follow (a leakage ripple) as noise; when effects are accepted the noise is
//! re-estimated from the final model's residual and the check rerun with it if that
//! moves χ²/ν by more than its band's half-width ([`noise::estimate_from_residual`]).
//!
//! Not implemented (see the report's `method` field): bootstrap calibration of the
//! screening threshold, line-to-line noise correlation (κ = 1 assumed).
//!
//! ```no_run
//! # fn demo(spec: &rbprops_sim::CampaignSpec, g: &rbprops_core::Geometry, frf: &rbprops_core::FrfSet) {
//! let out = rbprops_check::check(spec, g, frf, &rbprops_check::CheckOptions::default()).unwrap();
//! println!("{}", out.report.verdict);
//! # }
//! ```

pub mod candidates;
pub mod check;
pub mod cv;
pub mod error;
pub mod lm;
pub mod locate;
pub mod noise;
pub mod params;
pub mod predict;
pub mod report;
pub mod resonance;
pub mod stats;

pub use check::{check, CheckOptions, CheckOutcome, Progress};
pub use error::CheckError;
pub use noise::NoiseModel;
pub use report::ModelCheckReport;
