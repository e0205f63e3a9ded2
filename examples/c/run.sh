#!/usr/bin/env bash
# Builds the C ABI, compiles the C examples against the committed header and the static
# library under AddressSanitizer and UndefinedBehaviorSanitizer (C side), and runs them.
# Each example checks its own results and exits non-zero on any failed check.
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release -p stereotrace-capi
mkdir -p target/c
for example in kernels pipeline frame_time; do
    cc -std=c11 -Wall -Wextra -Werror -O1 -g -fsanitize=address,undefined -fno-omit-frame-pointer \
        -Icapi/include -Iexamples/c "examples/c/$example.c" target/release/libstereotrace_capi.a \
        -lpthread -ldl -lm -o "target/c/$example"
    echo "== examples/c/$example.c"
    ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=halt_on_error=1 "target/c/$example" \
        $([ "$example" = frame_time ] && echo "cornell 1 2")
done
