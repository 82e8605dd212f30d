//! Exact tests of the estimators, the windows and the line correlation, and the Monte
//! Carlo calibration of each line's variance.

// Index loops over channels and lines read like the equations they check.
#![allow(clippy::needless_range_loop)]

use rbprops_core::noise::NormalStream;
use rbprops_frfest::*;
use std::f64::consts::{PI, TAU};

/// Naive DFT at line k (the test's own, independent of the FFT).
fn dft(x: &[f64], k: usize) -> c64 {
    let n = x.len();
    x.iter()
        .enumerate()
        .map(|(i, v)| c64::from_polar(*v, -TAU * ((k * i) % n) as f64 / n as f64))
        .sum()
}

/// Sampled single-DOF impulse response (receptance, m = 1 kg): e^{−σt} sin(ω_d t)/ω_d.
fn sdof(n: usize, fs: f64, f0: f64, zeta: f64) -> Vec<f64> {
    let w0 = TAU * f0;
    let wd = w0 * (1.0 - zeta * zeta).sqrt();
    (0..n)
        .map(|i| {
            let t = i as f64 / fs;
            (-zeta * w0 * t).exp() * (wd * t).sin() / wd / fs
        })
        .collect()
}

fn circular(h: &[f64], f: &[f64]) -> Vec<f64> {
    let n = h.len();
    (0..n)
        .map(|i| (0..n).map(|j| h[j] * f[(i + n - j) % n]).sum())
        .collect()
}

fn linear(h: &[f64], f: &[f64]) -> Vec<f64> {
    (0..f.len())
        .map(|i| (0..=i).map(|j| h[j] * f[i - j]).sum())
        .collect()
}

fn normals(seed: u64, stream: u64, n: usize, s: f64) -> Vec<f64> {
    let mut g = NormalStream::new(seed, stream);
    (0..n).map(|_| s * g.pair().0).collect()
}

fn half_sine(n: usize, fs: f64, start_s: f64, dur_s: f64, amp: f64) -> Vec<f64> {
    (0..n)
        .map(|i| {
            let t = i as f64 / fs - start_s;
            if t > 0.0 && t < dur_s {
                amp * (PI * t / dur_s).sin()
            } else {
                0.0
            }
        })
        .collect()
}

fn rel_err(a: c64, b: c64) -> f64 {
    (a - b).norm() / b.norm()
}

/// A noise-free SDOF system driven by broadband forces through circular convolution:
/// H1 over 3 hits equals DFT(h) (the DFT ratio) to 1e-12 at every line, and H2 = Hv = H1.
#[test]
fn noise_free_sdof_h1_is_the_dft_ratio_and_h1_h2_hv_agree() {
    let (n, fs) = (512, 512.0);
    let h = sdof(n, fs, 40.0, 0.02);
    let mut sums = SpectralSums::new(n, fs, 1, 1).unwrap();
    for d in 0..3 {
        let f = normals(7, d, n, 10.0);
        let y = circular(&h, &f);
        sums.add_hit(&[&f], &[&y]).unwrap();
    }
    let c = ConditioningOptions::default();
    let h1 = sums.h1(None, &c).unwrap();
    let h2 = sums.h2(None).unwrap();
    let hv = sums.hv(None, &c).unwrap();
    let mut worst = [0.0f64; 3];
    for k in 0..sums.lines() {
        let exact = dft(&h, k);
        worst[0] = worst[0].max(rel_err(h1.h(0, 0, k), exact));
        worst[1] = worst[1].max(rel_err(h2.h(0, 0, k), h1.h(0, 0, k)));
        worst[2] = worst[2].max(rel_err(hv.h(0, 0, k), h1.h(0, 0, k)));
        assert!((h1.coherence_of(0)[k] - 1.0).abs() < 1e-12);
    }
    assert!(worst.iter().all(|w| *w < 1e-12), "{worst:?}");
    // n_d = 3: the variance is known and ~0.
    assert!(h1.variance.is_some());
}

