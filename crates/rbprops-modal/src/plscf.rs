//! Poly-reference least-squares complex frequency-domain estimator (pLSCF, "PolyMAX";
//! Peeters, Van der Auweraer, Guillaume & Leuridan, Shock Vib. 11, 2004): one common
//! matrix denominator for every excitation (reference) of a set-up.
//!
//! Right matrix-fraction model of the `No × Ni` FRF matrix, one row per output `o`:
//!
//! ```text
//!     H_o(ω) = B_o(z) A(z)⁻¹,   B_o(z) = Σ_{j=0..n} z^j β_{oj} (1×Ni),
//!     A(z) = Σ_{j=0..n} z^j α_j (Ni×Ni),   z = e^{iωΔt}, Δt = π/ω_max,
//! ```
//!
//! all coefficients real (conjugate pole pairs). The linearised equation error
//! `E_o = w_o (B_o − H_o A)` is minimised in least squares. With `X_o = [w z^j]` and
//! `Y_o = [−w z^j H_oe]` (columns `(j, e)`), the normal matrices `R_o = Re X_oᴴX_o`,
//! `S_o = Re X_oᴴY_o`, `T_o = Re Y_oᴴY_o` give, after eliminating the numerators, the
//! reduced normal equations `M α = 0`, `M = Σ_o (T_o − S_oᵀ R_o⁻¹ S_o)`, solved with
//! `α_n = I` (PolyMAX's constraint). Like the single-reference LSCF ([`crate::lscf`]),
//! every matrix is Toeplitz in the basis index on the unit circle, so it is built from
//! sums of `cos(mθ)`, `H z^m` and `H̄ H z^m`.
//!
//! Poles and participation factors: `A(z)` is singular at a pole `z_r`; its left null
//! vector `l_r` (`A(z_r)ᵀ l_r = 0`) is the modal participation vector, since near `z_r`
//! `A⁻¹ ≈ v_r l_rᵀ / (l_rᵀA'(z_r)v_r (z − z_r))` and so the residue of `H` is
//! `ψ_r l_rᵀ`. Both come from the eigen-decomposition of the block companion matrix of
//! `A(z)ᵀ`: eigenvalues `z_r`, eigenvectors `[l; z l; …; z^{n−1} l]`. The poles are
//! `λ_r = ln(z_r)/Δt`. A repeated root shows as two eigenvalues with independent `l`.
//!
//! The crate's Cholesky recursion makes the whole sweep `O(n_max)` factorisations: the
//! normal matrices of order `n` are the leading blocks of those of `n_max`, so
//! `R_o⁻¹`-reduction of order `n` is the leading block of `Y_o = L_o⁻¹ S_o`.

use crate::linalg;
use crate::lscf::OrderPoles;
use crate::pole::Pole;
use crate::setup_bands::Bands;
use crate::ModalError;
use faer::Mat;
use rbprops_core::c64;

/// FRFs of one set-up on one band: `h[o][e][k]`, output `o`, reference `e`, line `k`.
#[derive(Debug, Clone)]
pub struct PolyData<'a> {
    /// Angular frequency of every line (rad/s).
    pub omega: &'a [f64],
    /// `h[output][reference]`: each FRF's values on `omega`.
    pub h: Vec<Vec<&'a [c64]>>,
}

impl PolyData<'_> {
    /// Number of outputs (response channels).
    pub fn n_outputs(&self) -> usize {
        self.h.len()
    }
    /// Number of references (excitations).
    pub fn n_references(&self) -> usize {
        self.h.first().map_or(0, |r| r.len())
    }
}

/// Gram eigenvalue (a squared singular value), relative to the largest, below which a
/// principal direction carries nothing of the data: a singular value 1e-6 of the largest
/// (120 dB down), above the Gram eigen-solver's round-off (about 1e-16 of the largest
/// eigenvalue) and below any measured noise floor (16-bit data: about 1e-10).
const UNUSED_DIRECTION: f64 = 1e-12;

/// At most this many principal references in the sweep (see [`PrincipalReferences`]).
///
/// Why: the denominator needs one reference direction per real mode in the band and two
/// per complex one; a rigid-body test's band holds the six rigid modes and a few
/// elastic ones, so 16 directions hold them with room. Beyond them the data's
/// directions are noise (fifty references of the six rigid modes at 1 % noise: the
/// Gram eigenvalues of the six modes are 1 to 3e-4 of the largest, the other 44 below
/// 1.2e-5), and each costs: a sweep of order `n` on `q` references eigen-decomposes
/// companion matrices of size `n·q`, whose cost grows as `q³` (50 → 16 references:
/// 30 times less).
pub const MAX_PRINCIPAL_REFERENCES: usize = 16;

/// The directions beyond [`MAX_PRINCIPAL_REFERENCES`] are left out only when together
/// they hold at most this fraction of the FRFs' energy (the Gram matrix's trace): data
/// with more directions of signal than that are swept on every reference. At 1 % noise
/// the 34 directions left out of the bench's fifty references hold about 5e-5 of it.
const MAX_LEFT_OUT_ENERGY: f64 = 1e-2;

