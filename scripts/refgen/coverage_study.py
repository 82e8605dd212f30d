#!/usr/bin/env python3
"""Coverage of rb-solve's 95 % intervals on the independent generator's recordings
(issue 41: the bootstrap's calibration, checked beyond frf-sim's own output).

Per seed, Test Case II on its springs (modal damping, no gravity) with 1 % complex
Gaussian noise on every FRF value, written by the reference generator (`rbref.py`, its
own numpy formulation, float32 UFF as analysers export), then `modal-fit | ni-select`
and `rb-solve` twice on the same selection: `--uncertainty bootstrap` (the default) and
`--uncertainty linearised`. A property's interval covers when
|estimate − truth| ≤ 1.96 σ; the study counts, per estimator and uncertainty, how often
each of the ten properties (m, c, the six inertia entries about the centre of mass) is
covered, and prints the spread of the errors over the seeds in units of the RMS
reported σ (`sd/σ`, 1 when σ is right) and the mean error in the same unit (`bias/σ`).

With `--impact` each recording is instead an impact test (`examples/tc2-impact-time.toml`:
five hits per excitation, 24-bit ADC, force and response noise, exponential window)
written as per-hit time histories and turned into FRFs by `frf-est` (its defaults,
`--band 0.01:12.5`), whose line variances the bootstrap then draws from.

With `--exact` the recording carries no noise (the float32 quantisation only; the seed
then changes nothing, so one is run): a null on which every error must stay at the
generator's precision, printed as the relative error and the error in reported σ.

    python3 scripts/refgen/coverage_study.py --seeds 8001:8200 --bin target/release

Seeds fixed before the first run: 8001–8200.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
SPEC = os.path.abspath(os.path.join(HERE, "..", "..", "fixtures", "specs", "test-case-2.toml"))
IMPACT_CASE = os.path.join(HERE, "examples", "tc2-impact-time.toml")
BAND = "0.01:12.5"
PROPS = ["m", "cx", "cy", "cz", "Jxx", "Jyy", "Jzz", "Jxy", "Jxz", "Jyz"]
PAIRS = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]
UNCERTAINTIES = ["bootstrap", "linearised"]


def run(cmd, stdin=None):
    r = subprocess.run(cmd, input=stdin, capture_output=True)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd[:2])}: exit {r.returncode}: {r.stderr.decode()[-1500:]}")
    return r.stdout


def vector(est, std):
    """The ten properties (or their σ) of one rb-solve estimate, in PROPS order."""
    if std:
        m, c, j = est["mass_std_kg"], est["com_std_m"], est["inertia_cm_std_kg_m2"]
    else:
        m, c, j = est["mass_kg"], est["com_m"], est["inertia_cm_kg_m2"]
    return [m, *c, *(j[a][b] for a, b in PAIRS)]


def covered_either(est, x, s, t):
    """Per property: the truth inside the noise interval ±1.96σ or inside rb-solve's
    systematic 95 % interval (the jackknife it adds when the modes are not rigid-body
    consistent), when it gives one."""
    sys_ = est.get("systematic")
    inside = [abs(a - b) <= 1.96 * c for a, b, c in zip(x, t, s)]
    if not sys_:
        return inside
    j = sys_["inertia_cm_95_kg_m2"]
    bounds = [sys_["mass_95_kg"], *sys_["com_95_m"], *(j[a][b] for a, b in PAIRS)]
    return [i or lo <= v <= hi for i, (lo, hi), v in zip(inside, bounds, t)]


def truth_vector(t):
    p = t["properties"]
    j = p["inertia_cm_kg_m2"]
    return [p["mass_kg"], *p["com_m"], *(j[a][b] for a, b in PAIRS)]


def recording(seed, bindir, tmp, exact, impact):
    """The recording of `seed` to fit (its path and modal-fit's extra arguments) and its
    truth file."""
    uff, truth = os.path.join(tmp, "r.uff"), os.path.join(tmp, "truth.json")
    gen = [sys.executable, os.path.join(HERE, "rbref.py")]
    if impact:
        run(gen + [IMPACT_CASE, "--seed", str(seed), "--quiet", "--time-layout", "per-hit",
                   "--binary", "-o", uff, "--truth", truth])
        frfs = os.path.join(tmp, "est.mcap")
        run([os.path.join(bindir, "frf-est"), uff, "--band", BAND, "-o", frfs, "--force"])
        os.remove(uff)
        return frfs, ["--band", BAND], truth
    case = os.path.join(tmp, "case.toml")
    with open(case, "w") as f:
        f.write(f'spec = "{SPEC}"\nname = "tc2-coverage"\ngravity_m_s2 = 0.0\n'
                f'[noise]\nrelative = {0.0 if exact else 0.01}\n'
                '[output]\nprecision = "float32"\n')
    run(gen + [case, "--seed", str(seed), "--quiet", "-o", uff, "--truth", truth])
    return uff, [], truth


def one(seed, bindir, tmp, exact, impact):
    frfs, fit_args, truth = recording(seed, bindir, tmp, exact, impact)
    b = lambda n: os.path.join(bindir, n)
    sel = run([b("ni-select")], run([b("modal-fit"), frfs, *fit_args]))
    t = truth_vector(json.load(open(truth)))
    res = {"seed": seed}
    for u in UNCERTAINTIES:
        for est in json.loads(run([b("rb-solve"), "--format", "json", "--uncertainty", u], sel)):
            if est.get("errors"):
                res[f"{est['method']}/{u}"] = {"error": est["errors"]}
                continue
            x, s = vector(est, False), vector(est, True)
            res[f"{est['method']}/{u}"] = {"err": [a - b for a, b in zip(x, t)], "sigma": s,
                                           "truth": t}
            if u == "bootstrap":
                res[f"{est['method']}/{u}"]["covered_either"] = covered_either(est, x, s, t)
                res[f"{est['method']}/{u}"]["systematic"] = bool(est.get("systematic"))
    os.remove(frfs)
    os.remove(truth)
    return res


def summary(results, exact):
    keys = sorted({k for r in results for k in r if k != "seed"})
    if exact:
        print("\nThe exact recording (|error| / |truth|; |error| / σ):\n")
        print("| estimator/uncertainty | " + " | ".join(PROPS) + " |")
        print("|---" * (len(PROPS) + 1) + "|")
        for k in keys:
            x = results[0][k]
            if "err" not in x:
                print(f"| {k} | {x['error']} |")
                continue
            cells = [f"{abs(x['err'][i] / x['truth'][i]):.1e}; {abs(x['err'][i]) / x['sigma'][i]:.1f}"
                     for i in range(len(PROPS))]
            print(f"| {k} | " + " | ".join(cells) + " |")
        return
    print(f"\nCoverage of ±1.96σ over {len(results)} recordings (95 % expected):\n")
    print("| estimator/uncertainty | runs | " + " | ".join(PROPS) + " |")
    print("|---" * (len(PROPS) + 2) + "|")
    for k in keys:
        rows = [r[k] for r in results if "err" in r.get(k, {})]
        cov = [sum(abs(x["err"][i]) <= 1.96 * x["sigma"][i] for x in rows) / len(rows)
               for i in range(len(PROPS))]
        print(f"| {k} | {len(rows)} | " + " | ".join(f"{100 * c:.0f} %" for c in cov) + " |")
        either = [x["covered_either"] for x in rows if "covered_either" in x]
        if either:
            cov = [sum(e[i] for e in either) / len(either) for i in range(len(PROPS))]
            n_sys = sum(bool(x.get("systematic")) for x in rows)
            print(f"| {k} or systematic ({n_sys} given) | {len(either)} | "
                  + " | ".join(f"{100 * c:.0f} %" for c in cov) + " |")
    print("\nSpread and bias of the errors in units of the RMS reported σ (sd/σ, bias/σ):\n")
    print("| estimator/uncertainty | " + " | ".join(PROPS) + " |")
    print("|---" * (len(PROPS) + 1) + "|")
    for k in keys:
        rows = [r[k] for r in results if "err" in r.get(k, {})]
        cells = []
        for i in range(len(PROPS)):
            e = [x["err"][i] for x in rows]
            s = math.sqrt(sum(x["sigma"][i] ** 2 for x in rows) / len(rows))
            mean = sum(e) / len(e)
            sd = math.sqrt(sum((v - mean) ** 2 for v in e) / (len(e) - 1))
            cells.append(f"{sd / s:.2f}, {mean / s:+.2f}")
        print(f"| {k} | " + " | ".join(cells) + " |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="8001:8200", help="A:B inclusive")
    ap.add_argument("--bin", default=os.path.join(HERE, "..", "..", "target", "release"))
    ap.add_argument("--exact", action="store_true", help="no noise: the null")
    ap.add_argument("--impact", action="store_true",
                    help="impact tests: time histories through frf-est (its line variances)")
    ap.add_argument("--out", help="JSON file of every result")
    a = ap.parse_args()
    s0, s1 = (int(x) for x in a.seeds.split(":"))
    if a.exact:
        s1 = s0
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(s0, s1 + 1):
            results.append(one(seed, a.bin, tmp, a.exact, a.impact))
            print(json.dumps({"seed": seed}), file=sys.stderr, flush=True)
            if a.out:
                json.dump(results, open(a.out, "w"), indent=1)
    summary(results, a.exact)


if __name__ == "__main__":
    main()
