#!/usr/bin/env python3
"""Verifies the workspace's declared `rust-version` (the minimum supported Rust).

Only one toolchain can be installed on the build machines, so the floor is checked the
way Cargo itself enforces it: every dependency that is built for this host declares its
own `rust-version`, and ours may not be lower than the highest of them (a user on an
older compiler would fail inside a dependency). It may not be higher than the toolchain
that builds and tests the workspace, or the claim would be untested. Prints the
binding dependency; exits 1 on a violation.
"""
import json
import subprocess
import sys


def version(v):
    return tuple(int(x) for x in v.split(".")) + (0,) * (3 - len(v.split(".")))


def main():
    host = next(
        line.split(": ", 1)[1]
        for line in subprocess.run(
            ["rustc", "-vV"], check=True, capture_output=True, text=True
        ).stdout.splitlines()
        if line.startswith("host: ")
    )
    rustc = subprocess.run(
        ["rustc", "--version"], check=True, capture_output=True, text=True
    ).stdout.split()[1]
    meta = json.loads(
        subprocess.run(
            ["cargo", "metadata", "--format-version", "1", "--filter-platform", host],
            check=True,
            capture_output=True,
            text=True,
        ).stdout
    )
    packages = {p["id"]: p for p in meta["packages"]}
    members = set(meta["workspace_members"])
    declared = {packages[m]["rust_version"] for m in members}
    if len(declared) != 1 or None in declared:
        sys.exit(f"error: workspace members declare rust-version {sorted(map(str, declared))}; expected one shared value")
    ours = declared.pop()
    # Everything reachable from the members on this host (normal, build and dev edges).
    nodes = {n["id"]: n for n in meta["resolve"]["nodes"]}
    seen, stack = set(), list(members)
    while stack:
        pid = stack.pop()
        if pid in seen:
            continue
        seen.add(pid)
        stack.extend(d["pkg"] for d in nodes[pid]["deps"])
    deps = [packages[p] for p in seen - members if packages[p].get("rust_version")]
    binding = max(deps, key=lambda p: version(p["rust_version"]))
    floor = binding["rust_version"]
    print(
        f"rust-version {ours}: dependencies need ≥ {floor} ({binding['name']} {binding['version']}), "
        f"tested with rustc {rustc} on {host}"
    )
    if version(ours) < version(floor):
        sys.exit(f"error: declared rust-version {ours} is below {floor}, which {binding['name']} {binding['version']} requires")
    if version(ours) > version(rustc):
        sys.exit(f"error: declared rust-version {ours} is above the toolchain that tests it ({rustc})")


if __name__ == "__main__":
    main()
