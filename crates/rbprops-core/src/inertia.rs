//! Rigid-body inertia: properties at the CoM and the 6×6 mass matrix about any origin.

use crate::geometry::{cross_matrix, rigid_transform};
use crate::{CoreError, Mat3, Mat6, Vec3, Vec6};

/// The ten inertia properties: mass `m`, centre of mass `c` (in the geometry's frame),
/// and the inertia tensor `J` about the CoM (symmetric; off-diagonals are minus the
/// products of inertia, paper Eq. 6 sign).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidBodyProperties {
    /// Mass `m` (kg).
    pub mass: f64,
    /// Centre of mass `c` in the geometry's frame (m).
    pub com: Vec3,
    /// Inertia tensor `J` about the centre of mass (kg m²), off-diagonals `−J_xy`, `−J_xz`, `−J_yz`.
    pub inertia_cm: Mat3,
}

/// Products of inertia `J_xy = ∫xy dm`, `J_xz`, `J_yz` (kg m², docs/conventions.md §3;
/// the tensor's off-diagonal entries are their negatives). The same type as the record
/// field [`crate::records::Products`]: one products type, whether computed or read.
pub type ProductsOfInertia = crate::records::Products;

impl RigidBodyProperties {
    /// Builds the tensor from moments and *products* of inertia (CAD convention,
    /// as the paper lists Test Case II): tensor entry (x,y) = −J_xy.
    pub fn from_moments_and_products(
        mass: f64,
        com: Vec3,
        moments: [f64; 3],
        products: ProductsOfInertia,
    ) -> Self {
        let [jxx, jyy, jzz] = moments;
        let j = Mat3::new(
            jxx,
            -products.xy,
            -products.xz, //
            -products.xy,
            jyy,
            -products.yz, //
            -products.xz,
            -products.yz,
            jzz,
        );
        Self {
            mass,
            com,
            inertia_cm: j,
        }
    }

    /// Products of inertia in the docs/conventions.md sense (negated off-diagonal tensor entries).
    pub fn products_of_inertia(&self) -> ProductsOfInertia {
        let j = &self.inertia_cm;
        ProductsOfInertia {
            xy: -j[(0, 1)],
            xz: -j[(0, 2)],
            yz: -j[(1, 2)],
        }
    }

    /// Inertia tensor about the origin O: `J_O = J + m(|c|²I − ccᵀ)` (parallel axes).
    pub fn inertia_about_origin(&self) -> Mat3 {
        let c = self.com;
        self.inertia_cm + self.mass * (c.norm_squared() * Mat3::identity() - c * c.transpose())
    }

