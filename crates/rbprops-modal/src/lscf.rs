//! Least-squares complex frequency-domain estimator (LSCF; Guillaume et al., "A
//! poly-reference implementation of the least-squares complex frequency-domain
//! estimator", IMAC 2003), single-reference (SIMO) common-denominator form.
//!
//! Model per channel `o`: `H_o(ω) ≈ N_o(z)/d(z)` with `z = e^{iωΔt}`, `Δt = π/ω_max`,
//! polynomials of degree `n` with *real* coefficients (conjugate pole pairs). The
//! linearised equation error `ε_o = w_o (N_o(z) − H_o d(z))` is minimised in least
//! squares. With `X = [z^j]`, `Y_o = [−H_o z^j]` the normal matrices are
//! `R = Re XᴴX`, `S_o = Re XᴴY_o`, `T_o = Re Y_oᴴY_o`; eliminating the numerators gives
//! the reduced equations `M α = 0`, `M = Σ_o (T_o − S_oᵀ R⁻¹ S_o)`, solved with the
//! highest coefficient fixed to 1. Poles are `λ = ln(z_r)/Δt` for the roots `z_r` of `d`.
//!
//! All three normal matrices are Toeplitz in the basis index (`z^j` on the unit circle),
//! so they are built from `O(N·n)` sums of `H z^m`, `|H|² cos(mθ)` and `cos(mθ)` rather
//! than `O(N·n²)` products; any (non-uniform) axis works.

use crate::band::BandData;
use crate::linalg;
use crate::pole::Pole;
use crate::roots;
use rbprops_core::c64;

/// Poles of one model order with a shape (relative residue per channel) for each.
#[derive(Debug, Clone)]
pub struct OrderPoles {
    /// Denominator degree `n` (number of poles of the polynomial, both half-planes).
    pub order: usize,
    pub poles: Vec<Pole>,
    /// Per pole, residue-like vector over the channels (scale arbitrary; for MAC).
    pub shapes: Vec<Vec<c64>>,
}

/// Toeplitz sums of the LSCF normal equations for orders up to `n_max`.
struct Sums {
    /// Per channel `r(m) = Σ_k w_k² cos(mθ_k)`.
    r: Vec<Vec<f64>>,
    /// Per channel `Re g(m)`, `g(m) = Σ_k w_k² h_k z_k^m`, m = 0..=n_max.
    g_pos: Vec<Vec<f64>>,
    /// Per channel `Re g(−m)`.
    g_neg: Vec<Vec<f64>>,
    /// Per channel `t(m) = Σ_k w_k² |h_k|² cos(mθ_k)`.
    t: Vec<Vec<f64>>,
}

fn sums(theta: &[f64], chans: &[Vec<c64>], weights: &[Vec<f64>], n_max: usize) -> Sums {
    let no = chans.len();
    let nl = theta.len();
    let pm = n_max + 1;
    // Per channel and block of `B` powers, the four sums run over the lines in
    // registers (the same additions in the same order as line by line).
    const B: usize = 4;
    let pb = pm.div_ceil(B) * B;
    // Powers z_k^m by recurrence, re-anchored every 16 steps to bound rounding drift;
    // one table `[line][m]` (padded with zeros to whole blocks) shared by every channel.
    let mut zre = vec![0.0; nl * pb];
    let mut zim = vec![0.0; nl * pb];
    for (k, &th) in theta.iter().enumerate() {
        let z = c64::new(th.cos(), th.sin());
        let mut zm = c64::new(1.0, 0.0);
        for m in 0..pm {
            if m > 0 {
                zm = if m % 16 == 0 {
                    let a = th * m as f64;
                    c64::new(a.cos(), a.sin())
                } else {
                    zm * z
                };
            }
            zre[k * pb + m] = zm.re;
            zim[k * pb + m] = zm.im;
        }
    }
    let mut s = Sums {
        r: vec![vec![0.0; pm]; no],
        g_pos: vec![vec![0.0; pm]; no],
        g_neg: vec![vec![0.0; pm]; no],
        t: vec![vec![0.0; pm]; no],
    };
    for o in 0..no {
        let w = &weights[o];
        let hw: Vec<c64> = chans[o].iter().zip(w).map(|(h, w2)| h * *w2).collect();
        let h2: Vec<f64> = chans[o]
            .iter()
            .zip(w)
            .map(|(h, w2)| h.norm_sqr() * w2)
            .collect();
        for m0 in (0..pm).step_by(B) {
            let nb = B.min(pm - m0);
            let (mut r, mut gp, mut gn, mut t) = ([0.0; B], [0.0; B], [0.0; B], [0.0; B]);
            for k in 0..nl {
                let (w2, hk, h2) = (w[k], hw[k], h2[k]);
                let pr: &[f64; B] = zre[k * pb + m0..k * pb + m0 + B].try_into().unwrap();
                let pi: &[f64; B] = zim[k * pb + m0..k * pb + m0 + B].try_into().unwrap();
                // Only real parts enter the normal matrices: Re(h z^m) = a − b and
                // Re(h z^−m) = a + b with a = Re h Re z^m, b = Im h Im z^m.
                for i in 0..B {
                    let a = hk.re * pr[i];
                    let b = hk.im * pi[i];
                    r[i] += w2 * pr[i];
                    gp[i] += a - b;
                    gn[i] += a + b;
                    t[i] += h2 * pr[i];
                }
            }
            s.r[o][m0..m0 + nb].copy_from_slice(&r[..nb]);
            s.g_pos[o][m0..m0 + nb].copy_from_slice(&gp[..nb]);
            s.g_neg[o][m0..m0 + nb].copy_from_slice(&gn[..nb]);
            s.t[o][m0..m0 + nb].copy_from_slice(&t[..nb]);
        }
    }
    s
}

