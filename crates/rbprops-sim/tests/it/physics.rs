//! The nominal simulator against independent closed forms.

use crate::common::spec;
use nalgebra::Matrix6;
use rbprops_core::modal::modal_receptance;
use rbprops_core::{c64, rigid_body_modes, Mat6, Quantity, RigidMode};
use rbprops_sim::{
    example, example_names, simulate, simulate_with, CampaignSpec, SimOptions, SolveMethod,
};

fn rel(a: c64, b: c64) -> f64 {
    (a - b).norm() / b.norm().max(f64::MIN_POSITIVE)
}

/// Largest relative deviation of `a` from `b`, relative to the largest |b| of each FRF
/// (so lines near an antiresonance are judged on the FRF's scale).
fn max_rel_dev(a: &[c64], b: &[c64]) -> f64 {
    let scale = b.iter().map(|x| x.norm()).fold(0.0, f64::max);
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).norm() / scale)
        .fold(0.0, f64::max)
}

#[test]
fn test_case_1_matches_modal_sum_and_direct_solve() {
    let s = spec("test-case-1");
    let sim = simulate(&s).unwrap();
    let props = s.properties();
    let m0 = props.mass_matrix().0;
    let (alpha, beta) = (s.damping.alpha.unwrap(), s.damping.beta.unwrap());
    let g = &sim.geometry;
    let mut worst_modal = 0.0f64;
    let mut worst_direct = 0.0f64;
    for (si, setup) in s.setups.iter().enumerate() {
        let k = s.setup_stiffness(si);
        // Independent modal model: core eigen-solver, Rayleigh ratios ζ = α/2ω + βω/2.
        let modes: Vec<RigidMode> = rigid_body_modes(&m0, &k)
            .unwrap()
            .into_iter()
            .map(|(w, phi)| RigidMode {
                frequency_hz: w / std::f64::consts::TAU,
                damping_ratio: alpha / (2.0 * w) + beta * w / 2.0,
                shape: phi,
            })
            .collect();
        let c = alpha * m0 + beta * k;
        for (e, ex) in g.excitations.iter().enumerate() {
            if ex.setup != setup.id {
                continue;
            }
            let f = ex.column();
            for (ci, ch) in g.channels.iter().enumerate() {
                let row = ch.row();
                let got = sim.frf.frf(e, ci);
                let mut modal = Vec::new();
                let mut direct = Vec::new();
                for &hz in &sim.frf.frequency_hz {
                    let w = std::f64::consts::TAU * hz;
                    modal.push(modal_receptance(&modes, &row, &f, w));
                    let z: Matrix6<c64> = Matrix6::from_fn(|i, j| {
                        c64::new(k[(i, j)] - w * w * m0[(i, j)], w * c[(i, j)])
                    });
                    let fc = f.map(|x| c64::new(x, 0.0));
                    let x = z.lu().solve(&fc).unwrap();
                    direct.push((0..6).map(|i| x[i] * row[i]).sum::<c64>());
                }
                worst_modal = worst_modal.max(max_rel_dev(got, &modal));
                worst_direct = worst_direct.max(max_rel_dev(got, &direct));
            }
        }
    }
    assert!(worst_modal < 1e-10, "modal sum: {worst_modal:e}");
    assert!(worst_direct < 1e-10, "direct solve: {worst_direct:e}");
}

#[test]
fn direct_and_modal_methods_agree() {
    for name in ["test-case-1", "test-case-2", "close-modes"] {
        let mut s = spec(name);
        s.noise = Default::default();
        let a = simulate_with(
            &s,
            &SimOptions {
                method: SolveMethod::Direct,
            },
        )
        .unwrap();
        let b = simulate_with(
            &s,
            &SimOptions {
                method: SolveMethod::Modal,
            },
        )
        .unwrap();
        for e in 0..a.frf.n_excitations {
            for c in 0..a.frf.n_channels {
                let d = max_rel_dev(a.frf.frf(e, c), b.frf.frf(e, c));
                assert!(d < 1e-10, "{name} e{e} c{c}: {d:e}");
            }
        }
    }
}

