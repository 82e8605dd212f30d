#!/usr/bin/env python3
"""Side by side with pyFRF 1.5 on a per-hit recording written by rbref.

    python3 scripts/refgen/rbref.py CASE.toml --time-layout per-hit -o rec.uff -o h1.npz --truth truth.json
    python3 scripts/refgen/compare_pyfrf.py rec.uff --truth truth.json --h1 h1.npz

Needs pyuff and pyFRF 1.5 (`pip install pyFRF==1.5`; the generator itself does not).
Prints, per excitation:
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
    print(f"  {name:<9} truth+ flagged {tp:5d} missed {fn:5d} | truth- flagged {fp:5d} passed {tn:5d}"
          f" | recall {rec:.3f} false alarms {fa:.3f}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("uff", help="per-hit time-history UFF written by rbref.py --time-layout per-hit")
    ap.add_argument("--truth", required=True, help="its truth JSON (--truth)")
    ap.add_argument("--h1", help="its numpy H1 (.npz output); without it only the detectors run")
    a = ap.parse_args(argv)
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
