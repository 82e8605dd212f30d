//! `gravity_stiffness`: the pendulum (geometric) stiffness of a cord suspension.
//!
//! Each spring of the set-up is read as a vertical cord: its lower end at the spring's
//! attachment point `a_i`, its upper end at a fixed anchor `a_i + ℓ_i ẑ` (ẑ = `up`), its
//! axial stiffness `k_i = ẑᵀ k ẑ` taken from the spring. Static equilibrium under the
//! weight `W = −m g ẑ` (m, c from the model's current mass matrix, so attached masses
//! count) fixes the tensions: `Σ T_i = m g`, `Σ T_i a_i,h = m g c_h` (horizontal parts).
//! With more than three cords the tensions follow the cords' stiffness (a rigid tilt
//! `T_i = k_i (w0 + w·a_i,h)`, the elastic static solution). Linearising the exact
//! potential (elastic + gravitational) about that equilibrium adds
//!
//! `K_geo = Σ_i T(a_i)ᵀ (T_i/ℓ_i)(I − ẑẑᵀ) T(a_i) + blockdiag(0, K_θθ)`,
//! `K_θθ = −(Σ_i T_i [ẑ]×[a_i]× + [W]×[c]×)`
//!
//! (lateral pendulum stiffness of each cord, and the moments of the tensions and of
//! the weight about arms that rotate with the body; docs/physics.md, E1, Griffis & Duffy).
//! `K_θθ` is symmetric exactly when the moments balance. Checked in the tests against a
//! simple pendulum `ω² = g/ℓ`, the trifilar yaw `ω² = m g ρ²/(ℓ J)` and a
//! finite-difference Hessian of the exact potential.
//!
//! **Set-ups with cords** (`[[setup.cord]]`: attachment, anchor, unstretched length L₀,
//! axial stiffness k) are not read that way: there the body hangs. Without this effect
//! a cord is its axial spring `k e eᵀ` (the tester's model, which leaves the pendulum
//! directions free); with it the body moves from its reference pose to the static
//! equilibrium of the weight, the cords (tension `k (L − L₀)`) and the set-up's springs,
//! found with finite rotations, and the set-up's stiffness becomes the exact Hessian of
//! the potential there ([`hanging_equilibrium`]): axial springs along the cords' actual
//! directions, their lateral tension stiffness `(T/L)(I − e eᵀ)` and the load term of
//! every force, in body axes. Splayed cords (anchors not above the attachments) may so
//! tilt the body; the sensors and forces stay where the spec puts them on the body. For
//! vertical cords whose reference pose is their equilibrium this is the springs plus the
//! `K_geo` above, with `ℓ = L₀ + T/k` (tested). `unstretched_length_m`, when given,
//! replaces the cords' L₀ (the model check fits it), also for cords written as axial
//! springs, which otherwise hang in the drawn pose ([`axial_spring_cords`]): unequal
//! free lengths of splayed cords move and tilt the body; `cord_length_m` is for set-ups
//! of springs only. The gravity direction of the other gravity effects stays the spec's
//! `up` (its tilt with the body at equilibrium is second order for them).

pub mod screening;

use super::{BuildContext, Effect, ParamInfo};
use crate::model::DynamicModel;
use crate::spec::CampaignSpec;
use rbprops_core::{cross_matrix, rigid_transform, MassMatrix6, Mat3, Mat6, Vec3, Vec6};
use serde::{Deserialize, Serialize};

/// Standard gravity (m/s²).
pub const STANDARD_GRAVITY: f64 = 9.80665;

/// Spec parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GravityStiffness {
    /// Set-up whose springs are cords; all set-ups when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub setup: Option<String>,
    /// Cord length per spring (m), or one value for all: set-ups of springs, read as
    /// vertical cords.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub cord_length_m: Vec<f64>,
    /// Unstretched length L₀ per cord (m), or one value for all, replacing the spec's:
    /// set-ups with `[[setup.cord]]` (empty: the spec's own), or the cords written as
    /// axial springs (empty: the lengths at which the body hangs in the drawn pose,
    /// `ℓ − T/k`; given, the body moves to the equilibrium they make).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub unstretched_length_m: Vec<f64>,
    /// Set-ups of springs read as cords only: the fraction by which the springs turn
    /// with the sagged body, as linear springs to the ground do (1), rather than keep the
    /// spec's axes as cords do (0, the default). The springs' exact Hessian at the
    /// body's sagged equilibrium replaces that part of the cords' load term: `K =
    /// K_cords(ℓ) + s (K_sagged − K_spec − K_load)`, `K_load` the cords' load term
    /// (ℓ → ∞). A body on three-axis springs to the ground has s = 1 and ℓ → ∞.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub spring_turn_fraction: f64,
    /// Gravitational acceleration (m/s²).
    #[serde(default = "super::default_g")]
    pub g_m_per_s2: f64,
    /// Upward unit vector in the geometry frame.
    #[serde(default = "super::default_up")]
    pub up: [f64; 3],
}

