#!/usr/bin/env bash
# Issue 19's robustness table: simulate, calibrate, count, for each case and seed.
#   bash bench/robustness/run.sh [SEEDS] [CASES]     (from the repository root)
#   SEEDS: e.g. "1 2 3 4 5" (default 1..10); CASES: a subset of
#   "blur0.6 blur0.75 blur0.9 blur1.2 noise4 st3 mono" (default all).
# Needs the release binary (cargo build --release -p pingcal). Writes bench/robustness/out/.
# Per run: whether `pingcal calibrate` finished (exit 0), the mean check error (results.json,
# mean_check_error_mm), and the coded targets read in all images by `pingcal detect` (a read
# whose ID is not one of the field's coded IDs in truth.json counts as wrong).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
bin="${PINGCAL:-${CARGO_TARGET_DIR:-$root/target}/release/pingcal}"
seeds="${1:-1 2 3 4 5 6 7 8 9 10}"
cases="${2:-blur0.6 blur0.75 blur0.9 blur1.2 noise4 st3 mono}"
out="${OUT:-$here/out}"
mkdir -p "$out"
config() { # the simulator configuration of a case
  case "$1" in
    blur*) printf '[render]\nblur_sigma_px = %s\n' "${1#blur}" ;;
    noise4) printf '[render]\nfull_well_e = 700.0\nread_noise_e = 30.0\n' ;;
    st3) printf '[stations]\nconvergent = 3\n' ;;
    mono) printf '' ;;
  esac
}
printf 'case\tseed\tfinished\tmean_check_mm\tcoded_read\twrong_ids\terror\n' >"$out/runs.tsv"
for c in $cases; do
  for s in $seeds; do
    d="$out/$c-$s"
    rm -rf "$d"
    config "$c" >"$out/$c.toml"
    "$bin" simulate --out "$d" --seed "$s" --config "$out/$c.toml" >/dev/null
    if [ "$c" = mono ]; then # no [stereo]: the two cameras are oriented as independent images
      python3 - "$d/project.toml" <<'PY'
import re, sys
p = sys.argv[1]; t = open(p).read()
t = re.sub(r"\n\[stereo\]\n(?:[^\[\n][^\n]*\n)*", "\n", t)
open(p, "w").write(t)
PY
    fi
    if "$bin" calibrate "$d/project.toml" --out "$d/out" --json --seed "$s" >"$d/calibrate.json" 2>"$d/calibrate.err"; then ok=1; else ok=0; fi
    "$bin" detect "$d"/images/*.png --out "$d/detect.json" >/dev/null 2>&1 || true
    python3 - "$d" "$c" "$s" "$ok" >>"$out/runs.tsv" <<'PY'
import json, os, sys
d, c, s, ok = sys.argv[1:5]
truth = json.load(open(f"{d}/truth.json"))
coded = {t["id"] for t in truth["targets"] if t["kind"] == "coded"}
read = wrong = 0
if os.path.exists(f"{d}/detect.json"):
    for im in json.load(open(f"{d}/detect.json"))["images"]:
        for t in im["targets"]:
            if t["kind"] == "coded" and t.get("id") is not None:
                read += 1
                wrong += t["id"] not in coded
mean = ""
if ok == "1":
    r = json.load(open(f"{d}/out/results.json"))
    m = r.get("mean_check_error_mm")
    mean = "" if m is None else f"{m:.3f}"
err = ""
if ok == "0":
    lines = [l for l in open(f"{d}/calibrate.err").read().splitlines() if l.strip()]
    err = (lines[-1] if lines else "").replace("\t", " ")[:200]
print(f"{c}\t{s}\t{ok}\t{mean}\t{read}\t{wrong}\t{err}")
PY
    rm -rf "$d/images" "$d/scans"
  done
done
python3 - "$out/runs.tsv" <<'PY' | tee "$out/table.md"
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1]), delimiter="\t"))
print("| case | calibrations that finish | mean check error (mm) | coded targets read (mean per project) | wrong IDs |")
print("|---|---|---|---|---|")
for c in dict.fromkeys(r["case"] for r in rows):
    rs = [r for r in rows if r["case"] == c]
    ok = [r for r in rs if r["finished"] == "1"]
    m = [float(r["mean_check_mm"]) for r in ok if r["mean_check_mm"]]
    read = sum(int(r["coded_read"]) for r in rs) / len(rs)
    wrong = sum(int(r["wrong_ids"]) for r in rs)
    mean = f"{sum(m)/len(m):.2f}" if m else "—"
    print(f"| {c} | {len(ok)} / {len(rs)} | {mean} | {read:.0f} | {wrong} |")
PY
