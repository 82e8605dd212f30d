"""From a Case to FRFs and the truth.

Per set-up: the mass model (body plus sensor masses, each a point mass at its true
position), the static equilibrium of the potential energy, the tangent stiffness (Hessian),
the damping, then the pole–residue model of the set-up, and one more for each excitation
that changes the structure while it is measured (a force-gauge mass, a stinger, a drifted
suspension). Channels see
their true position and direction, times their gain, through their filters; forces act at
their true point along their true direction (body-fixed: a hammer strikes a face, so its
direction turns with the body), divided by the force gauge's gain.
"""
import numpy as np

from .case import QUANTITY_ORDER
from .dynamics import (PoleResidueModel, dashpot_damping, evaluate, modal_damping, modal_terms_for,
                       truncation_correction, undamped_modes)
from .rigid import cloud_mass_matrix, combine, mass_matrix, point_map, rotation_vector, skew
from .suspension import Suspension


class SetupModel:
    """One set-up's equilibrium (pose, Newton iterations, Hessian asymmetry), mass model,
    6×6 M, K, C, D about O in body axes, cord tensions and its pole–residue model."""


def build_setup(case, s):
    """Mass, equilibrium, stiffness and damping of set-up `s` (a dict of the Case)."""
    o = case.origin
    parts = [(case.mass, case.com, case.inertia)] + [(m, p, np.zeros((3, 3))) for p, m in case.sensor_masses]
    m_tot, c_tot, j_tot = combine(parts)
    sus = Suspension(s["springs"], s["cords"], m_tot, c_tot, case.gravity, case.up, o, s["rotational"])
    if not s["springs"] and not s["cords"]:
        if case.gravity != 0.0:
            raise ValueError(f"set-up '{s['id']}': no spring or cord: a free-free body needs gravity_m_s2 = 0")
    pose, iters = sus.equilibrium()
    slack = sus.near_slack(pose)
    if slack:
        raise ValueError(f"set-up '{s['id']}': cord(s) {slack} (0-based) are just at the point of going "
                         "slack at equilibrium: the stiffness is not defined there")
    k, asym = sus.stiffness(pose)
    if case.body_points is not None:
        # A point-cloud body: M straight from the kinetic energy ½ Σ m_i |ẋ_i|² of its
        # points and the sensor masses (equal to M0 of their m, c, J: tested).
        pts = np.vstack([case.body_points[0]] + [p[None, :] for p, _ in case.sensor_masses])
        ws = np.concatenate([case.body_points[1], [m for _, m in case.sensor_masses]])
        mm = cloud_mass_matrix(pts, ws, o)
    else:
        mm = mass_matrix(m_tot, c_tot, j_tot, o)
    w2, phi = undamped_modes(k, mm)
    if case.damping_model == "modal":
        c = modal_damping(mm, w2, phi, case.modal_ratios)
    elif case.damping_model == "proportional":
        c = case.alpha * mm + case.beta * k
    else:
        c = np.zeros((6, 6))
    c = c + dashpot_damping(s["dashpots"], pose[1], o)
    # Hysteretic loss: D = Σ_i η_i × (Hessian of element i alone at the equilibrium), so
    # element i's stiffness is k_i (1 + iη_i); gravity's geometric stiffness is lossless.
    d = np.zeros((6, 6))
    elements = [("s", x) for x in s["springs"]] + [("c", x) for x in s["cords"]]
    for (kind, el), eta in zip(elements, s["element_losses"]):
        if eta > 0:
            one = Suspension([el] if kind == "s" else [], [el] if kind == "c" else [], m_tot, c_tot, 0.0, case.up, o)
            d += eta * one.stiffness(pose)[0]
    sm = SetupModel()
    sm.id = s["id"]
    sm.pose, sm.iterations, sm.hessian_asymmetry = pose, iters, asym
    sm.mass_properties = (m_tot, c_tot, j_tot)
    sm.m, sm.k, sm.c, sm.d = mm, k, c, d
    sm.cord_tensions = sus.cord_tensions(pose)
    sm.nominal = PoleResidueModel.build(mm, c, k, d)
    return sm


def channel_rows(case):
    """Rows g·s_trueᵀ T(p_true − O) (n_ch × 6)."""
    return np.array([c["gain"] * c["true_direction"] @ point_map(c["true_position"] - case.origin)
                     for c in case.channels])


def force_column(case, e):
    return point_map(e["true_position"] - case.origin).T @ e["true_direction"]