/// A vertical cord: attachment point, length (m), axial stiffness (N/m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cord {
    /// Attachment point on the body (m).
    pub at: Vec3,
    /// Cord length (m).
    pub length: f64,
    /// Axial stiffness (N/m).
    pub axial_stiffness: f64,
}

/// Equilibrium tensions (N) of vertical cords holding mass `m` with CoM `c`.
pub fn cord_tensions(
    cords: &[Cord],
    m: f64,
    c: &Vec3,
    g: f64,
    up: &Vec3,
) -> Result<Vec<f64>, String> {
    // Horizontal basis ⟂ up.
    let h1 = if up.x.abs() < 0.9 {
        Vec3::x()
    } else {
        Vec3::y()
    };
    let h1 = (h1 - h1.dot(up) * up).normalize();
    let h2 = up.cross(&h1);
    let coord = |p: &Vec3| Vec3::new(1.0, p.dot(&h1), p.dot(&h2));
    // Σ_i k_i coord_i coord_iᵀ w = m g coord(c)
    let mut a = Mat3::zeros();
    for cd in cords {
        let v = coord(&cd.at);
        a += cd.axial_stiffness * v * v.transpose();
    }
    let rhs = m * g * coord(c);
    let w = a
        .svd(true, true)
        .solve(&rhs, 1e-12 * a.norm())
        .map_err(|e| e.to_string())?;
    let t: Vec<f64> = cords
        .iter()
        .map(|cd| cd.axial_stiffness * coord(&cd.at).dot(&w))
        .collect();
    // Equilibrium must hold (fails when the CoM is off the cords' line or plane).
    let mut f = Vec3::zeros();
    for (cd, ti) in cords.iter().zip(&t) {
        f += *ti * coord(&cd.at);
    }
    if (f - rhs).norm() > 1e-9 * rhs.norm() {
        return Err(format!(
            "the cords cannot hold the body in equilibrium (CoM {:?} is not over their support)",
            c.as_slice()
        ));
    }
    for (i, ti) in t.iter().enumerate() {
        if !(*ti > 0.0) {
            return Err(format!(
                "cord {i} at {:?} would be slack (tension {ti:.4} N): the CoM lies outside the cords' support polygon",
                cords[i].at.as_slice()
            ));
        }
    }
    Ok(t)
}

/// The geometric stiffness `K_geo` (see the module docs) and the tensions.
pub fn geometric_stiffness(
    mass: &Mat6,
    cords: &[Cord],
    g: f64,
    up: &Vec3,
) -> Result<(Mat6, Vec<f64>), String> {
    let mm = MassMatrix6(*mass);
    let (m, c) = (mm.mass(), mm.com());
    let t = cord_tensions(cords, m, &c, g, up)?;
    let lateral = Mat3::identity() - up * up.transpose();
    let zx = cross_matrix(up);
    let w = -m * g * up;
    let mut k = Mat6::zeros();
    let mut kth = -(cross_matrix(&w) * cross_matrix(&c));
    for (cd, ti) in cords.iter().zip(&t) {
        let tr = rigid_transform(&cd.at);
        k += tr.transpose() * ((*ti / cd.length) * lateral) * tr;
        kth -= *ti * zx * cross_matrix(&cd.at);
    }
    let asym = (kth - kth.transpose()).norm();
    if asym > 1e-9 * kth.norm().max(f64::MIN_POSITIVE) {
        return Err(format!("moments do not balance (asymmetry {asym:.3e})"));
    }
    let mut block = k.fixed_view_mut::<3, 3>(3, 3);
    block += (kth + kth.transpose()) / 2.0;
    Ok((k, t))
}

/// An elastic cord from body point `at` (body frame) to the fixed `anchor` (the
/// geometry frame at the body's reference pose): tension `k (L − L₀)₊` at length `L`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnchoredCord {
    /// Attachment point, body frame (m).
    pub at: Vec3,
    /// Fixed anchor point, geometry frame (m).
    pub anchor: Vec3,
    /// Axial stiffness `k` (N/m).
    pub axial_stiffness: f64,
    /// Free length `L₀` (m).
    pub unstretched_length: f64,
}

impl AnchoredCord {
    /// Unit vector from the attachment to the anchor at the reference pose.
    pub fn direction(&self) -> Vec3 {
        (self.anchor - self.at).normalize()
    }
    /// The cord without gravity: the axial spring `k e eᵀ` at its attachment.
    pub fn axial_spring(&self) -> crate::suspension::Spring {
        let e = self.direction();
        crate::suspension::Spring {
            at: self.at,
            stiffness: self.axial_stiffness * e * e.transpose(),
        }
    }
}

