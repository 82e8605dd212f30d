//! Free rigid-body directions and cords given as cords, against independent derivations:
//! the free–free mass line, a finite-difference Hessian of the hanging body's potential
//! written here with Rodrigues rotations, and the vertical-cord geometric stiffness.

use rbprops_core::{c64, rigid_transform, Mat3, Mat6, Vec3, Vec6};
use rbprops_sim::effects::gravity::{
    cord_tensions, geometric_stiffness, hanging_equilibrium, AnchoredCord, Cord, STANDARD_GRAVITY,
};
use rbprops_sim::suspension::{mount_stiffness, Spring};
use rbprops_sim::{simulate, simulate_with, CampaignSpec, SimOptions, SolveMethod};

const BODY: &str = r#"
[body]
mass_kg = 7.0
com_m = [0.12, 0.05, -0.08]
moments_kg_m2 = [0.2, 0.25, 0.3]
products_kg_m2 = { xy = 0.01, xz = -0.02, yz = 0.015 }
[[sensor]]
id = "1"
at_m = [0.0, 0.0, 0.0]
kind = "triaxial"
[[sensor]]
id = "2"
at_m = [0.3, 0.1, 0.05]
kind = "triaxial"
[[sensor]]
id = "3"
at_m = [-0.1, 0.2, -0.15]
kind = "triaxial"
[[excitation]]
id = "F1"
at_m = [0.3, 0.1, 0.05]
direction = [0.0, 0.6, 0.8]
setup = "A"
[[excitation]]
id = "F2"
at_m = [-0.1, -0.1, 0.1]
direction = [1.0, 0.0, 0.0]
setup = "A"
[damping]
model = "modal"
ratio = 0.02
"#;

fn spec(setup: &str, start_hz: f64, effects: &str) -> CampaignSpec {
    let text = format!(
        "name = \"cords\"\nquantity = \"receptance\"\n[frequency]\nstart_hz = {start_hz:?}\nstop_hz = 20.0\nlines = 81\n{BODY}\n[[setup]]\nid = \"A\"\n{setup}\n{effects}"
    );
    CampaignSpec::from_toml_str(&text).unwrap()
}

/// Four cords from the top corners to anchors 1 m above (or splayed outward by `dx`).
fn cords_toml(dx: f64, l0: f64) -> String {
    let mut s = String::new();
    for (x, y) in [(-0.1, -0.15), (0.35, -0.1), (0.3, 0.25), (-0.05, 0.2)] {
        let sx = if x > 0.1 { dx } else { -dx };
        s += &format!(
            "[[setup.cord]]\nat_m = [{x}, {y}, 0.12]\nanchor_m = [{}, {y}, 1.12]\naxial_stiffness_n_per_m = 900.0\nunstretched_length_m = {l0}\n",
            x + sx
        );
    }
    s
}

/// A free–free body (no suspension): six zero-frequency modes and, undamped, the exact
/// mass line `H = −S M⁻¹ F / ω²` on every line; the 0 Hz line is skipped with a note.
#[test]
fn free_free_body_is_its_mass_line() {
    let s = spec("", 0.0, "").clone();
    let mut s0 = s.clone();
    s0.damping.ratio = Some(0.0);
    let sim = simulate(&s0).unwrap();
    assert_eq!(sim.notes.len(), 1, "{:?}", sim.notes);
    assert!(sim.notes[0].contains("0 Hz"), "{}", sim.notes[0]);
    assert_eq!(sim.frf.frequency_hz.len(), 80);
    assert_eq!(sim.frf.frequency_hz[0], 0.25);
    assert!(sim.truth.setups[0]
        .modes
        .iter()
        .all(|m| m.frequency_hz == 0.0));
    let minv = s0.properties().mass_matrix().0.try_inverse().unwrap();
    let g = &sim.geometry;
    for (e, ex) in g.excitations.iter().enumerate() {
        let f = rigid_transform(&ex.position).transpose() * ex.direction;
        for (c, ch) in g.channels.iter().enumerate() {
            let row = ch.direction.transpose() * rigid_transform(&ch.position);
            let a = (row * minv * f)[0];
            for (l, &hz) in sim.frf.frequency_hz.iter().enumerate() {
                let w = std::f64::consts::TAU * hz;
                let want = c64::new(-a / (w * w), 0.0);
                let got = sim.frf.frf(e, c)[l];
                assert!(
                    (got - want).norm() <= 1e-10 * want.norm().max(1e-12 / (w * w)),
                    "e{e} c{c} {hz} Hz: {got} vs {want}"
                );
            }
        }
    }
}