/// The H1 with a force window (taper) and the exponential window on force and response
/// equals an independent computation: the windows written here from their definitions,
/// naive DFT sums: 1e-12 relative to the FRF's largest value (line by line the ratio's
/// rounding grows where the windowed pulse's spectrum is small).
#[test]
fn windowed_h1_equals_a_direct_computation() {
    let (n, fs) = (400, 2000.0);
    let h = sdof(n, fs, 90.0, 0.01);
    let fw = ForceWindow {
        pre_s: 0.004,
        post_s: 0.003,
        taper_s: 0.002,
    };
    let tau = 0.05;
    let rw = ResponseWindow::Exponential { tau_s: tau };
    let mut sums = SpectralSums::new(n, fs, 1, 2).unwrap();
    let mut win = HitWindows::new(n);
    let (mut sxf, mut sff) = (
        vec![[c64::new(0.0, 0.0); 2]; n / 2 + 1],
        vec![0.0; n / 2 + 1],
    );
    for d in 0..4 {
        let mut f = half_sine(n, fs, 0.02 + 0.001 * d as f64, 0.003, 100.0 + d as f64);
        for (v, e) in f.iter_mut().zip(normals(3, d, n, 0.05)) {
            *v += e;
        }
        let y0 = linear(&h, &f);
        let y1: Vec<f64> = y0
            .iter()
            .zip(normals(4, d, n, 1e-6))
            .map(|(a, b)| 2.0 * a + b)
            .collect();
        let rep = inspect_hit(&f, &[&y0, &y1], fs, &HitCheckOptions::default());
        assert!(rep.accepted(), "{rep:?}");
        win.set(fs, rep.trigger, rep.pulse_end, Some(&fw), &rw, true);
        sums.add_windowed_hit(&[&f], &[&y0, &y1], Some(&win.force), Some(&win.response))
            .unwrap();
        // Independent windows.
        let (a, b, m) = (rep.trigger as i64 - 8, rep.pulse_end as i64 + 6, 4i64);
        let wf: Vec<f64> = (0..n as i64)
            .map(|i| {
                let rect = if i >= a && i < b {
                    1.0
                } else if i < a && a - i <= m {
                    0.5 + 0.5 * (PI * (a - i) as f64 / m as f64).cos()
                } else if i >= b && i - b < m {
                    0.5 + 0.5 * (PI * (i - b + 1) as f64 / m as f64).cos()
                } else {
                    0.0
                };
                rect * (-((i - rep.trigger as i64) as f64) / fs / tau).exp()
            })
            .collect();
        let wr: Vec<f64> = (0..n as i64)
            .map(|i| (-((i - rep.trigger as i64) as f64) / fs / tau).exp())
            .collect();
        for (x, w) in win.force.iter().zip(&wf) {
            assert!((x - w).abs() < 1e-14);
        }
        let fwd: Vec<f64> = f.iter().zip(&wf).map(|(a, b)| a * b).collect();
        let ywd: Vec<Vec<f64>> = [&y0, &y1]
            .iter()
            .map(|y| y.iter().zip(&wr).map(|(a, b)| a * b).collect())
            .collect();
        for k in 0..=n / 2 {
            let fk = dft(&fwd, k);
            sff[k] += fk.norm_sqr();
            for o in 0..2 {
                sxf[k][o] += dft(&ywd[o], k) * fk.conj();
            }
        }
    }
    let est = sums.h1(None, &ConditioningOptions::default()).unwrap();
    let mut worst = 0.0f64;
    for o in 0..2 {
        let top = est.frf(o, 0).iter().fold(0.0f64, |m, h| m.max(h.norm()));
        for k in 0..=n / 2 {
            worst = worst.max((est.h(o, 0, k) - sxf[k][o] / sff[k]).norm() / top);
        }
    }
    assert!(worst < 1e-12, "{worst}");
}

/// The exponential window on force and response turns H into H(iω + 1/τ): with a long
/// record (response decayed) the windowed H1 equals the DFT of e^{−t/τ} h(t).
#[test]
fn exponential_window_shifts_the_poles_exactly() {
    let (n, fs) = (4096, 1024.0);
    let h = sdof(n, fs, 30.0, 0.05);
    let tau = 0.4;
    let q: Vec<f64> = (0..n).map(|i| (-(i as f64) / fs / tau).exp()).collect();
    let hw: Vec<f64> = h.iter().zip(&q).map(|(a, b)| a * b).collect();
    let mut sums = SpectralSums::new(n, fs, 1, 1).unwrap();
    let mut win = HitWindows::new(n);
    for d in 0..2 {
        let f = half_sine(n, fs, 0.05, 0.004 + 0.001 * d as f64, 50.0);
        let y = linear(&h, &f);
        let rep = inspect_hit(&f, &[&y], fs, &HitCheckOptions::default());
        win.set(
            fs,
            rep.trigger,
            rep.pulse_end,
            None,
            &ResponseWindow::Exponential { tau_s: tau },
            true,
        );
        sums.add_windowed_hit(&[&f], &[&y], Some(&win.force), Some(&win.response))
            .unwrap();
    }
    let est = sums
        .h1(Some(1..200), &ConditioningOptions::default())
        .unwrap();
    let mut worst = 0.0f64;
    for (j, k) in (1..200).enumerate() {
        worst = worst.max(rel_err(est.h(0, 0, j), dft(&hw, k)));
    }
    // The un-windowed response is at e^{-0.05·2π·30·4} ≈ 4e-17 of its start at the end.
    assert!(worst < 1e-10, "{worst}");
}

