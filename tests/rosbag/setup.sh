#!/usr/bin/env bash
# Makes target/rosbags-venv: the independent bag writers the rosbag fixtures and the
# `pingcal frames` test use (`rosbags`, the `mcap` package with zstd and lz4, numpy, pillow).
# tests/scans.rs skips, saying so, where it is absent. Exits 1 when PyPI cannot be reached.
#
#   bash tests/rosbag/setup.sh        # from anywhere
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
venv="$root/target/rosbags-venv"
if [ -x "$venv/bin/python" ] && "$venv/bin/python" -c 'import rosbags, numpy, mcap, zstandard, lz4, PIL' 2>/dev/null; then
    exit 0
fi
python3 -m venv "$venv"
"$venv/bin/pip" install -q 'rosbags==0.11.9' numpy 'mcap==1.6.0' 'zstandard==0.25.0' 'lz4==4.4.5' 'pillow==11.3.0'
