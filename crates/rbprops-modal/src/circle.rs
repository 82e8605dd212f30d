//! Kennedy–Pancu circle fit, SDOF per mode and channel (Ewins, *Modal Testing*, §4.3).
//!
//! Near a lightly damped mode the mobility `Y = iωA/(ω_r² − ω² + 2iζω_rω)` traces a
//! circle of diameter `A/(2ζω_r)` through the origin. With the angle `ψ` of a point
//! about the circle's centre, measured from the resonance diameter,
//! `tan(ψ/2) = (ω_r² − ω²)/(2ζω_rω)`, i.e. `ω tan(ψ/2) = a − bω²` with
//! `a = ω_r/(2ζ)`, `b = 1/(2ζω_r)`: a linear least-squares problem giving
//! `ω_r² = a/b` and `ζ = 1/(2√(ab))`. The circle itself is fitted algebraically (Kåsa),
//! and the modal constant is `A = 2ζω_r · 2r e^{iφ_0}` (`r` radius, `φ_0` the
//! resonance direction).
//!
//! The neighbours' contributions are subtracted with their *own* circle-fit models,
//! iterated a few sweeps, so the fit stays independent of LSCF/LSFD (LSCF only locates
//! the modes). Each mode uses the lines within ±2 half-power half-bandwidths. The SDOF
//! assumption fails when another mode lies within a few half-power bandwidths: the
//! window then holds both modes, the subtraction feeds each mode's error into the
//! other, and a warning is raised.

use crate::band::BandData;
use crate::pole::Pole;
use rbprops_core::c64;
use std::f64::consts::PI;

/// One mode's circle-fit estimate.
#[derive(Debug, Clone)]
pub struct CircleMode {
    /// The mode's pole (natural frequency and damping ratio).
    pub pole: Pole,
    /// Standard deviation of (f Hz, ζ) from the scatter of the per-channel estimates.
    pub std: (f64, f64),
    /// Modal constants `A` per channel (1/kg).
    pub modal_constants: Vec<c64>,
    /// From the scatter of the points about the fitted circle.
    pub modal_constant_std: Vec<f64>,
    /// This mode's warnings (fit failed, neighbour too close, …).
    pub warnings: Vec<String>,
}

/// Circle fits of every mode of one excitation (Kennedy–Pancu), with the FRFs they synthesise.
#[derive(Debug, Clone)]
pub struct CircleFit {
    /// The modes, ascending frequency.
    pub modes: Vec<CircleMode>,
    /// One line per mode whose circle fit failed or is expected to fail.
    pub warnings: Vec<String>,
    /// Sum of the SDOF models, measured quantity, `[channel][line]`.
    pub synthesised: Vec<Vec<c64>>,
}

/// Per-channel circle estimate.
#[derive(Debug, Clone, Copy)]
struct Circ {
    wr: f64,
    zeta: f64,
    radius: f64,
    phi0: f64,
    rms_dev: f64,
    ok: bool,
}

/// Algebraic (Kåsa) circle through points: minimises Σ(x² + y² + Dx + Ey + F)².
fn kasa(pts: &[c64]) -> Option<(c64, f64, f64)> {
    // Centre the data for conditioning.
    let n = pts.len() as f64;
    let mean: c64 = pts.iter().sum::<c64>() / n;
    let scale = pts.iter().map(|p| (p - mean).norm()).fold(0.0, f64::max);
    if !(scale > 0.0) {
        return None;
    }
    let q: Vec<c64> = pts.iter().map(|p| (p - mean) / scale).collect();
    let mut m = [[0.0f64; 3]; 3];
    let mut v = [0.0f64; 3];
    for p in &q {
        let row = [p.re, p.im, 1.0];
        let rhs = -(p.re * p.re + p.im * p.im);
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] += row[i] * row[j];
            }
            v[i] += row[i] * rhs;
        }
    }
    let mm = nalgebra::Matrix3::from_fn(|i, j| m[i][j]);
    let sol = mm.lu().solve(&nalgebra::Vector3::new(v[0], v[1], v[2]))?;
    let c = c64::new(-sol[0] / 2.0, -sol[1] / 2.0);
    let r2 = c.norm_sqr() - sol[2];
    if !(r2 > 0.0) {
        return None;
    }
    let r = r2.sqrt();
    let dev = (q.iter().map(|p| ((p - c).norm() - r).powi(2)).sum::<f64>() / n).sqrt();
    Some((c * scale + mean, r * scale, dev * scale))
}

