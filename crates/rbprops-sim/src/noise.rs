//! Measurement noise, reproducible independently of thread count and excitation order.
//!
//! Every FRF value `H` (in the output quantity) receives
//! `ε = (relative·|H| + floor)·(n₁ + i n₂)/√2`, where `n₁`, `n₂` are independent
//! standard normals, so `E[ε] = 0` and `E|ε|² = (relative·|H| + floor)²`
//! (variance `(relative·|H| + floor)²/2` in each of the real and imaginary parts).
//! The normals come from the Box–Muller transform of two uniforms, one pair per value,
//! drawn in `[channel][line]` order from a `ChaCha8Rng` whose 32-byte seed holds the
//! campaign seed (bytes 0–7, little-endian) and the excitation index (bytes 8–15).

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rbprops_core::c64;

/// The generator of excitation `index` of a campaign with seed `seed`.
pub fn excitation_rng(seed: u64, index: usize) -> ChaCha8Rng {
    let mut s = [0u8; 32];
    s[..8].copy_from_slice(&seed.to_le_bytes());
    s[8..16].copy_from_slice(&(index as u64).to_le_bytes());
    ChaCha8Rng::from_seed(s)
}

/// Two independent standard normals (Box–Muller).
pub fn standard_normal_pair(rng: &mut ChaCha8Rng) -> (f64, f64) {
    // 1 − U lies in (0, 1], so the logarithm is finite.
    let u1 = 1.0 - rng.random::<f64>();
    let u2 = rng.random::<f64>();
    let r = (-2.0 * u1.ln()).sqrt();
    let (s, c) = (std::f64::consts::TAU * u2).sin_cos();
    (r * c, r * s)
}

/// Adds the noise to one block of values in place.
pub fn add_noise(values: &mut [c64], relative: f64, floor: f64, rng: &mut ChaCha8Rng) {
    if relative == 0.0 && floor == 0.0 {
        return;
    }
    for v in values {
        let (n1, n2) = standard_normal_pair(rng);
        let sigma = (relative * v.norm() + floor) * std::f64::consts::FRAC_1_SQRT_2;
        *v += c64::new(sigma * n1, sigma * n2);
    }
}
