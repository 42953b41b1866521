#!/usr/bin/env bash
# Issue 16's streaming benchmark: `pingcal scans` on bags of SIZE_MB (default 1,100 MB)
# written by independent writers: ROS 1 and uncompressed MCAP by `rosbags`, zstd-chunked
# MCAP (rosbag2's MCAP default) by the `mcap` package. Prints MB/s (the bag file's bytes
# over wall time, from a warm page cache) and peak RSS for: reading and decoding every scan
# (the read_bag example: the reader alone), --list, and a full conversion to a scan file
# (reading plus writing ~0.9 GB of CSV).
#   bash bench/rosbag/run.sh [SIZE_MB]      (from the repository root; EXTS="bag mcap zstd.mcap db3")
# ZSTD_C=1 also times the reader built with the C zstd (feature pingcal-rosbag/zstd-c).
# SIZE_MB counts the messages' bytes; for a zstd MCAP of about 1 GB on disk give 3750.
# Wall times need an otherwise idle machine: the reader decompresses on one thread while it
# decodes on another (2 cores); the table's user+sys CPU seconds do not depend on the load.
# Installs the writers in target/rosbags-venv. Writes target/rosbag-big/ (several GB:
# removed at the end unless KEEP=1).
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
cd "$root"
size="${1:-1100}"
venv=target/rosbags-venv
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c 'import rosbags, numpy, mcap, zstandard' 2>/dev/null; then
    python3 -m venv "$venv" && "$venv/bin/pip" install -q 'rosbags==0.11.9' numpy 'mcap==1.6.0' 'zstandard==0.25.0'
fi
bin="${PINGCAL:-${CARGO_TARGET_DIR:-target}/release/pingcal}"
tdir="${CARGO_TARGET_DIR:-target}"
cargo build --release -q -p pingcal
if [ "${ZSTD_C:-0}" = 1 ]; then
    cargo build --release -q -p pingcal-rosbag --example read_bag --features zstd-c
    cp "$tdir/release/examples/read_bag" "$tdir/release/examples/read_bag_zstd_c"
fi
cargo build --release -q -p pingcal-rosbag --example read_bag
big=target/rosbag-big
mkdir -p "$big"
[ -f "$big/sim/scans/S00.csv" ] || "$bin" simulate --out "$big/sim" --seed 7 >/dev/null
printf '| bag | size MB | command | wall s | MB/s | peak RSS MB |\n|---|---|---|---|---|---|\n' >"$big/table.md"
for ext in ${EXTS:-bag mcap zstd.mcap}; do
    f="$big/big.$ext"
    [ -f "$f" ] || "$venv/bin/python" bench/rosbag/big_bag.py "$big/sim" "$f" "$size"
    mb=$(python3 -c "import os; print(os.path.getsize('$f') / 1e6)")
    cat "$f" >/dev/null # warm the page cache
    "${READ_BAG:-$tdir/release/examples/read_bag}" "$f" /scan /joint_states servo | tee "$big/read.txt"
    if [ "${ZSTD_C:-0}" = 1 ]; then
        /usr/bin/time -f "%e s wall, %U s user, %S s sys, %M KB peak" "$tdir/release/examples/read_bag_zstd_c" "$f" /scan /joint_states servo
    fi
    python3 - "$big/read.txt" "$ext" "$mb" >>"$big/table.md" <<'PY'
import re, sys
t = open(sys.argv[1]).read()
s = float(re.search(r"([0-9.]+) s \(", t).group(1)); rss = float(re.search(r"peak RSS ([0-9.]+)", t).group(1))
mb = float(sys.argv[3])
print(f"| {sys.argv[2]} | {mb:.0f} | read (decode every scan, no output) | {s:.2f} | {mb / s:.0f} | {rss:.1f} |")
PY
    for mode in list decode; do
        rm -f "$big/out.csv"
        if [ $mode = list ]; then args=(--list); else args=(--scan-topic /scan --servo-topic /joint_states --servo-joint servo --out "$big/out.csv"); fi
        /usr/bin/time -f "%e %M" -o "$big/time" "$bin" scans "$f" "${args[@]}" >/dev/null
        read -r wall kb <"$big/time"
        python3 -c "print(f'| $ext | {$mb:.0f} | $mode | {$wall:.2f} | {$mb / max($wall, 1e-3):.0f} | {$kb / 1024:.1f} |')" >>"$big/table.md"
    done
done
cat "$big/table.md"
[ "${KEEP:-0}" = 1 ] || rm -f "$big"/big.* "$big/out.csv"
