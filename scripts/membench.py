#!/usr/bin/env python3
"""Memory bench of the pipeline stages (issue 41): peak RSS and time of every stage, each
run as a whole process on `frf-sim` output, as the number of excitations and of lines
grows.

Two sweeps of the `demo` campaign (Test Case II, 1 % noise, 9 channels):
  - excitations 3, 12, 48, 192 at 1,601 lines (the demo's three forces, then copies of them
    moved by up to 2 cm, so that every set-up fit sees the same modes);
  - lines 1,601, 6,401, 25,601, 102,401 at 3 excitations.
Each stage runs under `/usr/bin/time -f '%M %e %U %S'` (peak RSS in kB, wall, user, system
seconds) with its input a file: `frf-sim SPEC -o frf.mcap`, `modal-fit frf.mcap -o
modal.mcap`, `ni-select modal.mcap -o sel.mcap`, `rb-solve sel.mcap -o est.mcap` (default
bootstrap) and `rb-solve --uncertainty linearised`.

The bound of the issue: peak RSS ≤ 2 × the largest excitation's data + 50 MB, the data of
one excitation being channels × lines complex f64 values (16 bytes each).

usage: scripts/membench.py [--bin target/release] [--work DIR] [--quick] [--markdown]
                           [--max-excitations N] [--max-lines N]
"""
import argparse
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

CHANNELS = 9
STAGES = ["frf-sim", "modal-fit", "ni-select", "rb-solve", "rb-solve linearised"]


def spec_text(frf_sim: Path, excitations: int, lines: int) -> str:
    base = subprocess.run([str(frf_sim), "--example", "demo", "--print-spec"], check=True,
                          capture_output=True, text=True).stdout
    text = base.replace("lines = 1601", f"lines = {lines}")
    blocks = re.findall(r"\[\[excitation\]\]\n(?:[^\[\n].*\n)*", base)
    if len(blocks) != 3:
        sys.exit("error: expected the demo's three [[excitation]] blocks")
    extra = []
    for k in range(3, excitations):
        b = blocks[k % 3]
        # Move the copy along the face it acts on by up to ±2 cm (deterministic).
        dx, dy = 0.004 * ((k // 3) % 5 - 2), 0.004 * ((k // 15) % 5 - 2)

        def moved(m: re.Match) -> str:
            x, y, z = (float(v) for v in m.group(1).split(","))
            return f"at_m = [{x + dx!r}, {y + dy!r}, {z!r}]"

        b = re.sub(r'id = "(force\d+)"', f'id = "force{k + 1}"', b)
        b = re.sub(r"at_m = \[([^\]]*)\]", moved, b)
        extra.append(b)
    return text.rstrip("\n") + "\n\n" + "\n".join(extra)


def timed(cmd: list, cwd: Path) -> dict:
    r = subprocess.run(["/usr/bin/time", "-f", "%M %e %U %S"] + cmd, cwd=cwd,
                       capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"error: {' '.join(cmd)} failed:\n{r.stderr}")
    kb, wall, user, system = r.stderr.strip().splitlines()[-1].split()
    return {"rss_mb": int(kb) / 1024, "wall_s": float(wall), "cpu_s": float(user) + float(system)}


def run_case(bin_dir: Path, work: Path, excitations: int, lines: int) -> dict:
    case = work / f"e{excitations}_l{lines}"
    case.mkdir(parents=True, exist_ok=True)
    (case / "spec.toml").write_text(spec_text(bin_dir / "frf-sim", excitations, lines))
    b = lambda s: str(bin_dir / s)
    out = {
        "frf-sim": timed([b("frf-sim"), "spec.toml", "-o", "frf.mcap"], case),
        "modal-fit": timed([b("modal-fit"), "frf.mcap", "-o", "modal.mcap"], case),
        "ni-select": timed([b("ni-select"), "modal.mcap", "-o", "sel.mcap"], case),
        "rb-solve": timed([b("rb-solve"), "sel.mcap", "-o", "est.mcap"], case),
        "rb-solve linearised": timed([b("rb-solve"), "sel.mcap", "--uncertainty", "linearised",
                                      "-o", "lin.mcap"], case),
    }
    out["record_mb"] = (case / "frf.mcap").stat().st_size / 2**20
    shutil.rmtree(case)
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", default="target/release", type=Path)
    ap.add_argument("--work", type=Path)
    ap.add_argument("--quick", action="store_true", help="the two smallest of each sweep")
    ap.add_argument("--markdown", action="store_true")
    ap.add_argument("--max-excitations", type=int, default=192)
    ap.add_argument("--max-lines", type=int, default=102401)
    a = ap.parse_args()
    exc = [3, 12, 48, 192]
    lines = [1601, 6401, 25601, 102401]
    if a.quick:
        exc, lines = exc[:2], lines[:2]
    exc = [e for e in exc if e <= a.max_excitations]
    lines = [n for n in lines if n <= a.max_lines]
    cases = [(e, 1601) for e in exc] + [(3, n) for n in lines if n != 1601]
    work = a.work or Path(tempfile.mkdtemp(prefix="membench."))
    rows = []
    for e, n in cases:
        r = run_case(a.bin.resolve(), work, e, n)
        one_mb = CHANNELS * n * 16 / 2**20
        r.update(excitations=e, lines=n, bound_mb=2 * one_mb + 50)
        rows.append(r)
        print(f"# {e} excitations × {n} lines done", file=sys.stderr)
    if a.markdown:
        print("| excitations × lines | record MB | bound MB | " +
              " | ".join(f"{s} MB (s)" for s in STAGES) + " |")
        print("|---" * (3 + len(STAGES)) + "|")
        for r in rows:
            cells = []
            for s in STAGES:
                m = r[s]
                flag = "" if m["rss_mb"] <= r["bound_mb"] else " ✗"
                cells.append(f"{m['rss_mb']:.0f}{flag} ({m['wall_s']:.2f})")
            print(f"| {r['excitations']} × {r['lines']:,} | {r['record_mb']:.1f} | "
                  f"{r['bound_mb']:.0f} | " + " | ".join(cells) + " |")
    else:
        for r in rows:
            print(r)


if __name__ == "__main__":
    main()
