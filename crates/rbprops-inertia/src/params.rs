//! The ten inertia parameters about an origin O and the linear map `p ↦ M0(p)`.
//!
//! `p = (m, m c_x, m c_y, m c_z, J_O,xx, J_O,yy, J_O,zz, J_O,xy, J_O,xz, J_O,yz)` where the
//! last three are *products* of inertia about O in the docs/conventions.md sense (`J_xy = ∫xy dm`),
//! so the tensor entry is their negative (paper Eq. 6, with its (6,6) typo fixed):
//!
//! ```text
//! M0(p) = [ m I        −[mc]× ]
//!         [ [mc]×       J_O   ]
//! ```
//! `M0` is linear in `p`: `M0(p) = Σ_k p_k E_k`, which makes Toivola–Nuutila (Eq. 10) and
//! the mass-line equations `M0 y = f` linear least-squares problems.

use rbprops_core::{cross_matrix, MassMatrix6, Mat6, Vec3, Vec6};

/// Number of inertia parameters.
pub const N_PARAMS: usize = 10;

/// Human names of the parameters, in order (used in null-space descriptions).
pub const PARAM_NAMES: [&str; N_PARAMS] = [
    "m", "m·c_x", "m·c_y", "m·c_z", "J_O,xx", "J_O,yy", "J_O,zz", "J_O,xy", "J_O,xz", "J_O,yz",
];

/// `M0(p)` for a parameter vector (not necessarily physical).
pub fn mass_matrix_of(p: &[f64; N_PARAMS]) -> MassMatrix6 {
    let m = p[0];
    let s = Vec3::new(p[1], p[2], p[3]);
    let sx = cross_matrix(&s);
    let mut mm = Mat6::zeros();
    for i in 0..3 {
        mm[(i, i)] = m;
    }
    mm.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-sx));
    mm.fixed_view_mut::<3, 3>(3, 0).copy_from(&sx);
    let (jxx, jyy, jzz, jxy, jxz, jyz) = (p[4], p[5], p[6], p[7], p[8], p[9]);
    let j = [[jxx, -jxy, -jxz], [-jxy, jyy, -jyz], [-jxz, -jyz, jzz]];
    for r in 0..3 {
        for c in 0..3 {
            mm[(3 + r, 3 + c)] = j[r][c];
        }
    }
    MassMatrix6(mm)
}

/// The parameter vector of an exact rigid-body mass matrix (inverse of [`mass_matrix_of`]).
pub fn params_of(m0: &MassMatrix6) -> [f64; N_PARAMS] {
    let m = &m0.0;
    // m·c from paper Eq. (7) (averages the two copies in the upper-right block).
    let mc = m0.com() * m0.mass();
    [
        m0.mass(),
        mc.x,
        mc.y,
        mc.z,
        m[(3, 3)],
        m[(4, 4)],
        m[(5, 5)],
        -(m[(3, 4)] + m[(4, 3)]) / 2.0,
        -(m[(3, 5)] + m[(5, 3)]) / 2.0,
        -(m[(4, 5)] + m[(5, 4)]) / 2.0,
    ]
}

/// The basis matrices `E_k = ∂M0/∂p_k`.
pub fn basis_matrices() -> [Mat6; N_PARAMS] {
    std::array::from_fn(|k| {
        let mut p = [0.0; N_PARAMS];
        p[k] = 1.0;
        mass_matrix_of(&p).0
    })
}

/// Row of the orthogonality equation `φ_iᵀ M0(p) φ_j = δ_ij` (paper Eq. 10):
/// coefficient `k` is `φ_iᵀ E_k φ_j`.
pub fn orthogonality_row(e: &[Mat6; N_PARAMS], phi_i: &Vec6, phi_j: &Vec6) -> [f64; N_PARAMS] {
    std::array::from_fn(|k| (phi_i.transpose() * e[k] * phi_j)[0])
}

/// The 6×10 block of `M0(p) y = f` (mass-line equations): column `k` is `E_k y`.
pub fn action_block(e: &[Mat6; N_PARAMS], y: &Vec6) -> [[f64; N_PARAMS]; 6] {
    let cols: [Vec6; N_PARAMS] = std::array::from_fn(|k| e[k] * y);
    std::array::from_fn(|r| std::array::from_fn(|k| cols[k][r]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rbprops_core::inertia::ProductsOfInertia;
    use rbprops_core::RigidBodyProperties;

    #[test]
    fn parameters_round_trip_through_the_closed_form_mass_matrix() {
        let props = RigidBodyProperties::from_moments_and_products(
            15.69,
            Vec3::new(0.17, 0.03, -0.05),
            [0.357, 0.394, 0.317],
            ProductsOfInertia {
                xy: 0.077,
                xz: -0.087,
                yz: -0.069,
            },
        );
        let m0 = props.mass_matrix();
        let p = params_of(&m0);
        assert!((mass_matrix_of(&p).0 - m0.0).norm() < 1e-14 * m0.0.norm());
        assert!((p[1] - props.mass * props.com.x).abs() < 1e-14);
        // Products about O in the ∫xy dm sense: the tensor entry (x,y) is −J_O,xy.
        let jo = props.inertia_about_origin();
        assert_eq!(p[7], -jo[(0, 1)]);
        let e = basis_matrices();
        let phi = Vec6::new(0.1, -0.2, 0.3, 0.5, 0.7, -0.4);
        let psi = Vec6::new(-0.3, 0.2, 0.1, 0.2, -0.6, 0.9);
        let row = orthogonality_row(&e, &phi, &psi);
        let direct = (phi.transpose() * m0.0 * psi)[0];
        let lin: f64 = row.iter().zip(&p).map(|(a, b)| a * b).sum();
        assert!((lin - direct).abs() < 1e-13);
        let blk = action_block(&e, &psi);
        let mv = m0.0 * psi;
        for r in 0..6 {
            let lin: f64 = blk[r].iter().zip(&p).map(|(a, b)| a * b).sum();
            assert!((lin - mv[r]).abs() < 1e-13);
        }
    }
}
