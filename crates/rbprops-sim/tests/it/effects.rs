//! Effects of the physics catalogue against independent derivations.

use crate::common::{max_dev, tc2, with_effect};
use rbprops_core::{c64, rigid_transform, Mat3, Mat6, Vec3, Vec6};
use rbprops_sim::effects::gravity::{cord_tensions, geometric_stiffness, Cord};
use rbprops_sim::effects::{parse_effect, parse_effects};
use rbprops_sim::spec::EffectSpec;
use rbprops_sim::{simulate, CampaignSpec, SimError};

/// Three vertical cords of length ℓ at radius ρ, 120° apart, in the CoM's horizontal
/// plane: lateral modes are pendulums `ω² = g/ℓ`, yaw is trifilar `ω² = m g ρ²/(ℓ J_zz)`.
#[test]
fn trifilar_pendulum_frequencies() {
    let (m, l, rho, g, jzz, k): (f64, f64, f64, f64, f64, f64) =
        (5.0, 0.8, 0.15, 9.80665, 0.05, 4000.0);
    let mut springs = String::new();
    for i in 0..3 {
        let a = std::f64::consts::TAU * i as f64 / 3.0;
        springs += &format!(
            "[[setup.spring]]\nat_m = [{}, {}, 0.0]\nstiffness_n_per_m = [0.0, 0.0, {k}]\n",
            rho * a.cos(),
            rho * a.sin()
        );
    }
    let text = format!(
        r#"
name = "trifilar"
quantity = "receptance"
[frequency]
start_hz = 0.1
stop_hz = 5.0
lines = 50
[body]
mass_kg = {m}
com_m = [0.0, 0.0, 0.0]
moments_kg_m2 = [0.03, 0.04, {jzz}]
products_kg_m2 = {{ xy = 0.0, xz = 0.0, yz = 0.0 }}
[[setup]]
id = "T"
{springs}
[[sensor]]
id = "a"
at_m = [0.1, 0.0, 0.05]
kind = "triaxial"
[[sensor]]
id = "b"
at_m = [0.0, 0.1, 0.05]
kind = "triaxial"
[[sensor]]
id = "c"
at_m = [-0.1, -0.1, 0.05]
kind = "triaxial"
[[excitation]]
id = "F"
at_m = [0.1, 0.05, 0.0]
direction = [0.0, 1.0, 0.0]
setup = "T"
[damping]
model = "modal"
ratio = 0.01
[[effect]]
id = "gravity_stiffness"
cord_length_m = [{l}]
"#
    );
    let s = CampaignSpec::from_toml_str(&text).unwrap();
    let sim = simulate(&s).unwrap();
    let f: Vec<f64> = sim.truth.setups[0]
        .modes
        .iter()
        .map(|m| m.frequency_hz)
        .collect();
    let tau = std::f64::consts::TAU;
    let pend = (g / l).sqrt() / tau;
    let yaw = (m * g * rho * rho / (l * jzz)).sqrt() / tau;
    let near = |x: f64| f.iter().filter(|y| (*y / x - 1.0).abs() < 1e-9).count();
    assert_eq!(near(pend), 2, "pendulum {pend} Hz in {f:?}");
    assert_eq!(near(yaw), 1, "trifilar yaw {yaw} Hz in {f:?}");
    assert_eq!(sim.truth.effects[0].id, "gravity_stiffness");
    // Without gravity the same springs leave x, y and yaw free: three zero-frequency
    // modes, the other three positive.
    let mut bare = s.clone();
    bare.effects.clear();
    let sim = simulate(&bare).unwrap();
    let f: Vec<f64> = sim.truth.setups[0]
        .modes
        .iter()
        .map(|m| m.frequency_hz)
        .collect();
    assert_eq!(f.iter().filter(|x| **x == 0.0).count(), 3, "{f:?}");
    assert!(f[3] > 0.1, "{f:?}");
}

