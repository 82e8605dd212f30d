//! Physical consistency flags, the projected estimate and thread-count independence.
use crate::common::*;
use rbprops_core::{Mat3, RigidBodyProperties, Vec3};
use rbprops_inertia::*;

#[test]
fn inconsistent_inertia_is_flagged_and_a_projected_estimate_offered() {
    // Principal moments (0.1, 0.2, 0.5) break J1 + J2 ≥ J3 (no real body has them), yet
    // the mass matrix is positive definite, so its modes exist and the estimators return it.
    let axes = nalgebra::Rotation3::from_euler_angles(0.2, -0.4, 0.7).into_inner();
    let j = axes * Mat3::from_diagonal(&Vec3::new(0.1, 0.2, 0.5)) * axes.transpose();
    let fake = RigidBodyProperties {
        mass: 12.0,
        com: Vec3::new(0.05, 0.02, -0.03),
        inertia_cm: j,
    };
    let g = geometry();
    let modes = modes(&fake);
    let modal = modal_record(&g, &modes, 0.0);
    let sel = selection(&g, &modes, &[0, 1, 2, 3, 4, 5]);
    let opts = SolveOptions {
        estimators: vec![Estimator::ToivolaNuutila],
        ..Default::default()
    };
    let out = solve(&g, &modal, &sel, None, &opts).unwrap();
    assert_eq!(out.estimates.len(), 2);
    let (raw, proj) = (&out.estimates[0], &out.estimates[1]);
    assert!(!raw.physically_consistent);
    assert!(
        raw.diagnostics.iter().any(|d| d.kind
            == rbprops_core::records::DiagnosticKind::PhysicallyInconsistent
            && d.severity == rbprops_core::records::Severity::ChangesAnswer
            && d.message.contains("triangle")),
        "{:?}",
        raw.diagnostics
    );
    assert!((raw.mass_kg - fake.mass).abs() < 1e-9 * fake.mass);
    assert_eq!(proj.method, "toivola_nuutila_projected");
    assert!(proj.physically_consistent);
    assert_eq!(proj.mass_kg, raw.mass_kg);
    assert_eq!(proj.com_m, raw.com_m);
    let pm = proj.principal_moments_kg_m2;
    assert!(pm[0] + pm[1] >= pm[2] * (1.0 - 1e-12), "{pm:?}");
    // (0.1, 0.2, 0.5) is 0.2 outside J1 + J2 ≥ J3: it moves by 0.2/3 along (1, 1, −1).
    let expect = [0.1 + 0.2 / 3.0, 0.2 + 0.2 / 3.0, 0.5 - 0.2 / 3.0];
    for k in 0..3 {
        assert!((pm[k] - expect[k]).abs() < 1e-9, "{pm:?}");
    }
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let truth = body();
    let g = geometry();
    let modes = modes(&truth);
    let modal = modal_record(&g, &modes, 0.01);
    let sel = selection(&g, &modes, &[0, 1, 2, 3, 4, 5]);
    let f_rigid = modes.last().unwrap().frequency_hz;
    let frf = frfs(&g, &modes, 10.0 * f_rigid, 20.0 * f_rigid, 1500);
    let run = |threads: usize, mc: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let opts = SolveOptions {
                monte_carlo_samples: mc,
                seed: 11,
                ..Default::default()
            };
            solve(&g, &modal, &sel, Some(&frf), &opts).unwrap()
        })
    };
    for mc in [0, 64] {
        let a = run(1, mc);
        let b = run(2, mc);
        assert_eq!(a.estimates.len(), 3, "{:?}", a.diagnostics);
        assert_eq!(a.estimates, b.estimates, "monte carlo samples {mc}");
    }
}