    /// The 6×6 mass matrix about O (docs/conventions.md; paper Eq. 6 with the (6,6) typo fixed).
    pub fn mass_matrix(&self) -> MassMatrix6 {
        let m = self.mass;
        let cx = cross_matrix(&self.com);
        let mut mm = Mat6::zeros();
        mm.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(m * Mat3::identity()));
        mm.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-m * cx));
        mm.fixed_view_mut::<3, 3>(3, 0).copy_from(&(m * cx));
        mm.fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&self.inertia_about_origin());
        MassMatrix6(mm)
    }

    /// The same body described in a frame whose origin sits at `new_origin` (same axes).
    pub fn with_origin_at(&self, new_origin: &Vec3) -> Self {
        Self {
            com: self.com - new_origin,
            ..*self
        }
    }

    /// Principal moments (ascending) and axes (columns, right-handed).
    pub fn principal(&self) -> (Vec3, Mat3) {
        let eig = self.inertia_cm.symmetric_eigen();
        let mut idx = [0usize, 1, 2];
        idx.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
        let vals = Vec3::new(
            eig.eigenvalues[idx[0]],
            eig.eigenvalues[idx[1]],
            eig.eigenvalues[idx[2]],
        );
        let mut axes = Mat3::from_columns(&[
            eig.eigenvectors.column(idx[0]).into_owned(),
            eig.eigenvectors.column(idx[1]).into_owned(),
            eig.eigenvectors.column(idx[2]).into_owned(),
        ]);
        if axes.determinant() < 0.0 {
            let c = -axes.column(2).into_owned();
            axes.set_column(2, &c);
        }
        (vals, axes)
    }

    /// Physical consistency of `m` and `J`: positive mass, positive-definite `J`, and the
    /// triangle inequalities between principal moments (`J1 + J2 ≥ J3`, …).
    /// Returns the list of violations (empty when consistent).
    pub fn consistency_violations(&self) -> Vec<String> {
        let mut v = Vec::new();
        if !(self.mass > 0.0) {
            v.push(format!("mass {} is not positive", self.mass));
        }
        let (pm, _) = self.principal();
        if !(pm.x > 0.0) {
            v.push(format!(
                "inertia tensor is not positive definite (smallest principal moment {:.6e})",
                pm.x
            ));
        }
        let j = &self.inertia_cm;
        let (a, b, c) = (j[(0, 0)], j[(1, 1)], j[(2, 2)]);
        for (name, lhs, rhs) in [
            ("Jxx + Jyy ≥ Jzz", a + b, c),
            ("Jxx + Jzz ≥ Jyy", a + c, b),
            ("Jyy + Jzz ≥ Jxx", b + c, a),
        ] {
            if lhs < rhs * (1.0 - 1e-12) {
                v.push(format!(
                    "triangle inequality {name} fails ({lhs:.6e} < {rhs:.6e})"
                ));
            }
        }
        let tri = pm.x + pm.y - pm.z;
        if tri < -1e-12 * pm.z.abs() {
            v.push(format!(
                "principal moments break J1 + J2 ≥ J3 ({:.6e} + {:.6e} < {:.6e})",
                pm.x, pm.y, pm.z
            ));
        }
        v
    }

    /// Relative errors as the paper's Figs. 5–8 and 14–17 report them: mass, the CoM
    /// vector and the 6-vector `{Jxx Jxy Jxz Jyy Jyz Jzz}`, each as `‖est − ref‖/‖ref‖`.
    pub fn relative_errors(&self, reference: &Self) -> RelativeErrors {
        let mass = (self.mass - reference.mass).abs() / reference.mass.abs();
        let com = (self.com - reference.com).norm() / reference.com.norm().max(f64::MIN_POSITIVE);
        let jv = |p: &Self| {
            let j = &p.inertia_cm;
            nalgebra::Vector6::new(
                j[(0, 0)],
                j[(0, 1)],
                j[(0, 2)],
                j[(1, 1)],
                j[(1, 2)],
                j[(2, 2)],
            )
        };
        let inertia = (jv(self) - jv(reference)).norm() / jv(reference).norm();
        RelativeErrors {
            mass,
            com,
            inertia,
            sum: mass + com + inertia,
        }
    }

    /// Checks that every value is finite and the mass positive.
    pub fn validate(&self) -> Result<(), CoreError> {
        if !(self.mass.is_finite() && self.mass > 0.0) {
            return Err(CoreError::Inertia(format!(
                "mass must be positive and finite, got {}",
                self.mass
            )));
        }
        if self
            .com
            .iter()
            .chain(self.inertia_cm.iter())
            .any(|x| !x.is_finite())
        {
            return Err(CoreError::Inertia(
                "non-finite centre of mass or inertia".into(),
            ));
        }
        if (self.inertia_cm - self.inertia_cm.transpose()).abs().max()
            > 1e-12 * self.inertia_cm.abs().max()
        {
            return Err(CoreError::Inertia("inertia tensor is not symmetric".into()));
        }
        Ok(())
    }
}

/// Relative errors of an estimate against reference properties (paper's error measures).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RelativeErrors {
    /// `|m̂ − m| / |m|`.
    pub mass: f64,
    /// `‖ĉ − c‖ / ‖c‖` (the reference CoM's norm floored at the smallest positive `f64`).
    pub com: f64,
    /// `‖ĵ − j‖ / ‖j‖` over `j = {Jxx Jxy Jxz Jyy Jyz Jzz}`, the tensor's upper triangle.
    pub inertia: f64,
    /// The sum of the three: the single figure the paper's error plots rank by.
    pub sum: f64,
}

/// The 6×6 rigid-body mass matrix about some origin O,
/// `M0 = [[mI, −m[c]×], [m[c]×, J_O]]` (docs/conventions.md).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MassMatrix6(pub Mat6);

impl MassMatrix6 {
    /// `Σ mᵢ T(pᵢ)ᵀ T(pᵢ)` over point masses: the definition the closed form must equal.
    pub fn from_point_masses(points: &[(f64, Vec3)]) -> Self {
        let mut m = Mat6::zeros();
        for (mi, p) in points {
            let t = rigid_transform(p);
            m += *mi * t.transpose() * t;
        }
        MassMatrix6(m)
    }

    /// Mass as the mean of the first three diagonal terms (paper, below Eq. 6).
    pub fn mass(&self) -> f64 {
        (self.0[(0, 0)] + self.0[(1, 1)] + self.0[(2, 2)]) / 3.0
    }