#[test]
fn true_modes_are_mass_normalised_and_damped_as_specified() {
    for name in example_names() {
        let s = spec(name);
        let sim = simulate(&s).unwrap();
        let m0 = s.properties().mass_matrix().0;
        for (si, t) in sim.truth.setups.iter().enumerate() {
            let phi = Mat6::from_fn(|i, r| t.modes[r].shape[i]);
            let id = phi.transpose() * m0 * phi;
            assert!(
                (id - Mat6::identity()).norm() < 1e-10,
                "{name}: ΦᵀMΦ − I = {:e}",
                (id - Mat6::identity()).norm()
            );
            let k = s.setup_stiffness(si);
            let kt = Mat6::from_fn(|i, j| t.stiffness[i][j]);
            assert!((k - kt).norm() <= 1e-14 * k.norm());
            let om = phi.transpose() * k * phi;
            for (r, m) in t.modes.iter().enumerate() {
                let w = std::f64::consts::TAU * m.frequency_hz;
                assert!((om[(r, r)] - w * w).abs() < 1e-10 * om.norm());
                let expect = match (s.damping.alpha, s.damping.beta, s.damping.ratio) {
                    (None, None, Some(z)) => z,
                    (a, b, None) => a.unwrap_or(0.0) / (2.0 * w) + b.unwrap_or(0.0) * w / 2.0,
                    _ => unreachable!(),
                };
                assert!((m.damping_ratio - expect).abs() < 1e-12, "{name} mode {r}");
            }
        }
        assert_eq!(sim.truth.campaign, s.name);
        assert!(sim.truth.effects.is_empty());
    }
}

#[test]
fn quantities_convert_by_powers_of_i_omega() {
    let mut s = spec("test-case-2");
    s.quantity = Quantity::Receptance;
    let h = simulate(&s).unwrap().frf;
    for (q, k) in [(Quantity::Mobility, 1), (Quantity::Accelerance, 2)] {
        s.quantity = q;
        let y = simulate(&s).unwrap().frf;
        assert_eq!(y.quantity, q);
        for e in 0..h.n_excitations {
            for c in 0..h.n_channels {
                for (l, &hz) in h.frequency_hz.iter().enumerate() {
                    let iw = c64::new(0.0, std::f64::consts::TAU * hz);
                    let expect = h.frf(e, c)[l] * iw.powi(k);
                    let got = y.frf(e, c)[l];
                    assert!(
                        (got - expect).norm() <= 1e-13 * expect.norm().max(1e-300),
                        "{q:?} {l}"
                    );
                }
            }
        }
        // And the core conversion back gives the receptance (0 Hz line excluded).
        let back = y.band(1e-9, 1e9).to_quantity(Quantity::Receptance).unwrap();
        let hb = h.band(1e-9, 1e9);
        for (a, b) in back.values.iter().zip(&hb.values) {
            assert!(rel(*a, *b) < 1e-12);
        }
    }
}

