#!/usr/bin/env bash
# Issue 19's network starts on fields too sparse for a relative orientation: simulate with
# few coded targets, then calibrate with each start, for each seed.
#   bash bench/robustness/starts.sh [SEEDS] [CODED]      (from the repository root)
#   SEEDS: default 1..10; CODED: coded targets per field, default "10 8".
# Needs the release binary (cargo build --release -p pingcal). Writes bench/robustness/out-starts/.
# The layout is the truth's room coordinates with N(0, 10 mm) on each axis (seeded), the
# project's layout_sigma_mm left at 20 mm. "mono" removes [stereo] from the project.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
bin="${PINGCAL:-${CARGO_TARGET_DIR:-$root/target}/release/pingcal}"
seeds="${1:-1 2 3 4 5 6 7 8 9 10}"
codeds="${2:-10 8}"
out="${OUT:-$here/out-starts}"
mkdir -p "$out"
printf 'coded\thead\tseed\tstart\tfinished\tmean_check_mm\tstart_used\terror\n' >"$out/runs.tsv"
for n in $codeds; do
  printf '[targets]\ncoded = %s\n[distances]\ncount = 3\n' "$n" >"$out/coded$n.toml"
  for s in $seeds; do
    d="$out/c$n-$s"
    rm -rf "$d"
    "$bin" simulate --out "$d" --seed "$s" --config "$out/coded$n.toml" >/dev/null
    python3 - "$d" "$s" <<'PY'
import json, random, re, sys
d, seed = sys.argv[1], int(sys.argv[2])
rng = random.Random(seed)
t = json.load(open(f"{d}/truth.json"))
with open(f"{d}/layout.csv", "w") as f:
    f.write("id,x_mm,y_mm,z_mm\n")
    for x in t["targets"]:
        if x["kind"] == "coded":
            f.write("%d,%.1f,%.1f,%.1f\n" % (x["id"], *[v + rng.gauss(0, 10) for v in x["world_mm"]]))
p = open(f"{d}/project.toml").read()
with_layout = p.replace("ring_outer = 3.0\n", 'ring_outer = 3.0\nlayout = "layout.csv"\n', 1)
mono = re.sub(r"\n\[stereo\]\n(?:[^\[\n][^\n]*\n)*", "\n", p)
mono_layout = re.sub(r"\n\[stereo\]\n(?:[^\[\n][^\n]*\n)*", "\n", with_layout)
for name, text in [("stereo", p), ("stereo-layout", with_layout), ("mono", mono), ("mono-layout", mono_layout)]:
    open(f"{d}/{name}.toml", "w").write(text)
PY
    for head in stereo stereo-layout mono mono-layout; do
      for start in relative auto; do
        o="$d/out-$head-$start"
        if "$bin" calibrate "$d/$head.toml" --out "$o" --quiet --seed "$s" --start "$start" 2>"$o.err"; then ok=1; else ok=0; fi
        python3 - "$o" "$n" "$head" "$s" "$start" "$ok" >>"$out/runs.tsv" <<'PY'
import json, sys
o, n, head, s, start, ok = sys.argv[1:7]
mean = used = err = ""
if ok == "1":
    r = json.load(open(f"{o}/results.json"))
    m = r.get("mean_check_error_mm")
    mean = "" if m is None else f"{m:.3f}"
    used = r["bundle"]["network_start"]
else:
    lines = [l for l in open(f"{o}.err").read().splitlines() if l.strip()]
    err = (lines[-1] if lines else "").replace("\t", " ")[:160]
print(f"{n}\t{head}\t{s}\t{start}\t{ok}\t{mean}\t{used}\t{err}")
PY
      done
    done
    rm -rf "$d/images" "$d/scans"
  done
done
python3 - "$out/runs.tsv" <<'PY' | tee "$out/table.md"
import csv, sys
from collections import Counter
rows = list(csv.DictReader(open(sys.argv[1]), delimiter="\t"))
print("| coded targets | head | --start | calibrations that finish | mean check error (mm) | starts used |")
print("|---|---|---|---|---|---|")
keys = dict.fromkeys((r["coded"], r["head"], r["start"]) for r in rows)
for k in keys:
    rs = [r for r in rows if (r["coded"], r["head"], r["start"]) == k]
    ok = [r for r in rs if r["finished"] == "1"]
    m = [float(r["mean_check_mm"]) for r in ok if r["mean_check_mm"]]
    used = ", ".join(f"{u} {c}" for u, c in Counter(r["start_used"] for r in ok).items())
    mean = f"{sum(m)/len(m):.2f}" if m else "—"
    print(f"| {k[0]} | {k[1]} | {k[2]} | {len(ok)} / {len(rs)} | {mean} | {used or '—'} |")
PY
