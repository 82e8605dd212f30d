#!/usr/bin/env python3
"""The force noise's common error as frf-est states it, against the error it makes.

For each seed the independent generator (`rbref.py`, examples/tc2-impact-time.toml)
records the same hits twice: with its force noise only (response noise 0) and with no
noise at all (`--set time.force_noise=0 --set time.response_noise=0`; the pulses, onsets
and ADC ranges are the seed's either way). `frf-est --band 0.01:12.5` runs on both with
its defaults, and per excitation and line the relative error of the noisy FRFs,
`ε_c = Ĥ_c/Ĥ_c,clean − 1`, is compared with what frf-est wrote beside them
(`/rbprops/frf_variance` → `force_noise`, docs/conventions.md "FRF estimation"):

- common: the spread of ε over the channels at a line against its mean (a common error
  has them equal up to the response-free residue, ADC rounding);
- size: `mean |ε̄|²` over lines against `mean ρ²` (a ratio near 1 over many seeds);
- correlation: `E[ε̄_l ε̄*_{l+m}]/E|ε̄|²` at lags m against `γ(m Δf)` of the stated bins;
- the null: the `ρ²` frf-est states for the noise-free hits (the force's pretrigger
  holds only ADC rounding) against the `ρ²` of the noisy ones.

Usage: force_noise_study.py --seeds 9501:9520 [--bin target/release] [--json]
(`--json`: one JSON object of the figures on stdout instead of the tables.)
"""
import argparse
import base64
import csv
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
CASE = os.path.join(HERE, "examples", "tc2-impact-time.toml")


def run(cmd):
    r = subprocess.run(cmd, capture_output=True)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd[:2])}: {r.stderr.decode()[-1500:]}")


def estimate(seed, bindir, tmp, tag, extra):
    uff = os.path.join(tmp, f"{tag}.uff")
    out = os.path.join(tmp, tag)
    run([sys.executable, os.path.join(HERE, "rbref.py"), CASE, "--seed", str(seed), "--quiet",
         "--time-layout", "per-hit", "--binary", "-o", uff, *extra])
    run([os.path.join(bindir, "frf-est"), uff, "--band", "0.01:12.5", "-o", out, "--force"])
    frf = {}
    for r in csv.DictReader(open(os.path.join(out, "frf.csv"))):
        frf.setdefault(r["excitation"], {}).setdefault(r["channel"], []).append(
            complex(float(r["re"]), float(r["im"])))
    freqs = sorted({float(r["frequency_hz"]) for r in csv.DictReader(open(os.path.join(out, "frf.csv")))})
    common = {}
    for r in csv.DictReader(open(os.path.join(out, "frf_variance.csv"))):
        ex = r["excitation"]
        rho2 = np.frombuffer(base64.b64decode(r["force_noise.relative_variance_f64le"]), "<f8")[::2] \
            if "force_noise.relative_variance_f64le" in r else None
        common[ex] = {"rho2": rho2}
    for part in ("times_s", "weights"):
        path = os.path.join(out, f"frf_variance_force_noise_window_{part}.csv")
        if not os.path.exists(path):
            continue
        for r in csv.DictReader(open(path)):
            common[r["excitation"]].setdefault(part, []).append(float(r["value"]))
    return frf, common, np.array(freqs)


def gamma(c, df):
    t, w = np.array(c["times_s"]), np.array(c["weights"])
    return np.sum(w * np.exp(-2j * np.pi * df * t))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="9501:9520")
    ap.add_argument("--bin", default=os.path.join(HERE, "..", "..", "target", "release"))
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    s0, s1 = (int(x) for x in a.seeds.split(":"))
    lags = [1, 4, 16, 64, 160]
    ratios, spreads, corr, pred = [], [], {m: [] for m in lags}, {m: [] for m in lags}
    null_ratios = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(s0, s1 + 1):
            noisy, common, f = estimate(seed, a.bin, tmp, "noisy", ["--set", "time.response_noise=0"])
            clean, clean_common, _ = estimate(seed, a.bin, tmp, "clean",
                                   ["--set", "time.force_noise=0", "--set", "time.response_noise=0"])
            df = f[1] - f[0]
            for ex, chans in noisy.items():
                eps = np.array([np.array(chans[c]) / np.array(clean[ex][c]) - 1 for c in chans])
                mean = eps.mean(axis=0)
                spreads.append(np.sqrt(np.mean(np.abs(eps - mean) ** 2) / np.mean(np.abs(mean) ** 2)))
                rho2 = common[ex]["rho2"]
                ratios.append(np.mean(np.abs(mean) ** 2) / np.mean(rho2))
                # No force_noise written for the noise-free hits counts as ρ² = 0.
                null_rho2 = clean_common[ex]["rho2"]
                null_ratios.append(0.0 if null_rho2 is None else np.mean(null_rho2) / np.mean(rho2))
                for m in lags:
                    corr[m].append(np.mean(mean[:-m] * np.conj(mean[m:])) / np.mean(np.abs(mean) ** 2))
                    pred[m].append(gamma(common[ex], m * df))
            print(json.dumps({"seed": seed, "size_ratio": ratios[-3:]}), file=sys.stderr, flush=True)
    r = np.array(ratios)
    if a.json:
        print(json.dumps({
            "excitations": len(r),
            "size_ratio_mean": float(r.mean()),
            "size_ratio_se": float(r.std(ddof=1) / np.sqrt(len(r))),
            "spread_median": float(np.median(spreads)),
            "spread_worst": float(max(spreads)),
            "null_ratio_worst": float(max(null_ratios)),
            "correlation": {str(m): [float(np.mean(np.real(corr[m]))),
                                     float(np.mean(np.real(pred[m])))] for m in lags},
        }))
        return
    print(f"\n{len(r)} excitations over {s1 - s0 + 1} seeds")
    print(f"channel spread of ε about its mean / |ε̄| (RMS): median {np.median(spreads):.2e}, worst {max(spreads):.2e}")
    print(f"mean |ε̄|² / mean ρ²: mean {r.mean():.3f}, median {np.median(r):.3f}, "
          f"5–95 % {np.quantile(r, 0.05):.3f}–{np.quantile(r, 0.95):.3f}")
    print(f"stated ρ² of the noise-free hits / of the noisy ones: worst {max(null_ratios):.2e}")
    print("\n| lag (lines) | Re of measured correlation (mean over excitations) | stated γ (mean) |")
    print("|---|---|---|")
    for m in lags:
        print(f"| {m} | {np.mean(np.real(corr[m])):.3f} | {np.mean(np.real(pred[m])):.3f} |")


if __name__ == "__main__":
    main()
