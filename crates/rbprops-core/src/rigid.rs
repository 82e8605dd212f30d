//! The least-squares rigid-body transform of a measured shape (paper Eqs. 3–5) and the
//! mass-normalisation from the force geometry (docs/conventions.md).

use crate::{c64, CoreError, Mat6, Vec6};
use nalgebra::RowVector6;

/// Channel rows `S` (n × 6) prepared for repeated least-squares fits `q = (SᵀS)⁻¹SᵀA`.
#[derive(Debug, Clone)]
pub struct RigidBasis {
    rows: Vec<RowVector6<f64>>,
    /// Cholesky factor of `SᵀS`.
    gram: nalgebra::Cholesky<f64, nalgebra::U6>,
    /// Condition number of `SᵀS` (ratio of extreme eigenvalues).
    pub condition: f64,
}

/// Beyond this condition number of `SᵀS` the transform is refused as ill-conditioned.
pub const MAX_CONDITION: f64 = 1e10;

impl RigidBasis {
    /// Builds the basis; refuses channel sets that cannot see all six rigid motions
    /// (e.g. collinear or only two triaxial points).
    pub fn new(rows: Vec<RowVector6<f64>>) -> Result<Self, CoreError> {
        let mut g = Mat6::zeros();
        for r in &rows {
            g += r.transpose() * r;
        }
        let ev = g.symmetric_eigenvalues();
        let (lo, hi) = (ev.min(), ev.max());
        let condition = if lo > 0.0 { hi / lo } else { f64::INFINITY };
        if !(condition < MAX_CONDITION) {
            return Err(CoreError::Geometry(format!(
                "the {} channels cannot resolve all six rigid-body motions (cond(SᵀS) = {condition:.3e}); \
                 use at least three non-collinear triaxial points",
                rows.len()
            )));
        }
        let gram = nalgebra::Cholesky::new(g)
            .ok_or_else(|| CoreError::Geometry("SᵀS is not positive definite".into()))?;
        Ok(Self {
            rows,
            gram,
            condition,
        })
    }

    /// Number of channels (rows of `S`).
    pub fn n_channels(&self) -> usize {
        self.rows.len()
    }

    /// The channel rows `sᵢᵀT(pᵢ)`.
    pub fn rows(&self) -> &[RowVector6<f64>] {
        &self.rows
    }

    /// `q = (SᵀS)⁻¹ Sᵀ a` (paper Eq. 5) and the per-channel residual `a − S q`.
    pub fn fit(&self, a: &[f64]) -> Result<RigidFit, CoreError> {
        if a.len() != self.rows.len() {
            return Err(CoreError::Geometry(format!(
                "shape has {} entries for {} channels",
                a.len(),
                self.rows.len()
            )));
        }
        let mut rhs = Vec6::zeros();
        for (r, &ai) in self.rows.iter().zip(a) {
            rhs += r.transpose() * ai;
        }
        let q = self.gram.solve(&rhs);
        let residual: Vec<f64> = self
            .rows
            .iter()
            .zip(a)
            .map(|(r, &ai)| ai - (r * q)[0])
            .collect();
        let norm_a = a.iter().map(|x| x * x).sum::<f64>().sqrt();
        let norm_r = residual.iter().map(|x| x * x).sum::<f64>().sqrt();
        Ok(RigidFit {
            q,
            residual,
            relative_residual: if norm_a > 0.0 { norm_r / norm_a } else { 0.0 },
        })
    }

    /// `(SᵀS)⁻¹`, the covariance factor of `q` for white channel noise of unit variance.
    pub fn gram_inverse(&self) -> Mat6 {
        self.gram.inverse()
    }
}

/// Result of one rigid-body transform.
#[derive(Debug, Clone, PartialEq)]
pub struct RigidFit {
    /// Rigid motion `q = [u; θ]` about the origin of the channel rows.
    pub q: Vec6,
    /// Per-channel residual `A − S q` (how far the measured shape is from rigid motion).
    pub residual: Vec<f64>,
    /// `‖A − Sq‖ / ‖A‖`.
    pub relative_residual: f64,
}

