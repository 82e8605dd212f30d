//! The plan's chain against exact answers, unobservable layouts, determinism and the
//! Monte Carlo of the real pipeline.

use rbprops_core::records::EstimateMethod;
use rbprops_core::Vec3;
use rbprops_plan::estimate::{properties_of_shapes, shape_jacobian};
use rbprops_plan::{
    evaluate, excitation_covariance, plan, Candidates, Estimator, Hit, Layout, PlanModel,
    PlanOptions, Sensor,
};
use rbprops_sim::CampaignSpec;

fn test_case_2(noise: f64) -> CampaignSpec {
    let mut s = CampaignSpec::from_toml_str(rbprops_sim::example("test-case-2").unwrap()).unwrap();
    s.noise.relative = noise;
    s
}

#[test]
fn estimators_recover_the_truth_from_the_true_shapes() {
    let spec = test_case_2(0.01);
    let model = PlanModel::from_spec(&spec).unwrap();
    let phi: Vec<_> = model.setups[0].modes.iter().map(|m| m.shape).collect();
    for est in [Estimator::ToivolaNuutila, Estimator::BretlConti] {
        let p = properties_of_shapes(est, &phi).unwrap();
        for k in 0..10 {
            let tol = 1e-9 * model.scales[k];
            assert!(
                (p[k] - model.truth[k]).abs() < tol,
                "{est:?} {k}: {} vs {}",
                p[k],
                model.truth[k]
            );
        }
    }
}

#[test]
fn shape_jacobian_is_the_derivative() {
    // Mass scales as the inverse square of a common shape scale: p(λφ) has m/λ², so
    // d m / d λ at λ = 1 is −2m = Σ_r ∂m/∂φ_r · φ_r.
    let spec = test_case_2(0.01);
    let model = PlanModel::from_spec(&spec).unwrap();
    let phi: Vec<_> = model.setups[0].modes.iter().map(|m| m.shape).collect();
    let j = shape_jacobian(Estimator::ToivolaNuutila, &phi).unwrap();
    let mut dm = 0.0;
    for (r, f) in phi.iter().enumerate() {
        for c in 0..6 {
            dm += j[(0, 6 * r + c)] * f[c];
        }
    }
    let m = model.truth[0];
    assert!((dm + 2.0 * m).abs() < 1e-6 * m, "{dm} vs {}", -2.0 * m);
}

#[test]
fn sensors_on_one_line_are_named_unobservable() {
    let spec = test_case_2(0.01);
    let model = PlanModel::from_spec(&spec).unwrap();
    let mut layout = Layout::from_spec(&spec, &model).unwrap();
    for (k, s) in layout.sensors.iter_mut().enumerate() {
        s.position = Vec3::new(0.1 * k as f64, 0.05, 0.02);
    }
    let ev = evaluate(&model, &layout, Estimator::ToivolaNuutila);
    let why = ev.setups[0].1.as_ref().unwrap_err().reason.clone();
    assert!(why.contains("rotation about the axis"), "{why}");
    // The line of the sensors: y = 0.05, z = 0.02, along x.
    assert!(why.contains("0.0500, 0.0200) m along (1.000,"), "{why}");
}

#[test]
fn a_mode_no_hit_excites_is_named_for_bretl_conti() {
    let spec = test_case_2(0.01);
    let model = PlanModel::from_spec(&spec).unwrap();
    let mut layout = Layout::from_spec(&spec, &model).unwrap();
    // One hit only: whatever it is, it excites a single direction of force space, and a
    // mode whose shape is orthogonal to it in the mass metric... use the mode's own
    // orthogonality instead: a force column orthogonal to mode 1 leaves mode 1 unexcited.
    let mode1 = model.setups[0].modes[0].shape;
    // Force d at point p: column [d; p × d]. Pick p = 0 and d ⟂ the translation of mode 1.
    let t = Vec3::new(mode1[0], mode1[1], mode1[2]);
    let d = t.cross(&Vec3::new(0.3, 0.5, 0.8)).normalize();
    let d2 = t.cross(&d).normalize();
    layout.hits = vec![
        Hit {
            id: "a".into(),
            position: Vec3::zeros(),
            direction: d,
            setup: 0,
        },
        Hit {
            id: "b".into(),
            position: Vec3::zeros(),
            direction: d2,
            setup: 0,
        },
    ];
    let ev = evaluate(&model, &layout, Estimator::BretlConti);
    let why = ev.setups[0].1.as_ref().unwrap_err().reason.clone();
    assert!(why.contains("mode 1"), "{why}");
}

fn grid_candidates(model: &PlanModel) -> Candidates {
    let _ = model;
    let mut c = Candidates::default();
    let mut k = 0;
    for x in [0.0, 0.18, 0.36] {
        for y in [-0.15, 0.22] {
            for z in [-0.19, 0.17] {
                let p = Vec3::new(x, y, z);
                c.sensors.push(Sensor::triaxial(&format!("p{k}"), p));
                for axis in 0..3 {
                    let mut d = Vec3::zeros();
                    d[axis] = 1.0;
                    c.hits.push(Hit {
                        id: format!("p{k}"),
                        position: p,
                        direction: d,
                        setup: 0,
                    });
                }
                k += 1;
            }
        }
    }
    c
}

