"""Suspension of a rigid body by its potential energy, with finite rotations.

The body's pose is (X, R): the body point p (geometry-frame coordinates, fixed to the
body) sits at x(p) = X + R (p − O) in space, O being the reference point (the geometry
origin unless told otherwise). The reference pose X = O, R = I is the geometry as given.

Potential energy V(pose):
  - point springs:  ½ (x(p) − a)ᵀ K (x(p) − a), anchor a fixed in space, 3×3 K in space axes
    (a defaults to the attachment's reference position, so the spring is unloaded there);
  - elastic cords:  ½ k (|a − x(p)| − L0)² when taut (|a − x(p)| > L0), 0 when slack;
  - rotational mounts: ½ ψᵀ K_r ψ, ψ the rotation vector of R (the body's rotation from the
    reference pose, space axes): bending/torsion of a clamped cord end or a rubber mount;
  - gravity:        m g up·x(c), c the CoM of the mass model (body plus attached sensors).

Perturbations about a pose P0 = (X0, R0) use the chart
  x(p; q) = X0 + R0 δu + R0 exp([θ]×) (p − O),    q = (δu, θ) in BODY axes,
so that to first order a body point moves by R0 T(p − O) q: q is the project's small
rigid motion about O, in the body's own (geometry) frame. At an equilibrium the gradient
of V in this chart vanishes and its Hessian is the tangent stiffness about O in body axes,
symmetric by construction (the Hessian of a scalar in a fixed chart), with no spurious
"torque × rotation" term: the chart is re-centred at the equilibrium pose rather than
using the absolute rotation vector of R_eq, whose Hessian at a loaded pose would mix the
load with the parametrisation.

The gradient is analytic (∂x/∂δu = R0, ∂x/∂θ = −R0 E [r]× J_r(θ)); the Hessian is central
differences of it with Richardson extrapolation (see `stiffness`).
"""
import numpy as np

from .rigid import right_jacobian, rotation, rotation_vector

FD_STEP = 1e-4
"""Relative step of the finite-difference Hessian: h_θ = FD_STEP rad, h_u = FD_STEP·L with
L the largest distance of an attachment point from O (at least 1 cm). Central differences
of the analytic gradient have truncation error (h/ℓ)²·|K| (ℓ: the shortest geometric
length, cord length or lever); one Richardson step (h and h/2) makes it (h/ℓ)⁴, ≈ 1e-16
relative for ℓ ≥ L; the rounding error is ≈ ε·F·L/h, F the largest preload force, i.e.
about 1e-12 relative to the stiffness. Measured against exact Hessians in test_rbref.py."""


