//! Human-readable tables for the terminal.

use rbprops_core::records::InertiaEstimate;
use std::fmt::Write;

fn pm(v: f64, s: f64, scale: f64, prec: usize) -> String {
    if s > 0.0 {
        format!("{:.*} ± {:.*}", prec, v * scale, prec, 1.96 * s * scale)
    } else {
        format!("{:.*}", prec, v * scale)
    }
}

/// One block per estimate: mass, CoM (mm), tensor at the CoM, products, principal
/// moments, errors against the reference, warnings. `±` is the 95 % half-width.
pub fn estimates(list: &[InertiaEstimate]) -> String {
    let mut s = String::new();
    for e in list {
        let _ = writeln!(
            s,
            "── {} (set-up {}, origin [{:.4}, {:.4}, {:.4}] m, uncertainty: {}) ──",
            e.method, e.setup, e.origin_m[0], e.origin_m[1], e.origin_m[2], e.uncertainty_method
        );
        let _ = writeln!(
            s,
            "  mass            {} kg",
            pm(e.mass_kg, e.mass_std_kg, 1.0, 5)
        );
        let c: Vec<String> = (0..3)
            .map(|i| pm(e.com_m[i], e.com_std_m[i], 1e3, 3))
            .collect();
        let _ = writeln!(s, "  CoM [mm]        x {}   y {}   z {}", c[0], c[1], c[2]);
        let _ = writeln!(
            s,
            "  J at CoM [kg m²] (tensor; off-diagonals are minus the products)"
        );
        for r in 0..3 {
            let row: Vec<String> = (0..3)
                .map(|k| {
                    format!(
                        "{:>24}",
                        pm(
                            e.inertia_cm_kg_m2[r][k],
                            e.inertia_cm_std_kg_m2[r][k],
                            1.0,
                            6
                        )
                    )
                })
                .collect();
            let _ = writeln!(s, "    {}", row.join(" "));
        }
        let p = &e.products_of_inertia_kg_m2;
        let _ = writeln!(
            s,
            "  products        Jxy {:.6}  Jxz {:.6}  Jyz {:.6} kg m²",
            p.xy, p.xz, p.yz
        );
        let pmo = e.principal_moments_kg_m2;
        let _ = writeln!(
            s,
            "  principal       {:.6}  {:.6}  {:.6} kg m²",
            pmo[0], pmo[1], pmo[2]
        );
        if let Some(err) = &e.errors {
            let _ = writeln!(
                s,
                "  rel. errors     m {:.3e}  c {:.3e}  J {:.3e}  sum {:.3e}",
                err.mass, err.com, err.inertia, err.sum
            );
        }
        let _ = writeln!(
            s,
            "  modes {:?} from {:?}; residual {:.3e}; physically consistent: {}",
            e.modes_used, e.excitations_used, e.residual, e.physically_consistent
        );
        if let Some(c) = &e.rigid_body_check {
            let _ = writeln!(
                s,
                "  rigid-body consistent: {} (χ²/dof {:.3e}, threshold {:.3} for noise alone, {} dof)",
                c.rigid_body_consistent, c.statistic, c.threshold, c.dof
            );
        }
        if let Some(y) = &e.systematic {
            let iv = |v: [f64; 2], scale: f64, prec: usize| {
                format!("[{:.*}, {:.*}]", prec, v[0] * scale, prec, v[1] * scale)
            };
            let _ = writeln!(s, "  95 % with systematic ({}):", y.method);
            let _ = writeln!(
                s,
                "    mass {} kg   CoM [mm] x {} y {} z {}",
                iv(y.mass_95_kg, 1.0, 5),
                iv(y.com_95_m[0], 1e3, 3),
                iv(y.com_95_m[1], 1e3, 3),
                iv(y.com_95_m[2], 1e3, 3)
            );
            let _ = writeln!(
                s,
                "    Jxx {}  Jyy {}  Jzz {} kg m²",
                iv(y.inertia_cm_95_kg_m2[0][0], 1.0, 6),
                iv(y.inertia_cm_95_kg_m2[1][1], 1.0, 6),
                iv(y.inertia_cm_95_kg_m2[2][2], 1.0, 6)
            );
        }
        for d in e
            .diagnostics
            .iter()
            .filter(|d| crate::warnings::shown_by_default(d))
        {
            let _ = writeln!(
                s,
                "  {}: {}",
                crate::warnings::severity_label(d.severity),
                d.line()
            );
        }
    }
    s
}