/// The FRF matrix on its principal references: `H V_r`, `V_r` the real right singular
/// vectors of every output's and line's rows `H_o(ω_k)` stacked as real and imaginary
/// parts (the eigen-decomposition of the real Gram matrix
/// `Σ_{o,k} Re H_o(ω_k)ᵀ Re H_o(ω_k) + Im H_o(ω_k)ᵀ Im H_o(ω_k)`), largest first: those
/// whose eigenvalues, relative to the largest, are above [`UNUSED_DIRECTION`], and of
/// them at most [`MAX_PRINCIPAL_REFERENCES`] when the rest hold at most
/// [`MAX_LEFT_OUT_ENERGY`] of the trace.
///
/// The model's rows are `H_o(ω) = Σ_r ψ_or l_rᵀ/(iω − λ_r) + c.c.`, so the rows lie in the
/// span of the `l_r` and `l̄_r`, which is the span of the real `Re l_r`, `Im l_r`; on the
/// principal references a pole's participation vector is `V_rᵀ l` and `l = V_r (V_rᵀ l)`
/// is exact while the kept directions hold that span. The poles are those of the same
/// FRFs (a projection of the references does not move a pole). The directions are real
/// so that the projected FRFs keep `H(−ω) = H̄(ω)`, the symmetry of the sweep's real
/// coefficients (a complex basis breaks it: on fifty references of two close pairs at
/// 1 % noise, 16 complex principal references found 3 of the 6 modes).
#[derive(Debug, Clone)]
pub struct PrincipalReferences {
    /// `h[o][q]`: output `o` on principal reference `q`, every line.
    pub h: Vec<Vec<Vec<c64>>>,
    /// `v[e][q]`: the (real) principal directions, reference `e`, direction `q`.
    back: Vec<Vec<f64>>,
}

impl PrincipalReferences {
    /// The principal references of the bands `bands` (one per reference, same axis and
    /// outputs) on their lines `keep` (the projected FRFs hold those lines only); `None`
    /// when the data use every direction (nothing to reduce), are zero, or the Gram
    /// matrix's eigen-decomposition fails (non-finite data).
    ///
    /// Made one reference at a time (issue 41): the Gram matrix by blocks of references
    /// ([`Bands::held_at_once`]), each block against itself and against every later
    /// reference, and the projection as a running sum over the references. Each entry
    /// `G_ef` is the same sum whatever the blocks (the products' order is fixed by the
    /// rows alone, [`crate::tallmul`]), so held and read-again bands agree bit for bit.
    pub(crate) fn of_bands(bands: &dyn Bands, keep: &[usize]) -> Result<Option<Self>, ModalError> {
        let ni = bands.len();
        let first = bands.band(0)?;
        let no = first.channels.len();
        let per_ref = 2 * keep.len() * no * std::mem::size_of::<f64>();
        drop(first);
        let block = bands.held_at_once(per_ref);
        // G = Re(XᴴX) over every output's and line's row H_o(ω_k), real and imaginary
        // parts as separate rows (real eigenvectors: the projected FRFs keep
        // H(−ω) = H̄(ω), which the real-coefficient model needs); summed output by
        // output for each pair of references.
        let mut g = Mat::<f64>::zeros(ni, ni);
        for a0 in (0..ni).step_by(block) {
            let a1 = (a0 + block).min(ni);
            let xa = stacked_rows(bands, a0..a1, keep)?;
            for x in &xa {
                linalg::t_mul_add_into(
                    g.as_mut().submatrix_mut(a0, a0, a1 - a0, a1 - a0),
                    x.as_ref(),
                    x.as_ref(),
                );
            }
            for f in a1..ni {
                let xf = stacked_rows(bands, f..f + 1, keep)?;
                for (x, y) in xa.iter().zip(&xf) {
                    linalg::t_mul_add_into(
                        g.as_mut().submatrix_mut(a0, f, a1 - a0, 1),
                        x.as_ref(),
                        y.as_ref(),
                    );
                }
            }
        }
        for j in 0..ni {
            for i in j + 1..ni {
                g[(i, j)] = g[(j, i)];
            }
        }
        let Some((cols, vecs)) = principal_directions(&g) else {
            return Ok(None);
        };
        // H V_r, the sum over the references in their order.
        let mut h = vec![vec![vec![c64::new(0.0, 0.0); keep.len()]; cols.len()]; no];
        for e in 0..ni {
            let b = bands.band(e)?;
            for (row, hb) in h.iter_mut().zip(&b.channels) {
                for (hq, &q) in row.iter_mut().zip(&cols) {
                    let v = vecs[(e, q)];
                    for (z, &k) in hq.iter_mut().zip(keep) {
                        *z += hb[k] * v;
                    }
                }
            }
        }
        let back = (0..ni)
            .map(|e| cols.iter().map(|&q| vecs[(e, q)]).collect())
            .collect();
        Ok(Some(PrincipalReferences { h, back }))
    }