/// Exact potential of vertical cords (anchors at `a_i + ℓ_i ẑ`, unstretched length
/// `ℓ_i − T_i/k_i`) plus gravity, for a finite rigid motion `u`, `R = exp([θ]×)`.
fn potential(cords: &[Cord], t: &[f64], m: f64, c: &Vec3, g: f64, up: &Vec3, q: &Vec6) -> f64 {
    let u = Vec3::new(q[0], q[1], q[2]);
    let r = nalgebra::Rotation3::new(Vec3::new(q[3], q[4], q[5])).into_inner();
    let mut v = m * g * up.dot(&(u + r * c));
    for (cd, ti) in cords.iter().zip(t) {
        let anchor = cd.at + cd.length * up;
        let len = (anchor - (u + r * cd.at)).norm();
        let l0 = cd.length - ti / cd.axial_stiffness;
        v += 0.5 * cd.axial_stiffness * (len - l0).powi(2);
    }
    v
}

#[test]
fn geometric_stiffness_is_the_hessian_of_the_exact_potential() {
    let up = Vec3::new(0.1, -0.2, 1.0).normalize();
    let props = rbprops_core::RigidBodyProperties::from_moments_and_products(
        7.0,
        Vec3::new(0.12, 0.05, -0.08),
        [0.2, 0.25, 0.3],
        rbprops_core::inertia::ProductsOfInertia {
            xy: 0.01,
            xz: -0.02,
            yz: 0.015,
        },
    );
    let mass = props.mass_matrix().0;
    let cords = [
        Cord {
            at: Vec3::new(-0.1, -0.15, 0.12),
            length: 0.9,
            axial_stiffness: 900.0,
        },
        Cord {
            at: Vec3::new(0.35, -0.1, 0.10),
            length: 1.1,
            axial_stiffness: 1200.0,
        },
        Cord {
            at: Vec3::new(0.3, 0.25, 0.15),
            length: 0.7,
            axial_stiffness: 800.0,
        },
        Cord {
            at: Vec3::new(-0.05, 0.2, 0.11),
            length: 1.0,
            axial_stiffness: 1000.0,
        },
    ];
    let g = 9.81;
    let (kgeo, t) = geometric_stiffness(&mass, &cords, g, &up).unwrap();
    let mut k = kgeo;
    for cd in &cords {
        let tr = rigid_transform(&cd.at);
        k += tr.transpose() * (cd.axial_stiffness * up * up.transpose()) * tr;
    }
    let (m, c) = (props.mass, props.com);
    let v = |q: &Vec6| potential(&cords, &t, m, &c, g, &up, q);
    let h = 1e-4;
    let e = |i: usize| Vec6::from_fn(|r, _| if r == i { h } else { 0.0 });
    let mut fd = Mat6::zeros();
    let mut grad = Vec6::zeros();
    for i in 0..6 {
        grad[i] = (v(&e(i)) - v(&(-e(i)))) / (2.0 * h);
        for j in 0..6 {
            fd[(i, j)] = (v(&(e(i) + e(j))) - v(&(e(i) - e(j))) - v(&(e(j) - e(i)))
                + v(&(-e(i) - e(j))))
                / (4.0 * h * h);
        }
    }
    // Equilibrium: no first-order force at q = 0 (relative to the weight's scale).
    assert!(grad.norm() < 1e-6 * m * g, "gradient {grad}");
    let err = (fd - k).norm() / k.norm();
    assert!(
        err < 1e-6,
        "relative Hessian error {err:e}\nFD {fd}\nanalytic {k}"
    );
    // The geometric part matters: without it the Hessian is far off.
    assert!((fd - (k - kgeo)).norm() / k.norm() > 1e-3);
}

