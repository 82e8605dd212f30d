//! `cord_mass`: the inertia and the internal resonances of the suspension cords
//! (docs/physics.md, E3).
//!
//! Each spring of the set-up is read as a vertical cord, as in
//! [`gravity_stiffness`](super::gravity): lower end at the attachment point `a_i`, upper
//! end pinned at a fixed anchor `a_i + ℓ_i ẑ`, axial stiffness `k_i = ẑᵀ k ẑ`, tension
//! `T_i` from the static equilibrium of the loaded body ([`cord_tensions`], the very
//! computation `gravity_stiffness` uses). The tension is a fact of the hanging body, so
//! it is computed whether or not `gravity_stiffness` is switched on; the cord's weight
//! is neglected (uniform tension, `μ ℓ g ≪ T`).
//!
//! **Cord model (assumed modes, Craig–Bampton form).** Along the cord (s = 0 at the
//! anchor, s = ℓ at the body) the motion in each of the three directions `e_d` (two
//! horizontal, one axial) is
//!
//! `w_d(s, t) = (s/ℓ) e_dᵀ T(a) q(t) + Σ_{n=1..N} sin(nπs/ℓ) a_{d,n}(t)`,
//!
//! the static shape driven by the body plus the cord's own pinned–pinned modes. With
//! the mass per length μ, the kinetic energy `½ μ ∫ |ẇ|² ds` gives, per cord,
//!
//! - added body mass `ΔM = (μℓ/3) T(a)ᵀ T(a)` (`∫ (s/ℓ)² ds = ℓ/3`: a third of the
//!   cord's mass at its attachment, in every direction),
//! - modal mass `μℓ/2` per coordinate, and the body coupling
//!   `μ ∫ (s/ℓ) sin(nπs/ℓ) ds = μℓ (−1)^{n+1}/(nπ)` along `T(a)ᵀ e_d`;
//!
//! the strain energy has no body–mode coupling (`∫ (1/ℓ) cos(nπs/ℓ) ds = 0`): the static
//! shape's stiffness (`T/ℓ` laterally, `k` axially) is already in the model (pendulum
//! stiffness from `gravity_stiffness`, or the spring), and the modes have
//!
//! - transverse (string): `ω_n = (nπ/ℓ) √(T/μ)`, i.e. `f_n = (n/2ℓ) √(T/μ)`;
//! - axial (surge): `ω_n = nπ √(k/(μℓ))`, i.e. `f_n = (n/2) √(k/m_cord)`.
//!
//! Eliminating the modal coordinates of one string gives the end stiffness
//! `(T/ℓ)[1 − β²/3 − 2β⁴ Σ_{n≤N} 1/(n²π²(n²π² − β²))]`, `β = ωℓ√(μ/T)`: the partial sum
//! of the Mittag-Leffler series of the exact taut-string end stiffness `(T/ℓ) β cot β`
//! (tail below `(T/ℓ) 2β⁴/(3π⁴N³)` well under the N-th mode). Both are checked in the tests.
//!
//! **Into the 6×6 model.** The augmented model (6 body coordinates plus the mass-
//! normalised cord coordinates) is solved for its real modes. All observations act on
//! the body, so the receptance is exactly the modal sum of the body parts `ψ_r` of all
//! augmented modes. The six modes with the largest body kinetic energy `ψ_rᵀ M ψ_r`
//! become the model's mass and stiffness, `M' = Ψ⁻ᵀΨ⁻¹`, `K' = Ψ⁻ᵀ Ω² Ψ⁻¹` (whose modes
//! are exactly those six), and the others become extra modes with shapes `S ψ_r` and
//! `f_eᵀ ψ_r`: rigid-shaped modes beyond six, as the note predicts. This is exact for
//! the modal damping of the spec on the six and `damping_ratio` on the cord modes.
//! The effect therefore runs after every other structure effect ([`Effect::order`] 2),
//! and a mass attached during one excitation only (`force_gauge_mass`) is added to `M'`
//! (first order in that mass). With all μ = 0 the model is left untouched (the
//! effect's neutral value).

use super::gravity::{cord_tensions, Cord};
use super::screening::{
    Build, Reciprocal, Screened, ScreeningForm, ScreeningKind, ScreeningResult,
};
use super::{BuildContext, Effect, ParamInfo};
use crate::model::{DynamicModel, ExtraMode};
use crate::spec::CampaignSpec;
use nalgebra::{DMatrix, Matrix6xX};
use rbprops_core::{rigid_transform, Geometry, MassMatrix6, Mat6, Vec3, Vec6};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

fn default_modes() -> usize {
    8
}
fn default_damping() -> f64 {
    0.01
}

/// Body kinetic energy `ψᵀMψ` (of a mode with unit total modal mass) below which a
/// cord mode is taken as body-free and left out (its FRF terms are below 1e-24/m).
pub const BODY_FREE_ENERGY: f64 = 1e-24;

/// Largest number of assumed modes per cord and direction.
pub const MAX_MODES_PER_DIRECTION: usize = 64;