/// Cords without gravity are axial springs `k e eᵀ`: vertical ones leave x, y and yaw
/// free (three zero modes in the truth), and the FRFs on the lines above 0 Hz agree
/// between the direct solve and the modal sum (zero modes as `−1/ω²` terms).
#[test]
fn vertical_cords_without_gravity_leave_three_directions_free() {
    let s = spec(&cords_toml(0.0, 0.99), 0.0, "");
    let sim = simulate(&s).unwrap();
    let f: Vec<f64> = sim.truth.setups[0]
        .modes
        .iter()
        .map(|m| m.frequency_hz)
        .collect();
    assert_eq!(f.iter().filter(|x| **x == 0.0).count(), 3, "{f:?}");
    assert!(f[3] > 1.0, "{f:?}");
    assert_eq!(sim.notes.len(), 1);
    let modal = simulate_with(
        &s,
        &SimOptions {
            method: SolveMethod::Modal,
        },
    )
    .unwrap();
    let scale = sim.frf.values.iter().map(|v| v.norm()).fold(0.0, f64::max);
    for (a, b) in sim.frf.values.iter().zip(&modal.frf.values) {
        assert!(a.re.is_finite() && a.im.is_finite());
        assert!((a - b).norm() <= 1e-9 * scale, "{a} vs {b}");
    }
    // The nominal stiffness is Σ T(a)ᵀ k e eᵀ T(a) with e vertical.
    let k = s.setup_stiffness(0);
    let mut want = Mat6::zeros();
    for c in &s.setups[0].cords {
        let t = rigid_transform(&Vec3::from(c.at_m));
        want += t.transpose() * Mat3::from_diagonal(&Vec3::new(0.0, 0.0, 900.0)) * t;
    }
    assert!((k - want).norm() <= 1e-12 * want.norm());
}

