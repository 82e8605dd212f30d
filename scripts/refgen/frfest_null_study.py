#!/usr/bin/env python3
"""Null study of `model-check` on `frf-est` output (issue 36's acceptance).

Exactly-nominal Test Case II impact tests from the independent generator
(`examples/tc2-impact-time.toml`: five hits per excitation, anti-alias filter, autoranged
ADC, exponential window), one recording per seed and ADC resolution, written as per-hit
time histories (UFF 58b type 1), turned into FRFs by `frf-est` with its defaults and
checked against the nominal spec. A recording passes when the check names nothing
(silent) and its final χ²/ν lies inside its noise band.

    python3 scripts/refgen/frfest_null_study.py --seeds 1001:1050 --bits 16,24 \\
        --bin target/release --out null-study.json

Seeds are fixed before the first run: 1001–1100 (the generator's example uses seed 2).
Prints one line per recording and a summary table (markdown) at the end.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))
CASE = os.path.join(HERE, "examples", "tc2-impact-time.toml")
SPEC = os.path.join(ROOT, "fixtures", "specs", "test-case-2.toml")


def run(cmd, **kw):
    r = subprocess.run(cmd, capture_output=True, text=True, **kw)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}: exit {r.returncode}: {r.stderr.strip()[-2000:]}")
    return r.stdout


def one(seed, bits, bindir, tmp, band):
    uff = os.path.join(tmp, f"s{seed}-{bits}.uff")
    mcap = os.path.join(tmp, f"s{seed}-{bits}.mcap")
    run([sys.executable, os.path.join(HERE, "rbref.py"), CASE, "--seed", str(seed),
         "--set", f"time.adc_bits={bits}", "--time-layout", "per-hit", "--binary",
         "-o", uff, "--quiet"])
    t0 = time.monotonic()
    run([os.path.join(bindir, "frf-est"), uff, "--band", band, "-o", mcap, "--force"])
    t1 = time.monotonic()
    out = json.loads(run([os.path.join(bindir, "model-check"), SPEC, "-i", mcap,
                          "--format", "json"]))
    t2 = time.monotonic()
    for f in (uff, mcap):
        os.remove(f)
    named = [a["id"] for a in out.get("accepted", [])]
    for fam in out.get("ambiguous", []) or []:
        named.append("{" + "|".join(fam.get("ids", [])) + "}")
    lo, hi = out["noise_band"]
    chi = out["chi2_nu_after"]
    return dict(seed=seed, bits=bits, named=named, chi2_nu=chi, band=[lo, hi],
                in_band=lo <= chi <= hi, floor=out.get("noise_floor_reached"),
                frf_est_s=round(t1 - t0, 2), check_s=round(t2 - t1, 2))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1001:1100", help="A:B inclusive")
    ap.add_argument("--bits", default="16,24")
    ap.add_argument("--bin", default=os.path.join(ROOT, "target", "release"),
                    help="directory holding frf-est and model-check")
    ap.add_argument("--band", default="0.01:12.5", help="frf-est --band")
    ap.add_argument("--out", help="JSON file of every result")
    a = ap.parse_args()
    s0, s1 = (int(x) for x in a.seeds.split(":"))
    bits = [int(b) for b in a.bits.split(",")]
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(s0, s1 + 1):
            for b in bits:
                try:
                    r = one(seed, b, a.bin, tmp, a.band)
                except RuntimeError as e:
                    r = dict(seed=seed, bits=b, error=str(e))
                results.append(r)
                print(json.dumps(r), flush=True)
                if a.out:
                    with open(a.out, "w") as f:
                        json.dump(results, f, indent=1)
    print("\n| ADC | recordings | silent | χ²/ν in band | floor reached | false claims | median check s | worst check s |")
    print("|---|---|---|---|---|---|---|---|")
    for b in bits:
        rs = [r for r in results if r["bits"] == b and "error" not in r]
        errors = sum(1 for r in results if r["bits"] == b and "error" in r)
        if not rs:
            continue
        ts = sorted(r["check_s"] for r in rs)
        claims = {}
        for r in rs:
            for n in r["named"]:
                claims[n] = claims.get(n, 0) + 1
        print(f"| {b}-bit | {len(rs)}{f' (+{errors} errors)' if errors else ''} | "
              f"{sum(not r['named'] for r in rs)} | {sum(r['in_band'] for r in rs)} | "
              f"{sum(bool(r['floor']) for r in rs)} | "
              f"{', '.join(f'{k} ×{v}' for k, v in sorted(claims.items())) or '—'} | "
              f"{ts[len(ts) // 2]:.1f} | {ts[-1]:.1f} |")


if __name__ == "__main__":
    main()
