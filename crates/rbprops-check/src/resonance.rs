//! Resonances inside the band that the rigid-body model lacks: an elastic mode of the
//! article or of its fixture (catalogue `elastic_mode`, docs/physics.md, E13 when the mode
//! sits in the band rather than above it).
//!
//! The catalogue's form `ψ_c ψ_e / (ω_m² − ω² + 2iζ_m ω_m ω)` is bilinear in the
//! shapes, so at its neutral point (ψ = 0) neither the shapes nor (ω_m, ζ_m) have a
//! first-order signature and a score test sees nothing; (ω_m, ζ_m) also enter
//! non-linearly, on the scale of the mode's half-bandwidth. So the check fits it as
//! `InBandResonance` (the effect's screening form, in rbprops-sim's `elastic` module):
//! one pole with a free real residue `A_ce` per channel and
//! excitation (linear in `A`, no scale gauge between ψ_c and ψ_e, and general enough for
//! a resonance local to one sensor mount), screened by a profile over (ω_m, ζ_m)
//! ([`profile_starts`], over the band's lines and a few frequencies above it, where a
//! mode is seen only through its smooth tail). The improved spec receives the rank-1 catalogue form
//! `A ≈ σ₁ u vᵀ`, `ψ_c = √σ₁ u_c`, `ψ_e = √σ₁ v_e`.

use crate::predict::Layout;
use nalgebra::DMatrix;
use rayon::prelude::*;
use rbprops_core::c64;
use std::f64::consts::TAU;

/// Damping ratios of the (ω_m, ζ_m) profile: light structural damping to a
/// rubber-mounted fixture, a factor of about two apart (the profile in ζ is broad on
/// that scale).
const PROFILE_DAMPING: [f64; 6] = [0.002, 0.005, 0.01, 0.02, 0.04, 0.08];
/// Profile frequencies per batch of [`profile_starts`] (× 6 damping ratios: 96 points,
/// 1.5 MB of line factors at 1 000 lines).
const PROFILE_BATCH: usize = 16;
/// Starting points handed to the profile evaluation (the best separate peaks).
const STARTS: usize = 3;
/// Modes above the band enter the profile at `f_m = f_top/√q` for these `q`: there a
/// mode is a smooth term across the band (its reach to the top grows as q → 1), so a
/// coarse grid in q finds the basin of a mode between 1.05 and 3.5 times the top.
const ABOVE_BAND_Q: [f64; 8] = [0.9, 0.8, 0.65, 0.5, 0.35, 0.25, 0.15, 0.08];

/// The profile's frequencies above the band (empty without lines).
fn above_band(frequency_hz: &[f64]) -> Vec<f64> {
    let top = frequency_hz.iter().copied().fold(0.0, f64::max);
    if !(top > 0.0) {
        return Vec::new();
    }
    ABOVE_BAND_Q.iter().map(|q| top / q.sqrt()).collect()
}