/// Spec parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CordMass {
    /// Set-up whose springs are cords; all set-ups when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub setup: Option<String>,
    /// Mass per unit length μ (kg/m) per spring, or one value for all. 0: no effect.
    pub mass_per_length_kg_per_m: Vec<f64>,
    /// Cord length ℓ (m) per spring, or one value for all.
    pub cord_length_m: Vec<f64>,
    /// Assumed modes N per cord and direction (two transverse, one axial).
    #[serde(default = "default_modes")]
    pub modes_per_direction: usize,
    /// Damping ratio of the cord modes.
    #[serde(default = "default_damping")]
    pub damping_ratio: f64,
    /// Gravitational acceleration (m/s²).
    #[serde(default = "super::default_g")]
    pub g_m_per_s2: f64,
    /// Upward unit vector in the geometry frame.
    #[serde(default = "super::default_up")]
    pub up: [f64; 3],
}

/// One cord of the assumed-modes model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MassiveCord {
    /// Attachment point on the body (m).
    pub at: Vec3,
    /// Length ℓ (m).
    pub length: f64,
    /// Mass per length μ (kg/m).
    pub mass_per_length: f64,
    /// Static tension T (N).
    pub tension: f64,
    /// Axial stiffness k (N/m).
    pub axial_stiffness: f64,
}

impl MassiveCord {
    /// Transverse (string) mode `f_n = (n/2ℓ) √(T/μ)` of the cord pinned at both ends (Hz).
    pub fn string_frequency_hz(&self, n: usize) -> f64 {
        n as f64 / (2.0 * self.length) * (self.tension / self.mass_per_length).sqrt()
    }
    /// Axial (surge) mode `f_n = (n/2) √(k/(μℓ))` of the cord fixed at both ends (Hz).
    pub fn surge_frequency_hz(&self, n: usize) -> f64 {
        n as f64 / 2.0 * (self.axial_stiffness / (self.mass_per_length * self.length)).sqrt()
    }
    /// The cord's mass `μℓ` (kg).
    pub fn mass(&self) -> f64 {
        self.mass_per_length * self.length
    }
}

/// The body coordinates plus the mass-normalised cord coordinates: `mass` and
/// `stiffness` of size `6 + 3 N n_cords`, body first (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct AugmentedModel {
    /// Mass matrix of the body and cord coordinates.
    pub mass: DMatrix<f64>,
    /// Stiffness matrix of the body and cord coordinates (tension stiffness included).
    pub stiffness: DMatrix<f64>,
}

/// Horizontal basis ⟂ `up` and `up` itself: the directions of a cord's motion.
fn cord_directions(up: &Vec3) -> [Vec3; 3] {
    let h1 = if up.x.abs() < 0.9 {
        Vec3::x()
    } else {
        Vec3::y()
    };
    let h1 = (h1 - h1.dot(up) * up).normalize();
    [h1, up.cross(&h1), *up]
}

/// Assembles the augmented model of a body (`mass`, `stiffness` about O) on `cords`
/// with `n_modes` assumed modes per cord and direction. Coordinates of cord i, direction
/// d (two horizontal, then `up`), mode n sit at `6 + (3 i + d) N + n − 1`.
pub fn augmented_model(
    mass: &Mat6,
    stiffness: &Mat6,
    cords: &[MassiveCord],
    up: &Vec3,
    n_modes: usize,
) -> AugmentedModel {
    let n = 6 + 3 * n_modes * cords.len();
    let mut m = DMatrix::<f64>::zeros(n, n);
    let mut k = DMatrix::<f64>::zeros(n, n);
    m.view_mut((0, 0), (6, 6)).copy_from(mass);
    k.view_mut((0, 0), (6, 6)).copy_from(stiffness);
    let dirs = cord_directions(up);
    for (i, cd) in cords.iter().enumerate() {
        let (mu, l) = (cd.mass_per_length, cd.length);
        let tr = rigid_transform(&cd.at);
        let added = (mu * l / 3.0) * tr.transpose() * tr;
        let mut body = m.view_mut((0, 0), (6, 6));
        body += added;
        for (d, e) in dirs.iter().enumerate() {
            let col: Vec6 = tr.transpose() * e;
            for j in 1..=n_modes {
                let idx = 6 + (3 * i + d) * n_modes + j - 1;
                let nj = j as f64 * PI;
                let sign = if j % 2 == 1 { 1.0 } else { -1.0 };
                // μ∫(s/ℓ) sin(nπs/ℓ) ds over the modal mass' square root √(μℓ/2).
                let b = sign * (2.0 * mu * l).sqrt() / nj;
                for r in 0..6 {
                    m[(r, idx)] = b * col[r];
                    m[(idx, r)] = b * col[r];
                }
                m[(idx, idx)] = 1.0;
                k[(idx, idx)] = if d < 2 {
                    nj * nj * cd.tension / (mu * l * l)
                } else {
                    nj * nj * cd.axial_stiffness / (mu * l)
                };
            }
        }
    }
    AugmentedModel {
        mass: m,
        stiffness: k,
    }
}

/// The augmented model as a 6×6 model plus extra modes (see the module docs); cord
/// modes with body energy below [`BODY_FREE_ENERGY`] are left out.
#[derive(Debug, Clone, PartialEq)]
pub struct ReducedModel {
    /// `M' = Ψ⁻ᵀΨ⁻¹` of the six body-dominated modes.
    pub mass: Mat6,
    /// `K' = Ψ⁻ᵀΩ²Ψ⁻¹`.
    pub stiffness: Mat6,
    /// The other modes: circular frequency (rad/s) and body part `ψ` (mass-normalised
    /// over the augmented model).
    pub extra: Vec<(f64, Vec6)>,
}