    /// The sweep ([`sweep`]) on the principal references, on the lines `omega` they
    /// were made on, each pole's participation vector mapped back to the measured
    /// references.
    ///
    /// Why: when the FRF rows span fewer directions than there are references
    /// (noise-free data of fewer modes than references: 6 modes seen by 50 excitations
    /// span at most 12), the normal equations of the measured references are singular
    /// and the sweep finds nothing; and more than [`MAX_PRINCIPAL_REFERENCES`]
    /// references whose further directions hold only noise cost `q³` for nothing.
    /// Other data (any measured noise on up to 16 references) are swept as they are.
    pub fn sweep(&self, omega: &[f64], n_max: usize) -> Vec<OrderPoles> {
        let mut orders = sweep(&self.data(omega), n_max);
        for o in &mut orders {
            for l in &mut o.shapes {
                *l = self.participation(l);
            }
        }
        orders
    }

    /// The sweep's data on the principal references (same lines as the original).
    pub fn data<'a>(&'a self, omega: &'a [f64]) -> PolyData<'a> {
        PolyData {
            omega,
            h: self
                .h
                .iter()
                .map(|row| row.iter().map(Vec::as_slice).collect())
                .collect(),
        }
    }

    /// Number of principal references.
    pub fn n_directions(&self) -> usize {
        self.back.first().map_or(0, Vec::len)
    }

    /// A participation vector on the principal references, `V_rᵀ l`, from one on the
    /// measured references (the inverse of [`PrincipalReferences::participation`] on the
    /// span of `V_r`, up to its normalisation).
    pub fn project(&self, l: &[c64]) -> Vec<c64> {
        (0..self.n_directions())
            .map(|q| self.back.iter().zip(l).map(|(row, x)| x * row[q]).sum())
            .collect()
    }

    /// A participation vector on the measured references (`l = V_r l_q`, unit norm,
    /// largest entry real positive) from one on the principal references.
    pub fn participation(&self, l_q: &[c64]) -> Vec<c64> {
        let mut l: Vec<c64> = self
            .back
            .iter()
            .map(|row| row.iter().zip(l_q).map(|(v, x)| v * x).sum())
            .collect();
        normalise_phase(&mut l);
        l
    }
}

/// The principal directions of the real Gram matrix `g` of the references: the
/// columns of its eigenvectors kept (largest first) and the eigenvectors; `None` when
/// every direction is kept, none is, or the eigen-decomposition fails.
fn principal_directions(g: &Mat<f64>) -> Option<(Vec<usize>, Mat<f64>)> {
    let ni = g.nrows();
    let (vals, vecs) = linalg::symmetric_eigen(g)?;
    // Eigenvalues ascend: the used directions, largest first.
    let top = vals[ni - 1];
    let mut cols: Vec<usize> = (0..ni)
        .rev()
        .filter(|&q| vals[q] > UNUSED_DIRECTION * top)
        .collect();
    let total: f64 = (0..ni).map(|q| vals[q].max(0.0)).sum();
    let left_out: f64 = cols
        .iter()
        .skip(MAX_PRINCIPAL_REFERENCES)
        .map(|&q| vals[q])
        .sum();
    if left_out <= MAX_LEFT_OUT_ENERGY * total {
        cols.truncate(MAX_PRINCIPAL_REFERENCES);
    }
    if cols.is_empty() || cols.len() == ni {
        return None;
    }
    Some((cols, vecs))
}

/// Per output, the references `refs` on the lines `keep` as the columns of a real
/// matrix, real parts over imaginary parts (`2·keep × refs`).
fn stacked_rows(
    bands: &dyn Bands,
    refs: std::ops::Range<usize>,
    keep: &[usize],
) -> Result<Vec<Mat<f64>>, ModalError> {
    let nl = keep.len();
    let mut out: Vec<Mat<f64>> = Vec::new();
    for (j, e) in refs.clone().enumerate() {
        let b = bands.band(e)?;
        if out.is_empty() {
            out = (0..b.channels.len())
                .map(|_| Mat::zeros(2 * nl, refs.len()))
                .collect();
        }
        for (x, hb) in out.iter_mut().zip(&b.channels) {
            for (i, &k) in keep.iter().enumerate() {
                x[(i, j)] = hb[k].re;
                x[(nl + i, j)] = hb[k].im;
            }
        }
    }
    Ok(out)
}

/// Per-output, per-line weights `w²_ok = 1/mean_e |H_oe(ω_k)|²` (floored at 1e-12 of
/// the output's mean square): relative equation errors, as in the single-reference
/// LSCF, with one weight per output row (the row's equations share it, so the
/// numerator elimination stays one Toeplitz system per output).
fn weights(data: &PolyData) -> Vec<Vec<f64>> {
    let nl = data.omega.len();
    let ni = data.n_references() as f64;
    data.h
        .iter()
        .map(|row| {
            let level: Vec<f64> = (0..nl)
                .map(|k| row.iter().map(|h| h[k].norm_sqr()).sum::<f64>() / ni)
                .collect();
            let ms = level.iter().sum::<f64>() / nl as f64;
            level
                .iter()
                .map(|l| {
                    if ms > 0.0 {
                        1.0 / l.max(1e-12 * ms)
                    } else {
                        0.0
                    }
                })
                .collect()
        })
        .collect()
}

/// The reduced normal matrices of every order `1..=n_max`, from one set of sums.
struct Reduced {
    ni: usize,
    pm: usize,
    /// `T = Σ_o T_o` for order `n_max`, `(pm·Ni)²`, row-major, index `(j, e) = j·Ni + e`.
    t: Vec<f64>,
    /// Per output, `Y_o = L_o⁻¹ S_o` (`pm × pm·Ni`, row-major).
    y: Vec<Vec<f64>>,
}

