//! Bretl–Conti and Toivola–Nuutila on exact and noisy modes of a fixture.
use crate::common::*;
use rbprops_core::records::DiagnosticKind;
use rbprops_core::records::InertiaEstimate;
use rbprops_core::{c64, MassMatrix6, RigidBodyProperties, Vec3};
use rbprops_inertia::*;

fn props_of(e: &InertiaEstimate) -> RigidBodyProperties {
    RigidBodyProperties {
        mass: e.mass_kg,
        com: Vec3::from(e.com_m),
        inertia_cm: rbprops_core::Mat3::from_fn(|r, c| e.inertia_cm_kg_m2[r][c]),
    }
}

fn rel_err(e: &InertiaEstimate, truth: &RigidBodyProperties) -> (f64, f64, f64) {
    let p = props_of(e);
    (
        (p.mass - truth.mass).abs() / truth.mass,
        (p.com - truth.com).norm() / truth.com.norm(),
        (p.inertia_cm - truth.inertia_cm).norm() / truth.inertia_cm.norm(),
    )
}

fn opts(est: &[Estimator], origin: OriginChoice) -> SolveOptions {
    SolveOptions {
        estimators: est.to_vec(),
        origin,
        ..Default::default()
    }
}

fn all_finite(v: &serde_json::Value) -> bool {
    match v {
        serde_json::Value::Null => false, // serde_json writes NaN/inf as null
        serde_json::Value::Array(a) => a.iter().all(all_finite),
        serde_json::Value::Object(o) => o
            .iter()
            .all(|(k, x)| k == "errors" || k == "mount_stiffness" || all_finite(x)),
        _ => true,
    }
}

#[test]
fn exact_modes_recover_all_properties_from_any_origin() {
    let truth = body();
    let g = geometry();
    let modes = modes(&truth);
    let modal = modal_record(&g, &modes, 0.0);
    let sel = selection(&g, &modes, &[0, 1, 2, 3, 4, 5]);
    for origin in [
        OriginChoice::GeometryOrigin,
        OriginChoice::Point([0.5, -0.2, 0.3]),
        OriginChoice::Channel("A2x".into()),
        OriginChoice::Channel("A3".into()),
    ] {
        let o = resolve_origin(&g, &origin).unwrap();
        let out = solve(
            &g,
            &modal,
            &sel,
            None,
            &opts(
                &[Estimator::BretlConti, Estimator::ToivolaNuutila],
                origin.clone(),
            ),
        )
        .unwrap();
        assert_eq!(out.estimates.len(), 2, "{:?}", out.diagnostics);
        assert_eq!(out.shapes.len(), 6);
        for e in &out.estimates {
            let (m, c, j) = rel_err(e, &truth);
            assert!(
                m < 1e-9 && c < 1e-9 && j < 1e-9,
                "{} {origin:?}: {m:e} {c:e} {j:e}",
                e.method
            );
            assert!(e.physically_consistent);
            assert!(e.residual < 1e-9, "{} residual {}", e.method, e.residual);
            assert_eq!(e.origin_m, <[f64; 3]>::from(o));
            assert_eq!(e.uncertainty_method, "none");
            // K0 about the working origin equals the true stiffness moved there.
            let k_true = MassMatrix6(stiffness()).moved_to(&o).0;
            let k = e.mount_stiffness.expect("six modes give K0");
            let k = rbprops_core::Mat6::from_fn(|r, c| k[r][c]);
            assert!(
                (k - k_true).norm() < 1e-8 * k_true.norm(),
                "{}",
                (k - k_true).norm()
            );
            assert!(all_finite(&serde_json::to_value(e).unwrap()));
        }
        for s in &out.shapes {
            assert!(s.relative_residual < 1e-12);
            assert!(s.force_projection > 0.0);
        }
    }
}

