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
use crate::pole::Pole;
use crate::roots;
use rbprops_core::c64;

/// Poles of one model order with a shape (relative residue per channel) for each.
#[derive(Debug, Clone)]
pub struct OrderPoles {
    /// Denominator degree `n` (number of poles of the polynomial, both half-planes).
    pub order: usize,
    /// The poles found at this order.
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

/// Per-line powers of a block for [`sums`], `[re, im]` of `SUM_BLOCK` powers.
type BlockPowers = [[f64; SUM_BLOCK]; 2];
/// Powers per block of [`sums`].
const SUM_BLOCK: usize = 8;

/// A table of powers of [`sums`] and the axis it was built for.
struct PowerTable {
    /// The angles `θ_k`.
    theta: Vec<f64>,
    /// Powers `0..pm`.
    pm: usize,
    /// `[block][line]` (see [`sums`]).
    table: Vec<BlockPowers>,
}

/// Tables of powers kept per thread (the most recently used last).
const KEPT_POWER_TABLES: usize = 6;

thread_local! {
    /// The tables of powers of the last [`sums`] on this thread, for the next ones.
    ///
    /// Why more than storage: every excitation of a campaign shares the frequency axis,
    /// so the whole-band locator sweeps of all of them run on the same decimated lines,
    /// and the sub-bands of the full and safety sweeps often coincide too (they follow
    /// the modes). A table built for exactly these angles (bitwise) and powers is the
    /// same table again, and its sines and cosines are most of its cost.
    static POWER_TABLES: std::cell::RefCell<Vec<PowerTable>> = const { std::cell::RefCell::new(Vec::new()) };
}

rbprops_core::avx_fn! {
fn sums(theta: &[f64], chans: &[Vec<c64>], weights: &[Vec<f64>], n_max: usize) -> Sums {
    let no = chans.len();
    let nl = theta.len();
    let pm = n_max + 1;
    // Per block of `B` powers and channel, the four sums run over the lines in
    // registers (the same additions in the same order as line by line). Eight powers
    // (two AVX vectors per sum, eight accumulators): each line's weight and data are
    // loaded once for twice the powers of a block of four, which more than pays for
    // the wider zero padding of the last block (−0.4M instructions per excitation).
    const B: usize = SUM_BLOCK;
    let blocks = pm.div_ceil(B);
    // The powers z_k^m, per block of powers and line (see `build_powers`), shared by
    // every channel. The table is kept for the next sweeps on this thread (see `POWER_TABLES`): taken
    // out here when one was built for these angles and powers, else built in the
    // storage of the least recently used one (every entry is written, padding
    // included: not allocated and zero-filled every sweep; it is most of the sweep's
    // memory), and put back at the end.
    let same = |p: &PowerTable| {
        p.pm == pm
            && p.theta.len() == nl
            && p.theta.iter().zip(theta).all(|(a, b)| a.to_bits() == b.to_bits())
    };
    let mut kept = POWER_TABLES.with(|t| {
        let mut t = t.borrow_mut();
        match t.iter().position(same) {
            Some(i) => Some(t.remove(i)),
            None if t.len() >= KEPT_POWER_TABLES => {
                let mut p = t.remove(0);
                p.pm = usize::MAX;
                Some(p)
            }
            None => None,
        }
    })
    .unwrap_or(PowerTable { theta: Vec::new(), pm: usize::MAX, table: Vec::new() });
    if kept.pm != pm {
        build_powers(&mut kept, theta, pm);
    }
    let table = &kept.table[..blocks * nl];
    let mut s = Sums {
        r: vec![vec![0.0; pm]; no],
        g_pos: vec![vec![0.0; pm]; no],
        g_neg: vec![vec![0.0; pm]; no],
        t: vec![vec![0.0; pm]; no],
    };
    let hw: Vec<Vec<c64>> = (0..no)
        .map(|o| chans[o].iter().zip(&weights[o]).map(|(h, w2)| h * *w2).collect())
        .collect();
    let h2: Vec<Vec<f64>> = (0..no)
        .map(|o| {
            chans[o]
                .iter()
                .zip(&weights[o])
                .map(|(h, w2)| h.norm_sqr() * w2)
                .collect()
        })
        .collect();
    for blk in 0..blocks {
        let m0 = blk * B;
        let nb = B.min(pm - m0);
        let zt = &table[blk * nl..(blk + 1) * nl];
        for o in 0..no {
            let (w, hw, h2) = (&weights[o][..nl], &hw[o][..nl], &h2[o][..nl]);
            // The last block is often a single power (orders 24 and 40: 25 and 41
            // powers); four lanes do it at about half the cost of eight.
            let [r, gp, gn, t] = if nb <= 4 {
                block_sums::<4, B>(zt, w, hw, h2).map(|x| {
                    let mut y = [0.0; B];
                    y[..4].copy_from_slice(&x);
                    y
                })
            } else {
                block_sums::<B, B>(zt, w, hw, h2)
            };
            s.r[o][m0..m0 + nb].copy_from_slice(&r[..nb]);
            s.g_pos[o][m0..m0 + nb].copy_from_slice(&gp[..nb]);
            s.g_neg[o][m0..m0 + nb].copy_from_slice(&gn[..nb]);
            s.t[o][m0..m0 + nb].copy_from_slice(&t[..nb]);
        }
    }
    POWER_TABLES.with(|t| t.borrow_mut().push(kept));
    s
}
}

/// Builds `p`'s table of powers `0..pm` at the angles `theta` (see [`sums`]).
fn build_powers(p: &mut PowerTable, theta: &[f64], pm: usize) {
    const B: usize = SUM_BLOCK;
    let nl = theta.len();
    let blocks = pm.div_ceil(B);
    // Powers z_k^m by recurrence, re-anchored every 16 steps to bound rounding drift;
    // one table per block of powers, `[line]` of `[re, im]` of `B` powers (zero-padded),
    // shared by every channel. Blocks outermost: each block's table (128 bytes a line)
    // stays in cache while every channel runs over it, where the whole table would not.
    // Its length is the largest yet (grown without copying the stale contents).
    if p.table.len() < blocks * nl {
        p.table.clear();
        p.table.resize(blocks * nl, [[0.0; B]; 2]);
    }
    let table = &mut p.table[..blocks * nl];
    for (k, &th) in theta.iter().enumerate() {
        let z = c64::new(th.cos(), th.sin());
        let mut zm = c64::new(1.0, 0.0);
        for blk in 0..blocks {
            let [re, im] = &mut table[blk * nl + k];
            let nb = B.min(pm - blk * B);
            for i in 0..nb {
                let m = blk * B + i;
                if m > 0 {
                    zm = if m % 16 == 0 {
                        let a = th * m as f64;
                        c64::new(a.cos(), a.sin())
                    } else {
                        zm * z
                    };
                }
                re[i] = zm.re;
                im[i] = zm.im;
            }
            re[nb..].fill(0.0);
            im[nb..].fill(0.0);
        }
    }
    p.theta.clear();
    p.theta.extend_from_slice(theta);
    p.pm = pm;
}

/// One channel's `[r, Re g(m), Re g(−m), t]` over the lines for the first `W` powers
/// of a block's table (`zt`: per line, re and im of the block's powers), each power's
/// sum over the lines in order, in registers.
#[inline(always)]
fn block_sums<const W: usize, const B: usize>(
    zt: &[[[f64; B]; 2]],
    w: &[f64],
    hw: &[c64],
    h2: &[f64],
) -> [[f64; W]; 4] {
    let (mut r, mut gp, mut gn, mut t) = ([0.0; W], [0.0; W], [0.0; W], [0.0; W]);
    for k in 0..w.len() {
        let (w2, hk, h2) = (w[k], hw[k], h2[k]);
        let [pr, pi] = &zt[k];
        // Only real parts enter the normal matrices: Re(h z^m) = a − b and
        // Re(h z^−m) = a + b with a = Re h Re z^m, b = Im h Im z^m.
        for i in 0..W {
            let a = hk.re * pr[i];
            let b = hk.im * pi[i];
            r[i] += w2 * pr[i];
            gp[i] += a - b;
            gn[i] += a + b;
            t[i] += h2 * pr[i];
        }
    }
    [r, gp, gn, t]
}

/// Channels per SIMD group of the factor recursion (see [`Factors`]).
const LANES: usize = 4;
/// One value per channel of a group.
type Lanes = [f64; LANES];

/// `v − Σ_m a_m b_m` in every lane, summed in index order (each lane bitwise the plain
/// scalar sum).
///
/// Four terms per loop step, still subtracted one after the other: the sums here are
/// short (up to the model order), and the loop's own counting and bounds checks cost
/// as much as the one vector multiply-subtract of each term.
#[inline(always)]
fn sub_lanes(mut v: Lanes, a: &[Lanes], b: &[Lanes]) -> Lanes {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for i in 0..4 {
            for t in 0..LANES {
                v[t] -= x[i][t] * y[i][t];
            }
        }
    }
    for (x, y) in ra.iter().zip(rb) {
        for t in 0..LANES {
            v[t] -= x[t] * y[t];
        }
    }
    v
}

