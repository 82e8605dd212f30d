//! Real modes of a rigid body on a linear suspension.

use crate::{c64, CoreError, Mat6, Vec6};
use nalgebra::RowVector6;

/// One real mode about an origin O, mass-normalised: `φᵀ M0 φ = 1`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidMode {
    /// Natural frequency `ω_r/2π` (Hz); 0 for a free rigid-body direction.
    pub frequency_hz: f64,
    /// Viscous damping ratio `ζ_r` (docs/conventions.md §5).
    pub damping_ratio: f64,
    /// `φ0 = [u; θ]` about the origin of the geometry.
    pub shape: Vec6,
}

impl RigidMode {
    /// Natural angular frequency `ω_r = 2π f_r` (rad/s).
    pub fn omega(&self) -> f64 {
        2.0 * std::f64::consts::PI * self.frequency_hz
    }

    /// A free rigid-body direction: the suspension gives it no stiffness, so its
    /// frequency is 0 (see [`rigid_body_modes`]).
    pub fn is_free(&self) -> bool {
        self.frequency_hz == 0.0
    }

    /// Modal constant of channel row `a` and force column `b`: `A = (aᵀφ)(bᵀφ)` (1/kg).
    pub fn modal_constant(&self, a: &RowVector6<f64>, b: &Vec6) -> f64 {
        (a * self.shape)[0] * b.dot(&self.shape)
    }
}

/// Receptance of the modal sum `H(ω) = Σ_r A_r / (ω_r² − ω² + 2iζ_r ω_r ω)` (docs/conventions.md).
pub fn modal_receptance(modes: &[RigidMode], a: &RowVector6<f64>, b: &Vec6, omega: f64) -> c64 {
    modes
        .iter()
        .map(|m| {
            let wr = m.omega();
            c64::new(m.modal_constant(a, b), 0.0)
                / c64::new(wr * wr - omega * omega, 2.0 * m.damping_ratio * wr * omega)
        })
        .sum()
}

/// Relative size `ω_r²/ω²_max` at or below which a mode is a free rigid-body direction
/// (the suspension gives no stiffness there): its ω is reported as exactly 0. Rounding in
/// `K` of a suspension with an exact free direction (vertical cords read as axial
/// springs, a free–free body) leaves eigenvalues near 1e-16 of the largest; a genuine
/// suspension mode at 1e-6 of the highest frequency would be far below any band.
pub const FREE_MODE_RELATIVE_EIGENVALUE: f64 = 1e-12;

