//! Poly-reference refinement of the poles and participation vectors of one set-up by
//! variable projection: the poly-reference counterpart of [`crate::lsfd::refine`].
//!
//! Model of output `o` and excitation `e` (as [`crate::plsfd`], `q(ω) = (iω)^k`):
//!
//! ```text
//!   H_oe(ω) = q(ω) [ Σ_r ( ψ_ro l_re/(iω−λ_r) + conj(ψ_ro l_re)/(iω−λ_r*) ) + U_oe + L_oe/(iω)² ]
//! ```
//!
//! Nonlinear parameters `θ`: one pole `λ_g` per root (the modes of an exactly repeated
//! root share it and keep their own participation vectors) and the participation
//! vectors `l_r`, one entry of each held fixed (the scale of the rank-one residue
//! `ψ_r l_rᵀ` belongs to `ψ_r`). Linear parameters: the shapes `ψ` and the residual
//! terms, for each trial `θ` the poly-reference LSFD solution ([`crate::plsfd`]'s basis,
//! one factorisation for every output). Levenberg–Marquardt minimises
//!
//! ```text
//!   Σ_o ‖W (h_o − Φ(θ) c_o)‖² / rms_o²
//! ```
//!
//! (`W` the LSFD line weights, `h_o` output `o` real-stacked over the excitations,
//! `rms_o` its RMS) with Kaufman's Jacobian `J_o = −P⊥ D_o`, `D_o = (∂Φ/∂θ) c_o`:
//! `JᵀJ = Σ_o (D_oᵀD_o − (Φ̃ᵀD_o)ᵀ(Φ̃ᵀΦ̃)⁻¹(Φ̃ᵀD_o))` and `Jᵀr = −Σ_o D_oᵀ r_o`.
//! With `u = 1/(iω − λ)`, `v = 1/(iω − λ*)` and `R = ψ_ro l_re` the columns of `D_o` are
//!
//! ```text
//!   ∂/∂Re λ:    q (R u² + R̄ v²)        ∂/∂Im λ:    q·i (R u² − R̄ v²)   (summed over the root's modes)
//!   ∂/∂Re l_re: q (ψ u + ψ̄ v)          ∂/∂Im l_re: q·i (ψ u − ψ̄ v)     (excitation e's rows only)
//! ```

use crate::band::BandData;
use crate::linalg;
use crate::lsfd::Residuals;
use crate::plscf::{self, normalise_phase};
use crate::plsfd::{self, SetupBasis, SetupLs};
use crate::pole::Pole;
use crate::setup_bands::Bands;
use crate::ModalError;
use faer::Mat;
use rbprops_core::c64;

/// Result of [`refine`].
#[derive(Debug, Clone)]
pub struct PolyRefined {
    /// One pole per mode (the modes of a root share it).
    pub poles: Vec<Pole>,
    /// `parts[r][e]`, unit norm, largest entry real positive.
    pub parts: Vec<Vec<c64>>,
    /// Gauss–Newton iterations taken.
    pub iterations: usize,
    /// Stopped at the minimum (negligible step or cost stall), not at the iteration limit.
    pub converged: bool,
    /// Weighted cost before and after (on the references refined on).
    pub cost: (f64, f64),
    /// References the refinement ran on: the set-up's excitations, or its principal
    /// references ([`refine_set_up`]).
    pub references: usize,
}

/// Above this many excitations in a set-up, [`refine_set_up`] refines on the set-up's
/// principal references instead of on every excitation.
///
/// Why: the refinement's parameters are the poles and a participation entry per mode
/// and excitation, and its Levenberg–Marquardt steps solve dense normal equations in
/// them, so its time grows as the cube and its memory as the square of the number of
/// excitations (48 excitations of the demo's 7 modes: 680 parameters, 1.5 s and 180 MB;
/// 96: 1,340, 6.4 s and 410 MB). On at most this many principal references the
/// parameters are bounded whatever the number of excitations. The bound is the sweep's
/// ([`plscf::MAX_PRINCIPAL_REFERENCES`]), for the same reason: a rigid-body test's band
/// holds the six rigid modes and a few elastic ones, whose participation vectors and
/// residual terms span fewer directions than that. Up to it, every excitation is
/// refined on as before (the same bits).
pub const MAX_REFINEMENT_REFERENCES: usize = plscf::MAX_PRINCIPAL_REFERENCES;

