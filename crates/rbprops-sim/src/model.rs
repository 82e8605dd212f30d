//! The linear dynamic model of one suspension set-up:
//! `H(ω) = S (K + iωC − ω²M)⁻¹ F` (receptance), plus any additive terms effects define.
//!
//! Effects of the physics catalogue act on this structure (see [`crate::effects`]), so
//! that a fitter can rebuild the same model with other effect parameters.

use nalgebra::{Matrix6, RowVector6, Vector6};
use rbprops_core::{c64, rigid_body_modes, Mat6, RigidMode, Vec3, Vec6};

/// A force input of a set-up's model.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelInput {
    /// Index of the excitation in the campaign (spec and `FrfSet` order).
    pub excitation: usize,
    /// Generalised force column about O, `T(p)ᵀ d` nominally.
    pub column: Vec6,
    /// Where the force acts (m, about O): the spec's point until `force_location` moves
    /// it. What sits at the driving point (a gauge's mass, a stinger) sits here.
    pub point: Vec3,
    /// The unit direction the force acts along: the spec's until `force_direction`
    /// turns it.
    pub direction: Vec3,
    /// Mass attached to the body only while this excitation is measured (e.g. the mass
    /// below a force gauge), about O: the model for this input is `Z(s) + s² M_a`.
    pub attached_mass: Mat6,
    /// Stiffness added only while this excitation is measured (a stinger to a grounded
    /// shaker, the suspension drifting between runs), about O: the model for this
    /// input is `Z(s) + K_a`.
    pub attached_stiffness: Mat6,
}

impl ModelInput {
    /// Whether this input sees the set-up's model unchanged.
    pub fn is_plain(&self) -> bool {
        self.attached_mass == Mat6::zeros() && self.attached_stiffness == Mat6::zeros()
    }
}

/// How the records are observed: signal processing and the sensor equation. The
/// default observes the plain FRF `s^k S G(s) F` at `s = iω` (k = quantity order).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Observation {
    /// Exponential window `e^{−σt}` on force and response (σ, 1/s): every FRF is its
    /// transfer function at `s = iω + σ` (see [`crate::effects::processing`]).
    pub window_decay_per_s: f64,
    /// Record length T (s): every FRF is the finite transform `∫_0^T y(t) e^{−st} dt` of
    /// its impulse response, not the infinite one.
    pub record_length_s: Option<f64>,
    /// Specific-force term of each channel, `g dᵀ[0 | [ẑ]×]` (accelerometers sense
    /// `a + g ẑ×θ`); empty when gravity is not in the sensor equation. It adds
    /// `s^{k−2} g_c G(s) F` to channel c.
    pub gravity_rows: Vec<RowVector6<f64>>,
    /// First-order high-pass time constants per channel (empty: none); channel c is
    /// multiplied by `Π iωτ/(1 + iωτ)` over its list.
    pub highpass_time_constants_s: Vec<Vec<f64>>,
}

impl Observation {
    /// True when the plain FRF is observed (the fast path of the simulator applies).
    pub fn is_plain(&self) -> bool {
        self.window_decay_per_s == 0.0
            && self.record_length_s.is_none()
            && self.gravity_rows.is_empty()
            && self.highpass_time_constants_s.iter().all(|v| v.is_empty())
    }
}

/// An extra mode outside the rigid-body model (an elastic mode, say), added to the
/// receptance as `ψ_c ψ_e / (ω_m² − ω² + 2iζ_m ω_m ω)`.
#[derive(Debug, Clone, PartialEq)]
pub struct ExtraMode {
    /// Natural frequency `ω_m/2π` (Hz).
    pub frequency_hz: f64,
    /// Damping ratio `ζ_m` (fraction of critical).
    pub damping_ratio: f64,
    /// Mass-normalised modal displacement along each channel (campaign channel order).
    pub at_channels: Vec<f64>,
    /// Mass-normalised modal displacement along each excitation's force (campaign order).
    pub at_excitations: Vec<f64>,
}

impl ExtraMode {
    /// The mode's receptance term between channel `c` and excitation `e`.
    pub fn receptance(&self, c: usize, e: usize, omega: f64) -> c64 {
        let wm = std::f64::consts::TAU * self.frequency_hz;
        c64::new(self.at_channels[c] * self.at_excitations[e], 0.0)
            / c64::new(
                wm * wm - omega * omega,
                2.0 * self.damping_ratio * wm * omega,
            )
    }
}

/// The line factors `h_m` of every extra mode of a set-up on every line (`[mode][line]`).
/// They do not depend on the excitation: a set-up's excitations share one table.
pub struct ModeLineFactors {
    n_lines: usize,
    h: Vec<c64>,
}

impl ModeLineFactors {
    /// At `s = iω` (the axis `omegas`): `h_m(ω) = 1/(ω_m² − ω² + 2iζ_m ω_m ω)`
    /// ([`ExtraMode::receptance`] without its shape factors).
    pub fn at_iw(modes: &[ExtraMode], omegas: &[f64]) -> ModeLineFactors {
        Self::of(modes, omegas.len(), |wm, zeta, h| {
            line_factors_at_iw(wm, zeta, omegas, h)
        })
    }

