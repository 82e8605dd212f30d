//! The inertia-restraint (mass-line) estimate straight from the FRFs (Lee et al. 1999,
//! direct method).
//!
//! Between the rigid-body modes and the first elastic mode the accelerance of a freely
//! suspended rigid body tends to its mass line: for `ω ≫ ω_r`,
//! `−ω² A_r/(ω_r² − ω² + 2iζω_rω) = A_r (1 + ω_r²/ω² + …) + i(…)/ω`, and an elastic mode
//! far above adds `−A_e ω²/ω_e² + …`. Summing the rigid modes, `Σ_r A_r = S Φ0Φ0ᵀ F =
//! S M0⁻¹ F`. So each FRF's real part is fitted on the band by `a0 + Σ b_k/ω^{2k}` (rigid
//! tail, k ≤ 3) `+ c ω²` (residual flexibility) `+ e ω²/(ω_e² − ω²)` (the first elastic mode,
//! when detected) and `a0` kept. The quadrature `1/ω` term lives in the imaginary part, which
//! is orthogonal to this fit and so cannot bias `a0`. Measured on the 10× fixture (noise
//! free): with only `a1/ω² + a2ω²` the mass was 1 % off on the band 3 f_r … f_e/3; the
//! extra tail terms and the elastic pole bring it to 2·10⁻⁵ on the wider default band
//! 2 f_r … f_e/2. With `Y = S⁺ G` (Eq. 5 applied to the mass-line matrix `G`),
//! `M0(p) Y = F` is linear in the ten parameters; every excitation gives six equations.
//! Two excitations leave `J` undetermined along `b1 × b2` (the normal to their rotational
//! parts), so at least three are required.

use crate::error::InertiaError;
use crate::lsq::{solve_parameters, LinearConstraint, PropertiesEstimate};
use crate::params::{action_block, basis_matrices, N_PARAMS};
use crate::shapes::RigidFrame;
use rbprops_core::{ExcitationFrf, FrfSource, Quantity, Vec6};
use serde::{Deserialize, Serialize};

/// Band selection for the mass line.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MassLineOptions {
    /// An explicit band (Hz); `None` chooses it automatically.
    pub band_hz: Option<(f64, f64)>,
    /// Automatic band starts at this multiple of the highest rigid-body mode (default 2).
    pub rigid_factor: f64,
    /// Automatic band ends at the first elastic mode divided by this (default 2), or at the
    /// top of the data when no elastic mode is found.
    pub elastic_factor: f64,
    /// An elastic resonance is a rise of the summed accelerance power by this factor over
    /// its level at the band start (default 10, i.e. 10 dB).
    pub elastic_threshold: f64,
    /// Terms of the rigid-body tail `Σ_k b_k/ω^{2k}`, k = 1..=rigid_terms (default 3).
    pub rigid_terms: usize,
    /// Terms of the residual flexibility `Σ_k c_k ω^{2k}`, k = 1..=flex_terms (default 1).
    pub flex_terms: usize,
}

impl Default for MassLineOptions {
    fn default() -> Self {
        Self {
            band_hz: None,
            rigid_factor: 2.0,
            elastic_factor: 2.0,
            elastic_threshold: 10.0,
            rigid_terms: 3,
            flex_terms: 1,
        }
    }
}

/// The band used, and how it was found.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MassLineBand {
    /// Lower band edge (Hz).
    pub lo_hz: f64,
    /// Upper band edge (Hz).
    pub hi_hz: f64,
    /// True when the band was chosen from the modes, false when given.
    pub automatic: bool,
    /// Highest rigid-body (suspension) mode frequency seen (Hz), when known.
    pub highest_rigid_hz: Option<f64>,
    /// Lowest elastic mode frequency seen (Hz), when known.
    pub first_elastic_hz: Option<f64>,
    /// Spectral lines inside the band.
    pub n_lines: usize,
}

/// Excitation `e`'s FRFs from the source (a reader's are decoded now).
fn excitation(frf: &dyn FrfSource, e: usize) -> Result<ExcitationFrf<'_>, InertiaError> {
    Ok(frf.excitation(e)?)
}

/// Minimum number of spectral lines for the three-term fit to have noise degrees of freedom.
pub const MIN_LINES: usize = 6;

