//! Indicator functions of one excitation's SIMO FRF set: the Norm Indicator (paper Eq. 12),
//! the hybrid MIF (Rades 1994) and the PRF MIF (Rades & Ewins 2000).
//!
//! All three use the same `n` FRFs of an excitation (for the paper: the nine FRFs of three
//! triaxial accelerometers).

use nalgebra::DMatrix;
use rbprops_core::{c64, FrfSet};
use serde::{Deserialize, Serialize};

/// Level returned by [`norm_indicator`] at a line where every FRF is exactly zero
/// (`20 log10 0 = −∞` would not survive JSON); far below any physical FRF.
pub const NI_FLOOR_DB: f64 = -400.0;

/// Default relative singular-value threshold for a principal response to count
/// (80 dB below the first).
pub const DEFAULT_PRF_RANK_TOLERANCE: f64 = 1e-4;

/// `Σ_i |H_ik(ω)|²` per line over the channels of excitation `k`.
pub fn response_power(frf: &FrfSet, excitation: usize) -> Vec<f64> {
    let nl = frf.n_lines();
    let mut p = vec![0.0; nl];
    for c in 0..frf.n_channels {
        for (acc, h) in p.iter_mut().zip(frf.frf(excitation, c)) {
            *acc += h.norm_sqr();
        }
    }
    p
}

/// Power (Σ|H|²) to dB, floored at [`NI_FLOOR_DB`].
pub fn power_db(p: f64) -> f64 {
    if p > 0.0 {
        (10.0 * p.log10()).max(NI_FLOOR_DB)
    } else {
        NI_FLOOR_DB
    }
}

/// Norm Indicator of excitation `k` (paper Eq. 12), in dB re 1 FRF unit:
///
/// `NI_k(ω) = 20 log10 sqrt( Σ_i (Re H_ik(ω))² + (Im H_ik(ω))² )`
///
/// over all channels `i`. It is computed on whatever quantity the set holds (the paper uses
/// receptance); at a given frequency the comparison between excitations does not depend
/// on that choice. Lines where all FRFs vanish give [`NI_FLOOR_DB`].
///
/// Panics if `excitation >= frf.n_excitations`, as slice indexing does.
pub fn norm_indicator(frf: &FrfSet, excitation: usize) -> Vec<f64> {
    assert!(
        excitation < frf.n_excitations,
        "excitation {excitation} out of range ({} excitations)",
        frf.n_excitations
    );
    response_power(frf, excitation)
        .into_iter()
        .map(power_db)
        .collect()
}

/// The part of `h` that vanishes at the resonance of a lightly damped real mode: the real
/// part of the receptance-phased FRF. Receptance and accelerance (`−ω²H`) resonate in
/// quadrature, so it is `Re h`; mobility (`iωH`) resonates in phase, so it is `Im h`.
fn coincident_part(frf: &FrfSet, h: c64) -> f64 {
    if frf.quantity.order() % 2 == 1 {
        h.im
    } else {
        h.re
    }
}

/// The MIF ratio `Σ_j |Re h_j| |h_j| / Σ_j |h_j|²` of a set of responses at one line.
/// 1 (no resonance) when every response is zero.
fn mif_ratio<'a>(frf: &FrfSet, hs: impl Iterator<Item = &'a c64>) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for h in hs {
        num += coincident_part(frf, *h).abs() * h.norm();
        den += h.norm_sqr();
    }
    if den > 0.0 {
        (num / den).clamp(0.0, 1.0)
    } else {
        1.0
    }
}

/// Hybrid MIF of excitation `k` (after Rades 1994, "A comparison of some mode indicator
/// functions"): one curve from all `n` FRFs of the excitation, using both their real and
/// imaginary parts,
///
/// `MIF_k(ω) = Σ_i |Re H_ik(ω)| · |H_ik(ω)| / Σ_i |H_ik(ω)|²`,   `|H| = sqrt(Re² + Im²)`.
///
/// The published formula could not be retrieved for this project (searches found only
/// secondary descriptions of MIF/MMIF/CMIF). This is the standard single-reference MIF
/// that weights each FRF's real part by its modulus, so it uses both the real and the
/// imaginary parts of every FRF, which is what the paper says of it: "MIF of all FRFs
/// measured with three triaxial accelerometers, using both real and imaginary parts".
/// Reading "hybrid" as this real-part × modulus product is our interpretation. It lies in [0, 1], is near 1 away from resonances and dips towards 0 at each
/// lightly damped normal mode that dominates the response there, whatever its level: it
/// tells where modes are, not how strongly the excitation drives them. For one mode alone
/// it equals `|ω_r² − ω²| / |ω_r² − ω² + 2iζω_rω|` exactly. `Re` is taken on the
/// receptance phase (for mobility data it is `Im H`).
pub fn hybrid_mif(frf: &FrfSet, excitation: usize) -> Vec<f64> {
    let nl = frf.n_lines();
    (0..nl)
        .map(|l| {
            let hs: Vec<c64> = (0..frf.n_channels)
                .map(|c| frf.frf(excitation, c)[l])
                .collect();
            mif_ratio(frf, hs.iter())
        })
        .collect()
}