class Suspension:
    """The potential energy of one set-up and the body's mass model for gravity."""

    def __init__(self, springs, cords, mass, com, gravity, up, origin=(0.0, 0.0, 0.0), rotational=()):
        # springs: list of (at, anchor, K); cords: list of (at, anchor, L0, k)
        self.springs = [(np.asarray(p, float), np.asarray(a, float), np.asarray(k, float))
                        for p, a, k in springs]
        self.cords = [(np.asarray(p, float), np.asarray(a, float), float(l0), float(k))
                      for p, a, l0, k in cords]
        self.mass = float(mass)
        self.com = np.asarray(com, float)
        self.g = float(gravity)
        self.up = np.asarray(up, float) / np.linalg.norm(up)
        self.origin = np.asarray(origin, float)
        self.rotational = sum((np.asarray(k, float) for k in rotational), np.zeros((3, 3)))
        pts = [s[0] for s in self.springs] + [c[0] for c in self.cords] + [self.com]
        self.length_scale = max(0.01, max(np.linalg.norm(p - self.origin) for p in pts))

    # --- the energy ------------------------------------------------------------------
    def _terms(self, x_of):
        """(V, [(body point, ∇_x V)]) for a map body point → space position."""
        v = 0.0
        grads = []
        for p, a, k in self.springs:
            d = x_of(p) - a
            f = k @ d
            v += 0.5 * d @ f
            grads.append((p, f))
        for p, a, l0, k in self.cords:
            d = a - x_of(p)
            ell = np.linalg.norm(d)
            if ell > l0:
                v += 0.5 * k * (ell - l0) ** 2
                grads.append((p, -k * (ell - l0) * d / ell))
        if self.g != 0.0:
            v += self.mass * self.g * (self.up @ x_of(self.com))
            grads.append((self.com, self.mass * self.g * self.up))
        return v, grads

    def energy(self, pose, q=np.zeros(6)):
        """V at the pose P0 = (X0, R0) perturbed by q in the chart above."""
        x0, r0 = pose
        e = rotation(q[3:])
        t = x0 + r0 @ q[:3]
        v = self._terms(lambda p: t + r0 @ (e @ (p - self.origin)))[0]
        if self.rotational.any():
            psi = rotation_vector(r0 @ e)
            v += 0.5 * psi @ self.rotational @ psi
        return v

    def gradient(self, pose, q=np.zeros(6)):
        """∂V/∂q in the chart about `pose`: g_u = R0ᵀ Σ ∇V, g_θ = J_rᵀ Σ (r × Eᵀ R0ᵀ ∇V)."""
        x0, r0 = pose
        e = rotation(q[3:])
        t = x0 + r0 @ q[:3]
        _, grads = self._terms(lambda p: t + r0 @ (e @ (p - self.origin)))
        gu = np.zeros(3)
        gt = np.zeros(3)
        for p, f in grads:
            fb = r0.T @ f
            gu += fb
            gt += np.cross(p - self.origin, e.T @ fb)
        g_theta = right_jacobian(q[3:]).T @ gt
        if self.rotational.any():
            # ψ = log(R0 exp([θ]×)): J_r(ψ) dψ = J_r(θ) dθ, so ∂ψ/∂θ = J_r(ψ)⁻¹ J_r(θ).
            psi = rotation_vector(r0 @ e)
            dpsi = np.linalg.solve(right_jacobian(psi), right_jacobian(q[3:]))
            g_theta = g_theta + dpsi.T @ (self.rotational @ psi)
        return np.concatenate([gu, g_theta])

    def force_scale(self, pose):
        """Largest force magnitude in the energy terms at the pose (for tolerances)."""
        x0, r0 = pose
        _, grads = self._terms(lambda p: x0 + r0 @ (p - self.origin))
        torque = np.linalg.norm(self.rotational @ rotation_vector(r0)) / self.length_scale
        return max([np.linalg.norm(f) for _, f in grads] + [torque, 1e-300])

    @staticmethod
    def moved(pose, q):
        """The pose of chart point q about `pose`."""
        x0, r0 = pose
        return x0 + r0 @ q[:3], r0 @ rotation(q[3:])

    # --- tangent stiffness -------------------------------------------------------------
    def stiffness(self, pose, step=FD_STEP):
        """Hessian of V at `pose` in the chart about it: central differences of the
        analytic gradient, H_j = (g(h e_j) − g(−h e_j))/(2h), with one Richardson step
        H = (4 H(h/2) − H(h))/3; returned symmetrised, with the relative asymmetry
        before symmetrisation (a diagnostic of the difference error)."""
        hs = np.array([step * self.length_scale] * 3 + [step] * 3)

        def central(scale):
            h = np.zeros((6, 6))
            for j in range(6):
                dq = np.zeros(6)
                dq[j] = hs[j] * scale
                h[:, j] = (self.gradient(pose, dq) - self.gradient(pose, -dq)) / (2 * dq[j])
            return h

        h = (4.0 * central(0.5) - central(1.0)) / 3.0
        norm = np.abs(h).max()
        asym = np.abs(h - h.T).max() / norm if norm > 0 else 0.0
        return 0.5 * (h + h.T), asym

    def near_slack(self, pose, step=FD_STEP):
        """Indices of cords whose stretch |ℓ − L0| at the pose is within 10 finite-difference
        displacements (10·step·L): the potential is not smooth there, so neither the
        Hessian nor a linear model is meaningful."""
        x0, r0 = pose
        out = []
        for i, (p, a, l0, k) in enumerate(self.cords):
            ell = np.linalg.norm(a - (x0 + r0 @ (p - self.origin)))
            if abs(ell - l0) < 10 * step * self.length_scale:
                out.append(i)
        return out

    def cord_tensions(self, pose):
        """Tension k(|a − x| − L0)⁺ of each cord at the pose (N)."""
        x0, r0 = pose
        out = []
        for p, a, l0, k in self.cords:
            ell = np.linalg.norm(a - (x0 + r0 @ (p - self.origin)))
            out.append(max(0.0, k * (ell - l0)))
        return out

    # --- static equilibrium ------------------------------------------------------------
    def equilibrium(self, max_iter=100):
        """Newton's method on ∇V = 0 from the reference pose, re-centring the chart on each
        iterate; directions the Hessian leaves free (relative eigenvalue < 1e-9) get no step
        and must carry no load. Returns (pose, iterations). Raises ValueError when there is
        no stable equilibrium."""
        pose = (self.origin.copy(), np.eye(3))
        if self.g == 0.0 and not self.springs and not self.cords:
            return pose, 0  # only rotational mounts (or nothing), unloaded at the reference
        scale_l = self.length_scale
        wts = np.array([1.0] * 3 + [1.0 / scale_l] * 3)  # torque → force units
        for it in range(1, max_iter + 1):
            g = self.gradient(pose)
            fs = self.force_scale(pose)
            if np.max(np.abs(g * wts)) <= 1e-13 * fs:
                return pose, it - 1
            k, _ = self.stiffness(pose)
            # Solve in scaled coordinates y = q/w (rotations times L) so translations and
            # rotations weigh alike: g_y = w g, K_y = K w wᵀ, δq = w δy.
            ks = k * np.outer(wts, wts)
            w, v = np.linalg.eigh(ks)
            tol = 1e-9 * max(np.abs(w).max(), 1e-300)
            gs = g * wts
            step = np.zeros(6)
            for lam, vec in zip(w, v.T):
                comp = vec @ gs
                if abs(lam) <= tol:
                    if abs(comp) > 1e-9 * fs:
                        raise ValueError(
                            "no static equilibrium: a load (gravity or preload) acts along a "
                            "direction the suspension leaves free")
                    continue
                step -= comp / abs(lam) * vec  # |λ|: descend even where V is not convex
            dq = step * wts
            v0 = self.energy(pose)
            alpha = 1.0
            while alpha > 1e-6 and self.energy(pose, alpha * dq) > v0 + 1e-14 * max(1.0, abs(v0)) \
                    and np.max(np.abs(g * wts)) > 1e-8 * fs:
                alpha /= 2.0
            pose = self.moved(pose, alpha * dq)
            r = pose[1]
            u, _, vt = np.linalg.svd(r)  # keep R orthonormal against accumulated rounding
            pose = (pose[0], u @ vt)
        raise ValueError(f"static equilibrium not found in {max_iter} Newton iterations")
