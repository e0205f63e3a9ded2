#!/usr/bin/env python3
"""Embree's work per ray beside ours, on the traversal bench's rays: nodes read, leaves
entered and triangle blocks tested per ray, for every scene and ray kind.

Embree keeps no counts in a release build. A build of Embree 3.13 with its statistics
counters (CMake option EMBREE_STAT_COUNTERS=ON; the same ISA and geometry options otherwise)
prints totals for the whole process when it exits. This script runs the traversal bench once
per row with `STEREOTRACE_BENCH_EMBREE_COUNTS=scene/kind/shape` (the bench traces that one ray
set once, prints our counts for the same rays and exits) and with that library first on the
loader's path, then divides Embree's totals by the rays traced.

    python3 tools/bench/embree_counts.py --embree-lib DIR [--robust] [--scenes cornell,atrium] [--times]

With `--times`, the rows are also timed: the medians of the bench's own last run of `single`
and `embree_single` (criterion's `target/criterion/traversal_{scene}_{kind}/`, or
`--criterion DIR`; run the bench on the same scenes first, with Embree in the same mode) are
divided by the rays, and each row's gap is split into nodes read per ray (ours ÷ Embree's)
and time per node read (ours ÷ Embree's), whose product is the time ratio.

DIR holds that build's libembree3.so.3. Without `--embree-lib` the bench links Debian's
release library, which prints no counters, and the script stops with a message.
"""
import argparse
import json
import os
import re
import subprocess
import sys

SCENES = ["cornell", "atrium", "living-room", "classroom", "courtyard", "sponza", "procedural700k"]
# Single rays only: Embree 3.13's packet paths count unevenly (its coherent packet traversal
# has its node counters commented out, and its shadow packets count nodes as normal rays), so
# its packet totals would not be comparable. The bench still accepts `packet_8x1`.
ROWS = [(kind, "single") for kind in ("primary", "shadow", "diffuse")]


def embree_totals(text, section):
    """Embree's printed totals of one section ("normal" or "shadow") of the ABSOLUTE block."""
    block = text.split("--------- ABSOLUTE ---------", 1)
    if len(block) < 2:
        return None
    lines = block[1].splitlines()
    start = next((i for i, l in enumerate(lines) if l.strip().startswith(f"#{section}_travs")), None)
    if start is None:
        return None
    totals = {}
    for line in lines[start + 1:]:
        m = re.match(r"\s+#(nodes|leaves|prims|prim_hits)\s*=\s*([-\d.e+]+)M", line)
        if m:
            totals[m.group(1)] = float(m.group(2)) * 1e6
        elif re.match(r"\s*#\w+_travs", line):
            break
    return totals