/// One output's share of the normal equations: `Re t_ef(m)` (`ni × pm·ni`, column
/// `m·ni + f`) and `Y_o = L_o⁻¹ S_o`, or `None` for a singular `R_o`.
struct OutputSums {
    t: Mat<f64>,
    y: Vec<f64>,
}

impl OutputSums {
    /// The sums of output `row` (`h[e][k]`) with weights `w` on the powers `zp[k][m]`.
    ///
    /// `T` needs only `Re t_ef(m) = Σ_k w_k Re(conj(h_e) h_f z^m)`, and
    /// `Re(conj(h_e) h_f z^m) = Re h_e · Re(h_f z^m) + Im h_e · Im(h_f z^m)`: a real
    /// inner product over the `2·nl` stacked real and imaginary parts of `U = [Re h_e;
    /// Im h_e]` and `V = [w Re(h_f z^m); w Im(h_f z^m)]`, so all of `T_o` is one product
    /// `UᵀV` ([`crate::tallmul::at_b`]: a fixed summation order, bit-identical whatever
    /// the threads) — a quarter of the complex outer products' arithmetic, vectorised.
    fn new(row: &[&[c64]], w: &[f64], zp: &[Vec<c64>], pm: usize) -> Option<Self> {
        let (ni, nl) = (row.len(), w.len());
        let nc = pm * ni;
        let u = Mat::<f64>::from_fn(2 * nl, ni, |r, e| {
            let h = row[e][r % nl];
            if r < nl {
                h.re
            } else {
                h.im
            }
        });
        let mut v = Mat::<f64>::zeros(2 * nl, nc);
        for m in 0..pm {
            for f in 0..ni {
                let c = m * ni + f;
                for k in 0..nl {
                    let hz = row[f][k] * zp[k][m] * w[k];
                    v[(k, c)] = hz.re;
                    v[(nl + k, c)] = hz.im;
                }
            }
        }
        let mut t = Mat::<f64>::zeros(ni, nc);
        crate::tallmul::at_b(u.as_ref(), v.as_ref(), t.as_mut(), 1.0, false);
        // r(m) = Σ w² cos(mθ); g_e(m) = Σ w² h_e z^m for m in −n..n.
        let mut r = vec![0.0; pm];
        let mut gp = vec![c64::new(0.0, 0.0); ni * pm];
        let mut gn = vec![c64::new(0.0, 0.0); ni * pm];
        for k in 0..nl {
            let wk = w[k];
            if wk == 0.0 {
                continue;
            }
            let z = &zp[k];
            for m in 0..pm {
                r[m] += wk * z[m].re;
            }
            for e in 0..ni {
                let hw = row[e][k] * wk;
                for m in 0..pm {
                    gp[e * pm + m] += hw * z[m];
                    gn[e * pm + m] += hw * z[m].conj();
                }
            }
        }
        // Cholesky of the Toeplitz R_o (pm × pm), row-major lower factor.
        let mut l = vec![0.0; pm * pm];
        for i in 0..pm {
            for j in 0..=i {
                let mut s = r[i - j];
                for k in 0..j {
                    s -= l[i * pm + k] * l[j * pm + k];
                }
                if i == j {
                    if !(s > 0.0) {
                        return None;
                    }
                    l[i * pm + i] = s.sqrt();
                } else {
                    l[i * pm + j] = s / l[j * pm + j];
                }
            }
        }
        // S_o[i, (j,e)] = Re Σ w² conj(z^i)(−z^j h_e) = −Re g_e(j − i).
        let s_at = |i: usize, j: usize, e: usize| -> f64 {
            if j >= i {
                -gp[e * pm + (j - i)].re
            } else {
                -gn[e * pm + (i - j)].re
            }
        };
        // Y = L⁻¹ S by forward substitution, column by column.
        let mut y = vec![0.0; pm * nc];
        for c in 0..nc {
            let (j, e) = (c / ni, c % ni);
            for i in 0..pm {
                let mut s = s_at(i, j, e);
                for k in 0..i {
                    s -= l[i * pm + k] * y[k * nc + c];
                }
                y[i * nc + c] = s / l[i * pm + i];
            }
        }
        Some(OutputSums { t, y })
    }
}