/// [`refine`] on a set-up of any number of excitations: up to
/// [`MAX_REFINEMENT_REFERENCES`] on the excitations themselves; above it on the set-up's
/// principal references ([`plscf::PrincipalReferences::of`], every line) when
/// at most that many hold the data, each participation vector mapped to them (`V_rᵀ l`)
/// and back (`V_r l_q`). The projection keeps the model's form (real directions: `H V_r`
/// has the poles of `H`, participations `V_rᵀ l_r` and residual terms `U V_r`, `L V_r`),
/// so on data the kept directions hold it is the same least-squares problem in fewer
/// unknowns. Data with more directions of signal than that are refined on every
/// excitation.
pub(crate) fn refine_set_up(
    poles: &[Pole],
    parts: &[Vec<c64>],
    roots: &[usize],
    bands: &dyn Bands,
    res: Residuals,
) -> Result<PolyRefined, ModalError> {
    if bands.len() > MAX_REFINEMENT_REFERENCES {
        let all: Vec<usize> = (0..bands.band(0)?.n_lines()).collect();
        if let Some(mut pr) = plscf::PrincipalReferences::of_bands(bands, &all)?
            .filter(|pr| pr.n_directions() <= MAX_REFINEMENT_REFERENCES)
        {
            let virtual_bands = principal_bands(bands, std::mem::take(&mut pr.h))?;
            let refs: Vec<&BandData> = virtual_bands.iter().collect();
            let projected: Vec<Vec<c64>> = parts.iter().map(|l| pr.project(l)).collect();
            let mut rf = refine(poles, &projected, roots, &refs, res);
            rf.parts = rf.parts.iter().map(|l| pr.participation(l)).collect();
            return Ok(rf);
        }
    }
    // At most MAX_REFINEMENT_REFERENCES (or data of more directions): held.
    let held: Vec<std::borrow::Cow<'_, BandData>> = (0..bands.len())
        .map(|e| bands.band(e))
        .collect::<Result<_, _>>()?;
    let refs: Vec<&BandData> = held.iter().map(|b| b.as_ref()).collect();
    Ok(refine(poles, parts, roots, &refs, res))
}

/// One band per principal reference: the FRFs `H V_r` (`h[o][q]`, moved in) on the axis
/// of `bands`. The line-quality factors, where given, are the mean of the excitations'
/// (a principal reference mixes them all).
fn principal_bands(
    bands: &dyn Bands,
    mut h: Vec<Vec<Vec<c64>>>,
) -> Result<Vec<BandData>, ModalError> {
    let nq = h.first().map_or(0, Vec::len);
    let first = bands.band(0)?.into_owned();
    let line_quality = match first.line_quality {
        None => None,
        Some(_) => {
            let mut sum = vec![0.0; first.n_lines()];
            for e in 0..bands.len() {
                let b = bands.band(e)?;
                for (s, k) in sum.iter_mut().zip(0..) {
                    *s += b.line_quality.as_ref().map_or(1.0, |v| v[k]);
                }
            }
            Some(
                sum.iter()
                    .map(|s| s / bands.len() as f64)
                    .collect::<Vec<f64>>(),
            )
        }
    };
    Ok((0..nq)
        .map(|q| BandData {
            quantity: first.quantity,
            frequency_hz: first.frequency_hz.clone(),
            omega: first.omega.clone(),
            channels: h
                .iter_mut()
                .map(|row| std::mem::take(&mut row[q]))
                .collect(),
            first_line: first.first_line,
            line_quality: line_quality.clone(),
        })
        .collect())
}

/// Most Levenberg–Marquardt iterations.
const MAX_ITERATIONS: usize = 50;

/// The fixed data of one refinement.
struct Problem<'a> {
    bands: &'a [&'a BandData],
    res: Residuals,
    /// Line weights per excitation (those of [`plsfd::fit_shapes`]).
    w: Vec<Vec<f64>>,
    /// `q(ω_k)·w_ek` per excitation and line.
    qw: Vec<Vec<c64>>,
    /// Weighted data, each output divided by its RMS (`2N·Ni × No`).
    b: Mat<f64>,
    /// Root index of each mode.
    roots: Vec<usize>,
    n_roots: usize,
    /// The entry of each `l_r` held fixed.
    fixed: Vec<usize>,
    n_params: usize,
}

/// The nonlinear parameters.
#[derive(Debug, Clone)]
struct State {
    /// One pole per root.
    lambda: Vec<c64>,
    parts: Vec<Vec<c64>>,
}

impl State {
    fn poles(&self, roots: &[usize]) -> Vec<Pole> {
        roots.iter().map(|&g| Pole(self.lambda[g])).collect()
    }
}

/// The poly-reference LSFD solution at one trial `θ`.
struct Trial {
    cost: f64,
    ls: SetupLs,
    /// `ψ_ro` per mode and output (of the RMS-scaled data).
    psi: Vec<Vec<c64>>,
    /// Real-stacked residuals, one column per output.
    resid: Mat<f64>,
}