    /// At complex Laplace variables `s` (one per line): `h_m = 1/(s² + 2ζ_m ω_m s + ω_m²)`
    /// ([`ExtraMode::receptance_at`] without its shape factors).
    pub fn at_s(modes: &[ExtraMode], s: &[c64]) -> ModeLineFactors {
        Self::of(modes, s.len(), |wm, zeta, h| {
            line_factors_at_s(wm, zeta, s, h)
        })
    }

    fn of(
        modes: &[ExtraMode],
        n_lines: usize,
        line_factors: impl Fn(f64, f64, &mut [c64]),
    ) -> ModeLineFactors {
        let mut h = vec![c64::new(0.0, 0.0); modes.len() * n_lines];
        if n_lines > 0 {
            for (m, h) in modes.iter().zip(h.chunks_exact_mut(n_lines)) {
                line_factors(std::f64::consts::TAU * m.frequency_hz, m.damping_ratio, h);
            }
        }
        ModeLineFactors { n_lines, h }
    }

    /// Mode m's factors on the lines `lines`.
    fn of_mode(&self, m: usize, lines: std::ops::Range<usize>) -> &[c64] {
        &self.h[m * self.n_lines..(m + 1) * self.n_lines][lines]
    }
}

rbprops_core::avx_fn! {
    /// `h = 1/(ω_m² − ω² + 2iζ_m ω_m ω)` per line.
    fn line_factors_at_iw(wm: f64, zeta: f64, omegas: &[f64], h: &mut [c64]) {
        for (h, &w) in h.iter_mut().zip(omegas) {
            *h = c64::new(wm * wm - w * w, 2.0 * zeta * wm * w).inv();
        }
    }
}

rbprops_core::avx_fn! {
    /// `h = 1/(s² + 2ζ_m ω_m s + ω_m²)` per line.
    fn line_factors_at_s(wm: f64, zeta: f64, s: &[c64], h: &mut [c64]) {
        for (h, &s) in h.iter_mut().zip(s) {
            *h = (s * s + s * (2.0 * zeta * wm) + wm * wm).inv();
        }
    }
}

/// Lines per block of [`add_extra_receptances`]: one channel's values of a block
/// (16 complex values, eight AVX registers) stay in registers while every mode is added
/// to them, eight independent sums in flight.
const EXTRA_MODE_BLOCK: usize = 16;

/// Adds the receptance terms of `modes` for excitation `e` to `values` (`[channel][line]`):
/// `H_ce += Σ_m ψ_c ψ_e h_m` over the modes that `e` drives, with the modes' line factors
/// `factors` ([`ModeLineFactors`], computed once per set-up); it is
/// [`ExtraMode::receptance`] (or [`ExtraMode::receptance_at`]) summed, to rounding.
///
/// The lines are walked in blocks of `EXTRA_MODE_BLOCK` (16): each channel's values of a
/// block are loaded once, receive every mode's term and are stored once. With the cords'
/// string modes (about a hundred extra modes) the values were otherwise loaded and
/// stored once per mode. Each value receives the same terms in the same (mode) order,
/// so the sums are bit-identical to adding the modes one by one.
pub fn add_extra_receptances(
    modes: &[ExtraMode],
    e: usize,
    factors: &ModeLineFactors,
    values: &mut [c64],
) {
    const B: usize = EXTRA_MODE_BLOCK;
    let nl = factors.n_lines;
    let driven: Vec<usize> = (0..modes.len())
        .filter(|&m| modes[m].at_excitations[e] != 0.0)
        .collect();
    if driven.is_empty() || nl == 0 {
        return;
    }
    let n_ch = values.len() / nl;
    // ψ_c ψ_e per channel and driven mode; channels a mode does not list get none.
    let coef: Vec<f64> = (0..n_ch)
        .flat_map(|c| {
            driven.iter().map(move |&m| {
                modes[m]
                    .at_channels
                    .get(c)
                    .map_or(0.0, |pc| pc * modes[m].at_excitations[e])
            })
        })
        .collect();
    let mut h = vec![c64::new(0.0, 0.0); driven.len() * B];
    let mut start = 0;
    while start < nl {
        let end = (start + B).min(nl);
        for (&m, h) in driven.iter().zip(h.chunks_exact_mut(B)) {
            h[..end - start].copy_from_slice(factors.of_mode(m, start..end));
        }
        add_mode_terms(values, nl, start, end, &coef, &h);
        start = end;
    }
}

