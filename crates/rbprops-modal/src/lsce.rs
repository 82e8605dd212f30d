//! Least-squares complex exponential (LSCE; Brown et al. 1979), MDOF, poles shared by
//! all channels.
//!
//! Impulse responses are the inverse DFT of the FRFs on `0, df, …, f_max` (Hermitian
//! extension, `L = 2(N−1)` samples, `Δt = 1/(L df)`). Each channel's response is a sum of
//! damped exponentials `h[t] = Σ_r c_r z_r^t`, `z_r = e^{λ_rΔt}`, so it obeys the linear
//! prediction `h[t+n] + Σ_{j<n} a_j h[t+j] = 0`; the real coefficients `a_j` are fitted in
//! least squares over all channels and samples, and the poles are the roots of
//! `z^n + Σ a_j z^j`.
//!
//! Limits (documented, tested): it needs a uniform axis that starts at 0 Hz — it cannot
//! fit a zoom band or a non-uniform axis (an `Axis` error says so). The FRF truncated at
//! `f_max` is not the DFT of the sampled impulse response (the aliased tail is missing),
//! which in principle biases the poles; on noise-free rigid-body baseband data the
//! over-modelled sweep absorbs it (measured frequency error ~1e-13 without refinement),
//! so in practice the axis requirement and the O(N·T) inverse DFT are the limits. Only
//! the first 2,048 impulse-response samples are used.

use crate::band::BandData;
use crate::linalg::{self, TallQr};
use crate::lscf::OrderPoles;
use crate::lsfd::{self, Residuals};
use crate::pole::Pole;
use faer::Mat;
use rbprops_core::c64;

/// Largest number of impulse-response samples used (the first half of the record).
const MAX_SAMPLES: usize = 2048;

/// Checks the axis LSCE needs and returns `df`.
pub fn check_axis(band: &BandData) -> Result<f64, String> {
    let f = &band.frequency_hz;
    if f[0] != 0.0 {
        return Err(format!(
            "LSCE needs a baseband axis starting at 0 Hz (the inverse DFT gives impulse responses only then); this band starts at {} Hz. Use LSCF for zoom bands",
            f[0]
        ));
    }
    if f.len() < 8 {
        return Err(format!(
            "{} lines are too few for an impulse response",
            f.len()
        ));
    }
    let df = f[1] - f[0];
    if let Some((l, w)) = f
        .windows(2)
        .enumerate()
        .find(|(_, w)| ((w[1] - w[0]) - df).abs() > 1e-6 * df)
    {
        return Err(format!(
            "LSCE needs a uniform frequency axis; spacing changes at line {} ({} Hz → {} Hz, expected step {df} Hz)",
            l + 1,
            w[0],
            w[1]
        ));
    }
    Ok(df)
}

/// First `t_len` samples of the impulse response of one FRF (uniform axis from 0 Hz).
pub fn impulse_response(h: &[c64], t_len: usize) -> Vec<f64> {
    let n = h.len();
    let l = 2 * (n - 1);
    let table: Vec<c64> = (0..l)
        .map(|j| {
            let a = 2.0 * std::f64::consts::PI * j as f64 / l as f64;
            c64::new(a.cos(), a.sin())
        })
        .collect();
    (0..t_len)
        .map(|t| {
            let mut s = h[0].re + h[n - 1].re * if t % 2 == 0 { 1.0 } else { -1.0 };
            for (k, hk) in h.iter().enumerate().take(n - 1).skip(1) {
                s += 2.0 * (hk * table[(k * t) % l]).re;
            }
            s / l as f64
        })
        .collect()
}

/// LSCE stabilisation sweep: poles for every order `2..=n_max`, with shapes from a
/// frequency-domain residue fit at each order.
pub fn sweep(band: &BandData, chans: &[Vec<c64>], n_max: usize) -> Result<Vec<OrderPoles>, String> {
    let df = check_axis(band)?;
    let n = band.n_lines();
    let dt = 1.0 / (2.0 * (n - 1) as f64 * df);
    let t_len = (n - 1).min(MAX_SAMPLES);
    // Skip t = 0: a non-strictly-proper FRF (mobility, accelerance) puts an impulse there.
    let skip = 1;
    if t_len < skip + n_max + 2 * n_max {
        return Err(format!(
            "{t_len} impulse-response samples are too few for model order {n_max}"
        ));
    }
    let irfs: Vec<Vec<f64>> = chans
        .iter()
        .map(|h| {
            let x = impulse_response(h, t_len);
            let rms = (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
            x.iter().map(|v| v / rms.max(f64::MIN_POSITIVE)).collect()
        })
        .collect();
    let rows_per = t_len - skip - n_max;
    let a = Mat::from_fn(rows_per * irfs.len(), n_max + 1, |i, j| {
        let (o, t) = (i / rows_per, i % rows_per);
        irfs[o][skip + t + j]
    });
    // One QR of the full Hankel stack serves every order: the LS problem of order n uses
    // the leading columns, whose R factor is the leading block.
    let qr = TallQr::new(a);
    let mut out = Vec::new();
    for order in 2..=n_max {
        let lhs = Mat::from_fn(order, order, |i, j| qr.r(i, j));
        let rhs = Mat::from_fn(order, 1, |i, _| -qr.r(i, order));
        let Some(coef) = linalg::solve_square(&lhs, &rhs) else {
            continue;
        };
        let c: Vec<f64> = (0..order).map(|j| coef[(j, 0)]).collect();
        let Some(roots) = linalg::polynomial_roots(&c) else {
            continue;
        };
        let poles: Vec<Pole> = roots
            .iter()
            .filter(|z| z.im > 0.0 && z.norm() > 0.0)
            .map(|z| Pole(z.ln() / dt))
            .collect();
        let phys: Vec<usize> = (0..poles.len()).filter(|&i| poles[i].0.re < 0.0).collect();
        let mut shapes = vec![vec![c64::new(0.0, 0.0); chans.len()]; poles.len()];
        if !phys.is_empty() && 2 * n > 2 * phys.len() + 2 {
            let pp: Vec<Pole> = phys.iter().map(|&i| poles[i]).collect();
            let rf = lsfd::fit_residues(
                &pp,
                band,
                chans,
                Residuals {
                    upper: false,
                    lower: false,
                },
            );
            for (k, &i) in phys.iter().enumerate() {
                shapes[i] = rf.residues[k].clone();
            }
        }
        out.push(OrderPoles {
            order,
            poles,
            shapes,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn impulse_response_of_a_sampled_exponential() {
        // h[t] = z^t + conj: its DFT over a long record is (nearly) exactly
        // H_k = 1/(1 − z e^{−iθ_k}) + conj-pole term; the inverse must give z^t back.
        let n = 513;
        let l = 2 * (n - 1);
        let z = c64::new(0.97 * 0.3f64.cos(), 0.97 * 0.3f64.sin());
        let h: Vec<c64> = (0..n)
            .map(|k| {
                let th = 2.0 * std::f64::consts::PI * k as f64 / l as f64;
                let e = c64::new(th.cos(), -th.sin());
                let zl = z.powi(l as i32);
                (1.0 - zl) / (1.0 - z * e) + (1.0 - zl.conj()) / (1.0 - z.conj() * e)
            })
            .collect();
        let x = impulse_response(&h, 40);
        for (t, v) in x.iter().enumerate() {
            let expect = 2.0 * z.powi(t as i32).re;
            assert!((v - expect).abs() < 1e-12, "t={t}: {v} vs {expect}");
        }
    }
}
