//! Real modes of a rigid body on a linear suspension.

use crate::records::{ModalFitRecord, WindowCorrectionRecord};
use crate::{c64, CoreError, FrfSet, Mat6, Vec6};
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

/// An exponential window `w(t) = e^{−t/τ}` applied to the response records (and to the
/// force records, or to a force pulse short against τ) before the FRFs were computed.
///
/// For a transient inside the record the transform of a windowed signal is its Laplace
/// transform at `s = iω + σ` with `σ = 1/τ`, and the force's window cancels, so a measured
/// FRF of quantity order k (receptance 0, mobility 1, accelerance 2) is
///
/// ```text
///   D_w(ω) = (iω + σ)^k H(iω + σ),   H(s) = Σ_r R_r/(s − λ_r) + R_r*/(s − λ_r*).
/// ```
///
/// Each mode's impulse response `R e^{λt}` becomes `R e^{(λ − σ)t}`: every pole moves to
/// `λ − σ` (its decay rate `ζω_r` grows by σ, the damped frequency `ω_d` is kept) and the
/// pole–residue residue `R` is unchanged. Since the receptance-form modal constant of
/// `docs/conventions` (README "Conventions"), `A/(ω_r² − ω² + 2iζ_rω_rω)`, is `A = 2iω_d R`
/// and `ω_d` is kept, `A` is unchanged too.
///
/// The quantity factor `(iω + σ)^k` is not the `(iω)^k` a modal fit assumes, so the fit is
/// given [`ExponentialWindow::prefilter`]ed data `(iω/(iω + σ))^k D_w = (iω)^k H(iω + σ)`:
/// exactly a modal model (with the same residual terms) of poles `λ − σ` and residues `R`.
/// The fitted poles are then moved back by [`ExponentialWindow::corrected_pole`].
/// Residual terms: the upper residual (a flexibility, an impulse at t = 0) is not changed by
/// a window; the lower ones (modes below the band) are modes like the others and move
/// with them. The accelerance mass line `lim s²H(s) = S M⁻¹ F` (the band-limited fit of
/// `Re D_w = a0 + Σ b_k/ω^{2k}`, even in ω because `D_w(−ω) = D_w(ω)*`) is unchanged.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExponentialWindow {
    /// τ (s).
    pub time_constant_s: f64,
}

impl ExponentialWindow {
    /// A window of time constant `tau` (s); refuses non-positive or non-finite values.
    pub fn new(tau: f64) -> Result<Self, CoreError> {
        if tau.is_finite() && tau > 0.0 {
            Ok(Self {
                time_constant_s: tau,
            })
        } else {
            Err(CoreError::NonFinite {
                what: "exponential window time constant τ (s) must be positive and finite".into(),
                value: tau,
            })
        }
    }

    /// `σ = 1/τ` (1/s).
    pub fn decay_per_s(&self) -> f64 {
        1.0 / self.time_constant_s
    }

    /// The pole `(f, ζ)` a mode of natural frequency `f_hz` and damping `zeta` shows in
    /// windowed data: `λ − σ`.
    pub fn windowed_pole(&self, f_hz: f64, zeta: f64) -> (f64, f64) {
        let wr = 2.0 * std::f64::consts::PI * f_hz;
        let decay = zeta * wr + self.decay_per_s();
        let wd = wr * (1.0 - zeta * zeta).max(0.0).sqrt();
        pole_from_parts(decay, wd)
    }

    /// The physical pole of a mode fitted as `(f_hz, zeta)` on windowed data: `μ + σ`,
    /// with `ω_d` kept, `ω_r = √(ω_d² + (ζ'ω'_r − σ)²)`, `ζ = (ζ'ω'_r − σ)/ω_r`. A fitted decay
    /// rate below σ (the window said to have damped more than the data show) gives a
    /// negative ζ, returned as is so the caller can say so.
    pub fn corrected_pole(&self, f_hz: f64, zeta: f64) -> (f64, f64) {
        let wr = 2.0 * std::f64::consts::PI * f_hz;
        let decay = zeta * wr - self.decay_per_s();
        let wd = wr * (1.0 - zeta * zeta).max(0.0).sqrt();
        pole_from_parts(decay, wd)
    }

