#!/usr/bin/env bash
# Issue 16: a continuous sweep (the servo turning while the LRF scans) read with per-beam
# servo angles (pingcal-scan v2, as `pingcal scans` writes from a bag) against the same
# scans read with one angle per scan (the first beam's, as a v1 reader would), and against
# stop-and-go at the same servo step.
#   bash bench/sweep/run.sh [SEEDS] [STEP_DEG]     (from the repository root)
# Default: seeds 1..5, a 0.3515625° step per 0.1 s scan (3.5°/s; the beams of one scan then
# span 0.23° of servo travel). NOISE=0 switches the LRF's range and servo noise off, to see
# the geometry alone. Needs the release binary. Writes bench/sweep/out/ (or $OUT).
# Besides the check errors, the table gives the RMS distance of the fitted sphere centres
# from the true ones in the LRF frame (results.json balls[].lrf_mm against truth.json).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
bin="${PINGCAL:-${CARGO_TARGET_DIR:-$root/target}/release/pingcal}"
seeds="${1:-1 2 3 4 5}"
step="${2:-0.3515625}"
out="${OUT:-$here/out}"
mkdir -p "$out"
noise="$([ "${NOISE:-1}" = 0 ] && echo 'noise = false' || true)"
printf '[lrf]\nservo_step_deg = %s\ncontinuous_sweep = true\n%s\n' "$step" "$noise" >"$out/continuous.toml"
printf '[lrf]\nservo_step_deg = %s\n%s\n' "$step" "$noise" >"$out/stop.toml"
printf 'case\tseed\tfinished\tmean_check_mm\tjoint_check_mm\tspheres_check_mm\tsphere_centre_rms_mm\n' >"$out/runs.tsv"
for s in $seeds; do
  for sweep in continuous stop; do
    d="$out/$sweep-$s"
    rm -rf "$d"
    "$bin" simulate --out "$d" --seed "$s" --config "$out/$sweep.toml" >/dev/null
  done
  # the continuous sweep's scans with one servo angle per scan: v1, the first beam's angle
  python3 - "$out/continuous-$s" <<'PY'
import glob, os, shutil, sys
d = sys.argv[1]
head, seed = d.rsplit("-", 1)
v1 = f"{head}-v1-{seed}"
shutil.rmtree(v1, ignore_errors=True)
shutil.copytree(d, v1, ignore=shutil.ignore_patterns("out*"))
for f in glob.glob(f"{v1}/scans/*.csv"):
    lines = open(f).read().splitlines()
    outl = []
    for l in lines:
        if l.startswith("# pingcal-scan v2"):
            outl.append("# pingcal-scan v1")
        elif l.startswith("stamp_s,"):
            c = l.split(",")
            outl.append(",".join(c[:2] + c[3:]))
        elif l.startswith("#"):
            outl.append(l)
        else:
            c = l.split(",")
            outl.append(",".join(c[:2] + c[3:]))
    open(f, "w").write("\n".join(outl) + "\n")
PY
  for case in stop continuous continuous-v1; do
    d="$out/$case-$s"
    if "$bin" calibrate "$d/project.toml" --out "$d/out" --quiet --seed "$s" >/dev/null 2>"$d/calibrate.err"; then ok=1; else ok=0; fi
    python3 - "$d" "$case" "$s" "$ok" >>"$out/runs.tsv" <<'PY'
import json, math, sys
d, case, s, ok = sys.argv[1:5]
m = j = sp = rms = ""
if ok == "1":
    r = json.load(open(f"{d}/out/results.json"))
    truth = {b["id"]: b["lrf_mm"] for b in json.load(open(f"{d}/truth.json"))["balls"]}
    e = [math.dist(b["lrf_mm"], truth[b["id"]]) for b in r["balls"] if b.get("lrf_mm") and b["id"] in truth]
    rms = f"{math.sqrt(sum(x * x for x in e) / len(e)):.3f}" if e else ""
    m = f'{r["mean_check_error_mm"]:.3f}'
    for x in r["methods"]:
        v = x.get("mean_check_error_mm")
        if v is not None and x["method"] == "joint": j = f"{v:.3f}"
        if v is not None and x["method"] == "spheres": sp = f"{v:.3f}"
print(f"{case}\t{s}\t{ok}\t{m}\t{j}\t{sp}\t{rms}")
PY
  done
  rm -rf "$out"/*-"$s"/images
done
python3 - "$out/runs.tsv" <<'PY' | tee "$out/table.md"
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1]), delimiter="\t"))
print("| scans | calibrations that finish | mean check error, joint (mm) | mean check error, spheres (mm) | sphere centres vs truth, RMS (mm) |")
print("|---|---|---|---|---|")
names = {"stop": "stop-and-go", "continuous": "continuous sweep, per-beam servo angles (v2)",
         "continuous-v1": "continuous sweep, one servo angle per scan (v1)"}
for c in ["stop", "continuous", "continuous-v1"]:
    rs = [r for r in rows if r["case"] == c]
    ok = [r for r in rs if r["finished"] == "1"]
    mean = lambda k: (f"{sum(float(r[k]) for r in ok if r[k]) / max(1, sum(1 for r in ok if r[k])):.2f}" if ok else "—")
    print(f"| {names[c]} | {len(ok)} / {len(rs)} | {mean('joint_check_mm')} | {mean('spheres_check_mm')} | {mean('sphere_centre_rms_mm')} |")
PY
