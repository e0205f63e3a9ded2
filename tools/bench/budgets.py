#!/usr/bin/env python3
"""The real-time table: `stereotrace throughput` at 1280x720 on 2 threads, spatiotemporal
mode at 1 spp, on every built-in scene, unbudgeted and with each budget. Prints a Markdown
table (median frame and stage times, fps, share traced per eye, frames over budget). With
`--mono-frames N`, then a second table from N frames per scene with the driver's baselines:
the stereo frame against a mono frame (the right eye alone path traced) and against full
stereo path tracing, measured in the same run. All three runs of that table are unbudgeted
(the driver forms time ratios only between runs without a budget).

    cargo build --release && python3 tools/bench/budgets.py [--budgets 33,50,100] [--frames 20] \
        [--mono-frames 6] [--background reproject]
"""
import argparse
import json
import subprocess
import sys

BIN = "target/release/stereotrace"


def run(scene, args, budget, frames=None):
    baselines = frames is not None
    cmd = [BIN, "throughput", "--scene", scene, "--res", args.res, "--threads", str(args.threads),
           "--frames", str(frames if baselines else args.frames), "--spp", "1", "--mode", "spatiotemporal",
           "--gbuffer", args.gbuffer, "--json"] + ([] if baselines else ["--no-baseline"]) \
        + (["--motion-vectors"] if args.motion_vectors else []) + ["--background", args.background]
    if budget is not None:
        cmd += ["--budget-ms", str(budget)]
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{out.stderr}")
    return json.loads(out.stdout)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--budgets", default="33,50,100")
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--res", default="1280x720")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--gbuffer", default="raster")
    ap.add_argument("--motion-vectors", action="store_true",
                    help="give the pipelines the surfaces' motion, as an engine's motion vectors")
    ap.add_argument("--background", default="trace", choices=["trace", "reproject"],
                    help="what reprojection does with sky pixels (the paper's: trace)")
    ap.add_argument("--scenes", default=None, help="comma-separated (default: every built-in)")
    ap.add_argument("--mono-frames", type=int, default=0, help="also the stereo-over-mono table")
    args = ap.parse_args()
    if args.scenes:
        scenes = args.scenes.split(",")
    else:
        listing = subprocess.run([BIN, "scenes"], capture_output=True, text=True, check=True).stdout
        table = listing.split("\n\n")[0].splitlines()[1:]
        scenes = [line.split()[0] for line in table if line.strip()]
    budgets = [None] + [float(b) for b in args.budgets.split(",")]
    print("| scene | budget ms | fps | frame ms (median / p95 / max) | g-buffers | reprojection | tracing "
          "| accumulation | left traced | right traced | over budget | over by > 1 ms |")
    print("|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for scene in scenes:
        for b in budgets:
            r = run(scene, args, b)
            f = r["frame"]
            over = f"{r['budget_misses']}/{r['frames_measured']}" if b else "-"
            over1 = f"{r['budget_misses_over_1ms']}/{r['frames_measured']}" if b else "-"
            print(f"| {r['scene']} | {b if b else 'none'} | {r['stereo_fps']:.1f} | {f['median_ms']:.1f} / "
                  f"{f['p95_ms']:.1f} / {f['max_ms']:.1f} | {r['gbuffer']['median_ms']:.1f} | "
                  f"{r['reprojection']['median_ms']:.1f} | {r['tracing']['median_ms']:.1f} | "
                  f"{r['accumulation']['median_ms']:.1f} | {100 * r['left_traced_share']:.1f} % | "
                  f"{100 * r['right_traced_share']:.1f} % | {over} | {over1} |", flush=True)
    if args.mono_frames:
        print()
        print("All three runs unbudgeted, 1 spp, same resolution and threads:")
        print()
        print("| scene | stereo frame ms | mono frame ms | stereo ÷ mono | full stereo ms | speed-up over full stereo |")
        print("|---|---:|---:|---:|---:|---:|")
        for scene in scenes:
            r = run(scene, args, None, args.mono_frames)
            print(f"| {r['scene']} | {r['frame']['median_ms']:.1f} | {r['mono_frame_ms']:.1f} | "
                  f"{r['stereo_over_mono']:.3f} | {r['full_stereo_frame_ms']:.1f} | "
                  f"{r['speedup_over_full_stereo']:.2f} |", flush=True)


if __name__ == "__main__":
    main()
