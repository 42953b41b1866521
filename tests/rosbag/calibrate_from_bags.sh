#!/usr/bin/env bash
# A simulated project calibrated from its scan CSV and from the same scans written as ROS 1,
# ROS 2 sqlite3 and MCAP bags by the `rosbags` package ([lrf.bag] in project-*.toml):
# the results must be the same. Prints a reason and exits 0 when rosbags cannot be
# installed. Work folder: target/rosbag-sim (made by make_fixtures.sh's simulation).
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
cd "$root"
venv=target/rosbags-venv
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c 'import rosbags, numpy' 2>/dev/null; then
    if ! { python3 -m venv "$venv" && "$venv/bin/pip" install -q 'rosbags==0.11.9' numpy; }; then
        echo "skipped: the rosbags package could not be installed in $venv"
        exit 0
    fi
fi
cargo build --release -q -p pingcal
sim=target/rosbag-sim
[ -f "$sim/scans/S00.csv" ] || target/release/pingcal simulate --out "$sim" --seed 7
"$venv/bin/python" tests/rosbag/make_fixtures.py --project "$sim"
rm -rf "$sim"/out-*
target/release/pingcal calibrate "$sim/project.toml" --out "$sim/out-csv" --quiet
status=0
for n in ros1 db3 mcap; do
    target/release/pingcal calibrate "$sim/project-$n.toml" --out "$sim/out-$n" --quiet
    # the one difference allowed: the corner baseline names its scan by line (CSV) or by
    # message number (bag)
    if diff <(sed 's/(file line [0-9]*,/(file line N,/' "$sim/out-csv/results.json") \
            <(sed 's/(file line [0-9]*,/(file line N,/' "$sim/out-$n/results.json") >/dev/null; then
        echo "$n: results.json the same as from the CSV"
    else
        echo "$n: results.json DIFFERS from the CSV's"; status=1
    fi
done
exit $status
