#!/usr/bin/env bash
# The single-sphere calibration (issue 15) over 20 seeds: pingcal's weighted estimate
# (cone fit of the silhouette with known radius, covariance-weighted 3D conformal transform)
# beside the published closed form (Tóth, Pusztai & Hajder 2020: sphere centre from the
# ellipse's major axis, unweighted SVD registration), both against the simulator's truth.
# Each seed simulates 10 frames (a 600 mm sphere at 1-10 m, a 16-beam lidar with the VLP-16
# noise profile, the default camera) with `pingcal_sim::sphere_calib`, and runs
# `pingcal::commands::sphere_calib::calibrate` on the files.
# Prints one line per seed, then the table. About 1 minute on 2 cores.
# `bash bench/spherecalib/run.sh 30`: the same with a lidar range σ of 30 mm (constant).
set -euo pipefail
cd "$(dirname "$0")/../.."
if [ $# -ge 1 ]; then export PINGCAL_SPHERECALIB_LIDAR_SIGMA_MM="$1"; fi
cargo test --release -p pingcal --test sphere_calib twenty_seed_comparison -- --ignored --nocapture 2>&1 \
    | tee "${TMPDIR:-/tmp}/spherecalib-bench.log" \
    | grep -E '^(seed [0-9]+:|\||frames used|centres of the frames)'
echo "frames left out, by reason:"
grep -E '^seed [0-9]+ F[0-9]+ skipped' "${TMPDIR:-/tmp}/spherecalib-bench.log" \
    | sed -E 's/.*(no sphere of [0-9]+ mm found|spheres of [0-9]+ mm found, one expected|no bright silhouette|round bright silhouettes|no round bright).*/\1/' \
    | sort | uniq -c
