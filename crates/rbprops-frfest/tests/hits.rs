//! Triggering, double-hit and overload detection: unit cases and a 2 000-hit statistical
//! test with realistic noise and quantisation.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rbprops_core::noise::standard_normal;
use rbprops_frfest::*;
use std::f64::consts::{PI, TAU};

fn half_sine_into(x: &mut [f64], fs: f64, start_s: f64, dur_s: f64, amp: f64) {
    for (i, v) in x.iter_mut().enumerate() {
        let t = i as f64 / fs - start_s;
        if t > 0.0 && t < dur_s {
            *v += amp * (PI * t / dur_s).sin();
        }
    }
}

fn quantise(x: &mut [f64], range: f64, bits: u32) {
    let lsb = 2.0 * range / 2f64.powi(bits as i32);
    let (lo, hi) = (
        -(2f64.powi(bits as i32 - 1)),
        2f64.powi(bits as i32 - 1) - 1.0,
    );
    for v in x {
        *v = ((*v / lsb).round().clamp(lo, hi)) * lsb;
    }
}

#[test]
fn single_and_double_hit_cases() {
    let fs = 25_600.0;
    let n = 2560;
    let opts = HitCheckOptions::default();
    let mut f = vec![0.0; n];
    half_sine_into(&mut f, fs, 0.01, 0.002, 200.0);
    let r = inspect_hit(&f, &[], fs, &opts);
    assert!(r.accepted(), "{r:?}");
    assert_eq!(r.trigger, 257 + 1); // 10 % of the peak: sin(πt/T) ≥ 0.1 first at the 2nd sample
    assert!((r.peak_force - 200.0).abs() < 0.1);
    // Separated second hit, 10 ms later at 10 %.
    let mut g = f.clone();
    half_sine_into(&mut g, fs, 0.02, 0.002, 20.0);
    let r = inspect_hit(&g, &[], fs, &opts);
    let d = r.double_hit.expect("double hit");
    assert!(
        (d.delay_s - 0.01).abs() < 2.0 / fs && (d.ratio - 0.1).abs() < 0.005,
        "{d:?}"
    );
    assert!(matches!(r.reasons[0], RejectReason::DoubleHit { .. }));
    // Overlapping: 1.5 ms later at 30 % on a 2 ms pulse.
    let mut g = f.clone();
    half_sine_into(&mut g, fs, 0.0115, 0.002, 60.0);
    assert!(inspect_hit(&g, &[], fs, &opts).double_hit.is_some());
    // A weaker first contact 3 ms before the main one.
    let mut g = f.clone();
    half_sine_into(&mut g, fs, 0.007, 0.002, 30.0);
    let r = inspect_hit(&g, &[], fs, &opts);
    assert!(r.double_hit.is_some(), "{r:?}");
    // Too weak against the noise; at the record's edge.
    let mut g: Vec<f64> = (0..n)
        .map(|i| 0.05 * ((i * 7919 % 13) as f64 - 6.0))
        .collect();
    half_sine_into(&mut g, fs, 0.05, 0.002, 2.0);
    let r = inspect_hit(&g, &[], fs, &opts);
    assert!(
        r.reasons
            .iter()
            .any(|x| matches!(x, RejectReason::TooWeak { .. })),
        "{r:?}"
    );
    let mut g = vec![0.0; n];
    half_sine_into(&mut g, fs, 0.0999, 0.002, 200.0);
    let r = inspect_hit(&g, &[], fs, &opts);
    assert!(r.reasons.contains(&RejectReason::AtRecordEdge), "{r:?}");
}