/// The augmented model in standard form after the change of cord coordinates
/// `q_c' = q_c + Bᵀ q_b`, with `L` the Cholesky factor of the body block of the mass.
///
/// With the mass `[[A, B], [Bᵀ, I]]` (cord coordinates mass-normalised) and the
/// stiffness `[[K_b, 0], [0, D]]` (`D` diagonal) that [`augmented_model`] assembles, the
/// kinetic energy `q̇_bᵀAq̇_b + 2q̇_bᵀBq̇_c + q̇_cᵀq̇_c` becomes `q̇_bᵀ(A − BBᵀ)q̇_b + q̇_c'ᵀq̇_c'`
/// and the strain energy `q_bᵀK_bq_b + (q_c' − Bᵀq_b)ᵀD(q_c' − Bᵀq_b)`: mass
/// `[[A − BBᵀ, 0], [0, I]]` (`A − BBᵀ`, the Schur complement of the unit block, is
/// positive definite with the whole mass), stiffness `[[K_b + BDBᵀ, −BD], [−DBᵀ, D]]`.
/// With `A − BBᵀ = LLᵀ` the standard form is
/// `[[L⁻¹(K_b + BDBᵀ)L⁻ᵀ, −L⁻¹BD], [−DBᵀL⁻ᵀ, D]]`; the body coordinates are unchanged,
/// so a mode's body part is `L⁻ᵀ` times the first six entries of its eigenvector, and
/// only a 6×6 Cholesky factor is needed (not one of the whole mass).
fn standard_form(aug: &AugmentedModel) -> Result<(DMatrix<f64>, Mat6), String> {
    let n = aug.mass.nrows();
    if n < 6 || aug.mass.ncols() != n || aug.stiffness.shape() != (n, n) {
        return Err("the augmented model's matrices are not square of size ≥ 6".into());
    }
    let nc = n - 6;
    let (m, k) = (&aug.mass, &aug.stiffness);
    let assembled = (6..n).all(|i| {
        (0..n).all(|j| {
            m[(i, j)]
                == if i == j {
                    1.0
                } else if j < 6 {
                    m[(j, i)]
                } else {
                    0.0
                }
                && (i == j || k[(i, j)] == 0.0 && k[(j, i)] == 0.0)
        })
    });
    if !assembled {
        return Err("the augmented model is not in the form `augmented_model` assembles".into());
    }
    let a: Mat6 = m.fixed_view::<6, 6>(0, 0).into_owned();
    let b: Matrix6xX<f64> = m.fixed_rows::<6>(0).columns(6, nc).into_owned();
    let d = k.diagonal().rows(6, nc).into_owned();
    let kb: Mat6 = k.fixed_view::<6, 6>(0, 0).into_owned();
    let mut bd = b.clone();
    for (mut col, dj) in bd.column_iter_mut().zip(d.iter()) {
        col *= *dj;
    }
    let k11 = (kb + kb.transpose()) / 2.0 + &bd * b.transpose();
    let s = a - &b * b.transpose();
    let l = ((s + s.transpose()) / 2.0)
        .cholesky()
        .ok_or("the mass matrix with the cords is not positive definite")?
        .l();
    let x = l
        .solve_lower_triangular(&k11)
        .ok_or("singular Cholesky factor")?;
    let h11 = l
        .solve_lower_triangular(&x.transpose())
        .ok_or("singular Cholesky factor")?;
    let h12 = -l
        .solve_lower_triangular(&bd)
        .ok_or("singular Cholesky factor")?;
    let mut h = DMatrix::<f64>::zeros(n, n);
    for (i, di) in d.iter().enumerate() {
        h[(6 + i, 6 + i)] = *di;
    }
    h.fixed_view_mut::<6, 6>(0, 0)
        .copy_from(&((h11 + h11.transpose()) / 2.0));
    h.view_mut((0, 6), (6, nc)).copy_from(&h12);
    h.view_mut((6, 0), (nc, 6)).copy_from(&h12.transpose());
    Ok((h, l))
}

/// The eigenvalues of the symmetric `h` and `rows` (six rows of length n) times its
/// orthonormal eigenvectors: with `h` and `rows = [L⁻ᵀ, 0]` from [`standard_form`],
/// the body parts of the mass-normalised modes, without forming the modes.
///
/// Householder tridiagonalisation `h = Q T Qᵀ`, then the implicit symmetric QR
/// iteration with Wilkinson's shift on `T = W Λ Wᵀ` (Golub & Van Loan §8.3; the
/// iteration of nalgebra's `SymmetricEigen`), carrying only the six rows `rows Q` and
/// then `rows Q W`. A general solver accumulates all n rows of `QW`, most of its cost.
fn eigen_body_rows(
    mut h: DMatrix<f64>,
    rows: &Matrix6xX<f64>,
) -> Result<(Vec<f64>, Matrix6xX<f64>), String> {
    let n = h.nrows();
    let largest = h.amax();
    if !largest.is_finite() {
        return Err("the modes of the body on massive cords are not finite".into());
    }
    // A power of two near the largest entry, so the scaling is exact.
    let scale = if largest > 0.0 {
        2f64.powi(largest.log2().round() as i32)
    } else {
        1.0
    };
    h /= scale;
    let (mut d, mut e, mut z) = tridiagonalise(&mut h, rows);
    tridiagonal_qr(&mut d, &mut e[..n.saturating_sub(1)], &mut z)?;
    d.iter_mut().for_each(|x| *x *= scale);
    Ok((d, Matrix6xX::from_fn(n, |r, c| z[6 * c + r])))
}

