//! Residues by least squares in the frequency domain (LSFD) once the poles are known,
//! and joint refinement of the poles (variable projection).
//!
//! Model of one channel in the measured quantity (`q(ω) = (iω)^k`, k = 0, 1, 2 for
//! receptance, mobility, accelerance):
//!
//! ```text
//!   H(ω) = q(ω) [ Σ_r ( R_r/(iω−λ_r) + R_r*/(iω−λ_r*) ) + U + L/(iω)² ]
//! ```
//!
//! with `R_r = a_r + i b_r` complex and the residual terms `U` (upper: modes above the
//! band, a constant receptance) and `L` (lower: modes below the band, a mass line) real.
//! Conjugate symmetry is enforced by solving for the real unknowns `(a_r, b_r, U, L)`
//! on the real-stacked equations `[Re; Im]`. All channels share the basis, so one QR
//! factorisation serves them all.

use crate::band::BandData;
use crate::linalg::{self, TallLs};
use crate::pole::Pole;
use faer::Mat;

mod blocked;
use rbprops_core::c64;

/// Which residual terms the model carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Residuals {
    /// Carry the upper residual term (modes above the band, a constant receptance).
    pub upper: bool,
    /// Carry the lower residual term (modes below the band, a mass line `1/(iω)²`).
    pub lower: bool,
}

impl Residuals {
    /// Upper always (when enabled); lower only when the band starts above 0 Hz, where
    /// `1/(iω)²` is finite.
    pub fn for_band(enabled: bool, band: &BandData) -> Self {
        Self {
            upper: enabled,
            lower: enabled && band.omega[0] > 0.0,
        }
    }
    /// No residual terms (the poles' own columns only).
    pub const NONE: Self = Self {
        upper: false,
        lower: false,
    };
    fn count(self) -> usize {
        self.upper as usize + self.lower as usize
    }
}

/// Per-line weights shared by all channels: `w_k = 1/√(mean_o |h_ok/rms_o|²)`.
///
/// Noise in measured FRFs is roughly proportional to |H| (1 % per line in the tests), so
/// unweighted least squares lets the resonance peaks dominate and makes the residual
/// variance meaningless for a model-order test. A weight common to all channels keeps
/// the basis shared (one QR for all channels) while equalising the lines.
pub fn line_weights(chans: &[Vec<c64>]) -> Vec<f64> {
    scaled_line_weights(&Slices(chans), None)
}

/// The channels a refinement reads ([`refine_channels`]), one at a time and possibly
/// more than once (once per trial): held, or made again on request (issue 41: a
/// bootstrap replicate of a set-up of many excitations keeps its draws out of memory).
/// Every read of channel `o` must give the same values.
pub trait Channels {
    /// The number of channels.
    fn count(&self) -> usize;
    /// Channel `o`'s values, one per line of the band.
    fn channel(&self, o: usize) -> std::borrow::Cow<'_, [c64]>;
}

/// Channels held as slices (anything that is one).
struct Slices<'a, C>(&'a [C]);

impl<C: AsRef<[c64]>> Channels for Slices<'_, C> {
    fn count(&self) -> usize {
        self.0.len()
    }
    fn channel(&self, o: usize) -> std::borrow::Cow<'_, [c64]> {
        std::borrow::Cow::Borrowed(self.0[o].as_ref())
    }
}

rbprops_core::avx_fn! {
/// [`line_weights`] of the channels `chans[o] / scale[o]` (each channel divided as it is
/// read, one at a time: the values of a scaled copy without the copy of them all), or
/// of `chans` as they are without `scale`.
fn scaled_line_weights(chans: &dyn Channels, scale: Option<&[f64]>) -> Vec<f64> {
    let n = chans.channel(0).len();
    let channel = |o: usize| -> std::borrow::Cow<'_, [c64]> {
        match scale {
            Some(s) => chans.channel(o).iter().map(|z| z / s[o]).collect(),
            None => chans.channel(o),
        }
    };
    let rms: Vec<f64> = (0..chans.count())
        .map(|o| (channel(o).iter().map(|z| z.norm_sqr()).sum::<f64>() / n as f64).sqrt())
        .collect();
    let live: Vec<usize> = (0..chans.count()).filter(|&o| rms[o] > 0.0).collect();
    if live.is_empty() {
        return vec![1.0; n];
    }
    // Channel by channel over contiguous lines (each line's sum in channel order, as
    // `Iterator::sum` would add them: bitwise the same, and the loops vectorise).
    let mut level = vec![std::iter::empty::<f64>().sum::<f64>(); n];
    for &o in &live {
        let r2 = rms[o] * rms[o];
        for (l, z) in level.iter_mut().zip(channel(o).iter()) {
            *l += z.norm_sqr() / r2;
        }
    }
    for l in level.iter_mut() {
        *l /= live.len() as f64;
    }
    let mean = level.iter().sum::<f64>() / n as f64;
    level
        .iter()
        .map(|l| 1.0 / l.max(1e-12 * mean).sqrt())
        .collect()
}
}

/// The line weights of `chans` on `band`: [`line_weights`], times the band's measured
/// quality factor `q_k ∝ √(γ²/(1 − γ²))` when it has one (`crate::weighting`), so that
/// `w_k ∝ 1/σ_k` with `σ_k² ∝ |H|²(1 − γ²)/γ²`.
pub fn band_line_weights(band: &BandData, chans: &[Vec<c64>]) -> Vec<f64> {
    with_line_quality(band, line_weights(chans))
}

/// Line weights `w` times the band's measured quality factor, when it has one.
fn with_line_quality(band: &BandData, w: Vec<f64>) -> Vec<f64> {
    match &band.line_quality {
        None => w,
        Some(q) => w.iter().zip(q).map(|(w, q)| w * q).collect(),
    }
}

