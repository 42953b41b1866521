#!/usr/bin/env python3
"""Whether two results.json files hold the same numbers: every number of A against B at the
same place, relative (or, below 1, absolute) tolerance; strings and structure must match;
time fields are skipped.

    python3 bench/ba/same_results.py A/results.json B/results.json [--tol 1e-9]

Used to show that a refactor leaves the calibration's results unchanged (issue 13: the
residual kinds moved onto one trait, "same results.json to 1e-9 on three seeds").
"""
import argparse, json, math, sys

SKIP = ("time", "_s", "seconds", "elapsed", "version", "created")


def walk(a, b, path, tol, out):
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if any(s in k for s in SKIP):
                continue
            if k not in a or k not in b:
                out.append((path + "/" + k, "missing on one side", None))
                continue
            walk(a[k], b[k], path + "/" + k, tol, out)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out.append((path, f"length {len(a)} vs {len(b)}", None))
            return
        for i, (x, y) in enumerate(zip(a, b)):
            walk(x, y, f"{path}[{i}]", tol, out)
    elif isinstance(a, bool) or isinstance(b, bool) or not isinstance(a, (int, float)) or not isinstance(b, (int, float)):
        if a != b:
            out.append((path, f"{a!r} vs {b!r}", None))
    else:
        if math.isnan(a) and math.isnan(b):
            return
        d = abs(a - b) / max(1.0, abs(a), abs(b))
        if d > tol:
            out.append((path, f"{a!r} vs {b!r}", d))
        return d


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("--tol", type=float, default=1e-9)
    args = ap.parse_args()
    a, b = (json.load(open(f)) for f in (args.a, args.b))
    out = []
    walk(a, b, "", args.tol, out)
    for path, what, d in out[:40]:
        print(f"{path}: {what}" + (f" (relative {d:.1e})" if d is not None else ""))
    print(f"{len(out)} differences beyond {args.tol:g}")
    sys.exit(1 if out else 0)


main()