/// [`sub_lanes`] of [`ROWS`] rows `b[j]` against one vector `a` (every `b[j]` at least
/// as long as `a`): `v[j] − Σ_m a_m b[j]_m`, each sum in index order (bitwise
/// `sub_lanes` row by row).
///
/// Why: the recursion's row-by-row inner products are short (up to the model order), so
/// a call per row paid its setup, remainder and bounds checks for a handful of terms;
/// several rows at once share those and each load of `a`, and run independent chains.
#[inline(always)]
fn sub_lanes_rows(mut v: [Lanes; ROWS], a: &[Lanes], b: [&[Lanes]; ROWS]) -> [Lanes; ROWS] {
    let n = a.len();
    let b = rows4(|j| &b[j][..n]);
    for i in 0..n {
        let x = a[i];
        for j in 0..ROWS {
            let y = b[j][i];
            for t in 0..LANES {
                v[j][t] -= x[t] * y[t];
            }
        }
    }
    v
}

/// Rows per block of [`forward_rows`] and [`Factors::extend_group`]'s row sums.
const ROWS: usize = 4;

/// `[f(0), f(1), f(2), f(3)]`: written out, as `std::array::from_fn` was left a call
/// (not inlined into the AVX copy).
#[inline(always)]
fn rows4<T>(f: impl Fn(usize) -> T) -> [T; ROWS] {
    [f(0), f(1), f(2), f(3)]
}