/// `(1/(iω − λ), 1/(iω − λ*))` in real arithmetic (one real division per term).
#[inline]
fn recips(p: c64, w: f64) -> (c64, c64) {
    let x = -p.re;
    let (y1, y2) = (w - p.im, w + p.im);
    let (i1, i2) = (1.0 / (x * x + y1 * y1), 1.0 / (x * x + y2 * y2));
    (c64::new(x * i1, -y1 * i1), c64::new(x * i2, -y2 * i2))
}

/// The pole pair's two real-coefficient basis functions at `ω`: `u + v` and `i(u − v)`
/// with `u = 1/(iω − λ)`, `v = 1/(iω − λ*)`, so that `R u + R* v = a(u + v) + b·i(u − v)`
/// for `R = a + ib`.
#[inline]
fn pair_basis(p: c64, w: f64) -> (c64, c64) {
    let (u, v) = recips(p, w);
    let d = u - v;
    (u + v, c64::new(-d.im, d.re))
}

/// One line of a pole pair's two real-stacked basis columns, `q·(u + v)` and
/// `q·i(u − v)` as (re₁, im₁, re₂, im₂), for `u = 1/(iω − λ)`, `v = 1/(iω − λ*)`,
/// `λ = −x + i·pim`, `q = qr + i·qi` (the operations of `pair_basis` and the complex
/// product by q, written out so that the loops calling it vectorise).
#[inline(always)]
fn pair_columns(x: f64, pim: f64, w: f64, qr: f64, qi: f64) -> (f64, f64, f64, f64) {
    let (ur, ui, vr, vi) = pole_reciprocals(x, pim, w);
    let (b1r, b1i) = (ur + vr, ui + vi);
    let (b2r, b2i) = (-(ui - vi), ur - vr);
    (
        qr * b1r - qi * b1i,
        qr * b1i + qi * b1r,
        qr * b2r - qi * b2i,
        qr * b2i + qi * b2r,
    )
}

/// Real-stacked (`[Re; Im]`) basis columns `2N × (2·poles + residual terms)`, each
/// multiplied by `q(ω)` and the line weight.
fn basis_stacked(poles: &[Pole], band: &BandData, res: Residuals, w: &[f64]) -> Mat<f64> {
    // Every entry is written by `basis_stacked_into` (pole pairs, then residual columns).
    let mut a = linalg::mat_for_overwrite(2 * band.n_lines(), 2 * poles.len() + res.count());
    basis_stacked_into(&mut a, poles, band, res, w);
    a
}

rbprops_core::avx_fn! {
/// [`basis_stacked`] written over every entry of `a` (already of its shape): the
/// refinement's trials reuse one matrix instead of allocating (and zeroing) each basis.
fn basis_stacked_into(a: &mut Mat<f64>, poles: &[Pole], band: &BandData, res: Residuals, w: &[f64]) -> () {
    let n = band.n_lines();
    debug_assert_eq!(a.shape(), (2 * n, 2 * poles.len() + res.count()));
    let q: Vec<c64> = band
        .quantity_factor()
        .iter()
        .zip(w)
        .map(|(q, w)| q * *w)
        .collect();
    let put = |a: &mut Mat<f64>, j: usize, f: &mut dyn FnMut(usize) -> c64| {
        let col = a.col_mut(j).try_as_col_major_mut().unwrap().as_slice_mut();
        let (re, im) = col.split_at_mut(n);
        for (k, (r, i)) in re.iter_mut().zip(im.iter_mut()).enumerate() {
            let z = f(k);
            *r = z.re;
            *i = z.im;
        }
    };
    // The pole columns in plain real arithmetic over line arrays (the operations of
    // `pair_basis` and the complex product by q, written out so that they vectorise).
    let (qre, qim): (Vec<f64>, Vec<f64>) = q.iter().map(|z| (z.re, z.im)).unzip();
    for (m, p) in poles.iter().enumerate() {
        let (r1, i1, r2, i2) = pair_halves(a, m, n);
        let (x, pim) = (-p.0.re, p.0.im);
        let cols = r1
            .iter_mut()
            .zip(i1.iter_mut())
            .zip(r2.iter_mut().zip(i2.iter_mut()));
        let line = band.omega.iter().zip(qre.iter().zip(&qim));
        for (((r1, i1), (r2, i2)), (&w, (&qr, &qi))) in cols.zip(line) {
            (*r1, *i1, *r2, *i2) = pair_columns(x, pim, w, qr, qi);
        }
    }
    let mut j = 2 * poles.len();
    if res.upper {
        put(a, j, &mut |k| q[k]);
        j += 1;
    }
    if res.lower {
        put(a, j, &mut |k| {
            let w = band.omega[k];
            q[k] * (-1.0 / (w * w))
        });
    }
}
}

rbprops_core::avx_fn! {
/// Scales every column of `a` to unit norm; returns the scales (1 for a zero column).
fn normalise(a: &mut Mat<f64>) -> Vec<f64> {
    // A plain loop, not `map(..).collect()`: the closure of an iterator adaptor need not
    // be inlined into the AVX copy, and the divisions would then run two to a vector.
    let mut scales = Vec::with_capacity(a.ncols());
    for j in 0..a.ncols() {
        let col = a.col_mut(j).try_as_col_major_mut().unwrap().as_slice_mut();
        let s = linalg::dot(col, col).sqrt();
        let s = if s > 0.0 { s } else { 1.0 };
        for x in col.iter_mut() {
            *x /= s;
        }
        scales.push(s);
    }
    scales
}
}

fn stack_data(chans: &[Vec<c64>], w: &[f64]) -> Mat<f64> {
    let n = chans[0].len();
    let mut b = linalg::mat_for_overwrite(2 * n, chans.len());
    for (j, h) in chans.iter().enumerate() {
        let col = b.col_mut(j).try_as_col_major_mut().unwrap().as_slice_mut();
        let (re, im) = col.split_at_mut(n);
        for (((r, i), z), wk) in re.iter_mut().zip(im.iter_mut()).zip(h).zip(w) {
            let z = z * *wk;
            *r = z.re;
            *i = z.im;
        }
    }
    b
}