rbprops_core::avx_fn! {
    /// `values[c][start..end] += Σ_m coef[c][m] h[m][..]` in mode order (`coef` by
    /// channel, one entry per mode; `h` by mode, [`EXTRA_MODE_BLOCK`] lines each), a zero
    /// coefficient adding nothing: [`add_extra_receptances`]' inner loop, each channel's
    /// values of the block held in registers over all modes (with AVX, two complex values
    /// per instruction).
    fn add_mode_terms(
        values: &mut [c64],
        nl: usize,
        start: usize,
        end: usize,
        coef: &[f64],
        h: &[c64],
    ) {
        const B: usize = EXTRA_MODE_BLOCK;
        let w = end - start;
        let n_modes = h.len() / B;
        for (dst, coef) in values.chunks_exact_mut(nl).zip(coef.chunks_exact(n_modes)) {
            let dst = &mut dst[start..end];
            let mut acc = [c64::new(0.0, 0.0); B];
            acc[..w].copy_from_slice(dst);
            // The whole block, fixed length: past `w` (the last block) the sums take
            // stale factors and are not stored.
            for (&a, h) in coef.iter().zip(h.chunks_exact(B)) {
                if a != 0.0 {
                    for (d, h) in acc.iter_mut().zip(h) {
                        *d += h * a;
                    }
                }
            }
            dst.copy_from_slice(&acc[..w]);
        }
    }
}

impl ExtraMode {
    /// The mode's receptance term at a complex Laplace variable `s`:
    /// `ψ_c ψ_e / (ω_m² + 2ζ_m ω_m s + s²)` (equals [`Self::receptance`] at `s = iω`).
    pub fn receptance_at(&self, c: usize, e: usize, s: c64) -> c64 {
        let wm = std::f64::consts::TAU * self.frequency_hz;
        c64::new(self.at_channels[c] * self.at_excitations[e], 0.0)
            / (s * s + s * (2.0 * self.damping_ratio * wm) + wm * wm)
    }
}

/// Mass, stiffness, viscous damping, output rows and input columns of one set-up.
#[derive(Debug, Clone, PartialEq)]
pub struct DynamicModel {
    /// The set-up's id.
    pub setup: String,
    /// 6×6 mass matrix about O (body plus any attached masses).
    pub mass: Mat6,
    /// 6×6 stiffness about O (springs plus any geometric stiffness).
    pub stiffness: Mat6,
    /// 6×6 viscous damping about O.
    pub damping: Mat6,
    /// 6×6 hysteretic (structural) damping D about O: a loss `iD` in the dynamic
    /// stiffness at every frequency, `Z = K + iD + iωC − ω²M` (rubber mounts' loss
    /// factors). It has no time-domain model.
    pub structural_damping: Mat6,
    /// Output rows, one per channel (campaign order): `sᵀT(p)` nominally.
    pub outputs: Vec<RowVector6<f64>>,
    /// Inputs of this set-up's excitations.
    pub inputs: Vec<ModelInput>,
    /// Modes outside the rigid-body model, added to every FRF of this set-up.
    pub extra_modes: Vec<ExtraMode>,
    /// How the FRFs are observed (window, record length, gravity in the sensors, filters).
    pub observation: Observation,
}

/// The receptance of a set of modes between generalised coordinates,
/// `G(ω) = Σ_r φ_r φ_rᵀ / (ω_r² − ω² + 2iζ_r ω_r ω)` (classical damping).
pub fn modal_compliance(modes: &[RigidMode], omega: f64) -> Matrix6<c64> {
    let mut g = Matrix6::<c64>::zeros();
    for m in modes {
        let wr = m.omega();
        let d = c64::new(1.0, 0.0)
            / c64::new(wr * wr - omega * omega, 2.0 * m.damping_ratio * wr * omega);
        for i in 0..6 {
            for j in 0..6 {
                g[(i, j)] += d * (m.shape[i] * m.shape[j]);
            }
        }
    }
    g
}

impl DynamicModel {
    /// Dynamic stiffness `Z(ω) = K + i sgn(ω) D + iωC − ω²M` (D: hysteretic damping,
    /// odd in ω so that the impulse response stays real).
    pub fn dynamic_stiffness(&self, omega: f64) -> Matrix6<c64> {
        let sgn = if omega < 0.0 { -1.0 } else { 1.0 };
        Matrix6::from_fn(|i, j| {
            c64::new(
                self.stiffness[(i, j)] - omega * omega * self.mass[(i, j)],
                omega * self.damping[(i, j)] + sgn * self.structural_damping[(i, j)],
            )
        })
    }

    /// Receptance between generalised coordinates by direct solution, `G = Z(ω)⁻¹`.
    /// Returns `None` when `Z` is singular at `ω` (an undamped resonance on the line).
    pub fn direct_compliance(&self, omega: f64) -> Option<Matrix6<c64>> {
        let z = self.dynamic_stiffness(omega);
        let g = z.lu().try_inverse()?;
        // An ill-conditioned Z yields a finite but meaningless inverse: check Z G = I.
        let resid = (z * g - Matrix6::<c64>::identity()).norm();
        (resid.is_finite() && resid < 1e-6).then_some(g)
    }