#[test]
fn overload_cases() {
    let fs = 10_000.0;
    let n = 2000;
    let mut f = vec![0.0; n];
    half_sine_into(&mut f, fs, 0.01, 0.002, 100.0);
    let resp = |amp: f64| -> Vec<f64> {
        (0..n)
            .map(|i| {
                let t = i as f64 / fs - 0.01;
                if t > 0.0 {
                    amp * (-t * 20.0).exp() * (TAU * 150.0 * t).sin()
                } else {
                    0.0
                }
            })
            .collect()
    };
    // Range given: a peak of ~1.5 × range clips several samples; one clipped sample is not
    // an overload.
    let mut x = resp(15.0);
    quantise(&mut x, 10.0, 16);
    let opts = HitCheckOptions {
        response_ranges: vec![Some(10.0)],
        ..Default::default()
    };
    let r = inspect_hit(&f, &[&x], fs, &opts);
    assert!(r.clipped[1] >= 2, "{r:?}");
    assert!(matches!(
        r.reasons[0],
        RejectReason::Overload {
            channel: Channel::Response(0),
            ..
        }
    ));
    let mut y = resp(8.0);
    let imax = (0..n)
        .max_by(|a, b| y[*a].abs().total_cmp(&y[*b].abs()))
        .unwrap();
    y[imax] = 10.0 * y[imax].signum();
    let r = inspect_hit(&f, &[&y], fs, &opts);
    assert_eq!(r.clipped[1], 1);
    assert!(r.accepted(), "{r:?}");
    // Inferred: the same clipped record without a range.
    let r = inspect_hit(&f, &[&x], fs, &HitCheckOptions::default());
    assert!(r.clipped[1] >= 2 && !r.accepted(), "{r:?}");
    // A slow, finely sampled peak quantised coarsely repeats its top code: not clipping.
    let slow: Vec<f64> = (0..n)
        .map(|i| {
            let t = i as f64 / fs - 0.01;
            if t > 0.0 {
                (TAU * 2.0 * t).sin() * 5.0
            } else {
                0.0
            }
        })
        .collect();
    let mut s = slow.clone();
    quantise(&mut s, 10.0, 12);
    let r = inspect_hit(&f, &[&s], fs, &HitCheckOptions::default());
    assert_eq!(r.clipped[1], 0, "{r:?}");
}

#[test]
fn throughput_triggers_and_edges() {
    let fs = 1000.0;
    let mut f = vec![0.0; 5000];
    for start in [0.002, 1.0, 2.5, 4.9] {
        half_sine_into(&mut f, fs, start, 0.005, 100.0);
    }
    let t = find_hits(
        &f,
        fs,
        &TriggerOptions {
            level: TriggerLevel::FractionOfMax(0.1),
            pretrigger_s: 0.01,
            record_len_samples: 1000,
            holdoff_s: None,
        },
    );
    assert_eq!(t.len(), 4, "{t:?}");
    assert_eq!(t[0].at_edge, Some(Edge::Start));
    assert_eq!(t[1].at_edge, None);
    assert_eq!(t[1].range(1000), Some(t[1].index - 10..t[1].index + 990));
    assert_eq!(t[2].at_edge, None);
    assert_eq!(t[3].at_edge, Some(Edge::End));
}