/// Rotates complex modal constants onto the real line: returns `Re(e^{-iα} A)` with α in
/// (−π/2, π/2] the angle that maximises the real part's energy (the principal direction of
/// the points in the complex plane), and α itself. For a proportionally damped mode the
/// modal constants are already real (α ≈ 0); |α| and the rejected imaginary energy measure
/// complexity.
pub fn real_modal_constants(a: &[c64]) -> (Vec<f64>, f64) {
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for z in a {
        sxx += z.re * z.re;
        syy += z.im * z.im;
        sxy += z.re * z.im;
    }
    let alpha = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let rot = c64::from_polar(1.0, -alpha);
    (a.iter().map(|z| (z * rot).re).collect(), alpha)
}

/// Mass-normalises a rigid motion from the force geometry: with `q = c φ0` and
/// `c = fᵀφ0`, `c² = fᵀq`, so `φ0 = q / sqrt(fᵀq)` (docs/conventions.md). Returns `(φ0, fᵀq)`.
/// `fᵀq ≤ 0` means the force does not excite the mode: an error, never a NaN.
pub fn mass_normalise(q: &Vec6, force: &Vec6) -> Result<(Vec6, f64), CoreError> {
    let s = force.dot(q);
    if !(s > 0.0) || !s.is_finite() {
        return Err(CoreError::Inertia(format!(
            "force projection fᵀq = {s:.3e} ≤ 0: this excitation does not excite the mode, it cannot be mass-normalised"
        )));
    }
    Ok((q / s.sqrt(), s))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Channel, Vec3};

    fn triax(p: Vec3) -> Vec<RowVector6<f64>> {
        (0..3)
            .map(|k| {
                Channel {
                    id: String::new(),
                    point: String::new(),
                    position: p,
                    direction: Vec3::from_fn(|i, _| (i == k) as u8 as f64),
                }
                .row()
            })
            .collect()
    }

    #[test]
    fn exact_rigid_shape_is_recovered_with_zero_residual() {
        let mut rows = triax(Vec3::new(0.1, 0.0, 0.0));
        rows.extend(triax(Vec3::new(-0.05, 0.09, 0.02)));
        rows.extend(triax(Vec3::new(-0.05, -0.09, -0.03)));
        let basis = RigidBasis::new(rows.clone()).unwrap();
        let phi = Vec6::new(0.01, -0.2, 0.05, 0.7, -0.3, 0.9);
        let f = Vec6::new(0.0, 1.0, 0.0, 0.0, 0.0, 0.1);
        let c = f.dot(&phi);
        let a: Vec<f64> = rows.iter().map(|r| (r * phi)[0] * c).collect();
        let fit = basis.fit(&a).unwrap();
        assert!((fit.q - phi * c).norm() < 1e-12 * phi.norm());
        assert!(fit.relative_residual < 1e-13);
        let (phi_back, s) = mass_normalise(&fit.q, &f).unwrap();
        assert!((phi_back - phi * c.signum()).norm() < 1e-12);
        assert!((s - c * c).abs() < 1e-12);
    }

    #[test]
    fn two_triaxial_points_are_refused() {
        let mut rows = triax(Vec3::new(0.1, 0.0, 0.0));
        rows.extend(triax(Vec3::new(-0.1, 0.0, 0.0)));
        let e = RigidBasis::new(rows).unwrap_err().to_string();
        assert!(e.contains("cannot resolve"), "{e}");
    }

    #[test]
    fn negative_projection_is_an_error_not_nan() {
        let q = Vec6::new(1.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        assert!(mass_normalise(&q, &(-q)).is_err());
        assert!(mass_normalise(&q, &Vec6::zeros()).is_err());
    }

    #[test]
    fn complex_constants_are_rotated_to_real() {
        let a = [
            c64::from_polar(2.0, 0.3),
            c64::from_polar(-1.0, 0.3),
            c64::from_polar(0.5, 0.3),
        ];
        let (r, alpha) = real_modal_constants(&a);
        assert!((alpha - 0.3).abs() < 1e-12);
        assert!((r[0] - 2.0).abs() < 1e-12 && (r[1] + 1.0).abs() < 1e-12);
    }
}
