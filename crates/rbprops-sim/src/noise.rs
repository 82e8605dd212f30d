//! Measurement noise of a simulated campaign, reproducible independently of thread
//! count and excitation order.
//!
//! The noise is the workspace's one noise model ([`rbprops_core::noise`]): every FRF value
//! `H` (in the output quantity) receives circular complex Gaussian noise with
//! `E|ε|² = σ² = relative²·|H|² + floor²` (variance `σ²/2` in each of the real and
//! imaginary parts), the model the model check and the bootstrap assume. The normals
//! come from one Box–Muller pair per value, drawn in `[channel][line]` order from the
//! [`NormalStream`] of the campaign seed and the excitation index.
//!
//! Until the noise model was shared, frf-sim drew `σ = relative·|H| + floor` (standard
//! deviations added); with `floor = 0` both give the same draws bit for bit.

use rbprops_core::c64;
use rbprops_core::noise::{NoiseModel, NormalStream};

/// The normal stream of excitation `index` of a campaign with seed `seed`.
pub fn excitation_rng(seed: u64, index: usize) -> NormalStream {
    NormalStream::new(seed, index as u64)
}

/// Adds the noise `E|ε|² = relative²|H|² + floor²` to one block of values in place.
pub fn add_noise(values: &mut [c64], relative: f64, floor: f64, normals: &mut NormalStream) {
    NoiseModel::new(relative, floor).add_to(values, normals);
}