/// 2 000 simulated hits: half-sine pulses of 0.2–5 ms, ~200 N, force noise 0.05 N, 16-
/// or 24-bit quantisation with an autoranged force range (1.2–3 × the peak), half of
/// them with a second contact 0.5–20 ms later at 5–50 % (its duration 0.8–1.2 × the
/// first's); a response of two damped modes whose range is 0.6–2 × its peak (clipping in
/// about a third of the hits). Sampled at 25.6 kHz, 0.2 s records, 20 ms pretrigger.
///
/// Measured and asserted: overload flagged on every hit with ≥ 2 clipped samples and on
/// none with fewer when the range is given (inferred from flat tops: measured, see below); double hits: no false alarm on single
/// hits (≤ 1 % asserted), recall ≥ 99 % on second contacts that leave a valley (start
/// after the first pulse's midpoint); the overall recall, including shoulders that no
/// time-domain test sees, is printed.
#[test]
fn statistical_detection_over_2000_hits() {
    let fs = 25_600.0;
    let n = 5120;
    let mut rng = ChaCha8Rng::seed_from_u64(2026);
    let (mut singles, mut false_alarms) = (0, 0);
    let (mut doubles, mut found) = (0, 0);
    let (mut valley_doubles, mut valley_found) = (0, 0);
    let mut clip_errors = (0, 0, 0);
    for hit in 0..2000 {
        let dur = 0.0002 + rng.random::<f64>() * 0.0048;
        let amp = 150.0 + 100.0 * rng.random::<f64>();
        let t0 = 0.02 + rng.random::<f64>() / fs;
        let mut f = vec![0.0; n];
        half_sine_into(&mut f, fs, t0, dur, amp);
        let double = hit % 2 == 1;
        let mut valley = false;
        if double {
            let d = 0.0005 + rng.random::<f64>() * 0.0195;
            let ratio = 0.05 + rng.random::<f64>() * 0.45;
            let dur2 = dur * (0.8 + 0.4 * rng.random::<f64>());
            half_sine_into(&mut f, fs, t0 + d, dur2, ratio * amp);
            valley = d > 0.5 * dur + 0.5 * dur2;
        }
        for v in f.iter_mut() {
            *v += 0.05 * standard_normal(&mut rng);
        }
        let bits = if hit % 4 < 2 { 16 } else { 24 };
        let frange = amp * (1.2 + 1.8 * rng.random::<f64>());
        quantise(&mut f, frange, bits);
        // Response: two damped modes driven by the first pulse (shape only matters for
        // clipping).
        let mut x: Vec<f64> = (0..n)
            .map(|i| {
                let t = i as f64 / fs - t0;
                if t > 0.0 {
                    (-t * 8.0).exp() * (TAU * 37.0 * t).sin()
                        + 0.6 * (-t * 30.0).exp() * (TAU * 410.0 * t + 0.4).sin()
                } else {
                    0.0
                }
            })
            .collect();
        for v in x.iter_mut() {
            *v += 1e-4 * standard_normal(&mut rng);
        }
        let peak = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let xrange = peak * (0.6 + 1.4 * rng.random::<f64>());
        let lsb = 2.0 * xrange / 2f64.powi(bits as i32);
        let truth_clipped = x
            .iter()
            .filter(|v| **v >= xrange - 0.5 * lsb || **v < -xrange - 0.5 * lsb)
            .count();
        quantise(&mut x, xrange, bits);
        for (k, opts) in [
            HitCheckOptions {
                force_range: Some(frange),
                response_ranges: vec![Some(xrange)],
                ..Default::default()
            },
            HitCheckOptions::default(),
        ]
        .iter()
        .enumerate()
        {
            let r = inspect_hit(&f, &[&x], fs, opts);
            let flagged = r
                .reasons
                .iter()
                .any(|x| matches!(x, RejectReason::Overload { .. }));
            if flagged != (truth_clipped >= 2) {
                if k == 0 {
                    clip_errors.0 += 1
                } else {
                    clip_errors.1 += 1;
                    if std::env::var("SHOW").is_ok() {
                        eprintln!(
                            "hit {hit}: truth {truth_clipped}, found {} bits {bits}",
                            r.clipped[1]
                        );
                    }
                }
            }
            if k == 0 {
                let dh = r.double_hit.is_some();
                if double {
                    doubles += 1;
                    found += dh as usize;
                    if valley {
                        valley_doubles += 1;
                        valley_found += dh as usize;
                    }
                } else {
                    singles += 1;
                    false_alarms += dh as usize;
                }
                if truth_clipped >= 2 {
                    clip_errors.2 += 1;
                }
            }
        }
    }
    let recall = found as f64 / doubles as f64;
    let valley_recall = valley_found as f64 / valley_doubles as f64;
    let fa = false_alarms as f64 / singles as f64;
    eprintln!(
        "double hits: recall {recall:.4} ({found}/{doubles}), with a valley {valley_recall:.4} ({valley_found}/{valley_doubles}), false alarms {fa:.4} ({false_alarms}/{singles}); overload mismatches: range given {}, inferred {} (of {} hits with ≥ 2 clipped)",
        clip_errors.0, clip_errors.1, clip_errors.2
    );
    assert!(fa <= 0.01);
    assert!(valley_recall >= 0.99);
    assert_eq!(clip_errors.0, 0);
    // Inferred ranges (flat tops) are not asserted: on noisy 16-bit records a smooth peak
    // can repeat its top code with noise-sized steps around it (measured: 35 of 2 000
    // hits mismatched, all false flags on unclipped channels). Pass the range.
    assert!(clip_errors.1 <= 50, "{}", clip_errors.1);
}