/// Refines `poles` and `parts` (`parts[r][e]`) of the modes of one set-up on `bands`
/// (one per excitation, same axis and outputs). `roots[r]` names the root of mode `r`:
/// modes with the same root index (an exactly repeated root) share one pole, started at
/// their mean. The fixed entry of each `l_r` is its largest one.
pub fn refine(
    poles: &[Pole],
    parts: &[Vec<c64>],
    roots: &[usize],
    bands: &[&BandData],
    res: Residuals,
) -> PolyRefined {
    let p = problem(parts, roots, bands, res);
    let mut lambda = vec![c64::new(0.0, 0.0); p.n_roots];
    let mut count = vec![0usize; p.n_roots];
    for (pole, &g) in poles.iter().zip(roots) {
        lambda[g] += pole.0;
        count[g] += 1;
    }
    for (l, c) in lambda.iter_mut().zip(&count) {
        *l /= (*c).max(1) as f64;
    }
    let mut s = State {
        lambda,
        parts: parts.to_vec(),
    };
    let first = crate::prof::time(8, || trial(&p, &s));
    let (cost0, mut cost) = (first.cost, first.cost);
    let mut t = Some(first);
    let mut mu = 1e-3;
    let mut converged = false;
    let mut iterations = 0;
    for it in 0..MAX_ITERATIONS {
        iterations = it + 1;
        // The accepted trial's basis and residuals serve its normal equations only:
        // let go before the candidates are tried (one trial held at a time, not two).
        let current = t.take().expect("an accepted trial");
        let (jtj, g) = crate::prof::time(9, || normal_equations(&p, &s, &current));
        drop(current);
        let rhs = Mat::from_fn(p.n_params, 1, |i, _| g[i]);
        // Converged when even the undamped Gauss–Newton step predicts a negligible drop.
        if let Some(gn) = crate::prof::time(10, || linalg::solve_square(&jtj, &rhs)) {
            let predicted: f64 = (0..p.n_params).map(|i| gn[(i, 0)] * g[i]).sum();
            if predicted.is_finite() && predicted >= 0.0 && predicted <= 1e-10 * cost {
                converged = true;
                break;
            }
        }
        let dmax = (0..p.n_params).map(|i| jtj[(i, i)]).fold(0.0, f64::max);
        let mut accepted = false;
        for _ in 0..12 {
            // Marquardt scaling, floored so that a parameter without influence (a mode
            // no output sees) keeps the system regular.
            let lhs = Mat::from_fn(p.n_params, p.n_params, |i, j| {
                jtj[(i, j)]
                    + if i == j {
                        mu * jtj[(i, i)].max(1e-12 * dmax)
                    } else {
                        0.0
                    }
            });
            let Some(step) = crate::prof::time(10, || linalg::solve_square(&lhs, &rhs)) else {
                mu *= 10.0;
                continue;
            };
            let cand = apply(&p, &s, &step);
            if cand.lambda.iter().any(|l| !(l.re < 0.0 && l.im > 0.0)) {
                mu *= 10.0;
                continue;
            }
            let t2 = crate::prof::time(8, || trial(&p, &cand));
            if t2.cost <= cost {
                let rel_step = (0..p.n_roots)
                    .map(|g| (cand.lambda[g] - s.lambda[g]).norm() / (-s.lambda[g].re))
                    .fold(0.0, f64::max);
                // As `lsfd::refine`: a negligible pole step or a stalled cost.
                converged = rel_step < 1e-9 || (cost - t2.cost) <= 1e-10 * cost;
                s = cand;
                cost = t2.cost;
                t = Some(t2);
                mu = (mu / 10.0).max(1e-12);
                accepted = true;
                break;
            }
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
    let poles = s.poles(&p.roots);
    let mut parts = s.parts;
    for l in parts.iter_mut() {
        normalise_phase(l);
    }
    PolyRefined {
        poles,
        parts,
        iterations,
        converged,
        cost: (cost0, cost),
        references: bands.len(),
    }
}

/// The fixed data of [`refine`]: weights, scaled data, parameter layout.
fn problem<'a>(
    parts: &[Vec<c64>],
    roots: &[usize],
    bands: &'a [&'a BandData],
    res: Residuals,
) -> Problem<'a> {
    let ni = bands.len();
    let w = plsfd::line_weights_per_excitation(bands);
    let q = bands[0].quantity_factor();
    let qw = w
        .iter()
        .map(|we| q.iter().zip(we).map(|(q, w)| q * *w).collect())
        .collect();
    let mut b = plsfd::stacked_data(bands, &w);
    for o in 0..b.ncols() {
        let ms = bands
            .iter()
            .map(|band| band.channels[o].iter().map(|z| z.norm_sqr()).sum::<f64>())
            .sum::<f64>()
            / (ni * bands[0].n_lines()) as f64;
        if ms > 0.0 {
            let s = ms.sqrt();
            for i in 0..b.nrows() {
                b[(i, o)] /= s;
            }
        }
    }
    let fixed: Vec<usize> = parts
        .iter()
        .map(|l| {
            (0..ni)
                .max_by(|&a, &c| l[a].norm().total_cmp(&l[c].norm()))
                .unwrap_or(0)
        })
        .collect();
    let n_roots = roots.iter().map(|&g| g + 1).max().unwrap_or(0);
    Problem {
        bands,
        res,
        w,
        qw,
        b,
        roots: roots.to_vec(),
        n_roots,
        fixed,
        n_params: 2 * n_roots + 2 * (ni - 1) * parts.len(),
    }
}

/// The poly-reference LSFD solution at `s`.
fn trial(p: &Problem, s: &State) -> Trial {
    let poles = s.poles(&p.roots);
    let mut a = SetupBasis::new(&poles, &s.parts, p.bands, p.res, &p.w);
    let scale = a.normalise_columns();
    let ls = SetupLs::new(a);
    let (x, resid, rss) = ls.solve_into(p.b.clone());
    let psi = (0..poles.len())
        .map(|r| {
            (0..p.b.ncols())
                .map(|o| {
                    c64::new(
                        x[(2 * r, o)] / scale[2 * r],
                        x[(2 * r + 1, o)] / scale[2 * r + 1],
                    )
                })
                .collect()
        })
        .collect();
    Trial {
        cost: rss.iter().sum(),
        ls,
        psi,
        resid,
    }
}

