#!/usr/bin/env bash
# A whole stereo frame through the C ABI against the same frame through Rust, in one run:
# for each scene, ROUNDS alternating runs of examples/c/frame_time.c (the C program, timing
# stereotrace_pipeline_render_frame) and `stereotrace throughput` (the Rust driver, same
# configuration: spatiotemporal, 1 spp, rasterised compact G-buffers, no budget, 1280x720,
# 2 threads, the camera walking the scene's path). Prints each run's median frame ms.
#   usage: tools/bench/c_abi_frames.sh [FRAMES] [ROUNDS] SCENE...
set -euo pipefail
cd "$(dirname "$0")/../.."
frames=${1:-10}
rounds=${2:-3}
shift 2 || true
scenes=("${@:-cornell atrium}")
cargo build --release -p stereotrace-capi -p stereotrace
mkdir -p target/c
cc -std=c11 -O2 -Icapi/include examples/c/frame_time.c target/release/libstereotrace_capi.a \
    -lpthread -ldl -lm -o target/c/frame_time
for scene in ${scenes[@]}; do
    for round in $(seq "$rounds"); do
        target/c/frame_time "$scene" "$frames" 2
        ./target/release/stereotrace throughput --scene "$scene" --res 1280x720 --threads 2 \
            --frames "$frames" --spp 1 --mode spatiotemporal --no-baseline --json |
            python3 -c "import json,sys; d=json.load(sys.stdin); print('$scene: $frames frames through Rust, median %.2f ms' % d['frame']['median_ms'])"
    done
done