/// The static equilibrium of a body hanging on cords (and linear springs) under gravity,
/// and the stiffness about it.
#[derive(Debug, Clone, PartialEq)]
pub struct HangingEquilibrium {
    /// Pose of the body at equilibrium: body point `a` sits at `R a + t` (geometry frame
    /// of the reference pose).
    pub rotation: Mat3,
    /// Translation `t` of the pose (m).
    pub translation: Vec3,
    /// Cord tensions (N) and stretched lengths (m), spec order.
    pub tensions: Vec<f64>,
    /// Stretched cord lengths `L` (m), spec order.
    pub lengths: Vec<f64>,
    /// Unit vectors from the attachments to the anchors, in body axes.
    pub directions: Vec<Vec3>,
    /// `up` in body axes, `Rᵀ up`.
    pub up_body: Vec3,
    /// Hessian of the potential about the equilibrium in body axes about the geometry
    /// origin (the model's stiffness; see [`hanging_equilibrium`]).
    pub stiffness: Mat6,
    /// Its lateral (tension) part `Σ T(a)ᵀ (T/L)(I − e eᵀ) T(a)`.
    pub lateral: Mat6,
}

/// `(F·r) I − sym(F rᵀ)`: the second-order work of a fixed force `F` at a body point `r`
/// under a small rotation (`r(θ) = r + θ×r + ½θ×(θ×r)`), the load term of the geometric
/// stiffness.
fn load_term(f: &Vec3, r: &Vec3) -> Mat3 {
    let fr = f * r.transpose();
    Mat3::identity() * f.dot(r) - (fr + fr.transpose()) / 2.0
}

/// One evaluation of the hanging body at a pose.
struct HangingState {
    potential: f64,
    /// Generalised force on the body (body axes, about the origin): −∇V.
    force: Vec6,
    hessian: Mat6,
    lateral: Mat6,
    /// Per cord: tension, length, direction (body axes).
    cords: Vec<(f64, f64, Vec3)>,
}

/// Potential, generalised force and Hessian of a body (mass `m`, CoM `c`) at pose
/// `(R, t)` on `cords` and `springs` (linear springs with no force at the reference pose,
/// to the ground) under gravity `g` along `−up`.
#[allow(clippy::too_many_arguments)]
fn hanging_state(
    rot: &Mat3,
    t: &Vec3,
    cords: &[AnchoredCord],
    springs: &[crate::suspension::Spring],
    m: f64,
    c: &Vec3,
    g: f64,
    up: &Vec3,
) -> HangingState {
    let gen = |f: &Vec3, a: &Vec3| -> Vec6 { rigid_transform(a).transpose() * f };
    let mut v = m * g * up.dot(&(rot * c + t));
    let w_b = rot.transpose() * (-m * g * up);
    let mut force = gen(&w_b, c);
    let mut k = Mat6::zeros();
    let mut lat = Mat6::zeros();
    let mut kth = load_term(&w_b, c);
    let mut per_cord = Vec::with_capacity(cords.len());
    for cd in cords {
        let d = cd.anchor - (rot * cd.at + t);
        let len = d.norm();
        let e_b = rot.transpose() * (d / len);
        let stretch = (len - cd.unstretched_length).max(0.0);
        let tension = cd.axial_stiffness * stretch;
        v += 0.5 * cd.axial_stiffness * stretch * stretch;
        let f_b = tension * e_b;
        force += gen(&f_b, &cd.at);
        kth += load_term(&f_b, &cd.at);
        let tr = rigid_transform(&cd.at);
        let axial = if stretch > 0.0 {
            cd.axial_stiffness
        } else {
            0.0
        };
        let lateral = (tension / len) * (Mat3::identity() - e_b * e_b.transpose());
        k += tr.transpose() * (axial * e_b * e_b.transpose() + lateral) * tr;
        lat += tr.transpose() * lateral * tr;
        per_cord.push((tension, len, e_b));
    }
    for s in springs {
        let u = rot * s.at + t - s.at;
        v += 0.5 * (u.transpose() * s.stiffness * u)[0];
        let f_b = rot.transpose() * (-(s.stiffness * u));
        force += gen(&f_b, &s.at);
        kth += load_term(&f_b, &s.at);
        let tr = rigid_transform(&s.at);
        k += tr.transpose() * (rot.transpose() * s.stiffness * rot) * tr;
    }
    let mut block = k.fixed_view_mut::<3, 3>(3, 3);
    block += kth;
    HangingState {
        potential: v,
        force,
        hessian: (k + k.transpose()) / 2.0,
        lateral: lat,
        cords: per_cord,
    }
}