    /// `(iω/(iω + σ))^k · D_w`: windowed FRFs of quantity order k turned into `(iω)^k H(iω+σ)`,
    /// which a modal fit models exactly (see the type's documentation). Receptance is
    /// returned unchanged.
    pub fn prefilter(&self, frf: &FrfSet) -> FrfSet {
        let k = frf.quantity.order();
        let mut out = frf.clone();
        if k == 0 {
            return out;
        }
        let sigma = self.decay_per_s();
        let nl = frf.n_lines();
        let factors: Vec<c64> = frf
            .frequency_hz
            .iter()
            .map(|&f| {
                let s = c64::new(0.0, 2.0 * std::f64::consts::PI * f);
                (s / (s + sigma)).powi(k)
            })
            .collect();
        for (i, v) in out.values.iter_mut().enumerate() {
            *v *= factors[i % nl];
        }
        out
    }
}

impl ExponentialWindow {
    /// Moves every pole of a modal fit made on [`ExponentialWindow::prefilter`]ed windowed
    /// data back to the physical pole (modal constants unchanged, see the type's
    /// documentation) and marks the record, so the correction is never applied twice: a
    /// record that already carries a correction is an error. The damping standard error
    /// scales with `ω'_r/ω_r` (the decay-rate error is the fit's; σ is exact). A fitted decay
    /// rate below σ cannot be corrected: the damping is set to 0 and the mode says why.
    pub fn correct_modal_fit(
        &self,
        rec: &mut ModalFitRecord,
        source: &str,
    ) -> Result<(), CoreError> {
        if let Some(w) = &rec.window_correction {
            return Err(CoreError::Processing(format!(
                "the modal fit was already corrected for an exponential window (τ = {} s, from {}); it is not corrected twice",
                w.time_constant_s, w.source
            )));
        }
        for m in &mut rec.modes {
            let (f, z) = self.corrected_pole(m.frequency_hz, m.damping_ratio);
            if z < 0.0 {
                m.warnings.push(format!(
                    "the fitted decay rate ζω_r = {:.4} 1/s is below the window's 1/τ = {:.4} 1/s: τ = {} s is too short for these data (or they were not windowed); the damping is set to 0",
                    m.damping_ratio * 2.0 * std::f64::consts::PI * m.frequency_hz,
                    self.decay_per_s(),
                    self.time_constant_s
                ));
            }
            m.damping_std *= m.frequency_hz / f;
            m.frequency_hz = f;
            m.damping_ratio = z.max(0.0);
        }
        for e in &mut rec.excitations {
            e.warnings.push(format!(
                "poles corrected for an exponential window τ = {} s ({}): each decay rate ζω_r reduced by 1/τ = {:.6} 1/s",
                self.time_constant_s,
                source,
                self.decay_per_s()
            ));
        }
        rec.window_correction = Some(WindowCorrectionRecord {
            time_constant_s: self.time_constant_s,
            source: source.into(),
        });
        Ok(())
    }

    /// The inverse of [`ExponentialWindow::correct_modal_fit`]: the record's poles as the
    /// windowed data show them (for resampling those data), without the mark. `None` when
    /// the record carries no correction.
    pub fn windowed_modal_fit(rec: &ModalFitRecord) -> Option<(Self, ModalFitRecord)> {
        let wc = rec.window_correction.as_ref()?;
        let w = Self {
            time_constant_s: wc.time_constant_s,
        };
        let mut out = rec.clone();
        out.window_correction = None;
        for m in &mut out.modes {
            let (f, z) = w.windowed_pole(m.frequency_hz, m.damping_ratio);
            m.damping_std *= m.frequency_hz / f;
            m.frequency_hz = f;
            m.damping_ratio = z;
        }
        let mark = "poles corrected for an exponential window";
        for e in &mut out.excitations {
            e.warnings.retain(|w| !w.starts_with(mark));
        }
        Some((w, out))
    }
}