    /// Real undamped modes of `(K, M)`, mass-normalised and ascending, each with the
    /// damping ratio `ζ_r = φ_rᵀ C φ_r / (2ω_r) + φ_rᵀ D φ_r / (2ω_r²)` (exact for
    /// classical viscous damping; the hysteretic part is its equivalent at resonance).
    pub fn modes(&self) -> Result<Vec<RigidMode>, String> {
        let modes = rigid_body_modes(&self.mass, &self.stiffness).map_err(|e| e.to_string())?;
        Ok(modes
            .into_iter()
            .map(|(w, phi)| RigidMode {
                frequency_hz: w / std::f64::consts::TAU,
                damping_ratio: if w > 0.0 {
                    (phi.transpose() * self.damping * phi)[0] / (2.0 * w)
                        + (phi.transpose() * self.structural_damping * phi)[0] / (2.0 * w * w)
                } else {
                    0.0
                },
                shape: phi,
            })
            .collect())
    }

    /// Largest off-diagonal of `ΦᵀCΦ` relative to its diagonal: 0 for classical damping;
    /// infinite with hysteretic damping, which the modal sum does not represent.
    pub fn damping_coupling(&self, modes: &[RigidMode]) -> f64 {
        let phi = Mat6::from_columns(&modes.iter().map(|m| m.shape).collect::<Vec<Vector6<f64>>>());
        if self.structural_damping != Mat6::zeros() {
            return f64::INFINITY;
        }
        // A free direction with viscous damping (`αM`) has a real pole at `−φᵀCφ`, which
        // the modal sum (a zero mode is `−1/ω²` there) does not represent.
        // (Modal damping gives it `2ζ·0 = 0` up to rounding, hence the relative test.)
        let c_rr: Vec<f64> = modes
            .iter()
            .map(|m| (m.shape.transpose() * self.damping * m.shape)[0])
            .collect();
        let c_max = c_rr.iter().fold(0.0f64, |a, c| a.max(c.abs()));
        if modes
            .iter()
            .zip(&c_rr)
            .any(|(m, c)| m.is_free() && c.abs() > 1e-9 * c_max)
        {
            return f64::INFINITY;
        }
        let cm = phi.transpose() * self.damping * phi;
        let diag = cm.diagonal().abs().max().max(f64::MIN_POSITIVE);
        let mut off = 0.0f64;
        for i in 0..6 {
            for j in 0..6 {
                if i != j {
                    off = off.max(cm[(i, j)].abs());
                }
            }
        }
        off / diag
    }
}

/// Displacements `x = Z(s)⁻¹ f` of a few force columns `f` for one dynamic stiffness
/// `Z(s) = K + i sgn(Im s) D + sC + s²M` (at `s = iω` it is
/// [`DynamicModel::dynamic_stiffness`]; `s = σ + iω` under an exponential window, as in
/// [`crate::observe`]), with the mass and stiffness given (an input's attached ones
/// included), by Gaussian elimination with partial pivoting on the 6×6 complex system
/// and all columns at once.
///
/// Why not `G = Z⁻¹` as [`DynamicModel::direct_compliance`]: a model fitter needs only
/// the set-up's inputs, so one elimination and a solve per input (≈ 200 complex
/// multiplications) replace the inverse, its check `Z G = I` and `S G` for every
/// coordinate (≈ 900). The values agree with the inverse's to rounding, not bit for bit.
///
/// `x[i]` receives the displacement of `forces[i]`. Returns `false` when `Z` is singular
/// to working precision: a pivot below 1e-10 of Z's largest entry (|re| + |im|), i.e.
/// a condition number above about 1e10, where the inverse's guard `‖Z G − I‖ < 1e-6`
/// (rounding 1e-16 × condition) fails too; or a non-finite solution. The pivots are
/// free by-products of the elimination, where checking `Z x = f` would cost another
/// third of the solve.
pub fn solve_columns(
    mass: &Mat6,
    stiffness: &Mat6,
    damping: &Mat6,
    structural_damping: &Mat6,
    s: c64,
    forces: &[[c64; 6]],
    x: &mut [[c64; 6]],
) -> bool {
    let sgn = if s.im < 0.0 { -1.0 } else { 1.0 };
    let s2 = s * s;
    let mut a: [[c64; 6]; 6] = std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            c64::new(
                stiffness[(i, j)] + s.re * damping[(i, j)] + s2.re * mass[(i, j)],
                s.im * damping[(i, j)] + sgn * structural_damping[(i, j)] + s2.im * mass[(i, j)],
            )
        })
    });
    let tiny = 1e-10 * a.iter().flatten().map(|v| v.l1_norm()).fold(0.0, f64::max);
    // Row k of the eliminated system; `perm` tracks the row swaps of the right-hand sides.
    let mut perm: [usize; 6] = std::array::from_fn(|i| i);
    for k in 0..6 {
        let p = (k..6)
            .max_by(|&x, &y| a[x][k].l1_norm().total_cmp(&a[y][k].l1_norm()))
            .unwrap_or(k);
        let pivot = a[p][k].l1_norm();
        if !(pivot > tiny && pivot.is_finite()) {
            return false;
        }
        a.swap(k, p);
        perm.swap(k, p);
        let inv = a[k][k].inv();
        a[k][k] = inv;
        let (top, below) = a.split_at_mut(k + 1);
        let pivot_row = &top[k];
        for row in below {
            let m = row[k] * inv;
            row[k] = m;
            for (r, p) in row[k + 1..].iter_mut().zip(&pivot_row[k + 1..]) {
                *r -= m * p;
            }
        }
    }
    for (x, b) in x.iter_mut().zip(forces) {
        let mut y: [c64; 6] = std::array::from_fn(|i| b[perm[i]]);
        for i in 1..6 {
            for j in 0..i {
                let t = a[i][j] * y[j];
                y[i] -= t;
            }
        }
        for i in (0..6).rev() {
            for j in i + 1..6 {
                let t = a[i][j] * y[j];
                y[i] -= t;
            }
            y[i] *= a[i][i];
        }
        *x = y;
    }
    x.iter()
        .flatten()
        .all(|v| v.re.is_finite() && v.im.is_finite())
}

