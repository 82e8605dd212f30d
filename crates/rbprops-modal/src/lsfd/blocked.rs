//! [`super::fit_residues`] by blocks of lines: the normal equations of the shared basis
//! accumulated block by block, then the residuals block by block, with each block's
//! basis rebuilt in cache for each pass instead of one `2N × p` matrix (≈ 1 MB for
//! 4,096 lines and 6 poles) streamed from memory several times.
//!
//! Solved as [`linalg::TallLs`] does: the Cholesky factor of the Gram matrix of the normalised
//! basis while it is well conditioned, with one refinement step on the residual below
//! [`linalg::TallLs::REFINE_BELOW`]; `None` below [`linalg::TallLs::GRAM_LIMIT`] (the caller then uses
//! Householder QR of the whole basis).

use super::{pair_columns, LsSolution, Residuals};
use crate::band::BandData;
use crate::linalg;
use crate::pole::Pole;
use faer::{Mat, MatMut, MatRef};
use rbprops_core::c64;

/// Lines per block: the block's basis, data and residuals (2·256 rows × (p + 2·channels)
/// values, ≈ 130 kB for 6 poles and 9 channels) stay in the second-level cache.
const BLOCK: usize = 256;

/// The least-squares solution for `chans` weighted by `w` on the basis of `poles` (and
/// the residual terms `res`), and the fitted FRFs `h − r/w`; `None` when the
/// normalised basis is too ill-conditioned for its Gram matrix.
pub(super) fn solve(
    poles: &[Pole],
    band: &BandData,
    chans: &[Vec<c64>],
    res: Residuals,
    w: &[f64],
) -> Option<(LsSolution, Vec<Vec<c64>>)> {
    let b = Blocks::new(poles, band, chans, res, w);
    let p = b.p;
    let (g, c) = b.normal_equations();
    let scale: Vec<f64> = (0..p)
        .map(|j| match g[(j, j)].sqrt() {
            s if s > 0.0 => s,
            _ => 1.0,
        })
        .collect();
    let gn = Mat::from_fn(p, p, |i, j| g[(i, j)] / (scale[i] * scale[j]));
    let r = linalg::cholesky_upper(&gn)?;
    let refine = linalg::gram_usable(&r)?;
    // Normalised coefficients x̃ = (ÃᵀÃ)⁻¹Ãᵀb with Ãᵀb = D⁻¹Aᵀb; A x = Ã x̃ for x = D⁻¹x̃.
    let unscale = |m: &Mat<f64>| Mat::from_fn(p, m.ncols(), |i, j| m[(i, j)] / scale[i]);
    let mut xn = unscale(&c);
    linalg::cholesky_solve(&r, &mut xn);
    let mut pass = b.residuals(&unscale(&xn), refine);
    if refine {
        // One refinement step: x̃ += (ÃᵀÃ)⁻¹Ãᵀr.
        let mut dx = unscale(&pass.atr);
        linalg::cholesky_solve(&r, &mut dx);
        xn = xn + dx;
        pass = b.residuals(&unscale(&xn), false);
    }
    let ginv = linalg::inverse_gram_of(p, |i, j| if i <= j { r[(i, j)] } else { 0.0 });
    let ls = LsSolution {
        x: xn,
        scale,
        rss: pass.rss,
        ginv,
        r_diag: (0..p).map(|i| r[(i, i)].abs()).collect(),
        rows: 2 * band.n_lines(),
    };
    Some((ls, pass.fitted))
}

/// The basis and weighted data, block by block.
struct Blocks<'a> {
    poles: &'a [Pole],
    omega: &'a [f64],
    /// The quantity factor times the line weight, real and imaginary parts.
    qre: Vec<f64>,
    qim: Vec<f64>,
    res: Residuals,
    chans: &'a [Vec<c64>],
    w: &'a [f64],
    p: usize,
}

/// One pass of residuals.
struct Pass {
    rss: Vec<f64>,
    /// `Aᵀr` (unnormalised basis), `p × channels` (empty unless asked for).
    atr: Mat<f64>,
    /// `h − r/w` per channel and line (empty when `atr` was asked for).
    fitted: Vec<Vec<c64>>,
}

impl<'a> Blocks<'a> {
    fn new(
        poles: &'a [Pole],
        band: &'a BandData,
        chans: &'a [Vec<c64>],
        res: Residuals,
        w: &'a [f64],
    ) -> Self {
        let (qre, qim) = band
            .quantity_factor()
            .iter()
            .zip(w)
            .map(|(q, w)| {
                let z = q * *w;
                (z.re, z.im)
            })
            .unzip();
        Self {
            poles,
            omega: &band.omega,
            qre,
            qim,
            res,
            chans,
            w,
            p: 2 * poles.len() + res.count(),
        }
    }

    /// The blocks `(first line, lines)`.
    fn spans(&self) -> impl Iterator<Item = (usize, usize)> {
        let n = self.omega.len();
        (0..n).step_by(BLOCK).map(move |k0| (k0, BLOCK.min(n - k0)))
    }

