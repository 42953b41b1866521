#!/usr/bin/env bash
# Issue 39: is the work bounded by the data, whatever the values in it? One range of
# 1e3 … 1e6 mm put into a scan, against the clean scan:
#   - `pingcal cloud` on the 94,610-point scan of ../shared/data/bad-inputs (the file with
#     999,999 mm on line 11, that range replaced), as run (the URG-04LX's 5.6 m masks the
#     far range) and with `--max-range-mm 1e6` (nothing masked: the finder's own bound);
#   - `pingcal calibrate` on a simulated project (seed 1; the range put on line 11 of
#     scans/S00.csv), as run (`max_range_mm = 5600` masks it) and with `max_range_mm = 1e6`;
#     its total time and its "LRF spheres" step.
# Each figure is the median of RUNS runs (default 3). Prints a table (seconds, and the ratio
# to the clean input's time). Never run in CI.
#   bash bench/bounded/run.sh            (from the repository root; needs the release binary)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
bin="${PINGCAL:-${CARGO_TARGET_DIR:-$root/target}/release/pingcal}"
runs="${RUNS:-3}"
data="$root/../shared/data/bad-inputs/scan_one_range_999999mm_hangs_cloud_and_calibrate.csv"
[ -x "$bin" ] || { echo "no binary at $bin (cargo build --release -p pingcal)"; exit 1; }
[ -f "$data" ] || { echo "no $data: ../shared/data is absent"; exit 1; }
out="${OUT:-$here/out}"
mkdir -p "$out"
values="clean 1000 10000 100000 999999"

# put_range FILE VALUE OUT: FILE with its line 11's first range past r300 that is not 0
# replaced by VALUE (0 for clean)
put_range() {
  python3 - "$1" "$2" "$3" <<'PY'
import sys
src, v, dst = sys.argv[1:]
lines = open(src).read().split("\n")
f = lines[10].split(",")
for k in range(2 + 300, len(f)):
    if f[k] not in ("0", "999999"):
        f[k] = v
        break
else:
    f[f.index("999999")] = v
lines[10] = ",".join(f)
open(dst, "w").write("\n".join(lines))
PY
}

# median of RUNS timings of a command (seconds); the command's stdout+stderr go to $out/last.log
timed() {
  local ts=()
  for _ in $(seq "$runs"); do
    local t0 t1
    t0=$(date +%s.%N)
    "$@" >"$out/last.log" 2>&1 || true
    t1=$(date +%s.%N)
    ts+=("$(echo "$t1 - $t0" | bc)")
  done
  printf '%s\n' "${ts[@]}" | sort -g | sed -n "$(((runs + 1) / 2))p"
}

sed 's/,999999,/,0,/' "$data" >"$out/base.csv"
echo "== pingcal cloud ($(basename "$data"), one range on line 11)"
printf '%-8s %12s %8s %22s %8s  %s\n' range "time s" ratio "--max-range-mm 1e6 s" ratio "result (as run)"
for v in $values; do
  f="$out/cloud-$v.csv"
  [ "$v" = clean ] && cp "$out/base.csv" "$f" || put_range "$out/base.csv" "$v" "$f"
  a=$(timed "$bin" cloud "$f"); res=$(tail -1 "$out/last.log" | cut -c1-70)
  b=$(timed "$bin" cloud "$f" --max-range-mm 1e6)
  [ "$v" = clean ] && { a0=$a; b0=$b; }
  printf '%-8s %12.2f %8.2f %22.2f %8.2f  %s\n' "$v" "$a" "$(echo "$a / $a0" | bc -l)" "$b" "$(echo "$b / $b0" | bc -l)" "$res"
done

proj="$out/sim"
if [ ! -f "$proj/project.toml" ]; then
  rm -rf "$proj"
  "$bin" simulate --out "$proj" --seed 1 >/dev/null
fi
echo "== pingcal calibrate (simulated project, seed 1; one range on line 11 of scans/S00.csv)"
printf '%-8s %-12s %10s %8s %12s  %s\n' range max_range_mm "total s" ratio "LRF step s" "mean check error"
for max in 5600.0 1000000.0; do
  for v in $values; do
    p="$out/sim-$v"
    rm -rf "$p"; mkdir -p "$p/scans"
    ln -s "$proj/images" "$p/images"
    sed "s/^max_range_mm = .*/max_range_mm = $max/" "$proj/project.toml" >"$p/project.toml"
    [ "$v" = clean ] && cp "$proj/scans/S00.csv" "$p/scans/S00.csv" || put_range "$proj/scans/S00.csv" "$v" "$p/scans/S00.csv"
    t=$(timed "$bin" calibrate "$p/project.toml" --out "$out/res-$v")
    lrf=$(grep -o 'LRF spheres [0-9.]* s' "$out/last.log" | head -1 | grep -o '[0-9.]*' || echo "?")
    check=$(grep -o 'mean check error: [^;]*' "$out/last.log" | head -1 | cut -c19-80)
    [ "$v" = clean ] && t0=$t
    printf '%-8s %-12s %10.2f %8.2f %12s  %s\n' "$v" "$max" "$t" "$(echo "$t / $t0" | bc -l)" "$lrf" "$check"
  done
done