/// Chooses the mass-line band: from `rigid_factor ×` the highest rigid mode up to the first
/// elastic resonance `/ elastic_factor`. The elastic resonance is the first local maximum,
/// above the band start, of `P(ω) = Σ |accelerance|²` over all FRFs that exceeds
/// `elastic_threshold ×` `P` at the band start.
pub fn choose_band(
    frf: &dyn FrfSource,
    highest_rigid_hz: f64,
    opts: &MassLineOptions,
) -> Result<MassLineBand, InertiaError> {
    let count = |lo: f64, hi: f64| {
        frf.frequency_hz()
            .iter()
            .filter(|&&f| f >= lo && f <= hi)
            .count()
    };
    if let Some((lo, hi)) = opts.band_hz {
        if !(lo > 0.0 && hi > lo && hi.is_finite()) {
            return Err(InertiaError::MassLine(format!(
                "band {lo}–{hi} Hz is not a positive increasing interval"
            )));
        }
        return Ok(MassLineBand {
            lo_hz: lo,
            hi_hz: hi,
            automatic: false,
            highest_rigid_hz: Some(highest_rigid_hz),
            first_elastic_hz: None,
            n_lines: count(lo, hi),
        });
    }
    if !(highest_rigid_hz > 0.0) {
        return Err(InertiaError::MassLine(
            "no rigid-body mode frequency to place the band above; give the band explicitly".into(),
        ));
    }
    let lo = opts.rigid_factor * highest_rigid_hz;
    let top = *frf.frequency_hz().last().unwrap_or(&0.0);
    // P(ω) summed excitation by excitation (one held at a time), each line's terms in
    // the order excitation, channel.
    let mut power: Vec<f64> = Vec::new();
    let mut axis: Vec<f64> = Vec::new();
    for e in 0..frf.n_excitations() {
        let acc = excitation(frf, e)?
            .band(lo, top)
            .to_quantity(Quantity::Accelerance)
            .map_err(|e| InertiaError::MassLine(e.to_string()))?;
        if e == 0 {
            power = vec![-0.0; acc.n_lines()];
            axis = acc.frequency_hz.clone();
        }
        for c in 0..acc.n_channels {
            for (p, h) in power.iter_mut().zip(acc.frf(0, c)) {
                *p += h.norm_sqr();
            }
        }
    }
    let acc_frequency_hz = axis;
    let nl = power.len();
    let mut first_elastic = None;
    if nl > 0 {
        let base = power[0];
        if let Some(start) = (0..nl).find(|&l| power[l] > opts.elastic_threshold * base) {
            let mut l = start;
            while l + 1 < nl && power[l + 1] >= power[l] {
                l += 1;
            }
            first_elastic = Some(acc_frequency_hz[l]);
        }
    }
    let hi = first_elastic.map_or(top, |fe| fe / opts.elastic_factor);
    if !(hi > lo) {
        return Err(InertiaError::MassLine(format!(
            "no mass-line band: {:.4} Hz ({}× the highest rigid mode {highest_rigid_hz:.4} Hz) is above {hi:.4} Hz ({}); give the band explicitly",
            lo,
            opts.rigid_factor,
            match first_elastic {
                Some(fe) => format!("the first elastic mode {fe:.4} Hz / {}", opts.elastic_factor),
                None => "the top of the data".into(),
            }
        )));
    }
    Ok(MassLineBand {
        lo_hz: lo,
        hi_hz: hi,
        automatic: true,
        highest_rigid_hz: Some(highest_rigid_hz),
        first_elastic_hz: first_elastic,
        n_lines: count(lo, hi),
    })
}

/// The fitted mass-line values `a0` of every FRF (accelerance, m/(N s²) = 1/kg).
#[derive(Debug, Clone, PartialEq)]
pub struct MassLineValues {
    /// The band fitted.
    pub band: MassLineBand,
    /// `a0` per `[excitation][channel]`.
    pub values: Vec<Vec<f64>>,
    /// Regression standard error of each `a0`.
    pub std: Vec<Vec<f64>>,
    /// Relative RMS residual of each FRF's fit on the band.
    pub fit_residual: Vec<Vec<f64>>,
}