/// Column of `∂/∂Re l_re` of mode `r` in the parameter vector (`e` not the fixed entry).
fn part_column(p: &Problem, r: usize, e: usize) -> usize {
    let ni = p.bands.len();
    let k = if e > p.fixed[r] { e - 1 } else { e };
    2 * p.n_roots + 2 * (ni - 1) * r + 2 * k
}

/// `θ + step`.
fn apply(p: &Problem, s: &State, step: &Mat<f64>) -> State {
    let mut out = s.clone();
    for (g, l) in out.lambda.iter_mut().enumerate() {
        *l += c64::new(step[(2 * g, 0)], step[(2 * g + 1, 0)]);
    }
    for (r, l) in out.parts.iter_mut().enumerate() {
        for (e, x) in l.iter_mut().enumerate() {
            if e != p.fixed[r] {
                let c = part_column(p, r, e);
                *x += c64::new(step[(c, 0)], step[(c + 1, 0)]);
            }
        }
    }
    out
}

/// Excitation `e`'s output-independent vectors of every mode `r`, real-stacked
/// (`2N` rows, columns `4r..4r + 4`): `d1 = qw(u² + v²)`, `d2 = qw·i(u² − v²)`,
/// `b1 = qw(u + v)`, `b2 = qw·i(u − v)` (`qw = q(ω)·w_e`). Every column of `D_o` on
/// excitation `e`'s rows is a combination of them (see [`coefficients`]).
fn line_vectors(p: &Problem, poles: &[Pole], e: usize) -> Mat<f64> {
    let n = p.bands[0].n_lines();
    let omega = &p.bands[0].omega;
    let qw = &p.qw[e];
    let mut m = Mat::<f64>::zeros(2 * n, 4 * poles.len());
    for (r, pole) in poles.iter().enumerate() {
        for (k, (&w, &q)) in omega.iter().zip(qw).enumerate() {
            let s = c64::new(0.0, w);
            let (u, v) = (1.0 / (s - pole.0), 1.0 / (s - pole.0.conj()));
            let (u2, v2) = (u * u, v * v);
            let i1 = c64::new(0.0, 1.0);
            let cols = [
                q * (u2 + v2),
                q * i1 * (u2 - v2),
                q * (u + v),
                q * i1 * (u - v),
            ];
            for (j, z) in cols.iter().enumerate() {
                m[(k, 4 * r + j)] = z.re;
                m[(n + k, 4 * r + j)] = z.im;
            }
        }
    }
    m
}

/// The parameters excitation `e`'s rows of `D_o` depend on, in order: every root's
/// pole (`2·roots` columns, the first ones of `θ`), then for each mode whose fixed
/// participation entry is not `e` its `l_re` (two columns). `slot[r]` is the position
/// of mode `r`'s `l_re` pair in that list (`None` for the fixed entry).
struct Active {
    cols: Vec<usize>,
    slot: Vec<Option<usize>>,
}

fn active(p: &Problem, e: usize) -> Active {
    let mut cols: Vec<usize> = (0..2 * p.n_roots).collect();
    let slot = (0..p.fixed.len())
        .map(|r| {
            (e != p.fixed[r]).then(|| {
                let c = part_column(p, r, e);
                cols.extend([c, c + 1]);
                cols.len() - 2
            })
        })
        .collect();
    Active { cols, slot }
}

/// `C_oe` on the parameters of `act` (`4·modes × act.cols`): `D_o` on excitation `e`'s
/// rows is `E_e C_oe` ([`line_vectors`]); the other columns of `θ` are zero there.
/// With `R = ψ_ro l_re = a + ib`: `∂/∂Re λ = a d1 + b d2`, `∂/∂Im λ = −b d1 + a d2`;
/// with `ψ_ro = c + id`: `∂/∂Re l_re = c b1 + d b2`, `∂/∂Im l_re = −d b1 + c b2`.
fn coefficients(
    p: &Problem,
    s: &State,
    psi: &[Vec<c64>],
    (o, e): (usize, usize),
    act: &Active,
) -> Mat<f64> {
    let mut c = Mat::<f64>::zeros(4 * s.parts.len(), act.cols.len());
    for (r, l) in s.parts.iter().enumerate() {
        let g = p.roots[r];
        let ps = psi[r][o];
        let rr = ps * l[e];
        c[(4 * r, 2 * g)] = rr.re;
        c[(4 * r + 1, 2 * g)] = rr.im;
        c[(4 * r, 2 * g + 1)] = -rr.im;
        c[(4 * r + 1, 2 * g + 1)] = rr.re;
        if let Some(j) = act.slot[r] {
            c[(4 * r + 2, j)] = ps.re;
            c[(4 * r + 3, j)] = ps.im;
            c[(4 * r + 2, j + 1)] = -ps.im;
            c[(4 * r + 3, j + 1)] = ps.re;
        }
    }
    c
}

/// The small products of excitation `e`'s line vectors `E_e` ([`line_vectors`]):
/// `E_eᵀE_e`, `Φ̃_eᵀE_e` (the rows of the basis columns non-zero on `e`'s rows) and
/// `E_eᵀr_oe` for every output.
struct LineProducts {
    gram: Mat<f64>,
    basis: Mat<f64>,
    resid: Mat<f64>,
}