/// Residues of one set of channels for fixed poles.
#[derive(Debug, Clone)]
pub struct ResidueFit {
    /// `R` per mode and channel (pole–residue form, receptance units m/N·rad/s).
    pub residues: Vec<Vec<c64>>,
    /// Standard error of Re R and Im R (root-mean of the two variances), per mode and channel.
    pub residue_std: Vec<Vec<f64>>,
    /// Upper residual term per channel (receptance units m/N), empty when not carried.
    pub upper: Vec<f64>,
    /// Lower residual term per channel (m/N·(rad/s)²), empty when not carried.
    pub lower: Vec<f64>,
    /// Residual sum of squares per channel (measured quantity units²).
    pub rss: Vec<f64>,
    /// Ratio of the smallest to the largest diagonal entry of R (QR) of the normalised
    /// basis: near 0 means two poles' columns are nearly collinear (inseparable modes).
    pub basis_conditioning: f64,
    /// The fitted FRFs `[channel][line]` in the measured quantity (as [`synthesise`]).
    pub synthesised: Vec<Vec<c64>>,
}

/// LSFD: residues (and residual terms) for every channel given the poles.
///
/// The basis is shared by every channel: its normal equations are formed once, by
/// blocks of lines (`blocked`), and solved by the Cholesky factor of its Gram matrix
/// as in `TallLs`; by Householder QR of the whole basis when that is ill-conditioned.
pub fn fit_residues(
    poles: &[Pole],
    band: &BandData,
    chans: &[Vec<c64>],
    res: Residuals,
) -> ResidueFit {
    let w = band_line_weights(band, chans);
    let (ls, synthesised) = match blocked::solve(poles, band, chans, res, &w) {
        Some(s) => s,
        None => solve_tall(poles, band, chans, res, &w),
    };
    residue_fit(poles.len(), res, ls, synthesised)
}

/// A least-squares solution on the normalised basis (columns of unit norm).
struct LsSolution {
    /// Coefficients of the normalised basis, `p × channels`.
    x: Mat<f64>,
    /// The column norms of the basis.
    scale: Vec<f64>,
    rss: Vec<f64>,
    /// `(ÃᵀÃ)⁻¹` of the normalised basis `Ã`.
    ginv: Mat<f64>,
    /// |diagonal of R| of the normalised basis.
    r_diag: Vec<f64>,
    rows: usize,
}

/// [`fit_residues`] on the whole basis ([`TallLs`]), and the fitted FRFs.
fn solve_tall(
    poles: &[Pole],
    band: &BandData,
    chans: &[Vec<c64>],
    res: Residuals,
    w: &[f64],
) -> (LsSolution, Vec<Vec<c64>>) {
    let mut a = basis_stacked(poles, band, res, w);
    let scale = normalise(&mut a);
    let rows = a.nrows();
    let qr = TallLs::new(a);
    let (x, resid, rss) = qr.solve_into(stack_data(chans, w));
    let ls = LsSolution {
        x,
        scale,
        rss,
        ginv: qr.inverse_gram(),
        r_diag: qr.r_diag(),
        rows,
    };
    (ls, unweighted_fit(chans, &resid, w))
}

/// Residues, their standard errors and the residual terms of `nm` poles from `ls`.
fn residue_fit(
    nm: usize,
    res: Residuals,
    ls: LsSolution,
    synthesised: Vec<Vec<c64>>,
) -> ResidueFit {
    let LsSolution {
        x,
        scale,
        rss,
        ginv,
        r_diag: rd,
        rows,
    } = ls;
    let p = x.nrows();
    let basis_conditioning =
        rd.iter().cloned().fold(f64::INFINITY, f64::min) / rd.iter().cloned().fold(0.0, f64::max);
    let dof = (rows.saturating_sub(p)).max(1) as f64;
    let no = x.ncols();
    let mut residues = vec![vec![c64::new(0.0, 0.0); no]; nm];
    let mut residue_std = vec![vec![0.0; no]; nm];
    for o in 0..no {
        let s2 = rss[o] / dof;
        for m in 0..nm {
            let (ia, ib) = (2 * m, 2 * m + 1);
            residues[m][o] = c64::new(x[(ia, o)] / scale[ia], x[(ib, o)] / scale[ib]);
            let va = s2 * ginv[(ia, ia)] / (scale[ia] * scale[ia]);
            let vb = s2 * ginv[(ib, ib)] / (scale[ib] * scale[ib]);
            residue_std[m][o] = ((va + vb) / 2.0).sqrt();
        }
    }
    let mut k = 2 * nm;
    let mut take = |on: bool| -> Vec<f64> {
        if !on {
            return vec![0.0; no];
        }
        let v = (0..no).map(|o| x[(k, o)] / scale[k]).collect();
        k += 1;
        v
    };
    let upper = take(res.upper);
    let lower = take(res.lower);
    ResidueFit {
        residues,
        residue_std,
        upper,
        lower,
        rss,
        basis_conditioning,
        synthesised,
    }
}

/// The fitted FRFs `h − r/w` per channel from the weighted real-stacked residuals `r`
/// (`2N × channels`) of the data `h` with line weights `w`: the synthesis of
/// [`synthesise`] without evaluating the basis again (equal to rounding).
fn unweighted_fit(chans: &[Vec<c64>], resid: &Mat<f64>, w: &[f64]) -> Vec<Vec<c64>> {
    chans
        .iter()
        .enumerate()
        .map(|(o, h)| {
            let col = resid.col(o).try_as_col_major().unwrap().as_slice();
            let (re, im) = col.split_at(h.len());
            h.iter()
                .zip(re.iter().zip(im))
                .zip(w)
                .map(|((z, (r, i)), wk)| c64::new(z.re - r / wk, z.im - i / wk))
                .collect()
        })
        .collect()
}

