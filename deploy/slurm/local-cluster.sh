#!/usr/bin/env bash
# A single-node Slurm cluster on this machine for the length of one command: installs
# Debian's slurm-wlm and munge when missing, starts munged (unless one runs), slurmctld and
# slurmd with a minimal slurm.conf (this node's name and CPU count), runs COMMAND with
# SLURM_CONF set, then cancels its jobs and stops the daemons it started, by their PIDs.
#
#   deploy/slurm/local-cluster.sh WORK COMMAND [ARGS...]
#
# WORK holds the cluster's config, spool and logs (emptied first). Needs root. SLURM_PORT
# (default 6817) is slurmctld's port and slurmd takes the next one, so a second cluster with
# its own WORK and port can run beside the first (CI's beside a long local run). Used by CI
# (.ci/slurm.sh) and for the paper-lite run (RESULTS.md), e.g.
#
#   deploy/slurm/local-cluster.sh /tmp/slurm env CACHE=... OUT=... WAIT=1 \
#       deploy/slurm/submit.sh 2 --preset paper-lite
set -euo pipefail
work=${1:?usage: local-cluster.sh WORK COMMAND [ARGS...]}
shift
[ $# -gt 0 ] || { echo "usage: local-cluster.sh WORK COMMAND [ARGS...]" >&2; exit 2; }
start=$(date +%s)
port=${SLURM_PORT:-6817}
[[ $port =~ ^[0-9]+$ ]] && [ "$port" -ge 1024 ] && [ "$port" -le 65534 ] || { echo "SLURM_PORT=$port: not a port in 1024..65534" >&2; exit 2; }
if ! command -v slurmctld > /dev/null || ! command -v munged > /dev/null; then
    apt-get update -qq > /dev/null
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq slurm-wlm munge > /dev/null
fi
rm -rf "$work"
mkdir -p "$work"/{etc,spool/ctld,spool/d,log,run}
work=$(cd "$work" && pwd)
pids=()
stop() {
    # Jobs first (a job step outlives slurmd otherwise), then the daemons.
    if [ -n "${SLURM_CONF:-}" ] && command -v scancel > /dev/null; then
        scancel --full "--user=$(id -un)" 2> /dev/null || true
        for _ in $(seq 100); do [ -z "$(squeue -h 2> /dev/null)" ] && break; sleep 0.2; done
    fi
    for p in "${pids[@]}"; do kill "$p" 2> /dev/null || true; done
    for p in "${pids[@]}"; do
        for _ in $(seq 50); do kill -0 "$p" 2> /dev/null || break; sleep 0.1; done
    done
}
trap stop EXIT
trap 'exit 130' INT TERM  # until the command starts (below)

# munge: a key of its own, and the PID it reports.
mkdir -p /etc/munge /var/lib/munge /var/log/munge /run/munge
chmod 0700 /etc/munge && chmod 0711 /var/lib/munge && chmod 0755 /run/munge
[ -f /etc/munge/munge.key ] || mungekey --create --keyfile=/etc/munge/munge.key
chmod 0400 /etc/munge/munge.key
if ! munge -n > /dev/null 2>&1; then
    munged --force
    for _ in $(seq 50); do [ -s /run/munge/munged.pid ] && break; sleep 0.1; done
    pids+=("$(cat /run/munge/munged.pid)")
fi
munge -n | unmunge > /dev/null

node=$(hostname -s)
cat > "$work/etc/slurm.conf" << CONF
ClusterName=stereotrace-local
SlurmctldHost=$node
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
MpiDefault=none
ReturnToService=2
StateSaveLocation=$work/spool/ctld
SlurmdSpoolDir=$work/spool/d
SlurmctldPidFile=$work/run/slurmctld.pid
SlurmdPidFile=$work/run/slurmd.pid
SlurmctldLogFile=$work/log/slurmctld.log
SlurmdLogFile=$work/log/slurmd.log
SlurmctldPort=$port
SlurmdPort=$((port + 1))
NodeName=$node CPUs=$(nproc) State=UNKNOWN
PartitionName=local Nodes=$node Default=YES MaxTime=INFINITE State=UP OverSubscribe=NO
CONF
export SLURM_CONF=$work/etc/slurm.conf
slurmctld -f "$SLURM_CONF"
sleep 0.5
pids+=("$(cat "$work/run/slurmctld.pid")")
slurmd -f "$SLURM_CONF"
for _ in $(seq 100); do [ -s "$work/run/slurmd.pid" ] && break; sleep 0.1; done
pids+=("$(cat "$work/run/slurmd.pid")")
for _ in $(seq 100); do sinfo -h -o %T 2> /dev/null | grep -qE '^idle' && break; sleep 0.2; done
sinfo
echo "slurm up in $(($(date +%s) - start)) s"
# In the background, so that a signal to this script ends it (and its cluster) at once
# instead of after the command: bash runs traps only between foreground commands.
"$@" &
child=$!
trap 'kill -TERM "$child" 2> /dev/null; exit 130' INT TERM
status=0
wait "$child" || status=$?
exit $status
