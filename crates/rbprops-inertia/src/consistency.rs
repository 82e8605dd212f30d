//! The nearest physically consistent inertia tensor.
//!
//! A physical `J` has principal moments obeying the triangle inequalities
//! `λ_i + λ_j ≥ λ_k` (which imply `λ_i ≥ 0`). This set of eigenvalue triples is a convex
//! cone invariant under permutations, so the Frobenius-nearest consistent tensor keeps the
//! principal axes and projects the moments onto the cone (Lewis 1996, spectral sets).
//! The projection onto a cone given by three half-spaces is found by enumerating the active
//! sets (at most 8): the projection is the projection onto the subspace of its own active
//! set, and no feasible candidate is nearer, so the nearest feasible candidate is it.

use nalgebra::{Matrix3, Vector3};
use rbprops_core::{Mat3, RigidBodyProperties, Vec3};

/// Outward constraint normals `a_k·λ ≥ 0`.
fn normals() -> [Vector3<f64>; 3] {
    [
        Vector3::new(-1.0, 1.0, 1.0),
        Vector3::new(1.0, -1.0, 1.0),
        Vector3::new(1.0, 1.0, -1.0),
    ]
}

/// Euclidean projection of a triple of moments onto the triangle-inequality cone.
pub fn project_moments(l: &Vec3) -> Vec3 {
    let a = normals();
    let feasible = |x: &Vec3| {
        a.iter()
            .all(|ak| ak.dot(x) >= -1e-14 * x.norm().max(1e-300))
    };
    if feasible(l) {
        return *l;
    }
    let mut best: Option<(f64, Vec3)> = None;
    for mask in 1u8..8 {
        let act: Vec<&Vector3<f64>> = (0..3)
            .filter(|k| mask >> k & 1 == 1)
            .map(|k| &a[k])
            .collect();
        // Project onto {x : a_kᵀx = 0, k active}: x = l − A(AᵀA)⁻¹Aᵀl.
        let n = act.len();
        let mut g = nalgebra::DMatrix::zeros(n, n);
        let mut r = nalgebra::DVector::zeros(n);
        for i in 0..n {
            r[i] = act[i].dot(l);
            for j in 0..n {
                g[(i, j)] = act[i].dot(act[j]);
            }
        }
        let Some(mu) = g.lu().solve(&r) else { continue };
        let mut x = *l;
        for i in 0..n {
            x -= act[i] * mu[i];
        }
        if !feasible(&x) {
            continue;
        }
        let d = (x - l).norm();
        if best.as_ref().is_none_or(|(bd, _)| d < *bd) {
            best = Some((d, x));
        }
    }
    best.map(|(_, x)| x).unwrap_or_else(Vec3::zeros)
}

/// The nearest (Frobenius) consistent inertia tensor: same principal axes, moments
/// projected onto the triangle-inequality cone. Mass and CoM are kept.
pub fn nearest_consistent(p: &RigidBodyProperties) -> RigidBodyProperties {
    let (moments, axes) = p.principal();
    let proj = project_moments(&moments);
    let j: Mat3 = axes * Matrix3::from_diagonal(&proj) * axes.transpose();
    RigidBodyProperties {
        inertia_cm: (j + j.transpose()) / 2.0,
        ..*p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn consistent_moments_are_unchanged_and_others_land_on_the_boundary() {
        let ok = Vec3::new(1.0, 2.0, 2.5);
        assert_eq!(project_moments(&ok), ok);
        // (1, 1, 3) violates λ1 + λ2 ≥ λ3 by 1: it moves by 1/3 along (1, 1, −1).
        let x = project_moments(&Vec3::new(1.0, 1.0, 3.0));
        assert!(
            (x - Vec3::new(4.0 / 3.0, 4.0 / 3.0, 8.0 / 3.0)).norm() < 1e-14,
            "{x}"
        );
        // A negative moment: (−1, 2, 2) projects to (0, 2, 2) (λ1 ≥ 0 via λ2 + λ3 ≥ … edge).
        let y = project_moments(&Vec3::new(-1.0, 2.0, 2.0));
        assert!(normals().iter().all(|a| a.dot(&y) >= -1e-14));
        assert!((y - Vec3::new(-1.0, 2.0, 2.0)).norm() <= 1.0 + 1e-14);
        // Brute-force check of optimality on a grid of feasible points.
        for l in [
            Vec3::new(-1.0, 2.0, 2.0),
            Vec3::new(0.2, 0.3, 1.4),
            Vec3::new(-0.5, -0.2, 0.1),
        ] {
            let p = project_moments(&l);
            let d = (p - l).norm();
            for i in 0..30 {
                for j in 0..30 {
                    for k in 0..30 {
                        let q = Vec3::new(i as f64, j as f64, k as f64) * 0.1;
                        if normals().iter().all(|a| a.dot(&q) >= 0.0) {
                            assert!((q - l).norm() >= d - 1e-12, "{l} {p} {q}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn nearest_consistent_tensor_passes_the_core_checks() {
        let axes = nalgebra::Rotation3::from_euler_angles(0.3, -0.5, 0.9).into_inner();
        let j = axes * Mat3::from_diagonal(&Vec3::new(0.1, 0.2, 0.5)) * axes.transpose();
        let bad = RigidBodyProperties {
            mass: 2.0,
            com: Vec3::new(0.1, 0.0, 0.0),
            inertia_cm: j,
        };
        assert!(!bad.consistency_violations().is_empty());
        let fixed = nearest_consistent(&bad);
        assert!(
            fixed.consistency_violations().is_empty(),
            "{:?}",
            fixed.consistency_violations()
        );
        assert_eq!(fixed.mass, bad.mass);
    }
}