/// Householder reduction of the symmetric `a` (overwritten) to tridiagonal form: the
/// diagonal, the subdiagonal (`e[i]` couples `i` and `i + 1`; `e[n − 1] = 0`) and
/// `rows` times `Q`, stored by column (`z[6 c + r] = (rows Q)[r, c]`).
fn tridiagonalise(a: &mut DMatrix<f64>, rows: &Matrix6xX<f64>) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let n = a.nrows();
    let mut e = vec![0.0; n];
    let mut z: Vec<f64> = rows.as_slice().to_vec();
    let a = a.as_mut_slice();
    let (mut v, mut p) = (vec![0.0; n], vec![0.0; n]);
    for k in 0..n.saturating_sub(2) {
        // The reflector I − τvvᵀ (v₀ = 1) taking a[k+1.., k] to βe₁.
        let lo = k + 1;
        let x = &a[k * n + lo..(k + 1) * n];
        let alpha = x[0];
        let sigma: f64 = x[1..].iter().map(|t| t * t).sum();
        if sigma == 0.0 {
            e[k] = alpha;
            continue;
        }
        let beta = -alpha.signum() * (alpha * alpha + sigma).sqrt();
        let tau = (beta - alpha) / beta;
        let scale = 1.0 / (alpha - beta);
        let v = &mut v[lo..];
        v[0] = 1.0;
        for (vi, xi) in v[1..].iter_mut().zip(&x[1..]) {
            *vi = xi * scale;
        }
        e[k] = beta;
        // Trailing block A ← HAH = A − vwᵀ − wvᵀ, p = τAv, w = p − (τ/2)(pᵀv)v.
        let p = &mut p[lo..];
        p.fill(0.0);
        for (j, &vj) in v.iter().enumerate() {
            let col = &a[(lo + j) * n + lo..(lo + j + 1) * n];
            for (pi, aij) in p.iter_mut().zip(col) {
                *pi += aij * vj;
            }
        }
        let pv: f64 = p.iter().zip(v.iter()).map(|(pi, vi)| pi * vi).sum::<f64>() * tau;
        for (pi, vi) in p.iter_mut().zip(v.iter()) {
            *pi = tau * *pi - 0.5 * tau * pv * vi;
        }
        for (j, (&vj, &wj)) in v.iter().zip(p.iter()).enumerate() {
            let col = &mut a[(lo + j) * n + lo..(lo + j + 1) * n];
            for ((aij, vi), wi) in col.iter_mut().zip(v.iter()).zip(p.iter()) {
                *aij -= vi * wj + wi * vj;
            }
        }
        // The six rows: rows Q ← rows Q H.
        let zk = &mut z[6 * lo..];
        let mut s = [0.0; 6];
        for (col, vj) in zk.chunks_exact(6).zip(v.iter()) {
            for (sr, zr) in s.iter_mut().zip(col) {
                *sr += zr * vj;
            }
        }
        for (col, vj) in zk.chunks_exact_mut(6).zip(v.iter()) {
            for (zr, sr) in col.iter_mut().zip(&s) {
                *zr -= tau * sr * vj;
            }
        }
    }
    if n >= 2 {
        e[n - 2] = a[(n - 2) * n + n - 1];
    }
    let d = (0..n).map(|i| a[i * n + i]).collect();
    (d, e, z)
}

/// The unreduced block `(start, end)` at the bottom of the tridiagonal `(d, e)` up to
/// `end`, its negligible couplings set to zero (`(0, 0)`: all decoupled).
fn delimit_subproblem(d: &[f64], e: &mut [f64], end: usize) -> (usize, usize) {
    let negligible = |e: f64, a: f64, b: f64| e.abs() <= f64::EPSILON * (a.abs() + b.abs());
    let mut n = end;
    while n > 0 && negligible(e[n - 1], d[n], d[n - 1]) {
        n -= 1;
    }
    if n == 0 {
        return (0, 0);
    }
    let mut start = n - 1;
    while start > 0 {
        let m = start - 1;
        if e[m] == 0.0 || negligible(e[m], d[start], d[m]) {
            e[m] = 0.0;
            break;
        }
        start -= 1;
    }
    (start, n)
}

/// Most QR sweeps of [`tridiagonal_qr`] per eigenvalue (two or three are usual).
const QR_MAX_SWEEPS: usize = 30;

