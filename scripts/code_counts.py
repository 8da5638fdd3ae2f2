#!/usr/bin/env python3
"""Counts that say how easy the code is to change (issue #43), over the tracked Rust sources
outside tests, benches, fuzz targets and examples:

- public modules of the binary's lib.rs (its surface: 0 means every module is private);
- functions returning `Result<_, String>` (errors as text);
- files over 800 lines (before their unit tests);
- functions over 100 lines.

Usage: python3 scripts/code_counts.py [--list]
"""

import re
import subprocess
import sys

LONG_FILE = 800
LONG_FUNCTION = 100
FN = re.compile(r"^(\s*)(pub(\([a-z]+\))? )?(async )?(const )?(unsafe )?fn (\w+)")


def sources():
    names = subprocess.check_output(["git", "ls-files", "*.rs"], text=True).split()
    skipped = ("tests/", "benches/", "fuzz/")
    return [
        n for n in names
        if not n.startswith(skipped) and "/examples/" not in n and "/tests/" not in n
    ]


def code_lines(path):
    """The file's lines before its unit tests."""
    lines = open(path, encoding="utf-8").read().split("\n")
    for i, line in enumerate(lines):
        if line.startswith("#[cfg(test)]"):
            return lines[:i]
    return lines


def long_functions(path, lines):
    found, i = [], 0
    while i < len(lines):
        m = FN.match(lines[i])
        if m and not lines[i].rstrip().endswith(";"):
            end = re.compile("^" + m.group(1) + r"}\s*$")
            j = i
            while j < len(lines) and not end.match(lines[j]):
                j += 1
            if j - i > LONG_FUNCTION:
                found.append((j - i, f"{path}:{i + 1} {m.group(7)}"))
            i = j
        i += 1
    return found


def main():
    files = sources()
    surface = [l for l in open("src/lib.rs", encoding="utf-8") if l.startswith("pub mod ")]
    strings = [
        f"{f}:{n + 1}"
        for f in files
        for n, l in enumerate(code_lines(f))
        if re.search(r"Result<[^;{]*, String>", l)
    ]
    big = sorted(((len(code_lines(f)), f) for f in files), reverse=True)
    big = [(n, f) for n, f in big if n > LONG_FILE]
    long = sorted((x for f in files for x in long_functions(f, code_lines(f))), reverse=True)
    print(f"pub mod in src/lib.rs: {len(surface)}")
    print(f"Result<_, String>: {len(strings)}")
    print(f"files over {LONG_FILE} lines: {len(big)}")
    print(f"functions over {LONG_FUNCTION} lines: {len(long)}")
    if "--list" in sys.argv:
        for line in surface:
            print("  " + line.strip())
        for s in strings:
            print("  " + s)
        for n, f in big:
            print(f"  {n:5} {f}")
        for n, what in long:
            print(f"  {n:5} {what}")


if __name__ == "__main__":
    main()
