#!/usr/bin/env python3
"""Side by side with pyFRF 1.5 on a per-hit recording written by rbref.

    python3 scripts/refgen/rbref.py CASE.toml --time-layout per-hit -o rec.uff -o h1.npz --truth truth.json
    python3 scripts/refgen/compare_pyfrf.py rec.uff --truth truth.json --h1 h1.npz

    python3 scripts/refgen/compare_pyfrf.py rec.uff --truth truth.json --frf-est target/release/frf-est

Needs pyuff and pyFRF 1.5 (`pip install pyFRF==1.5`; the generator itself does not).
With --frf-est, one run puts `frf-est` and pyFRF side by side on the same file:
  - `frf-est`'s H1 (its own windows: τ, trigger and force window from its processing
    topic's hit table) against pyFRF's H1 over the same accepted hits with those windows
    applied to the time data beforehand (window='none' in pyFRF), max relative difference
    over the lines `frf-est` writes;
  - both detectors' confusion tables against the truth (double hits; overload = the
    truth's ≥ 2 samples at the range on any channel);
  - whole-process wall time from the UFF file to the FRFs, best of --repeat runs: the
    `frf-est` process (reading, checks, FRFs, variances, writing CSV) against pyuff
    reading + windows + pyFRF; and `frf-est`'s peak RSS against the recording's samples
    stored as float32.
Without --frf-est it prints, per excitation:
  - the max relative difference (of max |H|) between pyFRF's H1 and the generator's numpy
    H1 over the same accepted hits, with the windows applied to the time data beforehand
    (the truth's force rectangle × exponential window from the trigger, and the exponential
    window on the responses) and window='none' in pyFRF — its own windows start at sample
    0 and carry their own amplitude scaling. pyFRF detrends each record (subtracts its
    mean), which changes the 0 Hz bin only, so bins ≥ 1 are compared;
  - pyFRF's double-impact flags (FRF._is_double_impact on the raw force, limit 1e-3) and
    overload flags (FRF._is_overflow: ≥ 3 samples equal to the record's max |x|, force
    and every channel) against the truth, as confusion tables over all hits;
  - wall time from the UFF file to pyFRF's FRFs (pyuff reading + windows + pyFRF), and
    the time pyuff alone took to read the file.
"""
import argparse
import json
import sys
import time

import numpy as np


def confusion(name, truth, flag):
    truth, flag = np.asarray(truth, bool), np.asarray(flag, bool)
    tp, fn = int(np.sum(truth & flag)), int(np.sum(truth & ~flag))
    fp, tn = int(np.sum(~truth & flag)), int(np.sum(~truth & ~flag))
    rec = tp / (tp + fn) if tp + fn else float("nan")
    fa = fp / (fp + tn) if fp + tn else float("nan")
    print(f"  {name:<16} truth+ flagged {tp:5d} missed {fn:5d} | truth- flagged {fp:5d} passed {tn:5d}"
          f" | recall {rec:.3f} false alarms {fa:.3f}")


