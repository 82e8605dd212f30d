#!/usr/bin/env python3
"""A campaign of analyser-style UFF exports, written with pyuff, for `rbprops campaign`.

    uff_campaign.py generate OUT [--n 24] [--df 0.025] [--seed 1]
    uff_campaign.py fill-spec INIT_SPEC TRUTH_JSON -o NOMINAL

`generate` writes OUT/run-NN.{uff,unv,58,58b}: each one test of the same article (Test
Case II of the paper: 15.69 kg on four soft springs), three triaxial accelerometers
(nodes 101, 102, 103; node 103 measures in a system rotated 0.3 rad about z, dataset
2420) and three hammer impacts (nodes 201 −x, 202 +y, 203 −z), accelerance 0–12.5 Hz,
processed with an exponential window of time constant τ, plus 0.1 % complex noise.
Datasets 2411 (nodes), 2420 (the rotated system) and 58 per FRF, in ASCII or binary 58b,
with no rbprops tags: the ids are the UFF DOF names (`101x`, `201-x`). Recordings whose
index is a multiple of 5 (and not 0) have channel `102y` read 6 % high (a calibration
error a model check should name). OUT/truth.json holds the article, the springs, the
damping and, per recording, what was done to it; OUT/campaign.toml the campaign options.

The FRFs are computed here from the rigid-body equations with numpy, independently of
rbprops-sim: mass matrix about the origin M0 = [[mI, −m[c]×], [m[c]×, J + m(|c|²I − ccᵀ)]],
mount stiffness K = Σ T(a)ᵀ diag(k) T(a) with T(p) = [I | −[p]×], modes from
K φ = ω² M0 φ (mass-normalised), modal damping ζ, and the windowed accelerance
A(s) = s² Σ_r (sᵀT(p)φ_r)(dᵀT(q)φ_r) / (ω_r² + 2ζω_r s + s²) at s = iω + 1/τ.

`fill-spec` fills the placeholders of a spec written by `rbprops init-spec` (the lines
marked FILL IN) with the article's values from truth.json, as a person would from the CAD
model and the rig drawing.
"""
import argparse
import json
import os
import re
import sys

import numpy as np
import pyuff

# Test Case II (paper Sec. 3.2), as in fixtures/specs/test-case-2.toml.
MASS = 15.69
COM = [0.17725, 0.03040, -0.00535]
MOMENTS = [0.35733194, 0.39469014, 0.31706832]
PRODUCTS = {"xy": 0.07722671, "xz": -0.08736156, "yz": -0.06919817}
SPRINGS = [([0.02, -0.13, 0.17], [150.0, 220.0, 2500.0]),
           ([0.34, -0.13, 0.17], [150.0, 220.0, 2500.0]),
           ([0.02, 0.20, 0.17], [150.0, 220.0, 2500.0]),
           ([0.34, 0.20, 0.17], [150.0, 220.0, 2500.0])]
DAMPING = 0.02
TAU_S = 4.0
NOISE = 1e-3
GAIN_CHANNEL = ("102y", 1.06)
SENSORS = {101: [0.0, 0.0, 0.0], 102: [0.10180, 0.21482, 0.055719],
           103: [0.13810, -0.05568, -0.13278]}
ROTATED = {103: 7}  # node -> displacement coordinate system
ROT_ANGLE = 0.3
HAMMER = {201: ([0.36, 0.18, -0.15], -1), 202: ([0.30, -0.15, 0.10], 2),
          203: ([0.05, 0.16, 0.17], -3)}
EXTENSIONS = ["uff", "unv", "58", "58b"]
STOP_HZ = 12.5


def skew(p):
    x, y, z = p
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def T(p):
    return np.hstack([np.eye(3), -skew(np.asarray(p, float))])


def inertia_tensor():
    jx, jy, jz = MOMENTS
    p = PRODUCTS
    return np.array([[jx, -p["xy"], -p["xz"]], [-p["xy"], jy, -p["yz"]],
                     [-p["xz"], -p["yz"], jz]])


def mass_matrix():
    c = np.asarray(COM)
    m = MASS
    return np.block([[m * np.eye(3), -m * skew(c)],
                     [m * skew(c), inertia_tensor() + m * (c @ c * np.eye(3) - np.outer(c, c))]])


def stiffness():
    K = np.zeros((6, 6))
    for at, k in SPRINGS:
        t = T(at)
        K += t.T @ np.diag(k) @ t
    return K


def rotation():
    c, s = np.cos(ROT_ANGLE), np.sin(ROT_ANGLE)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # rows = local axes


