#!/usr/bin/env bash
# Sphere finding in 100k-point lidar frames (issue 15): pingcal's find_balls against
# pyransac3d (PyPI) on the same simulated frames of a 600 mm sphere (16 rings, 0.042°
# azimuth steps: about 100k points a frame (137k beams; the upper rings see the sky), floor and wall), time and centre error against the
# simulator's truth. Makes its own venv bench/.venv-lrf; never run in CI.
#
#   bash bench/lrf/frame.sh [FRAMES=5]
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
frames=${1:-5}
venv="$root/bench/.venv-lrf"
[ -d "$venv" ] || python3 -m venv "$venv"
"$venv/bin/pip" install -q pyransac3d numpy
cd "$root"
cargo build -q --release -p pingcal
cargo build -q --release -p pingcal-lrf --example find_xyz
bin=${CARGO_TARGET_DIR:-target}/release
out=$(mktemp -d)
"$bin/pingcal" simulate --kind sphere-calib --frames "$frames" --azimuth-step-deg 0.042 --seed 5 --out "$out/set" >/dev/null
echo "machine: $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"
python3 - "$out/set" "$bin" <<'PY'
import json, os, subprocess, sys
d, bin = sys.argv[1], sys.argv[2]
t = json.load(open(os.path.join(d, "truth.json")))
for fr in t["frames"]:
    out = subprocess.run([os.path.join(bin, "examples", "find_xyz"), os.path.join(d, fr["cloud"]), "600", "m", "VLP-16", "5"],
                         capture_output=True, text=True, check=True).stdout.splitlines()
    c = [float(v) for v in out[1].split()[1:4]] if len(out) > 1 else None
    tc = fr["centre_lidar_mm"]
    err = sum((a - b) ** 2 for a, b in zip(c, tc)) ** 0.5 if c else float("nan")
    print(f"pingcal {fr['id']}: {out[0].split(': ', 1)[1]}; centre error {err:.2f} mm")
PY
"$venv/bin/python" "$here/py_frame_ransac.py" "$out/set"
rm -rf "$out"