    /// Centre of mass by paper Eq. (7) (1-based indices `m_ij`).
    pub fn com(&self) -> Vec3 {
        let m = self.mass();
        let e = |i: usize, j: usize| self.0[(i - 1, j - 1)];
        Vec3::new(
            (e(2, 6) - e(3, 5)) / (2.0 * m),
            (e(3, 4) - e(1, 6)) / (2.0 * m),
            (e(1, 5) - e(2, 4)) / (2.0 * m),
        )
    }

    /// Moves the matrix to a new origin `d` (given in the current frame, same axes):
    /// `M' = Sᵀ M S` with `S = [[I, [d]×], [0, I]]` — paper Eq. (8) with `R = [d]×` (Eq. 9).
    pub fn moved_to(&self, d: &Vec3) -> Self {
        MassMatrix6(origin_shift(d).transpose() * self.0 * origin_shift(d))
    }

    /// Extracts `m`, `c` (Eq. 7) and `J` at the CoM (Eqs. 8–9), symmetrising the result.
    /// The input need not be exactly of rigid-body form (an estimate); the lower-right
    /// block of the matrix moved to the CoM is taken as `J`.
    pub fn properties(&self) -> RigidBodyProperties {
        let c = self.com();
        let at_cm = self.moved_to(&c);
        let j = at_cm.0.fixed_view::<3, 3>(3, 3).into_owned();
        RigidBodyProperties {
            mass: self.mass(),
            com: c,
            inertia_cm: (j + j.transpose()) / 2.0,
        }
    }

    /// How far the matrix is from the exact rigid-body pattern (relative Frobenius norm of
    /// the difference to the matrix rebuilt from [`Self::properties`]).
    pub fn structure_residual(&self) -> f64 {
        let rebuilt = self.properties().mass_matrix();
        (self.0 - rebuilt.0).norm() / self.0.norm()
    }
}

/// The map `S(d) = [[I, [d]×], [0, I]]` with `q_old = S q_new` for a new origin at `d`.
/// Mode shapes move as `φ_new = S(d)⁻¹ φ_old = S(−d) φ_old`.
pub fn origin_shift(d: &Vec3) -> Mat6 {
    let mut s = Mat6::identity();
    s.fixed_view_mut::<3, 3>(0, 3).copy_from(&cross_matrix(d));
    s
}