/// The reduced equations of order `n`: `M = T − Σ_o G_o` (`T` Toeplitz with first
/// column `t_sum`, `G_o` the `pm`-strided row-major per-channel blocks), leading
/// `(n+1)×(n+1)` block; with `α_n = 1`, `A α_{0..n} = b` for `A` the leading `n×n`
/// block and `b` minus the first `n` entries of column `n`. Returned row-major.
fn reduced_system(t_sum: &[f64], g: &[Vec<f64>], pm: usize, n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut a = vec![0.0; n * n];
    let mut b = vec![0.0; n];
    let mut g_row = vec![0.0; n + 1];
    for j in 0..n {
        g_row.fill(0.0);
        for go in g {
            for (s, v) in g_row.iter_mut().zip(&go[j * pm..j * pm + n + 1]) {
                *s += v;
            }
        }
        for (k, (aj, gk)) in a[j * n..(j + 1) * n].iter_mut().zip(&g_row).enumerate() {
            *aj = t_sum[j.abs_diff(k)] - gk;
        }
        b[j] = g_row[n] - t_sum[n - j];
    }
    (a, b)
}

/// The LSCF stabilisation sweep: poles for every order `2..=n_max`.
///
/// `chans` are the channels to use (already restricted to non-zero ones); each is
/// weighted by the inverse of its RMS so that every channel counts equally.
pub fn sweep(band: &BandData, chans: &[Vec<c64>], n_max: usize) -> Vec<OrderPoles> {
    sweep_orders(band, chans, n_max, 1)
}

/// As [`sweep`], solving only every `step`-th order (`n % step == 0`). The reduced
/// normal equations are still built incrementally through every order; only the
/// companion eigenvalue problems (the dominant cost) are skipped. With real
/// coefficients the physical poles come in conjugate pairs, so even orders (`step = 2`)
/// lose nothing but the odd orders' single real root.
pub fn sweep_orders(
    band: &BandData,
    chans: &[Vec<c64>],
    n_max: usize,
    step: usize,
) -> Vec<OrderPoles> {
    sweep_with_roots(band, chans, n_max, step, roots::roots_near)
}

