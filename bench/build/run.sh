#!/usr/bin/env bash
# A fresh clone's build and tests, as the README's second command runs them, timed:
#   bash bench/build/run.sh [COMMIT]
# Clones this repository (at COMMIT, default HEAD) into a temporary folder, builds every
# test binary with `cargo test --workspace --release --no-run --timings`, then runs
# `cargo test --workspace --release` there, and prints the build's wall time, its 25
# longest units (cargo's own timings) and each test binary's wall time. Nothing is cached
# between runs but the registry's downloads; the machine's load is not controlled, so
# compare two commits in the same session, one after the other.
set -euo pipefail
repo="$(cd "$(dirname "$0")/../.." && pwd)"
commit="${1:-HEAD}"
work="$(mktemp -d /tmp/pingcal-build-bench.XXXXXX)"
trap 'rm -rf "$work"' EXIT
git clone -q "$repo" "$work/src"
cd "$work/src"
git checkout -q "$commit"
echo "commit $(git log --oneline -1)"
start=$(date +%s)
CI=true cargo test --workspace --release --no-run --timings >"$work/build.log" 2>&1
built=$(date +%s)
echo "build: $((built - start)) s, $(grep -c Executable "$work/build.log") test binaries"
python3 - "$work/src/target/cargo-timings/cargo-timing.html" <<'PY'
import json, re, sys
html = open(sys.argv[1]).read()
units = json.loads(re.search(r"const UNIT_DATA = (\[.*?\]);\n", html, re.S).group(1))
total = sum(u["duration"] for u in units)
own = sum(u["duration"] for u in units if u["name"].startswith("pingcal"))
print(f"units: {len(units)}, {total:.0f} s in all ({own:.0f} s pingcal's own crates)")
for u in sorted(units, key=lambda u: -u["duration"])[:25]:
    print(f"  {u['duration']:6.1f} s  {u['name']} {u['target'].strip()}")
PY
CI=true cargo test --workspace --release 2>&1 | while IFS= read -r line; do
    printf '%s %s\n' "$(date +%s)" "$line"
done >"$work/test.log"
done_at=$(date +%s)
echo "tests: $((done_at - built)) s; build and tests: $((done_at - start)) s"
awk '/ Running /{if (name) print "  " $1 - t " s  " name; t = $1; name = $NF}
     / Doc-tests /{if (name) print "  " $1 - t " s  " name; name = ""}' "$work/test.log"
grep -h "test result" "$work/test.log" | awk '{p += $5; f += $7; i += $9} END {print "passed " p ", failed " f ", ignored " i}'
