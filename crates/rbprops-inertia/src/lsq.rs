//! Rank-revealing linear least squares in the ten inertia parameters (faer SVD).
//!
//! The columns of the design matrix have different units (kg, kg m, kg m²), so they are
//! equilibrated first (`p = D y`, `D = diag(1/‖a_k‖)`); the rank, the condition number and
//! the null space are judged in the scaled, dimensionless variables `y`.
//! Exact linear constraints `C p = d` (side information) are eliminated by the null-space
//! method before the fit; a nominal parameter vector, when given, fixes only the components
//! of the solution in the data's null space (the limit of a vanishing Tikhonov weight), so the
//! combinations the data determine are untouched.

use crate::error::InertiaError;
use crate::params::{mass_matrix_of, N_PARAMS};
use faer::Mat;
use rbprops_core::MassMatrix6;

/// Singular values below this fraction of the largest count as zero.
pub const RANK_TOLERANCE: f64 = 1e-9;

/// An exact linear constraint `rowᵀ p = value` on the parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearConstraint {
    /// Coefficients on the ten properties `p` of docs/conventions.md §3 (about O).
    pub row: [f64; N_PARAMS],
    /// The value the combination must take.
    pub value: f64,
    /// What the constraint says, for labels and errors.
    pub label: String,
}

/// Solution of a parameter least-squares problem.
#[derive(Debug, Clone, PartialEq)]
pub struct LsqSolution {
    /// Minimum-norm (in scaled variables) least-squares solution, or the nominal-completed
    /// one when a nominal vector was given and the system is rank deficient.
    pub p: [f64; N_PARAMS],
    /// Rank of the (constrained, scaled) design matrix plus the number of constraints.
    pub rank: usize,
    /// Singular values of the scaled (constrained) design matrix, descending.
    pub singular_values: Vec<f64>,
    /// `σ_max / σ_min` over the retained singular values.
    pub condition: f64,
    /// Null-space directions in parameter units (each of unit norm in scaled variables).
    pub null_space: Vec<[f64; N_PARAMS]>,
    /// The same directions in scaled (dimensionless) variables, unit norm.
    pub null_space_scaled: Vec<[f64; N_PARAMS]>,
    /// `‖A p − b‖ / ‖b‖`.
    pub residual: f64,
}

/// The ten properties a least-squares estimator found (Toivola–Nuutila, the mass line):
/// the solution, its mass matrix and how well the data determine it.
#[derive(Debug, Clone, PartialEq)]
pub struct PropertiesEstimate {
    /// `M0(p)` about O of the fitted properties (rigid-body form by construction).
    pub mass_matrix: MassMatrix6,
    /// The ten properties about O, docs/conventions.md §3.
    pub params: [f64; N_PARAMS],
    /// Rank of the estimator's system with the constraints counted (10 when every
    /// property is determined).
    pub rank: usize,
    /// Condition number of the column-equilibrated system.
    pub condition: f64,
    /// Directions in property space the data do not determine (parameter units), empty
    /// when the rank is 10.
    pub null_space: Vec<[f64; N_PARAMS]>,
    /// The same, unit vectors in column-equilibrated variables (for describing them).
    pub null_space_scaled: Vec<[f64; N_PARAMS]>,
    /// `‖A p − b‖/‖b‖` of the estimator's equations (Toivola–Nuutila: the orthogonality
    /// equations; the mass line: `M0(p) (S⁺ G_k) = f_k`).
    pub residual: f64,
}

impl PropertiesEstimate {
    /// The estimate a least-squares solution of the ten properties gives.
    pub(crate) fn from_solution(sol: LsqSolution) -> PropertiesEstimate {
        PropertiesEstimate {
            mass_matrix: mass_matrix_of(&sol.p),
            params: sol.p,
            rank: sol.rank,
            condition: sol.condition,
            null_space: sol.null_space,
            null_space_scaled: sol.null_space_scaled,
            residual: sol.residual,
        }
    }
}

