#!/usr/bin/env python3
"""Proves that pyuff (an independent reader) reads what rbprops writes.

Usage:
    python3 scripts/check_uff_with_pyuff.py <file.uff> <expected.json>

<expected.json> is committed beside the .uff; the rbprops-uff test
`writer_gives_the_committed_files_for_the_pyuff_check` checks that our writer still gives
both byte for byte (RBPROPS_BLESS=1 rewrites them, straight from the campaign that was
written, not from the file). Checked with pyuff:
  - node labels and coordinates (dataset 2411 or 15),
  - for every FRF (dataset 58/58b, in writing order): response/reference node, the
    global response/reference direction (± axis of the node's displacement coordinate
    system, from dataset 2420), the frequency axis and the complex values, each within
    the JSON's tolerances,
  - dataset 164 is SI.
Exits 0 when everything matches, 1 with a list of mismatches otherwise, 2 on usage errors.
Needs `pip install pyuff numpy`.
"""
import json
import sys

import numpy as np
import pyuff


def main():
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    path, expected_path = sys.argv[1], sys.argv[2]
    with open(expected_path) as fh:
        exp = json.load(fh)
    sets = pyuff.UFF(path).read_sets()
    if isinstance(sets, dict):
        sets = [sets]
    problems = []

    def check(cond, what):
        if not cond:
            problems.append(what)

    units = [s for s in sets if s.get("type") == 164]
    check(len(units) == 1 and units[0]["units_code"] == 1
          and units[0]["length"] == 1.0 and units[0]["force"] == 1.0,
          "dataset 164 is not a single SI unit record")

    # Coordinate systems: label -> rows (local axes in global coordinates).
    systems = {0: np.eye(3)}
    for s in sets:
        if s.get("type") == 2420:
            for label, m in zip(s["CS_sys_labels"], s["CS_matrices"]):
                systems[int(label)] = np.asarray(m)[:3, :]

    nodes = {}
    for s in sets:
        if s.get("type") in (15, 2411):
            for i, label in enumerate(s["node_nums"]):
                nodes[int(label)] = (np.array([s["x"][i], s["y"][i], s["z"][i]], float),
                                     int(s["disp_cs"][i]))
    pos_tol = exp["position_tol"]
    for label, xyz in exp["nodes"].items():
        label = int(label)
        if label not in nodes:
            problems.append(f"node {label} missing")
            continue
        err = np.max(np.abs(nodes[label][0] - np.asarray(xyz)))
        check(err <= pos_tol * max(1.0, np.max(np.abs(xyz))),
              f"node {label}: coordinates {nodes[label][0]} vs {xyz}")

    def direction(node, code):
        if node not in nodes:
            return None
        cs = nodes[node][1]
        if cs not in systems:
            return None
        return np.sign(code) * systems[cs][abs(code) - 1]

    frfs = [s for s in sets if s.get("type") == 58 and s.get("func_type") == 4]
    check(len(frfs) == len(exp["frfs"]),
          f"{len(frfs)} FRF datasets, expected {len(exp['frfs'])}")
    rel, dir_tol, hz_tol = exp["value_rel_tol"], exp["direction_tol"], exp["frequency_rel_tol"]
    worst = 0.0
    for k, (got, want) in enumerate(zip(frfs, exp["frfs"])):
        tag = f"FRF {k + 1} ({want['channel']} / {want['excitation']})"
        check(int(got["rsp_node"]) == want["rsp_node"], f"{tag}: response node {got['rsp_node']}")
        check(int(got["ref_node"]) == want["ref_node"], f"{tag}: reference node {got['ref_node']}")
        for role, node, code in (("response", int(got["rsp_node"]), int(got["rsp_dir"])),
                                 ("reference", int(got["ref_node"]), int(got["ref_dir"]))):
            d = direction(node, code)
            w = np.asarray(want[f"{role}_direction"])
            check(d is not None and np.max(np.abs(d - w)) <= dir_tol,
                  f"{tag}: {role} direction {d} vs {w}")
        x = np.asarray(got["x"], float)
        wx = np.asarray(want["frequency_hz"], float)
        check(len(x) == len(wx) and np.all(np.abs(x - wx) <= hz_tol * np.max(np.abs(wx))),
              f"{tag}: frequency axis differs")
        y = np.asarray(got["data"])
        wy = np.asarray(want["re"]) + 1j * np.asarray(want["im"])
        if len(y) != len(wy):
            problems.append(f"{tag}: {len(y)} values, expected {len(wy)}")
            continue
        for a, b in ((y.real, wy.real), (np.imag(y), wy.imag)):
            e = np.abs(a - b)
            ok = e <= rel * np.abs(b) + 1e-300
            worst = max(worst, float(np.max(np.where(b != 0, e / np.maximum(np.abs(b), 1e-300), e))))
            check(bool(np.all(ok)), f"{tag}: values differ by up to {np.max(e)}")
    if problems:
        print(f"{path}: {len(problems)} mismatches", file=sys.stderr)
        for p in problems[:50]:
            print("  " + p, file=sys.stderr)
        return 1
    print(f"{path}: pyuff {pyuff.__version__} reads {len(frfs)} FRFs and {len(nodes)} nodes "
          f"as expected (worst relative value error {worst:.1e})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
