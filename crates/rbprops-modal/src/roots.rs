//! Roots of the LSCF denominator polynomials across a sweep of model orders by the
//! Aberth–Ehrlich simultaneous iteration (Aberth, *Math. Comp.* 27, 1973; Bini,
//! *Numer. Algorithms* 13, 1996), warm-started from the roots of the previous order.
//!
//! Why: the companion-matrix QR ([`linalg::polynomial_roots`]) costs `O(n³)` per order
//! and knows nothing of the neighbouring orders. Between two orders of a stabilisation
//! sweep most roots barely move, so the Aberth iteration, `O(n²)` per sweep over the
//! roots, converges in a few sweeps from the previous order's roots plus new starting
//! points for the added degrees. When it does not converge, the companion QR decides.

use crate::linalg;
use rbprops_core::c64;

/// Iterations (sweeps over all roots) before giving up and falling back to the QR.
const MAX_SWEEPS: usize = 40;

/// Roots of the monic real polynomial `p(z) = z^n + c_{n−1} z^{n−1} + … + c_0`
/// (`coef[j] = c_j`), warm-started from `near`, the roots of a fit of lower degree (or
/// none); the companion QR when there is no such start or the iteration fails.
///
/// Returned sorted by argument, then modulus: a canonical order, independent of how the
/// roots were found (the stabilisation's tie-breaks between equally supported clusters
/// follow the order of the poles, so the QR's deflation order would leak into them). Roots within `1e-9·|z|` of the real axis are made exactly real,
/// as the QR would return them: the iteration leaves real roots a rounding-level
/// imaginary part of either sign.
pub fn roots_near(coef: &[f64], near: Option<&[c64]>) -> Option<Vec<c64>> {
    roots_and_sweeps(coef, near).map(|r| r.0)
}

/// As [`roots_near`], with the number of Aberth sweeps (`None`: the companion QR).
pub fn roots_and_sweeps(coef: &[f64], near: Option<&[c64]>) -> Option<(Vec<c64>, Option<usize>)> {
    let (mut roots, sweeps) = match near
        .and_then(|prev| starting_points(prev, coef.len()))
        .and_then(|start| aberth(coef, start))
    {
        Some((r, k)) => (r, Some(k)),
        None => (linalg::polynomial_roots(coef)?, None),
    };
    for z in roots.iter_mut() {
        if z.im.abs() <= 1e-9 * z.norm() {
            z.im = 0.0;
        }
    }
    let mut keyed: Vec<(f64, f64, c64)> = roots.iter().map(|z| (z.arg(), z.norm(), *z)).collect();
    keyed.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    Some((keyed.into_iter().map(|k| k.2).collect(), sweeps))
}

/// `n` starting points: the roots `prev` of the lower-degree fit, plus new points for
/// the missing degrees, in conjugate pairs at the middle of the widest angular gap of
/// the upper half plane (and one on the real axis for an odd remainder), at the median
/// modulus of `prev`. `None` when `prev` is empty or has more than `n` roots.
fn starting_points(prev: &[c64], n: usize) -> Option<Vec<c64>> {
    if prev.is_empty() || prev.len() > n {
        return None;
    }
    let mut moduli: Vec<f64> = prev.iter().map(|z| z.norm()).collect();
    moduli.sort_by(f64::total_cmp);
    let radius = moduli[moduli.len() / 2];
    if !(radius > 0.0 && radius.is_finite()) {
        return None;
    }
    let mut start = prev.to_vec();
    while start.len() + 2 <= n {
        let angle = widest_gap_middle(&start);
        let z = c64::from_polar(radius, angle);
        start.push(z);
        start.push(z.conj());
    }
    if start.len() < n {
        // An odd degree: a real start on the side with fewer roots.
        let left = start.iter().filter(|z| z.re < 0.0).count();
        let sign = if 2 * left < start.len() { -1.0 } else { 1.0 };
        start.push(c64::new(sign * radius, 0.0));
    }
    Some(start)
}

/// The middle of the widest gap between the arguments in `[0, π]` of `roots` (with
/// 0 and π themselves as gap ends), slightly off-centre so that it never lands on
/// the real axis.
fn widest_gap_middle(roots: &[c64]) -> f64 {
    let pi = std::f64::consts::PI;
    let mut args: Vec<f64> = roots.iter().map(|z| z.arg().abs()).collect();
    args.extend([0.0, pi]);
    args.sort_by(f64::total_cmp);
    let (lo, hi) = args
        .windows(2)
        .map(|w| (w[0], w[1]))
        .fold((0.0, 0.0), |best, g| {
            if g.1 - g.0 > best.1 - best.0 {
                g
            } else {
                best
            }
        });
    (lo + 0.5 * (hi - lo)).clamp(1e-3 * pi, (1.0 - 1e-3) * pi)
}

/// `(p(z), p'(z), b(z))` of the monic `p` (`coef` as in [`roots_near`]) by Horner's
/// rule, where `b(z) = Σ_j |c_j| |z|^j` (with
/// `c_n = 1`) bounds the rounding error of the evaluation: `|fl(p(z)) − p(z)| ≲ 2nε·b`.
pub fn horner(coef: &[f64], z: c64) -> (c64, c64, f64) {
    let r = z.norm_sqr().sqrt();
    let (mut p, mut dp, mut b) = (c64::new(1.0, 0.0), c64::new(0.0, 0.0), 1.0);
    for &c in coef.iter().rev() {
        dp = dp * z + p;
        p = p * z + c;
        b = b * r + c.abs();
    }
    (p, dp, b)
}