/// Principal responses of one excitation's FRF set (Rades & Ewins, principal response
/// analysis): the `n_channels × n_lines` FRF matrix `A` is decomposed as `A = U Σ Vᴴ`
/// and the principal response functions are the rows of `Uᵀ A = Σ Vᴴ`.
///
/// The left singular vectors are taken from the SVD of the real matrix `[Re A | Im A]`
/// (the eigenvectors of `Re(A Aᴴ)`), so they are real, time-invariant spatial patterns:
/// for real normal modes the responses `u_jᵀ H(ω)` keep the modal phase (a complex
/// singular vector would rotate it arbitrarily and spoil the real/imaginary split the
/// MIF relies on).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct PrincipalResponses {
    /// Singular values of `[Re A | Im A]`, descending.
    pub singular_values: Vec<f64>,
    /// Left singular vectors (one per PRF, over the channels), largest entry positive.
    pub shapes: Vec<Vec<f64>>,
    /// `PRF_j(ω) = u_jᵀ H(ω)` per PRF and line.
    #[schemars(with = "Vec<Vec<[f64; 2]>>")]
    pub responses: Vec<Vec<c64>>,
}

impl PrincipalResponses {
    /// Number of PRFs whose singular value is at least `tolerance × σ_1`.
    pub fn rank(&self, tolerance: f64) -> usize {
        let s1 = self.singular_values.first().copied().unwrap_or(0.0);
        if s1 <= 0.0 {
            return 0;
        }
        self.singular_values
            .iter()
            .filter(|&&s| s >= tolerance * s1)
            .count()
    }
}

/// Computes the [`PrincipalResponses`] of excitation `k`.
pub fn principal_responses(frf: &FrfSet, excitation: usize) -> PrincipalResponses {
    let n = frf.n_channels;
    let nl = frf.n_lines();
    // Re(A Aᴴ) = Re A Re Aᵀ + Im A Im Aᵀ, the Gram matrix of [Re A | Im A].
    let mut g = DMatrix::<f64>::zeros(n, n);
    for i in 0..n {
        let hi = frf.frf(excitation, i);
        for j in 0..=i {
            let hj = frf.frf(excitation, j);
            let s: f64 = hi
                .iter()
                .zip(hj)
                .map(|(a, b)| a.re * b.re + a.im * b.im)
                .sum();
            g[(i, j)] = s;
            g[(j, i)] = s;
        }
    }
    let eig = g.symmetric_eigen();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let mut singular_values = Vec::with_capacity(n);
    let mut shapes = Vec::with_capacity(n);
    let mut responses = Vec::with_capacity(n);
    for j in order {
        singular_values.push(eig.eigenvalues[j].max(0.0).sqrt());
        let mut u: Vec<f64> = eig.eigenvectors.column(j).iter().copied().collect();
        let imax = (0..n)
            .max_by(|&a, &b| u[a].abs().total_cmp(&u[b].abs()))
            .unwrap_or(0);
        if n > 0 && u[imax] < 0.0 {
            u.iter_mut().for_each(|x| *x = -*x);
        }
        let mut prf = vec![c64::new(0.0, 0.0); nl];
        for (c, &uc) in u.iter().enumerate() {
            for (p, h) in prf.iter_mut().zip(frf.frf(excitation, c)) {
                *p += h * uc;
            }
        }
        shapes.push(u);
        responses.push(prf);
    }
    PrincipalResponses {
        singular_values,
        shapes,
        responses,
    }
}