/// Forward substitution against the rows of the lower-triangular `m` (row `k` at
/// `m[k·pm..]`): `x_k = (rhs(k) − Σ_{i<k} x_i m_{k,i}) / m_{k,k}` for every `k` of `x`,
/// each sum in index order (bitwise `sub_lanes(rhs(k), &x[..k], &m[k·pm..k·pm + k])`
/// one `k` after the other). Blocks of [`ROWS`] outputs: the terms `i` before the block
/// by [`sub_lanes_rows`], then the block's own triangle.
#[inline(always)]
fn forward_rows(x: &mut [Lanes], m: &[Lanes], pm: usize, rhs: impl Fn(usize) -> Lanes) {
    let q = x.len();
    let mut k0 = 0;
    while k0 + ROWS <= q {
        // Row k0 + j up to the block's last column.
        let rows = rows4(|j| &m[(k0 + j) * pm..(k0 + j) * pm + k0 + ROWS]);
        let (head, rest) = x.split_at_mut(k0);
        let block: &mut [Lanes; ROWS] = (&mut rest[..ROWS]).try_into().unwrap();
        let v = sub_lanes_rows(rows4(|j| rhs(k0 + j)), head, rows);
        for j in 0..ROWS {
            let tri: &[Lanes; ROWS] = rows[j][k0..].try_into().unwrap();
            let mut v = v[j];
            for i in 0..j {
                for t in 0..LANES {
                    v[t] -= block[i][t] * tri[i][t];
                }
            }
            block[j] = std::array::from_fn(|t| v[t] / tri[j][t]);
        }
        k0 += ROWS;
    }
    for k in k0..q {
        let v = sub_lanes(rhs(k), &x[..k], &m[k * pm..k * pm + k]);
        let d = m[k * pm + k];
        x[k] = std::array::from_fn(|t| v[t] / d[t]);
    }
}

/// `g_k += s y_k` in every lane.
///
/// Four entries per loop step, unrolled: as a plain loop the compiler vectorised it
/// across entries (two at a time, with lane shuffles, 15 instructions per entry)
/// instead of one vector operation per entry. `x + s·z` lane by lane, as before.
#[inline(always)]
fn add_lanes(g: &mut [Lanes], s: Lanes, y: &[Lanes]) {
    let n = g.len().min(y.len());
    let (g, y) = (&mut g[..n], &y[..n]);
    let mut cg = g.chunks_exact_mut(4);
    let cy = y.chunks_exact(4);
    let ry = cy.remainder();
    // Each entry read whole before it is written (written lane by lane in place,
    // the compiler kept every lane a scalar operation).
    let step = |x: Lanes, z: Lanes| -> Lanes { std::array::from_fn(|t| x[t] + s[t] * z[t]) };
    for (x, z) in (&mut cg).zip(cy) {
        let v: [Lanes; 4] = [x[0], x[1], x[2], x[3]];
        for i in 0..4 {
            x[i] = step(v[i], z[i]);
        }
    }
    for (x, z) in cg.into_remainder().iter_mut().zip(ry) {
        *x = step(*x, *z);
    }
}