/// Moves a 6-D rigid-body shape (or motion) from origin O to a new origin at `d`.
pub fn move_shape(phi: &Vec6, d: &Vec3) -> Vec6 {
    origin_shift(&(-d)) * phi
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn cloud(seed: u64, n: usize) -> Vec<(f64, Vec3)> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                let m = rng.random_range(0.1..2.0);
                let p = Vec3::new(
                    rng.random_range(-0.5..0.7),
                    rng.random_range(-0.3..0.4),
                    rng.random_range(-0.6..0.2),
                );
                (m, p)
            })
            .collect()
    }

    fn props_of_cloud(pts: &[(f64, Vec3)]) -> RigidBodyProperties {
        let m: f64 = pts.iter().map(|(mi, _)| mi).sum();
        let c = pts.iter().fold(Vec3::zeros(), |a, (mi, p)| a + *mi * p) / m;
        let mut j = Mat3::zeros();
        for (mi, p) in pts {
            let r = p - c;
            j += *mi * (r.norm_squared() * Mat3::identity() - r * r.transpose());
        }
        RigidBodyProperties {
            mass: m,
            com: c,
            inertia_cm: j,
        }
    }

    fn rel(a: &Mat6, b: &Mat6) -> f64 {
        (a - b).norm() / b.norm()
    }

    #[test]
    fn closed_form_equals_point_cloud_sum() {
        for seed in 0..20 {
            let pts = cloud(seed, 3 + seed as usize);
            let direct = MassMatrix6::from_point_masses(&pts);
            let closed = props_of_cloud(&pts).mass_matrix();
            assert!(
                rel(&closed.0, &direct.0) < 1e-13,
                "seed {seed}: {}",
                rel(&closed.0, &direct.0)
            );
        }
    }

    #[test]
    fn com_recovery_eq7_is_exact() {
        for seed in 0..20 {
            let props = props_of_cloud(&cloud(100 + seed, 7));
            let m = props.mass_matrix();
            assert!((m.mass() - props.mass).abs() <= 1e-14 * props.mass);
            assert!((m.com() - props.com).norm() <= 1e-14 * (1.0 + props.com.norm()));
            let back = m.properties();
            assert!((back.inertia_cm - props.inertia_cm).norm() <= 1e-12 * props.inertia_cm.norm());
            assert!(m.structure_residual() < 1e-14);
        }
    }

    #[test]
    fn origin_moves_round_trip_and_match_shifted_cloud() {
        for seed in 0..20 {
            let pts = cloud(200 + seed, 6);
            let d = Vec3::new(0.3, -0.1, 0.25 * seed as f64 / 10.0);
            let m0 = MassMatrix6::from_point_masses(&pts);
            let moved = m0.moved_to(&d);
            let shifted: Vec<(f64, Vec3)> = pts.iter().map(|(mi, p)| (*mi, p - d)).collect();
            let direct = MassMatrix6::from_point_masses(&shifted);
            assert!(rel(&moved.0, &direct.0) < 1e-13);
            let back = moved.moved_to(&(-d));
            assert!(rel(&back.0, &m0.0) < 1e-13);
        }
    }

    #[test]
    fn moving_to_com_decouples_translation_and_rotation() {
        let props = props_of_cloud(&cloud(7, 9));
        let at_cm = props.mass_matrix().moved_to(&props.com);
        assert!(at_cm.0.fixed_view::<3, 3>(0, 3).norm() < 1e-13 * props.mass);
        assert!(
            (at_cm.0.fixed_view::<3, 3>(3, 3) - props.inertia_cm).norm()
                < 1e-13 * props.inertia_cm.norm()
        );
    }

    #[test]
    fn shapes_move_consistently_with_mass_matrix() {
        let props = props_of_cloud(&cloud(9, 5));
        let m0 = props.mass_matrix();
        let phi = Vec6::new(0.1, -0.2, 0.3, 0.5, 0.7, -0.4);
        let d = Vec3::new(0.2, 0.4, -0.3);
        let e0 = (phi.transpose() * m0.0 * phi)[0];
        let phi1 = move_shape(&phi, &d);
        let e1 = (phi1.transpose() * m0.moved_to(&d).0 * phi1)[0];
        assert!((e0 - e1).abs() < 1e-13 * e0.abs());
        // A body point moves identically whichever origin describes the motion.
        let p = Vec3::new(0.9, -0.3, 0.1);
        let u0 = rigid_transform(&p) * phi;
        let u1 = rigid_transform(&(p - d)) * phi1;
        assert!((u0 - u1).norm() < 1e-14);
    }

    #[test]
    fn products_of_inertia_sign_convention() {
        // Test Case II lists products in the CAD sense: tensor (x,y) = −0.07722671.
        let p = RigidBodyProperties::from_moments_and_products(
            15.69,
            Vec3::zeros(),
            [0.35733194, 0.39469014, 0.31706832],
            ProductsOfInertia {
                xy: 0.07722671,
                xz: -0.08736156,
                yz: -0.06919817,
            },
        );
        assert_eq!(p.inertia_cm[(0, 1)], -0.07722671);
        assert_eq!(p.inertia_cm[(2, 0)], 0.08736156);
        assert_eq!(p.products_of_inertia().yz, -0.06919817);
        // A point cloud with mass in the +x+y quadrant has J_xy = ∫xy dm > 0.
        let q = props_of_cloud(&[
            (1.0, Vec3::new(1.0, 1.0, 0.0)),
            (1.0, Vec3::new(-1.0, -1.0, 0.0)),
            (1.0, Vec3::new(0.0, 0.0, 1.0)),
        ]);
        assert!(q.products_of_inertia().xy > 0.0);
        assert!(q.inertia_cm[(0, 1)] < 0.0);
        assert!(p.consistency_violations().is_empty());
    }

    #[test]
    fn consistency_flags_triangle_violation() {
        let bad = RigidBodyProperties {
            mass: 1.0,
            com: Vec3::zeros(),
            inertia_cm: Mat3::from_diagonal(&Vec3::new(1.0, 1.0, 3.0)),
        };
        let v = bad.consistency_violations();
        assert!(v.iter().any(|s| s.contains("Jxx + Jyy ≥ Jzz")), "{v:?}");
        let neg = RigidBodyProperties {
            mass: 1.0,
            com: Vec3::zeros(),
            inertia_cm: Mat3::from_diagonal(&Vec3::new(1.0, -1.0, 1.0)),
        };
        assert!(neg
            .consistency_violations()
            .iter()
            .any(|s| s.contains("positive definite")));
    }
}