fn wrap(a: f64) -> f64 {
    let mut x = a % (2.0 * PI);
    if x > PI {
        x -= 2.0 * PI;
    }
    if x <= -PI {
        x += 2.0 * PI;
    }
    x
}

/// Circle fit of one channel's mobility points `y` at `w` around a first guess `wr0`.
fn fit_channel(w: &[f64], y: &[c64], wr0: f64, zeta0: f64) -> Option<Circ> {
    let (centre, radius, rms_dev) = kasa(y)?;
    let ang: Vec<f64> = y.iter().map(|p| (p - centre).arg()).collect();
    // Unwrap along frequency (the points sweep clockwise once around the circle).
    let mut un = vec![ang[0]];
    for k in 1..ang.len() {
        let prev = *un.last().unwrap();
        un.push(prev + wrap(ang[k] - ang[k - 1]));
    }
    // Gauss–Newton on the angle residuals r_k = θ_k − φ0 − 2 atan(x_k),
    // x_k = (a − bω̂_k²)/ω̂_k (ω̂ = ω/ω_0 for conditioning), from the first guess
    // (ω_r = ω_0, ζ = ζ_0, φ0 = angle at ω_0). Three unknowns, well conditioned over a
    // window of a few bandwidths (unlike the linearised relaxations of this relation).
    let k0 = w.partition_point(|&x| x < wr0).clamp(1, w.len() - 1);
    let t0 = ((wr0 - w[k0 - 1]) / (w[k0] - w[k0 - 1])).clamp(0.0, 1.0);
    let mut phi0 = un[k0 - 1] + t0 * (un[k0] - un[k0 - 1]);
    let x: Vec<f64> = w.iter().map(|wk| wk / wr0).collect();
    let (mut a, mut b) = (1.0 / (2.0 * zeta0), 1.0 / (2.0 * zeta0));
    let cost = |a: f64, b: f64, phi0: f64| -> f64 {
        x.iter()
            .zip(&un)
            .map(|(xk, th)| (th - phi0 - 2.0 * ((a - b * xk * xk) / xk).atan()).powi(2))
            .sum()
    };
    let mut c = cost(a, b, phi0);
    for _ in 0..50 {
        let mut jtj = nalgebra::Matrix3::<f64>::zeros();
        let mut jtr = nalgebra::Vector3::<f64>::zeros();
        for (xk, th) in x.iter().zip(&un) {
            let xx = (a - b * xk * xk) / xk;
            let r = th - phi0 - 2.0 * xx.atan();
            let g = -2.0 / (1.0 + xx * xx);
            let jrow = nalgebra::Vector3::new(g / xk, -g * xk, -1.0);
            jtj += jrow * jrow.transpose();
            jtr += jrow * r;
        }
        let step = jtj.lu().solve(&(-jtr))?;
        let mut lam = 1.0;
        let mut improved = false;
        for _ in 0..20 {
            let (a2, b2, p2) = (a + lam * step[0], b + lam * step[1], phi0 + lam * step[2]);
            let c2 = cost(a2, b2, p2);
            if a2 > 0.0 && b2 > 0.0 && c2 <= c {
                improved = c - c2 > 1e-15 * c.max(1e-300);
                (a, b, phi0, c) = (a2, b2, p2, c2);
                break;
            }
            lam *= 0.5;
        }
        if !improved {
            break;
        }
    }
    if !(a > 0.0 && b > 0.0 && a.is_finite() && b.is_finite()) {
        return None;
    }
    let wr = wr0 * (a / b).sqrt();
    let zeta = 1.0 / (2.0 * (a * b).sqrt());
    Some(Circ {
        wr,
        zeta,
        radius,
        phi0,
        rms_dev,
        // A channel votes only when its circle is a clean SDOF circle near the guess:
        // points on the circle (rms deviation < 5 % of the radius), resonance inside the
        // window, damping below 0.5.
        ok: wr.is_finite()
            && zeta.is_finite()
            && zeta > 0.0
            && zeta < 0.5
            && (wr - wr0).abs() < (w[w.len() - 1] - w[0])
            && rms_dev < 0.05 * radius,
    })
}