/// Synthesised FRFs `[channel][line]` in the measured quantity.
pub fn synthesise(poles: &[Pole], fit: &ResidueFit, band: &BandData) -> Vec<Vec<c64>> {
    let q = band.quantity_factor();
    let no = fit.upper.len();
    let n = band.n_lines();
    // Residual terms first (the lower one is zero when the band starts at 0 Hz: no 0/0).
    let mut out: Vec<Vec<c64>> = (0..no)
        .map(|o| {
            band.omega
                .iter()
                .map(|&w| {
                    let lower = if fit.lower[o] != 0.0 {
                        fit.lower[o] / (w * w)
                    } else {
                        0.0
                    };
                    c64::new(fit.upper[o] - lower, 0.0)
                })
                .collect()
        })
        .collect();
    // The pole terms are shared by every channel: the pair's two basis functions once
    // per pole and line, then `a·(u + v) + b·i(u − v)` per channel.
    let mut b1 = vec![c64::new(0.0, 0.0); n];
    let mut b2 = vec![c64::new(0.0, 0.0); n];
    for (p, r) in poles.iter().zip(&fit.residues) {
        for ((x1, x2), &w) in b1.iter_mut().zip(b2.iter_mut()).zip(&band.omega) {
            (*x1, *x2) = pair_basis(p.0, w);
        }
        for (col, ro) in out.iter_mut().zip(r) {
            let (a, b) = (ro.re, ro.im);
            for ((hk, x1), x2) in col.iter_mut().zip(&b1).zip(&b2) {
                *hk += x1 * a + x2 * b;
            }
        }
    }
    for col in out.iter_mut() {
        for (hk, qk) in col.iter_mut().zip(&q) {
            *hk *= qk;
        }
    }
    out
}

/// Result of the pole refinement.
#[derive(Debug, Clone)]
pub struct Refined {
    /// The refined poles, in input order.
    pub poles: Vec<Pole>,
    /// Covariance of `(Re λ, Im λ)` per pole (rad/s)².
    pub covariance: Vec<[[f64; 2]; 2]>,
    /// `JᵀJ` was singular: some pole is not identifiable (two poles coincide).
    pub singular: bool,
    /// Gauss–Newton iterations taken.
    pub iterations: usize,
    /// Stopped at the minimum (negligible step or cost stall), not at the iteration limit.
    pub converged: bool,
    /// Weighted cost before and after.
    pub cost: (f64, f64),
    /// The LSFD solution at the final poles, kept for [`screen_extra_poles`].
    fit: std::sync::Arc<Trial>,
    /// The RMS of each input channel (the refinement fits them scaled to unit RMS).
    rms: Vec<f64>,
    /// Channels per block of the refinement's data (see [`BLOCK_BYTES`]).
    block: usize,
}

impl Refined {
    /// The residues `R` per mode and input channel at the refined poles, in the units of
    /// the channels given to [`refine`]: its last LSFD solution scaled back from unit
    /// RMS. The line weights are invariant to that scaling ([`line_weights`] levels each
    /// channel by its RMS), so these are [`fit_residues`] of the refined poles on the same
    /// channels, up to rounding, without fitting them again.
    pub fn residues(&self) -> Vec<Vec<c64>> {
        self.fit
            .residues
            .iter()
            .map(|r| r.iter().zip(&self.rms).map(|(r, s)| r * s).collect())
            .collect()
    }
}

/// The LSFD solution for one trial pole set (weighted data).
#[derive(Debug)]
struct Trial {
    cost: f64,
    /// The least-squares factorisation of the real-stacked (`[Re; Im]`),
    /// column-normalised basis `Φ̃` (`2N × p`).
    qr: TallLs,
    /// Residues `R = a + ib` per mode and channel.
    residues: Vec<Vec<c64>>,
    /// `Dᵀr_o`, one column per channel (`2M × channels`, `D` the derivative vectors at
    /// this trial's poles): all [`normal_equations`] needs of the residuals, so that
    /// they are never held whole.
    dtr: Mat<f64>,
    n_cols: usize,
    /// The line weights the basis and data carry.
    lw: std::sync::Arc<Vec<f64>>,
}

fn tmul(lhs: &Mat<f64>, rhs: &Mat<f64>) -> Mat<f64> {
    linalg::t_mul(lhs, rhs)
}

/// `R⁻ᵀ m` (forward substitution on the transposed triangular factor), i.e. `Qᵀ·X` from
/// `m = ΦᵀX`.
fn r_inv_t(qr: &TallLs, m: &Mat<f64>) -> Mat<f64> {
    let pc = qr.ncols();
    let mut y = Mat::<f64>::zeros(pc, m.ncols());
    for j in 0..m.ncols() {
        for i in 0..pc {
            let mut v = m[(i, j)];
            for l in 0..i {
                v -= qr.r(l, i) * y[(l, j)];
            }
            y[(i, j)] = v / qr.r(i, i);
        }
    }
    y
}

/// Bytes of weighted data per block of channels in [`refine`]'s trials (issue 41): the
/// trial's data and residuals are made block by block of channels, so that a bootstrap
/// replicate refining the poles of a set-up of 192 excitations holds its draws once (not
/// beside a weighted copy and two trials' residuals, each as large).
const BLOCK_BYTES: usize = 4 << 20;

/// Fewest channels per block: each block reads the basis (`2N × p`) again, so a block
/// narrower than the basis would spend more on it than on the data.
const MIN_BLOCK_CHANNELS: usize = 32;

/// Channels per block of [`refine`]'s data on `n_lines` lines.
fn block_channels(n_lines: usize) -> usize {
    (BLOCK_BYTES / (16 * n_lines.max(1))).max(MIN_BLOCK_CHANNELS)
}

/// The data [`refine`] fits: each channel scaled to unit RMS and weighted by the line
/// weights, made block by block of channels from the channels as given (no copy of them
/// all: see [`BLOCK_BYTES`]). The scaling is done as each block is made, with the same
/// operations as a scaled copy, so the blocks hold the values a copy would.
struct Weighted<'a> {
    chans: &'a dyn Channels,
    /// RMS of each channel.
    rms: Vec<f64>,
    /// The line weights of the unit-RMS channels ([`band_line_weights`]).
    lw: std::sync::Arc<Vec<f64>>,
    /// Channels per block.
    block: usize,
}