def s_axis(case, freq):
    """Laplace variable of each line: s = iω, or iω + 1/τ with the exponential window."""
    s = 2j * np.pi * np.asarray(freq, float)
    if case.window_tau > 0:
        s = s + 1.0 / case.window_tau
    return s


def channel_filters(case, s):
    """Per channel (n_ch, L): Π_i sτ_i/(1 + sτ_i) (first-order high-pass, AC coupling of
    the transducer or the conditioner) times e^{−sδ} (a sampling delay δ). Evaluated at
    the same s as the FRF, since the window multiplies the filtered, delayed signal."""
    out = np.ones((len(case.channels), len(s)), complex)
    for ci, c in enumerate(case.channels):
        for tau in c["highpass_s"]:
            out[ci] *= s * tau / (1.0 + s * tau)
        if c["delay_s"]:
            out[ci] *= np.exp(-s * c["delay_s"])
    return out


class Terms:
    """All pole–residue terms of the campaign, per excitation:
    H_e,c(s) = s^k [Σ_r a[c,r] b[r]/(s − λ_r) + p[c]/s² + Σ_m ρ_m[c]/(s − μ_m)]."""

    def __init__(self, case):
        self.case = case
        self.setups = [build_setup(case, s) for s in case.setups]
        rows = channel_rows(case)
        self.per_exc = []
        self.gravity_exc = []
        self.models = []
        for ei, e in enumerate(case.excitations):
            sm = next(x for x in self.setups if x.id == e["setup"])
            col = force_column(case, e)[:, None]
            model = sm.nominal
            if e["gauge_mass"] > 0 or e["stinger_lateral"] > 0 or e["stinger_bending"] > 0 \
                    or e["stiffness_factor"] != 1.0:
                # Attached while this excitation is measured: the gauge's structure-side
                # mass (a point mass), and a stinger's stiffness ACROSS the force direction n
                # (lateral k_l at the point, bending k_r about the axes ⟂ n; P = I − n nᵀ):
                # K_a = k_l T(p)ᵀ P T(p) + blockdiag(0, k_r P). The stinger's axial path is
                # the gauge's and is measured, so it adds nothing.
                tp = point_map(e["true_position"] - case.origin)
                pp = np.eye(3) - np.outer(e["true_direction"], e["true_direction"])
                ka = e["stinger_lateral"] * tp.T @ pp @ tp
                ka[3:, 3:] += e["stinger_bending"] * pp
                # The suspension drifting between runs: its stiffness × f during this one
                # (damping and loss unchanged).
                model = PoleResidueModel.build(sm.m + e["gauge_mass"] * tp.T @ tp, sm.c,
                                               e["stiffness_factor"] * sm.k + ka, sm.d)
            self.models.append(model)
            # The gauge reads force_gauge_gain × the true force: H_measured = H / gain.
            col = col / e["force_gauge_gain"]
            a, b, p = modal_terms_for(model, rows, col)
            extra = []
            gains = np.array([c["gain"] for c in case.channels])
            for m in case.elastic_modes:
                if e["setup"] not in m["setups"]:
                    continue
                wm, z = 2 * np.pi * m["frequency_hz"], m["damping_ratio"]
                # 1/(s² + 2ζω_m s + ω_m²) = [1/(s − μ₊) − 1/(s − μ₋)]/(μ₊ − μ₋)
                root = np.sqrt(complex(z * z - 1.0))
                mu_p, mu_m = -z * wm + wm * root, -z * wm - wm * root
                res = gains * m["at_channels"] * m["at_excitations"][ei] / e["force_gauge_gain"]
                extra.append((mu_p, (res / (mu_p - mu_m))[:, None]))
                extra.append((mu_m, (-res / (mu_p - mu_m))[:, None]))
            self.per_exc.append((model.poles, a, b, p, extra))
            if case.sensor_gravity:
                # Accelerometers sense the specific force: channel c reads g sᵀ Rᵀ up, and
                # with R = R_eq exp([θ]×), Rᵀ up ≈ up_b + up_b × θ (up_b = R_eqᵀ up), so the
                # dynamic part is g sᵀ [up_b]× θ: a row [0 | g sᵀ[up_b]×] seen as s^(k−2).
                up_b = sm.pose[1].T @ case.up
                rows_g = np.array([c["gain"] * case.gravity
                                   * np.concatenate([np.zeros(3), c["true_direction"] @ skew(up_b)])
                                   for c in case.channels])
                ag, _, pg = modal_terms_for(model, rows_g, col)
                self.gravity_exc.append((ag, pg))

    def frf(self, freq):
        """H[e, c, l] in the case's quantity on the axis `freq` (Hz)."""
        s = s_axis(self.case, freq)
        if np.any(s == 0) and any(np.any(p != 0) or np.any(lam == 0) for lam, _, _, p, _ in self.per_exc):
            raise ValueError("frequency: a line at 0 Hz with free rigid directions (their FRF is "
                             "infinite there): start above 0 Hz, or use a window")
        k = QUANTITY_ORDER[self.case.quantity]
        if self.gravity_exc and k < 2 and np.any(s == 0):
            raise ValueError("frequency: sensor_gravity with a line at 0 Hz needs accelerance")
        out = np.empty((len(self.per_exc), len(self.case.channels), len(s)), complex)
        rec = self.case.record_s
        if rec and (any(c["highpass_s"] or c["delay_s"] for c in self.case.channels)
                    or any(e["delay_s"] for e in self.case.excitations)):
            raise ValueError("window.record_s with channel filters or delays is not modelled "
                             "(the filter acts before the truncation)")
        if rec and self.gravity_exc and k != 2:
            raise ValueError("window.record_s with sensor_gravity needs accelerance")
        for ei, (lam, a, b, p, extra) in enumerate(self.per_exc):
            out[ei] = evaluate(lam, a, b, p, extra, s)[0] * s ** k
            if rec:
                out[ei] -= truncation_correction(lam, a, b, p, extra, s, k, rec)[0]
            if self.gravity_exc:
                ag, pg = self.gravity_exc[ei]
                out[ei] += evaluate(lam, ag, b, pg, [], s)[0] * s ** (k - 2)
                if rec:
                    out[ei] -= truncation_correction(lam, ag, b, pg, [], s, k - 2, rec)[0]
        out *= channel_filters(self.case, s)[None, :, :]
        for ei, e in enumerate(self.case.excitations):
            if e["delay_s"]:
                out[ei] *= np.exp(s * e["delay_s"])  # the force record is late: H × e^{+sδ_f}
        return out