/// Lines solved together by [`solve_columns_lines`].
pub const LINES_PER_SOLVE: usize = 8;

/// One value per line of a [`solve_columns_lines`] batch.
type Lanes = [f64; LINES_PER_SOLVE];

/// A 6×6 complex matrix of a batch of lines, split into real and imaginary parts with
/// the lines innermost (`re[i][j][line]`), so that each step of the elimination is the
/// same arithmetic on every line of the batch at once (SIMD-friendly).
#[derive(Clone, Copy)]
struct SplitMatrix {
    re: [[Lanes; 6]; 6],
    im: [[Lanes; 6]; 6],
}

/// `(ar + i ai)(br + i bi)` on every line, as `num_complex`'s product computes it
/// (`re = ar br − ai bi`, `im = ar bi + ai br`), so that the results are bit for bit
/// those of [`solve_columns`].
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn lanes_mul(ar: &Lanes, ai: &Lanes, br: &Lanes, bi: &Lanes) -> (Lanes, Lanes) {
    let mut re = [0.0; LINES_PER_SOLVE];
    let mut im = [0.0; LINES_PER_SOLVE];
    for l in 0..LINES_PER_SOLVE {
        re[l] = ar[l] * br[l] - ai[l] * bi[l];
        im[l] = ar[l] * bi[l] + ai[l] * br[l];
    }
    (re, im)
}

rbprops_core::avx_fn! {
    /// [`solve_columns`] for [`LINES_PER_SOLVE`] lines at once (`s[l]` the Laplace variable
    /// of line l): the same elimination with partial pivoting, each line choosing its own
    /// pivots, and the same floating-point operations in the same order, so `x[f][l]` (force
    /// f, line l) is bit for bit what [`solve_columns`] gives for line l. Returns per line
    /// whether its `Z` was regular (see [`solve_columns`]).
    ///
    /// Why: the per-line solve of 6×6 complex systems is a quarter of a model fitter's time,
    /// and one line at a time it is scalar code (a complex product mixes the real and
    /// imaginary parts of one value); with the lines innermost every operation is a vector
    /// operation over the batch.
    ///
    /// Compiled for the baseline and with AVX, the factorisation and the solves inlined
    /// into one function.
    pub fn solve_columns_lines(
        mass: &Mat6,
        stiffness: &Mat6,
        damping: &Mat6,
        structural_damping: &Mat6,
        s: &[c64; LINES_PER_SOLVE],
        forces: &[[c64; 6]],
        x: &mut [[[c64; 6]; LINES_PER_SOLVE]],
    ) -> [bool; LINES_PER_SOLVE] {
        let lu = factor_lines(assemble_lines(mass, stiffness, damping, structural_damping, s));
        let mut ok = lu.regular;
        for (x, f) in x.iter_mut().zip(forces) {
            solve_lines_into(&lu, &[*f; LINES_PER_SOLVE], x);
            for (ok, x) in ok.iter_mut().zip(x.iter()) {
                *ok &= x.iter().all(|v| v.re.is_finite() && v.im.is_finite());
            }
        }
        ok
    }
}

/// The LU factors (partial pivoting) of `Z(s) = K + i sgn(Im s) D + sC + s²M` on each
/// line of a batch of [`LINES_PER_SOLVE`] lines, by the elimination of
/// [`solve_columns`] (see [`solve_columns_lines`]): factor once ([`factor_batch`]), then
/// solve for any right-hand sides, one per line ([`solve_batch`]).
pub struct LinesLu {
    /// Multipliers below the diagonal, the pivots' reciprocals on it, U above it.
    a: SplitMatrix,
    /// Row permutation of each line.
    perm: [[usize; 6]; LINES_PER_SOLVE],
    /// Whether each line's Z is regular (no pivot below 1e-10 of Z's largest entry).
    pub regular: [bool; LINES_PER_SOLVE],
}

rbprops_core::avx_fn! {
    /// Factorises Z(s) of each line of the batch `s` ([`LinesLu`]), compiled for the
    /// baseline and with AVX.
    pub fn factor_batch(
        mass: &Mat6,
        stiffness: &Mat6,
        damping: &Mat6,
        structural_damping: &Mat6,
        s: &[c64; LINES_PER_SOLVE],
    ) -> LinesLu {
        factor_lines(assemble_lines(mass, stiffness, damping, structural_damping, s))
    }
}

