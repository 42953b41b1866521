#!/usr/bin/env bash
# The single-sphere calibration (issues 15 and 36) against the simulator's truth.
#
#   bash bench/spherecalib/run.sh [SIGMA_MM]   the clean rendering over 20 seeds: pingcal's
#       weighted estimate (silhouette cone fit with known radius, covariance-weighted 3D
#       conformal transform) beside the published closed form (Tóth, Pusztai & Hajder 2020:
#       sphere centre from the ellipse's major axis, unweighted SVD registration). Each seed
#       simulates 10 frames (a 600 mm sphere at 1-10 m, a 16-beam lidar with the VLP-16 noise
#       profile, the default camera). SIGMA_MM: a constant lidar range σ instead. Prints one
#       line per seed, then the table. About 2 minutes on 2 cores.
#   bash bench/spherecalib/run.sh cluttered    the harder rendering over 10 seeds (a shaded
#       sphere with a highlight on a stand, bricks, tiles, bright round plates, every fourth
#       frame across the image's border): frames used, the frames at least half visible that
#       were left out, the seeds whose extrinsic is within 3σ of the truth on every component.
#   bash bench/spherecalib/image_side.sh       the image side's time on one photograph.
set -euo pipefail
cd "$(dirname "$0")/../.."
if [ "${1:-}" = cluttered ]; then
  cargo test --release -p pingcal --test cli sphere_calib::cluttered_ten_seed_study -- --ignored --nocapture 2>&1 \
      | tee "${TMPDIR:-/tmp}/spherecalib-cluttered.log" | grep -E '^cluttered'
  exit 0
fi
if [ $# -ge 1 ]; then export PINGCAL_SPHERECALIB_LIDAR_SIGMA_MM="$1"; fi
cargo test --release -p pingcal --test cli sphere_calib::twenty_seed_comparison -- --ignored --nocapture 2>&1 \
    | tee "${TMPDIR:-/tmp}/spherecalib-bench.log" \
    | grep -E '^(seed [0-9]+:|\||frames used|centres of the frames)'
echo "frames left out, by reason:"
grep -E '^seed [0-9]+ F[0-9]+ skipped' "${TMPDIR:-/tmp}/spherecalib-bench.log" \
    | sed -E 's/.*(no sphere of [0-9]+ mm found|spheres of [0-9]+ mm found, one expected|no sphere silhouette where|silhouettes where the lidar).*/\1/' \
    | sort | uniq -c
