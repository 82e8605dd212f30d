#!/usr/bin/env python3
"""The code-structure rules of docs/conventions.md ("Code structure"), checked.

1. Each physics-catalogue effect id appears (as a string literal) in exactly one
   non-test Rust source file besides the registry's own module list: the file of the
   effect that owns it.
2. No `use super::*` in the model check's stage modules (`crates/rbprops-check/src/check`).
3. No source file over 1,200 lines and no function over 120 lines outside tests,
   except the exceptions listed below, each with its reason (printed on every run; an
   exception that no longer matches anything over the limits is a breach).

Exit status 1 and one line per breach when a rule is broken; `--report` prints the
measurements (longest files and functions, where each id appears) whatever the outcome.
"""
import os
import re
import sys
from collections import defaultdict

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from long_functions import functions, strip_code, test_module_spans  # noqa: E402

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
MAX_FILE_LINES = 1200
MAX_FN_LINES = 120

# path (relative to the root) → reason, and "path::function" → reason. Keep these lists
# short and every reason true: the script prints each exception it applies, and an
# exception that no longer matches a breach is itself a breach (prune it).
NOT_YET = "not split yet: left open in issue #39 (its session note names it)"
FILE_EXCEPTIONS = {
}
FN_EXCEPTIONS = {
}


def rust_sources():
    for base, dirs, files in os.walk(os.path.join(ROOT, "crates")):
        dirs[:] = [d for d in dirs if d not in ("tests", "benches", "examples", "target")]
        for f in files:
            if f.endswith(".rs"):
                path = os.path.join(base, f)
                yield os.path.relpath(path, ROOT), open(path, encoding="utf-8").read()


def without_tests(text):
    """The text with its `#[cfg(test)]` items blanked (line structure kept), found as
    scripts/long_functions.py finds them."""
    out = list(text)
    for a, b in test_module_spans(strip_code(text)):
        for i in range(a, b + 1):
            if out[i] != "\n":
                out[i] = " "
    return "".join(out)


def without_comments(text):
    """Line comments and doc comments removed (a `//` inside a string literal is kept)."""
    out = []
    for line in text.split("\n"):
        i = line.find("//")
        while i >= 0 and line[:i].count('"') % 2 == 1:
            i = line.find("//", i + 2)
        out.append(line if i < 0 else line[:i])
    return "\n".join(out)


def effect_ids():
    ids = set()
    for path, text in rust_sources():
        if "rbprops-sim/src/effects/" in path:
            ids.update(re.findall(r'const ID: &\'static str = "(\w+)"', text))
    return sorted(ids)


def main():
    report = "--report" in sys.argv
    breaches = []
    sources = {p: without_tests(t) for p, t in rust_sources()}
    code = {p: without_comments(t) for p, t in sources.items()}
    # 1. effect ids
    where = defaultdict(list)
    for eid in effect_ids():
        for path, text in code.items():
            if re.search(r'"%s"' % re.escape(eid), text):
                where[eid].append(path)
    for eid, paths in sorted(where.items()):
        if len(paths) != 1:
            breaches.append(f"effect id {eid!r} in {len(paths)} files: {', '.join(sorted(paths))}")
    # 2. glob imports of the parent in the check's stage modules
    check_dir = os.path.join("crates", "rbprops-check", "src", "check")
    for path, text in rust_sources():
        if path.startswith(check_dir) and re.search(r"use\s+super::\*\s*;", text):
            breaches.append(f"{path}: `use super::*`")
    # 3. sizes
    sizes = []
    excused = []
    used = set()
    for path, text in sources.items():
        n = text.count("\n") + 1
        sizes.append((n, path))
        if n > MAX_FILE_LINES:
            if path in FILE_EXCEPTIONS:
                used.add(path)
                excused.append(f"{path}: {n} lines: {FILE_EXCEPTIONS[path]}")
            else:
                breaches.append(f"{path}: {n} lines (> {MAX_FILE_LINES})")
        for name, start, length in functions(os.path.join(ROOT, path)):
            key = f"{path}::{name}"
            if length <= MAX_FN_LINES:
                continue
            if key in FN_EXCEPTIONS:
                used.add(key)
                excused.append(f"{path}:{start}: fn {name} is {length} lines: {FN_EXCEPTIONS[key]}")
            else:
                breaches.append(f"{path}:{start}: fn {name} is {length} lines (> {MAX_FN_LINES})")
    for key in sorted(set(FILE_EXCEPTIONS) | set(FN_EXCEPTIONS)):
        if key not in used:
            breaches.append(f"exception {key!r} matches nothing over the limits: remove it")
    for e in excused:
        print(f"structure exception: {e}", file=sys.stderr)
    if report:
        for eid, paths in sorted(where.items()):
            print(f"{eid}: {', '.join(sorted(paths))}")
        for n, path in sorted(sizes, reverse=True)[:10]:
            print(f"{n:6d} {path}")
    for b in breaches:
        print(f"structure: {b}", file=sys.stderr)
    print(f"{len(breaches)} breach(es) of the code-structure rules, {len(excused)} named exception(s)", file=sys.stderr)
    return 1 if breaches else 0


if __name__ == "__main__":
    sys.exit(main())
