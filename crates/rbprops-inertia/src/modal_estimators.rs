//! The two modal estimators of the paper: Bretl–Conti (Eq. 2) and Toivola–Nuutila
//! (orthogonality least squares, Eq. 10), and the mount stiffness of Conti & Bretl (1989).

use crate::error::InertiaError;
use crate::lsq::{solve_parameters, LinearConstraint, PropertiesEstimate};
use crate::params::{basis_matrices, orthogonality_row, N_PARAMS, PARAM_NAMES};
use rbprops_core::{MassMatrix6, Mat6, Vec3, Vec6};

/// Above this condition number Φ0 counts as singular for Bretl–Conti.
pub const MAX_MODAL_CONDITION: f64 = 1e8;

/// Result of Bretl–Conti.
#[derive(Debug, Clone, PartialEq)]
pub struct BcSolution {
    /// `M0 = Φ0⁻ᵀΦ0⁻¹` about the shapes' origin (not symmetrised into rigid-body form).
    pub mass_matrix: MassMatrix6,
    /// Condition number of Φ0.
    pub condition: f64,
    /// Distance of `M0` from the rigid-body pattern (`MassMatrix6::structure_residual`):
    /// zero for exact rigid-body modes; the estimator's residual.
    pub residual: f64,
}

fn modal_matrix(phi0: &[Vec6]) -> Mat6 {
    Mat6::from_columns(phi0)
}

/// Inverse of Φ0 with a conditioning check.
fn modal_inverse(phi0: &[Vec6]) -> Result<(Mat6, f64), InertiaError> {
    let phi = modal_matrix(phi0);
    let sv = phi.singular_values();
    let (lo, hi) = (sv.min(), sv.max());
    let condition = if lo > 0.0 { hi / lo } else { f64::INFINITY };
    if !(condition < MAX_MODAL_CONDITION) {
        return Err(InertiaError::SingularModalMatrix { condition });
    }
    let inv = phi
        .try_inverse()
        .ok_or(InertiaError::SingularModalMatrix { condition })?;
    Ok((inv, condition))
}

/// Bretl & Conti: `M0 = Φ0⁻ᵀ Φ0⁻¹` (paper Eq. 2). Needs exactly six mass-normalised modes.
pub fn bretl_conti(phi0: &[Vec6]) -> Result<BcSolution, InertiaError> {
    if phi0.len() != 6 {
        return Err(InertiaError::TooFewModes {
            method: "bretl_conti",
            needed: "exactly the six rigid-body modes (Eq. 2 inverts the 6×6 modal matrix)".into(),
            got: phi0.len(),
        });
    }
    let (inv, condition) = modal_inverse(phi0)?;
    let m = inv.transpose() * inv;
    let mass_matrix = MassMatrix6((m + m.transpose()) / 2.0);
    Ok(BcSolution {
        residual: mass_matrix.structure_residual(),
        mass_matrix,
        condition,
    })
}

/// Mount (suspension) stiffness about the shapes' origin, `K0 = Φ0⁻ᵀ Ω² Φ0⁻¹`
/// (Conti & Bretl 1989); needs six modes. `omegas` in rad/s.
pub fn mount_stiffness(phi0: &[Vec6], omegas: &[f64]) -> Result<Mat6, InertiaError> {
    if phi0.len() != 6 || omegas.len() != 6 {
        return Err(InertiaError::TooFewModes {
            method: "mount_stiffness",
            needed: "six modes".into(),
            got: phi0.len(),
        });
    }
    let (inv, _) = modal_inverse(phi0)?;
    let w2 = Mat6::from_diagonal(&Vec6::from_iterator(omegas.iter().map(|w| w * w)));
    let k = inv.transpose() * w2 * inv;
    Ok((k + k.transpose()) / 2.0)
}

/// Result of Toivola–Nuutila: the rank and residual are those of the `n(n+1)/2 × 10`
/// orthogonality system.
pub type TnSolution = PropertiesEstimate;