/// `JᵀJ` and `−Jᵀr = Σ_o D_oᵀ r_o` at `s` (the trial `t`), from the small products of
/// the line vectors `E_e` with themselves, with the basis and with the residuals:
/// `D_oᵀD_o = Σ_e C_oeᵀ(E_eᵀE_e)C_oe`, `Φ̃ᵀD_o = Σ_e (Φ̃_eᵀE_e)C_oe`,
/// `D_oᵀr_o = Σ_e C_oeᵀ(E_eᵀr_oe)`: O(N·Ni·modes²) per iteration, not O(N·Ni·No·θ²).
///
/// Each `C_oe` is non-zero on the poles and `e`'s participations only ([`Active`]), and
/// `Φ̃_e` on the pole columns and `e`'s residual terms: the products are taken on those
/// (about 24 of 600 parameters with 50 excitations and 6 modes) and scattered. The
/// projection term `Σ_o (Φ̃ᵀD_o)ᵀ(Φ̃ᵀΦ̃)⁻¹(Φ̃ᵀD_o)` is `Σ_o Y_oᵀY_o` with
/// `Y_o = R⁻ᵀ(Φ̃ᵀD_o)` (Gram products, their lower triangles).
fn normal_equations(p: &Problem, s: &State, t: &Trial) -> (Mat<f64>, Vec<f64>) {
    use rayon::prelude::*;
    let n2 = 2 * p.bands[0].n_lines();
    let basis = t.ls.basis();
    let poles = s.poles(&p.roots);
    // Each excitation's line vectors made, used and let go (one per thread at a time,
    // not all: 10 MB at 16 references × 1,601 lines; issue 41).
    let prods: Vec<LineProducts> = (0..p.bands.len())
        .into_par_iter()
        .map(|e| {
            let em = line_vectors(p, &poles, e);
            LineProducts {
                gram: linalg::gram(&em),
                basis: basis.block_t_mul(e, em.as_ref()),
                resid: linalg::t_mul(&em, &t.resid.as_ref().subrows(n2 * e, n2).to_owned()),
            }
        })
        .collect();
    let acts: Vec<Active> = (0..p.bands.len()).map(|e| active(p, e)).collect();
    // The outputs in parallel, added in output order: the same sums for any thread count.
    let terms: Vec<(Mat<f64>, Vec<f64>)> = (0..p.b.ncols())
        .into_par_iter()
        .map(|o| output_terms(p, s, t, o, (&prods, &acts)))
        .collect();
    let mut it = terms.into_iter();
    let (mut jtj, mut g) = it.next().expect("at least one output");
    for (a, b) in it {
        jtj += a;
        g.iter_mut().zip(b).for_each(|(x, y)| *x += y);
    }
    (jtj, g)
}

/// Output `o`'s share of [`normal_equations`]: `D_oᵀD_o − (Φ̃ᵀD_o)ᵀ(Φ̃ᵀΦ̃)⁻¹(Φ̃ᵀD_o)` and
/// `D_oᵀr_o`, the latter term as `Y_oᵀY_o` with `Y_o = R⁻ᵀ(Φ̃ᵀD_o)`.
fn output_terms(
    p: &Problem,
    s: &State,
    t: &Trial,
    o: usize,
    (prods, acts): (&[LineProducts], &[Active]),
) -> (Mat<f64>, Vec<f64>) {
    let np = p.n_params;
    let basis = t.ls.basis();
    let mut jtj = Mat::<f64>::zeros(np, np);
    let mut g = vec![0.0; np];
    let mut m = Mat::<f64>::zeros(t.ls.ncols(), np);
    for (e, (pr, act)) in prods.iter().zip(acts).enumerate() {
        let c = coefficients(p, s, &t.psi, (o, e), act);
        let cgc = linalg::t_mul(&c, &(&pr.gram * &c));
        for (i, &pi) in act.cols.iter().enumerate() {
            for (j, &pj) in act.cols.iter().enumerate() {
                jtj[(pi, pj)] += cgc[(i, j)];
            }
            for q in 0..c.nrows() {
                g[pi] += c[(q, i)] * pr.resid[(q, o)];
            }
        }
        let pc = &pr.basis * &c;
        for (i, &bi) in basis.block_cols(e).iter().enumerate() {
            for (j, &pj) in act.cols.iter().enumerate() {
                m[(bi, pj)] += pc[(i, j)];
            }
        }
    }
    let y = r_inv_t(&t.ls, &m);
    let mut proj = Mat::<f64>::zeros(np, np);
    linalg::gram_lower_add(&mut proj, y.as_ref());
    linalg::mirror_lower(&mut proj);
    (jtj - proj, g)
}

/// `R⁻ᵀ m` (forward substitution on the transposed triangular factor of `ls`).
fn r_inv_t(ls: &SetupLs, m: &Mat<f64>) -> Mat<f64> {
    let pc = ls.ncols();
    let r = Mat::from_fn(pc, pc, |i, j| ls.r(i, j));
    let mut y = Mat::<f64>::zeros(pc, m.ncols());
    for j in 0..m.ncols() {
        for i in 0..pc {
            let mut v = m[(i, j)];
            for l in 0..i {
                v -= r[(l, i)] * y[(l, j)];
            }
            y[(i, j)] = v / r[(i, i)];
        }
    }
    y
}

#[cfg(test)]
mod tests {
    use super::*;
    use rbprops_core::Quantity;