/// A body with its CoM at the origin between two springs on the z axis: vertical motion
/// decouples and the z/z receptance is the SDOF `1/(k − mω² + 2iζ√(km) ω)`.
#[test]
fn single_dof_vertical_mode_matches_analytic_receptance() {
    let text = r#"
name = "sdof"
quantity = "receptance"
[frequency]
start_hz = 0.0
stop_hz = 5.0
lines = 501
[body]
mass_kg = 2.0
com_m = [0.0, 0.0, 0.0]
moments_kg_m2 = [0.01, 0.012, 0.014]
products_kg_m2 = { xy = 0.0, xz = 0.0, yz = 0.0 }
[[setup]]
id = "A"
[[setup.spring]]
at_m = [0.0, 0.0, 0.1]
stiffness_n_per_m = [30.0, 40.0, 250.0]
[[setup.spring]]
at_m = [0.0, 0.0, -0.1]
stiffness_n_per_m = [30.0, 40.0, 250.0]
[[setup.spring]]
at_m = [0.1, 0.0, 0.0]
stiffness_n_per_m = [0.0, 25.0, 0.0]
[[setup.spring]]
at_m = [-0.1, 0.0, 0.0]
stiffness_n_per_m = [0.0, 25.0, 0.0]
[[sensor]]
id = "a"
at_m = [0.1, 0.0, 0.0]
kind = "triaxial"
[[sensor]]
id = "b"
at_m = [0.0, 0.1, 0.0]
kind = "triaxial"
[[sensor]]
id = "c"
at_m = [0.0, 0.0, 0.1]
kind = "triaxial"
[[excitation]]
id = "Fz"
at_m = [0.0, 0.0, 0.0]
direction = [0.0, 0.0, 1.0]
setup = "A"
[damping]
model = "modal"
ratio = 0.03
"#;
    let s = CampaignSpec::from_toml_str(text).unwrap();
    let sim = simulate(&s).unwrap();
    let (m, k, z) = (2.0, 500.0, 0.03);
    let g = &sim.geometry;
    for (ci, ch) in g.channels.iter().enumerate() {
        for (l, &hz) in sim.frf.frequency_hz.iter().enumerate() {
            let w = std::f64::consts::TAU * hz;
            let sdof = c64::new(1.0, 0.0) / c64::new(k - m * w * w, 2.0 * z * (k * m).sqrt() * w);
            let got = sim.frf.frf(0, ci)[l];
            if ch.direction.z == 1.0 {
                assert!(
                    rel(got, sdof) < 1e-12,
                    "{} at {hz} Hz: {got} vs {sdof}",
                    ch.id
                );
            } else {
                assert!(
                    got.norm() < 1e-12 * sdof.norm(),
                    "{} at {hz} Hz: {got}",
                    ch.id
                );
            }
        }
    }
}

#[test]
fn every_example_parses_round_trips_and_simulates() {
    for name in example_names() {
        let s = spec(name);
        assert_eq!(s.name, *name);
        let back = CampaignSpec::from_toml_str(&s.to_toml_string()).unwrap();
        assert_eq!(
            back, s,
            "{name}: --print-spec output must parse back to the same spec"
        );
        let sim = simulate(&s).unwrap();
        sim.frf.validate().unwrap();
        assert_eq!(sim.frf.n_channels, sim.geometry.channels.len());
        assert_eq!(sim.geometry.excitations.len(), s.excitations.len());
        sim.geometry.check_rigid_observability().unwrap();
    }
    assert!(example("no-such-campaign").is_none());
}

#[test]
fn demo_is_test_case_2_with_noise() {
    let a = spec("test-case-2");
    let mut d = spec("demo");
    assert_eq!(d.noise.relative, 0.01);
    assert_eq!(a.noise.relative, 0.0);
    d.name = a.name.clone();
    d.description = a.description.clone();
    d.seed = a.seed;
    d.noise = a.noise.clone();
    assert_eq!(d, a);
}

#[test]
fn test_case_2_geometry_reproduces_paper_com_vectors() {
    let s = spec("test-case-2");
    let c = s.properties().com;
    let expect_mm = [
        [177.25, 30.40, -5.35],
        [75.45, -184.42, -61.069],
        [39.15, 86.08, 127.43],
    ];
    for (sensor, v) in s.sensors.iter().zip(expect_mm) {
        for i in 0..3 {
            assert!(
                ((c[i] - sensor.at_m[i]) * 1e3 - v[i]).abs() < 1e-9,
                "sensor {}",
                sensor.id
            );
        }
    }
    let p = s.properties();
    assert!((p.inertia_cm[(0, 1)] + 0.07722671).abs() < 1e-15);
    assert!((p.inertia_cm[(0, 2)] - 0.08736156).abs() < 1e-15);
    assert!((p.inertia_cm[(1, 2)] - 0.06919817).abs() < 1e-15);
    let sim = simulate(&s).unwrap();
    let f: Vec<f64> = sim.truth.setups[0]
        .modes
        .iter()
        .map(|m| m.frequency_hz)
        .collect();
    assert!(
        f[0] > 0.8 && f[5] < 8.0,
        "rigid modes roughly 1-8 Hz: {f:?}"
    );
}

