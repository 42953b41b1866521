#!/usr/bin/env bash
# Ball-finding benchmark: pingcal vs pyransac3d vs Open3D on the same ~1M-point cloud.
# Makes its own venv under bench/.venv-lrf (gitignored); never run in CI.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
venv="$root/bench/.venv-lrf"
[ -d "$venv" ] || python3 -m venv "$venv"
"$venv/bin/pip" install -q pyransac3d open3d numpy
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target-lrf}"
out=$(mktemp -d)
PINGCAL_BENCH_XYZ="$out/cloud.xyz" cargo bench -q -p pingcal-lrf --bench ball_finding
"$venv/bin/python" "$here/py_sphere_ransac.py" "$out/cloud.xyz" "$out/cloud.xyz.balls"