rbprops_core::avx_fn! {
    /// `x = Z⁻¹ b` on each line of a factorised batch (`b[l]` line l's right-hand side);
    /// a line that is not [`LinesLu::regular`] gets meaningless values. Compiled for the
    /// baseline and with AVX.
    pub fn solve_batch(
        lu: &LinesLu,
        b: &[[c64; 6]; LINES_PER_SOLVE],
    ) -> [[c64; 6]; LINES_PER_SOLVE] {
        let mut x = [[c64::new(0.0, 0.0); 6]; LINES_PER_SOLVE];
        solve_lines_into(lu, b, &mut x);
        x
    }
}

/// The elimination of [`solve_columns`] on every line of a batch (see [`LinesLu`]).
// Indexed loops over the lines: the same index into several arrays is what vectorises.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn factor_lines(mut a: SplitMatrix) -> LinesLu {
    const L: usize = LINES_PER_SOLVE;
    let mut tiny = [0.0f64; L];
    for i in 0..6 {
        for j in 0..6 {
            for l in 0..L {
                tiny[l] = tiny[l].max(a.re[i][j][l].abs() + a.im[i][j][l].abs());
            }
        }
    }
    let mut regular = [true; L];
    let mut perm = [[0usize; 6]; L];
    for p in perm.iter_mut() {
        *p = std::array::from_fn(|i| i);
    }
    for k in 0..6 {
        let mut norms = [[0.0; L]; 6];
        for r in k..6 {
            for l in 0..L {
                norms[r][l] = a.re[r][k][l].abs() + a.im[r][k][l].abs();
            }
        }
        for l in 0..L {
            // `max_by` keeps the last of equal maxima.
            let mut p = k;
            let mut best = norms[k][l];
            for (r, n) in norms.iter().enumerate().skip(k + 1) {
                let v = n[l];
                if best.total_cmp(&v) != std::cmp::Ordering::Greater {
                    best = v;
                    p = r;
                }
            }
            if !(best > 1e-10 * tiny[l] && best.is_finite()) {
                regular[l] = false;
            }
            if p != k {
                for j in 0..6 {
                    let (lo, hi) = (k.min(p), k.max(p));
                    let (top, bottom) = a.re.split_at_mut(hi);
                    std::mem::swap(&mut top[lo][j][l], &mut bottom[0][j][l]);
                    let (top, bottom) = a.im.split_at_mut(hi);
                    std::mem::swap(&mut top[lo][j][l], &mut bottom[0][j][l]);
                }
                perm[l].swap(k, p);
            }
        }
        // The pivot's reciprocal as `num_complex`'s `inv`: (re, −im) / |z|².
        let (pr, pi) = (a.re[k][k], a.im[k][k]);
        let mut inv_re = [0.0; L];
        let mut inv_im = [0.0; L];
        for l in 0..L {
            let n = pr[l] * pr[l] + pi[l] * pi[l];
            inv_re[l] = pr[l] / n;
            inv_im[l] = -pi[l] / n;
        }
        a.re[k][k] = inv_re;
        a.im[k][k] = inv_im;
        for r in k + 1..6 {
            let (mr, mi) = lanes_mul(&a.re[r][k], &a.im[r][k], &inv_re, &inv_im);
            a.re[r][k] = mr;
            a.im[r][k] = mi;
            for j in k + 1..6 {
                let (tr, ti) = lanes_mul(&mr, &mi, &a.re[k][j], &a.im[k][j]);
                for l in 0..L {
                    a.re[r][j][l] -= tr[l];
                    a.im[r][j][l] -= ti[l];
                }
            }
        }
    }
    LinesLu { a, perm, regular }
}

/// Forward and back substitution of [`solve_columns`] on every line of a batch, into `x`.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn solve_lines_into(
    lu: &LinesLu,
    b: &[[c64; 6]; LINES_PER_SOLVE],
    x: &mut [[c64; 6]; LINES_PER_SOLVE],
) {
    const L: usize = LINES_PER_SOLVE;
    let a = &lu.a;
    let mut yr = [[0.0; L]; 6];
    let mut yi = [[0.0; L]; 6];
    for l in 0..L {
        for i in 0..6 {
            yr[i][l] = b[l][lu.perm[l][i]].re;
            yi[i][l] = b[l][lu.perm[l][i]].im;
        }
    }
    for i in 1..6 {
        for j in 0..i {
            let (tr, ti) = lanes_mul(&a.re[i][j], &a.im[i][j], &yr[j], &yi[j]);
            for l in 0..L {
                yr[i][l] -= tr[l];
                yi[i][l] -= ti[l];
            }
        }
    }
    for i in (0..6).rev() {
        for j in i + 1..6 {
            let (tr, ti) = lanes_mul(&a.re[i][j], &a.im[i][j], &yr[j], &yi[j]);
            for l in 0..L {
                yr[i][l] -= tr[l];
                yi[i][l] -= ti[l];
            }
        }
        // `y *= d` as `num_complex`'s `*=`: re = yr dr − yi di, im = yi dr + yr di.
        let (dr, di) = (a.re[i][i], a.im[i][i]);
        for l in 0..L {
            let (r0, i0) = (yr[i][l], yi[i][l]);
            yr[i][l] = r0 * dr[l] - i0 * di[l];
            yi[i][l] = i0 * dr[l] + r0 * di[l];
        }
    }
    for (l, x) in x.iter_mut().enumerate() {
        for (i, x) in x.iter_mut().enumerate() {
            *x = c64::new(yr[i][l], yi[i][l]);
        }
    }
}

