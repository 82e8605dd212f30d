//! Design aid for the built-in campaigns (not part of the library): prints each
//! campaign's rigid modes and how strongly each excitation drives each mode, and the
//! numbers of the `close-modes` and `missing-mode` fixtures.
//! Run: `cargo run -p rbprops-sim --example design_fixtures`.

use rbprops_sim::{build_models, example, example_names, CampaignSpec};

fn main() {
    if std::env::args().any(|a| a == "missing-mode") {
        missing_mode_design();
        return;
    }
    if std::env::args().any(|a| a == "close-modes") {
        close_modes_design();
        return;
    }
    for name in example_names() {
        let Some(text) = example(name) else { continue };
        let spec = match CampaignSpec::from_toml_str(text) {
            Ok(s) => s,
            Err(e) => {
                println!("{name}: {e}");
                continue;
            }
        };
        let g = spec.geometry().unwrap();
        let models = build_models(&spec, &g, &[]).unwrap();
        println!("== {name}");
        for sm in &models {
            print!("set-up {}: f =", sm.model.setup);
            for m in &sm.modes {
                print!(" {:.4} ({:.4})", m.frequency_hz, m.damping_ratio);
            }
            println!();
            for inp in &sm.model.inputs {
                let e = &g.excitations[inp.excitation];
                // Peak receptance norm over channels ∝ |fᵀφ| ‖Sφ‖ / (2ζω²).
                let s: Vec<f64> = sm
                    .modes
                    .iter()
                    .map(|m| {
                        let sphi: f64 = g
                            .channels
                            .iter()
                            .map(|c| (c.row() * m.shape)[0].powi(2))
                            .sum::<f64>()
                            .sqrt();
                        (inp.column.dot(&m.shape)).abs() * sphi
                            / (2.0 * m.damping_ratio * m.omega().powi(2))
                    })
                    .collect();
                let mx = s.iter().cloned().fold(0.0, f64::max);
                print!("  {:>8}:", e.id);
                for v in &s {
                    print!(" {:6.1} dB", 20.0 * (v / mx).log10());
                }
                println!();
            }
        }
    }
}

/// `close-modes`: a decoupled design in the body's principal frame (CoM at the origin,
/// four springs at (±a, ±b, 0) with diagonal stiffness), where each mode is a pure
/// translation or rotation with `ω² = K_ii / M_ii`:
/// x: 4kx/m, y: 4ky/m, z: 4kz/m, θx: 4kz b²/Jxx, θy: 4kz a²/Jyy, θz: 4(kx b² + ky a²)/Jzz.
/// Solving for kx, ky, kz, Jxx, Jyy, Jzz hits the target frequencies exactly; the whole
/// assembly is then rotated by R and moved to the CoM c, which leaves the frequencies
/// unchanged but couples every mode in the geometry frame.
#[allow(dead_code)]
pub fn close_modes_design() {
    use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
    let w = |f: f64| (std::f64::consts::TAU * f).powi(2);
    let (m, a, b) = (12.0, 0.25, 0.18);
    let (fx, fy, fz, frx, fry, frz) = (0.800, 0.812, 1.10, 1.550, 1.575, 1.30);
    let kx = m * w(fx) / 4.0;
    let ky = m * w(fy) / 4.0;
    let kz = m * w(fz) / 4.0;
    let jxx = 4.0 * kz * b * b / w(frx);
    let jyy = 4.0 * kz * a * a / w(fry);
    let jzz = 4.0 * (kx * b * b + ky * a * a) / w(frz);
    let r = Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(1.0, 2.0, 2.0)), 0.6);
    let r = r.matrix();
    let c = Vector3::new(0.30, 0.22, 0.15);
    let j = r * Matrix3::from_diagonal(&Vector3::new(jxx, jyy, jzz)) * r.transpose();
    let k = r * Matrix3::from_diagonal(&Vector3::new(kx, ky, kz)) * r.transpose();
    let row = |v: Vector3<f64>| format!("[{}, {}, {}]", v.x, v.y, v.z);
    let mat = |mm: Matrix3<f64>| {
        format!(
            "[{}, {}, {}]",
            row(mm.row(0).transpose()),
            row(mm.row(1).transpose()),
            row(mm.row(2).transpose())
        )
    };
    println!("# close-modes: kx {kx} ky {ky} kz {kz}; J {jxx} {jyy} {jzz}");
    println!("com_m = {}", row(c));
    println!("inertia_cm_kg_m2 = {}", mat(j));
    for (sx, sy) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
        println!(
            "[[setup.spring]]\nat_m = {}",
            row(c + r * Vector3::new(sx * a, sy * b, 0.0))
        );
        println!("stiffness_matrix_n_per_m = {}", mat(k));
    }
    for (id, p) in [
        ("1", Vector3::new(0.25, -0.15, 0.12)),
        ("2", Vector3::new(-0.22, -0.12, 0.12)),
        ("3", Vector3::new(0.0, 0.17, 0.12)),
    ] {
        println!(
            "[[sensor]]\nid = \"{id}\"\nat_m = {}\nkind = \"triaxial\"",
            row(c + r * p)
        );
    }
    for (id, p, d) in [
        (
            "E1",
            Vector3::new(0.27, 0.1, -0.12),
            Vector3::new(1.0, 0.0, 0.0),
        ),
        (
            "E2",
            Vector3::new(-0.27, -0.15, 0.05),
            Vector3::new(0.0, 1.0, 0.0),
        ),
        (
            "E3",
            Vector3::new(0.2, 0.18, 0.12),
            Vector3::new(0.0, 0.0, -1.0),
        ),
        (
            "E4",
            Vector3::new(-0.1, 0.18, -0.08),
            Vector3::new(0.6, -0.8, 0.0),
        ),
        (
            "E5",
            Vector3::new(0.27, -0.18, 0.0),
            Vector3::new(0.0, 0.6, 0.8),
        ),
    ] {
        println!(
            "[[excitation]]\nid = \"{id}\"\nat_m = {}\ndirection = {}\nsetup = \"A\"",
            row(c + r * p),
            row(r * d)
        );
    }
}

/// `missing-mode`: a force at point p along d gives mode r the modal force
/// `fᵀφ_r = dᵀ T(p) φ_r = d · u_r(p)`, the work of the force on the point's motion in that
/// mode. A direction perpendicular to `u_r(p)` therefore leaves mode r unexcited. Prints
/// such a direction (the component of a chosen w perpendicular to u_r(p)).
#[allow(dead_code)]
pub fn missing_mode_design() {
    use rbprops_core::{rigid_transform, Vec3};
    let spec = CampaignSpec::from_toml_str(example("test-case-2").unwrap()).unwrap();
    let g = spec.geometry().unwrap();
    let models = build_models(&spec, &g, &[]).unwrap();
    let r = 2; // mode 3
    let p = Vec3::new(0.25, -0.10, 0.17);
    let u = rigid_transform(&p) * models[0].modes[r].shape;
    let uh = u.normalize();
    let w = Vec3::new(0.3, 0.5, -0.8);
    let d = (w - w.dot(&uh) * uh).normalize();
    println!(
        "mode {} at {:.6} Hz: u(p) direction {:?}",
        r + 1,
        models[0].modes[r].frequency_hz,
        uh
    );
    println!(
        "at_m = [{}, {}, {}]\ndirection = [{}, {}, {}]",
        p.x, p.y, p.z, d.x, d.y, d.z
    );
}
