#!/usr/bin/env python3
"""`rbprops plan` against an Effective Independence layout from SDynPy and the paper's
layout, on Test Case II (1 % FRF noise), same number of sensors and hits.

usage: scripts/compare_sdynpy_efi.sh [SEEDS]      (installs SDynPy, then runs this file)
       python compare_sdynpy_efi.py --seeds 200 --out DIR [--standin]

Layouts, all drawn from the 200 candidate points of
`crates/rbprops-plan/tests/data/test-case-2-candidates.csv` (each a triaxial sensor
position and a hit along its face's inward normal) except the paper's:

(a) the paper's: Test Case II's three triaxial sensors and three hits
    (`fixtures/specs/test-case-2.toml`);
(b) Effective Independence (Kammer 1991) on the rigid-body modes, computed by SDynPy's
    `ShapeArray.optimize_degrees_of_freedom(n, group_by_node=True, method='ei')`
    (triaxial bundles: a node is kept or removed whole), with the paper's hits: EfI is
    a sensor-placement method and says nothing about where to hit; with fewer hits
    than modes its information matrix is singular, so the tester's hits are kept;
(c) `rbprops plan ... --sensors 3 --hits 3` (D-optimal, Toivola–Nuutila).

EfI depends only on the span of the mode shapes (its projector Φ(ΦᵀΦ)⁻¹Φᵀ is the same
for ΦA, A invertible), and the six rigid-body modes span the rigid motions: the shapes
given to SDynPy are the six unit rigid motions `T(p) = [I | −[p]×]` at each candidate,
which is EfI on the rigid-body modes exactly.

Each layout goes through the real pipeline (`frf-sim | modal-fit | ni-select |
rb-solve` as library calls, default options, the `monte_carlo` example of
`rbprops-plan`) over SEEDS noise seeds; the figure of merit is the worst property's
relative standard deviation (std / scale: m for the mass, ℓ = √(tr J/m) for the centre
of mass, tr J/3 for the inertia; `rbprops_plan::property_scales`).

With `--standin` (or when SDynPy cannot be imported) EfI is computed by this script's
own implementation of the same algorithm (SDynPy's `by_effective_independence`,
triaxial bundles), and every line printed says so.
"""
import argparse
import csv
import re
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
CANDIDATES = ROOT / "crates/rbprops-plan/tests/data/test-case-2-candidates.csv"
SPEC = ROOT / "fixtures/specs/test-case-2.toml"
NAMES = ["m", "cx", "cy", "cz", "Jxx", "Jyy", "Jzz", "Jxy", "Jxz", "Jyz"]


def read_candidates():
    with open(CANDIDATES, newline="") as f:
        rows = list(csv.DictReader(f))
    return [
        (r["id"], np.array([float(r[k]) for k in ("x_m", "y_m", "z_m")]),
         np.array([float(r[k]) for k in ("dx", "dy", "dz")]))
        for r in rows
    ]


def rigid_rows(p):
    """T(p) = [I | −[p]×]: a point's displacement for the six unit rigid motions."""
    x, y, z = p
    skew = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return np.hstack([np.eye(3), -skew])


def efi_sdynpy(points, n_keep):
    import sdynpy as sdpy

    nodes = np.arange(1, len(points) + 1)
    coords = sdpy.coordinate_array(nodes[:, None], [1, 2, 3]).flatten()
    # shape_matrix: (modes, dofs); the dof order of `coords`: node by node, x y z.
    phi = np.vstack([rigid_rows(p) for p in points])  # (3n, 6)
    shapes = sdpy.shape_array(coords, phi.T, frequency=np.arange(1.0, 7.0), damping=0.0)
    reduced = shapes.optimize_degrees_of_freedom(n_keep, group_by_node=True, method="ei")
    kept = sorted(set(int(n) for n in np.unique(reduced.coordinate.node)))
    from importlib.metadata import version

    return [k - 1 for k in kept], f"SDynPy {version('sdynpy')} optimize_degrees_of_freedom(ei)"


def efi_standin(points, n_keep):
    """SDynPy's `by_effective_independence` on triaxial bundles, reimplemented: remove
    one bundle at a time, the one with the least `1 − det(I − Φ_b Q⁻¹ Φ_bᵀ)`."""
    shape = np.stack([rigid_rows(p) for p in points])  # (n, 3, 6)
    keep = list(range(len(points)))
    while len(keep) > n_keep:
        s = shape[keep]
        flat = s.reshape(-1, 6)
        qinv = np.linalg.inv(flat.T @ flat)
        efi = 1 - np.linalg.det(np.eye(3) - np.einsum("ijk,kl,iml->ijm", s, qinv, s))
        del keep[int(np.argmin(efi))]
    return keep, "STAND-IN EfI (this script's reimplementation of SDynPy's by_effective_independence; SDynPy not used)"