/// Peak level of mode r in excitation e's FRFs, `|fᵀφ| ‖Sφ‖ / (2ζω²)`, in dB re the
/// excitation's strongest mode.
fn excitation_levels(s: &CampaignSpec) -> Vec<(String, String, Vec<f64>)> {
    let sim = simulate(s).unwrap();
    let g = &sim.geometry;
    let mut out = Vec::new();
    for t in &sim.truth.setups {
        for e in g.excitations.iter().filter(|e| e.setup == t.setup) {
            let f = e.column();
            let lv: Vec<f64> = t
                .modes
                .iter()
                .map(|m| {
                    let phi = rbprops_core::Vec6::from(m.shape);
                    let sphi = g
                        .channels
                        .iter()
                        .map(|c| (c.row() * phi)[0].powi(2))
                        .sum::<f64>()
                        .sqrt();
                    let w = std::f64::consts::TAU * m.frequency_hz;
                    f.dot(&phi).abs() * sphi / (2.0 * m.damping_ratio * w * w)
                })
                .collect();
            let mx = lv.iter().cloned().fold(0.0, f64::max);
            out.push((
                t.setup.clone(),
                e.id.clone(),
                lv.iter().map(|v| 20.0 * (v / mx).log10()).collect(),
            ));
        }
    }
    out
}

#[test]
fn test_case_1_forces_excite_subsets() {
    let lv = excitation_levels(&spec("test-case-1"));
    for (_, id, l) in &lv {
        assert!(
            l.iter().any(|&x| x < -20.0),
            "{id} excites all six modes within 20 dB: {l:?}"
        );
    }
    for setup in ["A", "B"] {
        for r in 0..6 {
            assert!(
                lv.iter().any(|(s, _, l)| s == setup && l[r] > -15.0),
                "set-up {setup} mode {}: no force within 15 dB",
                r + 1
            );
        }
    }
}

#[test]
fn close_modes_hit_their_design_frequencies() {
    let sim = simulate(&spec("close-modes")).unwrap();
    let f: Vec<f64> = sim.truth.setups[0]
        .modes
        .iter()
        .map(|m| m.frequency_hz)
        .collect();
    let target = [0.800, 0.812, 1.100, 1.300, 1.550, 1.575];
    for (a, b) in f.iter().zip(target) {
        assert!((a / b - 1.0).abs() < 5e-3, "{f:?}");
    }
    // Each pair lies within its half-power bandwidth 2ζf.
    let z = sim.truth.setups[0].modes[0].damping_ratio;
    for (i, j) in [(0, 1), (4, 5)] {
        assert!(
            f[j] - f[i] < 2.0 * z * f[i],
            "pair {i},{j}: {} Hz apart",
            f[j] - f[i]
        );
    }
    assert_eq!(sim.geometry.excitations.len(), 5);
}

#[test]
fn missing_mode_force4_leaves_mode_3_unexcited() {
    let s = spec("missing-mode");
    let sim = simulate(&s).unwrap();
    let g = &sim.geometry;
    let e = g.excitation_index("force4").unwrap();
    let f = g.excitations[e].column();
    let modal_forces: Vec<f64> = sim.truth.setups[0]
        .modes
        .iter()
        .map(|m| f.dot(&rbprops_core::Vec6::from(m.shape)))
        .collect();
    let mx = modal_forces.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    assert!(modal_forces[2].abs() < 1e-9 * mx, "{modal_forces:?}");
    for (r, v) in modal_forces.iter().enumerate() {
        if r != 2 {
            assert!(
                v.abs() > 0.05 * mx,
                "mode {} barely excited: {modal_forces:?}",
                r + 1
            );
        }
    }
    // The other forces all excite mode 3.
    let lv = excitation_levels(&s);
    for (_, id, l) in lv.iter().filter(|(_, id, _)| id != "force4") {
        assert!(l[2] > -15.0, "{id}: {l:?}");
    }
}