/// Toivola & Nuutila: every pair `i ≤ j` of the `n ≥ 4` modes gives
/// `φ0_iᵀ M0(p) φ0_j = δ_ij` (paper Eq. 10), linear in the ten parameters; the
/// `n(n+1)/2 × 10` system is solved in least squares with rank detection. With a rank
/// deficiency the minimum-norm solution is returned unless `nominal` completes it (only its
/// null-space components are used). `constraints` are exact side information.
pub fn toivola_nuutila(
    phi0: &[Vec6],
    constraints: &[LinearConstraint],
    nominal: Option<&[f64; N_PARAMS]>,
) -> Result<TnSolution, InertiaError> {
    if phi0.len() < 4 {
        return Err(InertiaError::TooFewModes {
            method: "toivola_nuutila",
            needed: "at least four modes (n modes give n(n+1)/2 equations for ten unknowns)".into(),
            got: phi0.len(),
        });
    }
    let e = basis_matrices();
    let mut rows = Vec::new();
    let mut rhs = Vec::new();
    for i in 0..phi0.len() {
        for j in i..phi0.len() {
            rows.push(orthogonality_row(&e, &phi0[i], &phi0[j]));
            rhs.push((i == j) as u8 as f64);
        }
    }
    Ok(PropertiesEstimate::from_solution(solve_parameters(
        &rows,
        &rhs,
        constraints,
        nominal,
    )?))
}

/// The pure translation contained in the span of the modes, if any: a combination
/// `Φ0 a` whose rotation part vanishes. Any four vectors of the 6-D rigid-motion space
/// meet the 3-D translation subspace (4 + 3 > 6), so four modes always contain one.
/// Returns the unit translation direction, or `None` when the rotational parts of the
/// modes are independent (then no translation is in the span).
pub fn translation_in_span(phi0: &[Vec6]) -> Option<Vec3> {
    let n = phi0.len();
    if n == 0 {
        return None;
    }
    // Rotational parts B (3 × n); a ∈ null(B) gives a pure translation Φ0 a.
    let b = nalgebra::DMatrix::from_fn(3, n, |r, c| phi0[c][3 + r]);
    let svd = (b.transpose() * &b).symmetric_eigen();
    let scale = svd.eigenvalues.amax().max(f64::MIN_POSITIVE);
    let (imin, &lmin) = svd
        .eigenvalues
        .iter()
        .enumerate()
        .min_by(|x, y| x.1.total_cmp(y.1))?;
    if lmin > 1e-12 * scale {
        return None;
    }
    let a = svd.eigenvectors.column(imin);
    let mut t = Vec6::zeros();
    for (k, p) in phi0.iter().enumerate() {
        t += p * a[k];
    }
    let u = Vec3::new(t[0], t[1], t[2]);
    let n = u.norm();
    (n > 0.0).then(|| u / n)
}

/// Describes unidentifiable parameter combinations in words.
pub fn describe_null_space(sol: &TnSolution, phi0: &[Vec6]) -> String {
    let mut parts = Vec::new();
    for v in &sol.null_space_scaled {
        let mut idx: Vec<usize> = (0..N_PARAMS).filter(|&k| v[k].abs() >= 0.05).collect();
        idx.sort_by(|&a, &b| v[b].abs().total_cmp(&v[a].abs()));
        let sign = if v[idx[0]] < 0.0 { -1.0 } else { 1.0 };
        let terms: Vec<String> = idx
            .iter()
            .map(|&k| format!("{:+.3}·{}", sign * v[k], PARAM_NAMES[k]))
            .collect();
        parts.push(format!(
            "the combination [{}] (column-equilibrated units) can change without changing any orthogonality equation",
            terms.join(" ")
        ));
    }
    let mut text = parts.join("; ");
    if let Some(u) = translation_in_span(phi0) {
        let mass_free = sol.null_space_scaled.iter().any(|v| v[0].abs() > 1e-6);
        text.push_str(&format!(
            ". The {} modes span a pure translation along u = ({:.3}, {:.3}, {:.3}); \
             the first moment of mass m·c along u and the inertia terms coupled to it are not \
             determined by the orthogonality equations{}. Give side information: the centre of \
             mass (known_com) or nominal values (nominal), or select more modes",
            phi0.len(),
            u.x,
            u.y,
            u.z,
            if mass_free {
                ""
            } else {
                "; the mass is determined, so a known mass does not help"
            }
        ));
    }
    text
}