    /// Basis (`2b × p`) and weighted data (`2b × channels`) of the `b` lines from `k0`,
    /// real-stacked, column-major.
    fn load(&self, k0: usize, b: usize, phi: &mut Vec<f64>, dat: &mut Vec<f64>) {
        let r = 2 * b;
        phi.resize(r * self.p, 0.0);
        dat.resize(r * self.chans.len(), 0.0);
        let span = k0..k0 + b;
        block_basis(
            self.poles,
            &self.omega[span.clone()],
            &self.qre[span.clone()],
            &self.qim[span.clone()],
            self.res,
            phi,
        );
        block_data(self.chans, &self.w[span], k0, dat);
    }

    /// `(AᵀA, Aᵀb)` of the unnormalised basis (block products by faer's sequential
    /// matrix multiplication, see [`linalg::t_mul_add`]; the symmetric `AᵀA` on its lower
    /// triangle, see [`linalg::gram`]).
    fn normal_equations(&self) -> (Mat<f64>, Mat<f64>) {
        let (p, no) = (self.p, self.chans.len());
        let (mut g, mut c) = (Mat::<f64>::zeros(p, p), Mat::<f64>::zeros(p, no));
        let (mut phi, mut dat) = (Vec::new(), Vec::new());
        for (k0, b) in self.spans() {
            self.load(k0, b, &mut phi, &mut dat);
            let phi = MatRef::from_column_major_slice(&phi, 2 * b, p);
            let dat = MatRef::from_column_major_slice(&dat, 2 * b, no);
            linalg::gram_lower_add(&mut g, phi);
            linalg::t_mul_add(&mut c, phi, dat, 1.0);
        }
        linalg::mirror_lower(&mut g);
        (g, c)
    }

    /// Residuals `b − A x` (`x` for the unnormalised basis): their sum of squares per
    /// channel, and `Aᵀr` when `atr`, else the fitted FRFs.
    fn residuals(&self, x: &Mat<f64>, atr: bool) -> Pass {
        let (p, no, n) = (self.p, self.chans.len(), self.omega.len());
        let mut rss = vec![0.0; no];
        let mut g = Mat::<f64>::zeros(if atr { p } else { 0 }, no);
        let mut fitted = if atr {
            Vec::new()
        } else {
            vec![Vec::with_capacity(n); no]
        };
        let (mut phi, mut dat) = (Vec::new(), Vec::new());
        for (k0, b) in self.spans() {
            self.load(k0, b, &mut phi, &mut dat);
            let r = 2 * b;
            {
                let phi = MatRef::from_column_major_slice(&phi, r, p);
                let mut resid = MatMut::from_column_major_slice_mut(&mut dat, r, no);
                linalg::mul_add_into(resid.as_mut(), phi, x.as_ref(), -1.0);
                if atr {
                    linalg::t_mul_add(&mut g, phi, resid.as_ref(), 1.0);
                }
            }
            for (s, ro) in rss.iter_mut().zip(dat.chunks_exact(r)) {
                *s += linalg::dot(ro, ro);
            }
            for (o, f) in fitted.iter_mut().enumerate() {
                let (re, im) = dat[o * 2 * b..(o + 1) * 2 * b].split_at(b);
                let h = &self.chans[o][k0..k0 + b];
                let w = &self.w[k0..k0 + b];
                f.extend((0..b).map(|k| c64::new(h[k].re - re[k] / w[k], h[k].im - im[k] / w[k])));
            }
        }
        Pass {
            rss,
            atr: g,
            fitted,
        }
    }
}

rbprops_core::avx_fn! {
    /// The pole pairs' columns and the residual terms (`q`, `q·(−1/ω²)`) of one block.
    fn block_basis(
        poles: &[Pole],
        omega: &[f64],
        qre: &[f64],
        qim: &[f64],
        res: Residuals,
        phi: &mut [f64],
    ) -> () {
        let b = omega.len();
        let mut cols = phi.chunks_exact_mut(2 * b);
        for p in poles {
            let (c1, c2) = (cols.next().unwrap(), cols.next().unwrap());
            let ((r1, i1), (r2, i2)) = (c1.split_at_mut(b), c2.split_at_mut(b));
            let (x, pim) = (-p.0.re, p.0.im);
            let out = r1.iter_mut().zip(i1.iter_mut()).zip(r2.iter_mut().zip(i2.iter_mut()));
            let line = omega.iter().zip(qre.iter().zip(qim));
            for (((r1, i1), (r2, i2)), (&w, (&qr, &qi))) in out.zip(line) {
                (*r1, *i1, *r2, *i2) = pair_columns(x, pim, w, qr, qi);
            }
        }
        if res.upper {
            let (re, im) = cols.next().unwrap().split_at_mut(b);
            re.copy_from_slice(qre);
            im.copy_from_slice(qim);
        }
        if res.lower {
            let (re, im) = cols.next().unwrap().split_at_mut(b);
            for k in 0..b {
                let s = -1.0 / (omega[k] * omega[k]);
                re[k] = qre[k] * s;
                im[k] = qim[k] * s;
            }
        }
    }
}

rbprops_core::avx_fn! {
    /// Weighted data `w h` of the lines from `k0` (`w` already restricted to them).
    fn block_data(chans: &[Vec<c64>], w: &[f64], k0: usize, dat: &mut [f64]) -> () {
        let b = w.len();
        for (col, h) in dat.chunks_exact_mut(2 * b).zip(chans) {
            let (re, im) = col.split_at_mut(b);
            for (k, z) in h[k0..k0 + b].iter().enumerate() {
                re[k] = z.re * w[k];
                im[k] = z.im * w[k];
            }
        }
    }
}
