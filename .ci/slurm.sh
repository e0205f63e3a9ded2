#!/usr/bin/env bash
# A single-node Slurm cluster on this machine (munged, slurmctld, slurmd from Debian's
# slurm-wlm and munge), the quick preset submitted to it as an array with
# deploy/slurm/submit.sh, and the merged reports compared byte for byte with a
# single-process run of the same preset. Stops the daemons it started (by their PIDs).
#
#   .ci/slurm.sh SINGLE_OUT [TASKS]   SINGLE_OUT: the single-process run's output folder
#
# Needs root (it installs packages and starts daemons). Works in target/slurm-ci.
set -euo pipefail
cd "$(dirname "$0")/.."
single=${1:?usage: .ci/slurm.sh SINGLE_OUT [TASKS]}
tasks=${2:-4}
start=$(date +%s)
if ! command -v slurmctld > /dev/null || ! command -v munged > /dev/null; then
    apt-get update -qq > /dev/null
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq slurm-wlm munge > /dev/null
fi
work=$PWD/target/slurm-ci
rm -rf "$work"
mkdir -p "$work"/{etc,spool/ctld,spool/d,log,run}
pids=()
stop() {
    for p in "${pids[@]}"; do kill "$p" 2> /dev/null || true; done
    for p in "${pids[@]}"; do
        for _ in $(seq 50); do kill -0 "$p" 2> /dev/null || break; sleep 0.1; done
    done
}
trap stop EXIT

# munge: a fresh key, its own socket, and the PID it reports.
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
ClusterName=stereotrace-ci
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
SlurmctldPort=6817
SlurmdPort=6818
NodeName=$node CPUs=$(nproc) State=UNKNOWN
PartitionName=ci Nodes=$node Default=YES MaxTime=INFINITE State=UP OverSubscribe=NO
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
echo "slurm up in $(( $(date +%s) - start )) s"

# The quick preset as an array of $tasks shards of one CPU each (the node has $(nproc)), then
# the dependent merge; --wait returns when the merge has finished.
cargo build --release --quiet
STEREOTRACE=$PWD/target/release/stereotrace CACHE=$work/cache OUT=$work/out LOGS=$work/log \
    CPUS_PER_TASK=1 WAIT=1 bash deploy/slurm/submit.sh "$tasks" --preset quick
cat "$work"/log/stereotrace-eval-merge-*.out | tail -5
status=0
for f in $(cd "$single" && ls *.md *.csv results.json warnings.txt 2> /dev/null); do
    if ! cmp -s "$single/$f" "$work/out/$f"; then
        echo "DIFFERS from the single-process run: $f"
        status=1
    fi
done
n=$(cd "$single" && ls *.md *.csv | wc -l)
[ "$status" = 0 ] && echo "all $n tables and results.json equal the single-process run byte for byte"
echo "slurm step wall time: $(( $(date +%s) - start )) s"
exit $status