impl Reduced {
    fn new(data: &PolyData, dt: f64, n_max: usize) -> Option<Self> {
        use rayon::prelude::*;
        let ni = data.n_references();
        let pm = n_max + 1;
        let w2 = weights(data);
        // z_k^m, m = 0..pm, by direct cos/sin (few lines, exact to rounding).
        let zp: Vec<Vec<c64>> = data
            .omega
            .iter()
            .map(|&w| {
                let th = w * dt;
                (0..pm)
                    .map(|m| {
                        let a = th * m as f64;
                        c64::new(a.cos(), a.sin())
                    })
                    .collect()
            })
            .collect();
        let nc = pm * ni;
        // Each output's sums are independent (in parallel); they are added in output
        // order, so the result does not depend on the thread count. An output of zero
        // weight is left out; a singular R_o makes the whole sweep fail.
        let per_output: Vec<Option<OutputSums>> = (0..data.n_outputs())
            .into_par_iter()
            .filter(|&o| w2[o].iter().any(|&x| x != 0.0))
            .map(|o| OutputSums::new(&data.h[o], &w2[o], &zp, pm))
            .collect();
        if per_output.is_empty() || per_output.iter().any(Option::is_none) {
            return None;
        }
        // T: Re t_ef(m) summed over the outputs; T[(i,e),(j,f)] = Re t_ef(j − i), with
        // Re t_ef(−m) = Re t_fe(m).
        let mut tef = Mat::<f64>::zeros(ni, nc);
        let mut y = Vec::with_capacity(per_output.len());
        for so in per_output.into_iter().flatten() {
            for c in 0..nc {
                for e in 0..ni {
                    tef[(e, c)] += so.t[(e, c)];
                }
            }
            y.push(so.y);
        }
        let mut t = vec![0.0; nc * nc];
        for a in 0..nc {
            let (i, e) = (a / ni, a % ni);
            for b in 0..nc {
                let (j, f) = (b / ni, b % ni);
                t[a * nc + b] = if j >= i {
                    tef[(e, (j - i) * ni + f)]
                } else {
                    tef[(f, (i - j) * ni + e)]
                };
            }
        }
        Some(Self { ni, pm, t, y })
    }

    /// The reduced matrix `M` of order `n` (`(n+1)·Ni` square, row-major).
    fn matrix(&self, n: usize) -> Vec<f64> {
        let (ni, nc_max) = (self.ni, self.pm * self.ni);
        let p = n + 1;
        let nc = p * ni;
        let mut m = vec![0.0; nc * nc];
        for a in 0..nc {
            for b in a..nc {
                let mut s = 0.0;
                for yo in &self.y {
                    for k in 0..p {
                        s += yo[k * nc_max + a] * yo[k * nc_max + b];
                    }
                }
                let v = self.t[a * nc_max + b] - s;
                m[a * nc + b] = v;
                m[b * nc + a] = v;
            }
        }
        m
    }
}

/// Poles and participation vectors of the matrix polynomial with monic leading
/// coefficient and lower coefficients `alpha` (`n·Ni × Ni`, row-major, block `j` rows
/// `j·Ni..`), from the block companion matrix of `A(z)ᵀ`. Only roots with `Im z > 0`
/// (poles of the upper half plane) are returned, each with its unit participation
/// vector (phase: largest entry real positive).
fn companion_poles(
    alpha: &[f64],
    n: usize,
    ni: usize,
    dt: f64,
) -> Option<(Vec<Pole>, Vec<Vec<c64>>)> {
    let d = n * ni;
    let mut c = Mat::<f64>::zeros(d, d);
    for b in 0..n.saturating_sub(1) {
        for e in 0..ni {
            c[(b * ni + e, (b + 1) * ni + e)] = 1.0;
        }
    }
    // Last block row: z^n l = −Σ_j α_jᵀ z^j l.
    for j in 0..n {
        for e in 0..ni {
            for f in 0..ni {
                c[((n - 1) * ni + e, j * ni + f)] = -alpha[(j * ni + f) * ni + e];
            }
        }
    }
    if (0..d).any(|i| (0..d).any(|j| !c[(i, j)].is_finite())) {
        return None;
    }
    let (re, im, u) = linalg::eigen_with_vectors(&c)?;
    let mut poles = Vec::new();
    let mut parts = Vec::new();
    let mut j = 0;
    while j < d {
        if im[j] == 0.0 {
            j += 1;
            continue;
        }
        // A conjugate pair in columns j (re), j+1 (im) of u; eigenvalue re + i·im.
        let (zr, zi) = (re[j], im[j]);
        let (z, sign) = if zi > 0.0 {
            (c64::new(zr, zi), 1.0)
        } else {
            (c64::new(zr, -zi), -1.0)
        };
        if z.norm() > 0.0 && z.re.is_finite() && z.im.is_finite() {
            // The first block of the eigenvector of z (conjugated when the stored
            // eigenvalue was the lower one).
            let mut l: Vec<c64> = (0..ni)
                .map(|e| c64::new(u[(e, j)], sign * u[(e, j + 1)]))
                .collect();
            normalise_phase(&mut l);
            poles.push(Pole(z.ln() / dt));
            parts.push(l);
        }
        j += 2;
    }
    Some((poles, parts))
}

/// Scales `v` to unit norm with its largest entry real positive (the first of equals).
pub(crate) fn normalise_phase(v: &mut [c64]) {
    let n = v.iter().map(|z| z.norm_sqr()).sum::<f64>().sqrt();
    if !(n > 0.0) {
        return;
    }
    let mut big = 0;
    for (i, z) in v.iter().enumerate() {
        if z.norm() > v[big].norm() {
            big = i;
        }
    }
    let ph = v[big].conj() / v[big].norm();
    for z in v.iter_mut() {
        *z = *z * ph / n;
    }
}

/// Poles of one order closer than this many half-power half-bandwidths share their
/// stabilisation shape (see [`stabilisation_shapes`]).
pub const SHARED_SHAPE_BANDWIDTHS: f64 = 0.25;