/// Solves `A p ≈ b` (rows of `A` given as arrays) subject to `C p = d`.
pub fn solve_parameters(
    rows: &[[f64; N_PARAMS]],
    rhs: &[f64],
    constraints: &[LinearConstraint],
    nominal: Option<&[f64; N_PARAMS]>,
) -> Result<LsqSolution, InertiaError> {
    assert_eq!(rows.len(), rhs.len());
    if rows.iter().flatten().chain(rhs).any(|x| !x.is_finite()) {
        return Err(InertiaError::NonFinite {
            what: "least-squares design matrix or right-hand side".into(),
        });
    }
    // Column equilibration p = D y.
    let d: [f64; N_PARAMS] = std::array::from_fn(|k| {
        let n = rows.iter().map(|r| r[k] * r[k]).sum::<f64>().sqrt();
        if n > 0.0 {
            1.0 / n
        } else {
            1.0
        }
    });
    // Constraints C D y = value: y = y_c + Z z.
    let (y_c, z_basis) = constraint_nullspace(constraints, &d)?;
    let nz = z_basis.ncols();
    let n = rows.len();
    // A' = A D Z, b' = b − A D y_c.
    let adz = Mat::<f64>::from_fn(n, nz, |i, j| {
        (0..N_PARAMS)
            .map(|k| rows[i][k] * d[k] * z_basis[(k, j)])
            .sum()
    });
    let b2: Vec<f64> = (0..n)
        .map(|i| {
            rhs[i]
                - (0..N_PARAMS)
                    .map(|k| rows[i][k] * d[k] * y_c[k])
                    .sum::<f64>()
        })
        .collect();
    let (z, sv, rank_z, null_z) = if nz == 0 || n == 0 {
        (vec![0.0; nz], vec![], 0, identity_columns(nz))
    } else {
        min_norm_solve(&adz, &b2)?
    };
    let mut y: [f64; N_PARAMS] =
        std::array::from_fn(|k| y_c[k] + (0..nz).map(|j| z_basis[(k, j)] * z[j]).sum::<f64>());
    // Null directions in y: Z v (Z has orthonormal columns, so unit norm is kept).
    let null_scaled: Vec<[f64; N_PARAMS]> = null_z
        .iter()
        .map(|v| std::array::from_fn(|k| (0..nz).map(|j| z_basis[(k, j)] * v[j]).sum()))
        .collect();
    if let Some(nom) = nominal {
        if !null_scaled.is_empty() {
            let y_nom: [f64; N_PARAMS] = std::array::from_fn(|k| nom[k] / d[k]);
            for v in &null_scaled {
                let t: f64 = (0..N_PARAMS).map(|k| v[k] * (y_nom[k] - y[k])).sum();
                for k in 0..N_PARAMS {
                    y[k] += t * v[k];
                }
            }
        }
    }
    let p: [f64; N_PARAMS] = std::array::from_fn(|k| d[k] * y[k]);
    let null_space = null_scaled
        .iter()
        .map(|v| std::array::from_fn(|k| d[k] * v[k]))
        .collect();
    let bnorm = rhs.iter().map(|x| x * x).sum::<f64>().sqrt();
    let rnorm = rows
        .iter()
        .zip(rhs)
        .map(|(r, b)| {
            let e = r.iter().zip(&p).map(|(a, x)| a * x).sum::<f64>() - b;
            e * e
        })
        .sum::<f64>()
        .sqrt();
    let condition = if rank_z > 0 {
        sv[0] / sv[rank_z - 1]
    } else {
        f64::INFINITY
    };
    if p.iter().any(|x| !x.is_finite()) {
        return Err(InertiaError::NonFinite {
            what: "least-squares parameters".into(),
        });
    }
    Ok(LsqSolution {
        p,
        rank: rank_z + (N_PARAMS - nz),
        singular_values: sv,
        condition,
        null_space,
        null_space_scaled: null_scaled,
        residual: if bnorm > 0.0 { rnorm / bnorm } else { rnorm },
    })
}

fn identity_columns(n: usize) -> Vec<Vec<f64>> {
    (0..n)
        .map(|j| (0..n).map(|i| (i == j) as u8 as f64).collect())
        .collect()
}

/// Particular solution `y_c` (minimum norm) and an orthonormal basis `Z` of the null space
/// of the scaled constraint matrix `C D`.
fn constraint_nullspace(
    constraints: &[LinearConstraint],
    d: &[f64; N_PARAMS],
) -> Result<([f64; N_PARAMS], Mat<f64>), InertiaError> {
    if constraints.is_empty() {
        return Ok(([0.0; N_PARAMS], Mat::<f64>::identity(N_PARAMS, N_PARAMS)));
    }
    let k = constraints.len();
    let c = Mat::<f64>::from_fn(k, N_PARAMS, |i, j| constraints[i].row[j] * d[j]);
    let values: Vec<f64> = constraints.iter().map(|c| c.value).collect();
    let svd = c
        .svd()
        .map_err(|e| InertiaError::LinearAlgebra(format!("SVD of the constraints: {e:?}")))?;
    let s = svd.S().column_vector();
    let smax = if k > 0 { s[0] } else { 0.0 };
    let rank = (0..k.min(N_PARAMS))
        .filter(|&i| s[i] > RANK_TOLERANCE * smax)
        .count();
    if rank < k {
        let labels: Vec<&str> = constraints.iter().map(|c| c.label.as_str()).collect();
        return Err(InertiaError::SideInformation(format!(
            "the constraints [{}] are redundant or contradictory (rank {rank} of {k})",
            labels.join(", ")
        )));
    }
    let (u, v) = (svd.U(), svd.V());
    let mut y_c = [0.0; N_PARAMS];
    for i in 0..rank {
        let coef: f64 = (0..k).map(|r| u[(r, i)] * values[r]).sum::<f64>() / s[i];
        for j in 0..N_PARAMS {
            y_c[j] += coef * v[(j, i)];
        }
    }
    let z = Mat::<f64>::from_fn(N_PARAMS, N_PARAMS - rank, |i, j| v[(i, rank + j)]);
    Ok((y_c, z))
}

