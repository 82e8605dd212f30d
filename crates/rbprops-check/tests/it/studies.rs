//! Longer studies, run on demand (release recommended):
//! `cargo test -p rbprops-check --release --test it -- --ignored --nocapture studies::`

use crate::common::*;
use rbprops_check::{check, CheckOptions};

/// Null study: 100 seeded replicates with only nominal-parameter errors (mass, CoM,
/// stiffness, damping, drawn per seed) and 1 % noise, noise estimated from the data.
/// Prints the rate of replicates with nothing claimed and at the noise floor; requires
/// ≥ 95 % of each (M8; the noise band's own tail is far below 5 %).
#[test]
#[ignore]
fn null_study_100_replicates() {
    let nom = nominal(1000);
    let t0 = std::time::Instant::now();
    let mut clean = 0;
    let mut at_floor = 0;
    let mut claims = Vec::new();
    for seed in 0..100u64 {
        // Deterministic pseudo-random parameter errors per seed (±3 % mass, ±10 % springs,
        // ±5 mm CoM, ±30 % damping).
        let u = |k: u64| (((seed * 7919 + k * 104_729) % 1000) as f64 / 1000.0) * 2.0 - 1.0;
        let mut truth = nom.clone();
        truth.body.mass_kg *= 1.0 + 0.03 * u(1);
        truth.body.com_m[0] += 0.005 * u(2);
        truth.body.com_m[2] += 0.005 * u(3);
        for s in &mut truth.setups {
            for sp in &mut s.springs {
                if let Some(k) = &mut sp.stiffness_n_per_m {
                    k[0] *= 1.0 + 0.1 * u(4);
                    k[2] *= 1.0 + 0.1 * u(5);
                }
            }
        }
        truth.damping.ratio = Some(0.015 * (1.0 + 0.3 * u(6)));
        let (g, frf) = record_sim(&truth, &[], 0.01, 1000 + seed);
        let r = check(&nom, &g, &frf, &CheckOptions::default())
            .unwrap()
            .report;
        at_floor += usize::from(r.noise_floor_reached);
        if !r.noise_floor_reached {
            claims.push(format!("seed {seed}: not at the floor: {}", r.verdict));
        }
        if r.accepted.is_empty() && r.ambiguous.is_empty() {
            clean += 1;
        } else {
            claims.push(format!("seed {seed}: {}", r.verdict));
        }
    }
    println!(
        "null study: nothing claimed in {clean} of 100 replicates, at the noise floor in {at_floor} ({:.1} s)",
        t0.elapsed().as_secs_f64()
    );
    for c in &claims {
        println!("  {c}");
    }
    assert!(clean >= 95, "false claims in {} of 100", 100 - clean);
    assert!(
        at_floor >= 95,
        "not at the noise floor in {} of 100",
        100 - at_floor
    );
}

/// Test Case II, 3 excitations × 9 channels × 1000 lines, concealed gravity stiffness,
/// noise from the data: prints the wall time (< 30 s required in release).
#[test]
#[ignore]
fn test_case_2_timing() {
    let nom = nominal(1000);
    let mut truth = nom.clone();
    truth.body.mass_kg *= 1.02;
    let (g, frf) = record_sim(
        &truth,
        &["id = \"gravity_stiffness\"\ncord_length_m = [1.0]"],
        0.01,
        7,
    );
    let t0 = std::time::Instant::now();
    let r = check(&nom, &g, &frf, &CheckOptions::default())
        .unwrap()
        .report;
    let dt = t0.elapsed().as_secs_f64();
    println!(
        "Test Case II 3×9×1000: {dt:.2} s on {} rayon threads; {}",
        rayon::current_num_threads(),
        r.verdict
    );
    let named: Vec<&str> = r.accepted.iter().map(|a| a.id.as_str()).collect();
    assert_eq!(named, ["gravity_stiffness"], "{}", r.verdict);
    assert!(
        r.ambiguous.is_empty() && r.noise_floor_reached,
        "{}",
        r.verdict
    );
    if !cfg!(debug_assertions) {
        assert!(dt < 30.0, "{dt} s");
    }
}