def add_noise(h, relative, floor, seed):
    """H + ε, ε = σ (n₁ + i n₂)/√2 with σ² = a²|H|² + b² (a = relative, b = floor) and
    n₁, n₂ standard normals from numpy.random.default_rng(seed), drawn as one array of
    shape (excitation, channel, line, 2) in C order. E|ε|² = σ²."""
    if relative == 0 and floor == 0:
        return h
    rng = np.random.default_rng(seed)
    n = rng.standard_normal(h.shape + (2,))
    sigma = np.sqrt(relative ** 2 * np.abs(h) ** 2 + floor ** 2)
    return h + sigma * (n[..., 0] + 1j * n[..., 1]) / np.sqrt(2.0)


def quantise(h, precision):
    """float32: real and imaginary parts rounded to the nearest float32 (complex64)."""
    if precision == "float32":
        return h.astype(np.complex64)
    return h


def properties_record(m, c, j):
    return {
        "mass_kg": float(m),
        "com_m": [float(x) for x in c],
        "inertia_cm_kg_m2": np.asarray(j).tolist(),
        "moments_kg_m2": [float(j[0, 0]), float(j[1, 1]), float(j[2, 2])],
        "products_of_inertia_kg_m2": {"xy": float(-j[0, 1]), "xz": float(-j[0, 2]), "yz": float(-j[1, 2])},
    }


