#!/usr/bin/env bash
# The cluster profile against a real scheduler: a private one-node SLURM without accounting.
#
#   tests/slurm/run_slurm_test.sh WORKDIR      (as root; tests/slurm/test_slurm_profile.py runs it)
#
# Installs Debian's slurm-wlm and munge if they are missing (apt-get), and the SLURM executor
# plugin if it is missing (pip). Starts munged, slurmctld and slurmd on this machine with
# their own key, socket, ports, config and state under WORKDIR (SLURM_CONF points every
# SLURM command there), so nothing of a cluster already on the machine is read or touched.
# Accounting is off (no slurmdbd), so sacct fails as on many small clusters. Then:
#   1. `snakemake --profile` with a profile derived from profiles/slurm (the shipped settings,
#      with the tiny test configs instead of the paper-size ones) builds the tiny config's
#      table and the Section 4 objects drawn on it: each job must go through sbatch and
#      complete (slurmctld's log; there is no sacct);
#   2. the same command again must submit nothing ("Nothing to be done").
# Every daemon it started is stopped on exit, also on failure or interruption.
# Exit status: 0 passed, 77 skipped (the reason on the last line), anything else failed.
set -euo pipefail

REPO="$(cd "$(dirname "$0")/../.." && pwd)"
WORK="$(mkdir -p "${1:?usage: $0 WORKDIR}" && cd "$1" && pwd)"
TARGET="results/section4/objects.csv"
N_JOBS=2              # table, then s4_objects on it: one job waits on the other
RUN_LIMIT=300         # seconds for the first run (1-2 minutes; each job starts Snakemake again)
PY="${PYTHON:-python3}"

skip() { echo "SKIP: $*"; exit 77; }
fail() { echo "FAIL: $*" >&2; exit 1; }
step() { echo "[slurm-test $(date +%H:%M:%S)] $*"; }

[ "$(uname -s)" = Linux ] || skip "needs Linux"
[ "$(id -u)" -eq 0 ] || skip "needs root to start munged, slurmctld and slurmd"

# -- software: Debian's SLURM and munge, the executor plugin ------------------------------
daemon_pids() { for name in munged slurmctld slurmd slurmstepd; do pgrep -x "$name" || true; done | tr '\n' ' '; }
before_install="$(daemon_pids)"
if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null || ! command -v munged >/dev/null; then
    command -v apt-get >/dev/null || skip "slurmctld/slurmd/munged not installed and no apt-get to install them"
    step "installing slurm-wlm and munge with apt-get"
    export DEBIAN_FRONTEND=noninteractive
    timeout 300 apt-get update -q >"$WORK/apt.log" 2>&1 || true
    timeout 600 apt-get install -y -q -o DPkg::Lock::Timeout=120 slurm-wlm munge >>"$WORK/apt.log" 2>&1 \
        || { tail -5 "$WORK/apt.log"; skip "apt-get could not install slurm-wlm and munge (see $WORK/apt.log)"; }
    # a package's scripts may start its service: stop what the install started
    for pid in $(daemon_pids); do
        case " $before_install " in *" $pid "*) ;; *) kill "$pid" 2>/dev/null || true ;; esac
    done
fi
if ! "$PY" -c "import snakemake_executor_plugin_slurm" 2>/dev/null; then
    step "installing snakemake-executor-plugin-slurm with pip"
    timeout 300 "$PY" -m pip install -q "snakemake-executor-plugin-slurm>=2.8,<3" \
        || skip "pip could not install snakemake-executor-plugin-slurm"
fi

# -- a private one-node cluster ----------------------------------------------------------
D="$WORK/cluster"
rm -rf "$D" && mkdir -p "$D/state" "$D/spool" "$D/munge" && chmod 700 "$D" "$D/munge"
PIDS=()
steps_before=""

stop_daemons() {
    local rc=$?
    trap - EXIT INT TERM
    if [ -n "${SLURM_CONF:-}" ] && [ ${#PIDS[@]} -gt 0 ]; then
        # cancel what is left of our jobs before their daemons go
        timeout 10 scancel --quiet --full --user=root >/dev/null 2>&1 || true
    fi
    for pid in "${PIDS[@]}"; do kill "$pid" 2>/dev/null || true; done
    for pid in "${PIDS[@]}"; do
        for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.2; done
        kill -9 "$pid" 2>/dev/null || true
    done
    # job steps started by our slurmd end with their jobs; none may stay
    sleep 1
    for pid in $(pgrep -x slurmstepd || true); do
        case " $steps_before " in *" $pid "*) ;; *) kill -9 "$pid" 2>/dev/null || true ;; esac
    done
    step "stopped munged, slurmctld and slurmd (pids ${PIDS[*]:-none})"
    exit "$rc"
}
trap stop_daemons EXIT
trap 'exit 130' INT TERM

