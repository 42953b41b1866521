#!/usr/bin/env bash
# The image side of `pingcal sphere-calib` on one core: per photograph of SphereCalib's
# example 3 (1280 × 1024, ../shared/data/spherecalib-ex3-cam2), the time to load it, to find
# the candidate circles (edges at three scales, Hough of centres) and to fit every candidate's
# silhouette cone — everything the command does per photograph before the lidar helps choose.
# Best of REPS repetitions (default 3). The camera: the data set's pinhole (f 4546.4 px,
# principal point (703.2, 609.2) px), the ball's radius 300 mm.
#   bash bench/spherecalib/image_side.sh [REPS]
set -euo pipefail
cd "$(dirname "$0")/../.."
data=../shared/data/spherecalib-ex3-cam2/images
if [ ! -d "$data" ]; then
  echo "skipped: $data is absent" >&2
  exit 0
fi
cargo build --release -q -p pingcal-targets --example bench_silhouette
bin="${CARGO_TARGET_DIR:-target}/release/examples/bench_silhouette"
RAYON_NUM_THREADS=1 taskset -c 0 "$bin" 4546.4 703.2 609.2 300 --reps "${1:-3}" "$data"/*.png \
  | grep -E '^[^ ].*image side'