def spec_with_layout(text, sensors, hits, noise):
    """The spec text with its sensors and excitations replaced and the noise set."""
    body = re.sub(r"(?ms)^\[\[(sensor|excitation)\]\].*?(?=^\[|\Z)", "", text)
    body = re.sub(r"(?m)^relative = .*$", f"relative = {noise}", body)
    out = [body.rstrip() + "\n"]
    for sid, p in sensors:
        out.append(f'\n[[sensor]]\nid = "{sid}"\nat_m = [{p[0]}, {p[1]}, {p[2]}]\nkind = "triaxial"\n')
    for hid, p, d in hits:
        out.append(
            f'\n[[excitation]]\nid = "{hid}"\nat_m = [{p[0]}, {p[1]}, {p[2]}]\n'
            f'direction = [{d[0]}, {d[1]}, {d[2]}]\nsetup = "A"\n'
        )
    return "".join(out)


def layout_of_spec(text):
    sensors = [(m[0], [float(v) for v in m[1].split(",")]) for m in re.findall(
        r'(?ms)^\[\[sensor\]\]\s*id = "([^"]+)"\s*at_m = \[([^\]]+)\]', text)]
    hits = [(m[0], [float(v) for v in m[1].split(",")], [float(v) for v in m[2].split(",")])
            for m in re.findall(
                r'(?ms)^\[\[excitation\]\]\s*id = "([^"]+)"\s*at_m = \[([^\]]+)\]\s*direction = \[([^\]]+)\]',
                text)]
    return sensors, hits


def monte_carlo(spec_path, seeds):
    """MC std of the ten properties (Toivola–Nuutila) and the truth, from the example."""
    out = subprocess.run(
        ["cargo", "run", "-q", "--release", "-p", "rbprops-plan", "--example", "monte_carlo",
         "--", str(spec_path), str(seeds)],
        cwd=ROOT, check=True, capture_output=True, text=True).stdout
    block = out.split("bretl_conti")[0]
    truth, pred, mc = {}, {}, {}
    for line in block.splitlines():
        f = line.split()
        if f and f[0] in NAMES and len(f) == 6:
            truth[f[0]], pred[f[0]], mc[f[0]] = float(f[1]), float(f[3]), float(f[4])
    return truth, pred, mc


def worst(truth, std):
    m = truth["m"]
    tr = truth["Jxx"] + truth["Jyy"] + truth["Jzz"]
    scale = {k: (m if k == "m" else np.sqrt(tr / m) if k.startswith("c") else tr / 3) for k in NAMES}
    rel = {k: std[k] / scale[k] for k in NAMES}
    k = max(rel, key=rel.get)
    return rel[k], k


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=200)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--standin", action="store_true")
    ap.add_argument("--noise", type=float, default=0.01)
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    text = SPEC.read_text()
    paper_sensors, paper_hits = layout_of_spec(text)
    n_s, n_h = len(paper_sensors), len(paper_hits)
    cands = read_candidates()
    points = [p for _, p, _ in cands]
    if a.standin:
        kept, how = efi_standin(points, n_s)
    else:
        try:
            kept, how = efi_sdynpy(points, n_s)
        except ImportError as e:
            print(f"SDynPy cannot be imported ({e}); using the stand-in", file=sys.stderr)
            kept, how = efi_standin(points, n_s)
    layouts = {}
    layouts["a_paper"] = a.out / "a_paper.toml"
    layouts["a_paper"].write_text(spec_with_layout(text, paper_sensors, paper_hits, a.noise))
    efi_sensors = [(cands[k][0], cands[k][1].tolist()) for k in kept]
    layouts["b_efi"] = a.out / "b_efi.toml"
    layouts["b_efi"].write_text(spec_with_layout(text, efi_sensors, paper_hits, a.noise))
    layouts["c_planned"] = a.out / "c_planned.toml"
    subprocess.run(
        ["cargo", "run", "-q", "--release", "-p", "rbprops-cli", "--bin", "rbprops", "--", "plan",
         str(layouts["a_paper"]), "--candidates", str(CANDIDATES), "--sensors", str(n_s),
         "--hits", str(n_h), "-o", str(layouts["c_planned"])],
        cwd=ROOT, check=True, capture_output=True, text=True)
    print(f"Test Case II, {a.noise:.0%} noise, {n_s} triaxial sensors and {n_h} hits, "
          f"{a.seeds} noise seeds through the pipeline (Toivola–Nuutila)")
    print(f"(b) sensors by {how}: {[cands[k][0] for k in kept]}")
    res = {}
    for name, path in layouts.items():
        truth, pred, mc = monte_carlo(path, a.seeds)
        res[name] = (worst(truth, mc), worst(truth, pred))
        s, h = layout_of_spec(path.read_text())
        print(f"{name:10} sensors {[x[0] for x in s]} hits {[x[0] for x in h]}")
    print("| layout | worst relative std, Monte Carlo | predicted |")
    print("|---|---|---|")
    label = {"a_paper": "(a) paper", "b_efi": "(b) EfI" + (" (stand-in)" if "STAND-IN" in how else " (SDynPy)"),
             "c_planned": "(c) planned"}
    for name, ((w, k), (wp, kp)) in res.items():
        print(f"| {label[name]} | {w:.3e} ({k}) | {wp:.3e} ({kp}) |")
    wc = res["c_planned"][0][0]
    for name in ("a_paper", "b_efi"):
        w = res[name][0][0]
        print(f"planned lower than {label[name]} by {100 * (1 - wc / w):.0f} % (acceptance: ≥ 30 %)")


if __name__ == "__main__":
    main()