impl<'a> Weighted<'a> {
    fn new(band: &BandData, chans: &'a dyn Channels, block: usize) -> Self {
        let rms: Vec<f64> = (0..chans.count())
            .map(|o| channel_rms(&chans.channel(o)))
            .collect();
        let w = scaled_line_weights(chans, Some(&rms));
        Self {
            chans,
            rms,
            lw: std::sync::Arc::new(with_line_quality(band, w)),
            block: block.max(1),
        }
    }

    /// The same data with the scaling and weights of an earlier refinement of `chans`.
    fn of_refined(fit: &'a Refined, chans: &'a dyn Channels) -> Self {
        assert_eq!(
            chans.count(),
            fit.rms.len(),
            "the channels the refinement was given"
        );
        Self {
            chans,
            rms: fit.rms.clone(),
            lw: fit.fit.lw.clone(),
            block: fit.block,
        }
    }

    fn blocks(&self) -> impl Iterator<Item = std::ops::Range<usize>> + '_ {
        let no = self.chans.count();
        (0..no)
            .step_by(self.block)
            .map(move |s| s..(s + self.block).min(no))
    }

    /// The channels `range`, unit RMS, weighted, real-stacked (`2N × range.len()`),
    /// written over `spare` when it has that shape.
    fn stacked(&self, range: std::ops::Range<usize>, spare: Option<Mat<f64>>) -> Mat<f64> {
        let n = self.lw.len();
        let mut b = match spare {
            Some(m) if m.shape() == (2 * n, range.len()) => m,
            // Every entry is written below.
            _ => linalg::mat_for_overwrite(2 * n, range.len()),
        };
        for (j, o) in range.enumerate() {
            let col = b.col_mut(j).try_as_col_major_mut().unwrap().as_slice_mut();
            let (re, im) = col.split_at_mut(n);
            let s = self.rms[o];
            let h = self.chans.channel(o);
            let line = h.iter().zip(self.lw.iter());
            for ((r, i), (z, wk)) in re.iter_mut().zip(im.iter_mut()).zip(line) {
                let z = (z / s) * *wk;
                *r = z.re;
                *i = z.im;
            }
        }
        b
    }

    /// Solves every block on the basis `qr` and hands each to `each` with its
    /// coefficients, residuals and residual sums of squares; `spare` carries a block's
    /// storage to the next (and out, for the next call).
    fn solve_blocks(
        &self,
        qr: &TallLs,
        spare: &mut Option<Mat<f64>>,
        mut each: impl FnMut(std::ops::Range<usize>, &Mat<f64>, &Mat<f64>, Vec<f64>),
    ) {
        for range in self.blocks() {
            let (x, resid, rss) = qr.solve_into(self.stacked(range.clone(), spare.take()));
            each(range, &x, &resid, rss);
            *spare = Some(resid);
        }
    }
}

/// `(Σ_k |h_k|² / N)^½`.
fn channel_rms(h: &[c64]) -> f64 {
    (h.iter().map(|z| z.norm_sqr()).sum::<f64>() / h.len() as f64).sqrt()
}

/// The tall matrices of trials that are done with (rejected, or superseded by a better
/// one), reused by the next trial of the same refinement: its basis (`2N × p`) and a
/// block of residuals. Why: allocating a fresh, zeroed tall matrix per trial cost about
/// a fifth of the trial itself; every entry is overwritten anyway.
#[derive(Default)]
struct Spares {
    basis: Option<Mat<f64>>,
    resid: Option<Mat<f64>>,
}

impl Spares {
    /// Keeps the storage of `t` for the next trial.
    fn recycle(&mut self, t: Trial) {
        self.basis = Some(t.qr.into_matrix());
    }
}

/// The LSFD solution at `poles` of the weighted data, in the storage of `spares` when it
/// holds some, with the derivative vectors at `poles` (written into `d`, `2N × 2M`; `q`:
/// the weighted quantity factor, [`weighted_quantity_factor`]) against its residuals.
///
/// `d` is the refinement's one matrix of derivative vectors: it holds those of the last
/// trial made, which is the current one whenever [`normal_equations`] reads it (at the
/// start, and after each accepted step). Why not one per trial: at 1,601 lines and
/// eight poles it is 400 kB, and each fresh one costs page faults (issue 41's bench:
/// twice the system time).
fn trial(
    poles: &[Pole],
    band: &BandData,
    data: &Weighted,
    q: &(Vec<f64>, Vec<f64>),
    res: Residuals,
    spares: &mut Spares,
    d: &mut Mat<f64>,
) -> Trial {
    let n = band.n_lines();
    let mut phi = match spares.basis.take() {
        Some(m) => m,
        // Every entry is written by `basis_stacked_into`.
        None => linalg::mat_for_overwrite(2 * n, 2 * poles.len() + res.count()),
    };
    basis_stacked_into(&mut phi, poles, band, res, &data.lw);
    let scale = normalise(&mut phi);
    let p = phi.ncols();
    let qr = TallLs::new(phi);
    derivative_columns(d, poles, &band.omega, &q.0, &q.1);
    let no = data.chans.count();
    let mut residues = vec![Vec::with_capacity(no); poles.len()];
    let mut dtr = Mat::<f64>::zeros(d.ncols(), no);
    let mut rss = Vec::with_capacity(no);
    data.solve_blocks(&qr, &mut spares.resid, |range, x, resid, r| {
        for (m, rm) in residues.iter_mut().enumerate() {
            rm.extend((0..range.len()).map(|o| {
                c64::new(
                    x[(2 * m, o)] / scale[2 * m],
                    x[(2 * m + 1, o)] / scale[2 * m + 1],
                )
            }));
        }
        dtr.as_mut()
            .subcols_mut(range.start, range.len())
            .copy_from(tmul(d, resid));
        rss.extend(r);
    });
    Trial {
        cost: rss.iter().sum(),
        qr,
        residues,
        dtr,
        n_cols: p,
        lw: data.lw.clone(),
    }
}

