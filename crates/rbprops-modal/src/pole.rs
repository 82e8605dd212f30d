//! Poles and the two residue conventions.
//!
//! A mode is the conjugate pole pair `λ, λ*` with `λ = −ζω_r + iω_d`, `ω_d = ω_r√(1−ζ²)`
//! (time dependence `e^{+iωt}`, so `s = iω`). Its receptance contribution in
//! pole–residue form is `R/(iω − λ) + R*/(iω − λ*)`.
//!
//! The records carry modal constants `A` of the docs/conventions.md receptance form
//! `A/(ω_r² − ω² + 2iζω_rω)`. Since `(iω − λ)(iω − λ*) = ω_r² − ω² + 2iζω_rω` and
//! `1/((s−λ)(s−λ*)) = [1/(s−λ) − 1/(s−λ*)]/(2iω_d)`, a purely imaginary `R` gives exactly
//!
//! ```text
//!     A = 2i ω_d R          (1/kg, real for a proportionally damped mode)
//! ```
//!
//! For a complex mode `R` has a real part; `A = 2iω_d R` then has an imaginary part,
//! which measures modal complexity, and the receptance form with complex `A` is the
//! first-order approximation of the pole–residue pair around the resonance.

use rbprops_core::c64;
use std::f64::consts::PI;

/// One pole of the upper half plane (`Im λ > 0`), rad/s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pole(pub c64);

impl Pole {
    /// The pole of a mode with natural frequency `f_hz` and viscous damping ratio `zeta`.
    pub fn from_modal(f_hz: f64, zeta: f64) -> Self {
        let wr = 2.0 * PI * f_hz;
        Pole(c64::new(-zeta * wr, wr * (1.0 - zeta * zeta).sqrt()))
    }
    /// Natural (undamped) angular frequency `ω_r = |λ|`.
    pub fn omega_n(&self) -> f64 {
        self.0.norm()
    }
    /// Natural frequency `f_r = ω_r/2π` (Hz).
    pub fn frequency_hz(&self) -> f64 {
        self.omega_n() / (2.0 * PI)
    }
    /// Damping ratio `ζ = −Re λ / |λ|`.
    pub fn damping(&self) -> f64 {
        -self.0.re / self.0.norm()
    }
    /// Damped angular frequency `ω_d = Im λ`.
    pub fn omega_d(&self) -> f64 {
        self.0.im
    }
    /// Half-power half-bandwidth `ζω_r = −Re λ` (rad/s): the natural length scale for
    /// deciding whether two poles are the same (never a fixed Hz window).
    pub fn half_bandwidth(&self) -> f64 {
        (-self.0.re).max(0.0)
    }
    /// Pole-to-pole distance in units of the smaller half-power half-bandwidth.
    pub fn distance_in_bandwidths(&self, other: &Pole) -> f64 {
        let b = self
            .half_bandwidth()
            .min(other.half_bandwidth())
            .max(1e-9 * self.omega_n().max(other.omega_n()));
        (self.0 - other.0).norm() / b
    }
    /// Modal constant from the pole–residue residue: `A = 2iω_d R`.
    pub fn modal_constant(&self, r: c64) -> c64 {
        c64::new(0.0, 2.0 * self.omega_d()) * r
    }
    /// Inverse of [`Pole::modal_constant`]: `R = A/(2iω_d)`.
    pub fn residue_from_modal_constant(&self, a: c64) -> c64 {
        a / c64::new(0.0, 2.0 * self.omega_d())
    }
    /// Receptance of the pair with residue `R` at `s = iω`.
    pub fn receptance(&self, r: c64, omega: f64) -> c64 {
        let s = c64::new(0.0, omega);
        r / (s - self.0) + r.conj() / (s - self.0.conj())
    }
}

/// Mode phase collinearity of a complex vector (Pappa et al.): 1 for a real (or
/// real-up-to-a-phase) vector, 0 for a circular one.
pub fn mpc(v: &[c64]) -> f64 {
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for z in v {
        sxx += z.re * z.re;
        syy += z.im * z.im;
        sxy += z.re * z.im;
    }
    let tr = sxx + syy;
    if tr <= 0.0 {
        return 0.0;
    }
    let det = sxx * syy - sxy * sxy;
    let disc = ((tr * tr / 4.0) - det).max(0.0).sqrt();
    let (l1, l2) = (tr / 2.0 + disc, tr / 2.0 - disc);
    ((l1 - l2) / (l1 + l2)).powi(2)
}

/// Modal assurance criterion between two complex vectors.
pub fn mac(a: &[c64], b: &[c64]) -> f64 {
    let num: c64 = a.iter().zip(b).map(|(x, y)| x.conj() * y).sum();
    let na: f64 = a.iter().map(|x| x.norm_sqr()).sum();
    let nb: f64 = b.iter().map(|x| x.norm_sqr()).sum();
    if na <= 0.0 || nb <= 0.0 {
        return 0.0;
    }
    num.norm_sqr() / (na * nb)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn modal_constant_form_equals_pole_residue_form() {
        let p = Pole::from_modal(1.3, 0.015);
        let a = c64::new(0.37, 0.0);
        let r = p.residue_from_modal_constant(a);
        let wr = p.omega_n();
        for w in [0.0, 3.0, wr, 20.0] {
            let h_a = a / c64::new(wr * wr - w * w, 2.0 * p.damping() * wr * w);
            assert!((p.receptance(r, w) - h_a).norm() < 1e-13 * h_a.norm().max(1e-3));
        }
        assert!((p.frequency_hz() - 1.3).abs() < 1e-14);
        assert!((p.damping() - 0.015).abs() < 1e-15);
        assert!((p.modal_constant(r) - a).norm() < 1e-15);
    }

    #[test]
    fn mpc_and_mac_limits() {
        let real = [c64::new(1.0, 1.0), c64::new(-2.0, -2.0)];
        assert!((mpc(&real) - 1.0).abs() < 1e-12);
        let circ = [c64::new(1.0, 0.0), c64::new(0.0, 1.0)];
        assert!(mpc(&circ) < 1e-12);
        let b: Vec<c64> = real.iter().map(|z| z * c64::new(0.0, 3.0)).collect();
        assert!((mac(&real, &b) - 1.0).abs() < 1e-12);
        assert!(
            mac(
                &[c64::new(1.0, 0.0), c64::new(0.0, 0.0)],
                &[c64::new(0.0, 0.0), c64::new(1.0, 0.0)]
            ) < 1e-15
        );
    }
}
