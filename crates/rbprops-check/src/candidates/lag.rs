//! The residual's lag scan: the delays (record lengths) where its lag transform rises
//! or peaks, by FFT, screening `record_truncation` between the profile's points.

/// Lag scan of a residual for a truncated record (`record_truncation`). The leakage of a
/// record of length T is the impulse response's tail cut off at T, which at the lines
/// f_k reads `D(f_k) = −Σ_r R_r e^{λ_r T} e^{−i2πf_kT}/(i2πf_k − λ_r) + c.c.`: a smooth
/// envelope times e^{−i2πf_kT}. The tapered lag transform of the residual of FRF b,
/// `S_b(τ) = Σ_k w_k r_{b,k} e^{+i2πf_kτ}` (Hann taper w over the lines, so a step in
/// lag is smoothed monotonically), summed as `P(τ) = Σ_b |S_b(τ)|²`, therefore steps up
/// at τ = T and decays after it. The lags of the largest local maxima of dP/dτ and of P
/// in `[tau_lo, tau_hi]` (parabolic refinement, at most `n`, at least a resolution cell
/// 1/B apart; B the bandwidth) are returned with M = ⌈(tau_hi − tau_lo) B⌉, the number
/// of independent lags scanned (the profile is Bonferroni corrected for them).
/// `rows`: (FRF index, line index, normalised residual).
pub fn delay_peaks(
    rows: &[(usize, usize, rbprops_core::c64)],
    freqs: &[f64],
    tau_lo: f64,
    tau_hi: f64,
    n: usize,
) -> (Vec<f64>, usize) {
    use rayon::prelude::*;
    use rbprops_core::c64;
    let nl = freqs.len();
    if nl < 2 || !(tau_hi > tau_lo) {
        return (Vec::new(), 0);
    }
    let band = freqs[nl - 1] - freqs[0];
    let n_frf = rows.iter().map(|r| r.0 + 1).max().unwrap_or(0);
    // Line-major (`[line][FRF]`), real and imaginary parts apart: see `lag_sums`.
    let (mut re, mut im) = (vec![0.0; n_frf * nl], vec![0.0; n_frf * nl]);
    for &(b, k, v) in rows {
        let w = 0.5 - 0.5 * (std::f64::consts::TAU * k as f64 / (nl - 1) as f64).cos();
        let x = v * w;
        (re[k * n_frf + b], im[k * n_frf + b]) = (x.re, x.im);
    }
    let step = 1.0 / (4.0 * band);
    let m = ((tau_hi - tau_lo) / step).ceil() as usize + 1;
    let p: Vec<f64> = match lag_power_by_fft(&re, &im, freqs, n_frf, tau_lo, m) {
        Some(p) => p,
        None => (0..m)
            .into_par_iter()
            .map(|j| {
                let tau = tau_lo + j as f64 * step;
                let ph: Vec<c64> = freqs
                    .iter()
                    .map(|f| c64::from_polar(1.0, std::f64::consts::TAU * f * tau))
                    .collect();
                let (sr, si) = lag_sums(&re, &im, &ph, n_frf);
                sr.iter().zip(&si).map(|(r, i)| r * r + i * i).sum()
            })
            .collect(),
    };
    let dp: Vec<f64> = (0..m)
        .map(|j| p[(j + 1).min(m - 1)] - p[j.saturating_sub(1)])
        .collect();
    let mut picks: Vec<(f64, f64)> = Vec::new();
    for series in [&dp, &p] {
        let mut maxima: Vec<(f64, f64)> = (1..m.saturating_sub(1))
            .filter(|&j| series[j] > series[j - 1] && series[j] >= series[j + 1])
            .map(|j| {
                // Parabola through the three samples around the maximum.
                let (a, b, c) = (series[j - 1], series[j], series[j + 1]);
                let den = a - 2.0 * b + c;
                let off = if den < 0.0 { 0.5 * (a - c) / den } else { 0.0 };
                (b, tau_lo + (j as f64 + off) * step)
            })
            .collect();
        maxima.sort_by(|x, y| y.0.total_cmp(&x.0));
        for (_, tau) in maxima.into_iter().take(n.div_ceil(2)) {
            if picks.iter().all(|q| (q.1 - tau).abs() > 1.0 / band) {
                picks.push((0.0, tau));
            }
        }
    }
    let independent = ((tau_hi - tau_lo) * band).ceil() as usize;
    (
        picks.into_iter().map(|q| q.1).take(n).collect(),
        independent,
    )
}

