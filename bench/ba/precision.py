#!/usr/bin/env python3
"""Time and memory of the precision of large free networks: `pingcal ba --synthetic CxP
--precision` on pingcal's own generator (6 observations per point), banded (a street) or
random (a dense camera graph) visibility. One subprocess per size; prints a markdown table.

    python3 bench/ba/precision.py --sizes 600x60000,1500x120000 --visibility banded
    python3 bench/ba/precision.py --pingcal-bin /tmp/pingcal --threads 2

Columns: the adjustment's own time (pingcal's time_s), the precision's time (σ0, every
pose's and point's σ and every observation's redundancy number), how its cofactors were
computed, σ0, and the peak RSS of the whole process (os.wait4). Not part of CI.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def run(binary, size, visibility, threads):
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "out.json")
        cmd = [binary, "ba", "--synthetic", size, "--visibility", visibility,
               "--threads", str(threads), "--precision", "--quiet", "--out", out]
        t0 = time.time()
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.time() - t0
        stdout, stderr = proc.stdout.read(), proc.stderr.read()
        result = json.load(open(out)) if os.path.exists(out) else {}
        return {
            "size": size, "visibility": visibility, "threads": threads,
            "rc": os.waitstatus_to_exitcode(status), "wall_s": wall,
            "peak_mib": usage.ru_maxrss / 1024.0, "result": result,
            "stderr": stderr.strip().splitlines()[-1:] if stderr.strip() else [],
            "stdout": stdout,
        }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="600x60000,1500x120000,4000x300000")
    ap.add_argument("--visibility", default="banded", choices=["banded", "random"])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--pingcal-bin", default=os.path.join(ROOT, "target", "release", "pingcal"))
    args = ap.parse_args()
    if not os.path.exists(args.pingcal_bin):
        sys.exit(f"{args.pingcal_bin}: no such binary (cargo build --release -p pingcal)")
    print(f"binary {args.pingcal_bin}, {args.visibility} visibility, {args.threads} threads\n")
    print("| cameras / points / observations | adjustment s | precision s | cofactors | σ0 | peak MiB |")
    print("|---|---|---|---|---|---|")
    for size in args.sizes.split(","):
        r = run(args.pingcal_bin, size, args.visibility, args.threads)
        res = r["result"]
        p = res.get("precision")
        obs = res.get("observations", "?")
        if p:
            print(f"| {size.replace('x', ' / ')} / {obs} | {res['time_s']:.1f} | {p['time_s']:.1f} "
                  f"| {p['method']} | {p['sigma0']:.4f} | {r['peak_mib']:.0f} |", flush=True)
        else:
            why = res.get("precision_error") or " ".join(r["stderr"]) or f"rc {r['rc']}"
            adj = f"{res['time_s']:.1f}" if "time_s" in res else "—"
            print(f"| {size.replace('x', ' / ')} / {obs} | {adj} | — | {why} | — | {r['peak_mib']:.0f} |",
                  flush=True)


if __name__ == "__main__":
    main()