/// MIMO: two uncorrelated broadband forces into three responses, circular convolution:
/// H1 recovers every DFT(h_or) to 1e-11; Hv agrees; fully coherent inputs are an error
/// naming the line.
#[test]
fn mimo_h1_recovers_a_two_input_system_and_coherent_inputs_fail() {
    let (n, fs) = (256, 256.0);
    let hs: Vec<Vec<Vec<f64>>> = (0..3)
        .map(|o| {
            (0..2)
                .map(|r| sdof(n, fs, 20.0 + 7.0 * o as f64 + 13.0 * r as f64, 0.03))
                .collect()
        })
        .collect();
    let mut sums = SpectralSums::new(n, fs, 2, 3).unwrap();
    let mut bad = SpectralSums::new(n, fs, 2, 3).unwrap();
    for d in 0..6 {
        let f0 = normals(11, 2 * d, n, 1.0);
        let f1 = normals(11, 2 * d + 1, n, 1.0);
        let ys: Vec<Vec<f64>> = (0..3)
            .map(|o| {
                let a = circular(&hs[o][0], &f0);
                let b = circular(&hs[o][1], &f1);
                a.iter().zip(&b).map(|(x, y)| x + y).collect()
            })
            .collect();
        let yr: Vec<&[f64]> = ys.iter().map(|v| v.as_slice()).collect();
        sums.add_hit(&[&f0, &f1], &yr).unwrap();
        let f1c: Vec<f64> = f0.iter().map(|v| 2.0 * v).collect();
        bad.add_hit(&[&f0, &f1c], &yr).unwrap();
    }
    let c = ConditioningOptions::default();
    let h1 = sums.h1(None, &c).unwrap();
    let hv = sums.hv(None, &c).unwrap();
    let (mut worst, mut worst_v) = (0.0f64, 0.0f64);
    for o in 0..3 {
        for r in 0..2 {
            for k in 0..sums.lines() {
                worst = worst.max(rel_err(h1.h(o, r, k), dft(&hs[o][r], k)));
                worst_v = worst_v.max(rel_err(hv.h(o, r, k), h1.h(o, r, k)));
            }
        }
        assert!(h1.coherence_of(o).iter().all(|g| (g - 1.0).abs() < 1e-10));
    }
    assert!(worst < 1e-11, "H1 {worst}");
    assert!(worst_v < 1e-8, "Hv {worst_v}");
    match bad.h1(None, &c) {
        Err(FrfError::IllConditioned { line, .. }) => assert_eq!(line, 0),
        other => panic!("{other:?}"),
    }
    // One hit, two references: singular by construction.
    let mut one = SpectralSums::new(n, fs, 2, 1).unwrap();
    let f0 = normals(1, 0, n, 1.0);
    let f1 = normals(1, 1, n, 1.0);
    one.add_hit(&[&f0, &f1], &[&f0]).unwrap();
    assert!(matches!(
        one.h1(None, &c),
        Err(FrfError::IllConditioned { .. })
    ));
}

/// One run of the variance Monte Carlo: sums of |Ĥ−H|² and σ̂² (raw and smoothed).
fn variance_run(window: Option<f64>, seeds: u64, n_d: u64) -> (f64, f64, f64) {
    let (n, fs) = (256, 256.0);
    let h = sdof(n, fs, 50.0, 0.03);
    let (mut err, mut var, mut svar) = (0.0, 0.0, 0.0);
    let mut win = HitWindows::new(n);
    let c = ConditioningOptions::default();
    let band = 1..n / 2;
    for seed in 0..seeds {
        let mut noisy = SpectralSums::new(n, fs, 1, 1).unwrap();
        let mut clean = SpectralSums::new(n, fs, 1, 1).unwrap();
        for d in 0..n_d {
            let f = half_sine(n, fs, 0.03, 0.006 + 0.001 * d as f64, 100.0);
            let y = circular(&h, &f);
            let e = normals(seed, d, n, 0.002);
            let yn: Vec<f64> = y.iter().zip(&e).map(|(a, b)| a + b).collect();
            let rw = match window {
                Some(t) => ResponseWindow::Exponential { tau_s: t },
                None => ResponseWindow::None,
            };
            win.set(fs, 8, 10, None, &rw, true);
            noisy
                .add_windowed_hit(&[&f], &[&yn], Some(&win.force), Some(&win.response))
                .unwrap();
            clean
                .add_windowed_hit(&[&f], &[&y], Some(&win.force), Some(&win.response))
                .unwrap();
        }
        let est = noisy.h1(Some(band.clone()), &c).unwrap();
        let truth = clean.h1(Some(band.clone()), &c).unwrap();
        let v = est.variance_of(0, 0).unwrap();
        let sm = smoothed_variance(&est, 3, None).unwrap();
        for j in 0..est.len() {
            err += (est.h(0, 0, j) - truth.h(0, 0, j)).norm_sqr();
            var += v[j];
            svar += sm.variance[j];
        }
    }
    (err, var, svar)
}