/// Starting points for rbprops-sim's `InBandResonance` (`elastic_mode`'s screening
/// form) from the current normalised residual
/// `r = √2 (y − ŷ)/σ` (re, im interleaved over `used`): for every line frequency f_m of
/// the recording and every ζ_m of `PROFILE_DAMPING`, the residue of each cell is the
/// linear least-squares coefficient of `b = √2 Q(ω)/(σ (ω_m² − ω² + 2iζ_m ω_m ω))`
/// (`Q` the receptance-to-quantity factor), and the χ² it removes is
/// `Σ_cells (bᵀr)²/‖b‖²`. Returns the best `STARTS` points at separate frequencies
/// (more than two half-bandwidths apart) as full parameter vectors, best first, and the
/// number of profile points searched (for the Bonferroni correction).
pub fn profile_starts(
    layout: &Layout,
    used: &[usize],
    sigma: &[f64],
    residual: &[f64],
) -> (Vec<Vec<f64>>, usize) {
    let nl = layout.n_lines();
    let n_rch = layout.channel_map.len();
    let n_cells = n_rch * layout.excitation_map.len();
    let ne = layout.spec_geometry.excitations.len();
    let nc = layout.spec_geometry.channels.len();
    let omega: Vec<f64> = layout.frequency_hz.iter().map(|f| TAU * f).collect();
    let q: Vec<c64> = omega
        .iter()
        .map(|&w| layout.quantity.from_receptance_factor(w))
        .collect();
    let mut f_grid: Vec<f64> = layout
        .frequency_hz
        .iter()
        .copied()
        .filter(|f| *f > 0.0)
        .collect();
    f_grid.extend(above_band(&layout.frequency_hz));
    // Per value, what no profile point changes: with `b = s g(ω)`, `s = √2 Q(ω)/σ` and the
    // line factor `g = 1/(ω_m² − ω² + 2iζ_m ω_m ω)`, `bᵀr = Re(g · s r̄)` and
    // `‖b‖² = |s|² |g|²`: so with `w = s r̄` per value, a cell's `Σ bᵀr` is
    // `Σ_lines (Re g · Re w − Im g · Im w)` and its `Σ ‖b‖²` is `Σ_lines |g|² |s|²`: two
    // matrix products of the points' line factors (points × lines) with the values'
    // (lines × cells; zero where a value is not used), in batches of points.
    let mut w_lines = DMatrix::<f64>::zeros(2 * nl, n_cells);
    let mut s2_lines = DMatrix::<f64>::zeros(nl, n_cells);
    for (k, &i) in used.iter().enumerate() {
        let (line, cell) = (i % nl, i / nl);
        let s = q[line] * (std::f64::consts::SQRT_2 / sigma[i]);
        let w = s * c64::new(residual[2 * k], residual[2 * k + 1]).conj();
        w_lines[(line, cell)] = w.re;
        w_lines[(nl + line, cell)] = w.im;
        s2_lines[(line, cell)] = s.norm_sqr();
    }
    let n_z = PROFILE_DAMPING.len();
    let mut points: Vec<(f64, f64, f64, Vec<f64>)> = f_grid
        .par_chunks(PROFILE_BATCH)
        .flat_map_iter(|fms| {
            let n_pts = fms.len() * n_z;
            let mut g_lines = DMatrix::<f64>::zeros(n_pts, 2 * nl);
            let mut g2_lines = DMatrix::<f64>::zeros(n_pts, nl);
            for (l, &w) in omega.iter().enumerate() {
                for (j, &fm) in fms.iter().enumerate() {
                    let wm = TAU * fm;
                    for (k, &z) in PROFILE_DAMPING.iter().enumerate() {
                        let g = c64::new(wm * wm - w * w, 2.0 * z * wm * w).inv();
                        let pt = j * n_z + k;
                        g_lines[(pt, l)] = g.re;
                        g_lines[(pt, nl + l)] = -g.im;
                        g2_lines[(pt, l)] = g.norm_sqr();
                    }
                }
            }
            let num = g_lines * &w_lines;
            let den = g2_lines * &s2_lines;
            (0..n_pts)
                .map(|pt| {
                    let (fm, z) = (fms[pt / n_z], PROFILE_DAMPING[pt % n_z]);
                    let (num, den) = (num.row(pt), den.row(pt));
                    let drop: f64 = num
                        .iter()
                        .zip(den.iter())
                        .filter(|(_, d)| **d > 0.0)
                        .map(|(n, d)| n * n / d)
                        .sum();
                    let mut a = vec![0.0; nc * ne];
                    for cell in 0..n_cells {
                        if den[cell] > 0.0 {
                            let (re, rc) = (cell / n_rch, cell % n_rch);
                            let (se, sc) = (layout.excitation_map[re], layout.channel_map[rc]);
                            a[sc * ne + se] = num[cell] / den[cell];
                        }
                    }
                    (drop, fm, z, a)
                })
                .collect::<Vec<_>>()
        })
        .collect();
    let n_tests = points.len().max(1);
    points.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.total_cmp(&y.1)));
    let mut starts: Vec<Vec<f64>> = Vec::new();
    let mut taken: Vec<(f64, f64)> = Vec::new();
    for (_, fm, z, a) in points {
        if starts.len() == STARTS {
            break;
        }
        if taken
            .iter()
            .any(|(f, zt)| (fm - f).abs() < 2.0 * zt.max(z) * f)
        {
            continue;
        }
        taken.push((fm, z));
        let mut v = vec![fm, z];
        v.extend(a);
        starts.push(v);
    }
    (starts, n_tests)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rbprops_sim::effects::elastic::InBandResonance;
    use rbprops_sim::effects::{Effect, Reach};
    use rbprops_sim::CampaignSpec;

    /// The declared reach holds: a residue `A_ce` moved, every FRF but that of c and e
    /// is bit for bit what it was (and that one moved); the pole reaches every FRF.
    #[test]
    fn a_residue_reaches_its_own_frf_alone() {
        let mut spec =
            CampaignSpec::from_toml_str(rbprops_sim::example("test-case-2").unwrap()).unwrap();
        spec.frequency.lines = 40;
        let sim = rbprops_sim::simulate(&spec).unwrap();
        let layout = Layout::new(&spec, &sim.geometry, &sim.frf).unwrap();
        let neutral = InBandResonance::neutral(&spec);
        let reach = neutral.parameter_reach(&layout.spec_geometry);
        assert_eq!(reach.len(), neutral.values().len());
        assert_eq!(&reach[..2], &[Reach::Any, Reach::Any]);
        let mut v = neutral.values();
        for (k, x) in v.iter_mut().enumerate().skip(2) {
            *x = 1e-3 * ((k * 7 % 11) as f64 - 5.0);
        }
        let model = |v: &[f64]| {
            crate::predict::predict(&spec, &layout, &[neutral.with_values(v).unwrap()]).unwrap()
        };
        let m0 = model(&v);
        let (nl, n_ch) = (layout.n_lines(), layout.channel_map.len());
        for j in [2, 3, v.len() / 2, v.len() - 1] {
            let mut w = v.clone();
            w[j] += 1e-4;
            let m1 = model(&w);
            for (i, (a, b)) in m0.iter().zip(&m1).enumerate() {
                let (c, e) = (
                    layout.channel_map[(i / nl) % n_ch],
                    layout.excitation_map[i / (nl * n_ch)],
                );
                if !reach[j].reaches(c, e) {
                    assert_eq!(
                        (a.re.to_bits(), a.im.to_bits()),
                        (b.re.to_bits(), b.im.to_bits())
                    );
                } else if i % nl != 0 {
                    assert_ne!(a, b, "parameter {j}, value {i}");
                }
            }
        }
    }

    /// The profile with its line factors taken per line equals the per-value form of its
    /// definition (`b = √2 Q/(σ d)` per value, `Σ (bᵀr)²/‖b‖²` over the cells) to
    /// rounding, at every point, with values left out as the check leaves the 0 Hz line
    /// out; and its best start sits at the resonance planted in the residual.
    #[test]
    fn profile_starts_follow_the_per_value_definition() {
        let mut spec =
            CampaignSpec::from_toml_str(rbprops_sim::example("test-case-2").unwrap()).unwrap();
        spec.frequency.lines = 60;
        let sim = rbprops_sim::simulate(&spec).unwrap();
        let layout = Layout::new(&spec, &sim.geometry, &sim.frf).unwrap();
        let (nl, n) = (layout.n_lines(), layout.n_values());
        let used: Vec<usize> = (0..n).filter(|i| i % nl != 0).collect();
        let sigma: Vec<f64> = (0..n).map(|i| 1e-6 * (1.0 + (i % 7) as f64)).collect();
        let omega: Vec<f64> = layout.frequency_hz.iter().map(|f| TAU * f).collect();
        let q: Vec<c64> = omega
            .iter()
            .map(|&w| layout.quantity.from_receptance_factor(w))
            .collect();
        // A residual of one resonance at a line frequency (each cell its own residue)
        // plus a deterministic disturbance.
        let (fm0, z0) = (layout.frequency_hz[31], 0.01);
        let b_of = |i: usize, fm: f64, z: f64| {
            let (w, wm) = (omega[i % nl], TAU * fm);
            q[i % nl] * (std::f64::consts::SQRT_2 / sigma[i])
                / c64::new(wm * wm - w * w, 2.0 * z * wm * w)
        };
        let residual: Vec<f64> = used
            .iter()
            .flat_map(|&i| {
                let b = b_of(i, fm0, z0) * (1e-4 * (1.0 + (i / nl) as f64));
                [b.re + (i as f64).sin(), b.im + (i as f64).cos()]
            })
            .collect();
        let (starts, n_tests) = profile_starts(&layout, &used, &sigma, &residual);
        assert_eq!(
            n_tests,
            (nl - 1 + ABOVE_BAND_Q.len()) * PROFILE_DAMPING.len()
        );
        assert_eq!((starts[0][0], starts[0][1]), (fm0, z0));
        for start in &starts {
            let (fm, z) = (start[0], start[1]);
            let n_cells = layout.channel_map.len() * layout.excitation_map.len();
            let (mut num, mut den) = (vec![0.0; n_cells], vec![0.0; n_cells]);
            for (k, &i) in used.iter().enumerate() {
                let b = b_of(i, fm, z);
                num[i / nl] += b.re * residual[2 * k] + b.im * residual[2 * k + 1];
                den[i / nl] += b.norm_sqr();
            }
            let ne = layout.spec_geometry.excitations.len();
            for cell in 0..n_cells {
                let n_rch = layout.channel_map.len();
                let (se, sc) = (
                    layout.excitation_map[cell / n_rch],
                    layout.channel_map[cell % n_rch],
                );
                let (got, want) = (start[2 + sc * ne + se], num[cell] / den[cell]);
                assert!(
                    (got - want).abs() <= 1e-12 * want.abs().max(1e-300),
                    "f {fm}, ζ {z}, cell {cell}: {got} vs {want}"
                );
            }
        }
    }
}