/// Mobility of an SDOF mode with modal constant `a`.
fn sdof_mobility(wr: f64, zeta: f64, a: c64, w: f64) -> c64 {
    c64::new(0.0, w) * a / c64::new(wr * wr - w * w, 2.0 * zeta * wr * w)
}

/// A mode's current SDOF model: `(ω_r, ζ, A per channel)`.
type SdofModel = (f64, f64, Vec<c64>);

/// Circle-fits every mode located by `poles` (ascending) on every channel of `band`.
pub fn fit(band: &BandData, poles: &[Pole], min_separation: f64) -> CircleFit {
    let no = band.channels.len();
    let mob = mobilities(band);
    let nm = poles.len();
    let mut warnings = Vec::new();
    let mut mode_warn = separation_warnings(poles, min_separation);
    let mut model: Vec<Option<SdofModel>> = vec![None; nm];
    let mut per_channel: Vec<Vec<Option<Circ>>> = vec![vec![None; no]; nm];
    for _sweep in 0..6 {
        for m in 0..nm {
            let (wr0, z0) = match &model[m] {
                Some((w, z, _)) => (*w, *z),
                None => (poles[m].omega_n(), poles[m].damping()),
            };
            let idx = window_lines(band, wr0, z0);
            if idx.len() < 4 {
                if model[m].is_none() {
                    mode_warn[m].push(format!(
                        "only {} lines near {:.4} Hz: too few for a circle",
                        idx.len(),
                        wr0 / (2.0 * PI)
                    ));
                }
                continue;
            }
            let fits = fit_channels_without_neighbours(band, &mob, &model, m, &idx, (wr0, z0));
            if let Some(consensus) = consensus_model(&fits) {
                model[m] = Some(consensus);
                per_channel[m] = fits;
            }
        }
    }
    let mut modes = Vec::with_capacity(nm);
    for m in 0..nm {
        match &model[m] {
            Some(sdof) => modes.push(fitted_mode(sdof, &per_channel[m], mode_warn[m].clone())),
            None => {
                let mut w = mode_warn[m].clone();
                w.push(
                    "circle fit failed on every channel; LSCF pole reported with zero residues"
                        .into(),
                );
                warnings.push(format!(
                    "mode {} ({:.4} Hz): circle fit failed on every channel",
                    m + 1,
                    poles[m].frequency_hz()
                ));
                modes.push(CircleMode {
                    pole: poles[m],
                    std: (0.0, 0.0),
                    modal_constants: vec![c64::new(0.0, 0.0); no],
                    modal_constant_std: vec![0.0; no],
                    warnings: w,
                });
            }
        }
    }
    for (m, mw) in mode_warn.iter().enumerate() {
        if mw
            .iter()
            .any(|w| w.starts_with("circle fit expected to fail"))
        {
            warnings.push(format!(
                "mode {} ({:.4} Hz): circle fit expected to fail, a neighbouring mode is within {min_separation} half-power bandwidths",
                m + 1,
                poles[m].frequency_hz()
            ));
        }
    }
    let synthesised = synthesise(band, &modes);
    CircleFit {
        modes,
        warnings,
        synthesised,
    }
}