/// The static equilibrium of a body with mass matrix `mass` (about the origin) hanging on
/// `cords` and `springs` under gravity `g` along `−up`, from its reference pose, by
/// damped Newton on the exact potential with finite rotations
/// `V = Σ ½ k (L − L₀)₊² + Σ ½ uᵀk u + m g upᵀ(R c + t)`, perturbing the pose as
/// `R ← R exp([θ]×)`, `t ← t + R u` (body axes). Its Hessian there is the model's
/// stiffness:
///
/// `K = Σ_cords T(a)ᵀ [k e eᵀ + (T/L)(I − e eᵀ)] T(a) + Σ_springs T(a)ᵀ Rᵀk R T(a)
///      + blockdiag(0, Σ_forces (F·r) I − sym(F rᵀ))`,
///
/// every vector in body axes (`e` toward the anchor, `F` each cord's, spring's and the
/// weight's force, `r` its point). For vertical cords in equilibrium at the reference
/// pose it is the axial springs plus [`geometric_stiffness`] (checked in the tests).
/// Errors: no stable equilibrium (the body falls, a direction with no restoring force),
/// or a cord slack at equilibrium.
pub fn hanging_equilibrium(
    mass: &Mat6,
    cords: &[AnchoredCord],
    springs: &[crate::suspension::Spring],
    g: f64,
    up: &Vec3,
) -> Result<HangingEquilibrium, String> {
    let mm = MassMatrix6(*mass);
    let (m, c) = (mm.mass(), mm.com());
    let weight = m * g;
    // Length scale of the body and cords, for the convergence test on the moments.
    let size = cords
        .iter()
        .map(|cd| cd.at.norm().max(cd.unstretched_length))
        .chain(springs.iter().map(|s| s.at.norm()))
        .fold(c.norm(), f64::max)
        .max(1e-3);
    let residual = |f: &Vec6| f.fixed_rows::<3>(0).norm() + f.fixed_rows::<3>(3).norm() / size;
    let mut rot = Mat3::identity();
    let mut t = Vec3::zeros();
    let mut st = hanging_state(&rot, &t, cords, springs, m, &c, g, up);
    // Levenberg damping in the mass metric (M is positive definite): a step that does
    // not lower the potential is retried shorter and closer to M⁻¹-steepest descent.
    let mut mu = 0.0f64;
    let mu0 = 1e-6 * st.hessian.diagonal().abs().max().max(weight / size) / mass.diagonal().max();
    for _ in 0..500 {
        if residual(&st.force) <= 1e-13 * weight {
            break;
        }
        let mut stepped = false;
        for _ in 0..80 {
            if let Some(ch) = nalgebra::Cholesky::new(st.hessian + mass * mu) {
                let dq = ch.solve(&st.force);
                let du = Vec3::new(dq[0], dq[1], dq[2]);
                let dth = Vec3::new(dq[3], dq[4], dq[5]);
                let rot2 = rot * nalgebra::Rotation3::new(dth).into_inner();
                let t2 = t + rot * du;
                let s2 = hanging_state(&rot2, &t2, cords, springs, m, &c, g, up);
                // Near the minimum the potential is flat to rounding: accept a step that
                // does not raise it beyond that and lowers the force.
                let tol = 1e-14 * (st.potential.abs() + weight * size);
                if s2.potential < st.potential
                    || (s2.potential <= st.potential + tol
                        && residual(&s2.force) < residual(&st.force))
                {
                    rot = rot2;
                    t = t2;
                    st = s2;
                    mu = if mu < 4.0 * mu0 { 0.0 } else { mu / 4.0 };
                    stepped = true;
                    break;
                }
            }
            mu = if mu == 0.0 { mu0 } else { mu * 4.0 };
        }
        if !stepped {
            break;
        }
    }
    let r = residual(&st.force);
    if !(r <= 1e-9 * weight) {
        return Err(format!(
            "no static equilibrium: the cords and springs cannot hold the body (residual force {r:.3e} N for a weight of {weight:.3e} N)"
        ));
    }
    if let Some(i) = st.cords.iter().position(|(tn, _, _)| !(*tn > 0.0)) {
        return Err(format!(
            "cord {i} (at {:?}) is slack at equilibrium: give a shorter unstretched length",
            cords[i].at.as_slice()
        ));
    }
    let ev = st.hessian.symmetric_eigenvalues();
    if ev.min() < -1e-9 * ev.abs().max() {
        return Err(format!(
            "the equilibrium is unstable (stiffness eigenvalue {:.3e})",
            ev.min()
        ));
    }
    Ok(HangingEquilibrium {
        up_body: rot.transpose() * up,
        rotation: rot,
        translation: t,
        tensions: st.cords.iter().map(|p| p.0).collect(),
        lengths: st.cords.iter().map(|p| p.1).collect(),
        directions: st.cords.iter().map(|p| p.2).collect(),
        stiffness: st.hessian,
        lateral: st.lateral,
    })
}

