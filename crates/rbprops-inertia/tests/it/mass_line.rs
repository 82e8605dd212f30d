//! The inertia-restraint (mass-line) estimate from FRFs.
use crate::common::*;
use rbprops_core::{Mat3, Vec3};
use rbprops_inertia::*;

fn ml_opts() -> SolveOptions {
    SolveOptions {
        estimators: vec![Estimator::MassLine],
        ..Default::default()
    }
}

#[test]
fn noise_free_mass_line_with_elastic_mode_ten_times_above() {
    let truth = body();
    let g = geometry();
    let modes = modes(&truth);
    let f_rigid = modes.last().unwrap().frequency_hz;
    let fe = 10.0 * f_rigid;
    let frf = frfs(&g, &modes, fe, 2.0 * fe, 4000);
    let modal = modal_record(&g, &modes, 0.0);
    let sel = selection(&g, &modes, &[0, 1, 2, 3, 4, 5]);
    let out = solve(&g, &modal, &sel, Some(&frf), &ml_opts()).unwrap();
    let band = out.mass_line_band.clone().unwrap();
    assert!(band.automatic);
    let fe_found = band.first_elastic_hz.expect("elastic mode found");
    assert!(
        (fe_found / fe - 1.0).abs() < 0.01,
        "found {fe_found}, true {fe}"
    );
    assert!((band.lo_hz - 2.0 * f_rigid).abs() < 1e-9);
    assert!((band.hi_hz - fe_found / 2.0).abs() < 1e-9);
    let e = &out.estimates[0];
    assert_eq!(e.method, "mass_line");
    let m_err = (e.mass_kg - truth.mass).abs() / truth.mass;
    let c_err = (Vec3::from(e.com_m) - truth.com).norm();
    let j = Mat3::from_fn(|r, c| e.inertia_cm_kg_m2[r][c]);
    let j_err = (j - truth.inertia_cm).norm() / truth.inertia_cm.norm();
    println!("mass-line: band {band:?}; m {m_err:.3e}, c {c_err:.3e} m, J {j_err:.3e}");
    assert!(m_err < 0.005, "mass error {m_err}");
    assert!(c_err < 1e-3, "CoM error {c_err} m");
    assert!(j_err < 0.02, "J error {j_err}");
    assert!(e.physically_consistent);
}

#[test]
fn pure_rigid_mass_line_is_exact_far_above_the_modes() {
    // No elastic mode in range: the three-term fit removes the rigid 1/ω² tail.
    let truth = body();
    let g = geometry();
    let modes = modes(&truth);
    let f_rigid = modes.last().unwrap().frequency_hz;
    let frf = frfs(&g, &modes, 1e6, 40.0 * f_rigid, 2000);
    let modal = modal_record(&g, &modes, 0.0);
    let sel = selection(&g, &modes, &[0, 1, 2, 3, 4, 5]);
    let mut o = ml_opts();
    o.mass_line.band_hz = Some((10.0 * f_rigid, 40.0 * f_rigid));
    let out = solve(&g, &modal, &sel, Some(&frf), &o).unwrap();
    let e = &out.estimates[0];
    let m_err = (e.mass_kg - truth.mass).abs() / truth.mass;
    let c_err = (Vec3::from(e.com_m) - truth.com).norm();
    let j = Mat3::from_fn(|r, c| e.inertia_cm_kg_m2[r][c]);
    let j_err = (j - truth.inertia_cm).norm() / truth.inertia_cm.norm();
    assert!(
        m_err < 1e-4 && c_err < 1e-5 && j_err < 1e-3,
        "{m_err:e} {c_err:e} {j_err:e}"
    );
    assert!(!out.mass_line_band.unwrap().automatic);
}

#[test]
fn mass_line_needs_three_excitations() {
    let truth = body();
    let mut g = geometry();
    g.excitations.truncate(2);
    let modes = modes(&truth);
    let f_rigid = modes.last().unwrap().frequency_hz;
    let frf = frfs(&g, &modes, 10.0 * f_rigid, 20.0 * f_rigid, 1000);
    let modal = modal_record(&g, &modes, 0.0);
    let sel = selection(&g, &modes, &[0, 1, 2, 3, 4, 5]);
    let err = solve(&g, &modal, &sel, Some(&frf), &ml_opts())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("at least three excitations") && err.contains("got 2"),
        "{err}"
    );
    // Without FRFs the mass line says so.
    let err = solve(&g, &modal, &sel, None, &ml_opts())
        .unwrap_err()
        .to_string();
    assert!(err.contains("no FRFs"), "{err}");
}

/// Noise-free, no elastic mode, data ending 2.3× above the highest rigid mode (as Test
/// Case II's 12.5 Hz): the automatic band 2–2.3 f_r leaves a rigid-tail truncation bias
/// far above the regression error; the standard errors must include it, so the truth lies
/// inside the 95 % interval of mass and J diagonal, and a warning says how it was found.
#[test]
fn mass_line_interval_includes_the_rigid_tail_truncation_bias() {
    let truth = body();
    let g = geometry();
    let modes = modes(&truth);
    let f_rigid = modes.last().unwrap().frequency_hz;
    let frf = frfs(&g, &modes, 1e6, 2.3 * f_rigid, 2000);
    let modal = modal_record(&g, &modes, 0.0);
    let sel = selection(&g, &modes, &[0, 1, 2, 3, 4, 5]);
    let out = solve(&g, &modal, &sel, Some(&frf), &ml_opts()).unwrap();
    let e = &out.estimates[0];
    assert_eq!(e.method, "mass_line");
    assert!(
        e.diagnostics.iter().any(
            |d| d.kind == rbprops_core::records::DiagnosticKind::MassLineBand
                && d.message.contains("truncation bias")
        ),
        "{:?}",
        e.diagnostics
    );
    let z_m = (e.mass_kg - truth.mass) / e.mass_std_kg;
    println!("mass {} ± {} (z {z_m:.2})", e.mass_kg, e.mass_std_kg);
    assert!(z_m.abs() < 1.96, "mass z = {z_m}");
    for k in 0..3 {
        let z =
            (e.inertia_cm_kg_m2[k][k] - truth.inertia_cm[(k, k)]) / e.inertia_cm_std_kg_m2[k][k];
        assert!(z.abs() < 1.96, "J{k}{k} z = {z}");
    }
}
