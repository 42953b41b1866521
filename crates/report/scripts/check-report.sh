#!/usr/bin/env bash
# Renders REPORT.html in headless Chromium and checks the screenshot is non-trivial.
#   crates/report/scripts/check-report.sh REPORT.html OUT.png [MIN_BYTES (default 20000)]
# Installs Debian's chromium with apt-get when /usr/bin/chromium is missing and we are root.
set -euo pipefail
if [ $# -lt 2 ]; then
    echo "usage: $0 REPORT.html OUT.png [MIN_BYTES]" >&2
    exit 2
fi
report=$(realpath "$1")
out=$(realpath -m "$2")
min=${3:-20000}
[ -f "$report" ] || { echo "no such file: $report" >&2; exit 2; }
chromium=/usr/bin/chromium
if [ ! -x "$chromium" ]; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        echo "installing chromium with apt-get" >&2
        apt-get update -qq >&2
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >&2
    else
        echo "skipped: /usr/bin/chromium not installed (and not root to install it)" >&2
        exit 3
    fi
fi
profile=$(mktemp -d)
trap 'rm -rf "$profile"' EXIT
rm -f "$out"
timeout 120 "$chromium" --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
    --disable-background-networking --disable-component-update --disable-sync \
    --user-data-dir="$profile" --window-size=1400,4000 --hide-scrollbars \
    --screenshot="$out" "file://$report" >"$profile/chromium.log" 2>&1 || {
    echo "chromium failed:" >&2
    cat "$profile/chromium.log" >&2
    exit 1
}
if [ ! -f "$out" ]; then
    echo "no screenshot written" >&2
    cat "$profile/chromium.log" >&2
    exit 1
fi
size=$(stat -c %s "$out")
if [ "$size" -lt "$min" ]; then
    echo "screenshot $out is only $size bytes (< $min): blank page?" >&2
    exit 1
fi
echo "$out: $size bytes"