/// PRF MIF of excitation `k` (after Rades & Ewins 2000): the MIF ratio of
/// [`hybrid_mif`] applied to the significant principal response functions instead of the
/// raw FRFs,
///
/// `PRF-MIF_k(ω) = Σ_j |Re P_j(ω)| |P_j(ω)| / Σ_j |P_j(ω)|²`,  `j` over PRFs with
/// `σ_j ≥ rank_tolerance · σ_1`.
///
/// Discarding the insignificant PRFs removes the noise subspace; the measure is
/// invariant to any orthogonal change of the channel set (rotating the accelerometers),
/// which the hybrid MIF is not. With all PRFs kept its denominator equals NI's power.
/// The published formula could not be retrieved for this project; this is the
/// documented reading of "PRF MIF: MIF of the principal response functions".
pub fn prf_mif(frf: &FrfSet, excitation: usize, rank_tolerance: f64) -> Vec<f64> {
    prf_mif_from(frf, &principal_responses(frf, excitation), rank_tolerance)
}

/// [`prf_mif`] from already computed principal responses.
pub fn prf_mif_from(frf: &FrfSet, prf: &PrincipalResponses, rank_tolerance: f64) -> Vec<f64> {
    let r = prf.rank(rank_tolerance);
    (0..frf.n_lines())
        .map(|l| {
            let hs: Vec<c64> = prf.responses[..r].iter().map(|p| p[l]).collect();
            mif_ratio(frf, hs.iter())
        })
        .collect()
}

/// Lines within `half_width_hz` of `f_hz`; the nearest line when none is.
pub fn window_lines(frequency_hz: &[f64], f_hz: f64, half_width_hz: f64) -> std::ops::Range<usize> {
    let lo = frequency_hz.partition_point(|&x| x < f_hz - half_width_hz);
    let hi = frequency_hz.partition_point(|&x| x <= f_hz + half_width_hz);
    if lo < hi {
        return lo..hi;
    }
    let n = frequency_hz.len();
    if n == 0 {
        return 0..0;
    }
    let i = lo.min(n - 1);
    let nearest = if i > 0 && (frequency_hz[i - 1] - f_hz).abs() <= (frequency_hz[i] - f_hz).abs() {
        i - 1
    } else {
        i
    };
    nearest..nearest + 1
}

/// Spacing of the axis around `f_hz` (0 for a single line).
pub fn local_spacing(frequency_hz: &[f64], f_hz: f64) -> f64 {
    let n = frequency_hz.len();
    if n < 2 {
        return 0.0;
    }
    let i = frequency_hz.partition_point(|&x| x < f_hz).clamp(1, n - 1);
    frequency_hz[i] - frequency_hz[i - 1]
}

#[cfg(test)]
mod tests {
    use super::*;
    use rbprops_core::Quantity;

    fn sdof(f: &[f64], fr: f64, zeta: f64, shape: &[f64]) -> FrfSet {
        let mut s = FrfSet::zeros(Quantity::Receptance, f.to_vec(), 1, shape.len());
        let wr = 2.0 * std::f64::consts::PI * fr;
        for (c, a) in shape.iter().enumerate() {
            for (l, h) in s.frf_mut(0, c).iter_mut().enumerate() {
                let w = 2.0 * std::f64::consts::PI * f[l];
                *h = c64::new(*a, 0.0) / c64::new(wr * wr - w * w, 2.0 * zeta * wr * w);
            }
        }
        s
    }

    #[test]
    fn ni_is_eq12_and_peaks_at_the_analytic_level() {
        let f: Vec<f64> = (1..=400).map(|i| i as f64 * 0.005).collect();
        let shape = [0.3, -0.4, 1.2];
        let s = sdof(&f, 1.0, 0.02, &shape);
        let ni = norm_indicator(&s, 0);
        for l in [0, 57, 199, 399] {
            let p: f64 = (0..3).map(|c| s.frf(0, c)[l].norm_sqr()).sum();
            assert!((ni[l] - 20.0 * p.sqrt().log10()).abs() < 1e-12);
        }
        // f = 1.0 Hz is line 199: |H| = ‖a‖ / (2ζω_r²).
        let wr = 2.0 * std::f64::consts::PI;
        let norm_a = shape.iter().map(|x| x * x).sum::<f64>().sqrt();
        let expect = 20.0 * (norm_a / (2.0 * 0.02 * wr * wr)).log10();
        assert!((ni[199] - expect).abs() < 1e-10, "{} vs {expect}", ni[199]);
        let zero = FrfSet::zeros(Quantity::Receptance, vec![1.0], 1, 2);
        assert_eq!(norm_indicator(&zero, 0), vec![NI_FLOOR_DB]);
    }