def truth(case, terms):
    out = {
        "generator": "rbref",
        "case": case.name,
        "seed": case.seed,
        "quantity": case.quantity,
        "reference_point_m": case.origin.tolist(),
        "gravity_m_s2": case.gravity,
        "sensor_gravity": case.sensor_gravity,
        "up": case.up.tolist(),
        "properties": properties_record(case.mass, case.com, case.inertia),
        "window_tau_s": case.window_tau or None,
        "record_s": case.record_s or None,
        "noise": {"relative": case.noise_relative, "floor": case.noise_floor,
                  "model": "sigma^2 = relative^2 |H|^2 + floor^2, circular complex normal"},
        "precision": case.precision,
        "channels": [{"id": c["id"], "point": c["point"], "position_m": c["position"].tolist(),
                      "direction": c["direction"].tolist(), "true_position_m": c["true_position"].tolist(),
                      "true_direction": c["true_direction"].tolist(), "gain": c["gain"],
                      "highpass_s": c["highpass_s"], "delay_s": c["delay_s"]} for c in case.channels],
        "excitations": [{"id": e["id"], "point": e["point"], "setup": e["setup"],
                         "position_m": e["position"].tolist(), "direction": e["direction"].tolist(),
                         "true_position_m": e["true_position"].tolist(),
                         "true_direction": e["true_direction"].tolist(),
                         "gauge_mass_kg": e["gauge_mass"],
                         "stinger_lateral_n_per_m": e["stinger_lateral"],
                         "stinger_bending_n_m_per_rad": e["stinger_bending"],
                         "force_gauge_gain": e["force_gauge_gain"], "delay_s": e["delay_s"],
                         "suspension_stiffness_factor": e["stiffness_factor"]}
                        for e in case.excitations],
        "elastic_modes": [{"frequency_hz": m["frequency_hz"], "damping_ratio": m["damping_ratio"],
                           "at_channels": m["at_channels"].tolist(),
                           "at_excitations": m["at_excitations"].tolist(), "setups": m["setups"]}
                          for m in case.elastic_modes],
        "setups": [],
        "modes_during_excitation": {
            e["id"]: [{"frequency_hz": f, "damping_ratio": z, "pole_re": lam.real, "pole_im": lam.imag}
                      for f, z, lam in model.rigid_poles()]
            for e, model in zip(case.excitations, terms.models)
            if model is not next(x for x in terms.setups if x.id == e["setup"]).nominal},
    }
    if case.sensor_masses:
        out["properties_with_sensor_masses"] = properties_record(*terms.setups[0].mass_properties)
    for sm in terms.setups:
        x, r = sm.pose
        m_tot, c_tot, _ = sm.mass_properties
        modes = []
        for f, z, lam in sm.nominal.rigid_poles():
            modes.append({"frequency_hz": f, "damping_ratio": z, "pole_re": lam.real, "pole_im": lam.imag})
        w2 = sm.nominal.undamped_w2
        out["setups"].append({
            "setup": sm.id,
            "equilibrium": {
                "reference_point_displacement_m": (x - case.origin).tolist(),
                "com_position_m": (x + r @ (c_tot - case.origin)).tolist(),
                "rotation_vector_rad": rotation_vector(r).tolist(),
                "rotation_matrix": r.tolist(),
                "newton_iterations": sm.iterations,
            },
            "cord_tensions_n": sm.cord_tensions,
            "hessian_asymmetry": sm.hessian_asymmetry,
            "free_directions": sm.nominal.n_free,
            "undamped_frequencies_hz": [float(np.sqrt(max(x, 0.0)) / (2 * np.pi)) for x in w2],
            "modes": modes,
            "mass_6x6": sm.m.tolist(),
            "stiffness_6x6": sm.k.tolist(),
            "damping_6x6": sm.c.tolist(),
            "hysteretic_6x6": sm.d.tolist(),
        })
    return out


class Result:
    """frequency_hz (L,), frf[e, c, l] (complex128, or complex64 when float32), truth dict."""

    def __init__(self, case, freq, frf, truth, coherence=None, recording=None):
        self.case, self.frequency_hz, self.frf, self.truth = case, freq, frf, truth
        self.coherence = coherence
        self.recording = recording   # recording.Recording (time histories) or None


def generate(case, freq=None, terms=None, seed=None, recording=None):
    """The case's FRFs (frequency or time route) with noise and precision applied, and the
    truth. `terms` (from an earlier call's `Terms(case)`) skips rebuilding the physics;
    `seed` replaces the case's seed for the noise. A [time] case is recorded (time
    histories, ADC, double hits: recording.py; the FRFs are the numpy H1 of the written
    samples, the truth gains "recording") when it uses a recording field or `recording`
    is true; otherwise the time route of timedomain.py runs as before."""
    if seed is not None:
        case.seed = int(seed)
    terms = Terms(case) if terms is None else terms
    if case.time is not None and (case.recording if recording is None else recording):
        from . import recording as rc
        rec = rc.record(case, terms)
        freq, h, coh, used = rc.h1(case, rec)
        tr = truth(case, terms)
        tr["recording"] = rc.truth_record(case, rec, used)
        return Result(case, freq, quantise(h, case.precision), tr, coh, rec)
    if case.time is not None:
        from .timedomain import measure
        freq, h, coh = measure(case, terms)
    else:
        freq = case.frequency_axis() if freq is None else np.asarray(freq, float)
        h = terms.frf(freq)
        coh = None
        h = add_noise(h, case.noise_relative, case.noise_floor, case.seed)
    h = quantise(h, case.precision)
    return Result(case, freq, h, truth(case, terms), coh)
