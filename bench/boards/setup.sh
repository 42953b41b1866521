#!/usr/bin/env bash
# Creates target/bench-venv with OpenCV (opencv-python-headless) and numpy for the board
# benchmarks (bench/boards/opencv.py). Idempotent. Not used in CI.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
venv="${BOARDS_VENV:-$root/target/bench-venv}"
py="${PYTHON:-python3}"
if [ ! -x "$venv/bin/python" ]; then
  "$py" -m venv "$venv"
fi
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
  "opencv-python-headless>=4.8" "numpy"
"$venv/bin/python" -c 'import cv2, numpy; print("cv2", cv2.__version__, "numpy", numpy.__version__)'
echo "venv ready: $venv"