/// The weighted cost `Σ_o ‖w (h_o/rms_o − Φ c_o)‖²` that [`refine`] minimised (at the
/// refined poles of `fit`, on the same `band` and `chans`), and the same cost with each
/// candidate pole added in turn (residues re-fitted, poles fixed): used to screen
/// candidates for the model-order test.
///
/// One QR serves every candidate. The candidate's two basis columns `N` are projected
/// off the current basis (`Ñ = P⊥N`, `ÑᵀÑ = NᵀN − (QᵀN)ᵀQᵀN`, `QᵀN = R⁻ᵀΦᵀN`); as the
/// residuals `r_o` are already orthogonal to the basis, the cost drops by
/// `Σ_o (Nᵀr_o)ᵀ(ÑᵀÑ)⁻¹(Nᵀr_o)` — O(N·(p + channels)) per candidate instead of a QR.
/// The refinement's own factorisation is reused (it is the basis at `fit.poles`); its
/// residuals are made again block by block from `chans` (the refined channels), with
/// the refinement's operations, so they are its residuals.
pub fn screen_extra_poles<C: AsRef<[c64]>>(
    fit: &Refined,
    candidates: &[Pole],
    band: &BandData,
    chans: &[C],
) -> (f64, Vec<f64>) {
    let t = &*fit.fit;
    if candidates.is_empty() {
        return (t.cost, Vec::new());
    }
    // Every candidate's two columns side by side, unnormalised: N (2N × 2K).
    let nm = basis_stacked(candidates, band, Residuals::NONE, &t.lw);
    // y = QᵀN by forward substitution on Rᵀ; Nᵀr per channel.
    let y = r_inv_t(&t.qr, &tmul(t.qr.matrix(), &nm));
    let mut nr = Mat::<f64>::zeros(nm.ncols(), chans.len());
    Weighted::of_refined(fit, &Slices(chans)).solve_blocks(
        &t.qr,
        &mut None,
        |range, _, resid, _| {
            nr.as_mut()
                .subcols_mut(range.start, range.len())
                .copy_from(tmul(&nm, resid));
        },
    );
    let pc = t.n_cols;
    let with = (0..candidates.len())
        .map(|c| {
            let (j0, j1) = (2 * c, 2 * c + 1);
            let col = |j: usize| nm.col(j).try_as_col_major().unwrap().as_slice();
            let g = |a: usize, b: usize| {
                linalg::dot(col(a), col(b)) - (0..pc).map(|l| y[(l, a)] * y[(l, b)]).sum::<f64>()
            };
            let (g00, g01, g11) = (g(j0, j0), g(j0, j1), g(j1, j1));
            let det = g00 * g11 - g01 * g01;
            // A candidate in the span of the basis (det ≈ 0) explains nothing new.
            if !(det > 1e-12 * g00.max(g11).powi(2)) {
                return t.cost;
            }
            let drop: f64 = (0..nr.ncols())
                .map(|o| {
                    let (b0, b1) = (nr[(j0, o)], nr[(j1, o)]);
                    (g11 * b0 * b0 - 2.0 * g01 * b0 * b1 + g00 * b1 * b1) / det
                })
                .sum();
            (t.cost - drop).max(0.0)
        })
        .collect();
    (t.cost, with)
}

/// Levenberg–Marquardt on the variable-projection functional (Golub & Pereyra; Kaufman's
/// Jacobian `J = −P⊥ (∂Φ/∂θ) c`): minimises `Σ_o ‖w_o (h_o − Φ(λ) c_o)‖²` over the poles,
/// the residues being the LSFD solution for each trial set (`w_o` = 1/RMS of channel o).
/// For noise-free data this converges to the exact poles, which the polynomial
/// (LSCF/LSCE) estimators only approach; with noise it is the least-squares estimate,
/// and `σ²(JᵀJ)⁻¹` its covariance.
///
/// Cost: with `∂Φ/∂Re λ_m · c = a d1 + b d2`, `∂Φ/∂Im λ_m · c = a d2 − b d1`
/// (`d1 = q(u + u')`, `d2 = q·i(u − u')`, `u = (iω−λ)⁻²`, `u' = (iω−λ*)⁻²`, `R = a + ib`),
/// `JᵀJ` and `Jᵀr` only need the Gram matrix `DᵀP⊥D` of the `2M` vectors `d` and `Dᵀr_o`:
/// O(N·M·(M + p + channels)) per iteration instead of forming J.
///
/// Memory: the channels are read as given; each trial makes its weighted data and
/// residuals a block of channels at a time ([`BLOCK_BYTES`]) and keeps only `Dᵀr_o`.
pub fn refine<C: AsRef<[c64]>>(
    poles: &[Pole],
    band: &BandData,
    chans: &[C],
    res: Residuals,
) -> Refined {
    refine_channels(poles, band, &Slices(chans), res)
}

/// [`refine`] of channels read through [`Channels`] (each once per trial, a block at a
/// time): bit for bit what [`refine`] gives for the same values held.
pub fn refine_channels(
    poles: &[Pole],
    band: &BandData,
    chans: &dyn Channels,
    res: Residuals,
) -> Refined {
    refine_in_blocks(poles, band, chans, res, block_channels(band.n_lines()))
}