#[test]
fn planning_is_deterministic_and_beats_the_input_layout() {
    let spec = test_case_2(0.01);
    let model = PlanModel::from_spec(&spec).unwrap();
    let cands = grid_candidates(&model);
    let opts = PlanOptions {
        sensors: 3,
        hits: 3,
        max_rounds: 1,
        ..Default::default()
    };
    let a = plan(&model, &cands, 0, &opts).unwrap();
    // Same answer on one thread as on the default pool.
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let b = one.install(|| plan(&model, &cands, 0, &opts)).unwrap();
    assert_eq!((a.sensors.clone(), a.hits.clone()), (b.sensors, b.hits));
    assert_eq!(a.value.to_bits(), b.value.to_bits());
    let input = Layout::from_spec(&spec, &model).unwrap();
    let ev = evaluate(&model, &input, Estimator::ToivolaNuutila);
    let before = opts
        .criterion
        .value(&model, ev.setups[0].1.as_ref().unwrap());
    assert!(a.value < before, "plan {} vs input {before}", a.value);
}

fn data_spec(name: &str) -> CampaignSpec {
    let path = format!("{}/tests/data/{name}", env!("CARGO_MANIFEST_DIR"));
    CampaignSpec::from_toml_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Every property's predicted standard deviation within ±20 % of the real pipeline's
/// spread over 200 noise seeds, both estimators, on Test Case II (the paper's layout and
/// a planned one, 1 % noise), the plate (2 %) and the bar (mobility, 1 % and a noise
/// floor). The sample standard deviation of 200 draws has a relative standard error of
/// 1/√(2·199) = 5 %, so ±20 % is four of them. Measured (release, Toivola–Nuutila):
/// Test Case II 0.92–1.11, planned 0.96–1.15, plate 0.92–1.00, bar 0.92–1.06
/// (docs/results.md).
#[test]
#[ignore = "Monte Carlo of 8 × 200 pipeline runs: 6 min in release on a loaded 2-core machine, far longer in a debug build"]
fn prediction_matches_the_pipeline_monte_carlo() {
    let mut cases = vec![("test-case-2 (1 %)".to_string(), test_case_2(0.01))];
    for name in ["test-case-2-planned-3x3.toml", "plate.toml", "bar.toml"] {
        cases.push((name.to_string(), data_spec(name)));
    }
    for (name, spec) in cases {
        let model = PlanModel::from_spec(&spec).unwrap();
        let layout = Layout::from_spec(&spec, &model).unwrap();
        for (est, method) in [
            (Estimator::ToivolaNuutila, EstimateMethod::ToivolaNuutila),
            (Estimator::BretlConti, EstimateMethod::BretlConti),
        ] {
            let ev = evaluate(&model, &layout, est);
            let p = ev.setups[0].1.as_ref().unwrap();
            assert!(p.limit.is_none(), "{name}: {:?}", p.limit);
            let pred = p.std();
            let (mc, _, failed) = crate::pipeline_mc::pipeline_spread(&spec, 200, method);
            assert!(failed < 10, "{name}: {failed} runs failed");
            for k in 0..10 {
                let r = pred[k] / mc[k];
                assert!(
                    (0.8..=1.2).contains(&r),
                    "{name} {est:?} property {k}: predicted/MC = {r:.3}"
                );
            }
        }
    }
}

/// Modes within modal-fit's near-one-frequency distance make the pipeline refit
/// poly-reference, which the plan does not model: the prediction says so (close-modes:
/// modes 1 and 2, 0.75 half-bandwidths apart) and stays silent on Test Case II (closest
/// pair 2.03 half-bandwidths).
#[test]
fn close_modes_are_named_as_the_predictions_limit() {
    let spec = CampaignSpec::from_toml_str(rbprops_sim::example("close-modes").unwrap()).unwrap();
    let model = PlanModel::from_spec(&spec).unwrap();
    let layout = Layout::from_spec(&spec, &model).unwrap();
    let ev = evaluate(&model, &layout, Estimator::ToivolaNuutila);
    let limit = ev.setups[0].1.as_ref().unwrap().limit.clone().unwrap();
    assert!(
        limit.starts_with("modes 1 (0.8000 Hz) and 2 (0.8120 Hz) are 0.75 half-bandwidths apart"),
        "{limit}"
    );
    let spec = test_case_2(0.01);
    let model = PlanModel::from_spec(&spec).unwrap();
    let layout = Layout::from_spec(&spec, &model).unwrap();
    let ev = evaluate(&model, &layout, Estimator::ToivolaNuutila);
    assert_eq!(ev.setups[0].1.as_ref().unwrap().limit, None);
}

/// The covariance of one hit's constants is the sum of its channels' terms: the same
/// channels combined in another order give the same covariance, permuted.
#[test]
fn channel_terms_combine_to_the_excitation_covariance() {
    let spec = test_case_2(0.01);
    let model = PlanModel::from_spec(&spec).unwrap();
    let layout = Layout::from_spec(&spec, &model).unwrap();
    let rows = layout.rows();
    let col = layout.hits[0].column();
    let direct = excitation_covariance(&model, &model.setups[0], &rows, &col);
    let basis = rbprops_plan::ExcitationBasis::new(&model, &model.setups[0], &col, &rows);
    let terms: Vec<_> = rows.iter().map(|r| basis.channel(r)).collect();
    let rev: Vec<_> = terms.iter().rev().collect();
    let c = rbprops_plan::combine(&rev);
    let (nc, nm) = (rows.len(), 6);
    let scale = direct.cov.amax();
    for r in 0..nm {
        for i in 0..nc {
            assert_eq!(c.constants[r][nc - 1 - i], direct.constants[r][i]);
            for t in 0..nm {
                for j in 0..nc {
                    let d = c.cov[(r * nc + nc - 1 - i, t * nc + nc - 1 - j)]
                        - direct.cov[(r * nc + i, t * nc + j)];
                    assert!(d.abs() <= 1e-12 * scale, "{r} {i} {t} {j}: {d:e}");
                }
            }
        }
    }
}
