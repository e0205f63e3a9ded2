#!/usr/bin/env bash
# Submits a stereotrace evaluation to Slurm: an array of TASKS shards, then the merge as a
# job that starts only when every shard succeeded (--dependency=afterok).
#
#   CACHE=/shared/st-cache OUT=/shared/st-out deploy/slurm/submit.sh TASKS [EVAL OPTIONS...]
#
# e.g. `deploy/slurm/submit.sh 64 --preset paper`. Size TASKS with
# `stereotrace eval --preset paper --plan` (README: "The evaluation on a cluster").
# Environment: CACHE, OUT (required); STEREOTRACE (the binary, default `stereotrace` on the
# PATH); CPUS_PER_TASK (default 2); PARTITION; LOGS (folder for the jobs' output, default .);
# WAIT=1 to return only when the merge has finished (its exit status is this script's).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
tasks=${1:?usage: submit.sh TASKS [EVAL OPTIONS...]}
shift
: "${CACHE:?set CACHE to a folder every node sees}" "${OUT:?set OUT to the output folder}"
[[ "$tasks" =~ ^[1-9][0-9]*$ ]] || { echo "TASKS must be a positive whole number, got '$tasks'" >&2; exit 2; }
logs=${LOGS:-.}
mkdir -p "$CACHE" "$OUT" "$logs"
# The jobs inherit these (--export=ALL); options may hold commas, which --export=NAME=VALUE cannot.
export CACHE OUT STEREOTRACE=${STEREOTRACE:-stereotrace} EVAL_ARGS="$*"
common=(--cpus-per-task="${CPUS_PER_TASK:-2}" --export=ALL)
[ -n "${PARTITION:-}" ] && common+=(--partition="$PARTITION")
array=$(sbatch --parsable "${common[@]}" --array="0-$((tasks - 1))" \
    --output="$logs/stereotrace-eval-%A_%a.out" "$here/eval-array.sbatch")
echo "array job $array: $tasks shards"
wait_flag=()
[ "${WAIT:-0}" = 1 ] && wait_flag=(--wait)
merge_cpus=(--cpus-per-task=1)
merge=$(sbatch --parsable "${common[@]}" "${merge_cpus[@]}" --dependency="afterok:$array" --kill-on-invalid-dep=yes \
    --output="$logs/stereotrace-eval-merge-%j.out" "${wait_flag[@]}" "$here/eval-merge.sbatch")
echo "merge job $merge (after every shard of $array succeeds): reports in $OUT"