/// Each line's H1 variance is calibrated: over 400 seeds × 127 lines with response noise,
/// Σ|Ĥ − H|² / Σσ̂² ≈ 1 (H the noise-free H1 with the same windows), raw and smoothed.
///
/// Tolerance: |Ĥ−H|²/(σ_N²/S_ff) is exponential (sd 1), so over M = 50 800 values the
/// numerator's relative SE is 1/√M = 0.0044; σ̂² has 2(n_d − 1) = 8 degrees of freedom
/// (relative sd 0.5, SE 0.0022) and is independent of Ĥ − H (Gaussian noise: the residual
/// is orthogonal to the force projection). The ratio's SE is ≈ 0.005; 4 SE = 0.02. With
/// the exponential window (τ = T/2) neighbouring lines are correlated: the effective M
/// falls by Σ_m |γ_m|² ≈ 2.2, SE ≈ 0.0074, bound 0.035. The smoothed (±3 lines) estimate's
/// denominator is smoother, same bounds.
#[test]
fn h1_variance_is_calibrated_by_monte_carlo() {
    for (window, tol) in [(None, 0.02), (Some(0.5), 0.035)] {
        let (err, var, svar) = variance_run(window, 400, 5);
        let (r, rs) = (err / var, err / svar);
        eprintln!("window {window:?}: E|Ĥ−H|²/σ̂² = {r:.4}, smoothed {rs:.4}");
        assert!((r - 1.0).abs() < tol, "{window:?}: ratio {r}");
        assert!((rs - 1.0).abs() < tol, "{window:?}: smoothed ratio {rs}");
    }
}

/// n_d = 1: the variance is unknown (None), and so is the quality summary.
#[test]
fn one_average_has_no_variance() {
    let (n, fs) = (64, 64.0);
    let mut s = SpectralSums::new(n, fs, 1, 1).unwrap();
    let f = half_sine(n, fs, 0.1, 0.05, 1.0);
    s.add_hit(&[&f], &[&f]).unwrap();
    let est = s.h1(None, &ConditioningOptions::default()).unwrap();
    assert!(est.variance.is_none());
    assert!(quality(&est).is_none());
    assert!(smoothed_variance(&est, 2, None).is_none());
}

/// The line correlation of the exponential window equals its closed form (1e-12) from
/// any trigger, and a Monte Carlo of windowed white noise (4 000 records × 64 lines).
///
/// Tolerance of the Monte Carlo: each product ε_k ε̄_{k−m}/E|ε|² has sd ≤ 1; the lines
/// of one record are correlated, so take the records (4 000) as the sample count:
/// SE ≤ 1/√4000 = 0.016 per component, bound 0.06 (≈ 4 SE).
#[test]
fn line_correlation_is_exact_and_matches_monte_carlo() {
    let (n, fs, tau) = (256usize, 100.0, 0.6);
    for trigger in [0usize, 17] {
        let w = ResponseWindow::Exponential { tau_s: tau }.values(n, fs, trigger);
        let g = line_correlation(&w, 6);
        assert!((g[0] - c64::new(1.0, 0.0)).norm() < 1e-14);
        for (m, gm) in g.iter().enumerate() {
            let exact = exponential_line_correlation(tau, fs, n, m);
            assert!((gm - exact).norm() < 1e-12, "m={m}: {gm} vs {exact}");
        }
    }
    let w = ResponseWindow::Exponential { tau_s: tau }.values(n, fs, 0);
    let g = line_correlation(&w, 2);
    let mut planner = realfft::RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(n);
    let mut spec = fft.make_output_vec();
    let (mut c0, mut c1, mut c2) = (0.0, c64::new(0.0, 0.0), c64::new(0.0, 0.0));
    let mut gen = NormalStream::new(99, 0);
    for _ in 0..4000 {
        let mut x: Vec<f64> = w.iter().map(|wi| wi * gen.pair().0).collect();
        fft.process(&mut x, &mut spec).unwrap();
        for k in 10..74 {
            c0 += spec[k].norm_sqr();
            c1 += spec[k] * spec[k - 1].conj();
            c2 += spec[k] * spec[k - 2].conj();
        }
    }
    assert!((c1 / c0 - g[1]).norm() < 0.06, "{} vs {}", c1 / c0, g[1]);
    assert!((c2 / c0 - g[2]).norm() < 0.06, "{} vs {}", c2 / c0, g[2]);
    assert!(g[1].norm() > 0.3);
}