/// `(f_hz, ζ)` of the pole `−decay + iω_d`.
fn pole_from_parts(decay: f64, wd: f64) -> (f64, f64) {
    let wr = wd.hypot(decay);
    (wr / (2.0 * std::f64::consts::PI), decay / wr)
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

    /// Exact pole shift: the impulse response of a windowed mode is `R e^{(λ − σ)t}`;
    /// windowed_pole is checked against the pole written from that definition, and
    /// corrected_pole inverts it to rounding.
    #[test]
    fn window_moves_every_pole_by_minus_one_over_tau() {
        let w = ExponentialWindow::new(8.0).unwrap();
        for (f, z) in [(0.51, 0.02), (1.7, 0.001), (12.0, 0.05), (0.05, 0.3)] {
            let wr = 2.0 * std::f64::consts::PI * f;
            let lam = c64::new(-z * wr, wr * (1.0f64 - z * z).sqrt());
            let mu = lam - 0.125;
            let (fw, zw) = w.windowed_pole(f, z);
            let wrw = 2.0 * std::f64::consts::PI * fw;
            let got = c64::new(-zw * wrw, wrw * (1.0 - zw * zw).sqrt());
            assert!(
                (got - mu).norm() < 1e-14 * mu.norm(),
                "{f} {z}: {got} vs {mu}"
            );
            let (fc, zc) = w.corrected_pole(fw, zw);
            assert!((fc - f).abs() < 1e-14 * f, "{fc} vs {f}");
            assert!((zc - z).abs() < 1e-13 * z.max(1e-3), "{zc} vs {z}");
        }
        assert!(ExponentialWindow::new(0.0).is_err());
        assert!(ExponentialWindow::new(f64::NAN).is_err());
    }

    /// The prefiltered windowed accelerance equals the modal model with shifted poles and
    /// unchanged modal constants, line by line (an exact identity, not a fit).
    #[test]
    fn prefiltered_windowed_accelerance_is_a_modal_model_of_the_shifted_poles() {
        let w = ExponentialWindow::new(4.0).unwrap();
        let sigma = w.decay_per_s();
        let modes = [(0.6, 0.02, 1.3), (1.1, 0.01, -0.4), (2.5, 0.03, 0.8)];
        let hz: Vec<f64> = (0..200).map(|i| 0.02 * i as f64).collect();
        let mut frf = FrfSet::zeros(crate::Quantity::Accelerance, hz.clone(), 1, 1);
        let h_of = |s: c64| -> c64 {
            modes
                .iter()
                .map(|&(f, z, a)| {
                    let wr = 2.0 * std::f64::consts::PI * f;
                    c64::new(a, 0.0) / (s * s + 2.0 * z * wr * s + wr * wr)
                })
                .sum()
        };
        for (l, &f) in hz.iter().enumerate() {
            let s = c64::new(sigma, 2.0 * std::f64::consts::PI * f);
            frf.frf_mut(0, 0)[l] = s * s * h_of(s);
        }
        let pre = w.prefilter(&frf);
        for (l, &f) in hz.iter().enumerate() {
            let om = 2.0 * std::f64::consts::PI * f;
            let model: c64 = modes
                .iter()
                .map(|&(fr, z, a)| {
                    let (fw, zw) = w.windowed_pole(fr, z);
                    let wr = 2.0 * std::f64::consts::PI * fw;
                    // A/(ω_r'² − ω² + 2iζ'ω_r'ω) with the receptance form's A unchanged.
                    c64::new(a, 0.0) / c64::new(wr * wr - om * om, 2.0 * zw * wr * om)
                })
                .sum::<c64>()
                * (-om * om);
            let got = pre.frf(0, 0)[l];
            assert!(
                (got - model).norm() <= 1e-12 * model.norm().max(1e-300),
                "{f} Hz: {got} vs {model}"
            );
        }
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
