#!/usr/bin/env python3
"""Prints the RELIABILITY.md fuzzing table from the logs fuzz/fuzz.sh appends to
fuzz/target/fuzz-logs/<target>.log: per target, the runs (with their sanitizer and length),
the executions summed over the runs that printed their final statistics (a run stopped by a
crash prints them too; one killed from outside does not), the coverage (libFuzzer's `cov:` edges and
`ft:` features) at the end of the last run, and the crashes.

    python3 fuzz/stats.py
"""
import glob
import os
import re

LOGS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "target", "fuzz-logs")


def main():
    print("| target | runs (sanitizer × seconds) | executions | coverage (edges / features) | crashes |")
    print("|---|---|--:|---|--:|")
    for path in sorted(glob.glob(os.path.join(LOGS, "*.log"))):
        target = os.path.basename(path)[:-4]
        runs, executions, cov, crashes = [], 0, "", 0
        for line in open(path, errors="replace"):
            m = re.match(r"# \S+ sanitizer=(\w+) seconds=(\d+)", line)
            if m:
                runs.append(f"{m.group(1)} × {m.group(2)}")
            m = re.match(r"stat::number_of_executed_units:\s+(\d+)", line)
            if m:
                executions += int(m.group(1))
            m = re.search(r"cov: (\d+) ft: (\d+)", line)
            if m:
                cov = f"{m.group(1)} / {m.group(2)}"
            if "Test unit written to" in line and "slow-unit-" not in line:
                crashes += 1
        summary = ", ".join(f"{n} {r}" if n > 1 else r for r, n in count(runs))
        print(f"| `{target}` | {summary} | {executions:,} | {cov} | {crashes} |")


def count(items):
    out = []
    for i in items:
        if out and out[-1][0] == i:
            out[-1] = (i, out[-1][1] + 1)
        else:
            out.append((i, 1))
    return out


if __name__ == "__main__":
    main()