/// `P(τ_j) = Σ_b |Σ_k x_bk e^{i2πf_kτ_j}|²` at the lags `τ_j = τ_lo + j/(4B)`, j < m, by
/// one FFT per FRF, when the lines are equally spaced (`None` otherwise).
///
/// With `f_k = f_0 + kΔf` and `B = (n_l − 1)Δf`, `f_kτ_j = f_0τ_j + kΔfτ_lo + kj/N` with
/// `N = 4(n_l − 1)`: the sum is `e^{i2πf_0τ_j}` (which |·|² drops) times the inverse DFT
/// of length N of `x_bk e^{i2πkΔfτ_lo}` at j (zero-padded; periodic in j, so m > N wraps
/// as the direct sum does). The direct sum over 3 800 lags × 1 000 lines × 54 FRFs was
/// 0.4 s per screening step; this is a few milliseconds, equal to rounding
/// (`lag_power_by_fft_is_the_direct_sum`).
fn lag_power_by_fft(
    re: &[f64],
    im: &[f64],
    freqs: &[f64],
    n_frf: usize,
    tau_lo: f64,
    m: usize,
) -> Option<Vec<f64>> {
    use rbprops_core::c64;
    let nl = freqs.len();
    let df = (freqs[nl - 1] - freqs[0]) / (nl - 1) as f64;
    let uniform = freqs
        .iter()
        .enumerate()
        .all(|(k, f)| (f - (freqs[0] + k as f64 * df)).abs() <= 1e-9 * df.abs().max(f.abs()));
    if !uniform || df <= 0.0 || n_frf == 0 {
        return None;
    }
    let n = 4 * (nl - 1);
    let fft = rustfft::FftPlanner::<f64>::new().plan_fft_inverse(n);
    let shift: Vec<c64> = (0..nl)
        .map(|k| c64::from_polar(1.0, std::f64::consts::TAU * k as f64 * df * tau_lo))
        .collect();
    let mut p = vec![0.0; m];
    let mut buf = vec![c64::new(0.0, 0.0); n];
    for b in 0..n_frf {
        buf.iter_mut().for_each(|z| *z = c64::new(0.0, 0.0));
        for (k, s) in shift.iter().enumerate() {
            buf[k] = c64::new(re[k * n_frf + b], im[k * n_frf + b]) * s;
        }
        fft.process(&mut buf);
        for (j, pj) in p.iter_mut().enumerate() {
            *pj += buf[j % n].norm_sqr();
        }
    }
    Some(p)
}

rbprops_core::avx_fn! {
    /// Per FRF b, `Σ_k x_bk e_k` (the residual's lag transform at one lag; `x`
    /// line-major, `re`/`im` at `k n_frf + b`), each sum in line order from zero with
    /// `num_complex`'s product (`re = xr er − xi ei`, `im = xr ei + xi er`): bit for bit
    /// the sums of the complex values one FRF at a time, with the FRFs innermost so the
    /// loop is a vector loop.
    fn lag_sums(
        re: &[f64],
        im: &[f64],
        ph: &[rbprops_core::c64],
        n_frf: usize,
    ) -> (Vec<f64>, Vec<f64>) {
        let (mut sr, mut si) = (vec![0.0; n_frf], vec![0.0; n_frf]);
        if n_frf == 0 {
            return (sr, si);
        }
        for ((xr, xi), e) in re.chunks_exact(n_frf).zip(im.chunks_exact(n_frf)).zip(ph) {
            for (((sr, si), xr), xi) in sr.iter_mut().zip(si.iter_mut()).zip(xr).zip(xi) {
                *sr += xr * e.re - xi * e.im;
                *si += xr * e.im + xi * e.re;
            }
        }
        (sr, si)
    }
}

#[cfg(test)]
mod lag_tests {
    use super::{delay_peaks, lag_sums};
    use rbprops_core::c64;

