//! Test fixtures: a rigid body on springs with exact modes, residues and FRFs.
#![allow(dead_code)]

use rbprops_core::inertia::ProductsOfInertia;
use rbprops_core::records::{ModalFitRecord, ModeEstimate, SelectedMode, SelectionRecord};
use rbprops_core::{
    c64, modal::modal_receptance, Excitation, FrfSet, Geometry, Mat6, Quantity,
    RigidBodyProperties, RigidMode, SuspensionSetup, Vec3, Vec6,
};

/// Test Case II inertia with an off-origin CoM.
pub fn body() -> RigidBodyProperties {
    RigidBodyProperties::from_moments_and_products(
        15.69,
        Vec3::new(0.12, -0.05, 0.08),
        [0.35733194, 0.39469014, 0.31706832],
        ProductsOfInertia {
            xy: 0.07722671,
            xz: -0.08736156,
            yz: -0.06919817,
        },
    )
}

fn unit(x: f64, y: f64, z: f64) -> Vec3 {
    Vec3::new(x, y, z).normalize()
}

pub use rbprops_testkit::triaxial;

/// Three triaxial accelerometers on a near-equilateral triangle and five forces.
pub fn geometry() -> Geometry {
    geometry_with_points(&[
        ("A1", Vec3::new(0.30, 0.00, 0.05)),
        ("A2", Vec3::new(-0.15, 0.26, -0.02)),
        ("A3", Vec3::new(-0.15, -0.26, 0.10)),
    ])
}

pub fn geometry_with_points(pts: &[(&str, Vec3)]) -> Geometry {
    let mut g = Geometry::default();
    for (id, p) in pts {
        let (pt, ch) = triaxial(id, *p);
        g.points.push(pt);
        g.channels.extend(ch);
    }
    g.setups.push(SuspensionSetup {
        id: "A".into(),
        description: "springs".into(),
    });
    let forces = [
        ("F1", Vec3::new(0.30, 0.10, 0.05), unit(1.0, 0.3, 0.2)),
        ("F2", Vec3::new(-0.10, 0.25, 0.10), unit(0.2, 1.0, -0.3)),
        ("F3", Vec3::new(0.00, -0.20, 0.15), unit(0.1, 0.2, 1.0)),
        ("F4", Vec3::new(0.20, -0.25, -0.05), unit(-0.6, 0.7, 0.4)),
        ("F5", Vec3::new(-0.25, 0.05, 0.20), unit(0.5, -0.3, 0.8)),
    ];
    for (id, p, d) in forces {
        g.excitations.push(Excitation {
            id: id.into(),
            point: id.into(),
            position: p,
            direction: d,
            setup: "A".into(),
        });
    }
    g
}

/// Suspension: springs at four corners with (kx, ky, kz) each.
pub fn stiffness() -> Mat6 {
    rbprops_testkit::spring_stiffness([
        (Vec3::new(0.4, 0.3, 0.2), [800.0, 1500.0, 3000.0]),
        (Vec3::new(-0.4, 0.3, 0.25), [900.0, 1300.0, 2500.0]),
        (Vec3::new(-0.35, -0.3, 0.2), [1000.0, 1700.0, 2800.0]),
        (Vec3::new(0.45, -0.3, 0.15), [700.0, 1100.0, 3300.0]),
    ])
}

/// The body's modes on [`stiffness`], 2 % damping each.
pub fn modes(props: &RigidBodyProperties) -> Vec<RigidMode> {
    rbprops_testkit::rigid_modes(props, &stiffness(), |_| 0.02)
}

/// Exact modal record: every excitation has all six modes with residues `(Sφ)(fᵀφ)`;
/// `residue_std[i] = rel_std · max_i |A_i|` per mode.
pub fn modal_record(g: &Geometry, modes: &[RigidMode], rel_std: f64) -> ModalFitRecord {
    let mut rec = ModalFitRecord {
        residue_convention: "receptance modal constants".into(),
        ..Default::default()
    };
    for e in &g.excitations {
        let f = e.column();
        for (r, m) in modes.iter().enumerate() {
            let res: Vec<c64> = g
                .channels
                .iter()
                .map(|c| c64::new(m.modal_constant(&c.row(), &f), 0.0))
                .collect();
            let amax = res.iter().map(|z| z.norm()).fold(0.0, f64::max);
            rec.modes.push(ModeEstimate {
                excitation: e.id.clone(),
                setup: e.setup.clone(),
                mode: r + 1,
                frequency_hz: m.frequency_hz,
                frequency_std_hz: 0.0,
                damping_ratio: m.damping_ratio,
                damping_std: 0.0,
                residue_std: vec![rel_std * amax; res.len()],
                residues: res,
                confidence: 1.0,
                mpc: 1.0,
                weak: false,
                warnings: vec![],
            });
        }
    }
    rec
}

/// Per mode, the excitation with the largest (fᵀφ)² relative to |f|²; only `which` modes.
pub fn selection(g: &Geometry, modes: &[RigidMode], which: &[usize]) -> SelectionRecord {
    let mut sel = SelectionRecord::default();
    for &r in which {
        let m = &modes[r];
        let (best, s) = g
            .excitations
            .iter()
            .map(|e| (e, e.column().dot(&m.shape).powi(2)))
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap();
        sel.selected.push(SelectedMode {
            setup: best.setup.clone(),
            mode: r + 1,
            frequency_hz: m.frequency_hz,
            excitation: best.id.clone(),
            excitation_mode: r + 1,
            ni_db: 0.0,
            margin_db: 0.0,
            runner_up: None,
            strength: s,
            criterion: rbprops_core::records::SelectionCriterion::Manual,
        });
    }
    sel
}

/// Accelerance FRFs: rigid modal sum plus one elastic mode (non-rigid shape) at `fe_hz`.
pub fn frfs(g: &Geometry, modes: &[RigidMode], fe_hz: f64, f_top: f64, n: usize) -> FrfSet {
    let hz: Vec<f64> = (1..=n).map(|i| f_top * i as f64 / n as f64).collect();
    let mut set = FrfSet::zeros(
        Quantity::Accelerance,
        hz.clone(),
        g.excitations.len(),
        g.channels.len(),
    );
    // Elastic shape: a smooth non-rigid field over the points (bending-like), 1/kg scale.
    let psi = |p: &Vec3, d: &Vec3| -> f64 {
        let u = Vec3::new(0.0, 0.0, 0.3 * (p.x * p.x - 0.05) / 0.05);
        let v = Vec3::new(0.15 * p.y * p.z / 0.02, 0.0, 0.0);
        (u + v).dot(d)
    };
    let we = 2.0 * std::f64::consts::PI * fe_hz;
    for (k, e) in g.excitations.iter().enumerate() {
        let f = e.column();
        for (i, c) in g.channels.iter().enumerate() {
            let row = c.row();
            let ae = psi(&c.position, &c.direction) * psi(&e.position, &e.direction);
            let out = set.frf_mut(k, i);
            for (l, &fh) in hz.iter().enumerate() {
                let w = 2.0 * std::f64::consts::PI * fh;
                let h = modal_receptance(modes, &row, &f, w)
                    + c64::new(ae, 0.0) / c64::new(we * we - w * w, 2.0 * 0.01 * we * w);
                out[l] = h * (-w * w);
            }
        }
    }
    set
}

pub fn phi_matrix(modes: &[RigidMode]) -> Vec<Vec6> {
    modes.iter().map(|m| m.shape).collect()
}
