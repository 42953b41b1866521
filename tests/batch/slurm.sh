#!/usr/bin/env bash
# Runs docs/batch/slurm-array.sh on a single-node Slurm started here, then stops it.
#
#   bash tests/batch/slurm.sh WORK PINGCAL PROJECT.toml...
#
# Starts munged and a Slurm controller and node of its own (config, key, sockets, state and
# logs all under WORK/slurm, on free ports, the machine's own Slurm and munge untouched),
# writes WORK/projects.txt (one project per line), runs
# `sbatch --wait --array=0-(N-1) docs/batch/slurm-array.sh projects.txt WORK/results` from WORK
# and writes sbatch's exit code to WORK/sbatch.rc; the tasks' JSON lines and results are
# in WORK/results/<i>.json and WORK/results/<i>/. Every daemon it started is stopped on exit.
# Exits 0 when the array ran (whatever its tasks' codes), 77 with a line `skip: REASON` when
# Slurm cannot run here (not root, slurm-wlm not installed: `.ci/run` installs it), 1 when
# Slurm was there and failed.
set -uo pipefail
skip() { echo "skip: $*"; exit 77; }
fail() { echo "slurm.sh: $*" >&2; for f in "$D"/*.log; do [ -f "$f" ] && { echo "== $f" >&2; tail -20 "$f" >&2; }; done; exit 1; }
[ $# -ge 3 ] || { echo "usage: $0 WORK PINGCAL PROJECT.toml..." >&2; exit 2; }
work="$(mkdir -p "$1" && cd "$1" && pwd)"
pingcal="$(cd "$(dirname "$2")" && pwd)/$(basename "$2")"
shift 2
here="$(cd "$(dirname "$0")" && pwd)"
script="$here/../../docs/batch/slurm-array.sh"
D="$work/slurm"

[ "$(id -u)" = 0 ] || skip "not root: slurmd must run as root to start jobs"
for b in munged slurmctld slurmd sbatch sinfo scontrol; do
    command -v "$b" >/dev/null || skip "$b not found (Debian: apt-get install slurm-wlm; .ci/run does)"
done

# A free TCP port of localhost, from a start.
free_port() {
    local p="$1"
    while (exec 3<>"/dev/tcp/127.0.0.1/$p") 2>/dev/null; do p=$((p + 1)); done
    echo "$p"
}

pids=()
stop() {
    # only the daemons this script started, by their pid files
    for f in "$D/slurmd.pid" "$D/slurmctld.pid" "$D/munged.pid"; do
        [ -s "$f" ] && kill "$(cat "$f")" 2>/dev/null
    done
    sleep 1
    for f in "$D/slurmd.pid" "$D/slurmctld.pid" "$D/munged.pid"; do
        [ -s "$f" ] && kill -9 "$(cat "$f")" 2>/dev/null
    done
    return 0
}
trap stop EXIT

rm -rf "$D" && mkdir -p "$D/state" "$D/spool" && chmod 700 "$D"
head -c 1024 /dev/urandom >"$D/munge.key" && chmod 400 "$D/munge.key"
munged --key-file="$D/munge.key" --socket="$D/munge.socket" --pid-file="$D/munged.pid" \
    --log-file="$D/munged.log" --seed-file="$D/munged.seed" --force \
    || skip "munged does not start here: $(tail -1 "$D/munged.log" 2>/dev/null)"

host="$(hostname -s)"
ctld_port="$(free_port 16817)"
slurmd_port="$(free_port $((ctld_port + 1)))"
cat >"$D/slurm.conf" <<CONF
ClusterName=pingcal-test
SlurmctldHost=localhost
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$D/munge.socket
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$D/state
SlurmdSpoolDir=$D/spool
SlurmctldPidFile=$D/slurmctld.pid
SlurmdPidFile=$D/slurmd.pid
SlurmctldLogFile=$D/slurmctld.log
SlurmdLogFile=$D/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
ReturnToService=2
NodeName=$host NodeAddr=127.0.0.1 CPUs=$(nproc) State=UNKNOWN
PartitionName=batch Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF="$D/slurm.conf"
slurmctld -f "$SLURM_CONF" || fail "slurmctld did not start"
slurmd -f "$SLURM_CONF" -N "$host" || fail "slurmd did not start"
state=""
for _ in $(seq 60); do
    state="$(sinfo -h -N -o %T 2>/dev/null | head -1)"
    [ "$state" = idle ] && break
    sleep 1
done
[ "$state" = idle ] || fail "the node is not idle after 60 s (state: '${state:-none}')"

cd "$work" || exit 1
: >projects.txt
for p in "$@"; do echo "$p" >>projects.txt; done
n="$(wc -l <projects.txt)"
rm -rf results
PINGCAL="$pingcal" timeout 600 sbatch --wait --array=0-$((n - 1)) "$script" projects.txt "$work/results"
echo $? >sbatch.rc
echo "sbatch --wait exited $(cat sbatch.rc)"
cat pingcal-*.log 2>/dev/null
exit 0
