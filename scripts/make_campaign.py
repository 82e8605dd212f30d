#!/usr/bin/env python3
"""Write N campaign specs under DIR: variations of a built-in campaign (default `demo`).

Each spec scales the mass and inertia, moves the centre of mass, scales the spring
stiffnesses and changes the noise seed, deterministically from its index, so that
`rbprops campaign DIR` has a realistic batch to run.

usage: scripts/make_campaign.py N DIR [--example demo] [--frf-sim target/release/frf-sim]
"""
import argparse
import random
import re
import subprocess
from pathlib import Path


def scale_list(match: re.Match, factor: float) -> str:
    values = [float(v) * factor for v in match.group(2).split(",")]
    return f"{match.group(1)}[{', '.join(repr(v) for v in values)}]"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("n", type=int)
    ap.add_argument("dir", type=Path)
    ap.add_argument("--example", default="demo")
    ap.add_argument("--frf-sim", default="target/release/frf-sim")
    a = ap.parse_args()
    base = subprocess.run([a.frf_sim, "--example", a.example, "--print-spec"], check=True, capture_output=True, text=True).stdout
    a.dir.mkdir(parents=True, exist_ok=True)
    for i in range(a.n):
        rng = random.Random(i)
        s = rng.uniform(0.8, 1.25)
        text = re.sub(r"(?m)^seed = \d+", f"seed = {1000 + i}", base)
        text = re.sub(r"(?m)^name = \"[^\"]*\"", f'name = "{a.example}-{i:04d}"', text)
        text = re.sub(r"(?m)^mass_kg = ([0-9.eE+-]+)", lambda m: f"mass_kg = {float(m.group(1)) * s!r}", text)
        text = re.sub(r"(?m)^(moments_kg_m2 = )\[([^\]]*)\]", lambda m: scale_list(m, s), text)
        text = re.sub(r"(?m)^products_kg_m2 = \{([^}]*)\}", lambda m: "products_kg_m2 = { " + ", ".join(f"{kv.split('=')[0].strip()} = {float(kv.split('=')[1]) * s!r}" for kv in m.group(1).split(",")) + " }", text)
        text = re.sub(r"(?m)^(com_m = )\[([^\]]*)\]", lambda m: "com_m = [" + ", ".join(repr(float(v) + rng.uniform(-0.01, 0.01)) for v in m.group(2).split(",")) + "]", text)
        k = rng.uniform(0.8, 1.2)
        text = re.sub(r"(?m)^(stiffness_n_per_m = )\[([^\]]*)\]", lambda m: scale_list(m, k), text)
        (a.dir / f"{a.example}-{i:04d}.toml").write_text(text)


if __name__ == "__main__":
    main()
