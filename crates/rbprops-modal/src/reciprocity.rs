//! The modal basis of a repeated root that satisfies Maxwell reciprocity.
//!
//! At a repeated root `λ` with multiplicity `k`, the data fix only the residue matrix
//! `Σ_r ψ_r l_rᵀ = Ψ Lᵀ` of the group, not its split into modes: `(Ψ T, L T⁻ᵀ)` fits
//! equally for any invertible `T`, and the eigen-solver returns an arbitrary one. The
//! rigid-body estimators read one mode at a time (`φ = q/√(fᵀq)` from one excitation),
//! so the split must be a set of true modes: each mode's participation must be its own
//! shape seen at the force DOFs, `l_r ∝ Fᵀ x_r`, where `x_r = (SᵀS)⁻¹Sᵀψ_r` is the mode's
//! rigid motion (paper Eq. 5, rows `S` of the channels, columns `F` of the forces).
//!
//! With `Ψ = S Φ T₀` and `L = Fᵀ Φ T₀⁻ᵀ` for true (mass-normalised, real) modes `Φ`:
//! `Σ := L⁺ Fᵀ X = T₀ᵀ T₀` is symmetric, and `T` gives true modes exactly when
//! `(T₀T)ᵀ(T₀T) = Tᵀ Σ T` is diagonal, i.e. `T` = the eigenvectors of `Σ` (after `X`
//! has been made real, so that `Σ` is real symmetric and `T` a real rotation). Any
//! such `T` is as good as another: within a repeated root every orthogonal rotation of
//! the modes is a set of modes.

use nalgebra::{DMatrix, SymmetricEigen};
use rbprops_core::{c64, Geometry, RigidBasis};

/// The participation vectors (`[r][e]`) of a reciprocal modal basis for the group with
/// shapes `psi[r][o]` (all geometry channels) and participation `parts[r][e]` (the
/// excitations `members`), or `None` with the reason when it cannot be built (channels
/// that do not resolve rigid motion, shapes far from rigid, too few excitations).
pub fn reciprocal_participation(
    geometry: &Geometry,
    members: &[usize],
    psi: &[Vec<c64>],
    parts: &[Vec<c64>],
) -> Result<Vec<Vec<c64>>, String> {
    let k = psi.len();
    let ni = members.len();
    if k < 2 {
        return Ok(parts.to_vec());
    }
    if ni < k {
        return Err(format!(
            "{ni} excitations cannot separate a root of multiplicity {k}"
        ));
    }
    let rows = geometry.channels.iter().map(|c| c.row()).collect();
    let basis = RigidBasis::new(rows).map_err(|e| e.to_string())?;
    // X = rigid motions of the shapes (6 × k, complex), real and imaginary parts apart.
    let mut x = DMatrix::<c64>::zeros(6, k);
    for (r, p) in psi.iter().enumerate() {
        let re: Vec<f64> = p.iter().map(|z| z.re).collect();
        let im: Vec<f64> = p.iter().map(|z| z.im).collect();
        let (fr, fi) = (
            basis.fit(&re).map_err(|e| e.to_string())?,
            basis.fit(&im).map_err(|e| e.to_string())?,
        );
        let norm = p.iter().map(|z| z.norm_sqr()).sum::<f64>().sqrt();
        let res = (fr.residual.iter().chain(&fi.residual))
            .map(|v| v * v)
            .sum::<f64>()
            .sqrt();
        if !(res <= 0.2 * norm) {
            return Err(format!(
                "mode shapes are not rigid-body motions (residual {:.0} % of the shape)",
                100.0 * res / norm
            ));
        }
        for i in 0..6 {
            x[(i, r)] = c64::new(fr.q[i], fi.q[i]);
        }
    }
    // T₁: the real basis of span(X) (top k left singular vectors of [Re X, Im X]).
    let mut ri = DMatrix::<f64>::zeros(6, 2 * k);
    for r in 0..k {
        for i in 0..6 {
            ri[(i, r)] = x[(i, r)].re;
            ri[(i, k + r)] = x[(i, r)].im;
        }
    }
    let svd = ri.svd(true, false);
    let u = svd.u.ok_or("SVD failed")?;
    // Columns by decreasing singular value (nalgebra does not sort).
    let mut order: Vec<usize> = (0..svd.singular_values.len()).collect();
    order.sort_by(|&a, &b| {
        svd.singular_values[b]
            .total_cmp(&svd.singular_values[a])
            .then(a.cmp(&b))
    });
    let b = DMatrix::<c64>::from_fn(6, k, |i, j| c64::new(u[(i, order[j])], 0.0));
    let xh = x.adjoint();
    let t1 = (xh.clone() * &x)
        .try_inverse()
        .ok_or("the shapes of the repeated root are not independent")?
        * xh
        * &b;
    let t1_inv_t = t1
        .clone()
        .try_inverse()
        .ok_or("singular change of basis")?
        .transpose();
    let l0 = DMatrix::<c64>::from_fn(ni, k, |e, r| parts[r][e]);
    let l1 = &l0 * &t1_inv_t;
    // G = Fᵀ X₁ with X₁ = X T₁ = B (real).
    let g = DMatrix::<c64>::from_fn(ni, k, |e, r| {
        let f = geometry.excitations[members[e]].column();
        (0..6).map(|i| b[(i, r)] * f[i]).sum()
    });
    let l1h = l1.adjoint();
    let sigma = (l1h.clone() * &l1)
        .try_inverse()
        .ok_or("the participation vectors of the repeated root are not independent")?
        * l1h
        * g;
    // Σ = c·(real symmetric) with c the common phase of L₁: remove it, symmetrise.
    let tr: c64 = (0..k).map(|i| sigma[(i, i)]).sum();
    let ph = if tr.norm() > 0.0 {
        tr.conj() / tr.norm()
    } else {
        c64::new(1.0, 0.0)
    };
    let sr = DMatrix::<f64>::from_fn(k, k, |i, j| {
        0.5 * ((sigma[(i, j)] * ph).re + (sigma[(j, i)] * ph).re)
    });
    let eig = SymmetricEigen::new(sr);
    let v = DMatrix::<c64>::from_fn(k, k, |i, j| c64::new(eig.eigenvectors[(i, j)], 0.0));
    // L₂ = L₁ V⁻ᵀ = L₁ V (V orthogonal).
    let l2 = l1 * v;
    Ok((0..k)
        .map(|r| {
            let mut l: Vec<c64> = (0..ni).map(|e| l2[(e, r)]).collect();
            crate::plscf::normalise_phase(&mut l);
            l
        })
        .collect())
}
