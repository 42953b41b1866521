#!/usr/bin/env bash
# `pingcal plan` on the paper's field (issue 18, "Must show"):
#  (1) its wall time with the defaults (5 seeds, each station and distance removed once);
#  (2) the planner's predicted σ of the extrinsic against the RMS of the true errors over
#      SEEDS simulated seeds of the same plan (`pingcal plan --seeds SEEDS`, which reports
#      both): goal, a ratio within 20 % (0.8–1.25) per component.
#
#   bash bench/plan/run.sh [SEEDS=20] [CONFIG=]    (CONFIG: a simulation.toml; default the paper's field)
#
# The two plan.json files are kept in $OUT (default /tmp/pingcal-bench-plan).
set -euo pipefail
cd "$(dirname "$0")/../.."
seeds=${1:-20}
config=${2:-}
cargo build --release -p pingcal >/dev/null
bin=target/release/pingcal
cfg=()
[ -n "$config" ] && cfg=(--config "$config")
tmp=${OUT:-/tmp/pingcal-bench-plan}
mkdir -p "$tmp"
echo "machine: $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"

echo "== (1) pingcal plan ${cfg[*]} (defaults: 5 seeds, sensitivity on 1 seed)"
/usr/bin/time -f "%e %M" -o "$tmp/time" "$bin" plan "${cfg[@]}" --quiet --out "$tmp/plan5.json" | tee "$tmp/plan5.txt"
read -r wall rss <"$tmp/time"
echo "wall ${wall} s, peak RSS $((rss / 1024)) MiB"

echo
echo "== (2) pingcal plan ${cfg[*]} --seeds $seeds --no-sensitivity"
/usr/bin/time -f "%e %M" -o "$tmp/time" "$bin" plan "${cfg[@]}" --seeds "$seeds" --no-sensitivity --quiet --out "$tmp/plan.json" >"$tmp/plan.txt"
read -r wall20 rss20 <"$tmp/time"
head -1 "$tmp/plan.txt"
grep '^  failed' "$tmp/plan.txt" || true
echo "wall ${wall20} s, peak RSS $((rss20 / 1024)) MiB"
echo
jq -r '. as $root |
  "component   predicted σ   Monte Carlo RMS error   ratio   within 20 %   in the honest band (95 %, \(.calibrated) seeds)",
  (.extrinsic[], .ball_centres[] |
    [.name, .predicted_sigma, .monte_carlo_rms_error, .ratio] as [$n, $p, $m, $r] |
    "\($n | . + (" " * (10 - length)))  \($p * 10000 | round / 10000 | tostring | . + (" " * (12 - length)))  \($m * 10000 | round / 10000 | tostring | . + (" " * (22 - length)))  \($r * 100 | round / 100 | tostring | . + (" " * (6 - length)))  \(if $r >= 0.8 and $r <= 1.25 then "yes" else "no " end)           \(if .consistent_with_honest_sigma then "yes" else "no" end)"),
  "",
  "per seed (n = \(.runs | length)): mean error (bias) and RMS of error / its own σ",
  (["tx", "ty", "tz"] | to_entries[] | .key as $k | .value as $n |
    "\($n) mm   bias \([$root.runs[].error_translation_mm[$k]] | add / length * 1000 | round / 1000)   RMS(error/σ) \([$root.runs[] | (.error_translation_mm[$k] / .sigma_translation_mm[$k]) | . * .] | add / length | sqrt * 100 | round / 100)"),
  (["ω", "φ", "κ"] | to_entries[] | .key as $k | .value as $n |
    "\($n) deg  bias \([$root.runs[].error_rotation_deg[$k]] | add / length * 10000 | round / 10000)   RMS(error/σ) \([$root.runs[] | (.error_rotation_deg[$k] / .sigma_rotation_deg[$k]) | . * .] | add / length | sqrt * 100 | round / 100)"),
  "",
  "check error: expected \(.expected_check_error_mm * 100 | round / 100) mm, simulated mean \(.mean_check_error_mm * 100 | round / 100) mm (sd \(.sd_check_error_mm * 100 | round / 100)) over \(.calibrated) seeds",
  "extrinsic given by: \([.runs[].method] | group_by(.) | map("\(.[0]) \(length)") | join(", ")); verdicts: \([.runs[].verdict] | group_by(.) | map("\(.[0]) \(length)") | join(", "))"
' "$tmp/plan.json"
echo "(plan.json files in $tmp)"