/// Undamped modes of `K φ = ω² M φ`, mass-normalised (`ΦᵀMΦ = I`), ascending in frequency.
/// Each shape's largest-magnitude entry is made positive so results are reproducible.
/// Negative eigenvalues (an unstable suspension) are an error. A direction the springs
/// leave free is a zero-frequency mode (ω = 0 exactly, see
/// [`FREE_MODE_RELATIVE_EIGENVALUE`]); when several are free their shapes are one
/// mass-orthonormal basis of the free directions (any other is as valid). With `K = 0`
/// (a free–free body) all six are.
pub fn rigid_body_modes(m: &Mat6, k: &Mat6) -> Result<Vec<(f64, Vec6)>, CoreError> {
    let chol = nalgebra::Cholesky::new(*m)
        .ok_or_else(|| CoreError::Inertia("mass matrix is not positive definite".into()))?;
    let l = chol.l();
    let linv = l
        .try_inverse()
        .ok_or_else(|| CoreError::Inertia("mass matrix is singular".into()))?;
    let a = linv * k * linv.transpose();
    let a = (a + a.transpose()) / 2.0;
    let eig = a.symmetric_eigen();
    let mut idx: Vec<usize> = (0..6).collect();
    idx.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    let scale = eig.eigenvalues.abs().max().max(f64::MIN_POSITIVE);
    let mut out = Vec::with_capacity(6);
    for i in idx {
        let w2 = eig.eigenvalues[i];
        if w2 < -1e-12 * scale {
            return Err(CoreError::Inertia(format!(
                "suspension is unstable: eigenvalue ω² = {w2:.4e} < 0"
            )));
        }
        let mut phi: Vec6 = linv.transpose() * eig.eigenvectors.column(i);
        let imax = phi.iamax();
        if phi[imax] < 0.0 {
            phi = -phi;
        }
        let w = if w2 <= FREE_MODE_RELATIVE_EIGENVALUE * scale {
            0.0
        } else {
            w2.sqrt()
        };
        out.push((w, phi));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{RigidBodyProperties, Vec3};

    /// Test Case II-like inertia with an offset centre and products.
    fn test_body() -> RigidBodyProperties {
        RigidBodyProperties::from_moments_and_products(
            15.69,
            Vec3::new(0.1, -0.05, 0.2),
            [0.357, 0.394, 0.317],
            crate::inertia::ProductsOfInertia {
                xy: 0.077,
                xz: -0.087,
                yz: -0.069,
            },
        )
    }

    #[test]
    fn modes_are_mass_normalised_and_diagonalise_k() {
        let props = test_body();
        let m = props.mass_matrix().0;
        let mut k = Mat6::zeros();
        for (i, v) in [100.0, 200.0, 300.0, 5.0, 7.0, 9.0].iter().enumerate() {
            k[(i, i)] = *v;
        }
        k[(0, 4)] = 3.0;
        k[(4, 0)] = 3.0;
        let modes = rigid_body_modes(&m, &k).unwrap();
        let phi = Mat6::from_columns(&modes.iter().map(|(_, p)| *p).collect::<Vec<_>>());
        let id = phi.transpose() * m * phi;
        assert!((id - Mat6::identity()).norm() < 1e-12);
        let om = phi.transpose() * k * phi;
        for i in 0..6 {
            assert!((om[(i, i)] - modes[i].0.powi(2)).abs() < 1e-10 * modes[5].0.powi(2));
        }
        assert!(modes.windows(2).all(|w| w[0].0 <= w[1].0));
    }

    /// Four vertical axial springs `k ẑẑᵀ` leave x, y and yaw free: exactly three modes at
    /// ω = 0 whose shapes span those directions (K φ = 0), and three positive ones. A
    /// free–free body (K = 0) has six zero modes, still mass-normalised.
    #[test]
    fn free_directions_are_zero_frequency_modes() {
        let props = test_body();
        let m = props.mass_matrix().0;
        let mut k = Mat6::zeros();
        for (x, y) in [(0.0, -0.1), (0.3, -0.1), (0.0, 0.2), (0.3, 0.2)] {
            let t = crate::rigid_transform(&Vec3::new(x, y, 0.17));
            let kz = nalgebra::Matrix3::from_diagonal(&Vec3::new(0.0, 0.0, 2500.0));
            k += t.transpose() * kz * t;
        }
        let modes = rigid_body_modes(&m, &k).unwrap();
        let free: Vec<_> = modes.iter().filter(|(w, _)| *w == 0.0).collect();
        assert_eq!(free.len(), 3, "{modes:?}");
        assert!(modes[3].0 > 1.0);
        for (_, phi) in &free {
            assert!((k * phi).norm() < 1e-9 * k.norm() * phi.norm());
            assert!(((phi.transpose() * m * phi)[0] - 1.0).abs() < 1e-12);
            // No vertical motion, pitch or roll in a free direction.
            assert!(phi[2].abs() + phi[3].abs() + phi[4].abs() < 1e-9 * phi.norm());
        }
        let ff = rigid_body_modes(&m, &Mat6::zeros()).unwrap();
        assert!(ff.iter().all(|(w, _)| *w == 0.0));
        let phi = Mat6::from_columns(&ff.iter().map(|(_, p)| *p).collect::<Vec<_>>());
        assert!((phi.transpose() * m * phi - Mat6::identity()).norm() < 1e-12);
    }
}