/// The implicit symmetric QR iteration with Wilkinson's shift on the tridiagonal
/// `(d, e)` (`e[i]` couples `i` and `i + 1`): `d` becomes the eigenvalues and each
/// rotation is applied to the six rows `z` (by column, `z[6 c + r]`).
fn tridiagonal_qr(d: &mut [f64], e: &mut [f64], z: &mut [f64]) -> Result<(), String> {
    let n = d.len();
    if n < 2 {
        return Ok(());
    }
    let rotate = |z: &mut [f64], i: usize, c: f64, s: f64| {
        for k in 0..6 {
            let (a, b) = (z[6 * i + k], z[6 * (i + 1) + k]);
            z[6 * i + k] = c * a + s * b;
            z[6 * (i + 1) + k] = c * b - s * a;
        }
    };
    let (mut start, mut end) = delimit_subproblem(d, e, n - 1);
    let mut sweeps = 0;
    while end != start {
        sweeps += 1;
        if sweeps > QR_MAX_SWEEPS * n {
            return Err("the modes of the body on massive cords did not converge".into());
        }
        if end - start + 1 > 2 {
            let m = end - 1;
            let shift = wilkinson_shift(d[m], d[end], e[m]);
            let (mut x, mut y) = (d[start] - shift, e[start]);
            for i in start..end {
                if y == 0.0 {
                    break;
                }
                // The rotation taking (x, y) to (r, 0).
                let sign = if x >= 0.0 { 1.0 } else { -1.0 };
                let norm = (x * x + y * y).sqrt();
                let (c, s) = (x.abs() / norm, -y / (sign * norm));
                if i > start {
                    e[i - 1] = sign * norm;
                }
                let (dii, djj, eij) = (d[i], d[i + 1], e[i]);
                let (cc, ss, cs) = (c * c, s * s, c * s);
                let b = cs * 2.0 * eij;
                d[i] = (cc * dii + ss * djj) - b;
                d[i + 1] = (ss * dii + cc * djj) + b;
                e[i] = cs * (dii - djj) + eij * (cc - ss);
                if i != end - 1 {
                    x = e[i];
                    y = -s * e[i + 1];
                    e[i + 1] *= c;
                }
                rotate(z, i, c, -s);
            }
            if e[m].abs() <= f64::EPSILON * (d[m].abs() + d[end].abs()) {
                end -= 1;
            }
        } else {
            // A 2×2 block: its eigenvalues and the rotation onto its eigenvectors.
            let (a, b, c) = (d[start], e[start], d[start + 1]);
            let half = (a - c) * 0.5;
            let root = (b * b + half * half).sqrt();
            let (l0, l1) = ((a + c) * 0.5 + root, (a + c) * 0.5 - root);
            let (bx, by) = if (l0 - c).abs() > (l0 - a).abs() {
                (l0 - c, b)
            } else {
                (b, l0 - a)
            };
            d[start] = l0;
            d[start + 1] = l1;
            let norm = (bx * bx + by * by).sqrt();
            if norm > f64::EPSILON {
                let sign = if bx >= 0.0 { 1.0 } else { -1.0 };
                rotate(z, start, bx.abs() / norm, by / (sign * norm));
            }
            end -= 1;
        }
        (start, end) = delimit_subproblem(d, e, end);
    }
    Ok(())
}

/// The eigenvalue of `[[tmm, tmn], [tmn, tnn]]` nearer `tnn`.
fn wilkinson_shift(tmm: f64, tnn: f64, tmn: f64) -> f64 {
    let sq = tmn * tmn;
    if sq == 0.0 {
        return tnn;
    }
    let d = (tmm - tnn) * 0.5;
    tnn - sq / (d + d.signum() * (d * d + sq).sqrt())
}

/// Solves the augmented model's real modes and reduces it; `body_mass` (the body
/// without cords) measures each mode's body kinetic energy. `aug` must have the form
/// [`augmented_model`] assembles (unit cord mass block, diagonal cord stiffness, no
/// stiffness coupling): an error otherwise.
pub fn reduce(aug: &AugmentedModel, body_mass: &Mat6) -> Result<ReducedModel, String> {
    let n = aug.mass.nrows();
    let (h, l) = standard_form(aug)?;
    // Body parts `L⁻ᵀ y_b`: the rows `[L⁻ᵀ, 0]` times the eigenvectors.
    let l_inv_t = l
        .transpose()
        .try_inverse()
        .ok_or("singular Cholesky factor")?;
    let mut rows = Matrix6xX::<f64>::zeros(n);
    rows.fixed_columns_mut::<6>(0).copy_from(&l_inv_t);
    let (eigenvalues, phi) = eigen_body_rows(h, &rows)?;
    if !phi.iter().all(|x| x.is_finite()) || !eigenvalues.iter().all(|x| x.is_finite()) {
        return Err("the modes of the body on massive cords are not finite".into());
    }
    let body = |r: usize| -> Vec6 { Vec6::from_fn(|i, _| phi[(i, r)]) };
    let energy: Vec<f64> = (0..n)
        .map(|r| {
            let p = body(r);
            (p.transpose() * body_mass * p)[0]
        })
        .collect();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| energy[j].total_cmp(&energy[i]).then(i.cmp(&j)));
    let mut six: Vec<usize> = order[..6].to_vec();
    six.sort_by(|&i, &j| eigenvalues[i].total_cmp(&eigenvalues[j]).then(i.cmp(&j)));
    let psi = Mat6::from_columns(&six.iter().map(|&r| body(r)).collect::<Vec<_>>());
    let sv = psi.singular_values();
    let cond = sv.max() / sv.min();
    if !(cond < 1e10) {
        return Err(format!(
            "the six body-dominated modes do not span the rigid-body motions (condition {cond:.2e})"
        ));
    }
    let pinv = psi
        .try_inverse()
        .ok_or("the six body-dominated modes are singular")?;
    let omega2 = Mat6::from_diagonal(&Vec6::from_fn(|i, _| eigenvalues[six[i]]));
    let mass = pinv.transpose() * pinv;
    let stiffness = pinv.transpose() * omega2 * pinv;
    let mut extra = Vec::with_capacity(n - 6);
    let mut rest: Vec<usize> = order[6..].to_vec();
    rest.sort_by(|&i, &j| eigenvalues[i].total_cmp(&eigenvalues[j]).then(i.cmp(&j)));
    for r in rest {
        let w2 = eigenvalues[r];
        if !(w2 > 0.0) {
            return Err(format!(
                "a cord mode has a non-positive eigenvalue ω² = {w2:.3e}"
            ));
        }
        // Modes in which the body does not move (cords swinging against each other in
        // a symmetric suspension) are invisible in every FRF: drop them rather than
        // divide roundoff by zero at their frequency.
        if energy[r] > BODY_FREE_ENERGY {
            extra.push((w2.sqrt(), body(r)));
        }
    }
    Ok(ReducedModel {
        mass: (mass + mass.transpose()) / 2.0,
        stiffness: (stiffness + stiffness.transpose()) / 2.0,
        extra,
    })
}

