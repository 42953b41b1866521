#!/usr/bin/env bash
# Issue 14's verdict figures: its false-alarm rate on clean simulations and its detection rate
# on simulations with an LRF mount error the project does not know.
#   bash bench/verdict/rates.sh [SEEDS] [CASES]      (from the repository root)
#   SEEDS default "1 2 ... 20"; CASES a subset of "clean offset25" (default both).
# clean:    `pingcal simulate --seed s` as it is (method = "all": joint, spheres, corner).
# offset25: the scanner 25 mm off the servo axis (x) in the simulation, the project's mount
#           left at zero; calibrated twice, with method = "spheres" (the paper's two steps,
#           which cannot absorb it) and with method = "all" (the joint adjustment estimates it).
# Needs the release binary. Writes bench/verdict/out/runs.tsv and prints the table.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
bin="${PINGCAL:-${CARGO_TARGET_DIR:-$root/target}/release/pingcal}"
seeds="${1:-$(seq -s ' ' 1 20)}"
cases="${2:-clean offset25}"
out="${OUT:-$here/out}"
mkdir -p "$out"
printf '[lrf]\nmount_offset_mm = [25.0, 0.0, 0.0]\n' >"$out/offset25.toml"
printf 'case\tmethod\tseed\tstatus\treasons\n' >"$out/runs.tsv"
calibrate() { # dir method seed case
  local d="$1" m="$2" s="$3" c="$4"
  sed -i "s/^method = .*/method = \"$m\"/" "$d/project.toml"
  rm -rf "$d/out-$m"
  if "$bin" calibrate "$d/project.toml" --out "$d/out-$m" --quiet --seed "$s" 2>"$d/err-$m"; then
    python3 - "$d/out-$m/results.json" "$c" "$m" "$s" >>"$out/runs.tsv" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
v = r["verdict"]
print("\t".join(sys.argv[2:5] + [v["status"], " | ".join(v["reasons"]).replace("\t", " ")]))
PY
  else
    printf '%s\t%s\t%s\tnot calibrated\t%s\n' "$c" "$m" "$s" "$(tail -1 "$d/err-$m" | tr '\t' ' ')" >>"$out/runs.tsv"
  fi
}
for c in $cases; do
  for s in $seeds; do
    d="$out/$c-$s"
    rm -rf "$d"
    if [ "$c" = offset25 ]; then
      "$bin" simulate --out "$d" --seed "$s" --config "$out/offset25.toml" >/dev/null
      calibrate "$d" spheres "$s" "$c"
    else
      "$bin" simulate --out "$d" --seed "$s" >/dev/null
    fi
    calibrate "$d" all "$s" "$c"
    rm -rf "$d/images" "$d/scans"
  done
done
python3 - "$out/runs.tsv" <<'PY' | tee "$out/table.md"
import csv, sys, collections
rows = list(csv.DictReader(open(sys.argv[1]), delimiter="\t"))
print("| case | method | seeds | ok | doubtful | failed | not calibrated |")
print("|---|---|---|---|---|---|---|")
keys = list(dict.fromkeys((r["case"], r["method"]) for r in rows))
for c, m in keys:
    rs = [r for r in rows if r["case"] == c and r["method"] == m]
    n = collections.Counter(r["status"] for r in rs)
    print(f"| {c} | {m} | {len(rs)} | {n['ok']} | {n['doubtful']} | {n['failed']} | {n['not calibrated']} |")
print()
for r in rows:
    if r["status"] != "ok":
        print(f"- {r['case']} {r['method']} seed {r['seed']}: {r['status']}: {r['reasons']}")
PY
