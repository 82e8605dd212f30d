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
//! Models are evaluated with rbprops-sim's own builder ([`predict`]), so the nominal
//! model and each candidate are the code that generates recordings. No I/O.
//!
//! ```no_run
//! # fn demo(spec: &rbprops_sim::CampaignSpec, g: &rbprops_core::Geometry, frf: &rbprops_core::FrfSet) {
//! let out = rbprops_check::check(spec, g, frf, &rbprops_check::CheckOptions::default()).unwrap();
//! println!("{}", out.report.verdict);
//! # }
//! ```

pub mod candidates;
pub mod check;
pub mod error;
pub mod lm;
pub mod locate;
pub mod noise;
pub mod params;
pub mod predict;
pub mod report;
pub mod stats;

pub use check::{check, CheckOptions, CheckOutcome};
pub use error::CheckError;
pub use noise::NoiseModel;
pub use report::ModelCheckReport;