#[test]
fn slack_cords_and_bad_lengths_are_errors() {
    let cords = [
        Cord {
            at: Vec3::new(0.0, 0.0, 0.0),
            length: 1.0,
            axial_stiffness: 100.0,
        },
        Cord {
            at: Vec3::new(1.0, 0.0, 0.0),
            length: 1.0,
            axial_stiffness: 100.0,
        },
        Cord {
            at: Vec3::new(0.0, 1.0, 0.0),
            length: 1.0,
            axial_stiffness: 100.0,
        },
    ];
    let e = cord_tensions(&cords, 1.0, &Vec3::new(0.9, 0.9, 0.0), 9.81, &Vec3::z()).unwrap_err();
    assert!(e.contains("slack"), "{e}");
    assert!(
        cord_tensions(&cords, 1.0, &Vec3::new(0.2, 0.3, -0.5), 9.81, &Vec3::z())
            .unwrap()
            .iter()
            .all(|t| *t > 0.0)
    );
    // Through the spec: CoM moved outside the springs' rectangle.
    let mut s = with_effect(tc2(), "id = \"gravity_stiffness\"\ncord_length_m = [1.0]");
    s.body.com_m = [0.6, 0.03, 0.0];
    let e = simulate(&s).unwrap_err();
    assert!(
        matches!(e, SimError::Effect { .. }) && e.to_string().contains("slack"),
        "{e}"
    );
    for bad in [
        "cord_length_m = [-1.0]",
        "cord_length_m = [1.0, 2.0]",
        "cord_length_m = [1.0]\nlength = 3",
    ] {
        let s = with_effect(tc2(), &format!("id = \"gravity_stiffness\"\n{bad}"));
        let e = s.validate().unwrap_err().to_string();
        assert!(e.contains("effect[0]"), "{bad}: {e}");
    }
}

/// Point masses at the sensors ≡ a heavier body with the combined m, c, J (parallel axes).
#[test]
fn sensor_mass_equals_the_combined_body() {
    let masses = [0.05, 0.02, 0.08];
    let s = with_effect(
        tc2(),
        "id = \"sensor_mass\"\nmass_kg = 0.05\nmasses_kg = { \"2\" = 0.02, \"3\" = 0.08 }",
    );
    let loaded = simulate(&s).unwrap();
    let p = s.properties();
    let pts: Vec<(f64, Vec3)> = s
        .sensors
        .iter()
        .zip(masses)
        .map(|(x, m)| (m, Vec3::from(x.at_m)))
        .collect();
    let m2 = p.mass + masses.iter().sum::<f64>();
    let c2 = (p.mass * p.com + pts.iter().fold(Vec3::zeros(), |a, (m, x)| a + *m * x)) / m2;
    let steiner = |m: f64, d: Vec3| m * (d.norm_squared() * Mat3::identity() - d * d.transpose());
    let mut j2 = p.inertia_cm + steiner(p.mass, p.com - c2);
    for (m, x) in &pts {
        j2 += steiner(*m, x - c2);
    }
    let mut heavy = tc2();
    heavy.body.mass_kg = m2;
    heavy.body.com_m = [c2.x, c2.y, c2.z];
    heavy.body.moments_kg_m2 = None;
    heavy.body.products_kg_m2 = None;
    heavy.body.inertia_cm_kg_m2 =
        Some(std::array::from_fn(|r| std::array::from_fn(|c| j2[(r, c)])));
    let h = simulate(&heavy).unwrap();
    for e in 0..3 {
        for c in 0..9 {
            let d = max_dev(loaded.frf.frf(e, c), h.frf.frf(e, c));
            assert!(d < 1e-9, "e{e} c{c}: {d:e}");
        }
    }
    // The truth keeps the bare body's properties and records the effect.
    assert_eq!(loaded.truth.properties.mass_kg, 15.69);
    assert_eq!(loaded.truth.effects[0].id, "sensor_mass");
    // Loading lowers every mode.
    let nominal = simulate(&tc2()).unwrap();
    for (a, b) in loaded.truth.setups[0]
        .modes
        .iter()
        .zip(&nominal.truth.setups[0].modes)
    {
        assert!(a.frequency_hz < b.frequency_hz);
    }
}

