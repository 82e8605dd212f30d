"""Rigid-body kinematics and inertia: skew matrices, finite rotations, the point map T(p)
and the 6×6 mass matrix about a reference point.

Conventions (the project's, see docs/conventions.md of rbprops and its README):
small rigid motion about a point O is q = [u_O; θ]; a body point p moves by
T(p − O) q with T(r) = [I | −[r]×]; the mass matrix about O is
M0 = [[m I, −m[c]×], [m[c]×, J + m(|c|² I − c cᵀ)]] with c the CoM relative to O and J
the inertia tensor about the CoM.
"""
import numpy as np


def skew(v):
    """[v]×, the matrix with [v]× w = v × w."""
    x, y, z = v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def _rot_coeffs(theta):
    """(sin t/t, (1 − cos t)/t², (t − sin t)/t³) for t = |θ|, by series near 0 (no
    cancellation: the series are used below t = 1e-3 where their truncation is < 1e-19)."""
    t2 = float(np.dot(theta, theta))
    if t2 < 1e-6:
        a = 1.0 - t2 / 6.0 + t2 * t2 / 120.0
        b = 0.5 - t2 / 24.0 + t2 * t2 / 720.0
        c = 1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0
        return a, b, c
    t = np.sqrt(t2)
    return np.sin(t) / t, (1.0 - np.cos(t)) / t2, (t - np.sin(t)) / (t2 * t)


def rotation(theta):
    """Rodrigues' formula: exp([θ]×) = I + (sin t/t)[θ]× + ((1 − cos t)/t²)[θ]×²."""
    a, b, _ = _rot_coeffs(theta)
    k = skew(theta)
    return np.eye(3) + a * k + b * (k @ k)


def right_jacobian(theta):
    """J_r(θ) with exp([θ + dθ]×) = exp([θ]×) exp([J_r(θ) dθ]×) + O(dθ²):
    J_r = I − ((1 − cos t)/t²)[θ]× + ((t − sin t)/t³)[θ]×²."""
    _, b, c = _rot_coeffs(theta)
    k = skew(theta)
    return np.eye(3) - b * k + c * (k @ k)


def rotation_vector(r):
    """Inverse of `rotation` for a proper rotation matrix (angle < π)."""
    cos_t = np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0)
    w = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]]) / 2.0
    s = np.linalg.norm(w)
    t = np.arctan2(s, cos_t)
    if s < 1e-12:
        return w  # t ≈ s: first order is exact to rounding here
    return w * (t / s)


def point_map(r):
    """T(r) = [I | −[r]×] (3×6): displacement of the body point at r from O."""
    return np.hstack([np.eye(3), -skew(r)])


def mass_matrix(mass, com, inertia_cm, origin=(0.0, 0.0, 0.0)):
    """M0 about `origin` from the mass, the CoM and the inertia tensor about the CoM."""
    c = np.asarray(com, float) - np.asarray(origin, float)
    m0 = np.zeros((6, 6))
    m0[:3, :3] = mass * np.eye(3)
    m0[:3, 3:] = -mass * skew(c)
    m0[3:, :3] = mass * skew(c)
    m0[3:, 3:] = np.asarray(inertia_cm, float) + mass * (c @ c * np.eye(3) - np.outer(c, c))
    return m0


def cloud_properties(points, masses):
    """Exact mass, CoM and inertia tensor about the CoM of point masses:
    m = Σ m_i, c = Σ m_i p_i / m, J = Σ m_i (|r_i|² I − r_i r_iᵀ), r_i = p_i − c."""
    p = np.asarray(points, float).reshape(-1, 3)
    w = np.asarray(masses, float).reshape(-1)
    m = float(w.sum())
    c = (w[:, None] * p).sum(axis=0) / m
    r = p - c
    j = np.einsum("i,i->", w, (r * r).sum(axis=1)) * np.eye(3) - np.einsum("i,ij,ik->jk", w, r, r)
    return m, c, j


def cloud_mass_matrix(points, masses, origin=(0.0, 0.0, 0.0)):
    """M = Σ m_i T(p_i − O)ᵀ T(p_i − O): the kinetic energy ½ Σ m_i |ẋ_i|² of the cloud
    in the coordinates q (independent of the M0 formula; used to test it)."""
    o = np.asarray(origin, float)
    m = np.zeros((6, 6))
    for p, w in zip(np.asarray(points, float).reshape(-1, 3), np.asarray(masses, float).reshape(-1)):
        t = point_map(p - o)
        m += w * t.T @ t
    return m


def combine(parts):
    """Mass, CoM, inertia about the CoM of rigidly joined parts, each (m, c, J about its
    own CoM); parallel-axis theorem."""
    m = sum(p[0] for p in parts)
    c = sum(p[0] * np.asarray(p[1], float) for p in parts) / m
    j = np.zeros((3, 3))
    for mi, ci, ji in parts:
        r = np.asarray(ci, float) - c
        j += np.asarray(ji, float) + mi * (r @ r * np.eye(3) - np.outer(r, r))
    return m, c, j


def tensor_from_moments(moments, products):
    """Inertia tensor from moments (Jxx, Jyy, Jzz) and CAD products
    (xy, xz, yz) = ∫xy dm etc.; the tensor's off-diagonal entries are minus the products."""
    jxx, jyy, jzz = moments
    pxy, pxz, pyz = products
    return np.array([[jxx, -pxy, -pxz], [-pxy, jyy, -pyz], [-pxz, -pyz, jzz]], float)