/// The per-channel factors of the reduced normal equations, grown one basis function
/// at a time: the Cholesky factor L_o of R_o, Y_o = L_o⁻¹S_o (stored transposed: row c
/// of `yt` is column c of Y_o, so that every inner product runs over contiguous memory)
/// and G_o = Y_oᵀY_o, so that S_oᵀR_o⁻¹S_o = G_o — O(n²) per order instead of O(n³).
///
/// Why channel groups: the recursion is the same sequence of operations for every
/// channel, and its sums are long chains of dependent additions. Stored as
/// [`LANES`]-channel vectors (entry (i, j) of group c at `c[i·pm + j]`), each operation
/// runs on a whole group at once, while every channel's sums keep their index order
/// (bitwise the per-channel recursion). Lanes beyond the last channel carry R = I and
/// S = 0 (factors I, 0, 0) and are never read out.
struct Factors {
    no: usize,
    pm: usize,
    /// Per group and lag m: (r(m), Re g(m), Re g(−m)) of its channels (see [`Sums`]).
    r: Vec<Vec<Lanes>>,
    g_pos: Vec<Vec<Lanes>>,
    g_neg: Vec<Vec<Lanes>>,
    l: Vec<Vec<Lanes>>,
    /// Lᵀ above the diagonal (the back substitution of `numerators` runs over columns
    /// of L; strided, it cost 16 instructions a term).
    lt: Vec<Vec<Lanes>>,
    yt: Vec<Vec<Lanes>>,
    /// G_o, lower triangle only (the entries above the diagonal are stale).
    g: Vec<Vec<Lanes>>,
    /// Scratch: the new row of Y of a group's step.
    row: Vec<Lanes>,
}