/// The band's channels as mobility, `[channel][line]`: the measured quantity times
/// `(iω)^{1−k}`.
fn mobilities(band: &BandData) -> Vec<Vec<c64>> {
    let k = band.quantity.order();
    let to_mob: Vec<c64> = band
        .omega
        .iter()
        .map(|&w| c64::new(0.0, w).powi(1 - k))
        .collect();
    band.channels
        .iter()
        .map(|h| h.iter().zip(&to_mob).map(|(a, b)| a * b).collect())
        .collect()
}

/// Per mode, a warning for every other mode closer than `min_separation` half-power
/// bandwidths: there the SDOF assumption of the circle fit is expected to fail.
fn separation_warnings(poles: &[Pole], min_separation: f64) -> Vec<Vec<String>> {
    let nm = poles.len();
    let mut mode_warn = vec![Vec::new(); nm];
    for m in 0..nm {
        for j in 0..nm {
            if j == m {
                continue;
            }
            let bw = 2.0 * poles[m].half_bandwidth();
            let sep = (poles[j].omega_d() - poles[m].omega_d()).abs() / bw;
            if sep < min_separation {
                mode_warn[m].push(format!(
                    "circle fit expected to fail: mode at {:.4} Hz is only {sep:.2} half-power bandwidths away (SDOF needs ≥ {min_separation})",
                    poles[j].frequency_hz()
                ));
            }
        }
    }
    mode_warn
}

/// Lines of the fitting window around `wr0`: within ±2 half-power half-bandwidths,
/// widened until at least 6 lines (or half of `wr0`).
fn window_lines(band: &BandData, wr0: f64, z0: f64) -> Vec<usize> {
    let nl = band.n_lines();
    let mut half = 2.0 * z0 * wr0;
    loop {
        let idx: Vec<usize> = (0..nl)
            .filter(|&l| (band.omega[l] - wr0).abs() <= half && band.omega[l] > 0.0)
            .collect();
        if idx.len() >= 6 || half > 0.5 * wr0 {
            return idx;
        }
        half *= 1.5;
    }
}

/// Circle fit of mode `m` on every channel over the window lines `idx`, after
/// subtracting the current SDOF models of all the other modes; `guess` is `(ω_r, ζ)`.
fn fit_channels_without_neighbours(
    band: &BandData,
    mob: &[Vec<c64>],
    model: &[Option<SdofModel>],
    m: usize,
    idx: &[usize],
    guess: (f64, f64),
) -> Vec<Option<Circ>> {
    let w: Vec<f64> = idx.iter().map(|&l| band.omega[l]).collect();
    let mut fits = Vec::with_capacity(mob.len());
    for (o, mob_o) in mob.iter().enumerate() {
        let y: Vec<c64> = idx
            .iter()
            .map(|&l| {
                let mut v = mob_o[l];
                for (j, mj) in model.iter().enumerate() {
                    if j != m {
                        if let Some((wj, zj, aj)) = mj {
                            v -= sdof_mobility(*wj, *zj, aj[o], band.omega[l]);
                        }
                    }
                }
                v
            })
            .collect();
        fits.push(fit_channel(&w, &y, guess.0, guess.1));
    }
    fits
}

/// The channels that vote: clean circles (`ok`) not tiny (radius above 1e-3 of the
/// largest clean one).
fn voters<'a>(fits: impl Iterator<Item = &'a Circ> + Clone) -> Vec<&'a Circ> {
    let rmax = fits
        .clone()
        .filter(|c| c.ok)
        .map(|c| c.radius)
        .fold(0.0, f64::max);
    fits.filter(|c| c.ok && c.radius > 1e-3 * rmax).collect()
}

