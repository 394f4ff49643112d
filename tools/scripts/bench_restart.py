#!/usr/bin/env python3
"""What a restart off the control path costs the real-time path.

For each case, RUNS (default 10) real-time runs of configs/realtime.toml
(4 s of plant time, `run.max_sim_time_s`), each in its own instance. In the
"recorder" and "identifier" cases that process is killed (SIGKILL) 2 s
after the five services appeared, and `exo run` restarts it; the
"baseline" case kills nothing, side by side in the same invocation. From
`exo run`'s summary it reads the plant's missed real-time deadlines (the
fault "the bus (plant-sim) missed N real-time deadlines", 0 when absent)
and whether the driver latched its safe state. Not a test: wall-clock
figures on a shared machine; they go in BENCHMARKS.md ("Restarts").

Usage, from the repository root after `cargo build --release --workspace`:
  target/py-venv/bin/python tools/scripts/bench_restart.py [RUNS]
(PROFILE=dev: the dev build's binaries, after `cargo build --workspace`)
(the venv of `tools/python/ensure_venv.sh`: it shares bench_faults.py's helpers)
"""
import os
import re
import signal
import statistics
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_faults import pct, start_run  # noqa: E402  (one copy of each)

RUNS = int(sys.argv[1]) if len(sys.argv) > 1 else 10
CASES = [("baseline", None), ("recorder", "exo-recorder"), ("identifier", "exo-identifier")]


def one(case, proc, i):
    d = tempfile.mkdtemp(prefix="exo-restart-")
    p, kids = start_run(d, f"br{case[0]}{i}")
    if proc:
        target = next(v for k, v in kids.items() if proc.startswith(k))
        os.kill(target, signal.SIGKILL)
    _, err = p.communicate(timeout=120)
    m = re.search(r"missed (\d+) real-time deadlines", err)
    missed = int(m.group(1)) if m else 0
    latched = "latched its safe state" in err
    restarted = "was restarted" in err
    return p.returncode, missed, latched, restarted


def main():
    print(f"{RUNS} real-time runs per case (4 s of plant time, kill at 2 s)")
    print("| case | runs | restarted | missed deadlines: median | p90 | max | runs with any | driver latched |")
    print("|---|---|---|---|---|---|---|---|")
    for case, proc in CASES:
        rows = [one(case, proc, i) for i in range(RUNS)]
        missed = [r[1] for r in rows]
        print(f"| {case} | {RUNS} | {sum(r[3] for r in rows)} | {statistics.median(missed):.0f} "
              f"| {pct(missed, 0.9)} | {max(missed)} | {sum(1 for x in missed if x)} "
              f"| {sum(r[2] for r in rows)} |", flush=True)


if __name__ == "__main__":
    main()
