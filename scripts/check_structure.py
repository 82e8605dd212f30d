#!/usr/bin/env python3
"""The code-structure rules of docs/conventions.md ("Code structure"), checked.

1. Each physics-catalogue effect id appears (as a string literal) in exactly one
   non-test Rust source file besides the registry's own module list: the file of the
   effect that owns it.
2. No `use super::*` in the model check's stage modules (`crates/rbprops-check/src/check`).
3. No source file over 1,200 lines and no function over 120 lines outside tests,
   except the exceptions listed below, each with its reason.

Exit status 1 and one line per breach when a rule is broken; `--report` prints the
measurements (longest files and functions, where each id appears) whatever the outcome.
"""
import os
import re
import sys
from collections import defaultdict

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
MAX_FILE_LINES = 1200
MAX_FN_LINES = 120

# path (relative to the root) → reason. Keep this list short and every reason true.
FILE_EXCEPTIONS = {}
FN_EXCEPTIONS = {}


def rust_sources():
    for base, dirs, files in os.walk(os.path.join(ROOT, "crates")):
        dirs[:] = [d for d in dirs if d not in ("tests", "benches", "examples", "target")]
        for f in files:
            if f.endswith(".rs"):
                path = os.path.join(base, f)
                yield os.path.relpath(path, ROOT), open(path, encoding="utf-8").read()


def strip_test_modules(text):
    """The text without `#[cfg(test)] mod … { … }` blocks (brace-matched)."""
    out, i = [], 0
    pat = re.compile(r"#\[cfg\(test\)\]\s*(pub(\([^)]*\))?\s+)?mod\s+\w+\s*\{")
    while True:
        m = pat.search(text, i)
        if not m:
            out.append(text[i:])
            return "".join(out)
        out.append(text[i : m.start()])
        depth, j = 1, m.end()
        while depth and j < len(text):
            depth += {"{": 1, "}": -1}.get(text[j], 0)
            j += 1
        out.append("\n" * text[m.start() : j].count("\n"))
        i = j


def code_only(text):
    """Comments and string/char literals blanked (line structure kept), for brace counting."""
    res, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            res.append(" " * (j - i))
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            res.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c == "r" and re.match(r'r#*"', text[i:i + 10]) and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            hashes = re.match(r'r(#*)"', text[i:]).group(1)
            end = text.find('"' + hashes, i + 2 + len(hashes))
            j = n if end < 0 else end + 1 + len(hashes)
            res.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            res.append(re.sub(r"[^\n]", " ", text[i:j + 1]))
            i = j + 1
        elif c == "'" and re.match(r"'(\\.|[^\\'])'", text[i:i + 4]) or c == "'" and text.startswith("'\\u{", i):
            j = text.find("'", i + 2) + 1
            res.append(" " * (j - i))
            i = j
        else:
            res.append(c)
            i += 1
    return "".join(res)


def functions(text):
    """(name, first line, line count) of every fn with a body."""
    code = code_only(text)
    for m in re.finditer(r"\bfn\s+(\w+)", code):
        j = m.end()
        # the body's opening brace: the first `{` at generic depth 0 before any `;`
        depth = 0
        while j < len(code):
            ch = code[j]
            if ch in "(<[":
                depth += 1
            elif ch in ")>]":
                depth -= 1 if not (ch == ">" and code[j - 1] == "-") else 0
            elif ch == ";" and depth <= 0:
                j = -1
                break
            elif ch == "{" and depth <= 0:
                break
            j += 1
        if j < 0 or j >= len(code):
            continue
        k, d = j + 1, 1
        while d and k < len(code):
            d += {"{": 1, "}": -1}.get(code[k], 0)
            k += 1
        start = code.count("\n", 0, m.start()) + 1
        end = code.count("\n", 0, k) + 1
        yield m.group(1), start, end - start + 1


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
    sources = {p: strip_test_modules(t) for p, t in rust_sources()}
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
    for path, text in sources.items():
        n = text.count("\n") + 1
        sizes.append((n, path))
        if n > MAX_FILE_LINES and path not in FILE_EXCEPTIONS:
            breaches.append(f"{path}: {n} lines (> {MAX_FILE_LINES})")
        for name, start, length in functions(text):
            key = f"{path}::{name}"
            if length > MAX_FN_LINES and key not in FN_EXCEPTIONS:
                breaches.append(f"{path}:{start}: fn {name} is {length} lines (> {MAX_FN_LINES})")
    if report:
        for eid, paths in sorted(where.items()):
            print(f"{eid}: {', '.join(sorted(paths))}")
        for n, path in sorted(sizes, reverse=True)[:10]:
            print(f"{n:6d} {path}")
    for b in breaches:
        print(f"structure: {b}", file=sys.stderr)
    print(f"{len(breaches)} breach(es) of the code-structure rules", file=sys.stderr)
    return 1 if breaches else 0


if __name__ == "__main__":
    sys.exit(main())
