#!/usr/bin/env bash
# The C ABI's C tests, each built and run twice:
# - under AddressSanitizer + UndefinedBehaviorSanitizer (C side), against the release library;
# - under ThreadSanitizer, against the library built with ThreadSanitizer too (the standard
#   library included, from source, so that TSan sees every synchronisation the library makes:
#   an uninstrumented library's locks are invisible to it and show up as false races). That
#   build needs `-Zsanitizer` and `-Zbuild-std` (RUSTC_BOOTSTRAP=1 on the stable toolchain),
#   the rust-src component, and Rust's own TSan runtime (the C side's gcc 12 runtime lacks
#   the entry points rustc's LLVM emits).
# Each test exits non-zero on any failed check; a sanitizer report fails the run too.
set -euo pipefail
cd "$(dirname "$0")/../../.."
target=x86_64-unknown-linux-gnu
tests=(reentrancy)

cargo build --release -p stereotrace-capi
mkdir -p target/c
for test in "${tests[@]}"; do
    cc -std=c11 -Wall -Wextra -Werror -O1 -g -fsanitize=address,undefined -fno-omit-frame-pointer -pthread \
        -Icapi/include -Iexamples/c "capi/tests/c/$test.c" target/release/libstereotrace_capi.a \
        -ldl -lm -o "target/c/$test-asan"
    echo "== capi/tests/c/$test.c under AddressSanitizer + UndefinedBehaviorSanitizer"
    ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=halt_on_error=1 "target/c/$test-asan"
done

if ! rustup component list --installed 2>/dev/null | grep -q '^rust-src'; then
    rustup component add rust-src || true
fi
if ! rustup component list --installed 2>/dev/null | grep -q '^rust-src'; then
    echo "!! ThreadSanitizer runs SKIPPED: the rust-src component could not be installed (needed to build"
    echo "!! the standard library with TSan). Install it with 'rustup component add rust-src'."
    exit 0
fi
RUSTC_BOOTSTRAP=1 RUSTFLAGS="-Zsanitizer=thread -C target-cpu=x86-64-v3" CARGO_TARGET_DIR=target/tsan \
    cargo build -Zbuild-std --release -p stereotrace-capi --target "$target"
runtime="$(rustc --print sysroot)/lib/rustlib/$target/lib/librustc-stable_rt.tsan.a"
for test in "${tests[@]}"; do
    cc -std=c11 -Wall -Wextra -Werror -O1 -g -fsanitize=thread -fno-omit-frame-pointer -pthread \
        -Icapi/include -Iexamples/c -c "capi/tests/c/$test.c" -o "target/c/$test-tsan.o"
    cc -pthread "target/c/$test-tsan.o" "target/tsan/$target/release/libstereotrace_capi.a" \
        -Wl,--whole-archive "$runtime" -Wl,--no-whole-archive -ldl -lm -lrt -o "target/c/$test-tsan"
    echo "== capi/tests/c/$test.c under ThreadSanitizer (library and standard library instrumented)"
    TSAN_OPTIONS=halt_on_error=1:exitcode=66 "target/c/$test-tsan"
done
