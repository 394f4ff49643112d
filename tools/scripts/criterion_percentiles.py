#!/usr/bin/env python3
"""Per-iteration time percentiles from criterion's raw samples.

Criterion stores, for every benchmark, the samples it took (iteration count
and total time of each) in target/criterion/<group>/<bench>/new/sample.json.
This prints p50/p99/max of the per-iteration time across those samples, so
BENCHMARKS.md can give percentiles next to criterion's own estimates.

Usage: python3 tools/scripts/criterion_percentiles.py [target/criterion]
"""
import json
import pathlib
import sys


def percentile(sorted_values, q):
    if not sorted_values:
        return float("nan")
    k = (len(sorted_values) - 1) * q
    lo, hi = int(k), min(int(k) + 1, len(sorted_values) - 1)
    return sorted_values[lo] + (sorted_values[hi] - sorted_values[lo]) * (k - lo)


def fmt(ns):
    return f"{ns / 1e3:.3f} µs" if ns >= 1e3 else f"{ns:.2f} ns"


def main():
    root = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "target/criterion")
    rows = []
    for sample in sorted(root.glob("*/*/new/sample.json")):
        data = json.loads(sample.read_text())
        per_iter = sorted(t / n for t, n in zip(data["times"], data["iters"]))
        bench = sample.parent.parent
        rows.append((f"{bench.parent.name}/{bench.name}", per_iter))
    if not rows:
        sys.exit(f"no criterion samples under {root}: run cargo bench first")
    print(f"| benchmark | samples | p50 | p99 | max |")
    print(f"|---|---|---|---|---|")
    for name, v in rows:
        print(f"| {name} | {len(v)} | {fmt(percentile(v, 0.5))} | {fmt(percentile(v, 0.99))} | {fmt(v[-1])} |")


if __name__ == "__main__":
    main()
