"""Linear dynamics about the equilibrium by state-space eigen-decomposition.

Model about O in body axes: M q̈ + C q̇ + (K + i D) q = Q (D = hysteretic loss, used only in
the frequency domain). The receptance between generalised coordinates is written in
pole–residue form

    G(s) = Σ_r R_r / (s − λ_r)  +  P / s²,

where the first sum runs over all 2n state-space poles (for a real system they come in
conjugate pairs, so this is the usual "Σ_r ψ_r ψ_rᵀ/(s − λ_r) + conj") and P = Φ₀ Φ₀ᵀ is
the mass-line term of the free rigid directions (Φ₀: M-orthonormal basis of the
directions with neither stiffness nor damping). A measured FRF is evaluated at
s = iω (no window) or s = iω + 1/τ (exponential window e^{−t/τ} on the response: the
transform of h(t) e^{−t/τ} is H(iω + 1/τ), i.e. every pole moves λ_r → λ_r − 1/τ).

Route (independent of a direct solve of (K + iωC − ω²M)⁻¹):
 1. undamped modes of (K, M) by a symmetric-definite eigensolver; modes with
    ω² ≤ FREE_TOLERANCE·max ω² are free; if C and D vanish on them they are split off
    exactly as P/s² (they are M-orthogonal to the rest and K, C, D do not couple them);
 2. the rest in M-orthonormal coordinates b (q = Φ₁ b, so the mass is I) in first-order
    form ż = A z, z = [b; ḃ], A = [[0, I], [−(K_b + iD_b), −C_b]];
 3. A = V Λ V⁻¹ (complex eigen-decomposition); then
    G_b(s) = [I 0](sI − A)⁻¹[0; I] = Σ_r V[:n, r] (V⁻¹)[r, n:] / (s − λ_r)
    — the left eigenvectors come from V⁻¹, which stays valid for repeated roots (where
    the symmetric normalisation ψᵀ[[C, M], [M, 0]]ψ = 1 needs an extra orthogonalisation).
"""
import numpy as np

from .rigid import point_map

FREE_TOLERANCE = 1e-9
"""A mode with ω² ≤ FREE_TOLERANCE·max ω² (or all modes when K = 0) is a free direction.
The finite-difference stiffness is accurate to ~1e-12 relative, so a truly free direction
comes out at |ω²| ≲ 1e-11·max ω²; a real suspension mode 3·10⁴ times below the highest one
in frequency would be misread as free (none of the cases of interest comes close)."""


def undamped_modes(k, m):
    """ω² (ascending) and M-orthonormal shapes of (K, M) (Cholesky M = L Lᵀ, symmetric
    eigenproblem of L⁻¹ K L⁻ᵀ); raises on a negative stiffness."""
    ell = np.linalg.cholesky(m)
    a = np.linalg.solve(ell, np.linalg.solve(ell, k).T)
    w2, y = np.linalg.eigh(0.5 * (a + a.T))
    phi = np.linalg.solve(ell.T, y)
    top = max(np.abs(w2).max(), 0.0)
    if top > 0 and w2[0] < -FREE_TOLERANCE * top:
        raise ValueError(f"unstable equilibrium: negative stiffness (ω² = {w2[0]:.4e} rad²/s²)")
    return w2, phi


def modal_damping(m, w2, phi, ratios):
    """C = M Φ diag(2 ζ_r ω_r) Φᵀ M over the elastic-support modes (free modes get none).
    A free mode is one with ω² ≤ FREE_TOLERANCE of the largest, as in `Terms`: its ω²
    comes out of the eigen-solver as ±1e-18 of rounding, and a damping 2ζ√ω² built on
    that would make it a (barely) damped mode, which the split then keeps in the state
    space."""
    c = np.zeros_like(m)
    floor = FREE_TOLERANCE * max(np.abs(w2).max(), 0.0)
    for r in range(len(w2)):
        if w2[r] > floor:
            mp = m @ phi[:, r]
            c += 2.0 * ratios[r] * np.sqrt(w2[r]) * np.outer(mp, mp)
    return 0.5 * (c + c.T)


def dashpot_damping(dashpots, r_eq, origin):
    """Σ T(p − O)ᵀ R_eqᵀ C_i R_eq T(p − O): point dashpots to ground, C_i (3×3, symmetric
    PSD) in space axes, acting on the velocity of body point p."""
    c = np.zeros((6, 6))
    for p, ci in dashpots:
        t = r_eq.T @ np.asarray(ci, float) @ r_eq
        tp = point_map(np.asarray(p, float) - origin)
        c += tp.T @ t @ tp
    return 0.5 * (c + c.T)