/// `Σ_j 1/(z − z_j)`, each term as `conj(d)/|d|²` (one division), summed in index order.
///
/// Why two passes: the divisions `1/|d_j|²` are independent of each other, so in a loop
/// of their own they run several to a vector instruction (`inv` is scratch space),
/// while the sum, a chain of dependent additions, keeps its order (bitwise the one-pass
/// fold).
fn sum_reciprocals(z: c64, others: &[c64], inv: &mut Vec<f64>) -> c64 {
    inv.clear();
    inv.extend(others.iter().map(|zj| 1.0 / (z - zj).norm_sqr()));
    others
        .iter()
        .zip(inv.iter())
        .fold(c64::new(0.0, 0.0), |s, (zj, &inv)| {
            let d = z - zj;
            c64::new(s.re + d.re * inv, s.im - d.im * inv)
        })
}

/// The Aberth–Ehrlich iteration on all roots from `z` (Gauss–Seidel order: each
/// update uses the newest values of the others),
///
/// `z_i ← z_i − w_i`, `w_i = N_i / (1 − N_i Σ_{j≠i} 1/(z_i − z_j))`, `N_i = p(z_i)/p'(z_i)`,
///
/// a root frozen once `|p(z_i)|` is at the rounding level of its evaluation
/// (`≤ 4nε·b(z_i)`, see [`horner`]: `z_i` is then an exact root of a polynomial whose
/// coefficients differ from `c` by a few ulps), after that last correction. `None`
/// when some root has not converged after [`MAX_SWEEPS`] sweeps or a value is not
/// finite; else the roots and the number of sweeps.
fn aberth(coef: &[f64], z: Vec<c64>) -> Option<(Vec<c64>, usize)> {
    aberth_sweeps(coef, z)
}

crate::simd::avx_fn! {
/// [`aberth`] (compiled with AVX where the CPU has it: four divisions a vector).
fn aberth_sweeps(coef: &[f64], z: Vec<c64>) -> Option<(Vec<c64>, usize)> {
    let mut z = z;
    let n = coef.len();
    let tol = 4.0 * n as f64 * f64::EPSILON;
    let mut done = vec![false; n];
    let mut inv = Vec::with_capacity(n);
    for sweep in 1..=MAX_SWEEPS {
        let mut all = true;
        for i in 0..n {
            if done[i] {
                continue;
            }
            let (p, dp, b) = horner(coef, z[i]);
            let newton = p / dp;
            let s = sum_reciprocals(z[i], &z[..i], &mut inv)
                + sum_reciprocals(z[i], &z[i + 1..], &mut inv);
            let w = newton / (1.0 - newton * s);
            if !(w.re.is_finite() && w.im.is_finite()) {
                return None;
            }
            z[i] -= w;
            if p.norm_sqr() <= (tol * b).powi(2) {
                done[i] = true;
            } else {
                all = false;
            }
        }
        if all {
            return Some((z, sweep));
        }
    }
    None
}
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testdata::{max_nearest, poly_from_roots};

    fn sorted(mut v: Vec<c64>) -> Vec<c64> {
        v.sort_by(|a, b| {
            a.arg()
                .total_cmp(&b.arg())
                .then(a.norm().total_cmp(&b.norm()))
        });
        v
    }

    #[test]
    fn cold_start_is_the_companion_qr() {
        let c = [-2.0, 1.0, -2.0];
        let a = roots_near(&c, None).unwrap();
        let b = sorted(linalg::polynomial_roots(&c).unwrap());
        assert_eq!(a, b);
    }

    /// Pseudo-random pole-like sets (conjugate pairs near the unit circle, as LSCF
    /// gives for lightly damped modes in the z-domain basis, plus scattered
    /// computational pairs and real roots), warm-started from a perturbed set of two
    /// fewer roots: the same roots as the companion QR, and few sweeps.
    #[test]
    fn warm_start_matches_the_companion_qr_on_pole_like_sets() {
        let mut seed = 2024u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut trials, mut sweeps, mut worst) = (0, 0, 0.0f64);
        for n in (4..=40).step_by(2) {
            for _ in 0..20 {
                let mut roots = Vec::new();
                while roots.len() + 2 <= n {
                    let (r, phi) = if rnd() < 0.5 {
                        (1.0 - 0.05 * rnd() * rnd(), std::f64::consts::PI * rnd())
                    } else {
                        (0.3 + 1.2 * rnd(), std::f64::consts::PI * rnd())
                    };
                    let z = c64::from_polar(r, phi);
                    roots.extend([z, z.conj()]);
                }
                if roots.len() < n {
                    roots.push(c64::new(2.0 * rnd() - 1.0, 0.0));
                }
                let coef = poly_from_roots(&roots);
                let near: Vec<c64> = roots[2..]
                    .iter()
                    .map(|z| z * c64::from_polar(1.0 + 1e-3 * (rnd() - 0.5), 1e-3 * (rnd() - 0.5)))
                    .collect();
                let (a, k) = roots_and_sweeps(&coef, Some(&near)).unwrap();
                let b = linalg::polynomial_roots(&coef).unwrap();
                assert_eq!(a.len(), n);
                // Both against the generating roots: the Aberth error may not exceed
                // the QR's by more than the rounding level (ill-conditioned clusters
                // limit both alike).
                let err = |x: &[c64]| max_nearest(x, &roots).max(max_nearest(&roots, x));
                let (ea, eb) = (err(&a), err(&b));
                worst = worst.max(ea / eb.max(1e-13));
                sweeps += k.expect("converged");
                trials += 1;
            }
        }
        eprintln!(
            "{trials} polynomials, {:.2} sweeps each, worst error ratio {worst:.2}",
            sweeps as f64 / trials as f64
        );
        assert!(worst < 10.0, "worst error ratio {worst}");
    }
}
