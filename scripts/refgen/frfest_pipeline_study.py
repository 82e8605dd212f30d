#!/usr/bin/env python3
"""Rigid-body properties from raw impact time histories against the same pipeline on
the generator's own FRFs (issue 36's acceptance: errors within 1.2x).

Per seed, Test Case II recorded as `examples/tc2-impact-time.toml` records it (five hits
per excitation, anti-alias filter, autoranged ADC, white force and response noise), then
the same `modal-fit | ni-select | rb-solve` on

  raw:   `frf-est` over the per-hit time histories (UFF 58b), its defaults and
         `--band 0.01:12.5` (it finds the hits, checks them, picks τ, carries the window
         and each line's variance to modal-fit);
  ideal: the generator's numpy H1 over the same five hits with its own windows (it knows
         where each hit is and which τ it applied: `modal-fit --exp-window τ`), the
         same physics and the same noise realisation — the FRFs an analyser that knew
         everything would make;
  exact: the generator's exact FRFs (no time simulation, no noise), the floor.

Errors against the truth: mass (%), centre of mass (mm, Euclidean), inertia about the
centre of mass (% of the largest moment about the centre-of-mass axes, max over the six
entries). Prints one
line per seed and the RMS over the seeds of each error, and raw/ideal ratios.

    python3 scripts/refgen/frfest_pipeline_study.py --seeds 2001:2020 --bin target/release

Seeds are fixed before the first run: 2001–2020 at 24 bit.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
CASE = os.path.join(HERE, "examples", "tc2-impact-time.toml")
SPEC = os.path.abspath(os.path.join(HERE, "..", "..", "fixtures", "specs", "test-case-2.toml"))
BAND = "0.01:12.5"


def run(cmd, stdin=None):
    r = subprocess.run(cmd, input=stdin, capture_output=True)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}: exit {r.returncode}: {r.stderr.decode()[-1500:]}")
    return r.stdout


def pipeline(bindir, frfs, fit_args):
    b = lambda n: os.path.join(bindir, n)
    m = run([b("modal-fit"), frfs, "--band", BAND, *fit_args])
    n = run([b("ni-select")], m)
    out = json.loads(run([b("rb-solve"), "--format", "json"], n))
    return out[0]


def errors(est, truth):
    p = truth["properties"]
    mass = 100 * (est["mass_kg"] - p["mass_kg"]) / p["mass_kg"]
    com = 1e3 * math.dist(est["com_m"], p["com_m"])
    j, jt = est["inertia_cm_kg_m2"], p["inertia_cm_kg_m2"]
    scale = max(p["moments_kg_m2"])
    jerr = max(abs(j[a][b] - jt[a][b]) for a in range(3) for b in range(3)) / scale * 100
    return mass, com, jerr


def one(seed, bits, bindir, tmp):
    gen = [sys.executable, os.path.join(HERE, "rbref.py"), CASE, "--seed", str(seed),
           "--set", f"time.adc_bits={bits}", "--quiet"]
    th, h1, exact = (os.path.join(tmp, f"{k}.uff") for k in ("th", "h1", "exact"))
    truth = os.path.join(tmp, "truth.json")
    run(gen + ["--time-layout", "per-hit", "--binary", "-o", th, "--truth", truth])
    run(gen + ["-o", h1])
    # The same case without its [time] and [window] tables: the exact FRFs.
    exact_case = os.path.join(tmp, "exact.toml")
    with open(exact_case, "w") as f:
        f.write(f'spec = "{SPEC}"\nname = "tc2-exact"\ngravity_m_s2 = 0.0\n'
                '[noise]\nrelative = 0.0\n')
    run([sys.executable, os.path.join(HERE, "rbref.py"), exact_case, "--seed", str(seed),
         "--quiet", "-o", exact])
    t = json.load(open(truth))
    est_mcap = os.path.join(tmp, "est.mcap")
    run([os.path.join(bindir, "frf-est"), th, "--band", BAND, "-o", est_mcap, "--force"])
    res = {"seed": seed, "bits": bits}
    res["raw"] = errors(pipeline(bindir, est_mcap, []), t)
    res["ideal"] = errors(pipeline(bindir, h1, ["--exp-window", str(t["window_tau_s"])]), t)
    res["exact"] = errors(pipeline(bindir, exact, []), t)
    for f in (th, h1, exact, est_mcap, truth):
        os.remove(f)
    return res


def rms(xs):
    return math.sqrt(sum(x * x for x in xs) / len(xs))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="2001:2020", help="A:B inclusive")
    ap.add_argument("--bits", type=int, default=24)
    ap.add_argument("--bin", default=os.path.join(HERE, "..", "..", "target", "release"))
    ap.add_argument("--out", help="JSON file of every result")
    a = ap.parse_args()
    s0, s1 = (int(x) for x in a.seeds.split(":"))
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(s0, s1 + 1):
            r = one(seed, a.bits, a.bin, tmp)
            results.append(r)
            print(json.dumps(r), flush=True)
            if a.out:
                json.dump(results, open(a.out, "w"), indent=1)
    print(f"\n{len(results)} recordings ({a.bits}-bit), RMS over the seeds:\n")
    print("| FRFs | mass % | CoM mm | J % of the largest moment |")
    print("|---|---|---|---|")
    for k in ("raw", "ideal", "exact"):
        cols = [rms([r[k][i] for r in results]) for i in range(3)]
        print(f"| {k} | {cols[0]:.4f} | {cols[1]:.3f} | {cols[2]:.4f} |")
    ratio = [rms([r["raw"][i] for r in results]) / rms([r["ideal"][i] for r in results])
             for i in range(3)]
    print(f"| raw / ideal | {ratio[0]:.2f} | {ratio[1]:.2f} | {ratio[2]:.2f} |")


if __name__ == "__main__":
    main()