    /// Three excitations × four outputs of accelerance, noise-free: two poles half a
    /// half-bandwidth apart with different participation vectors, and a root of
    /// multiplicity two (two modes, one pole, independent participations), with upper
    /// and lower residual terms. Returns the bands, the true poles, roots and parts.
    fn synthetic() -> (Vec<BandData>, Vec<Pole>, Vec<usize>, Vec<Vec<c64>>) {
        let c = c64::new;
        let poles = vec![
            Pole::from_modal(1.0, 0.02),
            Pole::from_modal(1.01, 0.02),
            Pole::from_modal(1.7, 0.01),
            Pole::from_modal(1.7, 0.01),
        ];
        let roots = vec![0, 1, 2, 2];
        let parts = vec![
            vec![c(1.0, 0.0), c(0.3, 0.05), c(-0.2, 0.0)],
            vec![c(-0.4, 0.0), c(1.0, 0.0), c(0.5, -0.1)],
            vec![c(0.8, 0.0), c(0.1, 0.0), c(0.6, 0.0)],
            vec![c(0.0, 0.0), c(1.0, 0.0), c(-0.7, 0.02)],
        ];
        let psi = [
            [c(1.0, 0.0), c(0.5, 0.1), c(-0.3, 0.0), c(0.2, 0.0)],
            [c(0.2, 0.0), c(-1.0, 0.0), c(0.7, -0.05), c(0.4, 0.0)],
            [c(0.6, 0.0), c(0.3, 0.0), c(-0.5, 0.0), c(1.0, 0.0)],
            [c(-0.2, 0.0), c(0.9, 0.0), c(0.4, 0.0), c(0.1, 0.0)],
        ];
        let freq: Vec<f64> = (1..=300).map(|k| k as f64 * 0.01).collect();
        let omega: Vec<f64> = freq
            .iter()
            .map(|f| 2.0 * std::f64::consts::PI * f)
            .collect();
        let bands = (0..3)
            .map(|e| {
                let channels = (0..4)
                    .map(|o| {
                        omega
                            .iter()
                            .map(|&w| {
                                let modes: c64 = (0..4)
                                    .map(|r| poles[r].receptance(psi[r][o] * parts[r][e], w))
                                    .sum();
                                let upper = 1e-3 * (o + e) as f64;
                                let lower = -2e-2 * (1 + o) as f64 / (w * w);
                                -w * w * (modes + c(upper + lower, 0.0))
                            })
                            .collect()
                    })
                    .collect();
                BandData {
                    quantity: Quantity::Accelerance,
                    frequency_hz: freq.clone(),
                    omega: omega.clone(),
                    channels,
                    first_line: 0,
                    line_quality: None,
                }
            })
            .collect();
        (bands, poles, roots, parts)
    }

    /// `ni` excitations × three outputs of accelerance, noise-free, of the poles and
    /// roots of [`synthetic`] (a close pair and a repeated root) with participation
    /// vectors spread over the excitations and residual terms per excitation: their
    /// rows span at most 8 + 3 + 3 real directions, fewer than
    /// [`MAX_REFINEMENT_REFERENCES`].
    fn synthetic_many(ni: usize) -> (Vec<BandData>, Vec<Pole>, Vec<usize>, Vec<Vec<c64>>) {
        let (three, poles, roots, _) = synthetic();
        let parts: Vec<Vec<c64>> = (0..poles.len())
            .map(|r| {
                (0..ni)
                    .map(|e| {
                        let (x, y) = (e as f64, r as f64);
                        c64::new(
                            (1.3 * x * (y + 1.0) + 0.2 * y).cos(),
                            0.3 * (0.7 * x + y).sin(),
                        )
                    })
                    .collect()
            })
            .collect();
        let psi = [
            [c64::new(1.0, 0.0), c64::new(0.5, 0.1), c64::new(-0.3, 0.0)],
            [
                c64::new(0.2, 0.0),
                c64::new(-1.0, 0.0),
                c64::new(0.7, -0.05),
            ],
            [c64::new(0.6, 0.0), c64::new(0.3, 0.0), c64::new(-0.5, 0.0)],
            [c64::new(-0.2, 0.0), c64::new(0.9, 0.0), c64::new(0.4, 0.0)],
        ];
        let omega = three[0].omega.clone();
        let bands = (0..ni)
            .map(|e| {
                let channels = (0..3)
                    .map(|o| {
                        omega
                            .iter()
                            .map(|&w| {
                                let modes: c64 = (0..4)
                                    .map(|r| poles[r].receptance(psi[r][o] * parts[r][e], w))
                                    .sum();
                                let upper = 1e-3 * ((o + 2 * e) % 5) as f64;
                                let lower = -2e-2 * (1 + (o * e) % 3) as f64 / (w * w);
                                -w * w * (modes + c64::new(upper + lower, 0.0))
                            })
                            .collect()
                    })
                    .collect();
                BandData {
                    channels,
                    ..three[0].clone()
                }
            })
            .collect();
        (bands, poles, roots, parts)
    }