def run_row(args, scene, kind, shape):
    env = dict(os.environ, STEREOTRACE_BENCH_EMBREE_COUNTS=f"{scene}/{kind}/{shape}")
    env["LD_LIBRARY_PATH"] = args.embree_lib + os.pathsep + env.get("LD_LIBRARY_PATH", "")
    if args.robust:
        env["EMBREE_ROBUST"] = "1"
    if args.bench_bin:
        cmd = [args.bench_bin, "--bench", "embree_counts"]
    else:
        cmd = ["cargo", "bench", "-q", "-p", "stereotrace-kernels", "--bench", "traverse", "--features",
               "peer-embree", "--", "embree_counts"]
    out = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if out.returncode != 0:
        sys.exit(f"{scene}/{kind}/{shape}: the bench failed:\n{out.stderr[-2000:]}")
    ours = re.search(r"EMBREE_COUNTS calls=(\d+) rays=\d+ hits=\d+ ours_nodes=(\d+) ours_leaves=(\d+) "
                     r"ours_triangles=(\d+) ours_blocks=(\d+)", out.stdout)
    if ours is None:
        sys.exit(f"{scene}/{kind}/{shape}: no EMBREE_COUNTS line in the bench's output:\n{out.stdout[-2000:]}")
    calls, *ours = (int(g) for g in ours.groups())
    embree = embree_totals(out.stdout, "shadow" if kind == "shadow" else "normal")
    if embree is None:
        sys.exit(f"{scene}/{kind}/{shape}: Embree printed no counters: is {args.embree_lib} a build "
                 "with EMBREE_STAT_COUNTERS=ON?")
    return calls, ours, embree


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--embree-lib", required=True, help="folder of an Embree 3.13 built with EMBREE_STAT_COUNTERS=ON")
    ap.add_argument("--robust", action="store_true", help="Embree in robust mode (RTC_SCENE_FLAG_ROBUST)")
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--bench-bin", help="a built traversal bench binary to run instead of `cargo bench` "
                    "(an earlier build, to count what it did)")
    ap.add_argument("--criterion", default=os.path.join("target", "criterion"),
                    help="criterion's output folder of the timed run (for --times)")
    ap.add_argument("--times", action="store_true", help="split each row's time ratio into nodes per ray "
                    "and time per node")
    args = ap.parse_args()
    singles = []
    mode = "robust" if args.robust else "default"
    print(f"Embree mode: {mode}. Per ray; ours ÷ Embree in the last column.")
    print()
    print("| scene | rays | Embree: nodes | leaves | triangle blocks (≤ 4) | ours: nodes | leaves | triangles "
          "| triangle blocks (≤ 8) | nodes ours ÷ Embree |")
    print("|---|---|--:|--:|--:|--:|--:|--:|--:|--:|")
    for scene in args.scenes.split(","):
        for kind, shape in ROWS:
            calls, ours, embree = run_row(args, scene, kind, shape)
            ours = [v / calls for v in ours]
            embree = {k: v / calls for k, v in embree.items()}
            singles.append((scene, kind, calls, ours[0], embree["nodes"]))
            print(f"| {scene} | {kind} | {embree['nodes']:.2f} | {embree['leaves']:.2f} | {embree['prims']:.2f} | "
                  + " | ".join(f"{v:.2f}" for v in ours) + f" | {ours[0] / embree['nodes']:.2f} |", flush=True)
    if args.times:
        split_times(singles, args.criterion)


def median_ns(criterion, scene, kind, row):
    """Criterion's median time of one iteration (one pass over the ray set) of the last run."""
    path = os.path.join(criterion, f"traversal_{scene}_{kind}", row, "new", "estimates.json")
    try:
        with open(path) as f:
            return json.load(f)["median"]["point_estimate"]
    except OSError:
        sys.exit(f"--times: {path} not found: run the traversal bench on {scene} first")


def split_times(singles, criterion):
    """Splits each row's speed gap into the work per ray (nodes read, ours ÷ Embree's) and the
    time per node read with everything it brings (its leaves' triangle blocks, the stack, the
    ray's setup shared out). A least-squares split into a cost per node and per block does not
    hold across ray kinds: the same counts cost twice as much for incoherent diffuse rays as for
    coherent primary rays (cache misses), so the ratio of two tracers on the same rays is the
    measure that holds the rays fixed."""
    print()
    print("| scene | rays | ours ns per ray | Embree ns per ray | speed, ours ÷ Embree | nodes, ours ÷ Embree "
          "| time per node read, ours ÷ Embree |")
    print("|---|---|--:|--:|--:|--:|--:|")
    for scene, kind, calls, ours_nodes, embree_nodes in singles:
        t_ours = median_ns(criterion, scene, kind, "single") / calls
        t_embree = median_ns(criterion, scene, kind, "embree_single") / calls
        nodes = ours_nodes / embree_nodes
        print(f"| {scene} | {kind} | {t_ours:.1f} | {t_embree:.1f} | {t_embree / t_ours:.2f} | {nodes:.2f} | "
              f"{t_ours / t_embree / nodes:.2f} |")


if __name__ == "__main__":
    main()