/// A spring's axis and axial stiffness when it is axial (a cord or a coil spring written
/// as `k e eᵀ`): its other two stiffnesses below 1e-6 of the largest. The axis points
/// up (`e · up ≥ 0`).
pub fn axial_spring(k: &Mat3, up: &Vec3) -> Option<(Vec3, f64)> {
    let eig = ((k + k.transpose()) / 2.0).symmetric_eigen();
    let i = eig.eigenvalues.imax();
    let kmax = eig.eigenvalues[i];
    if !(kmax > 0.0) || (0..3).any(|j| j != i && eig.eigenvalues[j].abs() > 1e-6 * kmax) {
        return None;
    }
    let e: Vec3 = eig.eigenvectors.column(i).into_owned().normalize();
    Some((if e.dot(up) < 0.0 { -e } else { e }, kmax))
}

/// Set-up `i`'s springs read as cords, when they are written as the cords' axial springs
/// (`k e eᵀ` along each cord, vertical or splayed, as testers write a suspension): every
/// axial spring within 60° of `up` becomes a cord from its attachment along its axis, of
/// length `length(j)` (j its index among the cords), its tension `T` from the static
/// balance of the body (mass matrix `mass`) in the spec's pose and its unstretched length
/// `ℓ − T/k`; the other springs stay springs. A gravity direction `up` other than the
/// spec's turns the cords with it: the body rests tilted from the spec's drawing (a centre
/// of mass off the cords' centroid stretches them unequally), so the cords, vertical in
/// the room, lean in the body's axes and their axial stiffness turns with them, coupling
/// bounce and sway (`Rᵀ k R − k`, of order ψ·k). The balance is the elastic solution
/// `T = K_d Aᵀ w` of `A T = W` (A the cords' unit wrenches, W the weight's, K_d their
/// stiffnesses): the small rigid displacement `w` that loads them, least squares where
/// the spec's pose is not quite an equilibrium (the hanging equilibrium then moves the
/// body there). `None` when the set-up has cords of its own, no axial spring, or a cord
/// would be slack.
pub fn axial_spring_cords(
    spec: &CampaignSpec,
    i: usize,
    mass: &Mat6,
    g: f64,
    up: &Vec3,
    length: impl Fn(usize) -> f64,
) -> Option<(Vec<AnchoredCord>, Vec<crate::suspension::Spring>)> {
    if !spec.setups[i].cords.is_empty() {
        return None;
    }
    // The springs are classified against the spec's vertical; a gravity direction `up`
    // tilted from it is the body resting tilted from the spec's drawing, so the cords,
    // anchored in space, turn with it in the body's axes (rotation from the spec's up to
    // `up`).
    let spec_up = spec.up_vector();
    let turn = nalgebra::Rotation3::rotation_between(&spec_up, up)
        .map(|r| r.into_inner())
        .unwrap_or_else(Mat3::identity);
    let mut cords: Vec<(Vec3, Vec3, f64)> = Vec::new();
    let mut springs = Vec::new();
    for s in spec.plain_springs(i) {
        match axial_spring(&s.stiffness, &spec_up) {
            Some((e, k)) if e.dot(&spec_up) > 0.5 => {
                cords.push((s.at, turn * e, k));
            }
            _ => springs.push(s),
        }
    }
    if cords.is_empty() {
        return None;
    }
    let mm = MassMatrix6(*mass);
    let (m, c) = (mm.mass(), mm.com());
    let wrench = |f: &Vec3, a: &Vec3| -> Vec6 { rigid_transform(a).transpose() * f };
    let a = nalgebra::DMatrix::from_fn(6, cords.len(), |r, j| wrench(&cords[j].1, &cords[j].0)[r]);
    let kd = nalgebra::DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(
        cords.len(),
        cords.iter().map(|x| x.2),
    ));
    let w_load = wrench(&(m * g * up), &c);
    let b = nalgebra::DVector::from_column_slice(w_load.as_slice());
    let akat = &a * &kd * a.transpose();
    let tol = 1e-12 * akat.norm();
    let w = akat.svd(true, true).solve(&b, tol).ok()?;
    let t = &kd * a.transpose() * w;
    if t.iter().any(|ti| !(*ti > 0.0)) {
        return None;
    }
    let anchored = cords
        .iter()
        .enumerate()
        .map(|(j, (at, e, k))| {
            let l = length(j);
            AnchoredCord {
                at: *at,
                anchor: at + e * l,
                axial_stiffness: *k,
                unstretched_length: l - t[j] / k,
            }
        })
        .collect();
    Some((anchored, springs))
}

