#!/usr/bin/env python3
"""modal-fit against pyEMA's LSCF on the same recordings: frequency and damping errors
against the simulation's truth, merged pairs, and the cost per excitation.

usage: scripts/compare_pyema.py [SPEC_OR_EXAMPLE ...] [--bin target/release] [--order 40]

Each argument is a campaign spec (.toml) or a built-in example name (default: `demo`
and `fixtures/specs/close-modes.toml`). `frf-sim` writes the recording as a CSV run
directory; `modal-fit` fits it (one thread, automatic pole selection); pyEMA
(`pip install pyEMA`) fits each excitation with `get_poles('lscf')` up to the same
order. pyEMA has no automatic selection, so it is *given the true natural frequencies*
(`select_closest_poles`), which favours it: its errors are a lower bound. A true mode
counts as merged when in no excitation its nearest pole is its own (shared with another
true mode). Errors are per true mode from its best excitation, as ni-select uses it.
"""
import argparse
import csv
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np


def read_rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def load_run(run):
    """FRFs {excitation: (freq, H[channels, lines])} and the true (f, zeta) per set-up."""
    by_exc = defaultdict(lambda: defaultdict(list))
    freq = {}
    for r in read_rows(run / "frf.csv"):
        by_exc[r["excitation"]][r["channel"]].append(complex(float(r["re"]), float(r["im"])))
        freq.setdefault((r["excitation"], r["channel"]), []).append(float(r["frequency_hz"]))
    frfs = {}
    for e, chans in by_exc.items():
        names = list(chans)
        f = np.array(freq[(e, names[0])])
        frfs[e] = (f, np.array([chans[c] for c in names]))
    setups = {r["_parent"]: r["setup"] for r in read_rows(run / "truth_setups.csv")}
    truth = defaultdict(list)
    for r in read_rows(run / "truth_setups_modes.csv"):
        truth[setups[r["_parent"]]].append((float(r["frequency_hz"]), float(r["damping_ratio"])))
    exc_setup = {r["id"]: r["setup"] for r in read_rows(run / "geometry_excitations.csv")}
    return frfs, truth, exc_setup


def score(est, truth, excitations):
    """Per true mode, its best estimate over the excitations (as a selection stage would
    use it); the worst of those relative frequency and damping errors; and the number
    of true modes that no excitation resolves (their nearest pole is always shared with
    another true mode: merged)."""
    wf = wz = 0.0
    merged = 0
    for k, (f, z) in enumerate(truth):
        best_f = best_z = float("inf")
        resolved = False
        for e in excitations:
            poles = est[e]
            nearest = [min(range(len(poles)), key=lambda i: abs(poles[i][0] - tf)) for tf, _ in truth]
            i = nearest[k]
            best_f = min(best_f, abs(poles[i][0] - f) / f)
            best_z = min(best_z, abs(poles[i][1] - z) / z)
            resolved |= nearest.count(i) == 1
        wf, wz = max(wf, best_f), max(wz, best_z)
        merged += not resolved
    return wf, wz, merged


def ours(run, bin_dir, workdir):
    out = workdir / "fit"
    t = time.perf_counter()
    subprocess.run([str(bin_dir / "modal-fit"), str(run), "-o", str(out)], check=True,
                   env={"RAYON_NUM_THREADS": "1", "PATH": "/usr/bin:/bin"},
                   stderr=subprocess.DEVNULL)
    dt = time.perf_counter() - t
    est = defaultdict(list)
    for r in read_rows(out / "modal_fit_modes.csv"):
        est[r["excitation"]].append((float(r["frequency_hz"]), float(r["damping_ratio"])))
    return est, dt


def pyema(frfs, truth, exc_setup, order, quantity):
    import pyEMA

    # pyEMA's pole search windows are whole hertz (`f_window // i`), made for modes in
    # the hundreds of Hz. LSCF depends only on the normalised axis (z = e^{iωΔt}), so
    # the axis is scaled by SCALE for pyEMA and its frequencies scaled back; damping
    # ratios are unchanged by the scaling.
    scale = 100.0
    est, dt = {}, 0.0
    for e, (f, h) in frfs.items():
        fs = f * scale
        lo = fs[fs > 0][0]
        t = time.perf_counter()
        m = pyEMA.Model(frf=h, freq=fs, lower=lo, upper=fs[-1], pol_order_high=order,
                        frf_form=quantity)
        m.get_poles("lscf", show_progress=False)
        m.select_closest_poles([tf * scale for tf, _ in truth[exc_setup[e]]], f_window=50)
        dt += time.perf_counter() - t
        est[e] = [(fn / scale, z) for fn, z in zip(np.atleast_1d(m.nat_freq), np.atleast_1d(m.nat_xi))]
    return est, dt


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("cases", nargs="*", default=["demo", "fixtures/specs/close-modes.toml"])
    ap.add_argument("--bin", default="target/release", type=Path)
    ap.add_argument("--order", default=40, type=int)
    a = ap.parse_args()
    print("| case | tool | excitations | worst Δf/f | worst Δζ/ζ | modes not resolved | ms per excitation |")
    print("|---|---|---|---|---|---|---|")
    for case in a.cases:
        with tempfile.TemporaryDirectory() as tmp:
            tmp = Path(tmp)
            run = tmp / "run"
            spec = [case] if case.endswith(".toml") else ["--example", case]
            subprocess.run([str(a.bin / "frf-sim"), *spec, "-o", str(run)], check=True,
                           stderr=subprocess.DEVNULL)
            quantity = read_rows(run / "frf_info.csv")[0]["quantity"]
            frfs, truth, exc_setup = load_run(run)
            n = len(frfs)
            for tool, (est, dt) in [
                ("rbprops modal-fit (automatic)", ours(run, a.bin, tmp)),
                ("pyEMA LSCF (given true f)", pyema(frfs, truth, exc_setup, a.order, quantity)),
            ]:
                wf = wz = 0.0
                merged = 0
                for setup, modes in truth.items():
                    excs = [e for e in frfs if exc_setup[e] == setup]
                    f, z, m = score(est, modes, excs)
                    wf, wz, merged = max(wf, f), max(wz, z), merged + m
                print(f"| {Path(case).stem} | {tool} | {n} | {wf:.1e} | {wz:.1e} | {merged} | {1e3 * dt / n:.0f} |")
            sys.stdout.flush()


if __name__ == "__main__":
    main()
