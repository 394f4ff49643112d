#!/usr/bin/env python3
"""An independent writer of contract recordings (docs/recording-format.md),
with mcap + mcap-ros2-support only: proof that any tool following the
contract produces files exo reads. Writes a short synthetic identification
run: a subject with complex stiffness K(1 + jc) and inertia M, driven by one
sine per period; only the contract's fixed fields are written (no
`stamp_ns` in ProtocolState), with schemas as a third party would copy them
from the document, the `exo` metadata record and the configuration
attachment. Chunking and compression are mcap's (zstd, 1 MiB chunks by
default; --compression and --chunk-size change them).

Usage: write_recording.py OUT.mcap [--subject NAME] [--k 40] [--c 0.4]
           [--periods 6] [--compression zstd|lz4|none] [--chunk-size BYTES]
           [--tau-c-delay-ms D] [--noise SIGMA_NM] [--seed N]

--tau-c-delay-ms delays the cuff torque by D ms (a sensor delay for `exo
diagnose` to find); --noise adds Gaussian noise (Nm) to both torques from a
seeded generator.
"""
import argparse
import math
import random

from mcap.writer import CompressionType
from mcap_ros2.writer import Writer

SENSOR = """uint64 seq
uint64 stamp_ns
float64 theta_e
float64 omega_e
float64 tau_c
float64 tau_s
uint32 status
"""
COMMAND = """uint64 seq
uint64 stamp_ns
uint64 sensor_seq
float64 tau_d
float64 tau_gravity
float64 tau_amplification
float64 tau_bias
float64 tau_excitation
uint32 mode
"""
PROTOCOL = """uint32 experiment
uint32 period
uint32 phase
float64 omega
float64 amplitude
float64 alpha
float64 load_kg
float64 grip_kg
float64 bias_nm
"""


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--subject", default="PY")
    ap.add_argument("--k", type=float, default=40.0)
    ap.add_argument("--c", type=float, default=0.4)
    ap.add_argument("--m", type=float, default=0.11)
    ap.add_argument("--me", type=float, default=1.01125)
    ap.add_argument("--periods", type=int, default=6)
    ap.add_argument("--compression", choices=["zstd", "lz4", "none"], default="zstd")
    ap.add_argument("--chunk-size", type=int, default=1024 * 1024)
    ap.add_argument("--tau-c-delay-ms", type=float, default=0.0)
    ap.add_argument("--noise", type=float, default=0.0)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    rng = random.Random(a.seed)
    d = a.tau_c_delay_ms * 1e-3
    rate = 1000
    compression = {
        "zstd": CompressionType.ZSTD,
        "lz4": CompressionType.LZ4,
        "none": CompressionType.NONE,
    }[a.compression]
    config = f"""# written by tools/python/write_recording.py
[run]
rate_hz = {rate}.0

[subject]
name = "{a.subject}"
k = {a.k}
c = {a.c}
m = {a.m}
"""
    with open(a.out, "wb") as f:
        w = Writer(f, chunk_size=a.chunk_size, compression=compression)
        s_sensor = w.register_msgdef("exo_msgs/msg/SensorSample", SENSOR)
        s_command = w.register_msgdef("exo_msgs/msg/ActuatorCommand", COMMAND)
        s_protocol = w.register_msgdef("exo_msgs/msg/ProtocolState", PROTOCOL)
        seq = 0
        t_ns = 0
        for p in range(1, a.periods + 1):
            omega = 2.0 * 10 ** (0.1 * (p - 1))
            # The human's stiffness S_h(jw) = K(1 + jc) - M w^2, as gain and phase.
            s_re, s_im = a.k - a.m * omega**2, a.k * a.c
            se_re = s_re - a.me * omega**2
            amp = 0.02
            # 2 s settling, 5 s analysis, 1 s rest.
            for phase, dur in ((2, 2.0), (3, 5.0), (5, 1.0)):
                w.write_message("exo/protocol", s_protocol, {
                    "experiment": 1, "period": p, "phase": phase, "omega": omega,
                    "amplitude": 2.0, "alpha": 1.0, "load_kg": 4.5, "grip_kg": 10.0, "bias_nm": 0.0,
                }, log_time=t_ns, publish_time=t_ns)
                for _ in range(int(dur * rate)):
                    t = t_ns * 1e-9
                    on = phase in (2, 3)
                    th = 0.8 + (amp * math.sin(omega * t) if on else 0.0)
                    x, y = (amp * math.sin(omega * t), amp * math.cos(omega * t)) if on else (0.0, 0.0)
                    xd, yd = (amp * math.sin(omega * (t - d)), amp * math.cos(omega * (t - d))) if on else (0.0, 0.0)
                    tau_c = s_re * xd + s_im * yd
                    tau_s = se_re * x + s_im * y
                    if a.noise > 0.0:
                        tau_c += rng.gauss(0.0, a.noise)
                        tau_s += rng.gauss(0.0, a.noise)
                    w.write_message("exo/sensor", s_sensor, {
                        "seq": seq, "stamp_ns": t_ns, "theta_e": th, "omega_e": 0.0,
                        "tau_c": tau_c, "tau_s": tau_s, "status": 0,
                    }, log_time=t_ns, publish_time=t_ns)
                    w.write_message("exo/command", s_command, {
                        "seq": seq, "stamp_ns": t_ns, "sensor_seq": seq, "tau_d": tau_s,
                        "tau_gravity": 0.0, "tau_amplification": 0.0, "tau_bias": 0.0,
                        "tau_excitation": tau_s, "mode": 1,
                    }, log_time=t_ns, publish_time=t_ns)
                    seq += 1
                    t_ns += 1_000_000
        w.write_message("exo/protocol", s_protocol, {
            "experiment": 0, "period": 0, "phase": 0, "omega": 0.0, "amplitude": 0.0,
            "alpha": 1.0, "load_kg": 4.5, "grip_kg": 0.0, "bias_nm": 0.0,
        }, log_time=t_ns, publish_time=t_ns)
        w.add_metadata("exo", {
            "subject": a.subject,
            "software_version": "tools/python/write_recording.py",
            "config_toml": config,
            "rate_hz": str(rate),
        })
        w.add_attachment(0, 0, "config.toml", "application/toml", config.encode())
        w.finish()


if __name__ == "__main__":
    main()
