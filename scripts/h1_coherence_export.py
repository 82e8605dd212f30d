#!/usr/bin/env python3
"""An analyser's H1 export with coherence, made independently of rbprops: numpy and pyuff.

A SIMO test of a known system (three modes, one hammer excitation, four responses) is
"measured" the way an analyser does it: n_d hits, each with its own force spectrum, the
responses with additive noise, then

    H1 = sum_i conj(F_i) Y_i / sum_i |F_i|^2,
    gamma^2 = |sum_i conj(F_i) Y_i|^2 / (sum_i |F_i|^2 sum_i |Y_i|^2).

The spectra are built per line in the frequency domain (the DFT of each hit's records;
no leakage: the exponential window is not modelled). The true FRF is accelerance

    H(w) = -w^2 sum_r A_rc / (w_r^2 - w^2 + 2 i zeta_r w_r w)

(receptance modal constants A in 1/kg, docs/conventions.md). Cases:

  exact      no noise: H1 = H, gamma^2 = 1 (to rounding)
  floor      a constant response-noise floor: coherence drops at antiresonances and
             away from the modes, where |H| is small
  double-hit the floor, and in 5 of the 8 averages a second hit 30 ms after the first
             with 0.95 of its amplitude: the force spectrum has notches at odd multiples
             of 1/(2*0.03 s) = 16.7 Hz, so near those lines the force is small, the
             response is mostly noise and the coherence is low

Writes OUT.uff (datasets 164 SI, 2411 nodes, 58 FRF then 58 coherence per channel,
ASCII double) and OUT.json with the truth (frequencies, damping ratios, modal constants)
and the coherence written.

Usage: h1_coherence_export.py CASE SEED OUT_BASENAME
"""
import json
import sys

import numpy as np
import pyuff

F_HZ = np.array([4.1, 7.3, 15.9])
ZETA = np.array([0.02, 0.025, 0.015])
# A[r][c] (1/kg): mode 1 and 2 of equal sign on channel 0 (an antiresonance between).
A = np.array([[0.50, 0.30, -0.20, 0.10],
              [0.40, -0.25, 0.35, 0.20],
              [0.30, 0.20, 0.15, -0.35]])
NODES = {1: (0.0, 0.0, 0.0), 2: (0.3, 0.0, 0.0), 3: (0.3, 0.2, 0.0), 4: (0.0, 0.2, 0.0)}
EXC = (1, 3)
RESP = [(1, 3), (2, 3), (3, 3), (4, 3)]
N_AVG = 8
DF = 1.0 / 32.0
X = 1.0 + DF * np.arange(int(round((19.0 - 1.0) / DF)) + 1)  # 1 .. 19 Hz


def true_frf(f_hz):
    w = 2 * np.pi * f_hz
    wr = 2 * np.pi * F_HZ
    h = np.zeros((len(RESP), len(f_hz)), complex)
    for r in range(len(F_HZ)):
        den = wr[r] ** 2 - w ** 2 + 2j * ZETA[r] * wr[r] * w
        for c in range(len(RESP)):
            h[c] += A[r, c] / den
    return -(w ** 2) * h


def measure(case, seed):
    rng = np.random.default_rng(seed)
    h = true_frf(X)
    n = len(X)
    # Half-sine pulse of 5 ms: flat to about 100 Hz; amplitudes jitter 10 %.
    tp = 0.005
    w = 2 * np.pi * X
    pulse = (np.pi * tp / 2) * (np.exp(-1j * w * tp) + 1) / (np.pi ** 2 - (w * tp) ** 2) * 2
    sxy = np.zeros((len(RESP), n), complex)
    sxx = np.zeros(n)
    syy = np.zeros((len(RESP), n))
    for i in range(N_AVG):
        f = 200.0 * (1 + 0.1 * rng.standard_normal()) * pulse
        if case == "double-hit" and i < 5:
            f = f * (1 + 0.95 * np.exp(-1j * w * 0.03))
        y = h * f
        if case != "exact":
            # Response noise floor, circular Gaussian, E|N|^2 = b^2 on every line.
            b = 0.02
            y = y + b * (rng.standard_normal((len(RESP), n))
                         + 1j * rng.standard_normal((len(RESP), n))) / np.sqrt(2)
        sxy += np.conj(f) * y
        sxx += np.abs(f) ** 2
        syy += np.abs(y) ** 2
    h1 = sxy / sxx
    g2 = np.abs(sxy) ** 2 / (sxx * syy)
    return h1, np.minimum(g2, 1.0)