free_port() { "$PY" -c 'import socket; s = socket.socket(); s.bind(("", 0)); print(s.getsockname()[1])'; }

wait_for() {  # wait_for SECONDS WHAT COMMAND...: poll until COMMAND succeeds
    local limit=$1 what=$2; shift 2
    for _ in $(seq $((limit * 2))); do "$@" >/dev/null 2>&1 && return 0; sleep 0.5; done
    fail "$what not ready after ${limit}s; logs: $D/*.log
$(tail -n 5 "$D"/*.log 2>/dev/null)"
}

step "munge key and munged (socket $D/munge/munge.socket)"
dd if=/dev/urandom of="$D/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$D/munge/munge.key"
munged --foreground --force --socket="$D/munge/munge.socket" --key-file="$D/munge/munge.key" \
    --pid-file="$D/munge/munged.pid" --log-file="$D/munged.log" --seed-file="$D/munge/munged.seed" \
    >"$D/munged.out" 2>&1 &
PIDS+=($!)
wait_for 20 munged test -S "$D/munge/munge.socket"

HOST="$(hostname -s)"
MEM_MB=$(($(awk '/^MemTotal:/ {print $2}' /proc/meminfo) / 1024))
export SLURM_CONF="$D/slurm.conf"
cat >"$SLURM_CONF" <<EOF
# one node, no accounting (no slurmdbd): sacct fails, as on many small clusters
ClusterName=implytest
SlurmctldHost=$HOST
SlurmctldPort=$(free_port)
SlurmdPort=$(free_port)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$D/munge/munge.socket
CredType=cred/munge
StateSaveLocation=$D/state
SlurmdSpoolDir=$D/spool
SlurmctldPidFile=$D/slurmctld.pid
SlurmdPidFile=$D/slurmd.pid
SlurmctldLogFile=$D/slurmctld.log
SlurmdLogFile=$D/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
MpiDefault=none
ReturnToService=2
SlurmdParameters=config_overrides
MinJobAge=300
NodeName=$HOST CPUs=2 RealMemory=$MEM_MB State=UNKNOWN
PartitionName=test Nodes=$HOST Default=YES MaxTime=INFINITE State=UP
EOF

step "slurmctld and slurmd ($HOST, 2 CPUs, $MEM_MB MB, no accounting)"
slurmctld -D -i -f "$SLURM_CONF" >"$D/slurmctld.out" 2>&1 &
PIDS+=($!)
wait_for 60 slurmctld scontrol ping
steps_before="$(pgrep -d ' ' -x slurmstepd || true)"
slurmd -D -N "$HOST" -f "$SLURM_CONF" >"$D/slurmd.out" 2>&1 &
PIDS+=($!)
node_idle() { sinfo -h -n "$HOST" -o %T | grep -qx idle; }
wait_for 90 "node $HOST (idle in sinfo)" node_idle
if sacct >/dev/null 2>&1; then
    step "note: sacct works here; the test is meant for a cluster without accounting"
else
    step "sacct fails as intended (no accounting): $(sacct 2>&1 | head -n 1)"
fi

# -- the workflow, through the profile -------------------------------------------------
WF="$WORK/wf"
rm -rf "$WF" && mkdir -p "$WF/tests"
cp -r "$REPO/Snakefile" "$REPO/config.yaml" "$REPO/workflow" "$REPO/envs" "$WF/"
cp -r "$REPO/tests/config" "$WF/tests/config"
# the shipped profile, with the tiny configs instead of the paper-size ones, requests this
# node can meet, status checks every 2 s (the first after 2 s instead of 40), and the job logs kept
"$PY" - "$REPO/profiles/slurm/config.yaml" "$WORK/profile/config.yaml" <<'EOF'
import sys
from pathlib import Path

import yaml

profile = yaml.safe_load(Path(sys.argv[1]).read_text())
assert profile["executor"] == "slurm", profile
profile.update(
    {
        "configfile": [
            "config.yaml",
            "tests/config/core_small.yaml",
            "tests/config/section4_small.yaml",
            "tests/config/slurm_grid.yaml",
        ],
        "default-resources": {**profile.get("default-resources", {}), "mem_mb": 1000, "runtime": 10},
        "jobs": 2,
        "retries": 0,
        "latency-wait": 5,
        "slurm-init-seconds-before-status-checks": 2,
        "seconds-between-status-checks": 2,
        "slurm-keep-successful-logs": True,
    }
)
Path(sys.argv[2]).parent.mkdir(parents=True, exist_ok=True)
Path(sys.argv[2]).write_text(yaml.safe_dump(profile))
EOF
grep -q '^slurm-status-command: squeue' "$WORK/profile/config.yaml" \
    || fail "profiles/slurm/config.yaml does not set slurm-status-command: squeue"

# The executor's job step drops every SLURM_* variable but the job's identity before it
# calls srun, SLURM_CONF among them; on a real cluster srun then reads /etc/slurm/slurm.conf.
# This machine's /etc is left alone: an srun first on the jobs' PATH restores SLURM_CONF.
mkdir -p "$D/bin"
printf '#!/bin/sh\nexport SLURM_CONF=%q\nexec %q "$@"\n' "$SLURM_CONF" "$(command -v srun)" >"$D/bin/srun"
chmod +x "$D/bin/srun"
export PATH="$D/bin:$PATH"

cd "$WF"
step "run 1: snakemake --profile (derived from profiles/slurm) $TARGET (limit ${RUN_LIMIT}s)"
rc=0
timeout -s INT -k 30 "$RUN_LIMIT" "$PY" -m snakemake --profile "$WORK/profile" "$TARGET" >"$WORK/run1.log" 2>&1 || rc=$?
if [ "$rc" -ne 0 ]; then
    tail -n 15 "$WORK/run1.log"
    echo "--- squeue:"; squeue --states=all -o '%i %j %T %r' || true
    # 124: stopped with SIGINT at the limit (Snakemake cancels its jobs), 137: killed 30 s later
    if [ "$rc" -eq 124 ] || [ "$rc" -eq 137 ]; then
        fail "snakemake did not finish in ${RUN_LIMIT}s (a job pending, or its state never read: see squeue above)"
    fi
    fail "snakemake exited $rc (log: $WORK/run1.log)"
fi
mapfile -t JOBIDS < <(grep -o 'submitted with SLURM jobid [0-9]*' "$WORK/run1.log" | awk '{print $NF}')
[ "${#JOBIDS[@]}" -eq "$N_JOBS" ] \
    || fail "expected $N_JOBS jobs submitted through sbatch, found ${#JOBIDS[@]} (log: $WORK/run1.log)"
for id in "${JOBIDS[@]}"; do
    grep -Eq "_job_complete: JobId=$id WEXITSTATUS 0" "$D/slurmctld.log" \
        || fail "SLURM job $id did not complete with status 0 in slurmctld's log ($D/slurmctld.log)"
done
[ -s "$WF/$TARGET" ] || fail "$TARGET was not written"
step "run 1: ${#JOBIDS[@]} jobs through sbatch, all completed (SLURM job ids ${JOBIDS[*]})"
grep -h "^\(Job\|Finished\|Nothing\|Complete\|[0-9]* of\)" "$WORK/run1.log" | tail -n 4 || true

step "run 2: the same command again"
timeout -s INT -k 30 180 "$PY" -m snakemake --profile "$WORK/profile" "$TARGET" >"$WORK/run2.log" 2>&1 \
    || { tail -n 20 "$WORK/run2.log"; fail "the rerun failed (log: $WORK/run2.log)"; }
grep -q "Nothing to be done" "$WORK/run2.log" || { tail -n 20 "$WORK/run2.log"; fail "the rerun was not a no-op"; }
if grep -q "submitted with SLURM jobid" "$WORK/run2.log"; then fail "the rerun submitted jobs"; fi
step "run 2: $(grep -m1 'Nothing to be done' "$WORK/run2.log")"
echo "PASS: $N_JOBS jobs through sbatch on a one-node SLURM without accounting; the rerun is a no-op"
