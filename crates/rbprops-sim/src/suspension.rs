//! Linear spring suspensions and their 6×6 mount stiffness about the origin.

use rbprops_core::{rigid_transform, Mat3, Mat6, Vec3};

/// A linear spring between body point `at` and the ground, with 3×3 stiffness `k`
/// (N/m) acting on the displacement of that point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spring {
    /// Attachment point on the body, geometry frame (m).
    pub at: Vec3,
    /// 3×3 stiffness `k` (N/m), symmetric positive semi-definite.
    pub stiffness: Mat3,
}

/// Stiffness of one spring about the origin: `K_a = T(a)ᵀ k T(a)`, since the spring sees
/// the displacement `u(a) = T(a) q0` and returns the force `−k u(a)`, whose generalised
/// force about O is `T(a)ᵀ(−k u(a))` (virtual work).
pub fn spring_stiffness(spring: &Spring) -> Mat6 {
    let t = rigid_transform(&spring.at);
    t.transpose() * spring.stiffness * t
}

/// Mount stiffness about the origin: `K = Σ_a T(a)ᵀ k_a T(a)`.
pub fn mount_stiffness(springs: &[Spring]) -> Mat6 {
    springs.iter().map(spring_stiffness).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertical_spring_gives_pitch_and_roll_stiffness() {
        // One vertical spring k at (x, y, 0): K_zz = k, K_θxθx = k y², K_θyθy = k x²,
        // K_zθx = k y, K_zθy = −k x (from u_z = z + θx y − θy x).
        let (k, x, y) = (100.0, 0.3, -0.2);
        let kk = mount_stiffness(&[Spring {
            at: Vec3::new(x, y, 0.0),
            stiffness: Mat3::from_diagonal(&Vec3::new(0.0, 0.0, k)),
        }]);
        let mut expect = Mat6::zeros();
        expect[(2, 2)] = k;
        expect[(3, 3)] = k * y * y;
        expect[(4, 4)] = k * x * x;
        expect[(2, 3)] = k * y;
        expect[(3, 2)] = k * y;
        expect[(2, 4)] = -k * x;
        expect[(4, 2)] = -k * x;
        expect[(3, 4)] = -k * x * y;
        expect[(4, 3)] = -k * x * y;
        assert!((kk - expect).norm() < 1e-12, "{kk}");
    }

    #[test]
    fn potential_energy_matches_spring_elongation() {
        let s = Spring {
            at: Vec3::new(0.1, 0.5, -0.3),
            stiffness: Mat3::new(3.0, 1.0, 0.5, 1.0, 4.0, -0.2, 0.5, -0.2, 2.0),
        };
        let q = rbprops_core::Vec6::new(1e-3, -2e-3, 3e-3, 0.01, -0.02, 0.005);
        let u = s.at;
        let du = q.fixed_rows::<3>(0).into_owned() + q.fixed_rows::<3>(3).cross(&u);
        let e_spring = 0.5 * (du.transpose() * s.stiffness * du)[0];
        let e_k = 0.5 * (q.transpose() * spring_stiffness(&s) * q)[0];
        assert!((e_spring - e_k).abs() < 1e-15);
    }
}
