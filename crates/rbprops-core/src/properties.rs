//! The ten inertia properties as one value and one ten-vector (docs/conventions.md, §3).
//!
//! Reference point: the **centre of mass**. The moments and products are those about axes
//! through the centre of mass, parallel to the geometry's axes; [`InertiaProperties::tensor_about`]
//! and [`InertiaProperties::from_tensor_about`] convert to and from another point by the
//! parallel-axis theorem.
//!
//! Sign convention: **products** of inertia `J_xy = ∫(x−c_x)(y−c_y) dm` (and `J_xz`,
//! `J_yz` alike), the convention of the paper's Eq. (6) and of CAD listings; the inertia
//! tensor's off-diagonal entries are their negatives.
//!
//! The ten-vector, in this order wherever one appears:
//! `(m, c_x, c_y, c_z, J_xx, J_yy, J_zz, J_xy, J_xz, J_yz)`.

use crate::inertia::ProductsOfInertia;
use crate::records::{InertiaEstimate, Products};
use crate::{Mat3, RigidBodyProperties, Vec3};

/// Mass, centre of mass, and the moments and products of inertia about the centre of mass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InertiaProperties {
    /// m (kg).
    pub mass: f64,
    /// Centre of mass c in the geometry's frame (m).
    pub com: Vec3,
    /// `[J_xx, J_yy, J_zz]` about the centre of mass (kg m²), `J_xx = ∫(y² + z²) dm`.
    pub moments: [f64; 3],
    /// Products about the centre of mass (kg m²), `J_xy = ∫xy dm` (minus the tensor entry).
    pub products: ProductsOfInertia,
}

impl InertiaProperties {
    /// Length of the ten-vector.
    pub const LEN: usize = 10;
    /// Names of the ten-vector's entries with their units (table columns, report keys).
    pub const NAMES: [&'static str; 10] = [
        "mass_kg",
        "com_x_m",
        "com_y_m",
        "com_z_m",
        "jxx_kg_m2",
        "jyy_kg_m2",
        "jzz_kg_m2",
        "jxy_kg_m2",
        "jxz_kg_m2",
        "jyz_kg_m2",
    ];
    /// Short symbols of the ten-vector's entries (figure labels).
    pub const SYMBOLS: [&'static str; 10] = [
        "m", "cx", "cy", "cz", "Jxx", "Jyy", "Jzz", "Jxy", "Jxz", "Jyz",
    ];

    /// The ten-vector `(m, c_x, c_y, c_z, J_xx, J_yy, J_zz, J_xy, J_xz, J_yz)`.
    pub fn to_vector(&self) -> [f64; 10] {
        let [jxx, jyy, jzz] = self.moments;
        let p = &self.products;
        [
            self.mass, self.com.x, self.com.y, self.com.z, jxx, jyy, jzz, p.xy, p.xz, p.yz,
        ]
    }

    /// The properties of a ten-vector in [`Self::to_vector`]'s order.
    pub fn from_vector(v: &[f64; 10]) -> Self {
        Self {
            mass: v[0],
            com: Vec3::new(v[1], v[2], v[3]),
            moments: [v[4], v[5], v[6]],
            products: ProductsOfInertia {
                xy: v[7],
                xz: v[8],
                yz: v[9],
            },
        }
    }

    /// From the tensor form (products are the negated off-diagonal entries).
    pub fn from_rigid_body(p: &RigidBodyProperties) -> Self {
        let j = &p.inertia_cm;
        Self {
            mass: p.mass,
            com: p.com,
            moments: [j[(0, 0)], j[(1, 1)], j[(2, 2)]],
            products: p.products_of_inertia(),
        }
    }

    /// The tensor form.
    pub fn to_rigid_body(&self) -> RigidBodyProperties {
        RigidBodyProperties::from_moments_and_products(
            self.mass,
            self.com,
            self.moments,
            self.products,
        )
    }

    /// The inertia tensor about the centre of mass.
    pub fn tensor(&self) -> Mat3 {
        self.to_rigid_body().inertia_cm
    }

    /// The inertia tensor about `point` (geometry frame), by the parallel-axis theorem:
    /// `J_P = J + m(|d|² I − d dᵀ)` with `d = c − point`.
    pub fn tensor_about(&self, point: &Vec3) -> Mat3 {
        let d = self.com - point;
        self.tensor() + self.mass * (d.norm_squared() * Mat3::identity() - d * d.transpose())
    }

