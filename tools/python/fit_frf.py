#!/usr/bin/env python3
"""The Python baseline of `exo fit`'s core, for the throughput benchmark.

Reads contract recordings (docs/recording-format.md) with `mcap` and
`mcap-ros2-support`, and does what `exo fit` does to them: per period, the
analysis window (protocol phase 3) of theta_e, tau_c and tau_s, trimmed to
whole cycles, single-frequency correlation for S_h = tau_c/theta_e; then
per (subject, experiment) the linear least squares of M1, M2 and M3 on S_h
(eqs. Sh1-Sh3, the paper's estimate and exo fit's default; exo fit also
weights each point by its measured noise, which this baseline does not).

Usage: fit_frf.py [--me KG_M2] RECORDING.mcap [...]
Prints one JSON object: samples read, FRF points, fits, and seconds spent.
"""

import argparse
import json
import sys
import time

import numpy as np
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

ANALYSIS = 3


def read(path):
    """Sensor columns and protocol states of one recording."""
    seq, t, th, tc, ts = [], [], [], [], []
    grav = {}
    protocol = []
    subject = "?"
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _schema, channel, message, ros in reader.iter_decoded_messages(
            topics=["exo/sensor", "exo/protocol", "exo/command"]
        ):
            if channel.topic == "exo/command":
                grav[ros.stamp_ns] = ros.tau_gravity
            elif channel.topic == "exo/sensor":
                t.append(ros.stamp_ns)
                th.append(ros.theta_e)
                tc.append(ros.tau_c)
                ts.append(ros.tau_s)
            else:
                protocol.append(
                    (message.log_time, ros.experiment, ros.period, ros.phase, ros.omega, ros.alpha, ros.load_kg)
                )
        f.seek(0)
        try:
            for rec in make_reader(f).iter_metadata():
                if rec.name == "exo":
                    subject = rec.metadata.get("subject", subject)
        except Exception:  # a truncated file has no summary
            pass
    t = np.array(t, dtype=np.int64)
    # tau_s without the controller's gravity compensation, as the paper and exo fit do.
    g = np.array([grav.get(int(x), 0.0) for x in t])
    return subject, t, np.array(th), np.array(tc), np.array(ts) - g, protocol


def windows(protocol):
    """(experiment, period, omega, alpha, load, start_ns, end_ns) of each analysis phase."""
    out = []
    cur = None
    for stamp, exp, per, phase, omega, alpha, load in protocol:
        if phase == ANALYSIS and omega > 0 and cur is None:
            cur = [exp, per, omega, alpha, load, stamp]
        elif phase != ANALYSIS and cur is not None:
            out.append(tuple(cur) + (stamp,))
            cur = None
    return out


def correlate(t_s, x, y, omega):
    """Y/X at omega over the largest whole number of cycles."""
    period = 2 * np.pi / omega
    n_cycles = np.floor((t_s[-1] - t_s[0]) / period)
    if n_cycles < 1:
        return None
    keep = t_s - t_s[0] < n_cycles * period
    tt, xx, yy = t_s[keep], x[keep] - x[keep].mean(), y[keep] - y[keep].mean()
    e = np.exp(-1j * omega * tt)
    return (yy * e).sum() / (xx * e).sum()


def fit(points, extra_inertia):
    """M1, M2, M3 by least squares on stacked real and imaginary parts."""
    w = np.array([p[0] for p in points])
    s = np.array([p[1] for p in points]) + extra_inertia * w**2
    y = np.concatenate([s.real, s.imag])
    cols = {
        "M": np.concatenate([-(w**2), np.zeros_like(w)]),
        "B": np.concatenate([np.zeros_like(w), w]),
        "K": np.concatenate([np.ones_like(w), np.zeros_like(w)]),
        "H": np.concatenate([np.zeros_like(w), np.ones_like(w)]),
    }
    out = {}
    for name, terms in [("M1", "MBK"), ("M2", "MKH"), ("M3", "MBKH")]:
        a = np.stack([cols[c] for c in terms], axis=1)
        p, *_ = np.linalg.lstsq(a, y, rcond=None)
        rss = float(((y - a @ p) ** 2).sum())
        out[name] = dict(zip(terms, map(float, p)), rss=rss)
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--me", type=float, default=None, help="M_e without load (kg m^2); default 0.1")
    ap.add_argument("--lever", type=float, default=0.45)
    ap.add_argument("recordings", nargs="+")
    a = ap.parse_args()
    start = time.perf_counter()
    samples = 0
    results = {}
    n_points = 0
    for path in a.recordings:
        subject, t, th, tc, ts, protocol = read(path)
        samples += len(t)
        t_s = (t - t[0]) * 1e-9 if len(t) else t
        per_exp = {}
        for exp, per, omega, alpha, load, t0, t1 in windows(protocol):
            sel = (t >= t0) & (t < t1)
            if sel.sum() < 10:
                continue
            s_h = correlate(t_s[sel], th[sel], tc[sel], omega)
            if s_h is None:
                continue
            m_e = (a.me if a.me is not None else 0.1) + load * a.lever**2
            per_exp.setdefault(exp, {"alpha": alpha, "m_e": m_e, "points": []})["points"].append((omega, s_h))
            n_points += 1
        for exp, d in per_exp.items():
            if len(d["points"]) >= 2:
                results[f"{subject}/{exp}"] = fit(d["points"], 0.0)
    elapsed = time.perf_counter() - start
    json.dump(
        {"samples": samples, "frf_points": n_points, "fits": results, "seconds": elapsed,
         "samples_per_second": samples / elapsed if elapsed > 0 else None},
        sys.stdout,
    )
    print()


if __name__ == "__main__":
    main()