/// [`refine`] with `block` channels per block of data.
fn refine_in_blocks(
    poles: &[Pole],
    band: &BandData,
    chans: &dyn Channels,
    res: Residuals,
    block: usize,
) -> Refined {
    let n = band.n_lines();
    let no = chans.count();
    let data = Weighted::new(band, chans, block);
    let q = weighted_quantity_factor(band, &data.lw);
    let nm = poles.len();
    let np = 2 * nm;
    let mut cur: Vec<Pole> = poles.to_vec();
    let mut spares = Spares::default();
    // Every entry is written by each trial (`derivative_columns`).
    let mut d = linalg::mat_for_overwrite(2 * n, np);
    let mut t = trial(&cur, band, &data, &q, res, &mut spares, &mut d);
    let cost0 = t.cost;
    // Residual degrees of freedom (the basis has the same columns at every trial).
    let dof = (2 * n * no).saturating_sub(no * t.n_cols + np).max(1) as f64;
    let mut mu = 1e-3;
    let mut converged = false;
    let mut iterations = 0;
    let mut jtj = Mat::<f64>::zeros(np, np);
    for it in 0..40 {
        iterations = it + 1;
        let g = normal_equations(&d, &t, &mut jtj);
        // Converged when even the undamped Gauss–Newton step predicts a cost drop below
        // the stall tolerance (see below): saves evaluating a step that cannot matter.
        let gn_rhs = Mat::from_fn(np, 1, |i, _| g[i]);
        let mut gn_drop = None;
        if let Some(gn) = linalg::solve_square(&jtj, &gn_rhs) {
            let predicted: f64 = (0..np).map(|i| gn[(i, 0)] * g[i]).sum();
            if predicted.is_finite() && predicted >= 0.0 && predicted <= 1e-10 * t.cost {
                converged = true;
                break;
            }
            gn_drop = Some(predicted).filter(|d| d.is_finite());
        }
        // LM step with Marquardt scaling; more damping until the cost drops.
        let mut accepted = false;
        for _ in 0..12 {
            let lhs = Mat::from_fn(np, np, |i, j| {
                jtj[(i, j)] + if i == j { mu * jtj[(i, i)] } else { 0.0 }
            });
            let rhs = Mat::from_fn(np, 1, |i, _| g[i]);
            let Some(step) = linalg::solve_square(&lhs, &rhs) else {
                mu *= 10.0;
                continue;
            };
            let cand: Vec<Pole> = cur
                .iter()
                .enumerate()
                .map(|(m, p)| Pole(p.0 + c64::new(step[(2 * m, 0)], step[(2 * m + 1, 0)])))
                .collect();
            if cand.iter().any(|p| !(p.0.re < 0.0 && p.0.im > 0.0)) {
                mu *= 10.0;
                continue;
            }
            let t2 = trial(&cand, band, &data, &q, res, &mut spares, &mut d);
            if t2.cost <= t.cost {
                let rel_step = (0..nm)
                    .map(|m| {
                        c64::new(step[(2 * m, 0)], step[(2 * m + 1, 0)]).norm()
                            / cur[m].half_bandwidth().max(1e-300)
                    })
                    .fold(0.0, f64::max);
                // Converged when the step is negligible or the cost stalls: a relative
                // drop of 1e-10 of a cost ≈ ν·s² means the remaining step is about
                // √(1e-10·ν) ≈ 1e-3 of a standard error for ν ~ 10⁴ residuals.
                let small = rel_step < 1e-9 || (t.cost - t2.cost) <= 1e-10 * t.cost;
                // Also converged after a step whose predicted drop was below 0.1 σ² (a
                // step of at most ~0.3 standard errors) when the cost fell as predicted:
                // Gauss–Newton on this small-residual problem converges quadratically,
                // so what is left is ~1e-3 standard error (on the timing workload the
                // next linearisation predicts 1e-5–1e-7 σ²). Saves the linearisation
                // that would only confirm it; the covariance then uses the JᵀJ of this
                // step's start, 0.3 standard errors away.
                let s2 = t.cost / dof;
                let settled = gn_drop.is_some_and(|d| d <= 0.1 * s2 && t.cost - t2.cost >= 0.5 * d);
                let small = small || settled;
                cur = cand;
                spares.recycle(std::mem::replace(&mut t, t2));
                mu = (mu / 10.0).max(1e-12);
                accepted = true;
                converged = small;
                break;
            }
            spares.recycle(t2);
            mu *= 10.0;
        }
        if !accepted {
            // No descent left: at the minimum to working precision.
            converged = true;
        }
        if converged {
            break;
        }
    }
    // Covariance σ²(JᵀJ)⁻¹ (JᵀJ of the last linearisation).
    let (covariance, singular) = pole_covariance(&jtj, t.cost / dof, nm);
    Refined {
        poles: cur,
        covariance,
        singular,
        iterations,
        converged,
        cost: (cost0, t.cost),
        fit: std::sync::Arc::new(t),
        rms: data.rms,
        block,
    }
}

/// `q(ω)·w` per line as real and imaginary parts (`q` the quantity factor, `w` the
/// line weights), for the derivative columns.
fn weighted_quantity_factor(band: &BandData, lw: &[f64]) -> (Vec<f64>, Vec<f64>) {
    band.quantity_factor()
        .iter()
        .zip(lw.iter())
        .map(|(q, w)| {
            let z = q * *w;
            (z.re, z.im)
        })
        .unzip()
}

