#!/usr/bin/env bash
# Makes target/ecosystem-venv: the Python packages that check pingcal's ROS, OpenCV and
# Kalibr outputs with each ecosystem's own code (tests/ecosystem.rs runs the checks when
# this venv exists, and skips them with a printed reason otherwise).
#
#   bash tests/ecosystem/setup.sh        # from the repository root
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
venv="$root/target/ecosystem-venv"
python3 -m venv "$venv"
"$venv/bin/python" -m pip install --quiet --upgrade pip
"$venv/bin/python" -m pip install --quiet \
    "opencv-python-headless>=4.8" "scipy>=1.10" "PyYAML>=6" "urdf-parser-py>=0.0.4" \
    "yourdfpy>=0.0.56,<0.1"
"$venv/bin/python" - <<'PY'
import cv2, scipy, yaml, urdf_parser_py, yourdfpy
print("ecosystem venv ready: OpenCV", cv2.__version__, "SciPy", scipy.__version__, "PyYAML", yaml.__version__,
      "yourdfpy", getattr(yourdfpy, "__version__", "?"))
PY
