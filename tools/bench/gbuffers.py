#!/usr/bin/env python3
"""Both eyes' G-buffers at 1280x720 on 2 threads, per scene, for each rasteriser (`exact`,
`fixed`) and the traced pass, in one run: the rasterisers' step times (setup, binning,
fragments, resolve) as `examples/gbuffer_passes.rs` measures them (medians of 9 passes, the
compact layout's planes, as the pipeline writes them), and the traced pass (median of 3).
Prints a Markdown table; the passes of a scene run one after the other.

    cargo build --release --example gbuffer_passes && python3 tools/bench/gbuffers.py \
        [--scenes cornell,atrium,...] [--traced]
"""
import argparse
import os
import re
import subprocess
import sys

BIN = "target/release/examples/gbuffer_passes"
LINE = re.compile(
    r"raster \+ resolve ([\d.]+) ms \(setup ([\d.]+), binning ([\d.]+), fragments ([\d.]+), resolve ([\d.]+)\); "
    r"traced ([\d.a-zA-Z]+) ms")


def run(scene, visibility, traced):
    env = dict(os.environ, COMPACT="1", VISIBILITY=visibility, TRACED_RUNS="3" if traced else "0")
    out = subprocess.run([BIN, scene], capture_output=True, text=True, env=env)
    if out.returncode != 0:
        sys.exit(f"{BIN} {scene} ({visibility}) failed:\n{out.stderr}")
    m = LINE.search(out.stdout)
    if not m:
        sys.exit(f"unexpected output: {out.stdout}")
    return [float(v) if v != "NaN" else None for v in m.groups()]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenes", default="cornell,atrium,living-room,classroom,courtyard")
    ap.add_argument("--traced", action="store_true", help="also time the traced pass")
    args = ap.parse_args()
    print("| scene | rasteriser | total ms | setup | binning | fragments | resolve | traced ms |")
    print("|---|---|--:|--:|--:|--:|--:|--:|")
    for scene in args.scenes.split(","):
        for visibility in ["exact", "fixed"]:
            total, setup, binning, fragments, resolve, traced = run(scene, visibility,
                                                                     args.traced and visibility == "fixed")
            t = f"{traced:.1f}" if traced else "-"
            print(f"| {scene} | {visibility} | {total:.1f} | {setup:.1f} | {binning:.1f} | {fragments:.1f} | "
                  f"{resolve:.1f} | {t} |", flush=True)


if __name__ == "__main__":
    main()
