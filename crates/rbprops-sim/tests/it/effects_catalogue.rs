//! The second part of the physics catalogue against independent derivations:
//! augmented elastic DOF, state-space complex modes, shifted and truncated modal sums,
//! moved sensors and forces in the spec, the Woodbury form of a mass below the gauge,
//! the high-pass factor and the specific-force formula.

#![allow(clippy::needless_range_loop)] // index-heavy linear algebra reads clearer with indices

use crate::common::{max_dev, tc2, with_effect};
use nalgebra::{DMatrix, DVector, Vector3};
use rbprops_core::{c64, Mat6, Quantity, Vec3, Vec6};
use rbprops_sim::effects::parse_effects;
use rbprops_sim::{build_models, example, simulate, CampaignSpec, Simulation};

const TAU: f64 = std::f64::consts::TAU;

fn sim(s: &CampaignSpec) -> Simulation {
    simulate(s).unwrap_or_else(|e| panic!("{e}"))
}

fn c(x: f64) -> c64 {
    c64::new(x, 0.0)
}

/// An elastic coordinate η (unit modal mass, stiffness ω_e², damping 2ζω_e) appended to
/// the six rigid coordinates: the 7×7 direct solve must equal the simulated FRFs.
#[test]
fn elastic_mode_is_an_added_elastic_dof() {
    let (fe, ze) = (9.0, 0.02); // inside the band, to test the resonance too
    let psi_c = [0.3, 0.0, -0.2, 0.0, 0.25, 0.4, -0.35, 0.0, -0.3];
    let psi_e = [-0.3, 0.2, 0.45];
    let s = with_effect(
        tc2(),
        &format!(
            "id = \"elastic_mode\"\nfrequency_hz = {fe}\ndamping_ratio = {ze}\n\
             channels = {{ \"1x\" = 0.3, \"1z\" = -0.2, \"2y\" = 0.25, \"2z\" = 0.4, \"3x\" = -0.35, \"3z\" = -0.3 }}\n\
             excitations = {{ force1 = -0.3, force2 = 0.2, force3 = 0.45 }}"
        ),
    );
    let out = sim(&s);
    let nominal = tc2();
    let g = nominal.geometry().unwrap();
    let m = &build_models(&nominal, &g, &[]).unwrap()[0].model;
    let we = TAU * fe;
    let freq = nominal.frequency_axis();
    let mut worst = 0.0f64;
    for e in 0..3 {
        let f = g.excitations[e].column();
        for (l, &hz) in freq.iter().enumerate().skip(1) {
            let w = TAU * hz;
            let mut z = DMatrix::<c64>::zeros(7, 7);
            for i in 0..6 {
                for j in 0..6 {
                    z[(i, j)] = c64::new(
                        m.stiffness[(i, j)] - w * w * m.mass[(i, j)],
                        w * m.damping[(i, j)],
                    );
                }
            }
            z[(6, 6)] = c64::new(we * we - w * w, 2.0 * ze * we * w);
            let rhs = DVector::<c64>::from_fn(7, |i, _| c(if i < 6 { f[i] } else { psi_e[e] }));
            let x = z.lu().solve(&rhs).unwrap();
            for (ch, chan) in g.channels.iter().enumerate() {
                let row = chan.row();
                let mut y = x[6] * psi_c[ch];
                for i in 0..6 {
                    y += x[i] * row[i];
                }
                let expect = y * (-w * w);
                let got = out.frf.frf(e, ch)[l];
                let scale = out
                    .frf
                    .frf(e, ch)
                    .iter()
                    .map(|v| v.norm())
                    .fold(0.0, f64::max);
                worst = worst.max((got - expect).norm() / scale);
            }
        }
    }
    eprintln!("{}: worst = {:e}", module_path!(), worst);
    assert!(worst < 1e-10, "elastic DOF vs simulator: {worst:e}");
    assert_eq!(out.truth.effects[0].id, "elastic_mode");
    // The rigid modes of the truth are untouched.
    assert_eq!(out.truth.setups, sim(&tc2()).truth.setups);
}

