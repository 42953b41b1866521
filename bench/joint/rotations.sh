#!/usr/bin/env bash
# Issue 13, "the camera and the LRF need not look the same way" (the paper's requirement 3):
# the joint adjustment on rigs whose LRF is turned 0°, 45°, 90° and 180° about the vertical
# (the camera's y axis: φ of the extrinsic) with random mount and range errors, SEEDS seeds
# each; prints study.py's table per rotation.
#
#   bash bench/joint/rotations.sh [SEEDS=1-5] [BIN=target/release/pingcal]
set -euo pipefail
cd "$(dirname "$0")/../.."
seeds=${1:-1-5}
bin=${2:-target/release/pingcal}
for phi in 0 45 90 180; do
  echo "== LRF turned ${phi}° about the vertical"
  # the default extrinsic is ω, φ, κ = 0.8°, −1.2°, 0.6°: φ turned by the rotation
  p=$(python3 -c "print(-1.2 + $phi)")
  python3 bench/joint/study.py --seeds "$seeds" --mount-errors random --bin "$bin" \
    --work "/tmp/joint-rot-$phi" --extra "extrinsic_opk_deg = [0.8, $p, 0.6]" | grep -v '^{'
done
