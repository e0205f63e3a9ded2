#!/usr/bin/env bash
# The quick preset submitted as an array with deploy/slurm/submit.sh to a single-node Slurm
# cluster on this machine (deploy/slurm/local-cluster.sh: munged, slurmctld, slurmd from
# Debian's slurm-wlm and munge, stopped by their PIDs afterwards), and the merged reports
# compared byte for byte with a single-process run of the same preset.
#
#   .ci/slurm.sh SINGLE_OUT [TASKS]   SINGLE_OUT: the single-process run's output folder
#
# Needs root (it installs packages and starts daemons). Works in target/slurm-ci.
set -euo pipefail
cd "$(dirname "$0")/.."
single=${1:?usage: .ci/slurm.sh SINGLE_OUT [TASKS]}
tasks=${2:-4}
start=$(date +%s)
work=$PWD/target/slurm-ci
cargo build --release --quiet
# The quick preset as an array of $tasks shards of one CPU each, then the dependent merge;
# WAIT=1: submit.sh returns when the merge has finished.
STEREOTRACE=$PWD/target/release/stereotrace CACHE=$work/cache OUT=$work/out LOGS=$work/log \
    CPUS_PER_TASK=1 WAIT=1 deploy/slurm/local-cluster.sh "$work" bash deploy/slurm/submit.sh "$tasks" --preset quick
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
