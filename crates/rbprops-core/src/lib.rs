//! Domain model of **rbprops**: the types every pipeline stage shares.
//!
//! Conventions (fixed by docs/conventions.md, used everywhere):
//! - SI units; frequencies in Hz in files, rad/s inside formulas.
//! - Time dependence `e^{+iωt}`; receptance `H = X/F`, mobility `iωH`, accelerance `-ω²H`.
//! - Small rigid motion about an origin `O`: `q0 = [u0; θ]`; a body point `p` moves as
//!   `u(p) = T(p) q0` with `T(p) = [I | -[p]×]` ([`rigid_transform`]).
//! - Inertia tensor about the CoM with the paper's Eq. (6) sign: products of inertia are
//!   `J_xy = ∫ x y dm`, and the tensor's off-diagonal entries are their negatives.
//!
//! Shared numerics: the FRF noise model `E|ε|² = a²|H|² + b²` and the seeded normal
//! stream ([`noise`]), the quantisation floor of the storage precision ([`precision`]),
//! and the χ² / F distributions with the noise band of χ²/ν ([`stats`]).
//!
//! This crate does no I/O. Types that cross stage boundaries ([`records`]) derive
//! `serde` and `schemars` so the formats crate can write them with a JSON schema.

#![warn(missing_docs)]

pub mod error;
pub mod frf;
pub mod geometry;
pub mod inertia;
pub mod methods;
pub mod modal;
pub mod noise;
pub mod precision;
pub mod properties;
pub mod records;
pub mod rigid;
pub mod simd;
pub mod stats;
pub mod window;

pub use error::CoreError;
pub use frf::{excitations_in_parallel, ExcitationFrf, FrfSet, FrfSource, Quantity};
pub use geometry::{
    cross_matrix, rigid_transform, Channel, Excitation, Geometry, Point, SuspensionSetup,
};
pub use inertia::{MassMatrix6, RigidBodyProperties};
pub use modal::{rigid_body_modes, RigidMode};
pub use noise::{CoherenceNoise, CommonRelativeError, NoiseModel, NormalStream};
pub use precision::DataPrecision;
pub use properties::InertiaProperties;
pub use rigid::{mass_normalise, real_modal_constants, RigidBasis, RigidFit};
pub use window::{Prefiltered, WindowCorrection};

/// Complex double, the same type faer (`faer::c64`) and nalgebra use.
#[allow(non_camel_case_types)]
pub type c64 = num_complex::Complex64;
/// A 3-vector in the geometry's frame (m).
pub type Vec3 = nalgebra::Vector3<f64>;
/// A 6-vector of rigid-body coordinates `[u; θ]` about an origin.
pub type Vec6 = nalgebra::Vector6<f64>;
/// A 3×3 matrix.
pub type Mat3 = nalgebra::Matrix3<f64>;
/// A 6×6 matrix.
pub type Mat6 = nalgebra::Matrix6<f64>;