thread_local! {
    /// Storage of finished sweeps' factors, for the next sweep on this thread.
    static SPARE: std::cell::RefCell<Vec<Vec<Lanes>>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// `len` entries of factor storage, reused from an earlier sweep when there is one.
/// Not cleared: the recursion writes every entry before it reads it (the rows and
/// columns of step q are computed from those of steps < q), so stale values are never
/// used; clearing (and allocating) the three `pm²` tables of every group cost more
/// than the whole table of powers. Unit tests fill it with NaN instead, which any read
/// before a write would carry into the results.
fn spare_storage(len: usize) -> Vec<Lanes> {
    let mut v = SPARE.with(|s| s.borrow_mut().pop()).unwrap_or_default();
    v.truncate(len);
    v.resize(len, [0.0; LANES]);
    if cfg!(test) {
        v.fill([f64::NAN; LANES]);
    }
    v
}

impl Drop for Factors {
    fn drop(&mut self) {
        let done = [&mut self.l, &mut self.lt, &mut self.yt, &mut self.g].map(std::mem::take);
        SPARE.with(|s| s.borrow_mut().extend(done.into_iter().flatten()));
    }
}

impl Factors {
    fn new(s: &Sums, pm: usize) -> Self {
        let no = s.r.len();
        let groups = no.div_ceil(LANES);
        // Lag m of every channel of group c (`pad` in the unused lanes).
        let gather = |x: &[Vec<f64>], pad: &dyn Fn(usize) -> f64| -> Vec<Vec<Lanes>> {
            (0..groups)
                .map(|c| {
                    (0..pm)
                        .map(|m| {
                            std::array::from_fn(|t| match x.get(c * LANES + t) {
                                Some(xo) => xo[m],
                                None => pad(m),
                            })
                        })
                        .collect()
                })
                .collect()
        };
        let zero = |_: usize| 0.0;
        let storage = || (0..groups).map(|_| spare_storage(pm * pm)).collect();
        Self {
            no,
            pm,
            r: gather(&s.r, &|m| if m == 0 { 1.0 } else { 0.0 }),
            g_pos: gather(&s.g_pos, &zero),
            g_neg: gather(&s.g_neg, &zero),
            l: storage(),
            lt: storage(),
            yt: storage(),
            g: storage(),
            row: vec![[0.0; LANES]; pm],
        }
    }

    /// Extends every channel's factors with basis function `q`; `false` when some R_o
    /// is not positive definite.
    fn extend(&mut self, q: usize) -> bool {
        extend_factors(self, q)
    }

    #[inline(always)]
    fn extend_group(&mut self, c: usize, q: usize) -> bool {
        let pm = self.pm;
        let (r, gp, gn) = (&self.r[c], &self.g_pos[c], &self.g_neg[c]);
        let (lo, yo, go) = (&mut self.l[c], &mut self.yt[c], &mut self.g[c]);
        let lto = &mut self.lt[c];
        // S_o[j,k] = −Re Σ w² h z^{k−j}
        let s_at = |j: usize, k: usize| -> Lanes {
            if k >= j {
                gp[k - j].map(|x| -x)
            } else {
                gn[j - k].map(|x| -x)
            }
        };
        let div = |v: Lanes, d: Lanes| -> Lanes { std::array::from_fn(|t| v[t] / d[t]) };
        // Row q of L (a forward substitution against the rows k < q), and Lᵀ.
        {
            let (done, row_q) = lo.split_at_mut(q * pm);
            forward_rows(&mut row_q[..q], done, pm, |k| r[q - k]);
            for k in 0..q {
                lto[k * pm + q] = row_q[k];
            }
        }
        let lq = &lo[q * pm..q * pm + q];
        let d = sub_lanes(r[0], lq, lq);
        if !d.iter().all(|&x| x > 0.0) {
            return false;
        }
        let lqq = d.map(f64::sqrt);
        lo[q * pm + q] = lqq;
        // New column q of Y (rows < q; stored as row q of `yt`), then new row q
        // (columns ≤ q), the latter [`ROWS`] at a time.
        forward_rows(&mut yo[q * pm..q * pm + q], lo, pm, |i| s_at(i, q));
        let lq = &lo[q * pm..q * pm + q];
        let mut j0 = 0;
        while j0 + ROWS <= q + 1 {
            let rows = rows4(|j| &yo[(j0 + j) * pm..(j0 + j) * pm + q]);
            let v = sub_lanes_rows(rows4(|j| s_at(q, j0 + j)), lq, rows);
            for (j, v) in v.into_iter().enumerate() {
                yo[(j0 + j) * pm + q] = div(v, lqq);
            }
            j0 += ROWS;
        }
        for j in j0..=q {
            let v = sub_lanes(s_at(q, j), lq, &yo[j * pm..j * pm + q]);
            yo[j * pm + q] = div(v, lqq);
        }
        // G = YᵀY: the new row adds to the old block; the new column is computed. G is
        // symmetric, and its entries (j, k) and (k, j) would be the same products added
        // in the same order, so only the lower triangle (k ≤ j) is kept (half the
        // updates; `reduced_system` reads it so).
        // Row q of Y is copied out contiguous first: indexed in the strided table, the
        // update (the recursion's most frequent step) re-read the tables' addresses
        // and checked bounds every time (21 instructions per update).
        let row: &mut [Lanes] = &mut self.row[..q];
        for (k, y) in row.iter_mut().enumerate() {
            *y = yo[k * pm + q];
        }
        for (j, &yj) in row.iter().enumerate() {
            add_lanes(&mut go[j * pm..j * pm + j + 1], yj, &row[..=j]);
        }
        // Σ_i y_ij y_iq as −(0 − Σ …): the same additions in the same order as a plain
        // sum; [`ROWS`] columns j at a time.
        let rq = &yo[q * pm..q * pm + q + 1];
        let mut j0 = 0;
        while j0 + ROWS <= q + 1 {
            let rows = rows4(|j| &yo[(j0 + j) * pm..(j0 + j) * pm + q + 1]);
            let v = sub_lanes_rows([[0.0; LANES]; ROWS], rq, rows);
            for (j, v) in v.into_iter().enumerate() {
                go[q * pm + j0 + j] = v.map(|x| -x);
            }
            j0 += ROWS;
        }
        for j in j0..=q {
            let v = sub_lanes([0.0; LANES], &yo[j * pm..j * pm + q + 1], rq).map(|x| -x);
            go[q * pm + j] = v;
        }
        true
    }

    /// The reduced equations of order `n`: `M = T − Σ_o G_o` (`T` Toeplitz with first
    /// column `t_sum`), leading `(n+1)×(n+1)` block; with `α_n = 1`, `A α_{0..n} = b`
    /// for `A` the leading `n×n` block and `b` minus the first `n` entries of column
    /// `n`. Written to `a` row-major with rows [`padded_width`]`(n)` long (the padding
    /// columns are left as they are) and to `b`.
    fn reduced_system(&self, t_sum: &[f64], n: usize, a: &mut Vec<f64>, b: &mut Vec<f64>) {
        reduced_system_into(self, t_sum, n, a, b)
    }
    /// Numerator coefficients `β_o = −R_o⁻¹S_o α = −L⁻ᵀ(Y α)` of every channel for the
    /// denominator `coef` (`p` coefficients), per channel group: `[group][j]` holds
    /// `β_j` of the group's channels (unused lanes 0).
    fn numerators(&self, coef: &[f64]) -> Vec<Vec<Lanes>> {
        factor_numerators(self, coef)
    }
}

/// Row length of the reduced system of order `n` in [`Factors::reduced_system`] and
/// [`solve_reduced`]: `n` rounded up to whole AVX vectors.
fn padded_width(n: usize) -> usize {
    n.next_multiple_of(4)
}

rbprops_core::avx_fn! {
    /// [`Factors::reduced_system`].
    fn reduced_system_into(f: &Factors, t_sum: &[f64], n: usize, a: &mut Vec<f64>, b: &mut Vec<f64>) -> () {
        let (pm, w) = (f.pm, padded_width(n));
        if a.len() < n * w {
            a.resize(n * w, 0.0);
        }
        if cfg!(test) {
            // Stale entries (the padding is never written) must not reach the results.
            a.fill(f64::NAN);
        }
        b.clear();
        b.resize(n, 0.0);
        // Entry (j, k ≤ j) of Σ_o G_o: the lanes of every group in channel order, each
        // added to a running sum that starts at 0 (the additions, in the order, of the
        // sum over the packed lower triangle it replaces; G is symmetric and only its
        // lower triangle is kept). Four entries of a row at a time, their sums in
        // registers. A is symmetric: each entry is computed once and written to (j, k)
        // and (k, j).
        let full = f.no / LANES;
        let last = f.no - full * LANES;
        let (g_full, g_last) = f.g.split_at(full);
        let mut put = |j: usize, k: usize, s: f64| {
            if j < n {
                let v = t_sum[j - k] - s;
                a[j * w + k] = v;
                a[k * w + j] = v;
            } else {
                b[k] = s - t_sum[n - k];
            }
        };
        for j in 0..=n {
            // Row n: the first n entries only (b).
            let kn = if j < n { j + 1 } else { n };
            let row = j * pm;
            let mut k0 = 0;
            while k0 + 4 <= kn {
                let mut s = [0.0f64; 4];
                for gc in g_full {
                    let v: &[Lanes; 4] = gc[row + k0..row + k0 + 4].try_into().unwrap();
                    for e in 0..4 {
                        s[e] = s[e] + v[e][0] + v[e][1] + v[e][2] + v[e][3];
                    }
                }
                if let Some(gc) = g_last.first() {
                    let v: &[Lanes; 4] = gc[row + k0..row + k0 + 4].try_into().unwrap();
                    for t in 0..last {
                        for e in 0..4 {
                            s[e] += v[e][t];
                        }
                    }
                }
                for (e, &s) in s.iter().enumerate() {
                    put(j, k0 + e, s);
                }
                k0 += 4;
            }
            for k in k0..kn {
                let mut s = 0.0;
                for gc in g_full {
                    let v = gc[row + k];
                    s = s + v[0] + v[1] + v[2] + v[3];
                }
                if let Some(gc) = g_last.first() {
                    for &x in &gc[row + k][..last] {
                        s += x;
                    }
                }
                put(j, k, s);
            }
        }
    }
}

rbprops_core::avx_fn! {
    /// Solves `A x = b` for the reduced system of order `n` as [`Factors::reduced_system`]
    /// writes it (rows `padded_width(n)` long), overwriting both; `false` when `A` is
    /// (numerically) singular.
    ///
    /// The operations of `linalg::solve_rows` for one right-hand side, in its order:
    /// Gaussian elimination with partial pivoting (the largest magnitude, the last of
    /// equals), then back substitution; bitwise its solution. Cheaper: each row update
    /// runs over whole vectors, from the one holding the pivot's next column to the
    /// padded end of the row. The entries it also rewrites (the row's columns up to
    /// the pivot column and the padding) are never read again (the pivot searches read
    /// later columns, the back substitution the columns right of the diagonal), so the
    /// vectors need no partial first and last steps.
    fn solve_reduced(a: &mut [f64], x: &mut [f64], n: usize) -> bool {
        let w = padded_width(n);
        let a = &mut a[..n * w];
        let x = &mut x[..n];
        // The largest magnitude (NaN ignored, as by `f64::max`; the maximum of
        // non-negative numbers in any order).
        let mut scale = 0.0f64;
        for row in a.chunks_exact(w) {
            for v in &row[..n] {
                let v = v.abs();
                if v > scale {
                    scale = v;
                }
            }
        }
        if !(scale > 0.0) || !scale.is_finite() {
            return false;
        }
        for c in 0..n {
            let (mut p, mut best) = (c, a[c * w + c].abs());
            for i in c + 1..n {
                let v = a[i * w + c].abs();
                if best.total_cmp(&v) != std::cmp::Ordering::Greater {
                    (p, best) = (i, v);
                }
            }
            if best <= 1e-14 * scale {
                return false;
            }
            if p != c {
                let (head, tail) = a.split_at_mut(p * w);
                head[c * w..(c + 1) * w].swap_with_slice(&mut tail[..w]);
                x.swap(c, p);
            }
            let (top, below) = a.split_at_mut((c + 1) * w);
            let pivot = &top[c * w..];
            let d = pivot[c];
            let xc = x[c];
            let c4 = (c + 1) / 4 * 4;
            let pv = &pivot[c4..];
            for (row, xr) in below.chunks_exact_mut(w).zip(&mut x[c + 1..]) {
                let f = row[c] / d;
                if f != 0.0 {
                    for (v, u) in row[c4..].chunks_exact_mut(4).zip(pv.chunks_exact(4)) {
                        // Read whole, then written (in place lane by lane it stayed scalar).
                        let v: &mut [f64; 4] = v.try_into().unwrap();
                        *v = [v[0] - f * u[0], v[1] - f * u[1], v[2] - f * u[2], v[3] - f * u[3]];
                    }
                    *xr -= f * xc;
                }
            }
        }
        for i in (0..n).rev() {
            let mut s = x[i];
            let row = &a[i * w..i * w + n];
            for l in i + 1..n {
                s -= row[l] * x[l];
            }
            x[i] = s / row[i];
        }
        true
    }
}

rbprops_core::avx_fn! {
    /// [`Factors::extend`] (channel groups in turn).
    fn extend_factors(f: &mut Factors, q: usize) -> bool {
        // A plain loop: iterator adaptors' closures need not be inlined into the AVX copy.
        for c in 0..f.l.len() {
            if !f.extend_group(c, q) {
                return false;
            }
        }
        true
    }
}

rbprops_core::avx_fn! {
    /// [`Factors::numerators`].
    fn factor_numerators(f: &Factors, coef: &[f64]) -> Vec<Vec<Lanes>> {
        let (p, pm) = (coef.len(), f.pm);
        // The starting value of `Iterator::sum` (each lane is bitwise a plain `sum`).
        let zero: f64 = std::iter::empty::<f64>().sum();
        let mut out = Vec::with_capacity(f.l.len());
        let mut ya: Vec<Lanes> = Vec::with_capacity(p);
        for ((lc, ltc), yc) in f.l.iter().zip(&f.lt).zip(&f.yt) {
            // Y α in plain loops (an iterator adaptor's closure need not be inlined
            // into the AVX copy); each lane sums over j in order. Four entries at a
            // time: four independent chains of additions instead of one, and
            // contiguous reads of each column of Y (`yc` row j) instead of a stride.
            ya.clear();
            let full = p / 4 * 4;
            for i0 in (0..full).step_by(4) {
                let mut s = [[zero; LANES]; 4];
                for j in 0..p {
                    let y: &[Lanes; 4] = yc[j * pm + i0..j * pm + i0 + 4].try_into().unwrap();
                    for k in 0..4 {
                        for t in 0..LANES {
                            s[k][t] += y[k][t] * coef[j];
                        }
                    }
                }
                ya.extend_from_slice(&s);
            }
            for i in full..p {
                let mut s = [zero; LANES];
                for j in 0..p {
                    for t in 0..LANES {
                        s[t] += yc[j * pm + i][t] * coef[j];
                    }
                }
                ya.push(s);
            }
            let mut beta = vec![[0.0; LANES]; p];
            for i in (0..p).rev() {
                // Column i of L below the diagonal is row i of Lᵀ (contiguous).
                let below = &ltc[i * pm + i + 1..i * pm + p];
                let v = sub_lanes(ya[i], below, &beta[i + 1..p]);
                beta[i] = std::array::from_fn(|t| v[t] / lc[i * pm + i][t]);
            }
            for b in beta.iter_mut() {
                *b = b.map(|x| -x);
            }
            out.push(beta);
        }
        out
    }
}

rbprops_core::avx_fn! {
    /// The shape of the pole with powers `z^j` (`powers`) and `p'(z)` = `dprime`: per
    /// channel `Σ_j β_j z^j / p'(z)`, the sums over j in order for a group of channels
    /// at once (`betas` as [`Factors::numerators`] gives them; bitwise the sum channel
    /// by channel).
    fn pole_shape(betas: &[Vec<Lanes>], no: usize, powers: &[c64], dprime: c64) -> Vec<c64> {
        let mut shape = Vec::with_capacity(no);
        for (c, beta) in betas.iter().enumerate() {
            let (mut re, mut im) = ([0.0; LANES], [0.0; LANES]);
            for (b, z) in beta.iter().zip(powers) {
                for t in 0..LANES {
                    re[t] += z.re * b[t];
                    im[t] += z.im * b[t];
                }
            }
            for t in 0..LANES.min(no - c * LANES) {
                shape.push(c64::new(re[t], im[t]) / dprime);
            }
        }
        shape
    }
}

/// The LSCF stabilisation sweep: poles for the orders `2..=n_max`, solving only every
/// `step`-th (`n % step == 0`; `step = 1`: every order). `chans` are the channels to use
/// (already restricted to non-zero ones); each is weighted by the inverse of its RMS so
/// that every channel counts equally. The reduced
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
    // With measured coherence, w² is multiplied by the line's factor squared (q_k² ∝
    // γ²/(1 − γ²), `crate::weighting`): the inverse relative variance of the line.
    let weights = match &band.line_quality {
        None => weights,
        Some(q) => weights
            .into_iter()
            .map(|w| w.iter().zip(q).map(|(w2, q)| w2 * q * q).collect())
            .collect(),
    };
    let s = crate::prof::time(4, || sums(&theta, chans, &weights, n_max));
    // All normal matrices are nested in the order (leading blocks), so the reduction
    // is updated one basis function at a time (see `Factors`).
    let pm = n_max + 1;
    let mut f = Factors::new(&s, pm);
    // Σ_o t_o(m): T = Σ_o T_o is Toeplitz too.
    let t_sum: Vec<f64> = (0..pm).map(|m| s.t.iter().map(|t| t[m]).sum()).collect();
    let mut out = Vec::new();
    let mut previous: Option<Vec<c64>> = None;
    // The reduced system of each order (see `Factors::reduced_system`), storage reused.
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for q in 0..pm {
        if !f.extend(q) {
            return out;
        }
        let n = q;
        if n < 2 || n % step != 0 {
            continue;
        }
        f.reduced_system(&t_sum, n, &mut a, &mut b);
        if !solve_reduced(&mut a, &mut b, n) {
            continue;
        }
        let mut coef = b.clone();
        coef.push(1.0);
        let Some(z_roots) = crate::prof::time(5, || roots(&coef[..n], previous.as_deref())) else {
            continue;
        };
        previous = Some(z_roots.clone());
        // Numerators, for the shape vectors (−β per channel group, see `numerators`).
        let betas = f.numerators(&coef);
        let kept: Vec<c64> = z_roots
            .into_iter()
            .filter(|zr| zr.norm() != 0.0 && zr.im > 0.0)
            .collect();
        let at = roots::horner_all(&coef[..n], &kept);
        let mut poles = Vec::new();
        let mut shapes = Vec::new();
        for (&zr, &(_, dprime, _)) in kept.iter().zip(&at) {
            let lam = zr.ln() / dt;
            // The powers zr^j once for every channel (the same products as per channel).
            let mut zj = c64::new(1.0, 0.0);
            let powers: Vec<c64> = (0..coef.len())
                .map(|_| {
                    let z = zj;
                    zj *= zr;
                    z
                })
                .collect();
            let shape = pole_shape(&betas, f.no, &powers, dprime);
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
    use crate::linalg;
    use rbprops_core::Quantity;
    use rbprops_testkit::synthetic::{self, max_nearest};

    /// Every order's warm-started Aberth roots are the companion eigenvalues to the
    /// rounding level, on sweeps like those of the fit (noisy and close-mode data,
    /// whole band and a sub-band), and the iteration rarely needs the QR.
    #[test]
    fn warm_started_roots_match_the_companion_eigenvalues() {
        let cases = [
            synthetic::test_case(12.5, 4096, Quantity::Accelerance).with_noise(0.01, 7),
            synthetic::close_modes(5.0, 2048).with_noise(0.01, 8),
            synthetic::test_case(50.0, 4096, Quantity::Receptance).with_noise(0.03, 9),
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