/// How many of set-up `i`'s springs are cords written as axial springs
/// ([`axial_spring_cords`] for the spec's body, vertical and standard gravity).
pub fn axial_cord_count(spec: &CampaignSpec, i: usize) -> usize {
    axial_spring_cords(
        spec,
        i,
        &spec.properties().mass_matrix().0,
        STANDARD_GRAVITY,
        &spec.up_vector(),
        |_| 1.0,
    )
    .map_or(0, |(c, _)| c.len())
}

impl GravityStiffness {
    fn up(&self) -> Vec3 {
        Vec3::from(self.up)
    }
    fn lengths(&self, n: usize) -> Vec<f64> {
        per_item(&self.cord_length_m, n)
    }
    fn applies_to(&self, setup: &str) -> bool {
        self.setup.as_ref().is_none_or(|id| id == setup)
    }
    /// The cords of set-up `i` with the effect's unstretched lengths where given.
    pub fn hanging_cords(&self, spec: &CampaignSpec, i: usize) -> Vec<AnchoredCord> {
        let mut cords = spec.cords(i);
        if !self.unstretched_length_m.is_empty() {
            let l0 = per_item(&self.unstretched_length_m, cords.len());
            for (c, l) in cords.iter_mut().zip(l0) {
                c.unstretched_length = l;
            }
        }
        cords
    }
}

/// Checks the weight of a hanging body's effect: `g_m_per_s2` positive (`why`, when not
/// empty, says what needs it, after a space) and `up` a unit vector.
pub(crate) fn check_weight(g_m_per_s2: f64, up: [f64; 3], why: &str) -> Result<(), String> {
    if !(g_m_per_s2.is_finite() && g_m_per_s2 > 0.0) {
        return Err(format!(
            "g_m_per_s2 must be positive{why}, got {g_m_per_s2}"
        ));
    }
    super::check_unit_vector("up", up)
}

/// `v` for `n` items: itself, or its single value repeated.
fn per_item(v: &[f64], n: usize) -> Vec<f64> {
    if v.len() == 1 {
        vec![v[0]; n]
    } else {
        v.to_vec()
    }
}

impl GravityStiffness {
    /// The catalogue id (the spec's `id = "gravity_stiffness"`).
    pub const ID: &'static str = "gravity_stiffness";
}