/// Viscous damping on a free direction (`αM`) is a real pole the modal sum cannot
/// represent: the modal solve is refused, the direct one stays finite.
#[test]
fn damped_free_direction_needs_the_direct_solve() {
    let mut s = spec("", 1.0, "");
    s.damping = rbprops_sim::spec::DampingSpec {
        model: rbprops_sim::spec::DampingModel::Proportional,
        ratio: None,
        ratios: None,
        alpha: Some(0.5),
        beta: None,
    };
    let sim = simulate(&s).unwrap();
    assert!(sim.notes.is_empty());
    // Free–free with C = αM: H = S M⁻¹ F / (−ω² + iωα).
    let g = &sim.geometry;
    let minv = s.properties().mass_matrix().0.try_inverse().unwrap();
    let ex = &g.excitations[0];
    let ch = &g.channels[4];
    let a = (ch.direction.transpose()
        * rigid_transform(&ch.position)
        * minv
        * rigid_transform(&ex.position).transpose()
        * ex.direction)[0];
    for (l, &hz) in sim.frf.frequency_hz.iter().enumerate() {
        let w = std::f64::consts::TAU * hz;
        let want = c64::new(a, 0.0) / c64::new(-w * w, 0.5 * w);
        assert!((sim.frf.frf(0, 4)[l] - want).norm() <= 1e-10 * want.norm());
    }
    let e = simulate_with(
        &s,
        &SimOptions {
            method: SolveMethod::Modal,
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("direct solve"), "{e}");
}

/// Potential of the hanging body written independently of the library: pose
/// `x = R(exp([θ]×) a + u) + t` about `(R, t)`, Rodrigues' formula for the rotation.
fn potential(
    cords: &[AnchoredCord],
    m: f64,
    c: &Vec3,
    g: f64,
    up: &Vec3,
    rot: &Mat3,
    t: &Vec3,
    q: &Vec6,
) -> f64 {
    let th = Vec3::new(q[3], q[4], q[5]);
    let n = th.norm();
    let k = rbprops_core::cross_matrix(&th);
    let e = if n == 0.0 {
        Mat3::identity()
    } else {
        Mat3::identity() + k * (n.sin() / n) + k * k * ((1.0 - n.cos()) / (n * n))
    };
    let u = Vec3::new(q[0], q[1], q[2]);
    let place = |a: &Vec3| rot * (e * a + u) + t;
    let mut v = m * g * up.dot(&place(c));
    for cd in cords {
        let len = (cd.anchor - place(&cd.at)).norm();
        let s = (len - cd.unstretched_length).max(0.0);
        v += 0.5 * cd.axial_stiffness * s * s;
    }
    v
}

fn body() -> (Mat6, f64, Vec3) {
    let s = spec("", 1.0, "");
    let p = s.properties();
    (p.mass_matrix().0, p.mass, p.com)
}

/// Splayed cords (anchors outward of the attachments) with the CoM off centre tilt and
/// move the body at equilibrium. There the potential's gradient vanishes and its
/// Hessian (central differences of the independent potential above, step 1e-4) is the
/// library's stiffness to the differences' truncation error (O(h²) ≈ 1e-8 relative).
#[test]
fn splayed_cords_stiffness_is_the_hessian_at_equilibrium() {
    let (mass, m, c) = body();
    let up = Vec3::z();
    let g = STANDARD_GRAVITY;
    let s = spec(&cords_toml(0.25, 0.97), 1.0, "");
    let cords = s.cords(0);
    let eq = hanging_equilibrium(&mass, &cords, &[], g, &up).unwrap();
    let angle = nalgebra::Rotation3::from_matrix(&eq.rotation).angle();
    assert!(angle > 1e-3, "the body should tilt (angle {angle})");
    assert!(eq.tensions.iter().all(|t| *t > 0.0));
    let v = |q: &Vec6| potential(&cords, m, &c, g, &up, &eq.rotation, &eq.translation, q);
    let h = 1e-4;
    let mut hess = Mat6::zeros();
    let mut grad = Vec6::zeros();
    for i in 0..6 {
        let mut qp = Vec6::zeros();
        qp[i] = h;
        grad[i] = (v(&qp) - v(&-qp)) / (2.0 * h);
        for j in 0..6 {
            let mut a = Vec6::zeros();
            a[i] += h;
            a[j] += h;
            let mut b = Vec6::zeros();
            b[i] += h;
            b[j] -= h;
            let mut cc = Vec6::zeros();
            cc[i] -= h;
            cc[j] += h;
            hess[(i, j)] = (v(&a) - v(&b) - v(&cc) + v(&-a)) / (4.0 * h * h);
        }
    }
    let w = m * g;
    assert!(grad.norm() < 1e-6 * w, "gradient {grad}");
    let d = (hess - eq.stiffness).norm() / eq.stiffness.norm();
    assert!(
        d < 1e-6,
        "relative Hessian difference {d:.3e}\n{hess}\n{}",
        eq.stiffness
    );
    // The gravity effect puts exactly this stiffness into the model (the nominal axial
    // springs replaced).
    let sg = spec(
        &cords_toml(0.25, 0.97),
        1.0,
        "[[effect]]\nid = \"gravity_stiffness\"\n",
    );
    let sim = simulate(&sg).unwrap();
    let k = sim.truth.setups[0].stiffness;
    let k = Mat6::from_fn(|i, j| k[i][j]);
    assert!((k - eq.stiffness).norm() <= 1e-12 * k.norm());
    assert!(sim.truth.setups[0]
        .modes
        .iter()
        .all(|m| m.frequency_hz > 0.1));
}

/// Splayed cords written as their axial springs `k e eᵀ` (as testers write them) with the
/// gravity effect given the cords' anchor distance (`cord_length_m`) and free lengths
/// (`unstretched_length_m`) hang as the same cords given as cords: the body moves and
/// tilts to the same equilibrium, and the model's stiffness is the same to rounding.
#[test]
fn cords_written_as_springs_hang_at_their_free_lengths() {
    let as_cords = spec(
        &cords_toml(0.25, 0.97),
        1.0,
        "[[effect]]\nid = \"gravity_stiffness\"\n",
    );
    let cords = as_cords.cords(0);
    let springs = axial_springs_toml(&cords);
    let lengths: Vec<String> = cords
        .iter()
        .map(|c| format!("{:?}", (c.anchor - c.at).norm()))
        .collect();
    let as_springs = spec(
        &springs,
        1.0,
        &format!(
            "[[effect]]\nid = \"gravity_stiffness\"\ncord_length_m = [{}]\nunstretched_length_m = [0.97]\n",
            lengths.join(", ")
        ),
    );
    let k = |s: &CampaignSpec| {
        let k = simulate(s).unwrap().truth.setups[0].stiffness;
        Mat6::from_fn(|i, j| k[i][j])
    };
    let (k1, k2) = (k(&as_cords), k(&as_springs));
    let d = (k1 - k2).norm() / k1.norm();
    assert!(
        d < 1e-10,
        "relative stiffness difference {d:.3e}\n{k1}\n{k2}"
    );
    // Without the free lengths the springs hang in the drawn pose: another body.
    let drawn = spec(
        &springs,
        1.0,
        &format!(
            "[[effect]]\nid = \"gravity_stiffness\"\ncord_length_m = [{}]\n",
            lengths.join(", ")
        ),
    );
    assert!((k(&drawn) - k1).norm() > 1e-3 * k1.norm());
}

/// `cords` written as their axial springs `k e eᵀ` (`[[setup.spring]]` tables), as
/// testers write cords.
fn axial_springs_toml(cords: &[AnchoredCord]) -> String {
    let mut springs = String::new();
    for c in cords {
        let e = c.direction();
        let k = c.axial_stiffness * e * e.transpose();
        let rows: Vec<String> = (0..3)
            .map(|i| format!("[{:?}, {:?}, {:?}]", k[(i, 0)], k[(i, 1)], k[(i, 2)]))
            .collect();
        springs += &format!(
            "[[setup.spring]]\nat_m = [{:?}, {:?}, {:?}]\nstiffness_matrix_n_per_m = [{}]\n",
            c.at.x,
            c.at.y,
            c.at.z,
            rows.join(", ")
        );
    }
    springs
}

/// The gravity effect's cord lengths are plausible from 5 cm to 10 m where the set-up
/// hangs on cords (given as cords or written as axial springs), and from 5 cm without
/// end on three-axis springs: a point spring to the ground has no pendulum term (ℓ → ∞,
/// the load term alone), which a rigid body on a refgen spring set-up under gravity
/// shows (the `gravity-window-gain` bench recording fits 1/ℓ = 0).
#[test]
fn gravity_lengths_are_bounded_on_cords_and_not_on_three_axis_springs() {
    let entry = |lengths: &str| rbprops_sim::spec::EffectSpec {
        id: "gravity_stiffness".into(),
        parameters: toml::from_str(&format!("cord_length_m = [{lengths}]")).unwrap(),
    };
    let holds = |s: &CampaignSpec, lengths: &str| -> Vec<bool> {
        rbprops_sim::effects::plausibility(&entry(lengths), s)
            .unwrap()
            .iter()
            .map(|q| q.holds())
            .collect()
    };
    let three_axis = spec(
        &(0..4)
            .map(|i| {
                format!(
                    "[[setup.spring]]\nat_m = [{:?}, 0.1, 0.12]\nstiffness_n_per_m = [150.0, 220.0, 2500.0]\n",
                    0.1 * i as f64
                )
            })
            .collect::<String>(),
        1.0,
        "",
    );
    assert_eq!(holds(&three_axis, "1.0, 1500.0"), [true, true]);
    assert_eq!(holds(&three_axis, "0.01"), [false]);
    let cords = spec(&cords_toml(0.25, 0.97), 1.0, "").cords(0);
    let axial = spec(&axial_springs_toml(&cords), 1.0, "");
    assert_eq!(holds(&axial, "1.0, 1500.0"), [true, false]);
    let as_cords = spec(&cords_toml(0.25, 0.97), 1.0, "");
    assert_eq!(holds(&as_cords, "1.0, 1500.0"), [true, false]);
}

/// Vertical cords whose reference pose is their equilibrium (L₀ = ℓ − T/k with the
/// vertical-cord tensions) reproduce the springs-as-cords model: axial springs plus
/// [`geometric_stiffness`] at the hanging length ℓ, and the body does not move.
#[test]
fn vertical_cords_reproduce_the_spring_model() {
    let (mass, m, c) = body();
    let up = Vec3::z();
    let g = STANDARD_GRAVITY;
    let ats = [
        Vec3::new(-0.1, -0.15, 0.12),
        Vec3::new(0.35, -0.1, 0.12),
        Vec3::new(0.3, 0.25, 0.12),
        Vec3::new(-0.05, 0.2, 0.12),
    ];
    let (ell, k) = (1.0, 900.0);
    let vc: Vec<Cord> = ats
        .iter()
        .map(|a| Cord {
            at: *a,
            length: ell,
            axial_stiffness: k,
        })
        .collect();
    let t = cord_tensions(&vc, m, &c, g, &up).unwrap();
    let cords: Vec<AnchoredCord> = ats
        .iter()
        .zip(&t)
        .map(|(a, ti)| AnchoredCord {
            at: *a,
            anchor: a + ell * up,
            axial_stiffness: k,
            unstretched_length: ell - ti / k,
        })
        .collect();
    let eq = hanging_equilibrium(&mass, &cords, &[], g, &up).unwrap();
    assert!(eq.translation.norm() < 1e-12, "{}", eq.translation);
    assert!((eq.rotation - Mat3::identity()).norm() < 1e-12);
    for (a, b) in eq.tensions.iter().zip(&t) {
        assert!((a - b).abs() < 1e-9 * b, "{a} vs {b}");
    }
    let springs: Vec<Spring> = cords.iter().map(|c| c.axial_spring()).collect();
    let (kgeo, _) = geometric_stiffness(&mass, &vc, g, &up).unwrap();
    let want = mount_stiffness(&springs) + kgeo;
    let d = (eq.stiffness - want).norm() / want.norm();
    assert!(d < 1e-12, "{d:.3e}");
}

/// Bad cords are named with their TOML path; gravity lengths that do not match the cords
/// are refused naming the set-up. A cord longer than its anchor distance is not an
/// error: the body drops until the cords are taut (the equilibrium is found from there).
#[test]
fn bad_cords_are_named() {
    let text = |c: &str| {
        format!(
            "name = \"x\"\nquantity = \"receptance\"\n[frequency]\nstart_hz = 1.0\nstop_hz = 20.0\nlines = 11\n{BODY}\n[[setup]]\nid = \"A\"\n{c}"
        )
    };
    let e = CampaignSpec::from_toml_str(&text(
        "[[setup.cord]]\nat_m = [0.0, 0.0, 0.1]\nanchor_m = [0.0, 0.0, 0.1]\naxial_stiffness_n_per_m = -1.0\nunstretched_length_m = 0.0\n",
    ))
    .unwrap_err()
    .to_string();
    for w in [
        "setup[0].cord[0].axial_stiffness_n_per_m",
        "setup[0].cord[0].unstretched_length_m",
        "setup[0].cord[0].anchor_m",
    ] {
        assert!(e.contains(w), "{w} in {e}");
    }
    let e = CampaignSpec::from_toml_str(&text(&format!(
        "{}[[effect]]\nid = \"gravity_stiffness\"\nunstretched_length_m = [1.0, 1.0]\n",
        cords_toml(0.0, 0.97)
    )))
    .unwrap_err()
    .to_string();
    assert!(e.contains("set-up 'A'") && e.contains("4 cords"), "{e}");
    let long = spec(
        &cords_toml(0.0, 5.0),
        1.0,
        "[[effect]]\nid = \"gravity_stiffness\"\n",
    );
    let sim = simulate(&long).unwrap();
    // Hanging 4 m lower on 5 m cords: pendulum modes near √(g/5.0x m)/2π ≈ 0.22 Hz.
    let f1 = sim.truth.setups[0].modes[0].frequency_hz;
    assert!((0.2..0.24).contains(&f1), "{f1}");
    // Round trip through TOML keeps the cords.
    let s = spec(&cords_toml(0.1, 0.97), 1.0, "");
    let back = CampaignSpec::from_toml_str(&s.to_toml_string()).unwrap();
    assert_eq!(back, s);
}
