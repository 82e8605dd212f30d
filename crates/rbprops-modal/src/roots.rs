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

/// Roots evaluated side by side by [`horner_lanes`].
const HL: usize = 4;

/// [`horner`] at the points `z[i]` for every `i` of `idx`, written to `out[i]`: the
/// same operations in the same order per point (bitwise `horner`), [`HL`] points a
/// time (see [`horner4`]).
///
/// Why: Horner's rule is a chain of dependent complex multiply-adds, one per
/// coefficient, so one point at a time is latency-bound and scalar; the points are
/// independent, so side by side they fill the vector lanes and pipeline.
fn horner_lanes(coef: &[f64], z: &[c64], idx: &[usize], out: &mut [(c64, c64, f64)]) {
    for chunk in idx.chunks(HL) {
        // Unused lanes evaluate at 0 and are dropped.
        let at = |t: usize| chunk.get(t).map_or(c64::new(0.0, 0.0), |&i| z[i]);
        let [pr, pi, dr, di, b] = horner4(coef, std::array::from_fn(at));
        for (t, &i) in chunk.iter().enumerate() {
            out[i] = (c64::new(pr[t], pi[t]), c64::new(dr[t], di[t]), b[t]);
        }
    }
}

/// [`horner`] at four points: `[Re p, Im p, Re p', Im p', b]`, one lane per point.
fn horner4(coef: &[f64], z: [c64; HL]) -> [[f64; HL]; 5] {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        // SAFETY: the CPU supports AVX (checked just above).
        return unsafe { horner4_avx(coef, z) };
    }
    let v = z.map(|z| horner(coef, z));
    let lane = |f: &dyn Fn(&(c64, c64, f64)) -> f64| std::array::from_fn(|t| f(&v[t]));
    [
        lane(&|v| v.0.re),
        lane(&|v| v.0.im),
        lane(&|v| v.1.re),
        lane(&|v| v.1.im),
        lane(&|v| v.2),
    ]
}

/// [`horner`] at every point of `z` (bitwise; [`HL`] points at a time, see
/// [`horner_lanes`]).
pub fn horner_all(coef: &[f64], z: &[c64]) -> Vec<(c64, c64, f64)> {
    let mut out = vec![(c64::new(0.0, 0.0), c64::new(0.0, 0.0), 0.0); z.len()];
    let idx: Vec<usize> = (0..z.len()).collect();
    horner_lanes(coef, z, &idx, &mut out);
    out
}

/// [`horner4`] in AVX registers: the operations of `horner` (those of `c64`
/// arithmetic, in its order, no FMA), each on four lanes at once. Written with
/// intrinsics because the compiler does not vectorise the lanes of this loop-carried
/// recursion by itself.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
fn horner4_avx(coef: &[f64], z: [c64; HL]) -> [[f64; HL]; 5] {
    use std::arch::x86_64::*;
    let zr = _mm256_setr_pd(z[0].re, z[1].re, z[2].re, z[3].re);
    let zi = _mm256_setr_pd(z[0].im, z[1].im, z[2].im, z[3].im);
    let r = _mm256_sqrt_pd(_mm256_add_pd(_mm256_mul_pd(zr, zr), _mm256_mul_pd(zi, zi)));
    let (mut pr, mut pi) = (_mm256_set1_pd(1.0), _mm256_setzero_pd());
    let (mut dr, mut di) = (_mm256_setzero_pd(), _mm256_setzero_pd());
    let mut b = _mm256_set1_pd(1.0);
    for &c in coef.iter().rev() {
        // dp = dp·z + p
        let d_re = _mm256_add_pd(
            _mm256_sub_pd(_mm256_mul_pd(dr, zr), _mm256_mul_pd(di, zi)),
            pr,
        );
        let d_im = _mm256_add_pd(
            _mm256_add_pd(_mm256_mul_pd(dr, zi), _mm256_mul_pd(di, zr)),
            pi,
        );
        // p = p·z + c
        let p_re = _mm256_add_pd(
            _mm256_sub_pd(_mm256_mul_pd(pr, zr), _mm256_mul_pd(pi, zi)),
            _mm256_set1_pd(c),
        );
        let p_im = _mm256_add_pd(_mm256_mul_pd(pr, zi), _mm256_mul_pd(pi, zr));
        b = _mm256_add_pd(_mm256_mul_pd(b, r), _mm256_set1_pd(c.abs()));
        (dr, di, pr, pi) = (d_re, d_im, p_re, p_im);
    }
    [pr, pi, dr, di, b].map(|v| {
        let (lo, hi) = (_mm256_castpd256_pd128(v), _mm256_extractf128_pd::<1>(v));
        [
            _mm_cvtsd_f64(lo),
            _mm_cvtsd_f64(_mm_unpackhi_pd(lo, lo)),
            _mm_cvtsd_f64(hi),
            _mm_cvtsd_f64(_mm_unpackhi_pd(hi, hi)),
        ]
    })
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

rbprops_core::avx_fn! {
/// [`aberth`] (compiled with AVX where the CPU has it: four divisions a vector).
fn aberth_sweeps(coef: &[f64], z: Vec<c64>) -> Option<(Vec<c64>, usize)> {
    let mut z = z;
    let n = coef.len();
    let tol = 4.0 * n as f64 * f64::EPSILON;
    let mut done = vec![false; n];
    let mut inv = Vec::with_capacity(n);
    let mut live = Vec::with_capacity(n);
    let mut at = vec![(c64::new(0.0, 0.0), c64::new(0.0, 0.0), 0.0); n];
    for sweep in 1..=MAX_SWEEPS {
        let mut all = true;
        // Every live root's p, p' and bound first: z_i changes only at its own update
        // below, so these are the values the update would compute (see `horner_lanes`).
        live.clear();
        live.extend((0..n).filter(|&i| !done[i]));
        horner_lanes(coef, &z, &live, &mut at);
        for &i in &live {
            let (p, dp, b) = at[i];
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
    use rbprops_testkit::synthetic::{max_nearest, poly_from_roots};

    fn sorted(mut v: Vec<c64>) -> Vec<c64> {
        v.sort_by(|a, b| {
            a.arg()
                .total_cmp(&b.arg())
                .then(a.norm().total_cmp(&b.norm()))
        });
        v
    }

    /// The lane-wise evaluation is bitwise the scalar one, for any number of points
    /// (whole and partial groups of lanes) and any subset of them.
    #[test]
    fn horner_lanes_is_bitwise_horner() {
        let coef = [0.3, -1.7, 2.25, 1e-3, -0.5, 0.9, 4.0];
        let z: Vec<c64> = (0..11)
            .map(|k| c64::from_polar(0.5 + 0.1 * k as f64, 0.37 * k as f64 - 1.0))
            .collect();
        for idx in [(0..11).collect::<Vec<_>>(), vec![1, 4, 5, 9, 10], vec![7]] {
            let mut out = vec![(c64::new(0.0, 0.0), c64::new(0.0, 0.0), 0.0); z.len()];
            horner_lanes(&coef, &z, &idx, &mut out);
            for &i in &idx {
                let (p, dp, b) = horner(&coef, z[i]);
                let (q, dq, c) = out[i];
                assert_eq!(
                    [p.re, p.im, dp.re, dp.im, b].map(f64::to_bits),
                    [q.re, q.im, dq.re, dq.im, c].map(f64::to_bits)
                );
            }
        }
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
        let mut g = rbprops_testkit::Lcg::new(2024);
        let mut rnd = || g.unit();
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