impl CordMass {
    fn up(&self) -> Vec3 {
        Vec3::from(self.up)
    }
    fn per_spring(v: &[f64], n: usize) -> Vec<f64> {
        if v.len() == 1 {
            vec![v[0]; n]
        } else {
            v.to_vec()
        }
    }
    /// Checks the parameters on their own (signs, finiteness, counts given).
    pub fn check_self(&self) -> Result<(), String> {
        if self.mass_per_length_kg_per_m.is_empty() {
            return Err(
                "mass_per_length_kg_per_m: give one value per spring or one for all".into(),
            );
        }
        if self.cord_length_m.is_empty() {
            return Err("cord_length_m: give one length per spring or one for all".into());
        }
        if let Some((i, mu)) = self
            .mass_per_length_kg_per_m
            .iter()
            .enumerate()
            .find(|(_, m)| !(m.is_finite() && **m >= 0.0))
        {
            return Err(format!(
                "mass_per_length_kg_per_m[{i}]: must be finite and ≥ 0, got {mu}"
            ));
        }
        if let Some((i, l)) = self
            .cord_length_m
            .iter()
            .enumerate()
            .find(|(_, l)| !(l.is_finite() && **l > 0.0))
        {
            return Err(format!(
                "cord_length_m[{i}]: must be positive and finite, got {l}"
            ));
        }
        if !(1..=MAX_MODES_PER_DIRECTION).contains(&self.modes_per_direction) {
            return Err(format!(
                "modes_per_direction must be in 1..={MAX_MODES_PER_DIRECTION}, got {}",
                self.modes_per_direction
            ));
        }
        if !(self.damping_ratio.is_finite() && (0.0..1.0).contains(&self.damping_ratio)) {
            return Err(format!(
                "damping_ratio must be in [0, 1), got {}",
                self.damping_ratio
            ));
        }
        super::gravity::check_weight(
            self.g_m_per_s2,
            self.up,
            " (the cords' tension comes from the weight)",
        )
    }

    fn applies_to(&self, setup: &str) -> bool {
        self.setup.as_ref().is_none_or(|id| id == setup)
    }

    /// The cords of set-up `setup_index` for a body of mass `m` with CoM `c` (tensions
    /// from the static equilibrium), cords with μ = 0 included.
    pub fn cords(
        &self,
        spec: &CampaignSpec,
        setup_index: usize,
        m: f64,
        c: &Vec3,
    ) -> Result<Vec<MassiveCord>, String> {
        let springs = spec.springs(setup_index);
        let n = springs.len();
        let up = self.up();
        let mus = Self::per_spring(&self.mass_per_length_kg_per_m, n);
        let lengths = Self::per_spring(&self.cord_length_m, n);
        let id = &spec.setups[setup_index].id;
        for (what, v) in [
            ("mass_per_length_kg_per_m", &mus),
            ("cord_length_m", &lengths),
        ] {
            if v.len() != n {
                return Err(format!(
                    "{what} has {} values but set-up '{id}' (setup[{setup_index}]) has {n} springs",
                    v.len()
                ));
            }
        }
        let geo: Vec<Cord> = springs
            .iter()
            .zip(&lengths)
            .map(|(s, &l)| Cord {
                at: s.at,
                length: l,
                axial_stiffness: (up.transpose() * s.stiffness * up)[0],
            })
            .collect();
        if let Some(i) = geo.iter().position(|c| !(c.axial_stiffness > 0.0)) {
            return Err(format!(
                "set-up '{id}': spring {i} has no stiffness along `up`, so it cannot be a cord"
            ));
        }
        let t = cord_tensions(&geo, m, c, self.g_m_per_s2, &up)
            .map_err(|e| format!("set-up '{id}': {e}"))?;
        Ok(geo
            .iter()
            .zip(&t)
            .zip(&mus)
            .map(|((g, &tension), &mu)| MassiveCord {
                at: g.at,
                length: g.length,
                mass_per_length: mu,
                tension,
                axial_stiffness: g.axial_stiffness,
            })
            .collect())
    }
}

impl CordMass {
    /// The catalogue id (the spec's `id = "cord_mass"`).
    pub const ID: &'static str = "cord_mass";
}