def read_csv(path):
    import csv
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def run_frf_est(binary, uff, out, extra):
    """Runs frf-est on `uff` into `out` (CSV directory or .mcap); returns (wall s, peak RSS
    bytes, its summary line)."""
    import os
    import shutil
    import subprocess
    import tempfile
    if os.path.isdir(out):
        shutil.rmtree(out)
    # Peak RSS through /usr/bin/time: a child forked from this (large) Python process
    # would inherit its high-water mark across exec, so ru_maxrss here would not be
    # frf-est's own.
    with tempfile.NamedTemporaryFile("r", suffix=".txt") as rss_file:
        t0 = time.perf_counter()
        p = subprocess.run(["/usr/bin/time", "-f", "%M", "-o", rss_file.name, binary, uff, "-o", out, *extra],
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        wall = time.perf_counter() - t0
        err = p.stderr.decode()
        if p.returncode != 0:
            sys.exit(f"frf-est failed ({p.returncode}): {err}")
        rss_kb = int(rss_file.read().split()[-1])
    return wall, rss_kb * 1024, err.strip()


def frf_est_tables(out):
    """frf-est's CSV output: FRFs {(excitation, channel): (freqs, H)}, the hit table with
    reasons and force windows, τ and whether the exponential window is on the force."""
    frf = {}
    for r in read_csv(f"{out}/frf.csv"):
        frf.setdefault((r["excitation"], r["channel"]), []).append(
            (float(r["frequency_hz"]), complex(float(r["re"]), float(r["im"]))))
    proc = read_csv(f"{out}/processing.csv")[0]
    tau = proc["frf_estimation.exponential_window_s"]
    hits = read_csv(f"{out}/processing_frf_estimation_hits.csv")
    reasons = {}
    for r in read_csv(f"{out}/processing_frf_estimation_hits_reasons.csv"):
        reasons.setdefault((r["excitation"], int(r["hit"])), []).append(r["value"])
    table = {}
    for h in hits:
        key = (h["excitation"], int(h["hit"]))
        window = None
        if h.get("force_window_s.0"):
            window = [float(h["force_window_s.0"]), float(h["force_window_s.1"])]
        table.setdefault(h["excitation"], []).append(dict(
            hit=key[1], accepted=h["accepted"] == "true", trigger_s=float(h["trigger_s"]),
            reasons=reasons.get(key, []), force_window_s=window))
    return frf, table, (float(tau) if tau else None), proc["frf_estimation.exponential_on_force"] == "true"


def side_by_side(a, uff, tr):
    """frf-est against pyFRF on one file (module docs, --frf-est): prints the H1
    comparison, the times and the peak RSS; returns the detector flags
    {what: (truth, frf-est, pyFRF)} and the worst H1 difference."""
    import os
    import pyuff
    import pyFRF
    fs, n = tr["sample_rate_hz"], tr["record_samples"]
    n_ch = len(tr["channels"])
    n_hits = tr["impacts"]
    per_exc = 1 + n_ch
    out = os.path.splitext(uff)[0] + "-frf-est"
    extra = ["--keep-rejected"] if a.keep_rejected else []
    # Timed runs write MCAP (the pipeline's format); one more writes CSV to read back.
    mcap = out + ".mcap"
    runs = [run_frf_est(a.frf_est, uff, mcap, extra + ["--force"]) for _ in range(a.repeat)]
    wall = min(r[0] for r in runs)
    rss = max(r[1] for r in runs)
    run_frf_est(a.frf_est, uff, out, extra)
    frf, table, tau, exp_on_force = frf_est_tables(out)
    idx = np.arange(n)
    ids = [e["id"] for e in tr["excitations"]]
    sets = []
    h1_lines = []
    # pyFRF over frf-est's accepted hits with frf-est's windows applied beforehand.
    t_py, t_reads = [], []
    worst = 0.0
    for rep in range(a.repeat):
        t0 = time.perf_counter()
        sets = [s for s in pyuff.UFF(uff).read_sets() if s["type"] == 58]
        t_reads.append(time.perf_counter() - t0)
        h1s = {}
        for ei, eid in enumerate(ids):
            block = sets[ei * n_hits * per_exc:(ei + 1) * n_hits * per_exc]
            used = [h for h in table[eid] if h["accepted"] or a.keep_rejected]
            we = np.empty((len(used), 1, n))
            wr = np.empty((len(used), n_ch, n))
            for j, h in enumerate(used):
                k = h["hit"] - 1
                n0 = round(h["trigger_s"] * fs)
                w = np.exp(-(idx - n0) / (tau * fs)) if tau else np.ones(n)
                wf = w.copy() if exp_on_force else np.ones(n)
                if h["force_window_s"]:
                    lo, hi = (round(x * fs) for x in h["force_window_s"])
                    wf *= (idx >= lo) & (idx < hi)
                we[j, 0] = block[k * per_exc]["data"] * wf
                for c in range(n_ch):
                    wr[j, c] = block[k * per_exc + 1 + c]["data"] * w
            f = pyFRF.FRF(int(fs), exc=we, resp=wr, exc_type="f", resp_type="d", window="none",  # "d": no conversion (H1 as measured)
                          frf_estimator="H1")
            h1s[eid] = (f.get_f_axis(), f.get_H1()[:, 0, :])
        t_py.append(time.perf_counter() - t0)
    for eid in ids:
        f_axis, h1 = h1s[eid]
        d_max = 0.0
        line_worst = 0.0
        for c, ch in enumerate(tr["channels"]):
            ours = frf[(eid, ch)]
            f = np.array([x[0] for x in ours])
            h = np.array([x[1] for x in ours])
            k = np.rint(f / (fs / n)).astype(int)
            if not np.allclose(f_axis[k], f, rtol=0, atol=1e-9):
                sys.exit(f"error: {eid} {ch}: frequency axes differ")
            ref = h1[c, k]
            d_max = max(d_max, np.abs(h - ref).max() / np.abs(ref).max())
            line_worst = max(line_worst, np.max(np.abs(h - ref) / np.abs(ref)))
        worst = max(worst, d_max)
        used = [h["hit"] for h in table[eid] if h["accepted"] or a.keep_rejected]
        h1_lines.append(f"  H1 {eid}: hits {used}: max |frf-est − pyFRF| / max|H| = {d_max:.2e}, "
                        f"worst line {line_worst:.2e}")
    # Detectors against the truth, all hits.
    det = pyFRF.FRF(int(fs), exc_type="f", resp_type="d", window="none", fft_len=n)
    truth = {"double": [], "overload": []}
    ours = {"double": [], "overload": []}
    theirs = {"double": [], "overload": []}
    for ei, e in enumerate(tr["excitations"]):
        block = sets[ei * n_hits * per_exc:(ei + 1) * n_hits * per_exc]
        exc = np.array([block[h * per_exc]["data"] for h in range(n_hits)])
        resp = np.array([[block[h * per_exc + 1 + c]["data"] for c in range(n_ch)] for h in range(n_hits)])
        try:
            dbl = det._is_double_impact(exc, limit=1e-3)
        except ValueError:          # needs ≥ ~2,000 samples (1 % of its second FFT)
            dbl = np.zeros(n_hits, bool)
        ovl = det._is_overflow(exc) | det._is_overflow(resp).any(axis=1)
        by_hit = {h["hit"]: h for h in table[e["id"]]}
        for k, h in enumerate(e["hits"]):
            truth["double"].append(h["double"] is not None)
            truth["overload"].append(h["clipped"])
            r = by_hit[h["hit"]]["reasons"]
            ours["double"].append(any(x.startswith("double hit") for x in r))
            ours["overload"].append(any(x.startswith("overload") for x in r))
            theirs["double"].append(bool(dbl[k]))
            theirs["overload"].append(bool(ovl[k]))
    f32 = len(sets) * n * 4
    print(f"{uff}: {len(sets)} records, {len(ids)} excitations × {n_hits} hits, {n} samples at {fs:g} Hz")
    print(f"  frf-est: {runs[-1][2]}")
    for line in h1_lines:
        print(line)
    print(f"  wall time UFF → FRFs, best of {a.repeat}: frf-est {wall:.3f} s, pyuff + pyFRF {min(t_py):.3f} s "
          f"(pyuff reading alone {min(t_reads):.3f} s): pyFRF's time / frf-est's = {min(t_py) / wall:.1f}")
    print(f"  frf-est peak RSS {rss / 1e6:.1f} MB = {rss / f32:.2f}× the recording's {len(sets) * n:,} samples "
          f"as float32 ({f32 / 1e6:.1f} MB)")
    return {w: (truth[w], ours[w], theirs[w]) for w in truth}, worst


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("uff", nargs="+",
                    help="per-hit time-history UFF written by rbref.py --time-layout per-hit (several with --frf-est)")
    ap.add_argument("--truth", required=True, nargs="+", help="its truth JSON (--truth), one per UFF")
    ap.add_argument("--h1", help="its numpy H1 (.npz output); without it only the detectors run")
    ap.add_argument("--frf-est", help="the frf-est binary: put it side by side with pyFRF (module docs)")
    ap.add_argument("--keep-rejected", action="store_true",
                    help="frf-est --keep-rejected (a detection study whose excitations have too few clean hits)")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs of each (best taken)")
    a = ap.parse_args(argv)
    if len(a.uff) != len(a.truth):
        sys.exit("error: give one --truth per UFF file")
    if a.frf_est:
        flags = {}
        worst = 0.0
        for uff, truth in zip(a.uff, a.truth):
            f, w = side_by_side(a, uff, json.load(open(truth))["recording"])
            worst = max(worst, w)
            for what, cols in f.items():
                acc = flags.setdefault(what, ([], [], []))
                for k in range(3):
                    acc[k].extend(cols[k])
        print(f"H1: worst max |frf-est − pyFRF| / max|H| over the files {worst:.2e}")
        print(f"detectors vs the truth, all {len(flags['double'][0])} hits of the {len(a.uff)} files:")
        for what in ("double", "overload"):
            confusion(f"{what} frf-est", flags[what][0], flags[what][1])
            confusion(f"{what} pyFRF", flags[what][0], flags[what][2])
        return 0
    a.uff, a.truth = a.uff[0], a.truth[0]
    import pyuff
    import pyFRF

    tr = json.load(open(a.truth))["recording"]
    fs, n = tr["sample_rate_hz"], tr["record_samples"]
    n_ch = len(tr["channels"])
    tau = tr["window"]["tau_s"]
    fs_int = int(fs)                      # pyFRF takes an int sampling frequency
    if fs_int != fs:
        sys.exit(f"error: {a.truth}: pyFRF needs an integer sampling frequency, got {fs}")
    t0 = time.perf_counter()
    sets = [s for s in pyuff.UFF(a.uff).read_sets() if s["type"] == 58]
    t_read = time.perf_counter() - t0
    if any(s["func_type"] != 1 for s in sets):
        sys.exit(f"error: {a.uff}: not a time-history file (function type 1)")
    per_exc = 1 + n_ch
    n_hits = tr["impacts"]
    if len(sets) != len(tr["excitations"]) * n_hits * per_exc:
        sys.exit(f"error: {a.uff}: {len(sets)} records, expected {len(tr['excitations'])} × {n_hits} × {per_exc} "
                 "(a per-hit layout)")
    idx = np.arange(n)
    results = []
    flags = {"double": ([], []), "overload": ([], [])}
    t_frf = 0.0
    for ei, e in enumerate(tr["excitations"]):
        t1 = time.perf_counter()
        block = sets[ei * n_hits * per_exc:(ei + 1) * n_hits * per_exc]
        exc = np.array([block[h * per_exc]["data"] for h in range(n_hits)])                 # (hits, N)
        resp = np.array([[block[h * per_exc + 1 + c]["data"] for c in range(n_ch)] for h in range(n_hits)])
        used = [h["hit"] - 1 for h in e["hits"] if h["accepted"]]
        we = np.empty((len(used), 1, n))
        wr = np.empty((len(used), n_ch, n))
        for j, h in enumerate(used):
            hit = e["hits"][h]
            n0 = hit["trigger_sample"]
            w = np.where(idx >= n0, np.exp(-(idx - n0) / (fs * tau)), 1.0) if tau else np.ones(n)
            wf = w if tr["window"]["apply_to_force"] else np.ones(n)
            rect = hit["windows"]["force_rectangle"]
            if rect:
                wf = wf * ((idx >= rect[0]) & (idx <= rect[1]))
            we[j, 0] = exc[h] * wf
            wr[j] = resp[h] * w[None, :]
        frf = pyFRF.FRF(fs_int, exc=we, resp=wr, exc_type="f", resp_type="d", window="none", frf_estimator="H1")
        h1 = frf.get_H1()[:, 0, :]                                                       # (n_ch, bins)
        t_frf += time.perf_counter() - t1 + t_read / len(tr["excitations"])
        det = pyFRF.FRF(fs_int, exc_type="f", resp_type="d", window="none", fft_len=n)
        try:
            dbl = det._is_double_impact(exc, limit=1e-3)
        except ValueError as err:    # pyFRF's check needs ≥ ~2,000 samples (1 % of its second FFT)
            print(f"  pyFRF's double-impact check failed on {e['id']} ({err}): counted as not flagged")
            dbl = np.zeros(n_hits, bool)
        ovl = det._is_overflow(exc) | det._is_overflow(resp).any(axis=1)
        flags["double"][0].extend(h["double"] is not None for h in e["hits"])
        flags["double"][1].extend(bool(x) for x in dbl)
        flags["overload"][0].extend(h["clipped"] for h in e["hits"])
        flags["overload"][1].extend(bool(x) for x in ovl)
        results.append((e["id"], h1, used))
    print(f"{a.uff}: {len(sets)} records, {len(tr['excitations'])} excitations × {n_hits} hits, "
          f"{n} samples at {fs:g} Hz")
    if a.h1:
        z = np.load(a.h1)
        bins = z["fft_bins"]
        ok = bins >= 1
        for ei, (eid, h1, used) in enumerate(results):
            ref = z["frf"][ei][:, ok]
            got = h1[:, bins[ok]]
            d = np.abs(got - ref).max() / np.abs(ref).max()
            line = np.max(np.abs(got - ref) / np.abs(ref))
            print(f"  H1 {eid}: hits {[u + 1 for u in used]}: max |pyFRF − numpy| / max|H| = {d:.2e}, "
                  f"worst line {line:.2e}")
    print("pyFRF detectors vs the truth (all hits):")
    confusion("double", *flags["double"])
    confusion("overload", *flags["overload"])
    print(f"wall time UFF → pyFRF FRFs: {t_frf:.2f} s (pyuff reading alone {t_read:.2f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