/// The orders of a sweep with the shapes the stabilisation diagram compares: a pole's
/// own participation vector, except in a group of poles of one order closer than
/// [`SHARED_SHAPE_BANDWIDTHS`]. There the eigen-solver's split of the group's
/// participation space is arbitrary (exactly so for a repeated root), so each member
/// gets the group's subspace, represented by the largest column of its orthogonal
/// projector (deterministic, and stable across orders when the subspace is).
pub fn stabilisation_shapes(orders: &[OrderPoles]) -> Vec<OrderPoles> {
    orders
        .iter()
        .map(|op| {
            let n = op.poles.len();
            let mut shapes = op.shapes.clone();
            let mut done = vec![false; n];
            for i in 0..n {
                if done[i] {
                    continue;
                }
                let mut group = vec![i];
                let mut g = 0;
                while g < group.len() {
                    let a = group[g];
                    for j in 0..n {
                        if !group.contains(&j)
                            && op.poles[a].distance_in_bandwidths(&op.poles[j])
                                < SHARED_SHAPE_BANDWIDTHS
                        {
                            group.push(j);
                        }
                    }
                    g += 1;
                }
                group.sort_unstable();
                for &j in &group {
                    done[j] = true;
                }
                if group.len() < 2 {
                    continue;
                }
                let ni = op.shapes[i].len();
                let v = faer::Mat::<c64>::from_fn(ni, group.len(), |e, k| op.shapes[group[k]][e]);
                // Orthonormal basis Q of the span (modified Gram–Schmidt), P = Q Qᴴ.
                let mut q: Vec<Vec<c64>> = Vec::new();
                for k in 0..group.len() {
                    let mut x: Vec<c64> = (0..ni).map(|e| v[(e, k)]).collect();
                    for b in &q {
                        let c: c64 = b.iter().zip(&x).map(|(u, y)| u.conj() * y).sum();
                        for (y, u) in x.iter_mut().zip(b) {
                            *y -= c * u;
                        }
                    }
                    let nx = x.iter().map(|z| z.norm_sqr()).sum::<f64>().sqrt();
                    if nx > 1e-8 {
                        x.iter_mut().for_each(|z| *z /= nx);
                        q.push(x);
                    }
                }
                let col = |j: usize| -> Vec<c64> {
                    (0..ni)
                        .map(|e| q.iter().map(|b| b[e] * b[j].conj()).sum())
                        .collect()
                };
                let mut best = (0, -1.0);
                for j in 0..ni {
                    let c = col(j);
                    let nc = c.iter().map(|z| z.norm_sqr()).sum::<f64>();
                    if nc > best.1 {
                        best = (j, nc);
                    }
                }
                let mut c = col(best.0);
                normalise_phase(&mut c);
                for &j in &group {
                    shapes[j] = c.clone();
                }
            }
            OrderPoles {
                order: op.order,
                poles: op.poles.clone(),
                shapes,
            }
        })
        .collect()
}