#[test]
fn relative_errors_against_a_reference_are_reported() {
    let truth = body();
    let g = geometry();
    let modes = modes(&truth);
    let modal = modal_record(&g, &modes, 0.0);
    let sel = selection(&g, &modes, &[0, 1, 2, 3, 4, 5]);
    let mut o = opts(&[Estimator::ToivolaNuutila], OriginChoice::GeometryOrigin);
    let mut reference = truth;
    reference.mass *= 1.1;
    o.reference = Some(rbprops_core::records::PropertiesRecord::from_properties(
        &reference,
    ));
    let out = solve(&g, &modal, &sel, None, &o).unwrap();
    let err = out.estimates[0].errors.unwrap();
    assert!((err.mass - 0.1 / 1.1).abs() < 1e-9, "{}", err.mass);
    assert!(err.com < 1e-9 && err.inertia < 1e-9);
}

/// Noisy residues, same data, three origins: the paper's observation 6 (Fig. 14, 16).
#[test]
fn mass_does_not_depend_on_the_origin() {
    let truth = body();
    let g = geometry();
    let modes = modes(&truth);
    let mut modal = modal_record(&g, &modes, 0.02);
    // Deterministic perturbation of every residue.
    for (i, m) in modal.modes.iter_mut().enumerate() {
        for (j, z) in m.residues.iter_mut().enumerate() {
            let t = ((i * 31 + j * 17) % 13) as f64 / 13.0 - 0.5;
            *z += c64::new(0.04 * t * m.residue_std[j] / 0.02, 0.0);
        }
    }
    let sel = selection(&g, &modes, &[0, 1, 2, 3, 4, 5]);
    let mut runs = Vec::new();
    for origin in [
        OriginChoice::Channel("A1".into()),
        OriginChoice::Channel("A2".into()),
        OriginChoice::Channel("A3".into()),
    ] {
        let out = solve(
            &g,
            &modal,
            &sel,
            None,
            &opts(&[Estimator::BretlConti, Estimator::ToivolaNuutila], origin),
        )
        .unwrap();
        runs.push(out.estimates);
    }
    let base = &runs[0];
    assert!(
        (base[0].mass_kg - truth.mass).abs() > 1e-4 * truth.mass,
        "noise has an effect"
    );
    for r in &runs[1..] {
        for (a, b) in base.iter().zip(r) {
            assert_eq!(a.method, b.method);
            assert!(
                (a.mass_kg - b.mass_kg).abs() < 1e-10 * a.mass_kg,
                "{}: mass",
                a.method
            );
            assert!((a.mass_std_kg - b.mass_std_kg).abs() < 1e-6 * a.mass_std_kg);
        }
        // Toivola–Nuutila: the whole estimate is origin-covariant (full-rank least squares
        // in a parameterisation that origin shifts map linearly onto itself).
        let (a, b) = (&base[1], &r[1]);
        for i in 0..3 {
            assert!((a.com_m[i] - b.com_m[i]).abs() < 1e-10);
            for k in 0..3 {
                assert!((a.inertia_cm_kg_m2[i][k] - b.inertia_cm_kg_m2[i][k]).abs() < 1e-10);
            }
        }
    }
}

#[test]
fn five_modes_toivola_nuutila_works_where_bretl_conti_refuses() {
    let truth = body();
    let g = geometry();
    let modes = modes(&truth);
    let modal = modal_record(&g, &modes, 0.0);
    for skip in 0..6 {
        let which: Vec<usize> = (0..6).filter(|&r| r != skip).collect();
        let sel = selection(&g, &modes, &which);
        let out = solve(
            &g,
            &modal,
            &sel,
            None,
            &opts(
                &[Estimator::BretlConti, Estimator::ToivolaNuutila],
                OriginChoice::GeometryOrigin,
            ),
        )
        .unwrap();
        assert_eq!(out.estimates.len(), 1);
        let e = &out.estimates[0];
        assert_eq!(e.method, "toivola_nuutila");
        assert!(e.mount_stiffness.is_none());
        let (m, c, j) = rel_err(e, &truth);
        assert!(
            m < 1e-9 && c < 1e-9 && j < 1e-9,
            "skip {skip}: {m:e} {c:e} {j:e}"
        );
        assert!(
            out.diagnostics
                .iter()
                .any(|d| d.kind == DiagnosticKind::EstimatorFailed
                    && d.message.contains("bretl_conti")
                    && d.message.contains("six")),
            "{:?}",
            out.diagnostics
        );
    }
}