    /// The properties of a body of mass `mass` and centre `com` whose inertia tensor about
    /// `point` is `tensor_about_point` (inverse of [`Self::tensor_about`]; symmetrised).
    pub fn from_tensor_about(
        mass: f64,
        com: Vec3,
        point: &Vec3,
        tensor_about_point: &Mat3,
    ) -> Self {
        let d = com - point;
        let j =
            tensor_about_point - mass * (d.norm_squared() * Mat3::identity() - d * d.transpose());
        Self::from_rigid_body(&RigidBodyProperties {
            mass,
            com,
            inertia_cm: (j + j.transpose()) / 2.0,
        })
    }

    /// From an estimate record's fields: the moments are the tensor's diagonal, the
    /// products are taken as recorded.
    fn of_record_fields(mass: f64, com: [f64; 3], j: &[[f64; 3]; 3], p: &Products) -> Self {
        Self {
            mass,
            com: Vec3::from(com),
            moments: [j[0][0], j[1][1], j[2][2]],
            products: *p,
        }
    }

    /// An estimate's values.
    pub fn of_estimate(e: &InertiaEstimate) -> Self {
        Self::of_record_fields(
            e.mass_kg,
            e.com_m,
            &e.inertia_cm_kg_m2,
            &e.products_of_inertia_kg_m2,
        )
    }

    /// An estimate's standard errors, entry by entry (a product's is its tensor entry's).
    pub fn standard_errors_of(e: &InertiaEstimate) -> Self {
        Self::of_record_fields(
            e.mass_std_kg,
            e.com_std_m,
            &e.inertia_cm_std_kg_m2,
            &e.products_of_inertia_std_kg_m2,
        )
    }

    /// Standard errors laid out as the tensor's entries: the moments' on the diagonal,
    /// the products' off it, unsigned (a product's standard error is its tensor entry's).
    pub fn tensor_standard_errors(&self) -> [[f64; 3]; 3] {
        let [sxx, syy, szz] = self.moments;
        let p = &self.products;
        [[sxx, p.xy, p.xz], [p.xy, syy, p.yz], [p.xz, p.yz, szz]]
    }