def func58(rsp, data, func_type, ordinate, num_type, den_type):
    return pyuff.prepare_58(
        binary=0, func_type=func_type, ver_num=0, load_case_id=0,
        rsp_ent_name="NONE", rsp_node=rsp[0], rsp_dir=rsp[1],
        ref_ent_name="NONE", ref_node=EXC[0], ref_dir=EXC[1],
        ord_data_type=ordinate, num_pts=len(X), abscissa_spacing=1,
        abscissa_min=float(X[0]), abscissa_inc=DF, z_axis_value=0.0,
        abscissa_spec_data_type=18, abscissa_len_unit_exp=0, abscissa_force_unit_exp=0,
        abscissa_temp_unit_exp=0, abscissa_axis_units_lab="Hz",
        ordinate_spec_data_type=num_type, ordinate_len_unit_exp=1,
        ordinate_force_unit_exp=0, ordinate_temp_unit_exp=0,
        ordinate_axis_units_lab="NONE", orddenom_spec_data_type=den_type,
        orddenom_len_unit_exp=0, orddenom_force_unit_exp=1, orddenom_temp_unit_exp=0,
        orddenom_axis_units_lab="NONE", z_axis_spec_data_type=0, z_axis_len_unit_exp=0,
        z_axis_force_unit_exp=0, z_axis_temp_unit_exp=0, z_axis_axis_units_lab="NONE",
        data=data, x=X, id1="NONE")


def main():
    case, seed, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    if case not in ("exact", "floor", "double-hit"):
        sys.exit(f"error: unknown case {case!r}")
    h1, g2 = measure(case, seed)
    labels = sorted(NODES)
    sets = [
        pyuff.prepare_164(units_code=1, units_description="SI", temp_mode=2, length=1.0,
                          force=1.0, temp=1.0, temp_offset=273.15),
        pyuff.prepare_2411(
            node_nums=np.array(labels), def_cs=np.zeros(len(labels), int),
            disp_cs=np.zeros(len(labels), int), color=np.full(len(labels), 8),
            x=np.array([NODES[k][0] for k in labels], float),
            y=np.array([NODES[k][1] for k in labels], float),
            z=np.array([NODES[k][2] for k in labels], float)),
    ]
    for c, r in enumerate(RESP):
        sets.append(func58(r, h1[c], 4, 6, 12, 13))
        sets.append(func58(r, g2[c], 6, 4, 0, 0))
    u = pyuff.UFF(out + ".uff")
    u.write_sets(sets, mode="overwrite", force_double=True)
    with open(out + ".json", "w") as fh:
        json.dump({"frequency_hz": F_HZ.tolist(), "damping_ratio": ZETA.tolist(),
                   "modal_constants": A.tolist(), "coherence": g2.tolist(),
                   "n_averages": N_AVG, "line_variance": line_variance(out + ".uff")}, fh)


def line_variance(path):
    """Each line's H1 variance from the FRF and coherence as written (read back with
    pyuff): sigma^2 = E|H1 - H|^2 = |H1|^2 (1 - g2)/(n_d g2), twice Bendat & Piersol's
    Var|H| = (1 - g2)/(2 n_d g2) |H|^2 (real and imaginary parts alike); g2 clamped to
    [1e-6, 1 - 1e-6] as rbprops does. Per response node (+z), in RESP order."""
    sets = pyuff.UFF(path).read_sets()
    frf = {s["rsp_node"]: np.asarray(s["data"]) for s in sets
           if s.get("type") == 58 and s["func_type"] == 4}
    coh = {s["rsp_node"]: np.real(np.asarray(s["data"])) for s in sets
           if s.get("type") == 58 and s["func_type"] == 6}
    out = []
    for node, _ in RESP:
        g = np.clip(coh[node], 1e-6, 1 - 1e-6)
        out.append(((1 - g) / (N_AVG * g) * np.abs(frf[node]) ** 2).tolist())
    return out


if __name__ == "__main__":
    main()
