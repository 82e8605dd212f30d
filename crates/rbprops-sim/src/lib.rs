#![allow(clippy::neg_cmp_op_on_partial_ord)] // `!(x > 0.0)` deliberately rejects NaN too.
//! **rbprops-sim**: simulated FRF campaigns of a rigid body on a linear suspension, the
//! physics behind `frf-sim`. No I/O: specs come in as text, results go out as data.
//!
//! Model per suspension set-up (docs/conventions.md conventions, `e^{+iωt}`):
//! `H(ω) = S (K + iωC − ω²M0)⁻¹ F`, with `M0` the rigid-body mass matrix about the
//! geometry origin, `K = Σ T(a)ᵀ k T(a)` the mount stiffness (a cord is its axial spring
//! `k e eᵀ`, or with gravity the Hessian of the hanging body's potential at equilibrium,
//! see [`effects::gravity`]; a direction nothing resists is a mode at 0 Hz, and a 0 Hz
//! line is then skipped), `C` modal or Rayleigh
//! damping, `S` the stacked channel rows `sᵀT(p)` and `F` the force columns `T(p)ᵀd`;
//! converted to mobility (`iωH`) or accelerance (`−ω²H`) as asked, then noise is added
//! (see [`noise`]).

#![warn(missing_docs)]

mod deferred;
pub mod effects;
pub mod error;
pub mod examples;
pub mod model;
pub mod noise;
pub mod observe;
pub mod simulate;
pub mod spec;
pub mod suspension;

pub use deferred::{simulate_deferred, DeferredSimulation};
pub use error::{SimError, SpecError, SpecIssue};
pub use examples::{effect_examples, example, example_names};
pub use model::DynamicModel;
pub use simulate::{
    build_models, free_directions, predict, simulate, simulate_with, SetupModel, SimOptions,
    Simulation, SolveMethod,
};
pub use spec::CampaignSpec;
