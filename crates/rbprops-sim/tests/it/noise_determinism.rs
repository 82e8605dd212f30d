//! Noise statistics and reproducibility.

use crate::common::spec;
use rbprops_core::c64;
use rbprops_sim::simulate;

/// Noise normalised by its specified scale, `ε / (√(rel²|H|² + floor²)/√2)` (the
/// workspace's noise model, `E|ε|² = a²|H|² + b²`), must have independent
/// standard-normal real and imaginary parts. The floor is comparable with rel·|H| over
/// part of the band, where the old draw `σ = a|H| + b` gave up to twice the variance
/// (at a|H| = b: (2b)² against 2b²): the variance test below, ±4·√(2/n) ≈ ±0.008 for
/// n ≈ 58 000, tells the two apart.
#[test]
fn noise_has_the_specified_distribution() {
    let mut s = spec("test-case-2");
    s.quantity = rbprops_core::Quantity::Receptance;
    let clean = simulate(&s).unwrap().frf;
    let floor = 1e-6; // comparable with |H| in part of the band
    s.noise.relative = 0.02;
    s.noise.floor = floor;
    s.seed = 12345;
    let noisy = simulate(&s).unwrap().frf;
    let mut z = Vec::new();
    for (h, y) in clean.values.iter().zip(&noisy.values) {
        let sigma = (0.02 * h.norm()).hypot(floor) / std::f64::consts::SQRT_2;
        let e: c64 = (y - h) / sigma;
        z.push(e.re);
        z.push(e.im);
    }
    let n = z.len() as f64;
    let mean = z.iter().sum::<f64>() / n;
    let var = z.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    let kurt = z.iter().map(|x| (x - mean).powi(4)).sum::<f64>() / n / var.powi(2);
    // 4-sigma bands: mean ~ N(0, 1/n), variance ~ N(1, 2/n), kurtosis ~ N(3, 24/n).
    assert!(mean.abs() < 4.0 / n.sqrt(), "mean {mean}");
    assert!((var - 1.0).abs() < 4.0 * (2.0 / n).sqrt(), "variance {var}");
    assert!(
        (kurt - 3.0).abs() < 4.0 * (24.0 / n).sqrt(),
        "kurtosis {kurt}"
    );
    // Real and imaginary parts uncorrelated.
    let m = z.len() / 2;
    let corr = (0..m).map(|i| z[2 * i] * z[2 * i + 1]).sum::<f64>() / m as f64;
    assert!(
        corr.abs() < 4.0 / (m as f64).sqrt(),
        "re/im correlation {corr}"
    );
    // Lag-1 correlation along lines (independent draws per value).
    let lag = (0..m - 1).map(|i| z[2 * i] * z[2 * i + 2]).sum::<f64>() / (m - 1) as f64;
    assert!(
        lag.abs() < 4.0 / (m as f64).sqrt(),
        "lag-1 correlation {lag}"
    );
}

#[test]
fn noise_streams_differ_between_excitations_and_seeds() {
    let mut s = spec("test-case-2");
    s.noise.floor = 1.0;
    let clean_s = {
        let mut c = s.clone();
        c.noise = Default::default();
        c
    };
    let clean = simulate(&clean_s).unwrap().frf;
    let a = simulate(&s).unwrap().frf;
    let d0 = a.frf(0, 0)[5] - clean.frf(0, 0)[5];
    let d1 = a.frf(1, 0)[5] - clean.frf(1, 0)[5];
    assert_ne!(d0, d1);
    s.seed += 1;
    let b = simulate(&s).unwrap().frf;
    assert_ne!(a.values, b.values);
    s.seed -= 1;
    assert_eq!(
        simulate(&s).unwrap().frf.values,
        a.values,
        "same seed, same noise"
    );
}

#[test]
fn identical_for_one_and_two_threads() {
    let s = spec("demo");
    let run = |n: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
            .install(|| simulate(&s).unwrap())
    };
    let a = run(1);
    let b = run(2);
    assert_eq!(a.frf.values, b.frf.values);
    assert_eq!(a.truth, b.truth);
}