impl Effect for GravityStiffness {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        let mut p = super::list_info("cord_length_m", "m", self.cord_length_m.len(), (0.2, 3.0));
        p.extend(super::list_info(
            "unstretched_length_m",
            "m",
            self.unstretched_length_m.len(),
            (0.2, 3.0),
        ));
        p
    }
    fn values(&self) -> Vec<f64> {
        let mut v = self.cord_length_m.clone();
        v.extend_from_slice(&self.unstretched_length_m);
        v
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let (nc, nu) = (self.cord_length_m.len(), self.unstretched_length_m.len());
        let values = super::replace_list(nc + nu, values)?;
        let e = GravityStiffness {
            cord_length_m: values[..nc].to_vec(),
            unstretched_length_m: values[nc..].to_vec(),
            ..self.clone()
        };
        super::checked(e)
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn check_values(&self) -> Result<(), String> {
        for (name, v) in [
            ("cord_length_m", &self.cord_length_m),
            ("unstretched_length_m", &self.unstretched_length_m),
        ] {
            if let Some(l) = v.iter().find(|l| !(l.is_finite() && **l > 0.0)) {
                return Err(format!(
                    "{name}: lengths must be positive and finite, got {l}"
                ));
            }
        }
        if !self.spring_turn_fraction.is_finite() {
            return Err(format!(
                "spring_turn_fraction must be finite, got {}",
                self.spring_turn_fraction
            ));
        }
        check_weight(self.g_m_per_s2, self.up, "")
    }
    fn check(&self, spec: &CampaignSpec) -> Result<(), String> {
        self.check_values()?;
        super::check_setup(spec, self.setup.as_deref())?;
        for (i, s) in spec.setups.iter().enumerate() {
            if !self.applies_to(&s.id) {
                continue;
            }
            if s.cords.is_empty() {
                let n_axial = axial_cord_count(spec, i);
                let nu = per_item(&self.unstretched_length_m, n_axial).len();
                if nu != 0 && nu != n_axial {
                    return Err(format!(
                        "unstretched_length_m has {nu} lengths but set-up '{}' (setup[{i}]) has {n_axial} cords written as axial springs",
                        s.id
                    ));
                }
                let n = self.lengths(s.springs.len()).len();
                if n != s.springs.len() {
                    return Err(format!(
                        "cord_length_m has {n} lengths but set-up '{}' (setup[{i}]) has {} springs{}",
                        s.id,
                        s.springs.len(),
                        if n == 0 { ": give one length per spring or one for all" } else { "" }
                    ));
                }
            } else {
                let n = per_item(&self.unstretched_length_m, s.cords.len()).len();
                if n != 0 && n != s.cords.len() {
                    return Err(format!(
                        "unstretched_length_m has {n} lengths but set-up '{}' (setup[{i}]) has {} cords",
                        s.id,
                        s.cords.len()
                    ));
                }
            }
        }
        Ok(())
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        if !self.applies_to(&model.setup) {
            return Ok(());
        }
        let up = self.up();
        if !ctx.spec.setups[ctx.setup_index].cords.is_empty() {
            // The hanging body: the set-up's stiffness (springs, cords as axial springs
            // at the reference pose) is replaced by the Hessian at equilibrium.
            let eq = hanging_equilibrium(
                &model.mass,
                &self.hanging_cords(ctx.spec, ctx.setup_index),
                &ctx.spec.plain_springs(ctx.setup_index),
                self.g_m_per_s2,
                &up,
            )
            .map_err(|e| format!("set-up '{}': {e}", model.setup))?;
            model.stiffness += eq.stiffness - ctx.spec.setup_stiffness(ctx.setup_index);
            model.stiffness = (model.stiffness + model.stiffness.transpose()) / 2.0;
            return Ok(());
        }
        let lengths = self.lengths(ctx.spec.springs(ctx.setup_index).len());
        if let Some((mut cords, springs)) = axial_spring_cords(
            ctx.spec,
            ctx.setup_index,
            &model.mass,
            self.g_m_per_s2,
            &up,
            |j| lengths.get(j).copied().unwrap_or(lengths[0]),
        ) {
            // Cords written as axial springs: the body hangs on them (at the given free
            // lengths, else in the drawn pose).
            if !self.unstretched_length_m.is_empty() {
                let l0 = per_item(&self.unstretched_length_m, cords.len());
                for (c, l) in cords.iter_mut().zip(l0) {
                    c.unstretched_length = l;
                }
            }
            let eq = hanging_equilibrium(&model.mass, &cords, &springs, self.g_m_per_s2, &up)
                .map_err(|e| format!("set-up '{}': {e}", model.setup))?;
            model.stiffness += eq.stiffness - ctx.spec.setup_stiffness(ctx.setup_index);
            model.stiffness = (model.stiffness + model.stiffness.transpose()) / 2.0;
            return Ok(());
        }
        let springs = ctx.spec.springs(ctx.setup_index);
        let cords: Vec<Cord> = springs
            .iter()
            .zip(self.lengths(springs.len()))
            .map(|(s, l)| Cord {
                at: s.at,
                length: l,
                axial_stiffness: (up.transpose() * s.stiffness * up)[0],
            })
            .collect();
        // Springs with no stiffness along `up` (side springs) hold no weight: not cords.
        let kmax = cords.iter().map(|c| c.axial_stiffness).fold(0.0, f64::max);
        let cords: Vec<Cord> = cords
            .into_iter()
            .filter(|c| c.axial_stiffness > 1e-9 * kmax)
            .collect();
        if cords.is_empty() {
            return Err(format!(
                "set-up '{}': no spring has stiffness along `up`, so none can be a cord",
                model.setup
            ));
        }
        let (k, _) = geometric_stiffness(&model.mass, &cords, self.g_m_per_s2, &up)
            .map_err(|e| format!("set-up '{}': {e}", model.setup))?;
        model.stiffness += k;
        if self.spring_turn_fraction != 0.0 {
            model.stiffness += self.turned_springs(ctx, model, &cords, &up)?;
            model.stiffness = (model.stiffness + model.stiffness.transpose()) / 2.0;
        }
        Ok(())
    }
}

impl GravityStiffness {
    /// The springs' turn with the sagged body ([`Self::spring_turn_fraction`] s):
    /// s × [`springs_turn`], against the load term of `cords` (their geometric stiffness
    /// as ℓ → ∞).
    fn turned_springs(
        &self,
        ctx: &BuildContext,
        model: &DynamicModel,
        cords: &[Cord],
        up: &Vec3,
    ) -> Result<Mat6, String> {
        let far: Vec<Cord> = cords.iter().map(|c| Cord { length: 1e12, ..*c }).collect();
        let (load, _) = geometric_stiffness(&model.mass, &far, self.g_m_per_s2, up)
            .map_err(|e| format!("set-up '{}': {e}", model.setup))?;
        let turn = springs_turn(
            ctx.spec,
            ctx.setup_index,
            &model.mass,
            self.g_m_per_s2,
            up,
            &load,
        )?;
        Ok(turn * self.spring_turn_fraction)
    }
}

