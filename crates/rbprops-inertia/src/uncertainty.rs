//! Propagation of input standard errors to the ten properties.
//!
//! The inputs are independent with known standard deviations σ_i (residues: real and
//! imaginary parts each with `ModeEstimate.residue_std`; mass-line values: the regression
//! standard error of each FRF's constant term). Two methods, both deterministic:
//! - **linearised**: central differences of the whole estimator with a step of one σ_i
//!   (`J_i = (f(x + σ_i e_i) − f(x − σ_i e_i)) / 2`, a statistical linearisation that equals
//!   σ_i ∂f/∂x_i for a linear f), `var_k = Σ_i J_ki²`. Steps that make the estimator fail
//!   are halved up to four times.
//! - **monte_carlo**: `N` Gaussian draws, draw `s` seeded from `(seed, s)` (so the result
//!   does not depend on the rayon thread count), sample standard deviation about the mean.
//!
//! 95 % intervals are `value ± 1.96 σ` ([`Z95`]).

use crate::error::InertiaError;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use rbprops_core::noise::standard_normal;
use rbprops_core::records::UncertaintyMethod;
use rbprops_core::{InertiaProperties, RigidBodyProperties};

/// Two-sided 95 % normal quantile.
pub const Z95: f64 = 1.959963984540054;

/// Number of properties propagated: the ten-vector of [`InertiaProperties`] (m, c in the
/// geometry frame, moments and products of inertia about the CoM; docs/conventions.md §3).
pub const N_PROPS: usize = InertiaProperties::LEN;

/// The propagated property vector of a [`RigidBodyProperties`]
/// ([`InertiaProperties::to_vector`]). A product's standard error is its tensor entry's.
pub fn property_vector(p: &RigidBodyProperties) -> [f64; N_PROPS] {
    InertiaProperties::from_rigid_body(p).to_vector()
}

/// How to propagate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Propagation {
    /// First-order propagation of the residue and pole standard errors (Jacobian).
    Linearised,
    /// Monte Carlo: redraw the modal data from their standard errors and re-estimate.
    MonteCarlo {
        /// Number of draws.
        samples: usize,
        /// Seed of the draws' normal stream.
        seed: u64,
    },
}

impl Propagation {
    /// The `uncertainty_method` string of the record.
    pub fn name(&self) -> &'static str {
        self.record_name().as_str()
    }

    /// The `uncertainty_method` of the record.
    pub fn record_name(&self) -> UncertaintyMethod {
        match self {
            Propagation::Linearised => UncertaintyMethod::Linearised,
            Propagation::MonteCarlo { .. } => UncertaintyMethod::MonteCarlo,
        }
    }
}

/// Standard deviations of `f(x)` for independent inputs with std `sigma`.
pub fn propagate<F>(
    f: F,
    x: &[f64],
    sigma: &[f64],
    how: Propagation,
) -> Result<[f64; N_PROPS], InertiaError>
where
    F: Fn(&[f64]) -> Result<[f64; N_PROPS], InertiaError> + Sync,
{
    assert_eq!(x.len(), sigma.len());
    let std = match how {
        Propagation::Linearised => linearised(&f, x, sigma)?,
        Propagation::MonteCarlo { samples, seed } => monte_carlo(&f, x, sigma, samples, seed)?,
    };
    if std.iter().any(|s| !s.is_finite()) {
        return Err(InertiaError::NonFinite {
            what: "propagated standard deviation".into(),
        });
    }
    Ok(std)
}

fn linearised<F>(f: &F, x: &[f64], sigma: &[f64]) -> Result<[f64; N_PROPS], InertiaError>
where
    F: Fn(&[f64]) -> Result<[f64; N_PROPS], InertiaError> + Sync,
{
    let columns: Vec<Result<[f64; N_PROPS], InertiaError>> = (0..x.len())
        .into_par_iter()
        .map(|i| {
            if sigma[i] == 0.0 {
                return Ok([0.0; N_PROPS]);
            }
            let mut h = sigma[i];
            let mut last = None;
            for _ in 0..5 {
                let mut xp = x.to_vec();
                let mut xm = x.to_vec();
                xp[i] += h;
                xm[i] -= h;
                match (f(&xp), f(&xm)) {
                    (Ok(a), Ok(b)) => {
                        let s = sigma[i] / (2.0 * h);
                        return Ok(std::array::from_fn(|k| (a[k] - b[k]) * s));
                    }
                    (Err(e), _) | (_, Err(e)) => last = Some(e),
                }
                h /= 2.0;
            }
            Err(last.expect("at least one attempt"))
        })
        .collect();
    let mut var = [0.0; N_PROPS];
    for c in columns {
        let c = c?;
        for k in 0..N_PROPS {
            var[k] += c[k] * c[k];
        }
    }
    Ok(var.map(f64::sqrt))
}