class PoleResidueModel:
    """G(s) = Σ_r φ_r w_rᵀ/(s − λ_r) + P/s² between generalised coordinates (6×6)."""

    def __init__(self, poles, left, right, free):
        self.poles = poles          # (2n,) complex λ_r
        self.left = left            # (6, 2n): column r is the response side of R_r
        self.right = right          # (2n, 6): row r is the force side of R_r
        self.free = free            # (6, 6) real P = Φ₀Φ₀ᵀ
        self.n_free = 0

    @classmethod
    def build(cls, m, c, k, d=None):
        d = np.zeros_like(k) if d is None else d
        w2, phi = undamped_modes(k, m)
        top = np.abs(w2).max()
        free = w2 <= FREE_TOLERANCE * top if top > 0 else np.ones(len(w2), bool)
        phi0, phi1 = phi[:, free], phi[:, ~free]
        if free.any():
            # Within the free subspace, the combinations that C and D do not touch
            # (C, D PSD: φᵀ(C + D)φ = 0 ⇒ Cφ = Dφ = 0) are split off exactly; free but
            # damped combinations (a dashpot to ground) stay in the state space.
            cd = phi0.T @ (c + d) @ phi0
            ev, u = np.linalg.eigh(0.5 * (cd + cd.T))
            scale = max(np.abs(phi.T @ (c + d) @ phi).max(), 1e-300)
            undamped = ev <= 1e-12 * scale
            phi1 = np.hstack([phi1, phi0 @ u[:, ~undamped]])
            phi0 = phi0 @ u[:, undamped]
            free = np.zeros(len(w2), bool)
            free[:phi0.shape[1]] = True
        n = phi1.shape[1]
        if n:
            kb = phi1.T @ (k + 1j * d) @ phi1
            cb = phi1.T @ c @ phi1
            a = np.zeros((2 * n, 2 * n), complex)
            a[:n, n:] = np.eye(n)
            a[n:, :n] = -kb
            a[n:, n:] = -cb
            lam, v = np.linalg.eig(a)
            cond = np.linalg.cond(v)
            if not np.isfinite(cond) or cond > 1e10:
                raise ValueError(
                    f"state matrix nearly defective (eigenvector condition {cond:.2e}): "
                    "critically damped or repeated roots with coupled damping")
            w = np.linalg.solve(v, np.eye(2 * n))
            order = np.lexsort((lam.real, np.abs(lam.imag), np.abs(lam)))
            lam, v, w = lam[order], v[:, order], w[order, :]
            left = phi1 @ v[:n, :]
            right = w[:, n:] @ phi1.T
        else:
            lam = np.zeros(0, complex)
            left = np.zeros((6, 0), complex)
            right = np.zeros((0, 6), complex)
        model = cls(lam, left, right, phi0 @ phi0.T)
        model.n_free = int(free.sum())
        model.undamped_w2 = w2
        model.undamped_shapes = phi
        return model

    def compliance(self, s):
        """G(s) (6×6) at one complex s (for checks)."""
        g = (self.left / (s - self.poles)) @ self.right
        return g + self.free / s ** 2

    def rigid_poles(self):
        """Poles with Im λ ≥ 0 (one of each conjugate pair; real poles kept), as
        (frequency_hz = |λ|/2π, damping ratio = −Re λ/|λ|, λ)."""
        out = []
        for lam in self.poles:
            if lam.imag >= -1e-12 * abs(lam):
                a = abs(lam)
                out.append((a / (2 * np.pi), -lam.real / a if a > 0 else 0.0, lam))
        return out


def modal_terms_for(model, rows, cols):
    """Scalar pole–residue terms for channel rows S (n_ch×6) and force columns F (6×n_ex):
    residues ρ[c, e, r] = (S φ_r)(w_rᵀ F) as (S·left (n_ch×2n), right·F (2n×n_ex)),
    and the free term S P F (n_ch×n_ex)."""
    return rows @ model.left, model.right @ cols, rows @ model.free @ cols


def evaluate(poles, lres, rres, free, extra, s):
    """H[e, c, l] = Σ_r lres[c,r] rres[r,e]/(s_l − λ_r) + free[c,e]/s_l² + extra terms.
    `extra`: list of (pole, residue[c, e]) added the same way (elastic modes)."""
    inv = 1.0 / (s[None, :] - poles[:, None])                # (2n, L)
    h = np.einsum("cr,re,rl->ecl", lres, rres, inv, optimize=True)
    if np.any(free != 0):
        h += free.T[:, :, None] / (s ** 2)[None, None, :]
    for lam, res in extra:
        h += res.T[:, :, None] / (s - lam)[None, None, :]
    return h


def truncation_correction(poles, lres, rres, free, extra, s, k, record):
    """What a finite record [0, T] removes from s^k H(s): the transform of the tail t > T,
    for the impulse response of Σ ρ_r/(s − λ_r) + P/s² observed as its k-th derivative:
    Σ_r ρ_r λ_r^k e^{(λ_r − s)T}/(s − λ_r) + P·{e^{−sT}(1 + sT)/s², e^{−sT}/s, 0} for
    k = 0, 1, 2 (the polynomial part of s^k/(s − λ) is an impulse at t = 0, inside the
    record). Returns [e, c, l]."""
    lam = np.concatenate([poles, np.array([m for m, _ in extra], complex)])
    e = np.exp((lam[:, None] - s[None, :]) * record) * lam[:, None] ** k / (s[None, :] - lam[:, None])
    h = np.einsum("cr,re,rl->ecl", lres, rres, e[:len(poles)], optimize=True)
    for j, (_, res) in enumerate(extra):
        h += res.T[:, :, None] * e[len(poles) + j][None, None, :]
    if np.any(free != 0) and k < 2:
        tail = np.exp(-s * record) * ((1 + s * record) / s ** 2 if k == 0 else 1 / s)
        h += free.T[:, :, None] * tail[None, None, :]
    return h