/// Set-up `i`'s springs turning with the sagged body, as linear springs to the ground
/// do, in place of the cords' load term `load`: `K_sagged − K_spec − K_load`, with
/// `K_sagged` the Hessian of the body (mass matrix `mass`) hanging on the set-up under
/// gravity `g` along `−up`. Shared by the catalogue effect (`spring_turn_fraction`) and
/// the model check's gravity form (φ₅), so the improved spec is the fitted model.
pub(crate) fn springs_turn(
    spec: &CampaignSpec,
    i: usize,
    mass: &Mat6,
    g: f64,
    up: &Vec3,
    load: &Mat6,
) -> Result<Mat6, String> {
    let eq =
        hanging_equilibrium(mass, &spec.cords(i), &spec.plain_springs(i), g, up).map_err(|e| {
            format!(
                "set-up '{}': the springs turning with the body: {e}",
                spec.setups[i].id
            )
        })?;
    Ok(eq.stiffness - spec.setup_stiffness(i) - load)
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// [`super::EffectDescriptor::parse`] of `gravity_stiffness`: the table, checked.
fn parse_gravity_stiffness(spec: &crate::spec::EffectSpec) -> Result<Box<dyn Effect>, String> {
    let g: GravityStiffness = super::params(spec)?;
    g.check_values()?;
    Ok(Box::new(g))
}

/// Plausible: cords 5 cm to 10 m long (a laboratory's ceiling). Springs that are not
/// cords (a set-up of three-axis springs, read as vertical cords of length
/// `cord_length_m`) 5 cm and up, without end: a point spring to the ground has no
/// pendulum term at all (ℓ → ∞, only the load term is left), and the hardware between
/// the body and a coil spring's top is not a cord a tester measures.
fn plausible_gravity(
    entry: &crate::spec::EffectSpec,
    spec: &CampaignSpec,
) -> Result<Vec<super::Plausible>, String> {
    let e: GravityStiffness = super::params(entry)?;
    let longest_m = if only_three_axis_springs(spec, e.setup.as_deref()) {
        f64::INFINITY
    } else {
        10.0
    };
    let spring_lengths = e.cord_length_m.iter().map(|l| (*l, [0.05, longest_m]));
    let free_lengths = e.unstretched_length_m.iter().map(|l| (*l, [0.05, 10.0]));
    Ok(spring_lengths
        .chain(free_lengths)
        .enumerate()
        .map(|(i, (l, range))| super::Plausible::new(format!("cord {i}: length"), "m", l, range))
        .collect())
}

/// Set-up `i` hangs on springs that are neither cords (`[[setup.cord]]`) nor cords
/// written as axial springs ([`axial_cord_count`]): three-axis springs, which the
/// catalogue reads as vertical cords of a length no tester measured.
pub(crate) fn on_three_axis_springs(spec: &CampaignSpec, i: usize) -> bool {
    let s = &spec.setups[i];
    s.cords.is_empty() && !s.springs.is_empty() && axial_cord_count(spec, i) == 0
}

/// Every set-up the effect acts on (`setup`, or all) hangs on three-axis springs
/// ([`on_three_axis_springs`]).
fn only_three_axis_springs(spec: &CampaignSpec, setup: Option<&str>) -> bool {
    let mut acted_on = (0..spec.setups.len())
        .filter(|&i| setup.is_none_or(|id| id == spec.setups[i].id))
        .peekable();
    acted_on.peek().is_some() && acted_on.all(|i| on_three_axis_springs(spec, i))
}

/// This module's effects in the physics catalogue ([`super::registry`]).
pub(crate) const DESCRIPTORS: &[super::EffectDescriptor] = &[
    super::EffectDescriptor {
        id: GravityStiffness::ID,
        rank: 0,
        title: "gravity (pendulum) stiffness of the suspension",
        reveal: "a second suspension length, or the measured cord geometry",
        docs: "E1: the pendulum (geometric) stiffness of cords, each spring read as a vertical cord of length `cord_length_m` (axial springs, as cords are written: cords along their axes, tensions from the static balance, or their free lengths `unstretched_length_m`), or the set-up's cords hanging at their static equilibrium; on springs read as cords, `spring_turn_fraction` s (default 0) adds s times the springs' turn with the sagged body (their exact Hessian at the sagged equilibrium less the spec's springs and the cords' load term): a body on three-axis springs to the ground is s = 1 with ℓ → ∞, as the model check fits it and writes it in the improved spec",
        parse: parse_gravity_stiffness,
        neutral: super::NeutralForm::Screened(super::screening::Screened {
            rank: 1,
            form: screening::screen_gravity,
        }),
        follows_spec_up: true,
        repeatable: false,
        example: include_str!("../../../../fixtures/specs/effects/gravity_stiffness.toml"),
        plausible: Some(plausible_gravity),
    },
];