def dof(node, d):
    return f"{node}{'-' if d < 0 else ''}{'xyz'[abs(d) - 1]}"


def channels():
    """(node, direction code, global unit direction) per response channel."""
    out = []
    for n in SENSORS:
        for d in (1, 2, 3):
            axes = rotation() if n in ROTATED else np.eye(3)
            out.append((n, d, axes[d - 1]))
    return out


def accelerance(freq, sigma):
    """[excitation][channel][line] windowed accelerance (m/s²/N)."""
    # K φ = ω² M φ through the Cholesky factor M = L Lᵀ: (L⁻¹ K L⁻ᵀ) v = ω² v, φ = L⁻ᵀ v,
    # so that φᵀ M φ = I.
    L = np.linalg.cholesky(mass_matrix())
    Li = np.linalg.inv(L)
    w2, v = np.linalg.eigh(Li @ stiffness() @ Li.T)
    phi = Li.T @ v
    wr = np.sqrt(w2)
    s = 2j * np.pi * np.asarray(freq) + sigma
    chans = channels()
    out = np.zeros((len(HAMMER), len(chans), len(freq)), complex)
    for e, (q, (at, d)) in enumerate(HAMMER.items()):
        fd = np.zeros(3)
        fd[abs(d) - 1] = np.sign(d)
        fq = T(at).T @ fd @ phi  # f_kᵀ φ_r
        for c, (n, _, sd) in enumerate(chans):
            sp = sd @ T(SENSORS[n]) @ phi  # s_iᵀ T(p) φ_r
            h = sum(sp[r] * fq[r] / (wr[r] ** 2 + 2 * DAMPING * wr[r] * s + s ** 2)
                    for r in range(6))
            out[e, c] = s ** 2 * h
    return out