impl Effect for CordMass {
    fn id(&self) -> &'static str {
        Self::ID
    }
    /// After every other structure effect: the reduction must see the final M and K.
    fn order(&self) -> u8 {
        2
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        super::list_info(
            "mass_per_length_kg_per_m",
            "kg/m",
            self.mass_per_length_kg_per_m.len(),
            (0.01, 0.15),
        )
    }
    fn values(&self) -> Vec<f64> {
        self.mass_per_length_kg_per_m.clone()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let e = CordMass {
            mass_per_length_kg_per_m: super::replace_list(
                self.mass_per_length_kg_per_m.len(),
                values,
            )?,
            ..self.clone()
        };
        e.check_self()?;
        Ok(Box::new(e))
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_self()?;
        super::check_setup(spec, self.setup.as_deref())?;
        let props = spec.properties();
        for (i, s) in spec.setups.iter().enumerate() {
            if self.applies_to(&s.id) {
                self.cords(spec, i, props.mass, &props.com)?;
            }
        }
        Ok(())
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        if !self.applies_to(&model.setup) || self.mass_per_length_kg_per_m.iter().all(|&m| m == 0.0)
        {
            return Ok(());
        }
        let mm = MassMatrix6(model.mass);
        let cords: Vec<MassiveCord> = self
            .cords(ctx.spec, ctx.setup_index, mm.mass(), &mm.com())?
            .into_iter()
            .filter(|c| c.mass_per_length > 0.0)
            .collect();
        if cords.is_empty() {
            return Ok(());
        }
        let ks = model.stiffness;
        let asym = (ks - ks.transpose()).norm();
        if asym > 1e-9 * ks.norm().max(f64::MIN_POSITIVE) {
            return Err(format!(
                "set-up '{}': the stiffness is not symmetric (asymmetry {asym:.3e}), so it has no real modes to couple the cords to",
                model.setup
            ));
        }
        let aug = augmented_model(
            &model.mass,
            &ks,
            &cords,
            &self.up(),
            self.modes_per_direction,
        );
        let red =
            reduce(&aug, &model.mass).map_err(|e| format!("set-up '{}': {e}", model.setup))?;
        model.mass = red.mass;
        model.stiffness = red.stiffness;
        let n_ex = ctx.geometry.excitations.len();
        for (w, psi) in red.extra {
            let mut at_excitations = vec![0.0; n_ex];
            for inp in &model.inputs {
                at_excitations[inp.excitation] = inp.column.dot(&psi);
            }
            model.extra_modes.push(ExtraMode {
                frequency_hz: w / std::f64::consts::TAU,
                damping_ratio: self.damping_ratio,
                at_channels: model.outputs.iter().map(|r| (r * psi)[0]).collect(),
                at_excitations,
            });
        }
        Ok(())
    }
}

/// The `cord_mass` entry with one mass per length μ (kg/m) and one length ℓ (m) for
/// every cord hanging along `up` (the spec's; the catalogue's defaults for the cord
/// modes: 8 per direction, 1 % damping).
fn cord_entry(mu: f64, l: f64, up: Option<[f64; 3]>) -> crate::spec::EffectSpec {
    let mut t = toml::Table::new();
    if let Some(up) = up {
        t.insert("up".into(), crate::spec::up_value(up));
    }
    t.insert(
        "mass_per_length_kg_per_m".into(),
        toml::Value::Array(vec![mu.into()]),
    );
    t.insert("cord_length_m".into(), toml::Value::Array(vec![l.into()]));
    crate::spec::EffectSpec {
        id: CordMass::ID.into(),
        parameters: t,
    }
}

/// `cord_mass` through [`cord_entry`]; μ = 0 is "absent" whatever ℓ.
fn cord_build(v: &[f64], up: Option<[f64; 3]>) -> Result<Option<Box<dyn Effect>>, String> {
    if !(v[0] >= 0.0 && v[0].is_finite() && v[1] > 0.0 && v[1].is_finite()) {
        return Err(format!(
            "cord μ = {} kg/m, ℓ = {} m: need μ ≥ 0, ℓ > 0",
            v[0], v[1]
        ));
    }
    if v[0] == 0.0 {
        return Ok(None);
    }
    super::parse_effect(&cord_entry(v[0], v[1], up)).map(Some)
}

/// Cord masses `m = μℓ` (kg) of the `cord_mass` profile, a factor 2.5 apart.
const CORD_MASSES_KG: [f64; 4] = [0.015, 0.04, 0.1, 0.25];

/// Ratio of neighbouring first string frequencies on the `cord_mass` profile: the
/// half-power width `2ζ` of a cord mode at the catalogue's ζ = 1 %, so that any string
/// mode is within half a width of a profile frequency.
const CORD_FREQUENCY_RATIO: f64 = 1.02;

/// Cord lengths ℓ (m) and masses per length μ (kg/m) the profile spans.
const CORD_LENGTHS_M: (f64, f64) = (0.2, 5.0);

const CORD_MASSES_PER_LENGTH: (f64, f64) = (0.005, 0.3);

/// Mean static tension T̄ (N) of the cords of every set-up with springs, for the spec's
/// body (the statics of rbprops-sim's `cord_mass`); `None` when it has no positive one.
fn mean_cord_tension(spec: &CampaignSpec) -> Option<f64> {
    let cm: CordMass = toml::Value::Table(cord_entry(1.0, 1.0, spec.up).parameters)
        .try_into()
        .ok()?;
    let props = spec.properties();
    let mut tensions = Vec::new();
    for (si, s) in spec.setups.iter().enumerate() {
        if !s.springs.is_empty() {
            let cords = cm.cords(spec, si, props.mass, &props.com).ok()?;
            tensions.extend(cords.iter().map(|c| c.tension));
        }
    }
    let t = tensions.iter().sum::<f64>() / tensions.len() as f64;
    (t > 0.0 && t.is_finite()).then_some(t)
}