    /// The poly-reference passes read a set-up's bands one at a time
    /// ([`crate::setup_bands`]): held, or read again with 1, 5 or all 24 held at once by
    /// the Gram matrix's pass, the principal references, the refinement and the shape
    /// fit (shapes, residues, fitted FRFs) are the same bit for bit (1 % noise, so that
    /// every direction carries something and the cut is the noise's).
    #[test]
    fn bands_read_again_by_blocks_fit_as_held() {
        let res = Residuals {
            upper: true,
            lower: true,
        };
        let (mut bands, poles, roots, parts) = synthetic_many(24);
        let mut rng = rbprops_testkit::Lcg::new(3);
        for v in bands
            .iter_mut()
            .flat_map(|b| b.channels.iter_mut().flatten())
        {
            *v *= c64::new(1.0 + 0.01 * rng.centred(), 0.01 * rng.centred());
        }
        let bits = |z: &[c64]| -> Vec<(u64, u64)> {
            z.iter().map(|z| (z.re.to_bits(), z.im.to_bits())).collect()
        };
        let flat = |v: &[Vec<c64>]| -> Vec<(u64, u64)> { v.iter().flat_map(|x| bits(x)).collect() };
        let keep: Vec<usize> = (0..bands[0].n_lines()).step_by(3).collect();
        let held = &bands;
        let pr = plscf::PrincipalReferences::of_bands(held, &keep)
            .unwrap()
            .expect("cut");
        let rf = refine_set_up(&poles, &parts, &roots, held, res).unwrap();
        let sf = plsfd::fit_shapes(&poles, &parts, held, res).unwrap();
        assert!(rf.references < 24, "refined on the principal references");
        // The normal equations summed excitation by excitation against Householder QR
        // of the whole basis: the same shapes to rounding.
        let dense = plsfd::fit_shapes_whole(&poles, &parts, held, res).unwrap();
        for (a, b) in sf
            .shapes
            .iter()
            .flatten()
            .zip(dense.shapes.iter().flatten())
        {
            assert!(
                (a - b).norm() <= 1e-9 * b.norm().max(1e-3),
                "{a} against {b}"
            );
        }
        for block in [1, 5, 24] {
            let again = crate::setup_bands::ReadAgain {
                bands: &bands,
                block,
            };
            let p2 = plscf::PrincipalReferences::of_bands(&again, &keep)
                .unwrap()
                .unwrap();
            let h = |p: &plscf::PrincipalReferences| -> Vec<(u64, u64)> {
                p.h.iter().flat_map(|row| flat(row)).collect()
            };
            assert!(h(&p2) == h(&pr), "principal references, block {block}");
            for l in &parts {
                assert_eq!(bits(&p2.project(l)), bits(&pr.project(l)), "block {block}");
            }
            let r2 = refine_set_up(&poles, &parts, &roots, &again, res).unwrap();
            let poles_bits = |p: &[Pole]| bits(&p.iter().map(|p| p.0).collect::<Vec<_>>());
            assert_eq!(
                poles_bits(&r2.poles),
                poles_bits(&rf.poles),
                "block {block}"
            );
            assert_eq!(flat(&r2.parts), flat(&rf.parts), "block {block}");
            let s2 = plsfd::fit_shapes(&poles, &parts, &again, res).unwrap();
            assert_eq!(flat(&s2.shapes), flat(&sf.shapes), "block {block}");
            for e in [0, 11, 23] {
                assert_eq!(
                    flat(&s2.residues[e]),
                    flat(&sf.residues[e]),
                    "block {block}"
                );
                assert_eq!(
                    flat(&s2.synthesised(e, &bands[e])),
                    flat(&sf.synthesised(e, &bands[e])),
                    "block {block}"
                );
            }
        }
    }

    /// Above [`MAX_REFINEMENT_REFERENCES`] excitations the refinement runs on the
    /// principal references and still lands on the exact poles (1e-10 relative) from a
    /// start 0.3 half-bandwidths away, with the exact participation vectors of the
    /// distinct modes (1e-8) mapped back to every excitation; its unknowns do not grow
    /// with the excitations (the same number of references at 24 and 40).
    #[test]
    fn many_excitations_refine_on_principal_references_to_exact_poles() {
        let res = Residuals {
            upper: true,
            lower: true,
        };
        let mut references = Vec::new();
        for ni in [24, 40] {
            let (bands, poles, roots, parts) = synthetic_many(ni);
            let refs: Vec<&BandData> = bands.iter().collect();
            let moved: Vec<Pole> = poles
                .iter()
                .zip(&roots)
                .map(|(p, &g)| {
                    let ang = 1.0 + 2.0 * g as f64;
                    Pole(p.0 + 0.3 * p.half_bandwidth() * c64::from_polar(1.0, ang))
                })
                .collect();
            let tilted: Vec<Vec<c64>> = parts
                .iter()
                .map(|l| {
                    l.iter()
                        .enumerate()
                        .map(|(e, x)| x + c64::new(0.03 * (e % 3) as f64 - 0.03, 0.01))
                        .collect()
                })
                .collect();
            let rf = refine_set_up(&moved, &tilted, &roots, &refs, res).unwrap();
            assert!(
                rf.references <= MAX_REFINEMENT_REFERENCES,
                "{ni}: {}",
                rf.references
            );
            references.push(rf.references);
            let err = pole_error(&rf.poles, &poles);
            assert!(rf.converged && err < 1e-10, "{ni}: {err:e}: {:?}", rf.poles);
            assert_eq!(rf.parts[0].len(), ni);
            for r in 0..2 {
                let mut want = parts[r].clone();
                normalise_phase(&mut want);
                let d: f64 = rf.parts[r]
                    .iter()
                    .zip(&want)
                    .map(|(a, b)| (a - b).norm())
                    .sum();
                assert!(d < 1e-8, "{ni}, mode {r}: {d:e}");
            }
        }
        assert_eq!(references[0], references[1]);
    }

