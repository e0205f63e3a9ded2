#!/usr/bin/env python3
"""Compares the effective spp of two evaluation runs (their effective_spp_long.csv), row by
row: prints a Markdown table of both averages and the relative difference, and exits 1 when
any row differs by more than --tolerance (relative; default 1 %).

    python3 tools/compare/effective_spp.py A/effective_spp_long.csv B/effective_spp_long.csv \
        --names traced raster
"""
import argparse
import csv
import sys


def load(path):
    with open(path, newline="") as f:
        return {(r["scene"], r["variant"], r["input_spp"], r["metric"]): r for r in csv.DictReader(f)}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("--names", nargs=2, default=["a", "b"])
    ap.add_argument("--tolerance", type=float, default=0.01)
    args = ap.parse_args()
    a, b = load(args.a), load(args.b)
    if a.keys() != b.keys():
        print(f"the runs differ in rows: {sorted(a.keys() ^ b.keys())[:5]} ...", file=sys.stderr)
        return 2
    na, nb = args.names
    print(f"| scene | variant | spp | metric | {na} | {nb} | difference |")
    print("|---|---|---:|---|---:|---:|---:|")
    worst, over, undefined = 0.0, 0, 0
    for key in sorted(a):
        ra, rb = a[key], b[key]
        if not ra["avg"] or not rb["avg"]:
            undefined += 1
            same = ra["avg"] == rb["avg"]
            print(f"| {' | '.join(key)} | {ra['avg'] or '-'} | {rb['avg'] or '-'} | {'same' if same else 'DIFFERS'} |")
            over += 0 if same else 1
            continue
        va, vb = float(ra["avg"]), float(rb["avg"])
        rel = abs(vb - va) / max(abs(va), 1e-12)
        worst = max(worst, rel)
        over += rel > args.tolerance
        print(f"| {' | '.join(key)} | {va:.4f} | {vb:.4f} | {100 * rel:.3f} % |")
    print(f"\n{len(a)} rows ({undefined} without an average); largest relative difference "
          f"{100 * worst:.3f} %; {over} rows beyond {100 * args.tolerance:g} %")
    return 1 if over else 0


if __name__ == "__main__":
    sys.exit(main())
