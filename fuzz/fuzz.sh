#!/usr/bin/env bash
# Fuzzes the targets of this folder on the production instruction level (x86-64-v3, as
# .cargo/config.toml builds the project; cargo-fuzz replaces that file's flags with its own
# RUSTFLAGS, so they are set here), with the kernels' `check-scalar` feature on.
#
#   fuzz/fuzz.sh SECONDS [TARGET...]          every target (or those named), SECONDS each
#   fuzz/fuzz.sh --asan SECONDS [TARGET...]   the same under AddressSanitizer
#
# New inputs go to target/fuzz-new/<target> (the committed corpus in corpus/<target> is
# read, not written: merge finds into it with `cargo fuzz cmin`). A crash fails the script
# and leaves its input in artifacts/<target>. Each run appends its final statistics
# (executions, coverage) to target/fuzz-logs/<target>.log.
set -euo pipefail
cd "$(dirname "$0")"
sanitizer=none
target_dir=target
if [ "${1:-}" = "--asan" ]; then
    sanitizer=address
    export RUSTC_BOOTSTRAP=1   # -Zsanitizer on the stable toolchain
    target_dir=target/asan     # its own build, so it can run beside an unsanitized one
    shift
fi
seconds=${1:?usage: fuzz.sh [--asan] SECONDS [TARGET...]}
shift
command -v cargo-fuzz > /dev/null || cargo install cargo-fuzz --locked
targets=("$@")
[ ${#targets[@]} -gt 0 ] || mapfile -t targets < <(cargo fuzz list)
export RUSTFLAGS="-C target-cpu=x86-64-v3"
# One core per fuzzer: every target makes its fuzzing thread rayon's whole global pool
# (`fuzzing::run_on_this_thread`), so the kernels' bands run inline with no cross-thread
# wake-up per input. The results do not depend on the thread count (the kernels' tests check
# that). Pools a target builds itself get one thread.
export RAYON_NUM_THREADS="${RAYON_NUM_THREADS:-1}"
mkdir -p target/fuzz-logs
for t in "${targets[@]}"; do
    mkdir -p "target/fuzz-new/$t" "corpus/$t"
    dict=()
    [ -f "dicts/$t.dict" ] && dict=("-dict=dicts/$t.dict")
    echo "== $t: ${seconds}s, sanitizer $sanitizer"
    log="target/fuzz-logs/$t.log"
    echo "# $(date -u +%FT%TZ) sanitizer=$sanitizer seconds=$seconds" >> "$log"
    if ! cargo fuzz run --sanitizer "$sanitizer" --target-dir "$target_dir" -O "$t" "target/fuzz-new/$t" "corpus/$t" -- \
        -max_total_time="$seconds" -max_len=4096 -print_final_stats=1 "${dict[@]}" >> "$log" 2>&1; then
        tail -40 "$log"
        echo "fuzz target $t failed: see $log and artifacts/$t"
        exit 1
    fi
    grep -E "^stat::number_of_executed_units|^stat::new_units_added" "$log" | tail -2
done
