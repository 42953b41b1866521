#!/usr/bin/env python3
"""Compare two results.json files (or two folders of them) number by number.

    python3 bench/pin/compare.py BEFORE AFTER [--tol 1e-9] [--ignore KEY ...]

Every number must agree to `tol` (absolute, or relative for |x| > 1), every string and
key set must be equal, except keys named with --ignore (dotted paths, `*` for any list
index or key, e.g. `time_s` or `methods.*.extrinsic.opk_deg`). Prints each difference and
exits 1 when there is any; this is how a refactoring shows it kept the behaviour.
"""
import json
import math
import os
import sys


def walk(a, b, path, tol, ignore, out):
    if any(match(path, pat) for pat in ignore):
        return
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            p = path + [k]
            if any(match(p, pat) for pat in ignore):
                continue
            if k not in a or k not in b:
                out.append(f"{'.'.join(map(str, p))}: only in {'after' if k in b else 'before'}")
                continue
            walk(a[k], b[k], p, tol, ignore, out)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out.append(f"{'.'.join(map(str, path))}: {len(a)} items before, {len(b)} after")
            return
        for i, (x, y) in enumerate(zip(a, b)):
            walk(x, y, path + [i], tol, ignore, out)
    elif isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
            return
        scale = max(1.0, abs(a), abs(b))
        if not (abs(a - b) <= tol * scale):
            out.append(f"{'.'.join(map(str, path))}: {a!r} before, {b!r} after")
    elif a != b:
        out.append(f"{'.'.join(map(str, path))}: {a!r} before, {b!r} after")


def match(path, pat):
    parts = pat.split(".")
    if len(parts) != len(path):
        # a single key matches it anywhere
        return len(parts) == 1 and path and str(path[-1]) == parts[0]
    return all(q == "*" or q == str(p) for p, q in zip(path, parts))


def files(p):
    if os.path.isdir(p):
        return {f: os.path.join(p, f) for f in sorted(os.listdir(p)) if f.endswith(".json")}
    return {os.path.basename(p): p}


def main():
    args = sys.argv[1:]
    tol, ignore, pos = 1e-9, [], []
    i = 0
    while i < len(args):
        if args[i] == "--tol":
            tol = float(args[i + 1]); i += 2
        elif args[i] == "--ignore":
            ignore.append(args[i + 1]); i += 2
        else:
            pos.append(args[i]); i += 1
    if len(pos) != 2:
        sys.exit(__doc__)
    fa, fb = files(pos[0]), files(pos[1])
    bad = 0
    for name in sorted(set(fa) | set(fb)):
        if name not in fa or name not in fb:
            print(f"{name}: only in one folder"); bad += 1; continue
        out = []
        with open(fa[name]) as x, open(fb[name]) as y:
            walk(json.load(x), json.load(y), [], tol, ignore, out)
        for line in out:
            print(f"{name}: {line}")
        bad += len(out)
        print(f"{name}: {'same' if not out else f'{len(out)} differences'} (tol {tol})")
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
