//! Thin wrappers over faer's dense kernels, always run sequentially (`Par::Seq`).
//!
//! Why sequential: excitations are already fitted in parallel with rayon, and faer's
//! own parallel kernels would make the floating-point reduction order depend on the
//! thread count. Running each small problem on one thread keeps every result
//! bit-identical whatever the pool size.
//!
//! [`kernels`]: inner products and matrix products; [`lstsq`]: least squares and small
//! linear solves; [`eigen`]: the eigen-solver and polynomial roots. Their items are
//! re-exported here.

pub mod eigen;
pub mod kernels;
pub mod lstsq;

pub use eigen::*;
pub use kernels::*;
pub use lstsq::*;
