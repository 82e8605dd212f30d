//! **rbprops-inertia**: the ten rigid-body inertia properties (mass, centre of mass, inertia
//! tensor about the CoM) from identified rigid-body modes and from the mass line of FRFs,
//! with standard errors and physical-consistency checks.
//!
//! Pipeline of [`solve()`]:
//! 1. each selected mode's residues → least-squares rigid motion `q = (SᵀS)⁻¹SᵀA` (paper
//!    Eq. 5) about the chosen origin → `φ0 = q/√(f_kᵀq)` ([`shapes`]);
//! 2. [`bretl_conti`] (Eq. 2, six modes) and [`toivola_nuutila`] (Eq. 10, ≥ 4 modes, with
//!    rank detection and a description of what four modes cannot determine);
//! 3. [`mass_line()`]: the inertia-restraint method straight from the FRFs (Lee et al. 1999);
//! 4. `m`, `c` (Eq. 7) and `J` at the CoM (Eqs. 8–9) via `MassMatrix6::properties`, mount
//!    stiffness `K0 = Φ0⁻ᵀΩ²Φ0⁻¹`, standard errors ([`uncertainty`]), consistency and the
//!    nearest consistent estimate ([`consistency`]), relative errors against a reference.
//!
//! No I/O: data in, data (or typed errors) out.

// `!(x > 0.0)` is deliberate: it also rejects NaN. Index loops mirror the equations.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]
#![warn(missing_docs)]

pub mod consistency;
pub mod error;
pub mod lsq;
pub mod mass_line;
pub mod modal_estimators;
pub mod params;
pub mod rigid_check;
pub mod shapes;
pub mod solve;
pub mod uncertainty;

pub use consistency::{nearest_consistent, project_moments};
pub use error::InertiaError;
pub use lsq::{solve_parameters, LinearConstraint, LsqSolution, PropertiesEstimate};
pub use mass_line::{
    choose_band, mass_line, mass_line_values, MassLineBand, MassLineOptions, MassLineValues,
    MlSolution,
};
pub use modal_estimators::{
    bretl_conti, describe_null_space, mount_stiffness, toivola_nuutila, translation_in_span,
    BcSolution, TnSolution,
};
pub use params::{mass_matrix_of, params_of, N_PARAMS, PARAM_NAMES};
pub use shapes::{
    resolve_origin, rigid_shapes, OriginChoice, RigidFrame, RigidShape, ShapeCore, ShapeDiagnostics,
};
pub use solve::{solve, Estimator, SideInformation, SolveOptions, SolveOutput};
pub use uncertainty::{propagate, property_vector, Propagation, Z95};