    /// Up to [`MAX_REFINEMENT_REFERENCES`] excitations, [`refine_set_up`] is [`refine`]
    /// on the excitations themselves, bit for bit.
    #[test]
    fn few_excitations_refine_on_every_excitation() {
        let (bands, poles, roots, parts) = synthetic();
        let refs: Vec<&BandData> = bands.iter().collect();
        let res = Residuals {
            upper: true,
            lower: false,
        };
        let a = refine(&poles, &parts, &roots, &refs, res);
        let b = refine_set_up(&poles, &parts, &roots, &refs, res).unwrap();
        assert_eq!(b.references, 3);
        assert_eq!(format!("{:?}", a), format!("{:?}", b));
    }

    /// Largest distance of `got` from `want`, relative to |λ|.
    fn pole_error(got: &[Pole], want: &[Pole]) -> f64 {
        got.iter()
            .zip(want)
            .map(|(a, b)| (a.0 - b.0).norm() / b.0.norm())
            .fold(0.0, f64::max)
    }

    /// From the exact poles and participations, and from poles moved by 0.3
    /// half-bandwidths (and participations by ~5 %), the refinement lands on the exact
    /// poles to 1e-10 relative (rounding on noise-free data; the residue ψ lᵀ is
    /// recovered, so the participation spans too).
    #[test]
    fn refinement_recovers_exact_poles_from_perturbed_start() {
        let (bands, poles, roots, parts) = synthetic();
        let refs: Vec<&BandData> = bands.iter().collect();
        let res = Residuals {
            upper: true,
            lower: true,
        };
        let exact = refine(&poles, &parts, &roots, &refs, res);
        assert!(
            pole_error(&exact.poles, &poles) < 1e-10,
            "{:?}",
            exact.poles
        );
        // Start: each root moved by 0.3 of its half-bandwidth in a different direction.
        let moved: Vec<Pole> = poles
            .iter()
            .zip(&roots)
            .map(|(p, &g)| {
                let ang = 1.0 + 2.0 * g as f64;
                Pole(p.0 + 0.3 * p.half_bandwidth() * c64::from_polar(1.0, ang))
            })
            .collect();
        let start_err = pole_error(&moved, &poles);
        let tilted: Vec<Vec<c64>> = parts
            .iter()
            .enumerate()
            .map(|(r, l)| {
                l.iter()
                    .enumerate()
                    .map(|(e, x)| x + c64::new(0.05 * ((r + e) % 3) as f64 - 0.05, 0.02))
                    .collect()
            })
            .collect();
        let rf = refine(&moved, &tilted, &roots, &refs, res);
        let err = pole_error(&rf.poles, &poles);
        eprintln!(
            "start {start_err:.2e} → {err:.2e} in {} iterations, cost {:.2e} → {:.2e}",
            rf.iterations, rf.cost.0, rf.cost.1
        );
        assert!(rf.converged && err < 1e-10, "{err:e}: {:?}", rf.poles);
        // The two modes of the repeated root share their pole exactly.
        assert_eq!(rf.poles[2].0, rf.poles[3].0);
        // The distinct modes' participation vectors come back (unit norm, phase fixed).
        for r in 0..2 {
            let mut want = parts[r].clone();
            normalise_phase(&mut want);
            let d: f64 = rf.parts[r]
                .iter()
                .zip(&want)
                .map(|(a, b)| (a - b).norm())
                .sum();
            assert!(d < 1e-8, "mode {r}: {:?} vs {want:?}", rf.parts[r]);
        }
        // The repeated root's two participations span the true plane: each true vector
        // has no component off the span of the refined pair.
        let span = |v: &[c64]| -> f64 {
            let (a, b) = (&rf.parts[2], &rf.parts[3]);
            // Gram–Schmidt on (a, b), then the residual of v.
            let dot =
                |x: &[c64], y: &[c64]| -> c64 { x.iter().zip(y).map(|(p, q)| p.conj() * q).sum() };
            let na = dot(a, a).re.sqrt();
            let qa: Vec<c64> = a.iter().map(|x| x / na).collect();
            let ca = dot(&qa, b);
            let bb: Vec<c64> = b.iter().zip(&qa).map(|(x, q)| x - ca * q).collect();
            let nb = dot(&bb, &bb).re.sqrt();
            let qb: Vec<c64> = bb.iter().map(|x| x / nb).collect();
            let (pa, pb) = (dot(&qa, v), dot(&qb, v));
            let r: Vec<c64> = v
                .iter()
                .zip(qa.iter().zip(&qb))
                .map(|(x, (p, q))| x - pa * p - pb * q)
                .collect();
            dot(&r, &r).re.sqrt() / dot(v, v).re.sqrt()
        };
        for r in 2..4 {
            assert!(span(&parts[r]) < 1e-8, "mode {r}: {}", span(&parts[r]));
        }
    }
}
