#!/usr/bin/env python3
"""`exo fit` throughput against the equivalent Python (tools/python/fit_frf.py:
mcap + mcap-ros2-support + numpy), side by side in one run.

1. Makes ten recordings, one per subject A-J of Table III (the default run
   file with that subject: experiments 1 and 7, three periods each), with the
   real processes (`exo run`), unless --recordings are given.
2. Alternates `exo fit --json` and `fit_frf.py` over all of them, --rounds
   times each, and prints samples per second (p50, min, max over rounds) and
   the ratio.

Usage (from the repository root, after `cargo build --release --workspace`):
    target/py-venv/bin/python tools/python/bench_fit.py [--rounds 7] [--recordings F ...]
"""
import argparse
import json
import os
import pathlib
import re
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[2]
EXO = ROOT / "target" / "release" / "exo"


def make_recordings(out_dir):
    base = (ROOT / "configs" / "default.toml").read_text()
    cfgs = ROOT / "configs"
    recs = []
    for s in "ABCDEFGHIJ":
        text = (
            base.replace('"plants/', f'"{cfgs}/plants/')
            .replace('"subjects/B.toml"', f'"{cfgs}/subjects/{s}.toml"')
            .replace('"experiments.toml"', f'"{cfgs}/experiments.toml"')
            .replace('instance = "exo"', f'instance = "bench{s}{os.getpid()}"')
            .replace('output_dir = "out/runs"', f'output_dir = "{out_dir}"')
        )
        cfg = pathlib.Path(out_dir) / f"run-{s}.toml"
        cfg.write_text(text)
        out = subprocess.run([str(EXO), "run", "--no-report", str(cfg)], capture_output=True, text=True)
        if out.returncode != 0:
            sys.exit(f"exo run for subject {s} failed:\n{out.stderr[-2000:]}")
        m = re.search(r"exo: recording (\S+)", out.stderr)
        recs.append(m.group(1))
        print(f"recorded subject {s}: {m.group(1)}", file=sys.stderr)
    return recs


def timed(cmd):
    t = time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True)
    dt = time.perf_counter() - t
    if out.returncode != 0:
        sys.exit(f"{cmd[0]} failed:\n{out.stderr[-2000:]}")
    return dt, out.stdout


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--recordings", nargs="*")
    a = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="exo-bench-fit-")
    recs = a.recordings or make_recordings(tmp)
    py = [sys.executable, str(ROOT / "tools" / "python" / "fit_frf.py"), *recs]
    _, py_out = timed(py)
    samples = json.loads(py_out)["samples"]
    rust, python = [], []
    for _ in range(a.rounds):
        dt, _ = timed([str(EXO), "fit", "--json", *recs])
        rust.append(samples / dt)
        dt, _ = timed(py)
        python.append(samples / dt)

    def row(name, xs):
        return f"| {name} | {statistics.median(xs):,.0f} | {min(xs):,.0f} | {max(xs):,.0f} |"

    print(f"{len(recs)} recordings, {samples:,} sensor samples, {a.rounds} rounds each (whole process, file to fits)")
    print("| fitter | samples/s p50 | min | max |")
    print("|---|---|---|---|")
    print(row("exo fit", rust))
    print(row("Python (mcap + mcap-ros2-support + numpy)", python))
    print(f"ratio of medians: {statistics.median(rust) / statistics.median(python):.1f}x (target >= 10x)")


if __name__ == "__main__":
    main()
