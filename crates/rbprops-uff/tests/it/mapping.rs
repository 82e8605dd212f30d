//! Mapping rules on hand-edited files: unit systems and labels, coordinate systems.

use crate::common::{campaign, even_axis, Spec};
use rbprops_core::{FrfSet, Geometry, Quantity, Vec3};
use rbprops_uff::{from_campaign, parse, to_campaign, UffError, WriteOptions};

fn base() -> (Geometry, FrfSet, String) {
    let spec = Spec {
        point_ids: vec!["1".into(), "2".into(), "3".into(), "4".into()],
        misoriented: false,
        quantity: Quantity::Accelerance,
        frequency_hz: even_axis(6, 0.5),
        seed: 7,
    };
    let (g, frf) = campaign(&spec);
    let s = String::from_utf8(from_campaign(&g, &frf, &WriteOptions::default()).unwrap()).unwrap();
    (g, frf, s)
}

fn read(s: &str) -> Result<(Geometry, FrfSet), UffError> {
    to_campaign(&parse(s.as_bytes(), "edit.uff")?)
}

fn scaled(a: &FrfSet, b: &FrfSet, factor: f64) -> bool {
    a.values
        .iter()
        .zip(&b.values)
        .all(|(x, y)| (x - y * factor).norm() <= 1e-12 * (y * factor).norm())
}

#[test]
fn numerator_label_with_whole_frf_dimension_converts_alone() {
    let (_, frf, s) = base();
    let edited = s.replace("m/s^2               ", "g/N                 ");
    let (_, f2) = read(&edited).unwrap();
    assert_eq!(f2.quantity, Quantity::Accelerance);
    assert!(scaled(&f2, &frf, 9.80665));
    // Same with the labels in mm/s^2 over mN: (1e-3 m/s²)/(1e-3 N) = 1.
    let edited = s
        .replace("m/s^2               ", "mm/s^2              ")
        .replace("Force                N    ", "Force                mN   ");
    let (_, f3) = read(&edited).unwrap();
    assert!(scaled(&f3, &frf, 1.0));
}

#[test]
fn abscissa_in_rad_per_second() {
    let (_, frf, s) = base();
    let edited = s.replace("Frequency            Hz   ", "Frequency            rad/s");
    let (_, f2) = read(&edited).unwrap();
    for (a, b) in f2.frequency_hz.iter().zip(&frf.frequency_hz) {
        assert!((a - b / (2.0 * std::f64::consts::PI)).abs() <= 1e-15 * b);
    }
}

#[test]
fn unit_system_164_converts_lengths_and_forces_when_labels_are_unset() {
    let (g, frf, s) = base();
    // Code 8 (GM): millimetre and kilogram-force; labels removed so 164 applies.
    let code8 = format!(
        "{:>10}{:<20}{:>10}\n{:>25}{:>25}{:>25}",
        8, "GM: mm (kgf)", 2, "1.0000000000000000E+03", "1.0197162129779283E-01", "1.0"
    );
    let mut lines: Vec<&str> = s.lines().collect();
    let i = lines
        .iter()
        .position(|l| l.starts_with("         1SI"))
        .unwrap();
    lines.splice(i..i + 2, code8.lines());
    let edited = (lines.join("\n") + "\n")
        .replace("m/s^2               ", "NONE                ")
        .replace("Force                N    ", "Force                NONE ");
    let (g2, f2) = read(&edited).unwrap();
    // FRF (mm/s²)/kgf → SI: × 1e-3 / 9.80665.
    assert!(scaled(&f2, &frf, 1e-3 / 9.80665));
    for (a, b) in g2.points.iter().zip(&g.points) {
        assert!((a.position - b.position * 1e-3).norm() <= 1e-15 * b.position.norm());
    }
    // A 164 whose factors contradict its code is refused.
    let wrong = edited.replace("1.0000000000000000E+03", "1.0000000000000000E+00");
    let e = read(&wrong).unwrap_err().to_string();
    assert!(e.contains("units code 8") && e.contains("type 164"), "{e}");
}

