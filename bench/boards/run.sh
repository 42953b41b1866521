#!/usr/bin/env bash
# The chessboard benchmark (bench/boards/README.md): OpenCV's corners and calibration
# (opencv.py, writes opencv-chessboard.json), pingcal's corners (the board_corners
# example), and the tables (compare.py). Not in CI.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
data="${1:-$root/../shared/data/opencv-chessboard}"
bash "$here/setup.sh" >/dev/null
py="$root/target/bench-venv/bin/python"
"$py" "$here/opencv.py" "$data" "$here/opencv-chessboard.json" 2>/dev/null
cargo build --release -q -p pingcal-targets --example board_corners
out="$(mktemp)"
"$root/target/release/examples/board_corners" 9 6 "$data"/*.jpg > "$out"
"$py" "$here/compare.py" "$out" "$data"
"$py" "$here/edges.py" "$out"
rm -f "$out"
