#!/usr/bin/env bash
# pingcal vs OpenCV (SimpleBlobDetector + fitEllipse) on the real AICON panel photographs and a
# 24-megapixel synthetic image with known centres. Not part of CI.
#   bash bench/targets/run.sh [--threads 1,2] [--reps 5]      (from the repository root)
# Makes its own virtual environment in bench/targets/.venv (opencv-python-headless from PyPI).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
venv="$here/.venv"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install --quiet --upgrade pip
  "$venv/bin/pip" install --quiet opencv-python-headless numpy
fi
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target-targets}"
(cd "$root" && cargo build --quiet --release -p pingcal-targets --example bench_detect)
mkdir -p "$here/out"
"$venv/bin/python" "$here/compare.py" \
  --pingcal "$CARGO_TARGET_DIR/release/examples/bench_detect" \
  --panel "$root/../shared/data/aicon-panel/images" \
  --work "$here/out" "$@" 2> >(grep -v TIFF_Warning >&2) | tee "$here/out/report.md"
