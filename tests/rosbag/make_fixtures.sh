#!/usr/bin/env bash
# Writes crates/rosbag/tests/data/ with the `rosbags` Python package (an independent
# writer of ROS 1 and ROS 2 bags), from the scans of a simulated project. Run from anywhere;
# it builds pingcal, makes a virtual environment under target/ and prints a reason and
# exits 0 when rosbags cannot be installed.
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
cd "$root"
venv=target/rosbags-venv
if ! bash tests/rosbag/setup.sh; then
    echo "skipped: the rosbags package could not be installed in $venv"
    exit 0
fi
cargo build --release -q -p pingcal
sim=target/rosbag-sim
[ -f "$sim/scans/S00.csv" ] || target/release/pingcal simulate --out "$sim" --seed 7
"$venv/bin/python" tests/rosbag/make_fixtures.py "$sim/scans/S00.csv" crates/rosbag/tests/data
