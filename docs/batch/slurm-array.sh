#!/bin/bash
# A Slurm job array calibrating one pingcal project per task (docs/batch.md).
#
#   sbatch --array=0-$(( $(wc -l < projects.txt) - 1 )) slurm-array.sh projects.txt results
#
# projects.txt: one project file per line (relative to the folder sbatch is run from, or
# absolute). Task i calibrates line i+1 into RESULTS/<i>/ and writes its JSON line to
# RESULTS/<i>.json; the task's exit code is pingcal's (0 ok, 3 doubtful, 4 failed,
# 1 not calibrated), so `sbatch --wait` exits with the worst code of the array.
# PINGCAL (environment) names the binary (default: pingcal on the PATH).
#SBATCH --job-name=pingcal
#SBATCH --cpus-per-task=1
#SBATCH --output=pingcal-%A_%a.log
set -uo pipefail
list="${1:?usage: sbatch --array=0-N slurm-array.sh PROJECTS.txt RESULTS}"
results="${2:?usage: sbatch --array=0-N slurm-array.sh PROJECTS.txt RESULTS}"
task="${SLURM_ARRAY_TASK_ID:?not a task of a Slurm job array (sbatch --array=0-N)}"
project="$(sed -n "$((task + 1))p" "$list")"
if [ -z "$project" ]; then
    echo "task $task: $list has no line $((task + 1))" >&2
    exit 1
fi
mkdir -p "$results"
# --threads: the CPUs Slurm gave the task, not all of the node's
"${PINGCAL:-pingcal}" calibrate "$project" --out "$results/$task" --json --quiet \
    --threads "${SLURM_CPUS_PER_TASK:-1}" >"$results/$task.json"
status=$?
echo "task $task: $project: exit $status"
exit "$status"
