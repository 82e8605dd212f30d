//! Calibration of the reported standard errors: with residue noise of the stated standard
//! deviation, the 95 % intervals must contain the truth in at least 90 % of the runs for
//! every property and estimator.
//!
//! Why 400 runs and not 50: a perfectly calibrated 95 % interval is covered X ~ Bin(n, 0.95)
//! times; with n = 50, P(X < 45) = 3.8 % per property (7.8 % at a true coverage of 94 %), so
//! over the 20 property/estimator pairs a 50-run check fails more often than not by chance
//! alone. It did: seeds 1000–1049 gave 43/50 (Bretl–Conti c_x) and 42/50 (J_yz) while 400
//! runs gave 0.938–0.970 for every pair. With n = 400, P(X < 360) = 0.07 % per pair at 94 %.
use crate::common::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rbprops_core::c64;
use rbprops_core::noise::standard_normal;
use rbprops_core::records::InertiaEstimate;
use rbprops_inertia::*;

const SEEDS: u64 = 400;
const REL_STD: f64 = 0.01;

fn values(e: &InertiaEstimate) -> [(f64, f64); 10] {
    let j = &e.inertia_cm_kg_m2;
    let s = &e.inertia_cm_std_kg_m2;
    [
        (e.mass_kg, e.mass_std_kg),
        (e.com_m[0], e.com_std_m[0]),
        (e.com_m[1], e.com_std_m[1]),
        (e.com_m[2], e.com_std_m[2]),
        (j[0][0], s[0][0]),
        (j[1][1], s[1][1]),
        (j[2][2], s[2][2]),
        (j[0][1], s[0][1]),
        (j[0][2], s[0][2]),
        (j[1][2], s[1][2]),
    ]
}

fn coverage(
    which: &[usize],
    estimators: &[Estimator],
    monte_carlo: usize,
    seeds: u64,
) -> Vec<(rbprops_core::records::EstimateMethod, [u32; 10])> {
    let truth = body();
    let g = geometry();
    let modes = modes(&truth);
    let clean = modal_record(&g, &modes, REL_STD);
    let sel = selection(&g, &modes, which);
    let t = rbprops_core::records::PropertiesRecord::from_properties(&truth);
    let tv = [
        t.mass_kg,
        t.com_m[0],
        t.com_m[1],
        t.com_m[2],
        t.inertia_cm_kg_m2[0][0],
        t.inertia_cm_kg_m2[1][1],
        t.inertia_cm_kg_m2[2][2],
        t.inertia_cm_kg_m2[0][1],
        t.inertia_cm_kg_m2[0][2],
        t.inertia_cm_kg_m2[1][2],
    ];
    let mut hits: Vec<(rbprops_core::records::EstimateMethod, [u32; 10])> = Vec::new();
    for seed in 0..seeds {
        let mut rng = ChaCha8Rng::seed_from_u64(1000 + seed);
        let mut modal = clean.clone();
        for m in &mut modal.modes {
            for (z, s) in m.residues.iter_mut().zip(&m.residue_std) {
                *z += c64::new(s * standard_normal(&mut rng), s * standard_normal(&mut rng));
            }
        }
        let opts = SolveOptions {
            estimators: estimators.to_vec(),
            monte_carlo_samples: monte_carlo,
            seed: 7,
            ..Default::default()
        };
        let out = solve(&g, &modal, &sel, None, &opts).unwrap();
        for e in out.estimates.iter().filter(|e| !e.method.is_projected()) {
            let slot = match hits.iter().position(|(m, _)| *m == e.method) {
                Some(i) => i,
                None => {
                    hits.push((e.method, [0; 10]));
                    hits.len() - 1
                }
            };
            for (k, (v, s)) in values(e).iter().enumerate() {
                assert!(*s > 0.0, "{}: zero std for property {k}", e.method);
                if (v - tv[k]).abs() <= Z95 * s {
                    hits[slot].1[k] += 1;
                }
            }
        }
    }
    hits
}

#[test]
fn linearised_95_percent_intervals_are_calibrated() {
    let hits = coverage(
        &[0, 1, 2, 3, 4, 5],
        &[Estimator::BretlConti, Estimator::ToivolaNuutila],
        0,
        SEEDS,
    );
    assert_eq!(hits.len(), 2);
    for (method, h) in &hits {
        println!("{method}: coverage out of {SEEDS}: {h:?}");
        for (k, n) in h.iter().enumerate() {
            assert!(
                *n as f64 >= 0.9 * SEEDS as f64,
                "{method}: property {k} covered {n}/{SEEDS}"
            );
        }
    }
}

#[test]
fn five_mode_toivola_nuutila_intervals_are_calibrated() {
    let hits = coverage(&[0, 1, 2, 3, 5], &[Estimator::ToivolaNuutila], 0, SEEDS);
    for (method, h) in &hits {
        println!("{method} (5 modes): coverage out of {SEEDS}: {h:?}");
        for (k, n) in h.iter().enumerate() {
            assert!(
                *n as f64 >= 0.9 * SEEDS as f64,
                "{method}: property {k} covered {n}/{SEEDS}"
            );
        }
    }
}

#[test]
fn monte_carlo_and_linearised_standard_errors_agree() {
    let truth = body();
    let g = geometry();
    let modes = modes(&truth);
    let modal = modal_record(&g, &modes, REL_STD);
    let sel = selection(&g, &modes, &[0, 1, 2, 3, 4, 5]);
    let mut opts = SolveOptions {
        estimators: vec![Estimator::ToivolaNuutila],
        ..Default::default()
    };
    let lin = solve(&g, &modal, &sel, None, &opts).unwrap().estimates[0].clone();
    opts.monte_carlo_samples = 400;
    opts.seed = 3;
    let mc = solve(&g, &modal, &sel, None, &opts).unwrap().estimates[0].clone();
    assert_eq!(lin.uncertainty_method, "linearised");
    assert_eq!(mc.uncertainty_method, "monte_carlo");
    for (k, ((_, a), (_, b))) in values(&lin).iter().zip(values(&mc)).enumerate() {
        // 400 draws: sample-std relative error ≈ 1/sqrt(800) = 3.5 %; allow 5σ plus
        // 5 % for the nonlinearity at 1 % residue noise.
        assert!(
            (b / a - 1.0).abs() < 0.23,
            "property {k}: linearised {a:e}, MC {b:e}"
        );
    }
    let again = solve(&g, &modal, &sel, None, &opts).unwrap().estimates[0].clone();
    assert_eq!(mc, again, "Monte Carlo is deterministic for a fixed seed");
}