/// The pLSCF stabilisation sweep: poles and participation vectors (as
/// [`OrderPoles::shapes`]) for every matrix order `1..=n_max` (`n·Ni` poles each).
/// `omega` is the band (rad/s, ascending, positive top); `Δt = π/ω_max`.
pub fn sweep(data: &PolyData, n_max: usize) -> Vec<OrderPoles> {
    let ni = data.n_references();
    let Some(&w_max) = data.omega.last() else {
        return Vec::new();
    };
    if ni == 0 || n_max == 0 || !(w_max > 0.0) {
        return Vec::new();
    }
    let dt = std::f64::consts::PI / w_max;
    let Some(red) = crate::prof::time(4, || Reduced::new(data, dt, n_max)) else {
        return Vec::new();
    };
    // Orders whose normal equations or companion matrix are singular are left out. The
    // orders are independent (in parallel, each sequential inside; collected in order).
    use rayon::prelude::*;
    (1..=n_max)
        .into_par_iter()
        .filter_map(|n| {
            let m = crate::prof::time(4, || red.matrix(n));
            let nc = (n + 1) * ni;
            let d = n * ni;
            // M11 α = −M12 with α_n = I.
            let m11: Vec<f64> = (0..d * d).map(|i| m[(i / d) * nc + i % d]).collect();
            let rhs: Vec<f64> = (0..d * ni)
                .map(|i| -m[(i / ni) * nc + d + i % ni])
                .collect();
            let alpha = crate::prof::time(11, || linalg::solve_rows(m11, rhs, d, ni))?;
            let (poles, shapes) = crate::prof::time(5, || companion_poles(&alpha, n, ni, dt))?;
            Some(OrderPoles {
                order: n,
                poles,
                shapes,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` lines 0.01 Hz apart from 0.01 Hz, as ω (rad/s).
    fn omega_lines(n: usize) -> Vec<f64> {
        (1..=n)
            .map(|k| 2.0 * std::f64::consts::PI * k as f64 * 0.01)
            .collect()
    }

    /// Noise-free receptances `h[o][e][k] = Σ_r R(ψ_or l_re; λ_r, ω_k)` of `(outputs,
    /// references)`.
    fn pole_residue_frfs(
        poles: &[Pole],
        psi: impl Fn(usize, usize) -> c64,
        l: impl Fn(usize, usize) -> c64,
        (n_out, n_ref): (usize, usize),
        omega: &[f64],
    ) -> Vec<Vec<Vec<c64>>> {
        (0..n_out)
            .map(|o| {
                (0..n_ref)
                    .map(|e| {
                        omega
                            .iter()
                            .map(|&w| {
                                (0..poles.len())
                                    .map(|r| poles[r].receptance(psi(r, o) * l(r, e), w))
                                    .sum()
                            })
                            .collect()
                    })
                    .collect()
            })
            .collect()
    }

    /// The principal references of `h[o][e]` on every line, from one band per reference.
    fn principal(omega: &[f64], h: &[Vec<Vec<c64>>]) -> Option<PrincipalReferences> {
        let bands: Vec<crate::band::BandData> = (0..h[0].len())
            .map(|e| crate::band::BandData {
                quantity: rbprops_core::Quantity::Receptance,
                frequency_hz: omega
                    .iter()
                    .map(|w| w / (2.0 * std::f64::consts::PI))
                    .collect(),
                omega: omega.to_vec(),
                channels: h.iter().map(|row| row[e].clone()).collect(),
                first_line: 0,
                line_quality: None,
            })
            .collect();
        let all: Vec<usize> = (0..omega.len()).collect();
        PrincipalReferences::of_bands(&bands, &all).unwrap()
    }

    fn as_data<'a>(omega: &'a [f64], h: &'a [Vec<Vec<c64>>]) -> PolyData<'a> {
        PolyData {
            omega,
            h: h.iter()
                .map(|r| r.iter().map(|v| v.as_slice()).collect())
                .collect(),
        }
    }

    /// Noise-free pole–residue data with residues `ψ lᵀ`: the sweep converges with the
    /// order to the poles and the participation vectors.
    #[test]
    fn sweep_converges_to_poles_and_participation() {
        let poles = [Pole::from_modal(1.0, 0.02), Pole::from_modal(1.7, 0.01)];
        let psi = [
            [c64::new(1.0, 0.0), c64::new(0.5, 0.1), c64::new(-0.3, 0.0)],
            [
                c64::new(0.2, 0.0),
                c64::new(-1.0, 0.0),
                c64::new(0.7, -0.05),
            ],
        ];
        let l = [
            [c64::new(1.0, 0.0), c64::new(0.3, 0.0)],
            [c64::new(-0.4, 0.0), c64::new(1.0, 0.0)],
        ];
        let omega = omega_lines(400);
        let h = pole_residue_frfs(&poles, |r, o| psi[r][o], |r, e| l[r][e], (3, 2), &omega);
        let data = as_data(&omega, &h);
        // The z-domain model is not the s-domain pole–residue model: its poles converge
        // with the order (here 8e-1, 1e-2, 3e-4, 4e-6 and 7e-9 at orders 2, 4, 6, 8, 12).
        let sw = sweep(&data, 12);
        let err = |o: &OrderPoles| {
            poles
                .iter()
                .map(|p| {
                    o.poles
                        .iter()
                        .map(|q| (q.0 - p.0).norm() / p.0.norm())
                        .fold(f64::INFINITY, f64::min)
                })
                .fold(0.0, f64::max)
        };
        let e: Vec<f64> = [4, 8, 12].iter().map(|&n| err(&sw[n - 1])).collect();
        assert!(e[0] > e[1] && e[1] > e[2], "{e:?}");
        let o2 = &sw[11];
        assert_eq!(o2.order, 12);
        for (r, p) in poles.iter().enumerate() {
            let (i, q) = o2
                .poles
                .iter()
                .enumerate()
                .min_by(|a, b| (a.1 .0 - p.0).norm().total_cmp(&(b.1 .0 - p.0).norm()))
                .unwrap();
            assert!((q.0 - p.0).norm() < 1e-7 * p.0.norm(), "{q:?} vs {p:?}");
            let mut want = l[r].to_vec();
            normalise_phase(&mut want);
            let got = &o2.shapes[i];
            let d: f64 = got.iter().zip(&want).map(|(a, b)| (a - b).norm()).sum();
            assert!(d < 1e-7, "{got:?} vs {want:?}");
        }
    }

    /// Three modes seen by 24 references with complex participation vectors, noise-free:
    /// the data's rows span `l_r` and `l̄_r` (6 directions), so the principal references
    /// hold each participation vector exactly, and the sweep on them finds the poles and
    /// the measured-reference vectors (on the 24 references as measured it finds nothing
    /// at the higher orders: the normal equations are singular).
    /// The principal directions are real (the projected FRFs keep the symmetry of the
    /// sweep's real coefficients).
    #[test]
    fn principal_references_keep_poles_and_participation_vectors() {
        let ni = 24;
        let poles = [
            Pole::from_modal(1.0, 0.02),
            Pole::from_modal(1.3, 0.015),
            Pole::from_modal(1.7, 0.01),
        ];
        let psi = |r: usize, o: usize| c64::new(((r * 3 + o * 7) % 5) as f64 - 2.0, 0.1 * o as f64);
        let l: Vec<Vec<c64>> = (0..3)
            .map(|r| {
                (0..ni)
                    .map(|e| {
                        let a = 0.37 * (e * (r + 2)) as f64;
                        c64::new(a.cos() + 0.2, 0.3 * a.sin() * (r as f64 + 0.5))
                    })
                    .collect()
            })
            .collect();
        let omega = omega_lines(300);
        let h = pole_residue_frfs(&poles, psi, |r, e| l[r][e], (4, ni), &omega);
        let p = principal(&omega, &h).unwrap();
        let normalised = |v: &[c64]| {
            let mut v = v.to_vec();
            normalise_phase(&mut v);
            v
        };
        let distance =
            |a: &[c64], b: &[c64]| -> f64 { a.iter().zip(b).map(|(x, y)| (x - y).norm()).sum() };
        for lr in &l {
            // On the principal references: l_q = V_rᵀ l (back holds the real V_r).
            assert_eq!(p.back[0].len(), 6, "three complex modes use six directions");
            let lq: Vec<c64> = (0..6)
                .map(|q| (0..ni).map(|e| p.back[e][q] * lr[e]).sum())
                .collect();
            let d = distance(&p.participation(&lq), &normalised(lr));
            assert!(
                d < 1e-12,
                "participation vector back from the principal references: {d:e}"
            );
        }
        // The sweep on the principal references. The z-domain model is not exact for
        // s-domain poles; what the sweep must give is poles and participation vectors
        // the selection takes as stable (consecutive orders within the stabilisation
        // tolerances), which the joint refinement then makes exact (end to end:
        // `close_modes::fifty_excitations_resolve_the_close_pairs`, 1e-8). So at each of
        // the two highest orders every mode has a pole within half of those tolerances
        // of the truth (so the two orders agree within them). Noise-free
        // on six real directions, the normal equations become singular above order 4
        // (the model fits the data to rounding) and those orders are left out.
        let tol = crate::options::StabilisationTolerances::default();
        let sw = p.sweep(&omega, 10);
        assert!(sw.len() >= 3, "orders swept: {}", sw.len());
        for o in &sw[sw.len() - 2..] {
            assert_eq!(o.shapes[0].len(), ni);
            for (r, pole) in poles.iter().enumerate() {
                let (i, q) = o
                    .poles
                    .iter()
                    .enumerate()
                    .min_by(|a, b| {
                        (a.1 .0 - pole.0)
                            .norm()
                            .total_cmp(&(b.1 .0 - pole.0).norm())
                    })
                    .unwrap();
                let df = (q.frequency_hz() / pole.frequency_hz() - 1.0).abs();
                let dz = (q.damping() / pole.damping() - 1.0).abs();
                let dm = 1.0 - crate::pole::mac(&o.shapes[i], &l[r]);
                assert!(
                    df < 0.5 * tol.frequency && dz < 0.5 * tol.damping && dm < 0.5 * tol.shape,
                    "order {} mode {r}: frequency {df:e}, damping {dz:e}, 1 − MAC {dm:e}",
                    o.order
                );
            }
        }
    }

    /// Noisy FRFs of `n_modes` complex modes seen by 24 references (1 % relative
    /// noise, per value, deterministic): random participation vectors, or with
    /// `one_reference_each` mode `r` seen by reference `r` alone.
    fn noisy_24(n_modes: usize, one_reference_each: bool) -> (Vec<f64>, Vec<Vec<Vec<c64>>>) {
        let ni = 24;
        let mut rng = rbprops_testkit::Lcg::new(7);
        let poles: Vec<Pole> = (0..n_modes)
            .map(|r| Pole::from_modal(1.0 + 0.12 * r as f64, 0.015))
            .collect();
        // Independent participation vectors; residues scaled by ω_r² so that every
        // mode's peak is of one size.
        let l: Vec<Vec<c64>> = (0..n_modes)
            .map(|r| {
                (0..ni)
                    .map(|e| match one_reference_each {
                        true => c64::new((e == r) as u8 as f64, 0.0),
                        false => c64::new(rng.centred(), rng.centred()),
                    })
                    .collect()
            })
            .collect();
        let psi = |r: usize, o: usize| {
            c64::new(1.0 + 0.1 * ((r + o) % 3) as f64, 0.05 * o as f64) * poles[r].0.norm_sqr()
        };
        let omega = omega_lines(400);
        let mut h = pole_residue_frfs(&poles, psi, |r, e| l[r][e], (4, ni), &omega);
        for v in h.iter_mut().flatten().flatten() {
            *v *= c64::new(1.0 + 0.01 * rng.centred(), 0.01 * rng.centred());
        }
        (omega, h)
    }

    /// More than [`MAX_PRINCIPAL_REFERENCES`] references whose further directions hold
    /// only noise are cut to that many (three modes on 24 references: the 8 directions
    /// left out hold 3e-6 of the energy); data with more directions of signal than that
    /// keep every reference (24 modes of equal peaks, each on its own reference: the 8
    /// directions left out would hold 6e-2, six times the limit).
    #[test]
    fn many_references_are_cut_to_the_principal_ones_only_when_the_rest_is_noise() {
        let (omega, h) = noisy_24(3, false);
        let p = principal(&omega, &h).expect("cut");
        assert_eq!(p.back[0].len(), MAX_PRINCIPAL_REFERENCES);
        let (omega, h) = noisy_24(24, true);
        assert!(principal(&omega, &h).is_none());
    }
}