    #[test]
    fn hybrid_mif_of_one_mode_is_the_analytic_ratio() {
        let f: Vec<f64> = (1..=300).map(|i| i as f64 * 0.01).collect();
        let (fr, z) = (1.3, 0.03);
        let s = sdof(&f, fr, z, &[1.0, -2.0, 0.5, 0.1]);
        let mif = hybrid_mif(&s, 0);
        let wr = 2.0 * std::f64::consts::PI * fr;
        for (l, m) in mif.iter().enumerate() {
            let w = 2.0 * std::f64::consts::PI * f[l];
            let d = c64::new(wr * wr - w * w, 2.0 * z * wr * w);
            let expect = (wr * wr - w * w).abs() / d.norm();
            assert!((m - expect).abs() < 1e-12, "line {l}: {m} vs {expect}");
        }
        // At the resonance (line 129 = 1.30 Hz) it vanishes.
        assert!(mif[129] < 1e-9);
        // Mobility data give the same curve (Re of the receptance phase is Im of mobility).
        let mob = s.to_quantity(Quantity::Mobility).unwrap();
        let mm = hybrid_mif(&mob, 0);
        for (a, b) in mm.iter().zip(&mif) {
            assert!((a - b).abs() < 1e-12);
        }
    }

    #[test]
    fn prf_rank_counts_modes_and_prf_mif_ignores_channel_rotation() {
        let f: Vec<f64> = (1..=500).map(|i| i as f64 * 0.004).collect();
        let mut s = FrfSet::zeros(Quantity::Receptance, f.clone(), 1, 3);
        let modes = [(0.6, 0.02, [1.0, 0.2, -0.3]), (1.1, 0.02, [-0.1, 0.8, 0.5])];
        for c in 0..3 {
            for (l, h) in s.frf_mut(0, c).iter_mut().enumerate() {
                let w = 2.0 * std::f64::consts::PI * f[l];
                for (fr, z, a) in &modes {
                    let wr = 2.0 * std::f64::consts::PI * fr;
                    *h += c64::new(a[c], 0.0) / c64::new(wr * wr - w * w, 2.0 * z * wr * w);
                }
            }
        }
        let prf = principal_responses(&s, 0);
        assert_eq!(prf.rank(1e-8), 2, "{:?}", prf.singular_values);
        // Σ_j |P_j|² = Σ_i |H_i|² when every PRF is kept (U orthogonal).
        let p = response_power(&s, 0);
        for l in [0, 100, 374] {
            let q: f64 = prf.responses.iter().map(|r| r[l].norm_sqr()).sum();
            assert!((q - p[l]).abs() < 1e-10 * p[l]);
        }
        // Rotate the channels by an orthogonal matrix: PRF MIF unchanged, hybrid MIF not.
        let (ca, sa) = (0.6f64.cos(), 0.6f64.sin());
        let rot = [[ca, -sa, 0.0], [sa, ca, 0.0], [0.0, 0.0, 1.0]];
        let mut r = s.clone();
        for l in 0..f.len() {
            let h: Vec<c64> = (0..3).map(|c| s.frf(0, c)[l]).collect();
            for (i, row) in rot.iter().enumerate() {
                r.frf_mut(0, i)[l] = h.iter().zip(row).map(|(x, w)| x * w).sum();
            }
        }
        let a = prf_mif(&s, 0, 1e-8);
        let b = prf_mif(&r, 0, 1e-8);
        let max_diff = a
            .iter()
            .zip(&b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        assert!(max_diff < 1e-9, "{max_diff}");
        let ha = hybrid_mif(&s, 0);
        let hb = hybrid_mif(&r, 0);
        let hdiff = ha
            .iter()
            .zip(&hb)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        assert!(hdiff > 1e-3, "{hdiff}");
        // Both dips sit on the two resonances (lines 149 and 274).
        for line in [149, 274] {
            assert!(
                a[line] < 0.05 && ha[line] < 0.05,
                "{} {}",
                a[line],
                ha[line]
            );
        }
    }

    #[test]
    fn window_picks_lines_or_nearest() {
        let f = [0.0, 0.1, 0.2, 0.3, 0.4];
        assert_eq!(window_lines(&f, 0.2, 0.1), 1..4);
        assert_eq!(window_lines(&f, 0.26, 0.01), 3..4);
        assert_eq!(window_lines(&f, 9.0, 0.01), 4..5);
        assert!((local_spacing(&f, 0.25) - 0.1).abs() < 1e-15);
    }
}