/// Minimum-norm least squares by SVD: returns the solution, the singular values, the
/// numerical rank and the null-space basis vectors.
#[allow(clippy::type_complexity)]
fn min_norm_solve(
    a: &Mat<f64>,
    b: &[f64],
) -> Result<(Vec<f64>, Vec<f64>, usize, Vec<Vec<f64>>), InertiaError> {
    let (n, m) = (a.nrows(), a.ncols());
    // Tall systems (the mass line stacks six rows per excitation) need only the first m
    // columns of U: the full n×n factor made the cost grow as n³ with the excitations.
    // V stays whole either way (m ≤ n), so the null directions are still all there.
    let svd = if n >= m { a.thin_svd() } else { a.svd() }
        .map_err(|e| InertiaError::LinearAlgebra(format!("SVD of the design matrix: {e:?}")))?;
    let s = svd.S().column_vector();
    let ns = n.min(m);
    let sv: Vec<f64> = (0..ns).map(|i| s[i]).collect();
    let smax = sv.first().copied().unwrap_or(0.0);
    let rank = sv.iter().filter(|&&x| x > RANK_TOLERANCE * smax).count();
    let (u, v) = (svd.U(), svd.V());
    let mut x = vec![0.0; m];
    for i in 0..rank {
        let coef: f64 = (0..n).map(|r| u[(r, i)] * b[r]).sum::<f64>() / sv[i];
        for j in 0..m {
            x[j] += coef * v[(j, i)];
        }
    }
    let null: Vec<Vec<f64>> = (rank..m)
        .map(|i| (0..m).map(|j| v[(j, i)]).collect())
        .collect();
    Ok((x, sv, rank, null))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rows_of(f: impl Fn(usize, usize) -> f64, n: usize) -> Vec<[f64; N_PARAMS]> {
        (0..n).map(|i| std::array::from_fn(|k| f(i, k))).collect()
    }

    #[test]
    fn full_rank_system_is_solved_exactly_despite_column_scales() {
        // Columns scaled over six decades, as kg vs kg m² can be.
        let scale = |k: usize| 10f64.powi(k as i32 - 4);
        let rows = rows_of(
            |i, k| ((i * 7 + k * 3) % 11) as f64 * scale(k) + (i == k) as u8 as f64,
            14,
        );
        let p_true: [f64; N_PARAMS] = std::array::from_fn(|k| (k as f64 - 3.5) / scale(k));
        let rhs: Vec<f64> = rows
            .iter()
            .map(|r| r.iter().zip(&p_true).map(|(a, b)| a * b).sum())
            .collect();
        let sol = solve_parameters(&rows, &rhs, &[], None).unwrap();
        assert_eq!(sol.rank, 10);
        assert!(sol.null_space.is_empty());
        for k in 0..N_PARAMS {
            assert!(
                (sol.p[k] - p_true[k]).abs() < 1e-10 * p_true[k].abs().max(1.0),
                "{k}"
            );
        }
        assert!(sol.residual < 1e-12);
    }

    #[test]
    fn rank_deficiency_is_reported_and_filled_from_nominal_or_constraint() {
        // Columns 2 and 5 always appear as their sum: p2 − p5 is not identifiable.
        let rows = rows_of(
            |i, k| {
                let base = (((i + 1) * (k + 2)) % 7) as f64 + (i == k) as u8 as f64;
                if k == 5 {
                    ((((i + 1) * 4) % 7) as f64) + (i == 2) as u8 as f64
                } else {
                    base
                }
            },
            12,
        );
        let p_true: [f64; N_PARAMS] = std::array::from_fn(|k| 1.0 + k as f64);
        let rhs: Vec<f64> = rows
            .iter()
            .map(|r| r.iter().zip(&p_true).map(|(a, b)| a * b).sum())
            .collect();
        let sol = solve_parameters(&rows, &rhs, &[], None).unwrap();
        assert_eq!(sol.rank, 9);
        let v = sol.null_space_scaled[0];
        assert!(
            v[2].abs() > 0.7 && (v[2] + v[5]).abs() < 1e-9 * v[2].abs(),
            "{v:?}"
        );
        // A nominal vector fixes the unidentifiable combination and nothing else.
        let mut nominal = p_true;
        nominal[0] += 0.3; // a wrong nominal in an identifiable parameter is ignored
        let reg = solve_parameters(&rows, &rhs, &[], Some(&nominal)).unwrap();
        for k in 0..N_PARAMS {
            assert!((reg.p[k] - p_true[k]).abs() < 1e-9, "{k}: {}", reg.p[k]);
        }
        // So does an exact constraint p5 = 6.
        let mut row = [0.0; N_PARAMS];
        row[5] = 1.0;
        let c = LinearConstraint {
            row,
            value: 6.0,
            label: "p5 known".into(),
        };
        let con = solve_parameters(&rows, &rhs, &[c], None).unwrap();
        assert_eq!(con.rank, 10);
        for k in 0..N_PARAMS {
            assert!((con.p[k] - p_true[k]).abs() < 1e-9, "{k}");
        }
    }
}
