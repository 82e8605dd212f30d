#!/usr/bin/env python3
"""rbref: independent reference generator of rigid-body FRF recordings (see README.md).

Usage:
    rbref.py CASE.toml|CASE.json|SPEC.toml [-o OUT.uff|OUT.json|OUT.npz ...]
             [--truth TRUTH.json] [--binary] [--nodes auto|15|2411] [--seed N | --seeds A:B]
             [--set PATH=VALUE ...] [--precision float64|float32] [--quiet]
             [--time-layout per-hit|throughput]

Writes each output named with -o (the format follows the extension; .uff/.unv = UFF 58,
ASCII unless --binary) and the truth JSON. --set changes one case field after the merge
with the spec (VALUE is JSON, else a string; lists of tables by id), e.g.
`--set noise.relative=0.01 --set sensor.2.misorientation_rad=[0.03,0,0]`. --seeds A:B
writes one set of files per seed A..B (inclusive) in one run; every output name must then
contain {seed}. With --time-layout (a case with [time]), .uff/.unv outputs hold the
recorded time histories (UFF 58 function type 1) per hit or as one continuous record per
channel, and .json/.npz the numpy H1 of those samples. Errors go to stderr as `error: ...` with exit status 1 and no output file
written.
"""
import argparse
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import rbref  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(prog="rbref.py", description=__doc__.split("\n")[0])
    ap.add_argument("case", help="case file (TOML or JSON), or an rbprops campaign spec")
    ap.add_argument("-o", "--output", action="append", default=[],
                    help="output file: .uff/.unv (UFF 58), .json or .npz; may repeat")
    ap.add_argument("--truth", help="truth JSON output")
    ap.add_argument("--binary", action="store_true", help="UFF 58b binary instead of ASCII")
    ap.add_argument("--nodes", choices=["auto", "15", "2411"], default="auto",
                    help="UFF node dataset (auto: 15 unless coordinates need 2411's precision)")
    ap.add_argument("--seed", type=int, help="override the case's seed")
    ap.add_argument("--seeds", help="A:B — one output set per seed A..B; names contain {seed}")
    ap.add_argument("--set", action="append", default=[], metavar="PATH=VALUE",
                    help="set a case field (dotted path; JSON value); may repeat")
    ap.add_argument("--precision", choices=["float64", "float32"], help="override output.precision")
    ap.add_argument("--quiet", action="store_true")
    ap.add_argument("--time-layout", choices=["per-hit", "throughput"],
                    help="write the recorded time histories to .uff/.unv outputs (UFF 58 type 1): one "
                         "record per hit and channel, or one continuous record per channel")
    a = ap.parse_args(argv)
    if not a.output and not a.truth:
        ap.error("nothing to write: give -o and/or --truth")
    for o in a.output:
        if os.path.splitext(o)[1].lower() not in (".uff", ".unv", ".json", ".npz"):
            ap.error(f"{o}: unknown output extension (use .uff, .unv, .json or .npz)")
    for o in a.output + ([a.truth] if a.truth else []):
        d = os.path.dirname(os.path.abspath(o))
        if not os.path.isdir(d):
            ap.error(f"{o}: directory {d} does not exist")
    seeds = None
    if a.seeds:
        try:
            lo, hi = (int(x) for x in a.seeds.split(":"))
        except ValueError:
            ap.error(f"--seeds {a.seeds!r}: expected A:B (integers)")
        if a.seed is not None or hi < lo:
            ap.error("--seeds needs A ≤ B and no --seed")
        seeds = range(lo, hi + 1)
        for o in a.output + ([a.truth] if a.truth else []):
            if "{seed}" not in o:
                ap.error(f"{o}: with --seeds every output name must contain {{seed}}")
    settings = []
    for s in a.set:
        if "=" not in s:
            ap.error(f"--set {s!r}: expected PATH=VALUE")
        k, v = s.split("=", 1)
        try:
            v = json.loads(v)
        except json.JSONDecodeError:
            pass
        settings.append((k.strip(), v))
    try:
        overrides = {}
        if a.seed is not None:
            overrides["seed"] = a.seed
        if a.precision is not None:
            overrides["output"] = {"precision": a.precision}
        case = rbref.load(a.case, overrides, settings)
        if a.time_layout and case.time is None:
            raise rbref.CaseError("time: --time-layout needs a [time] table in the case")
        terms = rbref.Terms(case)
        for seed in seeds or [None]:
            result = rbref.generate(case, terms=terms, seed=seed, recording=True if a.time_layout else None)
            name = (lambda o: o.replace("{seed}", str(seed))) if seed is not None else (lambda o: o)
            if a.time_layout and any(os.path.splitext(o)[1].lower() in (".uff", ".unv") for o in a.output):
                rbref.writers.check_time_uff(result)
            for o in a.output:
                ext = os.path.splitext(o)[1].lower()
                if ext in (".uff", ".unv") and a.time_layout:
                    rbref.write_time_uff(result, name(o), layout=a.time_layout, binary=a.binary,
                                         node_dataset=a.nodes)
                elif ext in (".uff", ".unv"):
                    rbref.write_uff(result, name(o), binary=a.binary, node_dataset=a.nodes)
                elif ext == ".json":
                    rbref.write_json(result, name(o))
                else:
                    rbref.write_npz(result, name(o))
            if a.truth:
                rbref.write_truth(result, name(a.truth))
    except (rbref.CaseError, ValueError) as e:
        print(f"error: {a.case}: {e}" if not str(e).startswith(a.case) else f"error: {e}", file=sys.stderr)
        return 1
    except OSError as e:
        print(f"error: {e.filename or ''}: {e.strerror}", file=sys.stderr)
        return 1
    if not a.quiet:
        for s in result.truth["setups"]:
            fs = ", ".join(f"{m['frequency_hz']:.4g}" for m in s["modes"])
            print(f"set-up {s['setup']}: modes [{fs}] Hz, free directions {s['free_directions']}",
                  file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