/// Seed of Monte Carlo draw `s` (SplitMix64 of the pair), independent of scheduling.
fn draw_seed(seed: u64, s: u64) -> u64 {
    let mut z = seed ^ s.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn monte_carlo<F>(
    f: &F,
    x: &[f64],
    sigma: &[f64],
    samples: usize,
    seed: u64,
) -> Result<[f64; N_PROPS], InertiaError>
where
    F: Fn(&[f64]) -> Result<[f64; N_PROPS], InertiaError> + Sync,
{
    if samples < 2 {
        return Err(InertiaError::LinearAlgebra(
            "Monte Carlo needs at least two samples".into(),
        ));
    }
    let draws: Vec<Option<[f64; N_PROPS]>> = (0..samples as u64)
        .into_par_iter()
        .map(|s| {
            let mut rng = ChaCha8Rng::seed_from_u64(draw_seed(seed, s));
            let xs: Vec<f64> = x
                .iter()
                .zip(sigma)
                .map(|(xi, si)| xi + si * standard_normal(&mut rng))
                .collect();
            f(&xs).ok()
        })
        .collect();
    let ok: Vec<[f64; N_PROPS]> = draws.into_iter().flatten().collect();
    // A draw fails when the perturbed data cannot be processed (e.g. fᵀq ≤ 0); more than
    // 5 % failures means the linear-Gaussian picture is wrong: report it.
    if (ok.len() as f64) < 0.95 * samples as f64 {
        return Err(InertiaError::LinearAlgebra(format!(
            "Monte Carlo: {} of {samples} draws could not be processed; the input uncertainty is too large for this estimator",
            samples - ok.len()
        )));
    }
    let n = ok.len() as f64;
    let mut mean = [0.0; N_PROPS];
    for d in &ok {
        for k in 0..N_PROPS {
            mean[k] += d[k] / n;
        }
    }
    let mut var = [0.0; N_PROPS];
    for d in &ok {
        for k in 0..N_PROPS {
            var[k] += (d[k] - mean[k]).powi(2) / (n - 1.0);
        }
    }
    Ok(var.map(f64::sqrt))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lin(x: &[f64]) -> Result<[f64; N_PROPS], InertiaError> {
        Ok(std::array::from_fn(|k| {
            x.iter()
                .enumerate()
                .map(|(i, xi)| xi * ((i + k) % 3) as f64)
                .sum()
        }))
    }

    #[test]
    fn linear_map_is_propagated_exactly_and_mc_agrees() {
        let x = [1.0, 2.0, 3.0, 4.0];
        let s = [0.1, 0.2, 0.0, 0.4];
        let std = propagate(lin, &x, &s, Propagation::Linearised).unwrap();
        for k in 0..N_PROPS {
            let expect: f64 = (0..4)
                .map(|i| (s[i] * ((i + k) % 3) as f64).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!((std[k] - expect).abs() < 1e-12 * expect.max(1.0), "{k}");
        }
        let monte_carlo = || {
            propagate(
                lin,
                &x,
                &s,
                Propagation::MonteCarlo {
                    samples: 4000,
                    seed: 7,
                },
            )
            .unwrap()
        };
        let mc = monte_carlo();
        for k in 0..N_PROPS {
            // Sample std of 4000 normals: relative standard error 1/sqrt(2·3999) ≈ 1.1 %.
            assert!(
                (mc[k] / std[k] - 1.0).abs() < 0.05,
                "{k}: {} {}",
                mc[k],
                std[k]
            );
        }
        assert_eq!(mc, monte_carlo());
    }
}