/// Dashpots at the mounts: the FRFs equal the complex-mode expansion
/// `G(s) = Σ_r ψ_r ψ_rᵀ / (a_r (s − λ_r))`, `a_r = ψ_rᵀ(2λ_r M + C)ψ_r`, over the 12
/// eigenpairs of the first-order form (faer's general eigen-solver), and the modes are
/// complex.
#[test]
fn nonproportional_damping_matches_the_complex_mode_expansion() {
    let table = "id = \"nonproportional_damping\"\naxial_n_s_per_m = [8.0, 2.0, 5.0, 1.0]\nlateral_n_s_per_m = [1.5]";
    let s = with_effect(tc2(), table);
    let out = sim(&s);
    let g = s.geometry().unwrap();
    let effects = parse_effects(&s).unwrap();
    let model = build_models(&s, &g, &effects).unwrap().remove(0).model;
    // Independent damping matrix: nominal C plus the dashpots, assembled here.
    let nominal = build_models(&tc2(), &g, &[]).unwrap().remove(0).model;
    let mut cdamp = nominal.damping;
    let (ca, cl) = ([8.0, 2.0, 5.0, 1.0], 1.5);
    for (sp, a) in s.springs(0).iter().zip(ca) {
        let t = rbprops_core::rigid_transform(&sp.at);
        let cm = Vec3::new(cl, cl, a);
        cdamp += t.transpose() * rbprops_core::Mat3::from_diagonal(&cm) * t;
    }
    assert!((cdamp - model.damping).norm() < 1e-12 * cdamp.norm());
    let (mm, kk) = (nominal.mass, nominal.stiffness);
    let minv = mm.try_inverse().unwrap();
    let a = faer::Mat::<f64>::from_fn(12, 12, |i, j| match (i < 6, j < 6) {
        (true, true) => 0.0,
        (true, false) => (i + 6 == j) as u8 as f64,
        (false, true) => -(minv * kk)[(i - 6, j)],
        (false, false) => -(minv * cdamp)[(i - 6, j - 6)],
    });
    let evd = a.eigen().unwrap();
    let mut modes = Vec::new();
    let mut min_mpc = 1.0f64;
    for r in 0..12 {
        let lambda: c64 = evd.S().column_vector()[r];
        let psi = nalgebra::Vector6::<c64>::from_fn(|i, _| evd.U()[(i, r)]);
        let mc = (mm.map(c) * psi * (lambda * 2.0) + cdamp.map(c) * psi).transpose() * psi;
        modes.push((lambda, psi, mc[0]));
        // Modal phase collinearity of the shape: 1 for a real (classical) mode.
        let re = psi.map(|z| z.re);
        let im = psi.map(|z| z.im);
        let (sxx, syy, sxy) = (re.dot(&re), im.dot(&im), re.dot(&im));
        let ev = ((sxx - syy).powi(2) + 4.0 * sxy * sxy).sqrt();
        let mpc = (((sxx + syy + ev) / 2.0 - (sxx + syy - ev) / 2.0) / (sxx + syy)).powi(2);
        min_mpc = min_mpc.min(mpc);
    }
    eprintln!("{}: min_mpc = {:e}", module_path!(), min_mpc);
    assert!(
        min_mpc < 0.999,
        "dashpots should make complex modes (MPC {min_mpc})"
    );
    let freq = s.frequency_axis();
    let mut worst = 0.0f64;
    for e in 0..3 {
        let f = g.excitations[e].column().map(c);
        for ch in 0..9 {
            let row = g.channels[ch].row().transpose().map(c);
            let expect: Vec<c64> = freq
                .iter()
                .map(|hz| {
                    let sv = c64::new(0.0, TAU * hz);
                    let h: c64 = modes
                        .iter()
                        .map(|(l, p, a)| row.dot(p) * p.dot(&f) / (a * (sv - l)))
                        .sum();
                    h * sv * sv
                })
                .collect();
            worst = worst.max(max_dev(out.frf.frf(e, ch), &expect));
        }
    }
    eprintln!("{}: worst = {:e}", module_path!(), worst);
    assert!(
        worst < 1e-9,
        "complex-mode expansion vs simulator: {worst:e}"
    );
    // The modal solve refuses non-classical damping.
    let e = rbprops_sim::simulate_with(
        &s,
        &rbprops_sim::SimOptions {
            method: rbprops_sim::SolveMethod::Modal,
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("not classical"), "{e}");
}

/// Modal parameters of the nominal TC II: (λ_r, residue R_r = S φ φᵀ f /(2iω_d)) per
/// excitation and channel, from the truth record (classical damping).
fn modal_terms(s: &CampaignSpec) -> Vec<(c64, Vec<Vec<c64>>)> {
    let out = sim(s);
    let g = &out.geometry;
    out.truth.setups[0]
        .modes
        .iter()
        .map(|m| {
            let w = TAU * m.frequency_hz;
            let wd = w * (1.0 - m.damping_ratio.powi(2)).sqrt();
            let lambda = c64::new(-m.damping_ratio * w, wd);
            let phi = Vec6::from_column_slice(&m.shape);
            let r = (0..g.excitations.len())
                .map(|e| {
                    let pf = g.excitations[e].column().dot(&phi);
                    g.channels
                        .iter()
                        .map(|ch| c(ch.row().dot(&phi.transpose()) * pf) / c64::new(0.0, 2.0 * wd))
                        .collect()
                })
                .collect();
            (lambda, r)
        })
        .collect()
}

fn receptance(mut s: CampaignSpec) -> CampaignSpec {
    s.quantity = Quantity::Receptance;
    s
}

/// Exponential window: the windowed FRF is the modal sum with every pole moved by −σ,
/// and the accelerance carries `(iω + σ)²`; the mass line is unchanged.
#[test]
fn exponential_window_shifts_every_pole_by_sigma() {
    let sigma = 0.4;
    let terms = modal_terms(&tc2());
    for q in [Quantity::Receptance, Quantity::Accelerance] {
        let mut s = with_effect(
            tc2(),
            &format!("id = \"exponential_window\"\ndecay_per_s = {sigma}"),
        );
        s.quantity = q;
        let out = sim(&s);
        let mut worst = 0.0f64;
        for e in 0..3 {
            for ch in 0..9 {
                let expect: Vec<c64> = out
                    .frf
                    .frequency_hz
                    .iter()
                    .map(|hz| {
                        let iw = c64::new(0.0, TAU * hz);
                        let h: c64 = terms
                            .iter()
                            .map(|(l, r)| {
                                let (l, r) = (*l - sigma, r[e][ch]);
                                r / (iw - l) + r.conj() / (iw - l.conj())
                            })
                            .sum();
                        match q {
                            Quantity::Receptance => h,
                            _ => h * (iw + sigma) * (iw + sigma),
                        }
                    })
                    .collect();
                worst = worst.max(max_dev(out.frf.frf(e, ch), &expect));
            }
        }
        eprintln!("{}: worst = {:e}", module_path!(), worst);
        assert!(
            worst < 1e-9,
            "{q:?}: windowed FRF vs shifted modal sum {worst:e}"
        );
    }
    // Mass line: far above the suspension modes the windowed accelerance tends to
    // S M⁻¹ f, as the plain one does (relative distance O((ω_r/ω)², σ/ω)).
    let mut s = with_effect(
        tc2(),
        &format!("id = \"exponential_window\"\ndecay_per_s = {sigma}"),
    );
    s.frequency = rbprops_sim::spec::FrequencySpec {
        start_hz: 1000.0,
        stop_hz: 2000.0,
        lines: 2,
    };
    let out = sim(&s);
    let minv = s.properties().mass_matrix().0.try_inverse().unwrap();
    let g = &out.geometry;
    for e in 0..3 {
        let u = minv * g.excitations[e].column();
        let ml: Vec<f64> = (0..9)
            .map(|ch| g.channels[ch].row().dot(&u.transpose()))
            .collect();
        let scale = ml.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        for ch in 0..9 {
            let got = out.frf.frf(e, ch)[1];
            // Expected distance O(σ/ω + (ω_r/ω)²) ≈ 1e-4 at 2 kHz.
            assert!(
                (got - ml[ch]).norm() < 2e-4 * scale,
                "e{e} c{ch}: {got} vs mass line {}",
                ml[ch]
            );
        }
    }
}

/// Record truncation: the finite transform of the modal impulse response,
/// `H_T = Σ R (1 − e^{(λ − iω)T})/(iω − λ) + c.c.` (receptance) and
/// `A_T = S M⁻¹ f + Σ R λ² (1 − e^{(λ − iω)T})/(iω − λ) + c.c.` (accelerance, whose
/// impulse response has the direct term S M⁻¹ f δ(t)).
#[test]
fn record_truncation_is_the_finite_transform_of_the_impulse_response() {
    let t_rec = 16.0;
    let terms = modal_terms(&tc2());
    let minv = tc2().properties().mass_matrix().0.try_inverse().unwrap();
    for q in [Quantity::Receptance, Quantity::Accelerance] {
        let mut s = with_effect(
            tc2(),
            &format!("id = \"record_truncation\"\nrecord_length_s = {t_rec}"),
        );
        s.quantity = q;
        let out = sim(&s);
        let plain = sim(&{
            let mut p = tc2();
            p.quantity = q;
            p
        });
        let g = &out.geometry;
        let (mut worst, mut effect) = (0.0f64, 0.0f64);
        for e in 0..3 {
            let direct = minv * g.excitations[e].column();
            for ch in 0..9 {
                let d = g.channels[ch].row().dot(&direct.transpose());
                let expect: Vec<c64> = out
                    .frf
                    .frequency_hz
                    .iter()
                    .map(|hz| {
                        let iw = c64::new(0.0, TAU * hz);
                        let mut h = c(0.0);
                        for (l, r) in &terms {
                            for (l, r) in [(*l, r[e][ch]), (l.conj(), r[e][ch].conj())] {
                                let k = match q {
                                    Quantity::Receptance => c(1.0),
                                    _ => l * l,
                                };
                                h += r * k * (c(1.0) - ((l - iw) * t_rec).exp()) / (iw - l);
                            }
                        }
                        match q {
                            Quantity::Receptance => h,
                            _ => h + d,
                        }
                    })
                    .collect();
                worst = worst.max(max_dev(out.frf.frf(e, ch), &expect));
                effect = effect.max(max_dev(plain.frf.frf(e, ch), &expect));
            }
        }
        eprintln!("{}: worst = {:e}", module_path!(), worst);
        assert!(worst < 1e-8, "{q:?}: truncated FRF vs analytic {worst:e}");
        eprintln!("{}: effect = {:e}", module_path!(), effect);
        assert!(
            effect > 1e-2,
            "{q:?}: truncation should matter at T = {t_rec} s ({effect:e})"
        );
    }
}

/// Sensor and force placement errors equal moving the sensor or force in the spec.
#[test]
fn placement_errors_equal_moving_the_points_in_the_spec() {
    let dp = [0.003, -0.002, 0.004];
    let moved_sensor = {
        let mut s = tc2();
        for i in 0..3 {
            s.sensors[1].at_m[i] += dp[i];
        }
        s
    };
    let dr = [0.001, 0.004, -0.003];
    let moved_force = {
        let mut s = tc2();
        for i in 0..3 {
            s.excitations[0].at_m[i] += dr[i];
        }
        s
    };
    let beta = Vec3::new(0.0873, -0.03, 0.02);
    let turned_force = {
        let mut s = tc2();
        let d = nalgebra::Rotation3::new(beta) * Vec3::from(s.excitations[2].direction);
        s.excitations[2].direction = [d.x, d.y, d.z];
        s
    };
    let cases = [
        (
            format!("id = \"sensor_position\"\noffsets_m = {{ \"2\" = {dp:?} }}"),
            moved_sensor,
        ),
        (
            format!("id = \"force_location\"\noffsets_m = {{ force1 = {dr:?} }}"),
            moved_force,
        ),
        (
            format!(
                "id = \"force_direction\"\nrotations_rad = {{ force3 = [{}, {}, {}] }}",
                beta.x, beta.y, beta.z
            ),
            turned_force,
        ),
    ];
    let nominal = sim(&tc2());
    for (table, moved) in cases {
        let a = sim(&with_effect(tc2(), &table));
        let b = sim(&moved);
        let (mut worst, mut change) = (0.0f64, 0.0f64);
        for e in 0..3 {
            for ch in 0..9 {
                worst = worst.max(max_dev(a.frf.frf(e, ch), b.frf.frf(e, ch)));
                change = change.max(max_dev(nominal.frf.frf(e, ch), b.frf.frf(e, ch)));
            }
        }
        eprintln!("{}: worst = {:e}", module_path!(), worst);
        assert!(worst < 1e-12, "{table}: {worst:e}");
        eprintln!("{}: change = {:e}", module_path!(), change);
        assert!(
            change > 1e-3,
            "{table}: the error must be visible ({change:e})"
        );
    }
    // A shift along the force's line of action changes nothing.
    let along = sim(&with_effect(
        tc2(),
        "id = \"force_location\"\noffsets_m = { force2 = [0.0, 0.01, 0.0] }",
    ));
    for ch in 0..9 {
        assert!(max_dev(along.frf.frf(1, ch), nominal.frf.frf(1, ch)) < 1e-14);
    }
}

/// A mass m_b below the gauge of one excitation, against the Woodbury form in nominal
/// FRFs: `y = H d + ω² m_b H₃ (I − ω² m_b D)⁻¹ D d` with H₃ the responses to unit forces
/// along x, y, z at the driving point and D its 3×3 driving-point receptance, both read
/// from a nominal simulation with a triax and three extra forces at that point.
#[test]
fn force_gauge_mass_matches_the_woodbury_form() {
    let mb = 0.05;
    let mut s = tc2();
    s.quantity = Quantity::Receptance;
    let p = s.excitations[1].at_m;
    s.sensors.push(rbprops_sim::spec::SensorSpec {
        id: "g".into(),
        at_m: p,
        kind: rbprops_sim::spec::SensorKind::Triaxial,
        axes: None,
        direction: None,
        channels: None,
    });
    for (k, d) in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
        .iter()
        .enumerate()
    {
        s.excitations.push(rbprops_sim::spec::ExcitationSpec {
            id: format!("g{k}"),
            at_m: p,
            direction: *d,
            setup: "A".into(),
            point: Some("g".into()),
        });
    }
    let nominal = sim(&s);
    let loaded = sim(&with_effect(
        s.clone(),
        &format!("id = \"force_gauge_mass\"\nmasses_kg = {{ force2 = {mb} }}"),
    ));
    let d = Vector3::from(s.excitations[1].direction).map(c);
    let n_ch = 12;
    let freq = s.frequency_axis();
    let mut worst = 0.0f64;
    let mut change = 0.0f64;
    for ch in 0..n_ch {
        let expect: Vec<c64> = freq
            .iter()
            .enumerate()
            .map(|(l, hz)| {
                let w2 = (TAU * hz).powi(2);
                let h3 = nalgebra::RowVector3::from_fn(|_, j| nominal.frf.frf(3 + j, ch)[l]);
                let dp = nalgebra::Matrix3::from_fn(|i, j| nominal.frf.frf(3 + j, 9 + i)[l]);
                let m = nalgebra::Matrix3::<c64>::identity() - dp * c(w2 * mb);
                let corr = h3 * m.try_inverse().unwrap() * dp * d;
                nominal.frf.frf(1, ch)[l] + corr[0] * (w2 * mb)
            })
            .collect();
        worst = worst.max(max_dev(loaded.frf.frf(1, ch), &expect));
        change = change.max(max_dev(loaded.frf.frf(1, ch), nominal.frf.frf(1, ch)));
        // Other excitations are measured without the mass.
        assert_eq!(loaded.frf.frf(0, ch), nominal.frf.frf(0, ch));
    }
    eprintln!("{}: worst = {:e}", module_path!(), worst);
    assert!(worst < 1e-9, "gauge mass vs Woodbury: {worst:e}");
    eprintln!("{}: change = {:e}", module_path!(), change);
    assert!(change > 1e-3, "the mass must matter: {change:e}");
}

/// High-pass: each listed channel × iωτ/(1 + iωτ), others untouched.
#[test]
fn transducer_highpass_is_the_first_order_factor() {
    let nominal = sim(&tc2());
    let out = sim(&with_effect(
        tc2(),
        "id = \"transducer_highpass\"\ntime_constant_s = 1.5\ntime_constants_s = { \"2y\" = 0.4 }",
    ));
    let g = &out.geometry;
    for e in 0..3 {
        for ch in 0..9 {
            let tau = if g.channels[ch].id == "2y" { 0.4 } else { 1.5 };
            let expect: Vec<c64> = nominal
                .frf
                .frf(e, ch)
                .iter()
                .zip(&out.frf.frequency_hz)
                .map(|(h, hz)| {
                    let iwt = c64::new(0.0, TAU * hz * tau);
                    h * iwt / (iwt + 1.0)
                })
                .collect();
            assert!(max_dev(out.frf.frf(e, ch), &expect) < 1e-13, "e{e} c{ch}");
        }
    }
}

/// Added mass: the model's mass matrix is the nominal one plus `[[A, B], [Bᵀ, C]]`
/// entry by entry (B unsymmetric, so a transposed block would show), stiffness and
/// inputs unchanged, and the FRFs move.
#[test]
fn added_mass_adds_its_blocks_to_the_mass_matrix() {
    let s = tc2();
    let g = s.geometry().unwrap();
    let text = "id = \"added_mass\"\ntranslational_kg = [[0.1, 0.02, 0.0], [0.02, 0.2, 0.0], [0.0, 0.0, 0.5]]\n\
                coupling_kg_m = [[0.0, 0.01, -0.03], [0.02, 0.0, 0.0], [0.0, 0.04, 0.0]]\n\
                rotational_kg_m2 = [[0.01, 0.0, 0.002], [0.0, 0.02, 0.0], [0.002, 0.0, 0.005]]";
    let with = with_effect(s.clone(), text);
    let effects = parse_effects(&with).unwrap();
    let m1 = build_models(&with, &g, &effects).unwrap().remove(0).model;
    let m0 = build_models(&s, &g, &[]).unwrap().remove(0).model;
    let a = Mat6::from_row_slice(&[
        0.1, 0.02, 0.0, 0.0, 0.01, -0.03, //
        0.02, 0.2, 0.0, 0.02, 0.0, 0.0, //
        0.0, 0.0, 0.5, 0.0, 0.04, 0.0, //
        0.0, 0.02, 0.0, 0.01, 0.0, 0.002, //
        0.01, 0.0, 0.04, 0.0, 0.02, 0.0, //
        -0.03, 0.0, 0.0, 0.002, 0.0, 0.005,
    ]);
    // Round-off of adding to entries of order |M₀|.
    assert!((m1.mass - m0.mass - a).abs().max() < 4.0 * f64::EPSILON * m0.mass.abs().max());
    assert_eq!(m1.stiffness, m0.stiffness);
    assert_eq!(m1.inputs, m0.inputs);
    let (f0, f1) = (sim(&s), sim(&with));
    assert!(max_dev(f1.frf.frf(2, 5), f0.frf.frf(2, 5)) > 1e-2);
}

/// The receptance `row · (K + ΔK + i(ωC + D) − ω²M)⁻¹ f` of a model with a stiffness
/// ΔK and a hysteretic damping D added, solved line by line (independent of the
/// simulator's observation code).
fn direct_receptance(
    m: &rbprops_sim::model::DynamicModel,
    dk: &Mat6,
    d: &Mat6,
    f: &Vec6,
    row: &nalgebra::RowVector6<f64>,
    freq: &[f64],
) -> Vec<c64> {
    freq.iter()
        .map(|hz| {
            let w = TAU * hz;
            let z = nalgebra::Matrix6::<c64>::from_fn(|i, j| {
                c64::new(
                    m.stiffness[(i, j)] + dk[(i, j)] - w * w * m.mass[(i, j)],
                    w * m.damping[(i, j)] + d[(i, j)],
                )
            });
            let x = z.lu().solve(&f.map(c)).unwrap();
            (0..6).map(|k| x[k] * row[k]).sum()
        })
        .collect()
}

/// Drift: excitation force2's run sees `S (f K + iωC − ω²M)⁻¹ F` with the nominal
/// set-up's S, K, C, M and F (damping not rebuilt), the other runs the nominal model.
#[test]
fn suspension_drift_scales_the_stiffness_of_one_run_only() {
    let f = 1.03;
    let s = receptance(tc2());
    let g = s.geometry().unwrap();
    let nominal = sim(&s);
    let out = sim(&with_effect(
        s.clone(),
        &format!("id = \"suspension_drift\"\nstiffness_factors = {{ force2 = {f} }}"),
    ));
    let m = build_models(&s, &g, &[]).unwrap().remove(0).model;
    let fc = g.excitations[1].column();
    let freq = s.frequency_axis();
    let mut worst = 0.0f64;
    for ch in 0..9 {
        let row = g.channels[ch].row();
        let expect = direct_receptance(
            &m,
            &((f - 1.0) * m.stiffness),
            &Mat6::zeros(),
            &fc,
            &row,
            &freq,
        );
        worst = worst.max(max_dev(out.frf.frf(1, ch), &expect));
        assert_eq!(out.frf.frf(0, ch), nominal.frf.frf(0, ch));
        assert_eq!(out.frf.frf(2, ch), nominal.frf.frf(2, ch));
    }
    assert!(worst < 1e-9, "drifted run vs direct solve: {worst:e}");
}

/// Stinger: excitation force2's run sees `(K + K_a + iωC − ω²M)⁻¹` with `K_a` derived
/// here from the springs' energy, `½ k_l |P u(r)|² + ½ k_r |P θ|²` with `u(r) = x + θ × r`
/// and `P = I − n nᵀ` (probed column by column, without `rigid_transform`); the other runs
/// are the nominal model's, bit for bit.
#[test]
fn stinger_stiffness_acts_across_the_axis_during_its_run_only() {
    let (kl, kr) = (100.0, 2.0);
    let s = receptance(tc2());
    let g = s.geometry().unwrap();
    let nominal = sim(&s);
    let out = sim(&with_effect(
        s.clone(),
        &format!(
            "id = \"stinger_stiffness\"\nlateral_n_per_m = {{ force2 = {kl} }}\nrotational_n_m_per_rad = {{ force2 = {kr} }}"
        ),
    ));
    let m = build_models(&s, &g, &[]).unwrap().remove(0).model;
    let (r, n) = (
        g.excitations[1].position,
        g.excitations[1].direction.normalize(),
    );
    let across = |v: Vec3| v - n * n.dot(&v);
    // The generalised spring forces of unit coordinate q_j, projected on q_i.
    let strain = |q: &Vec6| -> (Vec3, Vec3) {
        let (x, th) = (Vec3::new(q[0], q[1], q[2]), Vec3::new(q[3], q[4], q[5]));
        (across(x + th.cross(&r)), across(th))
    };
    let ka = Mat6::from_fn(|i, j| {
        let (ui, ti) = strain(&Vec6::from_fn(|k, _| (k == i) as u8 as f64));
        let (uj, tj) = strain(&Vec6::from_fn(|k, _| (k == j) as u8 as f64));
        kl * ui.dot(&uj) + kr * ti.dot(&tj)
    });
    let fc = g.excitations[1].column();
    let freq = s.frequency_axis();
    let mut worst = 0.0f64;
    for ch in 0..9 {
        let row = g.channels[ch].row();
        let expect = direct_receptance(&m, &ka, &Mat6::zeros(), &fc, &row, &freq);
        worst = worst.max(max_dev(out.frf.frf(1, ch), &expect));
        assert_eq!(out.frf.frf(0, ch), nominal.frf.frf(0, ch));
        assert_eq!(out.frf.frf(2, ch), nominal.frf.frf(2, ch));
    }
    assert!(worst < 1e-9, "stinger run vs direct solve: {worst:e}");
    // And it matters: the lateral spring is 2/3 of one suspension spring's (150 N/m).
    assert!(max_dev(out.frf.frf(1, 4), nominal.frf.frf(1, 4)) > 1e-2);
}

/// Stinger axial stiffness (a shaker's armature suspension): force2's run sees
/// `(K + K_a + iωC − ω²M)⁻¹` with `K_a` derived here from the spring's energy
/// `½ k_a (n·u(r))²`, `u(r) = x + θ × r` (probed column by column). A uniaxial channel at
/// the force point along its direction then obeys Sherman–Morrison exactly: its
/// dynamic stiffness gains k_a at every line, `1/h' − 1/h = k_a`. The other runs are
/// the nominal model's, bit for bit.
#[test]
fn stinger_axial_stiffness_adds_k_a_to_the_driving_point_dynamic_stiffness() {
    let ka = 300.0;
    let text = format!(
        "{}\n[[sensor]]\nid = \"dp\"\nat_m = [0.30, -0.15, 0.10]\nkind = \"uniaxial\"\ndirection = [0.0, 1.0, 0.0]\n",
        example("test-case-2").unwrap()
    );
    let s = receptance(CampaignSpec::from_toml_str(&text).unwrap());
    let g = s.geometry().unwrap();
    let (r, n) = (
        g.excitations[1].position,
        g.excitations[1].direction.normalize(),
    );
    let dp = g.channels.iter().position(|c| c.point == "dp").unwrap();
    assert_eq!((g.channels[dp].position - r).norm(), 0.0);
    let nominal = sim(&s);
    let out = sim(&with_effect(
        s.clone(),
        &format!("id = \"stinger_axial_stiffness\"\naxial_n_per_m = {{ force2 = {ka} }}"),
    ));
    let m = build_models(&s, &g, &[]).unwrap().remove(0).model;
    let along =
        |q: &Vec6| n.dot(&(Vec3::new(q[0], q[1], q[2]) + Vec3::new(q[3], q[4], q[5]).cross(&r)));
    let unit = |k: usize| Vec6::from_fn(|i, _| (i == k) as u8 as f64);
    let k_a = Mat6::from_fn(|i, j| ka * along(&unit(i)) * along(&unit(j)));
    let fc = g.excitations[1].column();
    let freq = s.frequency_axis();
    let mut worst = 0.0f64;
    for ch in 0..g.channels.len() {
        let row = g.channels[ch].row();
        let expect = direct_receptance(&m, &k_a, &Mat6::zeros(), &fc, &row, &freq);
        worst = worst.max(max_dev(out.frf.frf(1, ch), &expect));
        assert_eq!(out.frf.frf(0, ch), nominal.frf.frf(0, ch));
        assert_eq!(out.frf.frf(2, ch), nominal.frf.frf(2, ch));
    }
    assert!(worst < 1e-9, "armature run vs direct solve: {worst:e}");
    // Sherman–Morrison at the driving point: the added dynamic stiffness is k_a.
    let (h1, h0) = (out.frf.frf(1, dp), nominal.frf.frf(1, dp));
    let mut worst_k = 0.0f64;
    for (l, (a, b)) in h1.iter().zip(h0).enumerate() {
        if freq[l] > 0.0 {
            worst_k = worst_k.max(((1.0 / a - 1.0 / b) - c(ka)).norm());
        }
    }
    // Measured 2.7e-10 N/m; the dynamic stiffness reaches 1e5 N/m at 12.5 Hz, so
    // 1e-6 k_a is roundoff with a wide margin.
    assert!(
        worst_k < 1e-6 * ka,
        "1/h' − 1/h − k_a up to {worst_k:e} N/m"
    );
    eprintln!("driving point: |1/h' − 1/h − k_a| ≤ {worst_k:e} N/m");
    // And it matters: the run's y suspension mode (4 × 220 N/m laterally) moves.
    assert!(max_dev(h1, h0) > 1e-2);
}

/// Hysteretic damping: every run sees `S (K + iD + iωC − ω²M)⁻¹ F` with
/// `D = Σ η_i K_i`, each spring's own stiffness `K_i = T(a_i)ᵀ k_i T(a_i)` assembled here
/// from the spec's spring table; the modal sum refuses it, and so does a finite record.
#[test]
fn hysteretic_damping_is_a_loss_factor_on_each_spring() {
    let eta = [0.08, 0.02, 0.15, 0.0];
    let s = receptance(tc2());
    let g = s.geometry().unwrap();
    let with = with_effect(
        s.clone(),
        "id = \"hysteretic_damping\"\nloss_factors = [0.08, 0.02, 0.15, 0.0]",
    );
    let out = sim(&with);
    let m = build_models(&s, &g, &[]).unwrap().remove(0).model;
    let mut d = Mat6::zeros();
    for (spring, e) in s.setups[0].springs.iter().zip(eta) {
        let a = Vec3::from(spring.at_m);
        let k = spring.stiffness_n_per_m.unwrap();
        // u(a) = x + θ × a: unit coordinate j moves the spring's end by column j.
        let u = |j: usize| -> Vec3 {
            let q = Vec6::from_fn(|i, _| (i == j) as u8 as f64);
            Vec3::new(q[0], q[1], q[2]) + Vec3::new(q[3], q[4], q[5]).cross(&a)
        };
        d += Mat6::from_fn(|i, j| e * (0..3).map(|x| k[x] * u(i)[x] * u(j)[x]).sum::<f64>());
    }
    let freq = s.frequency_axis();
    let mut worst = 0.0f64;
    for ex in 0..3 {
        let fc = g.excitations[ex].column();
        for ch in 0..9 {
            let row = g.channels[ch].row();
            let expect = direct_receptance(&m, &Mat6::zeros(), &d, &fc, &row, &freq);
            worst = worst.max(max_dev(out.frf.frf(ex, ch), &expect));
        }
    }
    assert!(worst < 1e-9, "hysteretic model vs direct solve: {worst:e}");
    let modal = rbprops_sim::simulate_with(
        &with,
        &rbprops_sim::SimOptions {
            method: rbprops_sim::SolveMethod::Modal,
        },
    );
    assert!(modal.unwrap_err().to_string().contains("not classical"));
    let truncated = with_effect(with, "id = \"record_truncation\"\nrecord_length_s = 8.0");
    let err = simulate(&truncated).unwrap_err().to_string();
    assert!(err.contains("hysteretic"), "{err}");
}

/// Delay: channel c of excitation e × e^{−iω(τ_c − τ_e)}, the others untouched.
#[test]
fn channel_delay_is_a_pure_phase_lag_of_the_difference() {
    let nominal = sim(&tc2());
    let out = sim(&with_effect(
        tc2(),
        "id = \"channel_delay\"\nchannels_s = { \"2y\" = 0.002, \"1x\" = -0.001 }\nexcitations_s = { force3 = 0.0005 }",
    ));
    let g = &out.geometry;
    for e in 0..3 {
        for ch in 0..9 {
            let tau_c = match g.channels[ch].id.as_str() {
                "2y" => 0.002,
                "1x" => -0.001,
                _ => 0.0,
            };
            let tau_e = if g.excitations[e].id == "force3" {
                0.0005
            } else {
                0.0
            };
            let expect: Vec<c64> = nominal
                .frf
                .frf(e, ch)
                .iter()
                .zip(&out.frf.frequency_hz)
                .map(|(h, hz)| h * c64::from_polar(1.0, -TAU * hz * (tau_c - tau_e)))
                .collect();
            assert!(max_dev(out.frf.frf(e, ch), &expect) < 1e-13, "e{e} c{ch}");
        }
    }
}

/// Specific force: channel c reads `s_cᵀ(a + g ẑ×θ)`; θ recovered from the nominal
/// receptances of the three triaxes by least squares (exact for a rigid body).
#[test]
fn sensor_tilt_gravity_adds_the_specific_force_term() {
    let gval = 9.80665;
    let plain = sim(&receptance(tc2()));
    let out = sim(&with_effect(tc2(), "id = \"sensor_tilt_gravity\""));
    let g = &out.geometry;
    let smat = DMatrix::from_fn(9, 6, |r, k| g.channels[r].row()[k]);
    let pinv = (smat.transpose() * &smat).try_inverse().unwrap() * smat.transpose();
    let up = Vec3::z();
    let (mut worst, mut effect) = (0.0f64, 0.0f64);
    for e in 0..3 {
        let n = out.frf.n_lines();
        let mut expect = vec![vec![c(0.0); n]; 9];
        for l in 0..n {
            let w = TAU * out.frf.frequency_hz[l];
            let x = DVector::from_fn(9, |ch, _| plain.frf.frf(e, ch)[l]);
            let q = pinv.map(c) * &x;
            let theta = Vector3::new(q[3], q[4], q[5]);
            let tilt = up.map(c).cross(&theta) * c(gval);
            for ch in 0..9 {
                let sdir = g.channels[ch].direction.map(c);
                expect[ch][l] = x[ch] * (-w * w) + sdir.dot(&tilt);
            }
        }
        for ch in 0..9 {
            worst = worst.max(max_dev(out.frf.frf(e, ch), &expect[ch]));
            let nominal: Vec<c64> = (0..n)
                .map(|l| plain.frf.frf(e, ch)[l] * -(TAU * out.frf.frequency_hz[l]).powi(2))
                .collect();
            let dev = max_dev(&nominal, &expect[ch]);
            if g.channels[ch].direction.z.abs() > 0.5 {
                // Vertical channels do not sense the tilt.
                assert!(dev < 1e-9, "vertical channel {ch}: {dev:e}");
            } else {
                effect = effect.max(dev);
            }
        }
    }
    eprintln!("{}: worst = {:e}", module_path!(), worst);
    assert!(worst < 1e-9, "specific-force formula: {worst:e}");
    eprintln!("{}: effect = {:e}", module_path!(), effect);
    assert!(
        effect > 1e-2,
        "horizontal channels must see the tilt: {effect:e}"
    );
    // Receptance and mobility from accelerometers are infinite at 0 Hz with tilt.
    let e = simulate(&with_effect(
        receptance(tc2()),
        "id = \"sensor_tilt_gravity\"",
    ))
    .unwrap_err();
    assert!(e.to_string().contains("0 Hz"), "{e}");
}

/// Rotational mount stiffness adds to K's rotation block, lateral shear at each mount.
#[test]
fn suspension_coupling_adds_the_mount_stiffness() {
    let out = sim(&with_effect(
        tc2(),
        "id = \"suspension_coupling\"\nrotational_n_m_per_rad = [0.5, 0.7, 0.2]\nlateral_n_per_m = 20.0",
    ));
    let nominal = sim(&tc2());
    let k1 = Mat6::from_fn(|i, j| out.truth.setups[0].stiffness[i][j]);
    let k0 = Mat6::from_fn(|i, j| nominal.truth.setups[0].stiffness[i][j]);
    // Independent: an extra spring (20, 20, 0) N/m at each mount through the spec.
    let mut springs = tc2();
    for sp in &mut springs.setups[0].springs {
        let k = sp.stiffness_n_per_m.as_mut().unwrap();
        k[0] += 20.0;
        k[1] += 20.0;
    }
    let mut expect = springs.setup_stiffness(0) - tc2().setup_stiffness(0);
    for (i, kr) in [0.5, 0.7, 0.2].iter().enumerate() {
        expect[(3 + i, 3 + i)] += 4.0 * kr;
    }
    assert!(((k1 - k0) - expect).norm() < 1e-9 * expect.norm());
    assert!(
        out.truth.setups[0].modes[0].frequency_hz > nominal.truth.setups[0].modes[0].frequency_hz
    );
}

/// Bad parameters are refused with the effect index and the parameter named.
#[test]
fn bad_effect_parameters_name_the_effect_and_parameter() {
    for (table, parts) in [
        ("id = \"elastic_mode\"\nfrequency_hz = -5.0\ndamping_ratio = 0.01\nchannels = { \"1x\" = 0.1 }\nexcitations = { force1 = 0.1 }", vec!["frequency_hz"]),
        ("id = \"elastic_mode\"\nfrequency_hz = 50.0\ndamping_ratio = 1.5\nchannels = { \"1x\" = 0.1 }\nexcitations = { force1 = 0.1 }", vec!["damping_ratio"]),
        ("id = \"elastic_mode\"\nfrequency_hz = 50.0\ndamping_ratio = 0.01\nchannels = { \"7x\" = 0.1 }\nexcitations = { force1 = 0.1 }", vec!["channel '7x' is not defined"]),
        ("id = \"elastic_mode\"\nfrequency_hz = 50.0\ndamping_ratio = 0.01\nchannels = { \"1x\" = 0.1 }\nexcitations = { hammer = 0.1 }", vec!["excitation 'hammer' is not defined"]),
        ("id = \"nonproportional_damping\"\naxial_n_s_per_m = [-1.0]", vec!["axial_n_s_per_m[0]"]),
        ("id = \"nonproportional_damping\"\naxial_n_s_per_m = [1.0, 2.0]", vec!["axial_n_s_per_m has 2 values", "4 springs"]),
        ("id = \"nonproportional_damping\"\naxial_n_s_per_m = [1.0]\nsetup = \"B\"", vec!["set-up 'B'"]),
        ("id = \"exponential_window\"\ndecay_per_s = -0.1", vec!["decay_per_s"]),
        ("id = \"exponential_window\"\ndecay_per_s = 0.1\ntime_constant_s = 10.0", vec!["exactly one"]),
        ("id = \"record_truncation\"\nrecord_length_s = 0.0", vec!["record_length_s"]),
        ("id = \"sensor_position\"\noffsets_m = { \"9\" = [0.0, 0.0, 0.001] }", vec!["sensor '9' is not defined"]),
        ("id = \"force_direction\"\nrotations_rad = { force1 = [4.0, 0.0, 0.0] }", vec!["rotations_rad.force1"]),
        ("id = \"force_location\"\noffsets_m = { force9 = [0.0, 0.0, 0.001] }", vec!["excitation 'force9' is not defined"]),
        ("id = \"force_gauge_mass\"\nmasses_kg = { force1 = -0.01 }", vec!["masses_kg.force1"]),
        ("id = \"transducer_highpass\"\ntime_constant_s = 0.0", vec!["positive"]),
        ("id = \"transducer_highpass\"\ntime_constants_s = { \"1q\" = 1.0 }", vec!["channel '1q'"]),
        ("id = \"channel_delay\"\nchannels_s = { \"1q\" = 0.001 }", vec!["channel '1q'"]),
        ("id = \"suspension_drift\"\nstiffness_factors = { force1 = -1.0 }", vec!["stiffness_factors.force1", "positive"]),
        ("id = \"added_mass\"\ntranslational_kg = [[0.1, 0.2, 0.0], [0.0, 0.1, 0.0], [0.0, 0.0, 0.1]]", vec!["translational_kg", "symmetric"]),
        ("id = \"added_mass\"\nrotational_kg_m2 = [[0.1, 0.0], [0.0, 0.1]]", vec!["rotational_kg_m2"]),
        ("id = \"suspension_drift\"\nstiffness_factors = { force8 = 1.01 }", vec!["excitation 'force8'"]),
        ("id = \"channel_delay\"\nexcitations_s = { force7 = 0.001 }", vec!["excitation 'force7'"]),
        ("id = \"stinger_stiffness\"\nlateral_n_per_m = { force7 = 100.0 }", vec!["stinger_stiffness", "excitation 'force7'"]),
        ("id = \"stinger_stiffness\"\nlateral_n_per_m = { force1 = -100.0 }", vec!["lateral_n_per_m.force1", "≥ 0"]),
        ("id = \"stinger_stiffness\"", vec!["lateral_n_per_m and/or rotational_n_m_per_rad"]),
        ("id = \"hysteretic_damping\"\nloss_factors = [0.1, -0.1, 0.0, 0.0]", vec!["loss_factors[1]", "[0, 2]"]),
        ("id = \"hysteretic_damping\"\nloss_factors = [0.1, 0.1]", vec!["loss_factors has 2 values", "4 springs"]),
        ("id = \"channel_delay\"\nchannels_s = { \"1x\" = 2.0 }", vec!["delay of '1x'", "±1 s"]),
        ("id = \"sensor_tilt_gravity\"\nup = [0.0, 1.0, 1.0]", vec!["up"]),
        ("id = \"suspension_coupling\"\nrotational_n_m_per_rad = [0.0, -1.0, 0.0]", vec!["stiffness"]),
        ("id = \"record_truncation\"\nrecord_length_s = 4.0\nwindow = 1", vec!["unknown field", "window"]),
    ] {
        let s = with_effect(tc2(), table);
        let e = s.validate().unwrap_err().to_string();
        for p in parts.iter().chain(&["effect[0]"]) {
            assert!(e.contains(p), "{table}: error {e:?} lacks {p:?}");
        }
    }
}

/// All effects at once still simulate, in any thread count identically, and every one
/// is recorded in the truth.
#[test]
fn all_new_effects_together_are_deterministic_across_threads() {
    let mut s = tc2();
    for (id, text) in rbprops_sim::effect_examples() {
        if *id == "nominal" || *id == "record_truncation" {
            continue;
        }
        let f = CampaignSpec::from_toml_str(text).unwrap();
        s.effects.extend(f.effects);
    }
    s.frequency.lines = 201;
    s.frequency.start_hz = 0.0;
    s.noise.relative = 0.01;
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| simulate(&s).unwrap())
    };
    let a = run(1);
    let b = run(2);
    assert_eq!(a.frf.values, b.frf.values);
    assert_eq!(a.truth.effects.len(), s.effects.len());
    assert!(a
        .frf
        .values
        .iter()
        .all(|v| v.re.is_finite() && v.im.is_finite()));
}