    /// A deterministic stream in [−1, 1) (xorshift64*).
    fn uniform(state: &mut u64) -> f64 {
        *state ^= *state >> 12;
        *state ^= *state << 25;
        *state ^= *state >> 27;
        (state.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    /// The lag power by FFT equals the direct sums over the lines to rounding, on an
    /// axis that does not start at 0 Hz and over more lags than one period.
    #[test]
    fn lag_power_by_fft_is_the_direct_sum() {
        let (n_frf, nl) = (5, 37);
        let freqs: Vec<f64> = (0..nl).map(|k| 0.25 + 0.125 * k as f64).collect();
        let mut st = 11u64;
        let (mut re, mut im) = (vec![0.0; n_frf * nl], vec![0.0; n_frf * nl]);
        for v in re.iter_mut().chain(im.iter_mut()) {
            *v = uniform(&mut st);
        }
        let band = freqs[nl - 1] - freqs[0];
        let (tau_lo, step) = (0.3, 1.0 / (4.0 * band));
        let m = 4 * (nl - 1) + 17;
        let p = super::lag_power_by_fft(&re, &im, &freqs, n_frf, tau_lo, m).expect("uniform");
        let scale = p.iter().fold(0.0f64, |a, &b| a.max(b));
        for (j, pj) in p.iter().enumerate() {
            let tau = tau_lo + j as f64 * step;
            let direct: f64 = (0..n_frf)
                .map(|b| {
                    (0..nl)
                        .map(|k| {
                            c64::new(re[k * n_frf + b], im[k * n_frf + b])
                                * c64::from_polar(1.0, std::f64::consts::TAU * freqs[k] * tau)
                        })
                        .sum::<c64>()
                        .norm_sqr()
                })
                .sum();
            assert!(
                (pj - direct).abs() <= 1e-12 * scale,
                "lag {j}: {pj} vs {direct}"
            );
        }
        let mut bent = freqs.clone();
        bent[3] += 0.01;
        assert!(super::lag_power_by_fft(&re, &im, &bent, n_frf, tau_lo, m).is_none());
    }

    /// The FRFs-innermost sums are the complex sums taken one FRF at a time, bit for bit
    /// (an odd number of FRFs, so the vector loop has a remainder).
    #[test]
    fn lag_sums_are_the_per_frf_complex_sums_bit_for_bit() {
        let (n_frf, nl) = (27, 101);
        let mut st = 7u64;
        let x: Vec<c64> = (0..n_frf * nl)
            .map(|_| c64::new(uniform(&mut st), uniform(&mut st)))
            .collect(); // [frf][line]
        let ph: Vec<c64> = (0..nl)
            .map(|k| c64::from_polar(1.0, 0.37 * k as f64))
            .collect();
        let mut re = vec![0.0; n_frf * nl];
        let mut im = vec![0.0; n_frf * nl];
        for b in 0..n_frf {
            for k in 0..nl {
                re[k * n_frf + b] = x[b * nl + k].re;
                im[k * n_frf + b] = x[b * nl + k].im;
            }
        }
        let (sr, si) = lag_sums(&re, &im, &ph, n_frf);
        for b in 0..n_frf {
            let s: c64 = x[b * nl..(b + 1) * nl]
                .iter()
                .zip(&ph)
                .map(|(x, e)| x * e)
                .sum();
            assert_eq!(
                (sr[b].to_bits(), si[b].to_bits()),
                (s.re.to_bits(), s.im.to_bits()),
                "FRF {b}"
            );
        }
    }

    /// A residual that is an echo delayed by T (`e^{−i2πfT}` times a smooth amplitude, as
    /// a truncated record leaves) is found at T, within a resolution cell 1/B.
    #[test]
    fn an_echo_is_found_at_its_delay() {
        let nl = 400;
        let freqs: Vec<f64> = (0..nl).map(|k| 1.0 + 0.25 * k as f64).collect();
        let t = 1.3;
        let rows: Vec<(usize, usize, c64)> = (0..3)
            .flat_map(|b| {
                freqs.iter().enumerate().map(move |(k, f)| {
                    let a = 1.0 + 0.3 * b as f64 + 0.001 * f;
                    (b, k, c64::from_polar(a, -std::f64::consts::TAU * f * t))
                })
            })
            .collect();
        let band = freqs[nl - 1] - freqs[0];
        let (taus, m) = delay_peaks(&rows, &freqs, 0.1, 3.8, 4);
        assert!(
            taus.iter().any(|tau| (tau - t).abs() < 1.0 / band),
            "{taus:?}"
        );
        assert_eq!(m, ((3.8 - 0.1) * band).ceil() as usize);
    }
}