/// `JᵀJ` (into `jtj`) and `−Jᵀr` of [`refine`] at the trial `t`, from its derivative
/// vectors `d` (`2N × 2M`): `JᵀJ` over the channels from the projected Gram matrix
/// `G_D = DᵀP⊥D` and each channel's residues, `Jᵀr` from `Dᵀr_o`.
fn normal_equations(d: &Mat<f64>, t: &Trial, jtj: &mut Mat<f64>) -> Vec<f64> {
    let np = d.ncols();
    let no = t.dtr.ncols();
    // G_D = DᵀD − (QᵀD)ᵀ(QᵀD), QᵀD = R⁻ᵀ Φ̃ᵀD; all products by matrix multiplication.
    let pc = t.n_cols;
    let y = r_inv_t(&t.qr, &tmul(t.qr.matrix(), d));
    let dd = linalg::gram(d);
    let mut gd = Mat::<f64>::zeros(np, np);
    for i in 0..np {
        for j in 0..=i {
            let mut v = dd[(i, j)];
            for l in 0..pc {
                v -= y[(l, i)] * y[(l, j)];
            }
            gd[(i, j)] = v;
            gd[(j, i)] = v;
        }
    }
    // JᵀJ and Jᵀr over channels; e-vectors: θ=Re λ_m → (a, b) on (d1, d2),
    // θ=Im λ_m → (−b, a).
    let mut g = vec![0.0; np];
    for v in jtj.col_iter_mut() {
        for x in v.iter_mut() {
            *x = 0.0;
        }
    }
    let dr: Vec<Vec<f64>> = (0..np)
        .map(|j| (0..no).map(|o| t.dtr[(j, o)]).collect())
        .collect();
    for o in 0..no {
        let e = |j: usize| -> (usize, f64, f64) {
            let m = j / 2;
            let r = t.residues[m][o];
            if j % 2 == 0 {
                (m, r.re, r.im)
            } else {
                (m, -r.im, r.re)
            }
        };
        for j in 0..np {
            let (mj, x1, x2) = e(j);
            g[j] += x1 * dr[2 * mj][o] + x2 * dr[2 * mj + 1][o];
            for k in 0..=j {
                let (mk, y1, y2) = e(k);
                let v = x1 * (y1 * gd[(2 * mj, 2 * mk)] + y2 * gd[(2 * mj, 2 * mk + 1)])
                    + x2 * (y1 * gd[(2 * mj + 1, 2 * mk)] + y2 * gd[(2 * mj + 1, 2 * mk + 1)]);
                jtj[(j, k)] += v;
                if k != j {
                    jtj[(k, j)] += v;
                }
            }
        }
    }
    g
}

/// The poles' covariances `σ²(JᵀJ)⁻¹` (2 × 2 per pole: Re λ, Im λ) with `s2 = σ²`, and
/// whether `JᵀJ` is singular (then zero covariances).
fn pole_covariance(jtj: &Mat<f64>, s2: f64, nm: usize) -> (Vec<[[f64; 2]; 2]>, bool) {
    let np = 2 * nm;
    let inv = linalg::solve_square(jtj, &Mat::identity(np, np));
    let covariance = (0..nm)
        .map(|m| match &inv {
            Some(ci) => [
                [s2 * ci[(2 * m, 2 * m)], s2 * ci[(2 * m, 2 * m + 1)]],
                [s2 * ci[(2 * m + 1, 2 * m)], s2 * ci[(2 * m + 1, 2 * m + 1)]],
            ],
            None => [[0.0; 2]; 2],
        })
        .collect();
    (covariance, inv.is_none())
}

/// Columns 2m and 2m + 1 of a real-stacked matrix (rows 0..n the real parts, n..2n the
/// imaginary parts) as the slices (re₁, im₁, re₂, im₂), for loops that vectorise.
fn pair_halves(
    a: &mut Mat<f64>,
    m: usize,
    n: usize,
) -> (&mut [f64], &mut [f64], &mut [f64], &mut [f64]) {
    let (c1, c2) = a.as_mut().two_cols_mut(2 * m, 2 * m + 1);
    let c1 = c1
        .try_as_col_major_mut()
        .expect("column-major")
        .as_slice_mut();
    let c2 = c2
        .try_as_col_major_mut()
        .expect("column-major")
        .as_slice_mut();
    let (r1, i1) = c1.split_at_mut(n);
    let (r2, i2) = c2.split_at_mut(n);
    (r1, i1, r2, i2)
}

/// 1/(iω − λ) and 1/(iω − λ*) as (re, im, re, im) for the pole λ = −x + i·pim, in
/// plain real arithmetic so that the loops over lines calling it vectorise.
#[inline(always)]
fn pole_reciprocals(x: f64, pim: f64, w: f64) -> (f64, f64, f64, f64) {
    let (y1, y2) = (w - pim, w + pim);
    let (v1, v2) = (1.0 / (x * x + y1 * y1), 1.0 / (x * x + y2 * y2));
    (x * v1, -y1 * v1, x * v2, -y2 * v2)
}

rbprops_core::avx_fn! {
    /// [`refine`]'s derivative vectors `d1_m, d2_m` for the poles `cur`, real-stacked
    /// into `d` (2N × 2M), with `(qre, qim)` the weighted quantity factors.
    fn derivative_columns(d: &mut Mat<f64>, cur: &[Pole], omega: &[f64], qre: &[f64], qim: &[f64]) -> () {
        let n = omega.len();
        for (m, p) in cur.iter().enumerate() {
            let (r1, i1, r2, i2) = pair_halves(d, m, n);
            let (x, pim) = (-p.0.re, p.0.im);
            let cols = r1
                .iter_mut()
                .zip(i1.iter_mut())
                .zip(r2.iter_mut().zip(i2.iter_mut()));
            let line = omega.iter().zip(qre.iter().zip(qim));
            for (((r1, i1), (r2, i2)), (&w, (&qr, &qi))) in cols.zip(line) {
                // a1 = 1/(iω − λ), a2 = 1/(iω − λ*); u = a1², u2 = a2².
                let (a1r, a1i, a2r, a2i) = pole_reciprocals(x, pim, w);
                let (ur, ui) = (a1r * a1r - a1i * a1i, a1r * a1i + a1i * a1r);
                let (u2r, u2i) = (a2r * a2r - a2i * a2i, a2r * a2i + a2i * a2r);
                // d1 = q(u + u2), d2 = q·i(u − u2).
                let (sr, si) = (ur + u2r, ui + u2i);
                let (er, ei) = (ur - u2r, ui - u2i);
                let (tr, ti) = (-ei, er);
                *r1 = qr * sr - qi * si;
                *i1 = qr * si + qi * sr;
                *r2 = qr * tr - qi * ti;
                *i2 = qr * ti + qi * tr;
            }
        }
    }
}

#[cfg(test)]
mod tests;
