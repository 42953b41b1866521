#!/usr/bin/env bash
# Wall time and peak memory of `pingcal demo` (issue 7: under 60 s on 2 cores, release build),
# with the split between simulation and calibration and the calibration's own steps.
#
#   bash bench/demo/run.sh [RUNS=3] [SEED=1]
set -euo pipefail
cd "$(dirname "$0")/../.."
runs=${1:-3}
seed=${2:-1}
cargo build --release -p pingcal >/dev/null
bin=target/release/pingcal
echo "machine: $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"
for r in $(seq 1 "$runs"); do
  log=$(mktemp)
  /usr/bin/time -f "%e %M" -o "$log.time" "$bin" demo --seed "$seed" >"$log" 2>"$log.err"
  read -r wall rss <"$log.time"
  split=$(grep -o 'simulated in [0-9.]* s, calibrated in [0-9.]* s' "$log")
  steps=$(grep -o 'time: .*' "$log.err" | head -1)
  sim=$(grep -o '(scene and LRF sweep [^)]*)' "$log.err" | head -1)
  echo "run $r: wall ${wall} s, peak RSS $((rss / 1024)) MiB; $split; simulation $sim; calibration $steps"
  rm -f "$log" "$log.time" "$log.err"
done