/// The `cord_mass` profile over (μ, ℓ), laid out as cord mass `m = μℓ` × first string
/// frequency `f = (1/2ℓ)√(T̄/μ) = ½√(T̄/(mℓ))` at the mean tension T̄, i.e.
/// `ℓ = T̄/(4f²m)`, `μ = m/ℓ`: the string modes are narrow peaks, so the frequencies step
/// by [`CORD_FREQUENCY_RATIO`] from the band's start (or the longest cord) to 1.2× its
/// stop, while the cord mass, which only scales them, steps coarsely. Points outside
/// [`CORD_LENGTHS_M`] × [`CORD_MASSES_PER_LENGTH`] are left out.
fn cord_grid(tension: f64, start_hz: f64, stop_hz: f64) -> Vec<Vec<f64>> {
    let mut grid = Vec::new();
    for m in CORD_MASSES_KG {
        let length = |f: f64| tension / (4.0 * f * f * m);
        let f0 = start_hz.max(0.5 * (tension / (m * CORD_LENGTHS_M.1)).sqrt());
        let points = (0..)
            .map(|k| f0 * CORD_FREQUENCY_RATIO.powi(k))
            .take_while(|&f| f <= 1.2 * stop_hz && length(f) >= CORD_LENGTHS_M.0);
        for f in points {
            let (mu, l) = (m / length(f), length(f));
            if (CORD_MASSES_PER_LENGTH.0..=CORD_MASSES_PER_LENGTH.1).contains(&mu) {
                grid.push(vec![mu, l]);
            }
        }
    }
    grid
}

/// `cord_mass`'s screening form: one mass per length μ and one length ℓ for all cords
/// ([`Reciprocal`] through μ, 0 meaning absent). At first order in μ a massive cord is a
/// point mass μℓ/3 at its attachment (absorbed by the free inertia); its visible part,
/// the string modes `f_n = (n/2ℓ)√(T/μ)`, is non-analytic at μ = 0, so it is screened by
/// a profile over (μ, ℓ) ([`cord_grid`]). Only when the spec has springs whose tension
/// puts a plausible cord's string mode in (or just above) the band, with a note when it
/// has springs but no such cord.
fn screen_cord_mass(spec: &CampaignSpec, _g: &Geometry) -> ScreeningResult {
    let has_springs = spec.setups.iter().any(|s| !s.springs.is_empty());
    if !has_springs {
        return Ok(None);
    }
    let grid = mean_cord_tension(spec)
        .map(|t| cord_grid(t, spec.frequency.start_hz, spec.frequency.stop_hz))
        .unwrap_or_default();
    if grid.is_empty() {
        return Err("cord_mass is not screened: the springs hold no cord tension, or no cord of plausible length and mass has a string mode below 1.2× the band's top".into());
    }
    let infos = vec![
        ParamInfo {
            name: "mass_per_length_kg_per_m".into(),
            unit: "kg/m",
            lower: 0.0,
            upper: 10.0,
            plausible: (0.01, 0.15),
        },
        ParamInfo {
            name: "cord_length_m".into(),
            unit: "m",
            lower: 0.05,
            upper: 50.0,
            plausible: (0.2, 5.0),
        },
    ];
    let build: Build = {
        let up = spec.up;
        std::sync::Arc::new(move |v: &[f64]| cord_build(v, up))
    };
    Ok(Some(ScreeningForm {
        effect: Box::new(Reciprocal::new(CordMass::ID, infos, vec![0.0, 1.0], build)),
        neutral: vec![0.0, 1.0],
        // The parameters' own magnitudes, so the finite-difference step is 1e-7 of
        // μ and ℓ: the string modes make some FRF values (antiresonances, cross
        // terms near 0 Hz) 1e-9 of the largest, where the model's roundoff is ~1e-7
        // of the value, and a smaller step turns that into Jacobian noise.
        scales: vec![0.1, 1.0],
        source: "rbprops-sim (screened by a parameter profile)",
        screening: ScreeningKind::Profile {
            grid,
            delay_scan: false,
        },
    }))
}

/// [`super::EffectDescriptor::parse`] of `cord_mass`: the table, checked.
fn parse_cord_mass(spec: &crate::spec::EffectSpec) -> Result<Box<dyn Effect>, String> {
    let c: CordMass = super::params(spec)?;
    c.check_self()
        .map_err(|e| format!("effect 'cord_mass': {e}"))?;
    Ok(Box::new(c))
}

/// This module's effects in the physics catalogue ([`super::registry`]).
pub(crate) const DESCRIPTORS: &[super::EffectDescriptor] = &[
    super::EffectDescriptor {
        id: CordMass::ID,
        rank: 17,
        title: "mass and string / surge modes of the suspension cords",
        reveal: "the cords' mass and length, or a suspension with lighter or shorter cords",
        docs: "E3: the suspension cords' mass and their string and surge modes, `mass_per_length_kg_per_m`, `cord_length_m`",
        parse: parse_cord_mass,
        neutral: super::NeutralForm::Screened(Screened {
            rank: 4,
            form: screen_cord_mass,
        }),
        follows_spec_up: true,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/cord_mass.toml"),
        plausible: None,
    },
];