/// `Z(s) = K + i sgn(Im s) D + sC + s²M` of each line of a batch, each entry computed as
/// [`solve_columns`] computes it.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn assemble_lines(
    mass: &Mat6,
    stiffness: &Mat6,
    damping: &Mat6,
    structural_damping: &Mat6,
    s: &[c64; LINES_PER_SOLVE],
) -> SplitMatrix {
    const L: usize = LINES_PER_SOLVE;
    let mut a = SplitMatrix {
        re: [[[0.0; L]; 6]; 6],
        im: [[[0.0; L]; 6]; 6],
    };
    for l in 0..L {
        let sgn = if s[l].im < 0.0 { -1.0 } else { 1.0 };
        let s2 = s[l] * s[l];
        for i in 0..6 {
            for j in 0..6 {
                a.re[i][j][l] =
                    stiffness[(i, j)] + s[l].re * damping[(i, j)] + s2.re * mass[(i, j)];
                a.im[i][j][l] = s[l].im * damping[(i, j)]
                    + sgn * structural_damping[(i, j)]
                    + s2.im * mass[(i, j)];
            }
        }
    }
    a
}

/// Assembles `C = M Φ diag(2ζ_r ω_r) Φᵀ M`, which gives mode r the ratio ζ_r exactly
/// (ΦᵀMΦ = I, so ΦᵀCΦ = diag(2ζ_r ω_r)).
pub fn modal_damping_matrix(mass: &Mat6, modes: &[(f64, Vec6)], ratios: &[f64]) -> Mat6 {
    let mut c = Mat6::zeros();
    for ((w, phi), z) in modes.iter().zip(ratios) {
        let mphi = mass * phi;
        c += 2.0 * z * w * mphi * mphi.transpose();
    }
    (c + c.transpose()) / 2.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic stream of numbers in [−1, 1) (xorshift64*).
    fn uniform(state: &mut u64) -> f64 {
        *state ^= *state >> 12;
        *state ^= *state << 25;
        *state ^= *state >> 27;
        let v = state.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11;
        v as f64 / (1u64 << 52) as f64 - 1.0
    }

    /// The batched solve is the one-line solve bit for bit, line by line: random
    /// non-symmetric systems with structural damping, Laplace variables over four decades
    /// with both signs of Im s and window shifts (so the lines of a batch pivot
    /// differently), and a line that is exactly singular, refused on its own.
    #[test]
    fn batched_column_solve_is_the_one_line_solve_bit_for_bit() {
        let mut st = 0x9e37_79b9_7f4a_7c15u64;
        let forces: Vec<[c64; 6]> = (0..3)
            .map(|_| std::array::from_fn(|_| c64::new(uniform(&mut st), 0.0)))
            .collect();
        let bits = |x: &[c64; 6]| x.map(|v| (v.re.to_bits(), v.im.to_bits()));
        for trial in 0..200 {
            let mut mat = |scale: f64| Mat6::from_fn(|_, _| scale * uniform(&mut st));
            let mass = Mat6::identity() + mat(0.3);
            let stiffness = mat(1e3);
            let damping = mat(1.0);
            let structural = if trial % 2 == 0 {
                mat(10.0)
            } else {
                Mat6::zeros()
            };
            let s: [c64; LINES_PER_SOLVE] = std::array::from_fn(|_| {
                let w = 10f64.powf(2.0 * uniform(&mut st) + 1.0) * uniform(&mut st).signum();
                c64::new(
                    if trial % 3 == 0 {
                        0.5 * w.abs() * uniform(&mut st)
                    } else {
                        0.0
                    },
                    w,
                )
            });
            let mut x = vec![[[c64::new(0.0, 0.0); 6]; LINES_PER_SOLVE]; forces.len()];
            let ok = solve_columns_lines(
                &mass,
                &stiffness,
                &damping,
                &structural,
                &s,
                &forces,
                &mut x,
            );
            for (l, &sl) in s.iter().enumerate() {
                let mut x1 = vec![[c64::new(0.0, 0.0); 6]; forces.len()];
                let ok1 = solve_columns(
                    &mass,
                    &stiffness,
                    &damping,
                    &structural,
                    sl,
                    &forces,
                    &mut x1,
                );
                assert_eq!(ok[l], ok1, "trial {trial} line {l}");
                for f in 0..forces.len() {
                    assert_eq!(
                        bits(&x[f][l]),
                        bits(&x1[f]),
                        "trial {trial} line {l} force {f}"
                    );
                }
            }
        }
        // Undamped, uncoupled: Z(iω) = K − ω²M is exactly singular at ω² = k_1.
        let w = 7.0f64;
        let stiffness = Mat6::from_diagonal(&Vec6::from_fn(|i, _| (w + i as f64) * (w + i as f64)));
        let s: [c64; LINES_PER_SOLVE] =
            std::array::from_fn(|l| c64::new(0.0, if l == 1 { w } else { 0.5 + l as f64 }));
        let mut x = vec![[[c64::new(0.0, 0.0); 6]; LINES_PER_SOLVE]; 1];
        let zero = Mat6::zeros();
        let ok = solve_columns_lines(
            &Mat6::identity(),
            &stiffness,
            &zero,
            &zero,
            &s,
            &forces[..1],
            &mut x,
        );
        let expected: [bool; LINES_PER_SOLVE] = std::array::from_fn(|l| l != 1);
        assert_eq!(ok, expected);
    }

    /// The per-line factor form equals the per-term sum of [`ExtraMode::receptance`] to
    /// rounding, including a mode the excitation does not drive.
    #[test]
    fn extra_receptances_are_the_sum_of_the_terms() {
        let modes = [
            (3.0, 0.01, [0.2, -0.5], [0.7, 0.0]),
            (11.0, 0.03, [1.5, 0.1], [-0.3, 0.4]),
        ]
        .map(|(f, z, c, e)| ExtraMode {
            frequency_hz: f,
            damping_ratio: z,
            at_channels: c.to_vec(),
            at_excitations: e.to_vec(),
        });
        let omegas: Vec<f64> = (0..50).map(|l| 0.4 * l as f64).collect();
        for e in 0..2 {
            let mut got = vec![c64::new(1.0, -2.0); 2 * omegas.len()];
            add_extra_receptances(
                &modes,
                e,
                &ModeLineFactors::at_iw(&modes, &omegas),
                &mut got,
            );
            for (c, row) in got.chunks_exact(omegas.len()).enumerate() {
                for (g, &w) in row.iter().zip(&omegas) {
                    let want: c64 = c64::new(1.0, -2.0)
                        + modes.iter().map(|m| m.receptance(c, e, w)).sum::<c64>();
                    assert!((g - want).norm() <= 1e-14 * want.norm(), "{g} vs {want}");
                }
            }
        }
    }

    /// The line blocks change no bit: every value is the per-mode accumulation (each
    /// mode's line factor added in mode order), over line counts below, at and across
    /// the block size, at `iω` and at `s` alike.
    #[test]
    fn extra_receptances_in_line_blocks_are_the_per_mode_sums_bit_for_bit() {
        let modes: Vec<ExtraMode> = (0..7)
            .map(|m| ExtraMode {
                frequency_hz: 0.7 + 1.9 * m as f64,
                damping_ratio: 0.002 * (m + 1) as f64,
                at_channels: (0..3).map(|c| ((m * 3 + c) as f64).sin()).collect(),
                at_excitations: vec![(m as f64).cos(), if m == 2 { 0.0 } else { 0.3 }],
            })
            .collect();
        for nl in [
            1,
            EXTRA_MODE_BLOCK - 1,
            EXTRA_MODE_BLOCK,
            3 * EXTRA_MODE_BLOCK + 5,
        ] {
            let omegas: Vec<f64> = (0..nl).map(|l| 0.37 * l as f64).collect();
            let s: Vec<c64> = omegas.iter().map(|&w| c64::new(-0.25, w)).collect();
            for e in 0..2 {
                let start: Vec<c64> = (0..3 * nl)
                    .map(|i| c64::new(i as f64 * 1e-3, -(i as f64).sqrt()))
                    .collect();
                let (mut want, mut want_s) = (start.clone(), start.clone());
                for m in &modes {
                    let (wm, z, pe) = (
                        std::f64::consts::TAU * m.frequency_hz,
                        m.damping_ratio,
                        m.at_excitations[e],
                    );
                    for (c, &pc) in m.at_channels.iter().enumerate() {
                        let a = pc * pe;
                        if pe == 0.0 || a == 0.0 {
                            continue;
                        }
                        for l in 0..nl {
                            let w = omegas[l];
                            want[c * nl + l] +=
                                c64::new(wm * wm - w * w, 2.0 * z * wm * w).inv() * a;
                            let x = s[l];
                            want_s[c * nl + l] += (x * x + x * (2.0 * z * wm) + wm * wm).inv() * a;
                        }
                    }
                }
                let (mut got, mut got_s) = (start.clone(), start);
                add_extra_receptances(
                    &modes,
                    e,
                    &ModeLineFactors::at_iw(&modes, &omegas),
                    &mut got,
                );
                add_extra_receptances(&modes, e, &ModeLineFactors::at_s(&modes, &s), &mut got_s);
                for (g, w) in got.iter().zip(&want).chain(got_s.iter().zip(&want_s)) {
                    assert_eq!(
                        (g.re.to_bits(), g.im.to_bits()),
                        (w.re.to_bits(), w.im.to_bits()),
                        "nl = {nl}, e = {e}"
                    );
                }
            }
        }
    }
}