/// Four modes: the paper says four suffice; the ten equations have rank 9 for every choice,
/// because four vectors of the 6-D rigid-motion space always contain a pure translation u.
#[test]
fn four_modes_leave_one_combination_unidentifiable() {
    let truth = body();
    let modes = modes(&truth);
    let phi = phi_matrix(&modes);
    let m0 = truth.mass_matrix();
    let mut n_subsets = 0;
    for a in 0..6 {
        for b in a + 1..6 {
            for c in b + 1..6 {
                for d in c + 1..6 {
                    let sub = [phi[a], phi[b], phi[c], phi[d]];
                    let tn = toivola_nuutila(&sub, &[], None).unwrap();
                    assert_eq!(tn.rank, 9, "modes {a}{b}{c}{d}");
                    let v = tn.null_space[0];
                    let u = translation_in_span(&sub).expect("four modes contain a translation");
                    // The null direction keeps the mass and moves m·c along u only.
                    let dmc = Vec3::new(v[1], v[2], v[3]);
                    assert!(v[0].abs() < 1e-9 * dmc.norm(), "δm = {}", v[0]);
                    assert!(dmc.cross(&u).norm() < 1e-7 * dmc.norm(), "δ(mc) ∦ u");
                    // Truth + t·null still satisfies every orthogonality equation.
                    let p = params_of(&m0);
                    let pt: [f64; N_PARAMS] = std::array::from_fn(|k| p[k] + 3.0 * v[k]);
                    let mt = mass_matrix_of(&pt).0;
                    for i in 0..4 {
                        for j in 0..4 {
                            let x = (sub[i].transpose() * mt * sub[j])[0];
                            assert!((x - (i == j) as u8 as f64).abs() < 1e-9);
                        }
                    }
                    n_subsets += 1;
                }
            }
        }
    }
    assert_eq!(n_subsets, 15);
}

#[test]
fn four_modes_need_labelled_side_information() {
    let truth = body();
    let g = geometry();
    let modes = modes(&truth);
    let modal = modal_record(&g, &modes, 0.0);
    let sel = selection(&g, &modes, &[0, 2, 3, 5]);
    let mut o = opts(&[Estimator::ToivolaNuutila], OriginChoice::GeometryOrigin);
    let err = solve(&g, &modal, &sel, None, &o).unwrap_err().to_string();
    assert!(
        err.contains("rank 9") && err.contains("pure translation"),
        "{err}"
    );
    assert!(err.contains("a known mass does not help"), "{err}");
    // A known mass does not resolve it (the null direction has δm = 0) …
    o.side_information.known_mass_kg = Some(truth.mass);
    let err = solve(&g, &modal, &sel, None, &o).unwrap_err().to_string();
    assert!(err.contains("rank 9"), "{err}");
    // … a known centre of mass does, and the estimate says it used it.
    o.side_information.known_mass_kg = None;
    o.side_information.known_com_m = Some(truth.com.into());
    let out = solve(&g, &modal, &sel, None, &o).unwrap();
    let e = &out.estimates[0];
    let (m, c, j) = rel_err(e, &truth);
    assert!(m < 1e-9 && c < 1e-9 && j < 1e-9, "{m:e} {c:e} {j:e}");
    assert!(
        e.diagnostics[0].kind == DiagnosticKind::SideInformation,
        "{:?}",
        e.diagnostics
    );
    // Nominal values fix only the unidentifiable combination: a nominal 5 % off everywhere
    // still leaves every orthogonality equation satisfied.
    o.side_information.known_com_m = None;
    let mut nominal = truth;
    nominal.mass *= 1.05;
    nominal.com *= 1.05;
    nominal.inertia_cm *= 1.05;
    o.side_information.nominal = Some(rbprops_core::records::PropertiesRecord::from_properties(
        &nominal,
    ));
    let out = solve(&g, &modal, &sel, None, &o).unwrap();
    let e = &out.estimates[0];
    assert!(e.residual < 1e-9, "{}", e.residual);
    assert!(
        (e.mass_kg - truth.mass).abs() < 1e-9 * truth.mass,
        "mass is identifiable"
    );
    assert_eq!(e.diagnostics[0].kind, DiagnosticKind::SideInformation);
    assert!(e
        .diagnostics
        .iter()
        .any(|d| d.kind == DiagnosticKind::IllConditioned && d.message.contains("rank 9")));
}