/// auto_tau: a response decaying to 10 % of its peak at the end gets τ with
/// 0.1 e^{−T/τ} = 0.01; an already decayed one gets none.
#[test]
fn auto_tau_reaches_one_percent() {
    let (n, fs) = (2048, 1024.0);
    // Envelope e^{−t/τ0}, τ0 chosen so the end is at 10 %.
    let t_end = (n - 1) as f64 / fs;
    let tau0 = t_end / 10f64.ln();
    let x: Vec<f64> = (0..n)
        .map(|i| {
            let t = i as f64 / fs;
            (-t / tau0).exp() * (TAU * 100.0 * t + 0.3).cos()
        })
        .collect();
    let tau = auto_tau(&x, fs, 0).unwrap();
    let end_env = x[n - n / 20..].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let peak = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!((end_env * (-t_end / tau).exp() / (0.01 * peak) - 1.0).abs() < 1e-9);
    assert!((tau / (t_end / 10f64.ln()) - 1.0).abs() < 0.05, "{tau}");
    let y: Vec<f64> = x
        .iter()
        .enumerate()
        .map(|(i, v)| v * (-(i as f64) / 100.0).exp())
        .collect();
    assert!(auto_tau(&y, fs, 0).is_none());
}

/// Quantity conversion: accelerance of a receptance multiplies by −ω²; back again
/// divides, the ω = 0 line excluded (no NaN); the variance scales by ω⁴.
#[test]
fn quantity_conversion_round_trip() {
    let (n, fs) = (128, 128.0);
    let h = sdof(n, fs, 10.0, 0.05);
    let mut s = SpectralSums::new(n, fs, 1, 1).unwrap();
    for d in 0..3 {
        let f = normals(5, d, n, 1.0);
        let y: Vec<f64> = circular(&h, &f)
            .iter()
            .zip(normals(6, d, n, 1e-5))
            .map(|(a, b)| a + b)
            .collect();
        s.add_hit(&[&f], &[&y]).unwrap();
    }
    let est = s.h1(None, &ConditioningOptions::default()).unwrap();
    let acc = convert_quantity(&est, Quantity::Receptance, Quantity::Accelerance);
    assert_eq!(acc.lines, 0..65);
    let back = convert_quantity(&acc, Quantity::Accelerance, Quantity::Receptance);
    assert_eq!(back.lines, 1..65);
    for j in 0..back.len() {
        let k = j + 1;
        let w = TAU * k as f64;
        assert!(rel_err(acc.h(0, 0, k), -w * w * est.h(0, 0, k)) < 1e-14);
        assert!(rel_err(back.h(0, 0, j), est.h(0, 0, k)) < 1e-13);
        assert!(back.h(0, 0, j).is_finite());
        let (va, ve) = (
            acc.variance_of(0, 0).unwrap()[k],
            est.variance_of(0, 0).unwrap()[k],
        );
        assert!((va / (ve * w.powi(4)) - 1.0).abs() < 1e-13);
    }
    let q = quality(&est).unwrap();
    assert_eq!(q.more_hits_to_halve, 9);
    assert!(q.relative_se > 0.0 && q.relative_se < 0.1, "{q:?}");
}

/// Same input, bit-identical output.
#[test]
fn deterministic() {
    let run = || {
        let (n, fs) = (128, 128.0);
        let h = sdof(n, fs, 10.0, 0.05);
        let mut s = SpectralSums::new(n, fs, 1, 1).unwrap();
        for d in 0..3 {
            let f = normals(5, d, n, 1.0);
            let y: Vec<f64> = circular(&h, &f)
                .iter()
                .zip(normals(6, d, n, 1e-3))
                .map(|(a, b)| a + b)
                .collect();
            s.add_hit(&[&f], &[&y]).unwrap();
        }
        s.h1(None, &ConditioningOptions::default()).unwrap()
    };
    let (a, b) = (run(), run());
    assert!(a
        .h
        .iter()
        .zip(&b.h)
        .all(|(x, y)| x.re.to_bits() == y.re.to_bits() && x.im.to_bits() == y.im.to_bits()));
}