/// Consensus SDOF model of one mode from its per-channel circles: `ω_r` and `ζ`
/// weighted by the squared diameter (large circles are the reliable ones), and each
/// clean channel's modal constant `A = 2ζω_r · 2r e^{iφ_0}`. `None` when no channel votes.
fn consensus_model(fits: &[Option<Circ>]) -> Option<SdofModel> {
    let voters = voters(fits.iter().flatten());
    if voters.is_empty() {
        return None;
    }
    let wsum: f64 = voters.iter().map(|c| c.radius * c.radius).sum();
    let wr = voters
        .iter()
        .map(|c| c.wr * c.radius * c.radius)
        .sum::<f64>()
        / wsum;
    let zeta = voters
        .iter()
        .map(|c| c.zeta * c.radius * c.radius)
        .sum::<f64>()
        / wsum;
    let a: Vec<c64> = fits
        .iter()
        .map(|c| match c {
            Some(c) if c.ok => c64::from_polar(2.0 * zeta * wr * 2.0 * c.radius, c.phi0),
            _ => c64::new(0.0, 0.0),
        })
        .collect();
    Some((wr, zeta, a))
}

/// A fitted mode: its pole from the consensus model, the standard deviation of
/// `(f, ζ)` from the weighted scatter of the voting channels, and each modal
/// constant's uncertainty from the scatter of the points about its circle.
fn fitted_mode(sdof: &SdofModel, fits: &[Option<Circ>], warnings: Vec<String>) -> CircleMode {
    let (wr, zeta, a) = (sdof.0, sdof.1, &sdof.2);
    let voters = voters(fits.iter().flatten());
    let wsum: f64 = voters.iter().map(|c| c.radius * c.radius).sum();
    let nv = voters.len().max(1) as f64;
    let vw = voters
        .iter()
        .map(|c| c.radius * c.radius * (c.wr - wr).powi(2))
        .sum::<f64>()
        / wsum;
    let vz = voters
        .iter()
        .map(|c| c.radius * c.radius * (c.zeta - zeta).powi(2))
        .sum::<f64>()
        / wsum;
    let a_std = fits
        .iter()
        .map(|c| match c {
            Some(c) if c.ok => 2.0 * zeta * wr * 2.0 * c.rms_dev,
            _ => 0.0,
        })
        .collect();
    let wd = wr * (1.0 - zeta * zeta).max(0.0).sqrt();
    CircleMode {
        pole: Pole(c64::new(-zeta * wr, wd)),
        std: ((vw / nv).sqrt() / (2.0 * PI), (vz / nv).sqrt()),
        modal_constants: a.clone(),
        modal_constant_std: a_std,
        warnings,
    }
}

/// Sum of the SDOF models in the measured quantity, `[channel][line]`: receptance
/// `A/(ω_r² − ω² + 2iζω_rω)` times `(iω)^k`.
fn synthesise(band: &BandData, modes: &[CircleMode]) -> Vec<Vec<c64>> {
    let q = band.quantity_factor();
    (0..band.channels.len())
        .map(|o| {
            (0..band.n_lines())
                .map(|l| {
                    let w = band.omega[l];
                    modes
                        .iter()
                        .map(|md| {
                            let (wr, z) = (md.pole.omega_n(), md.pole.damping());
                            md.modal_constants[o] / c64::new(wr * wr - w * w, 2.0 * z * wr * w)
                        })
                        .sum::<c64>()
                        * q[l]
                })
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn single_channel_sdof_circle_is_exact() {
        let (wr, z) = (2.0 * PI * 1.3, 0.015);
        for a in [c64::new(0.7, 0.0), c64::new(-0.2, 0.05)] {
            let w: Vec<f64> = (0..25)
                .map(|k| wr * (1.0 - 2.0 * z + 4.0 * z * k as f64 / 24.0))
                .collect();
            let y: Vec<c64> = w
                .iter()
                .map(|&x| sdof_mobility(wr, z, a, x) + c64::new(0.01, -0.02))
                .collect();
            let c = fit_channel(&w, &y, wr * 1.001, 0.012).unwrap();
            assert!((c.wr - wr).abs() < 1e-9 * wr, "{} vs {wr}", c.wr);
            assert!((c.zeta - z).abs() < 1e-9, "{} vs {z}", c.zeta);
            let a_est = c64::from_polar(2.0 * c.zeta * c.wr * 2.0 * c.radius, c.phi0);
            assert!((a_est - a).norm() < 1e-6 * a.norm(), "{a_est} vs {a}");
        }
    }
}