#[test]
fn gains_scale_exactly_the_named_channels_and_excitations() {
    let nominal = simulate(&tc2()).unwrap().frf;
    let s = with_effect(
        tc2(),
        "id = \"channel_gain\"\ngains = { \"2y\" = 1.05, \"3z\" = 0.9 }",
    );
    let s = with_effect(s, "id = \"excitation_gain\"\ngains = { force2 = 0.97 }");
    let s = with_effect(s, "id = \"global_gain\"\ngain = 1.02");
    let sim = simulate(&s).unwrap();
    let g = &sim.geometry;
    for e in 0..3 {
        for c in 0..9 {
            let mut k = 1.02;
            k *= match g.channels[c].id.as_str() {
                "2y" => 1.05,
                "3z" => 0.9,
                _ => 1.0,
            };
            if g.excitations[e].id == "force2" {
                k *= 0.97;
            }
            let expect: Vec<c64> = nominal.frf(e, c).iter().map(|x| x * k).collect();
            assert!(max_dev(sim.frf.frf(e, c), &expect) < 1e-13, "e{e} c{c}");
        }
    }
    assert_eq!(sim.truth.effects.len(), 3);
    let bad = with_effect(tc2(), "id = \"channel_gain\"\ngains = { \"9q\" = 1.0 }");
    assert!(bad
        .validate()
        .unwrap_err()
        .to_string()
        .contains("channel '9q' is not defined"));
    let bad = with_effect(tc2(), "id = \"global_gain\"\ngain = -1.0");
    assert!(bad.validate().unwrap_err().to_string().contains("positive"));
}

/// A rotated triax reports its point's motion rotated by Rᵀ.
#[test]
fn misorientation_rotates_the_triax_reading() {
    let psi = Vec3::new(0.03, -0.05, 0.02);
    let nominal = simulate(&tc2()).unwrap().frf;
    let s = with_effect(
        tc2(),
        "id = \"sensor_misorientation\"\nrotations_rad = { \"2\" = [0.03, -0.05, 0.02] }",
    );
    let sim = simulate(&s).unwrap().frf;
    let r = nalgebra::Rotation3::new(psi).into_inner();
    for e in 0..3 {
        for l in 0..nominal.n_lines() {
            let u = nalgebra::Vector3::from_fn(|i, _| nominal.frf(e, 3 + i)[l]);
            let expect = r.transpose().map(|x| c64::new(x, 0.0)) * u;
            let scale = u.norm().max(1e-300);
            for i in 0..3 {
                assert!((sim.frf(e, 3 + i)[l] - expect[i]).norm() <= 1e-12 * scale);
                assert_eq!(sim.frf(e, i)[l], nominal.frf(e, i)[l]);
                assert_eq!(sim.frf(e, 6 + i)[l], nominal.frf(e, 6 + i)[l]);
            }
        }
    }
}