def generate(a):
    os.makedirs(a.out, exist_ok=True)
    # Record 7 prints the increment with 6 significant digits (E13.5): df must be exact
    # there, or the stated axis would differ from the one the values were computed on.
    lines = round(STOP_HZ / a.df) + 1
    if abs((lines - 1) * a.df - STOP_HZ) > 1e-12 or float(f"{a.df:.5e}") != a.df:
        sys.exit(f"--df {a.df}: must divide {STOP_HZ} Hz and have at most 6 significant digits")
    freq = np.arange(lines) * a.df
    clean = accelerance(freq, 1.0 / TAU_S)
    chans = channels()
    runs = []
    for k in range(a.n):
        rng = np.random.default_rng(a.seed * 1000 + k)
        data = clean.copy()
        gain = k % 5 == 0 and k > 0
        if gain:
            c = [dof(n, d) for n, d, _ in chans].index(GAIN_CHANNEL[0])
            data[:, c, :] *= GAIN_CHANNEL[1]
        noise = (rng.standard_normal(data.shape) + 1j * rng.standard_normal(data.shape)) / np.sqrt(2)
        data = data + NOISE * np.abs(data) * noise
        ext = EXTENSIONS[k % len(EXTENSIONS)]
        name = f"run-{k + 1:02d}.{ext}"
        path = os.path.join(a.out, name)
        if os.path.exists(path):
            os.remove(path)
        labels = list(SENSORS) + list(HAMMER)
        pos = [SENSORS[n] for n in SENSORS] + [HAMMER[n][0] for n in HAMMER]
        sets = [pyuff.prepare_2420(Part_UID=1, Part_Name="article", CS_sys_labels=[7],
                                   CS_types=[0], CS_colors=[8], CS_names=["triax 103"],
                                   CS_matrices=[np.vstack([rotation(), np.zeros(3)])]),
                pyuff.prepare_2411(node_nums=np.array(labels), def_cs=np.zeros(len(labels), int),
                                   disp_cs=np.array([ROTATED.get(n, 0) for n in labels]),
                                   color=np.full(len(labels), 8),
                                   x=np.array([p[0] for p in pos], float),
                                   y=np.array([p[1] for p in pos], float),
                                   z=np.array([p[2] for p in pos], float))]
        binary = ext == "58b"
        for e, (q, (_, d)) in enumerate(HAMMER.items()):
            for c, (n, sd, _) in enumerate(chans):
                sets.append(pyuff.prepare_58(
                    binary=int(binary), func_type=4, ver_num=0, load_case_id=0,
                    rsp_ent_name="NONE", rsp_node=n, rsp_dir=sd,
                    ref_ent_name="NONE", ref_node=q, ref_dir=d,
                    ord_data_type=6, num_pts=len(freq), abscissa_spacing=1,
                    abscissa_min=0.0, abscissa_inc=float(freq[1] - freq[0]), z_axis_value=0.0,
                    abscissa_spec_data_type=18, abscissa_len_unit_exp=0,
                    abscissa_force_unit_exp=0, abscissa_temp_unit_exp=0,
                    abscissa_axis_units_lab="Hz",
                    ordinate_spec_data_type=12, ordinate_len_unit_exp=1,
                    ordinate_force_unit_exp=0, ordinate_temp_unit_exp=0,
                    ordinate_axis_units_lab="m/s^2",
                    orddenom_spec_data_type=13, orddenom_len_unit_exp=0,
                    orddenom_force_unit_exp=1, orddenom_temp_unit_exp=0,
                    orddenom_axis_units_lab="N",
                    z_axis_spec_data_type=0, z_axis_len_unit_exp=0, z_axis_force_unit_exp=0,
                    z_axis_temp_unit_exp=0, z_axis_axis_units_lab="NONE",
                    data=data[e, c], x=freq, id1=f"{dof(n, sd)}/{dof(q, d)}", id4="NONE"))
        pyuff.UFF(path).write_sets(sets, mode="add", force_double=True)
        runs.append({"file": name, "channel_gain": {GAIN_CHANNEL[0]: GAIN_CHANNEL[1]} if gain else {},
                     "noise_seed": a.seed * 1000 + k})
    truth = {"writer": f"pyuff {pyuff.__version__}", "mass_kg": MASS, "com_m": COM,
             "moments_kg_m2": MOMENTS, "products_kg_m2": PRODUCTS,
             "springs": [{"at_m": at, "stiffness_n_per_m": k} for at, k in SPRINGS],
             "damping_ratio": DAMPING, "window_time_constant_s": TAU_S,
             "noise_relative": NOISE, "df_hz": a.df, "runs": runs}
    with open(os.path.join(a.out, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=1)
    with open(os.path.join(a.out, "campaign.toml"), "w") as fh:
        fh.write("# rbprops campaign options for these exports (see `rbprops campaign --help`).\n"
                 "uncertainty = \"linearised\"\n"
                 f"window_time_constant_s = {TAU_S!r}   # the analyser's exponential window\n"
                 "nominal = \"nominal.toml\"            # model check of every export against it\n")
    print(f"wrote {a.n} UFF exports, truth.json and campaign.toml to {a.out}")


def fill_spec(a):
    with open(a.truth) as fh:
        t = json.load(fh)
    text = open(a.spec).read()
    f = lambda xs: "[" + ", ".join(repr(float(x)) for x in xs) + "]"
    p = t["products_kg_m2"]
    repl = {
        "mass_kg": repr(float(t["mass_kg"])),
        "com_m": f(t["com_m"]),
        "moments_kg_m2": f(t["moments_kg_m2"]),
        "products_kg_m2": f"{{ xy = {p['xy']!r}, xz = {p['xz']!r}, yz = {p['yz']!r} }}",
        "ratio": repr(float(t["damping_ratio"])),
    }
    lines = []
    for line in text.splitlines():
        m = re.match(r"^(\w+) = .*# FILL IN", line)
        if m and m.group(1) in repl:
            line = f"{m.group(1)} = {repl[m.group(1)]}"
        lines.append(line)
    text = "\n".join(lines) + "\n"
    springs = "\n".join(f"[[setup.spring]]\nat_m = {f(s['at_m'])}\nstiffness_n_per_m = {f(s['stiffness_n_per_m'])}"
                        for s in t["springs"])
    text, n = re.subn(r"\[\[setup\.spring\]\]\nat_m = \[nan, nan, nan\][^\n]*\nstiffness_n_per_m = \[nan, nan, nan\][^\n]*",
                      lambda _: springs, text)
    if n == 0 or "nan" in re.sub(r"#.*", "", text):
        sys.exit(f"{a.spec}: not every placeholder was filled (is it an init-spec output?)")
    with open(a.output, "w") as fh:
        fh.write(text)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    g = sub.add_parser("generate")
    g.add_argument("out")
    g.add_argument("--n", type=int, default=24)
    g.add_argument("--df", type=float, default=0.025, help="line spacing (Hz), 0 to 12.5 Hz")
    g.add_argument("--seed", type=int, default=1)
    fs = sub.add_parser("fill-spec")
    fs.add_argument("spec")
    fs.add_argument("truth")
    fs.add_argument("-o", "--output", required=True)
    a = ap.parse_args()
    generate(a) if a.cmd == "generate" else fill_spec(a)


if __name__ == "__main__":
    main()