/// Replaces the node block with one dataset 18 system and 2411 nodes using it.
fn with_systems(s: &str, systems: &str, node_cs: i64) -> String {
    let start = s.find("    -1\n  2411\n").unwrap();
    let end = start + s[start + 7..].find("    -1\n").unwrap() + 14;
    let mut nodes = s[start..end].to_string();
    // Node 2 (second record) uses system `node_cs` for its directions.
    nodes = nodes.replacen(
        "         2         0         0         8",
        &format!("         2         0{node_cs:>10}         8"),
        1,
    );
    format!("{}{systems}{nodes}{}", &s[..start], &s[end..])
}

#[test]
fn dataset_18_systems_chain_through_their_reference() {
    let (g, _, s) = base();
    // System 1: rotated 90° about Z (x' = Y, z' = Z), origin (1, 0, 0).
    // System 2: defined in system 1 with x'' = -z', z'' = x' → in global x'' = -Z, z'' = Y.
    let systems = "    -1\n    18\n\
         \x20        1         0         0         1         1\nS1\n\
         \x20 1.00000E+00  0.00000E+00  0.00000E+00  1.00000E+00  1.00000E+00  0.00000E+00\n\
         \x20 1.00000E+00  0.00000E+00  1.00000E+00\n\
         \x20        2         0         1         1         1\nS2\n\
         \x20 0.00000E+00  0.00000E+00  0.00000E+00  0.00000E+00  0.00000E+00 -1.00000E+00\n\
         \x20 1.00000E+00  0.00000E+00  0.00000E+00\n    -1\n";
    let (g2, _) = read(&with_systems(&s, systems, 2)).unwrap();
    let dirs: Vec<Vec3> = g2
        .channels
        .iter()
        .filter(|c| c.point == "2")
        .map(|c| c.direction)
        .collect();
    // Codes +1, -2, +3 (the writer's x, -y, z) in system 2: x'' = -Z, z'' = Y, y'' = z''×x'' = -X.
    let x2 = -Vec3::z();
    let z2 = Vec3::y();
    let y2 = z2.cross(&x2);
    for (got, want) in dirs.iter().zip([x2, -y2, z2]) {
        assert!((got - want).norm() < 1e-15, "{got:?} vs {want:?}");
    }
    // Positions are untouched (2411 coordinates are global).
    assert_eq!(g2.points, g.points);
}

#[test]
fn unsupported_or_broken_systems_are_named() {
    let (_, _, s) = base();
    let cyl = "    -1\n  2420\n         1\npart\n         5         1         8\ncyl\n\
         \x20  1.0000000000000000E+00   0.0000000000000000E+00   0.0000000000000000E+00\n\
         \x20  0.0000000000000000E+00   1.0000000000000000E+00   0.0000000000000000E+00\n\
         \x20  0.0000000000000000E+00   0.0000000000000000E+00   1.0000000000000000E+00\n\
         \x20  0.0000000000000000E+00   0.0000000000000000E+00   0.0000000000000000E+00\n    -1\n";
    let e = read(&with_systems(&s, cyl, 5)).unwrap_err().to_string();
    assert!(e.contains("Cylindrical") && e.contains("node 2"), "{e}");
    let skew = cyl
        .replace(
            "         5         1         8",
            "         5         0         8",
        )
        .replacen(
            "   0.0000000000000000E+00   1.0000000000000000E+00",
            "   0.5000000000000000E+00   1.0000000000000000E+00",
            1,
        );
    let e = read(&with_systems(&s, &skew, 5)).unwrap_err().to_string();
    assert!(
        e.contains("not orthonormal") && e.contains("type 2420"),
        "{e}"
    );
    let e = read(&with_systems(&s, "", 9)).unwrap_err().to_string();
    assert!(e.contains("coordinate system 9 is not defined"), "{e}");
}