/// Fits `Re A(ω) = a0 + Σ_k b_k/ω^{2k} + Σ_k c_k ω^{2k} (+ e ω²/(ω_e² − ω²))` to every FRF on
/// the band (accelerance) and returns `a0` with its regression standard error
/// `s √[(XᵀX)⁻¹]₀₀`. The elastic pole term is used when the band knows the first elastic
/// resonance (automatic band).
pub fn mass_line_values(
    frf: &dyn FrfSource,
    band: &MassLineBand,
    rigid_terms: usize,
    flex_terms: usize,
) -> Result<MassLineValues, InertiaError> {
    let in_band = |f: &&f64| **f >= band.lo_hz && **f <= band.hi_hz;
    let band_hz: Vec<f64> = frf.frequency_hz().iter().filter(in_band).copied().collect();
    let n = band_hz.len();
    let nb = 1 + rigid_terms + flex_terms;
    if n < MIN_LINES.max(nb + 3) {
        return Err(InertiaError::MassLine(format!(
            "the band {:.4}–{:.4} Hz holds {n} spectral lines; at least {} are needed",
            band.lo_hz,
            band.hi_hz,
            MIN_LINES.max(nb + 3)
        )));
    }
    // Each excitation's band in accelerance, one at a time.
    let accelerance = |e: usize| {
        excitation(frf, e)?
            .band(band.lo_hz, band.hi_hz)
            .to_quantity(Quantity::Accelerance)
            .map_err(|e| InertiaError::MassLine(e.to_string()))
    };
    // Basis in x = ω²/ω_c², scaled to the band centre for conditioning.
    let w: Vec<f64> = band_hz
        .iter()
        .map(|f| 2.0 * std::f64::consts::PI * f)
        .collect();
    let wc2 = w[0] * w[n - 1];
    // Columns: 1, t⁻¹…t^{-R}, t¹…t^{F} with t = ω²/ω_c², then the elastic pole's
    // quasi-static shape ω²/(ω_e² − ω²) when the first elastic resonance is known (it captures
    // the whole elastic series, which converges slowly near the band top).
    let we = band
        .first_elastic_hz
        .map(|f| 2.0 * std::f64::consts::PI * f)
        .filter(|&we| we > w[n - 1] * 1.05);
    let nb = nb + we.is_some() as usize;
    let x = nalgebra::DMatrix::from_fn(n, nb, |i, j| {
        let t = w[i] * w[i] / wc2;
        if j == 0 {
            1.0
        } else if j <= rigid_terms {
            t.powi(-(j as i32))
        } else if j <= rigid_terms + flex_terms {
            t.powi((j - rigid_terms) as i32)
        } else {
            let we = we.expect("elastic column only when known");
            w[i] * w[i] / (we * we - w[i] * w[i])
        }
    });
    let svd = x.clone().svd(true, true);
    let sv = &svd.singular_values;
    if sv.min() <= 1e-12 * sv.max() {
        return Err(InertiaError::MassLine(
            "the band is too narrow to separate the mass line from the 1/ω² and ω² terms".into(),
        ));
    }
    let vt = svd.v_t.as_ref().expect("v requested");
    // [(XᵀX)⁻¹]₀₀ = Σ_i V₀ᵢ²/σᵢ².
    let c00: f64 = (0..nb).map(|i| vt[(i, 0)].powi(2) / sv[i].powi(2)).sum();
    let mut values = Vec::new();
    let mut std = Vec::new();
    let mut fit_residual = Vec::new();
    for e in 0..frf.n_excitations() {
        let acc = accelerance(e)?;
        let (mut v, mut s, mut r) = (Vec::new(), Vec::new(), Vec::new());
        for c in 0..acc.n_channels {
            let y = nalgebra::DVector::from_iterator(n, acc.frf(0, c).iter().map(|z| z.re));
            let coef = svd
                .solve(&y, 0.0)
                .map_err(|m| InertiaError::MassLine(m.to_string()))?;
            let res = &y - &x * &coef;
            let rss = res.norm_squared();
            let sigma2 = rss / (n - nb) as f64;
            v.push(coef[0]);
            s.push((sigma2 * c00).sqrt());
            r.push(if y.norm() > 0.0 {
                res.norm() / y.norm()
            } else {
                0.0
            });
        }
        values.push(v);
        std.push(s);
        fit_residual.push(r);
    }
    Ok(MassLineValues {
        band: band.clone(),
        values,
        std,
        fit_residual,
    })
}

/// Result of the mass-line estimator.
#[derive(Debug, Clone, PartialEq)]
pub struct MlSolution {
    /// The ten properties: rank and residual of `M0(p) (S⁺ G_k) = f_k` over the
    /// excitations.
    pub estimate: PropertiesEstimate,
    /// Per excitation: `‖G_k − S y_k‖/‖G_k‖`, how rigid the mass line looks.
    pub rigid_residual: Vec<f64>,
}

/// Solves `M0(p) (S⁺ G_k) = f_k` over the given excitations in least squares.
/// `values[k]` is the mass-line vector of excitation `excitations[k]` (geometry index).
pub fn mass_line(
    frame: &RigidFrame,
    excitations: &[usize],
    values: &[Vec<f64>],
    constraints: &[LinearConstraint],
    nominal: Option<&[f64; N_PARAMS]>,
) -> Result<MlSolution, InertiaError> {
    if excitations.len() < 3 {
        return Err(InertiaError::MassLine(format!(
            "needs at least three excitations (two leave the inertia about the normal of their moment arms undetermined); got {}",
            excitations.len()
        )));
    }
    let e = basis_matrices();
    let mut rows = Vec::new();
    let mut rhs = Vec::new();
    let mut rigid_residual = Vec::new();
    for (&k, g) in excitations.iter().zip(values) {
        let fit = frame.basis.fit(g).map_err(|err| {
            InertiaError::MassLine(format!("excitation '{}': {err}", frame.excitation_ids[k]))
        })?;
        rigid_residual.push(fit.relative_residual);
        let y: Vec6 = fit.q;
        let blk = action_block(&e, &y);
        for r in 0..6 {
            rows.push(blk[r]);
            rhs.push(frame.forces[k][r]);
        }
    }
    Ok(MlSolution {
        estimate: PropertiesEstimate::from_solution(solve_parameters(
            &rows,
            &rhs,
            constraints,
            nominal,
        )?),
        rigid_residual,
    })
}