/// As [`sweep_orders`], with the roots of each order's denominator found by
/// `roots(coef, previous)`: `coef` the monic coefficients `c_0..c_{n−1}`, `previous`
/// the roots of the last order solved (a warm start).
fn sweep_with_roots(
    band: &BandData,
    chans: &[Vec<c64>],
    n_max: usize,
    step: usize,
    mut roots: impl FnMut(&[f64], Option<&[c64]>) -> Option<Vec<c64>>,
) -> Vec<OrderPoles> {
    let step = step.max(1);
    let w_max = *band.omega.last().unwrap();
    let dt = std::f64::consts::PI / w_max;
    let theta: Vec<f64> = band.omega.iter().map(|w| w * dt).collect();
    // Per-line weights w² = 1/|H|² (floored at 1e-6 of the channel's RMS): relative
    // equation errors, the maximum-likelihood weighting for noise proportional to |H|,
    // and every line counts, not only the resonance peaks and the mass line.
    let weights: Vec<Vec<f64>> = chans
        .iter()
        .map(|h| {
            let ms = h.iter().map(|z| z.norm_sqr()).sum::<f64>() / h.len() as f64;
            h.iter()
                .map(|z| 1.0 / z.norm_sqr().max(1e-12 * ms))
                .collect()
        })
        .collect();
    let s = crate::prof::time(4, || sums(&theta, chans, &weights, n_max));
    let no = chans.len();
    // All normal matrices are nested in the order (leading blocks), so the reduction
    // is updated one basis function at a time: per channel the Cholesky factor L of
    // R_o, Y_o = L⁻¹S_o and G_o = Y_oᵀY_o (so S_oᵀR_o⁻¹S_o = G_o) grow by one row and
    // column per order — O(n²) per order instead of O(n³).
    let pm = n_max + 1;
    let mut l = vec![vec![0.0f64; pm * pm]; no];
    // Y is stored transposed (row c of `yt` is column c of Y) so that every inner
    // product below runs over contiguous memory.
    let mut yt = vec![vec![0.0f64; pm * pm]; no];
    let mut g = vec![vec![0.0f64; pm * pm]; no];
    let s_at = |o: usize, j: usize, k: usize| -> f64 {
        // S_o[j,k] = −Re Σ w² h z^{k−j}
        if k >= j {
            -s.g_pos[o][k - j]
        } else {
            -s.g_neg[o][j - k]
        }
    };
    // `v − Σ_m a_m b_m`, summed in index order.
    let sub_dot = |v: f64, a: &[f64], b: &[f64]| a.iter().zip(b).fold(v, |v, (x, y)| v - x * y);
    // Four independent `sub_dot`s sharing `a`, interleaved: each is still summed in index
    // order (bitwise the same), but four chains of dependent additions run side by side.
    let sub_dot4 = |v: [f64; 4], a: &[f64], b: [&[f64]; 4]| -> [f64; 4] {
        let n = a.len();
        let (b0, b1, b2, b3) = (&b[0][..n], &b[1][..n], &b[2][..n], &b[3][..n]);
        let mut v = v;
        for i in 0..n {
            let x = a[i];
            v[0] -= x * b0[i];
            v[1] -= x * b1[i];
            v[2] -= x * b2[i];
            v[3] -= x * b3[i];
        }
        v
    };
    // Σ_o t_o(m): T = Σ_o T_o is Toeplitz too.
    let t_sum: Vec<f64> = (0..pm).map(|m| s.t.iter().map(|t| t[m]).sum()).collect();
    let mut out = Vec::new();
    let mut previous: Option<Vec<c64>> = None;
    let mut yq = vec![0.0; pm];
    for q in 0..pm {
        // Extend every channel's factors with basis function q.
        for o in 0..no {
            let (lo, yo, go) = (&mut l[o], &mut yt[o], &mut g[o]);
            let r = &s.r[o];
            for k in 0..q {
                let v = sub_dot(r[q - k], &lo[q * pm..q * pm + k], &lo[k * pm..k * pm + k]);
                lo[q * pm + k] = v / lo[k * pm + k];
            }
            let lq = &lo[q * pm..q * pm + q];
            let d = sub_dot(r[0], lq, lq);
            if !(d > 0.0) {
                return out;
            }
            lo[q * pm + q] = d.sqrt();
            // New column q of Y (rows < q), then new row q (columns ≤ q).
            for i in 0..q {
                let v = sub_dot(
                    s_at(o, i, q),
                    &lo[i * pm..i * pm + i],
                    &yo[q * pm..q * pm + i],
                );
                yo[q * pm + i] = v / lo[i * pm + i];
            }
            let lqq = lo[q * pm + q];
            let mut j0 = 0;
            while j0 + 4 <= q + 1 {
                let row = |j: usize| &yo[j * pm..j * pm + q];
                let v = sub_dot4(
                    [0, 1, 2, 3].map(|t| s_at(o, q, j0 + t)),
                    &lo[q * pm..q * pm + q],
                    [row(j0), row(j0 + 1), row(j0 + 2), row(j0 + 3)],
                );
                for (t, vt) in v.into_iter().enumerate() {
                    yo[(j0 + t) * pm + q] = vt / lqq;
                }
                j0 += 4;
            }
            for j in j0..=q {
                let v = sub_dot(
                    s_at(o, q, j),
                    &lo[q * pm..q * pm + q],
                    &yo[j * pm..j * pm + q],
                );
                yo[j * pm + q] = v / lqq;
            }
            // G = YᵀY: the new row adds to the old block; the new column is computed.
            for (j, y) in yq.iter_mut().enumerate().take(q + 1) {
                *y = yo[j * pm + q];
            }
            for j in 0..q {
                let yj = yq[j];
                for (gk, yk) in go[j * pm..j * pm + q].iter_mut().zip(&yq[..q]) {
                    *gk += yj * yk;
                }
            }
            let mut j0 = 0;
            while j0 + 4 <= q + 1 {
                let row = |j: usize| &yo[j * pm..j * pm + q + 1];
                let v = sub_dot4(
                    [0.0; 4],
                    row(q),
                    [row(j0), row(j0 + 1), row(j0 + 2), row(j0 + 3)],
                );
                for (t, vt) in v.into_iter().enumerate() {
                    go[(j0 + t) * pm + q] = -vt;
                    go[q * pm + j0 + t] = -vt;
                }
                j0 += 4;
            }
            for j in j0..=q {
                // Σ_i y_ij y_iq as −(0 − Σ …): the same additions in the same order as
                // a plain sum, so the factors stay bitwise as before.
                let v = -sub_dot(
                    0.0,
                    &yo[j * pm..j * pm + q + 1],
                    &yo[q * pm..q * pm + q + 1],
                );
                go[j * pm + q] = v;
                go[q * pm + j] = v;
            }
        }
        let n = q;
        if n < 2 || n % step != 0 {
            continue;
        }
        let p = n + 1;
        let (a, b) = reduced_system(&t_sum, &g, pm, n);
        let Some(mut coef) = linalg::solve_rows(a, b, n, 1) else {
            continue;
        };
        coef.push(1.0);
        let Some(z_roots) = crate::prof::time(5, || roots(&coef[..n], previous.as_deref())) else {
            continue;
        };
        previous = Some(z_roots.clone());
        // Numerators β_o = −R_o⁻¹S_o α = −L⁻ᵀ(Y α), for the shape vectors.
        let betas: Vec<Vec<f64>> = (0..no)
            .map(|o| {
                let (lo, yo) = (&l[o], &yt[o]);
                let ya: Vec<f64> = (0..p)
                    .map(|i| (0..p).map(|j| yo[j * pm + i] * coef[j]).sum())
                    .collect();
                let mut beta = vec![0.0; p];
                for i in (0..p).rev() {
                    let mut v = ya[i];
                    for k in i + 1..p {
                        v -= lo[k * pm + i] * beta[k];
                    }
                    beta[i] = v / lo[i * pm + i];
                }
                beta.iter().map(|b| -b).collect()
            })
            .collect();
        let mut poles = Vec::new();
        let mut shapes = Vec::new();
        for zr in z_roots {
            if zr.norm() == 0.0 || zr.im <= 0.0 {
                continue;
            }
            let lam = zr.ln() / dt;
            let (_, dprime, _) = roots::horner(&coef[..n], zr);
            let shape: Vec<c64> = betas
                .iter()
                .map(|beta| {
                    let mut num = c64::new(0.0, 0.0);
                    let mut zj = c64::new(1.0, 0.0);
                    for bj in beta {
                        num += zj * *bj;
                        zj *= zr;
                    }
                    num / dprime
                })
                .collect();
            poles.push(Pole(lam));
            shapes.push(shape);
        }
        out.push(OrderPoles {
            order: n,
            poles,
            shapes,
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testdata::{self, max_nearest};
    use rbprops_core::Quantity;

    /// Every order's warm-started Aberth roots are the companion eigenvalues to the
    /// rounding level, on sweeps like those of the fit (noisy and close-mode data,
    /// whole band and a sub-band), and the iteration rarely needs the QR.
    #[test]
    fn warm_started_roots_match_the_companion_eigenvalues() {
        let cases = [
            testdata::test_case(12.5, 4096, Quantity::Accelerance).with_noise(0.01, 7),
            testdata::close_modes(5.0, 2048).with_noise(0.01, 8),
            testdata::test_case(50.0, 4096, Quantity::Receptance).with_noise(0.03, 9),
        ];
        let (mut solved, mut fallbacks, mut sweeps, mut worst) = (0, 0, 0, 0.0f64);
        for case in &cases {
            for e in 0..case.frf.n_excitations {
                let band = BandData::extract(&case.frf, e, None, "E").unwrap();
                for top in [band.n_lines(), band.n_lines() / 4] {
                    let keep = BandData::decimation_indices(top, 1024);
                    let sub = band.lines(&keep);
                    let chans = sub.channels.clone();
                    sweep_with_roots(&sub, &chans, 40, 2, |coef, near| {
                        let (a, k) = roots::roots_and_sweeps(coef, near)?;
                        let b = linalg::polynomial_roots(coef)?;
                        assert_eq!(a.len(), b.len());
                        // Distances relative to the roots' size (about 1 here).
                        let scale = b.iter().map(|z| z.norm()).fold(1.0, f64::max);
                        worst = worst.max(max_nearest(&a, &b).max(max_nearest(&b, &a)) / scale);
                        solved += 1;
                        match k {
                            Some(k) => sweeps += k,
                            None => fallbacks += 1,
                        }
                        Some(a)
                    });
                }
            }
        }
        let warm = solved - fallbacks;
        eprintln!(
            "{solved} orders, {fallbacks} by QR, {:.2} Aberth sweeps per warm order, worst |Δz| {worst:.2e}",
            sweeps as f64 / warm as f64
        );
        assert!(worst < 1e-9, "worst root distance {worst:e}");
    }
}