/// A misorientation applied after a sensor offset or a channel gain on the same sensor
/// keeps them: at its neutral point the FRFs are exactly those without it, and with a
/// rotation they are the rotated FRFs with the gain (to first order in the offset's and
/// the rotation's product). It used to rewrite the sensor's rows from the geometry,
/// dropping both.
#[test]
fn misorientation_after_an_offset_or_a_gain_keeps_them() {
    let earlier = [
        "id = \"sensor_position\"\noffsets_m = { \"2\" = [0.004, -0.003, 0.005] }",
        "id = \"channel_gain\"\ngains = { \"2y\" = 1.05 }",
    ];
    for first in earlier {
        let without = simulate(&with_effect(tc2(), first)).unwrap().frf;
        let neutral = with_effect(
            with_effect(tc2(), first),
            "id = \"sensor_misorientation\"\nrotations_rad = { \"2\" = [0.0, 0.0, 0.0] }",
        );
        let sim = simulate(&neutral).unwrap().frf;
        for e in 0..3 {
            for c in 0..9 {
                assert!(
                    max_dev(sim.frf(e, c), without.frf(e, c)) < 1e-13,
                    "{first}: e{e} c{c}"
                );
            }
        }
    }
    // A gain and a rotation on sensor 2: channel 2y reads 1.05 × the rotated reading up
    // to the product of the two, (1.05 − 1)(R s − s)ᵀ u with |R s − s| ≤ |ψ|: at most
    // 0.05·|ψ|·|u| ≤ 0.087·|ψ| of the sensor's largest reading (|u| ≤ √3 × it), where a
    // dropped gain or rotation is of first order (0.05, or |ψ| = 0.037).
    let psi = Vec3::new(0.03, -0.02, 0.01);
    let rotations =
        "id = \"sensor_misorientation\"\nrotations_rad = { \"2\" = [0.03, -0.02, 0.01] }";
    let rotated = simulate(&with_effect(tc2(), rotations)).unwrap().frf;
    let both = simulate(&with_effect(with_effect(tc2(), earlier[1]), rotations))
        .unwrap()
        .frf;
    for e in 0..3 {
        let reading = (3..6)
            .flat_map(|c| rotated.frf(e, c).iter().map(|x| x.norm()))
            .fold(0.0, f64::max);
        let dev = |other: &dyn Fn(c64) -> c64| {
            both.frf(e, 4)
                .iter()
                .zip(rotated.frf(e, 4))
                .map(|(b, r)| (b - other(*r)).norm())
                .fold(0.0, f64::max)
                / reading
        };
        let with_gain = dev(&|r| r * 1.05);
        assert!(with_gain < 0.087 * psi.norm(), "e{e}: {with_gain}");
        // The gain is there: 2y moves by ≈ 5 % of its own largest value.
        let gain = max_dev(both.frf(e, 4), rotated.frf(e, 4));
        assert!(gain > 0.04, "e{e}: the gain is kept ({gain})");
    }
}

#[test]
fn effects_rebuild_from_their_parameter_vectors() {
    for (table, n) in [
        (
            "id = \"gravity_stiffness\"\ncord_length_m = [1.0, 1.1, 0.9, 1.2]",
            4,
        ),
        (
            "id = \"sensor_mass\"\nmass_kg = 0.02\nmasses_kg = { \"1\" = 0.03 }",
            2,
        ),
        ("id = \"channel_gain\"\ngains = { \"1x\" = 1.01 }", 1),
        ("id = \"excitation_gain\"\ngains = { force1 = 0.99 }", 1),
        ("id = \"global_gain\"\ngain = 1.1", 1),
        (
            "id = \"sensor_misorientation\"\nrotations_rad = { \"1\" = [0.01, 0.0, -0.01] }",
            3,
        ),
        (
            "id = \"elastic_mode\"\nfrequency_hz = 40.0\ndamping_ratio = 0.01\nchannels = { \"1x\" = 0.2, \"2z\" = -0.1 }\nexcitations = { force1 = 0.3 }",
            5,
        ),
        (
            "id = \"nonproportional_damping\"\naxial_n_s_per_m = [1.0, 2.0, 3.0, 4.0]\nlateral_n_s_per_m = [0.5]",
            5,
        ),
        ("id = \"exponential_window\"\ndecay_per_s = 0.3", 1),
        ("id = \"exponential_window\"\ntime_constant_s = 4.0", 1),
        ("id = \"record_truncation\"\nrecord_length_s = 12.0", 1),
        ("id = \"sensor_position\"\noffsets_m = { \"3\" = [0.001, 0.0, -0.002] }", 3),
        ("id = \"force_direction\"\nrotations_rad = { force2 = [0.05, 0.0, 0.02] }", 3),
        ("id = \"force_location\"\noffsets_m = { force3 = [0.002, 0.003, 0.0] }", 3),
        ("id = \"force_gauge_mass\"\nmasses_kg = { force1 = 0.01, force3 = 0.02 }", 2),
        ("id = \"transducer_highpass\"\ntime_constant_s = 1.0\ntime_constants_s = { \"2x\" = 3.0 }", 2),
        ("id = \"sensor_tilt_gravity\"", 1),
        ("id = \"suspension_coupling\"\nrotational_n_m_per_rad = [0.1, 0.2, 0.3]", 4),
        (
            "id = \"cord_mass\"\nmass_per_length_kg_per_m = [0.05, 0.06, 0.07, 0.08]\ncord_length_m = [1.0]",
            4,
        ),
    ] {
        let spec: EffectSpec = toml::from_str(table).unwrap();
        let e = parse_effect(&spec).unwrap();
        let v = e.values();
        assert_eq!(v.len(), n, "{table}");
        assert_eq!(e.parameters().len(), n);
        let same = e.with_values(&v).unwrap();
        assert_eq!(same.parameters_json(), e.parameters_json());
        for (p, x) in e.parameters().iter().zip(&v) {
            assert!(p.lower <= *x && *x <= p.upper, "{}", p.name);
        }
        assert!(e.with_values(&vec![1.0; n + 1]).is_err());
        let s = with_effect(tc2(), table);
        let sim = simulate(&s).unwrap();
        assert_eq!(sim.truth.effects.len(), 1);
        assert_eq!(sim.truth.effects[0].parameters, e.parameters_json());
        assert_eq!(parse_effects(&s).unwrap().len(), 1);
    }
}

