#!/usr/bin/env python3
"""Real-time stalls of the control path: how fast each is detected, and
what the run then says. Not a test (wall-clock figures on a shared
machine); the figures go in BENCHMARKS.md.

For each case, RUNS (default 20) real-time runs of configs/realtime.toml
(4 s of plant time, `run.max_sim_time_s`), each in its own instance, with
one process stopped by SIGSTOP 2 s after the five services appeared and
continued after the stall:

- plant (the bus) stopped 1 s: the sensor driver's first sample flagged
  BUS_FAULT after the last frame; latency = its stamp - the last frame's
  stamp (criterion: within 15 ms);
- sensor driver stopped 0.5 s: the plant's first frame flagged DRIVE_FAULT;
  latency = its stamp - the stamp of the frame the last motor command
  answered (criterion: within 20 ms);
- controller stopped 0.2 s: the driver's first sample flagged SAFE_STATE;
  latency = its stamp - the stamp of the last command before the stall;
  criterion: no command answering a sample two or more ticks after that
  sample is in mode 1 (Run).

Every run must exit non-zero (3: finished with faults). Stamps are the
run's monotonic clock as recorded (MCAP), so the latencies are measured
inside the run, not by this script's timing.

Usage, from the repository root after `cargo build --release --workspace`:
  target/py-venv/bin/python tools/scripts/bench_faults.py [RUNS]
(PROFILE=dev: the dev build's binaries, after `cargo build --workspace`)
(`tools/python/ensure_venv.sh` makes the venv: mcap, mcap-ros2-support.)
"""
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

ROOT = os.getcwd()
RUNS = int(sys.argv[1]) if len(sys.argv) > 1 else 20
DRIVE_FAULT = 1 << 4
BUS_FAULT = 1 << 3
SAFE_STATE = 1 << 4
RUN_MODE = 1
CASES = [("plant", "exo-plant-sim", 1.0), ("driver", "exo-sensor-driver", 0.5),
         ("controller", "exo-controller", 0.2)]


def run_file(d, instance):
    t = open("configs/realtime.toml").read()
    for a, b in [('"plants/', f'"{ROOT}/configs/plants/'),
                 ('"subjects/', f'"{ROOT}/configs/subjects/'),
                 ('"experiments.toml"', f'"{ROOT}/configs/experiments.toml"'),
                 ('instance = "exort"', f'instance = "{instance}"'),
                 ('output_dir = "out/runs"', f'output_dir = "{d}"')]:
        assert a in t, a
        t = t.replace(a, b)
    t = t.replace("[run]\n", "[run]\nmax_sim_time_s = 4.0\n", 1)
    path = f"{d}/run.toml"
    open(path, "w").write(t)
    return path


def children(pid):
    out = subprocess.run(["pgrep", "-P", str(pid)], capture_output=True, text=True).stdout
    kids = {}
    for k in out.split():
        try:
            kids[open(f"/proc/{k}/comm").read().strip()] = int(k)
        except FileNotFoundError:
            pass
    return kids


def topics(path):
    out = {"exo/sensor": [], "exo/command": [], "exo/bus/sensor": [], "exo/bus/motor": []}
    with open(path, "rb") as f:
        for _, channel, _, m in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages(
                topics=list(out)):
            out[channel.topic].append(m)
    return out


def exo_bin():
    """`exo` of the build the bench measures: the release build, or with
    PROFILE=dev the dev profile's (optimised, with line tables); under
    CARGO_TARGET_DIR if set."""
    target = os.environ.get("CARGO_TARGET_DIR", "target")
    return os.path.join(target, "debug" if os.environ.get("PROFILE") == "dev" else "release", "exo")


def start_run(d, instance):
    """Starts `exo run` of a real-time run file in `d` (instance `instance`),
    waits for its five services and 2 s more; returns the `exo run` process
    and its services' pids by name."""
    cfg = run_file(d, instance)
    p = subprocess.Popen([exo_bin(), "run", cfg, "--no-report"],
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                         env=dict(os.environ, RUST_LOG="warn"))
    t0 = time.time()
    kids = {}
    while len(kids) < 5 and time.time() - t0 < 30:
        time.sleep(0.05)
        kids = children(p.pid)
    time.sleep(2.0)
    return p, kids


def one(case, proc, stall_s, i):
    d = tempfile.mkdtemp(prefix="exo-faults-")
    p, kids = start_run(d, f"bf{case[0]}{i}")
    target = next(v for k, v in kids.items() if proc.startswith(k) or k.startswith(proc[:15]))
    os.kill(target, signal.SIGSTOP)
    time.sleep(stall_s)
    os.kill(target, signal.SIGCONT)
    _, err = p.communicate(timeout=120)
    rec = re.search(r"exo: recording (\S+)", err)
    if not rec:
        return p.returncode, None, False, err
    t = topics(rec.group(1))
    s, c, fr, mo = t["exo/sensor"], t["exo/command"], t["exo/bus/sensor"], t["exo/bus/motor"]
    ok = True
    if case == "plant":
        first = next(x for x in s if x.status & BUS_FAULT)
        last_frame = max(x.stamp_ns for x in fr if x.stamp_ns < first.stamp_ns)
        lat = (first.stamp_ns - last_frame) / 1e6
        ok = lat <= 15.0
    elif case == "driver":
        first = next(x for x in fr if x.status & DRIVE_FAULT)
        last_answer = max(x.stamp_ns for x in mo if x.stamp_ns < first.stamp_ns)
        lat = (first.stamp_ns - last_answer) / 1e6
        ok = lat <= 20.0
    else:
        first = next(x for x in s if x.status & SAFE_STATE)
        last_cmd = max(x.stamp_ns for x in c if x.stamp_ns < first.stamp_ns)
        lat = (first.stamp_ns - last_cmd) / 1e6
        ok = not any(x.mode == RUN_MODE and x.sensor_seq >= first.seq + 2 for x in c)
    return p.returncode, lat, ok, err


def pct(xs, q):
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(round(q * (len(xs) - 1))))]


def main():
    print(f"| stall | runs | detection p50 | p99 | max | criterion met | exit codes |")
    print("|---|---|---|---|---|---|---|")
    for case, proc, stall in CASES:
        lats, oks, codes = [], 0, {}
        for i in range(RUNS):
            code, lat, ok, err = one(case, proc, stall, i)
            codes[code] = codes.get(code, 0) + 1
            if lat is None:
                print(f"{case} run {i}: no recording\n{err}", file=sys.stderr)
                continue
            lats.append(lat)
            oks += ok
        print(f"| {proc} stopped {stall} s | {len(lats)} | {statistics.median(lats):.2f} ms "
              f"| {pct(lats, 0.99):.2f} ms | {max(lats):.2f} ms | {oks}/{len(lats)} "
              f"| {', '.join(f'{k}: {v}' for k, v in sorted(codes.items()))} |", flush=True)


if __name__ == "__main__":
    main()
