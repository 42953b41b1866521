#!/usr/bin/env bash
# Calibrates the simulated demo project of seeds 1, 2, 3 (or those given) and gathers their
# results.json into one folder, to compare a change against its parent with compare.py:
#   bash bench/pin/run.sh /tmp/before            # on the parent commit
#   bash bench/pin/run.sh /tmp/after             # on the change
#   python3 bench/pin/compare.py /tmp/before /tmp/after --ignore time_s
set -euo pipefail
out=${1:?usage: run.sh OUT_DIR [SEED...]}
shift
seeds=${*:-1 2 3}
cd "$(dirname "$0")/../.."
cargo build --release -p pingcal -q
mkdir -p "$out"
for s in $seeds; do
    work=$(mktemp -d)
    ./target/release/pingcal demo --seed "$s" --out "$work/demo" --quiet > "$out/demo_seed$s.txt"
    cp "$work/demo/results/results.json" "$out/seed$s.json"
    rm -rf "$work"
done
echo "results of seeds $seeds in $out"