#[test]
fn bad_inputs_give_named_errors_never_nan() {
    let truth = body();
    let g = geometry();
    let modes = modes(&truth);
    let modal = modal_record(&g, &modes, 0.0);
    let both = opts(
        &[Estimator::BretlConti, Estimator::ToivolaNuutila],
        OriginChoice::GeometryOrigin,
    );
    // Three modes.
    let sel = selection(&g, &modes, &[0, 1, 2]);
    let err = solve(&g, &modal, &sel, None, &both)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("at least four modes") && err.contains("got 3"),
        "{err}"
    );
    // Two triaxial points; three collinear points.
    let two = geometry_with_points(&[
        ("A1", Vec3::new(0.3, 0.0, 0.0)),
        ("A2", Vec3::new(-0.2, 0.1, 0.0)),
    ]);
    let sel6 = selection(&g, &modes, &[0, 1, 2, 3, 4, 5]);
    let m2 = modal_record(&two, &modes, 0.0);
    let err = solve(&two, &m2, &sel6, None, &both)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("cannot resolve all six rigid-body motions"),
        "{err}"
    );
    let line = geometry_with_points(&[
        ("A1", Vec3::new(0.3, 0.0, 0.0)),
        ("A2", Vec3::new(0.0, 0.1, 0.0)),
        ("A3", Vec3::new(-0.3, 0.2, 0.0)),
    ]);
    let m3 = modal_record(&line, &modes, 0.0);
    let err = solve(&line, &m3, &sel6, None, &both)
        .unwrap_err()
        .to_string();
    assert!(err.contains("cannot resolve"), "{err}");
    // A mode whose residues give fᵀq < 0 (sign-flipped residues): named, left out.
    let mut flipped = modal.clone();
    let s3 = &sel6.selected[3];
    let m = flipped
        .modes
        .iter_mut()
        .find(|m| m.excitation == s3.excitation && m.mode == s3.excitation_mode)
        .unwrap();
    for z in &mut m.residues {
        *z = -*z;
    }
    let out = solve(&g, &flipped, &sel6, None, &both).unwrap();
    assert!(
        out.diagnostics
            .iter()
            .any(|d| d.kind == DiagnosticKind::ModeLeftOut
                && d.message.contains("mode 4")
                && d.message.contains("fᵀq")),
        "{:?}",
        out.diagnostics
    );
    assert_eq!(
        out.estimates.len(),
        1,
        "Toivola–Nuutila continues with five modes"
    );
    // Singular Φ0: the same mode twice.
    let phi = phi_matrix(&modes);
    let dup = [phi[0], phi[1], phi[2], phi[3], phi[4], phi[4]];
    assert!(matches!(
        bretl_conti(&dup),
        Err(InertiaError::SingularModalMatrix { .. })
    ));
    // Unknown origin channel.
    let err = solve(
        &g,
        &modal,
        &sel6,
        None,
        &opts(
            &[Estimator::BretlConti],
            OriginChoice::Channel("nope".into()),
        ),
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("'nope'"), "{err}");
}