    /// Writes standard errors (as [`Self::standard_errors_of`] reads them) into an
    /// estimate: the mass, the CoM, the tensor ([`Self::tensor_standard_errors`]) and the
    /// products.
    pub fn set_standard_errors_of(&self, e: &mut InertiaEstimate) {
        let p = &self.products;
        e.mass_std_kg = self.mass;
        e.com_std_m = self.com.into();
        e.inertia_cm_std_kg_m2 = self.tensor_standard_errors();
        e.products_of_inertia_std_kg_m2.xy = p.xy;
        e.products_of_inertia_std_kg_m2.xz = p.xz;
        e.products_of_inertia_std_kg_m2.yz = p.yz;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Point masses `(m_i, p_i)`: mass, centre and the tensor about `point`, summed directly.
    fn cloud_tensor_about(pts: &[(f64, Vec3)], point: &Vec3) -> Mat3 {
        pts.iter().fold(Mat3::zeros(), |a, (m, p)| {
            let r = p - point;
            a + *m * (r.norm_squared() * Mat3::identity() - r * r.transpose())
        })
    }

    fn cloud_mass_and_com(pts: &[(f64, Vec3)]) -> (f64, Vec3) {
        let m: f64 = pts.iter().map(|(mi, _)| mi).sum();
        let c = pts.iter().fold(Vec3::zeros(), |a, (mi, p)| a + *mi * p) / m;
        (m, c)
    }

    /// Points on random-looking but fixed positions (no generator: the values are data).
    fn cloud() -> Vec<(f64, Vec3)> {
        [
            (1.3, [0.41, -0.22, 0.13]),
            (0.7, [-0.35, 0.18, 0.27]),
            (2.1, [0.05, 0.31, -0.44]),
            (0.9, [-0.12, -0.29, 0.08]),
            (1.6, [0.27, 0.07, -0.19]),
            (0.4, [-0.48, -0.06, -0.33]),
        ]
        .iter()
        .map(|&(m, p)| (m, Vec3::from(p)))
        .collect()
    }

    #[test]
    fn ten_vector_round_trips_in_the_documented_order() {
        let v = [
            15.69, 0.17, 0.03, -0.05, 0.357, 0.394, 0.317, 0.077, -0.087, -0.069,
        ];
        let p = InertiaProperties::from_vector(&v);
        assert_eq!(p.to_vector(), v);
        assert_eq!(p.mass, 15.69);
        assert_eq!(p.com, Vec3::new(0.17, 0.03, -0.05));
        assert_eq!(p.moments, [0.357, 0.394, 0.317]);
        assert_eq!(
            (p.products.xy, p.products.xz, p.products.yz),
            (0.077, -0.087, -0.069)
        );
        // The tensor form and back is exact (negation only).
        assert_eq!(InertiaProperties::from_rigid_body(&p.to_rigid_body()), p);
        assert_eq!(InertiaProperties::NAMES[7], "jxy_kg_m2");
        assert_eq!(InertiaProperties::SYMBOLS[9], "Jyz");
    }

    #[test]
    fn products_are_integrals_of_xy_dm_on_a_point_mass_cloud() {
        // Unit masses at c ± (a, b, 0): relative to their centre c, J_xy = ∫xy dm = 2ab,
        // J_xz = J_yz = 0 (z = 0), J_zz = 2(a² + b²).
        let (a, b, h) = (0.5, 0.25, 0.0);
        let c = Vec3::new(0.1, -0.2, 0.3);
        let pts = [
            (1.0, c + Vec3::new(a, b, h)),
            (1.0, c + Vec3::new(-a, -b, h)),
        ];
        let (m, com) = cloud_mass_and_com(&pts);
        let j = cloud_tensor_about(&pts, &com);
        let p = InertiaProperties::from_rigid_body(&RigidBodyProperties {
            mass: m,
            com,
            inertia_cm: j,
        });
        assert!(
            (p.products.xy - 2.0 * a * b).abs() < 1e-15,
            "{:?}",
            p.products
        );
        assert!(p.products.xz.abs() < 1e-15 && p.products.yz.abs() < 1e-15);
        assert!((p.moments[2] - 2.0 * (a * a + b * b)).abs() < 1e-15);
        // The tensor's off-diagonal entry is the negative.
        assert!((p.tensor()[(0, 1)] + 2.0 * a * b).abs() < 1e-15);
        assert!((p.to_vector()[7] - 2.0 * a * b).abs() < 1e-15);
        // Mirroring the cloud in x flips the product's sign.
        let mirrored: Vec<(f64, Vec3)> = pts
            .iter()
            .map(|(mi, q)| (*mi, Vec3::new(2.0 * c.x - q.x, q.y, q.z)))
            .collect();
        let (mm, cm) = cloud_mass_and_com(&mirrored);
        let q = InertiaProperties::from_rigid_body(&RigidBodyProperties {
            mass: mm,
            com: cm,
            inertia_cm: cloud_tensor_about(&mirrored, &cm),
        });
        assert!((q.products.xy + 2.0 * a * b).abs() < 1e-15);
    }

    #[test]
    fn reference_point_moves_follow_the_parallel_axis_theorem() {
        let pts = cloud();
        let (m, c) = cloud_mass_and_com(&pts);
        let props = InertiaProperties::from_rigid_body(&RigidBodyProperties {
            mass: m,
            com: c,
            inertia_cm: cloud_tensor_about(&pts, &c),
        });
        let scale = props.tensor().norm();
        for point in [
            Vec3::zeros(),
            Vec3::new(0.3, -0.1, 0.25),
            Vec3::new(-1.2, 0.8, 2.0),
            c,
        ] {
            // Against the tensor summed directly about the point.
            let direct = cloud_tensor_about(&pts, &point);
            let moved = props.tensor_about(&point);
            assert!((moved - direct).norm() <= 1e-12 * scale, "{point:?}");
            // And back to the centre of mass.
            let back = InertiaProperties::from_tensor_about(m, c, &point, &direct);
            let (v, w) = (back.to_vector(), props.to_vector());
            for k in 0..10 {
                assert!((v[k] - w[k]).abs() <= 1e-12 * scale.max(w[k].abs()), "{k}");
            }
        }
        // About the origin it is the core's `inertia_about_origin`.
        let jo = props.to_rigid_body().inertia_about_origin();
        assert!((props.tensor_about(&Vec3::zeros()) - jo).norm() <= 1e-12 * scale);
    }
}
