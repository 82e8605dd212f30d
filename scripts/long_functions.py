#!/usr/bin/env python3
"""List Rust functions longer than a limit (default 200 lines), outside tests.

Usage: scripts/long_functions.py [--limit N] [--fail] [ROOT ...]   (ROOT: a folder or a .rs file;
defaults to crates/)

A function is an `fn` item whose body is found by brace matching; strings, chars, and
comments are skipped so braces inside them do not count. Files under `tests/`,
`benches/` and `examples/`, and `#[cfg(test)]` modules, are left out. With `--fail` the
exit status is 1 when any function is over the limit (for CI).
"""
import argparse
import os
import re
import sys

FN_RE = re.compile(r"\bfn\s+([A-Za-z_][A-Za-z0-9_]*)")


def strip_code(text):
    """Blank out comments, string and char literals (keeping newlines) so braces count."""
    out = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif text.startswith("/*", i):
            depth, j = 1, i + 2
            while j < n and depth:
                if text.startswith("/*", j):
                    depth, j = depth + 1, j + 2
                elif text.startswith("*/", j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c == "r" and re.match(r'r#*"', text[i:i + 260]) and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            m = re.match(r'r(#*)"', text[i:])
            close = '"' + m.group(1)
            j = text.find(close, i + len(m.group(0)))
            j = n if j < 0 else j + len(close)
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            j = min(j + 1, n)
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c == "'":
            # A char literal ('x', '\n', '\u{..}') or a lifetime ('a): only literals are blanked.
            m = re.match(r"'(\\.|\\u\{[0-9a-fA-F]+\}|[^\\'])'", text[i:])
            if m:
                out.append(" " * len(m.group(0)))
                i += len(m.group(0))
            else:
                out.append(c)
                i += 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def matching_brace(code, open_at):
    depth = 0
    for j in range(open_at, len(code)):
        if code[j] == "{":
            depth += 1
        elif code[j] == "}":
            depth -= 1
            if depth == 0:
                return j
    return len(code) - 1


def test_module_spans(code):
    """Byte ranges of `#[cfg(test)]` items (modules or functions)."""
    spans = []
    for m in re.finditer(r"#\[cfg\(test\)\]", code):
        b = code.find("{", m.end())
        if b >= 0:
            spans.append((m.start(), matching_brace(code, b)))
    return spans


def functions(path):
    with open(path, encoding="utf-8") as f:
        text = f.read()
    code = strip_code(text)
    skip = test_module_spans(code)
    for m in FN_RE.finditer(code):
        if any(a <= m.start() <= b for a, b in skip):
            continue
        # The body starts at the first `{` after the signature, unless a `;` comes first
        # (a trait method without a body).
        j = m.end()
        depth = 0
        while j < len(code):
            ch = code[j]
            if ch in "(<[":
                depth += 1
            elif ch in ")>]":
                depth -= 1 if ch != ">" or code[j - 1] != "-" else 0
            elif ch == ";" and depth <= 0:
                j = -1
                break
            elif ch == "{" and depth <= 0:
                break
            j += 1
        if j < 0 or j >= len(code):
            continue
        end = matching_brace(code, j)
        first = code.count("\n", 0, m.start()) + 1
        last = code.count("\n", 0, end) + 1
        yield m.group(1), first, last - first + 1


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("roots", nargs="*", default=["crates"])
    ap.add_argument("--limit", type=int, default=200)
    ap.add_argument("--fail", action="store_true", help="exit 1 if any function is over the limit")
    args = ap.parse_args()
    rows = []
    for root in args.roots:
        if os.path.isfile(root):
            rows.extend((n, root, line, fn) for fn, line, n in functions(root) if n > args.limit)
            continue
        for dirpath, dirnames, filenames in os.walk(root):
            dirnames[:] = sorted(d for d in dirnames if d not in ("tests", "benches", "examples", "target"))
            for name in sorted(filenames):
                if not name.endswith(".rs"):
                    continue
                path = os.path.join(dirpath, name)
                for fn, line, length in functions(path):
                    if length > args.limit:
                        rows.append((length, path, line, fn))
    rows.sort(key=lambda r: (-r[0], r[1], r[2]))
    for length, path, line, fn in rows:
        print(f"{length:5d}  {path}:{line}  {fn}")
    print(f"{len(rows)} function(s) over {args.limit} lines", file=sys.stderr)
    return 1 if (args.fail and rows) else 0


if __name__ == "__main__":
    sys.exit(main())