#[test]
fn effect_fixtures_are_test_case_2_plus_one_effect() {
    let known: Vec<&str> = rbprops_sim::effects::registry()
        .iter()
        .map(|d| d.id)
        .collect();
    let fixtures = rbprops_sim::effect_examples();
    assert_eq!(fixtures.len(), known.len() + 1);
    for (id, text) in fixtures {
        let mut s = CampaignSpec::from_toml_str(text).unwrap();
        let back = CampaignSpec::from_toml_str(&s.to_toml_string()).unwrap();
        assert_eq!(back, s, "{id}: --print-spec round trip");
        let sim = simulate(&s).unwrap();
        if *id == "nominal" {
            assert!(s.effects.is_empty());
        } else {
            assert!(known.contains(id));
            assert_eq!(s.effects.len(), 1);
            assert_eq!(s.effects[0].id, *id);
            assert_eq!(sim.truth.effects[0].id, *id);
        }
        let base = tc2();
        s.name = base.name.clone();
        s.description = base.description.clone();
        assert_eq!(s.noise.relative, 0.01, "{id}: 1 % noise");
        s.noise = base.noise.clone();
        s.effects.clear();
        assert_eq!(s, base, "{id}");
    }
}

/// The spec's `up` is the default of every gravity effect's own `up`: a spec saying
/// `up = −z` (a frame with z down) with entries that give none simulates exactly as
/// entries that say `up = −z`, and differently from +z. A spec `up` that is not a unit vector is a validation error.
#[test]
fn the_spec_up_is_the_default_of_the_gravity_effects() {
    let mut base = tc2();
    base.frequency.lines = 200;
    // Off 0 Hz, where the tilt term of an accelerance is infinite.
    base.frequency.start_hz = 0.5;
    let entries = [
        "id = \"gravity_stiffness\"\ncord_length_m = [0.8]",
        "id = \"sensor_tilt_gravity\"",
    ];
    let build = |up: Option<[f64; 3]>, own: &str| {
        let mut s = base.clone();
        s.up = up;
        for e in entries {
            s = with_effect(s, &format!("{e}{own}"));
        }
        simulate(&s).unwrap().frf.values
    };
    let spec_up = build(Some([0.0, 0.0, -1.0]), "");
    let own_up = build(None, "\nup = [0.0, 0.0, -1.0]");
    let z_up = build(None, "");
    assert_eq!(spec_up, own_up);
    // The tilt term g[up]× is odd in `up` (the cords' stiffness is even in it).
    assert!(
        max_dev(&spec_up, &z_up) > 1e-3,
        "{}",
        max_dev(&spec_up, &z_up)
    );
    // An entry's own `up` wins over the spec's.
    let mixed = build(Some([0.0, 1.0, 0.0]), "\nup = [0.0, 0.0, -1.0]");
    assert_eq!(mixed, own_up);
    let mut bad = base.clone();
    bad.up = Some([0.0, 0.0, 2.0]);
    let err = bad.validate().unwrap_err().to_string();
    assert!(err.contains("up") && err.contains("unit"), "{err}");
}
