#!/usr/bin/env python3
"""Which side of an EtherCAT exchange was late, from a capture on the
master's interface (BENCHMARKS.md, "EtherCAT"): the emulated drive's answer
time (an LRW request on the wire -> its reply on the wire, paired by the
datagram's index) and the master's send gaps, and for every gap over 1.5
periods the previous reply's delay and the time from that reply to the
next send.

Usage: ethercat_capture.py CAPTURE.pcap [PERIOD_US=1000]
The capture: `tcpdump -i ecm0 -j adapter_unsynced --time-stamp-precision=nano
-w CAPTURE.pcap` during a row (`CAPTURE=... tools/scripts/bench_ethercat.sh`).
The master's frames carry the source MAC 10:10:10:10:10:10 (ethercrab), the
drive's replies the same with bit 1 of its first byte set (12:10:...)."""
import collections
import struct
import sys

LRW = 0x0C


def frames(path):
    data = open(path, "rb").read()
    magic = struct.unpack("<I", data[:4])[0]
    scale = 1e-9 if magic == 0xA1B23C4D else 1e-6
    off = 24
    while off + 16 <= len(data):
        sec, frac, cap, _ = struct.unpack("<IIII", data[off:off + 16])
        off += 16
        yield sec + frac * scale, data[off:off + cap]
        off += cap


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    period = (float(sys.argv[2]) if len(sys.argv) > 2 else 1000.0) * 1e-6
    reqs, replies = [], collections.defaultdict(list)
    for t, f in frames(sys.argv[1]):
        if len(f) < 18 or f[16] != LRW:
            continue
        src = f[6:12].hex()
        if src == "101010101010":
            reqs.append((t, f[17]))
        elif src == "121010101010":
            replies[f[17]].append(t)
    if not reqs:
        sys.exit("no LRW request from the master in the capture")
    nxt, delay = collections.defaultdict(int), {}
    for t, idx in reqs:
        lst = replies[idx]
        while nxt[idx] < len(lst) and lst[nxt[idx]] < t:
            nxt[idx] += 1
        if nxt[idx] < len(lst):
            delay[t] = lst[nxt[idx]] - t
    d = sorted(delay.values())
    q = lambda v, p: v[min(len(v) - 1, int(len(v) * p))] * 1e6
    print(f"{len(reqs)} LRW requests, {len(d)} answered: answer p50 {q(d, .5):.1f} us, p99 {q(d, .99):.1f} us, "
          f"p99.9 {q(d, .999):.1f} us, max {d[-1] * 1e6:.1f} us")
    t0 = reqs[0][0]
    late = 0
    for (a, _), (b, _) in zip(reqs, reqs[1:]):
        if b - a > 1.5 * period:
            late += 1
            r = delay.get(a)
            print(f"  send gap {(b - a) * 1e6:.0f} us at {a - t0:.4f} s: previous answer "
                  + ("none" if r is None else f"{r * 1e6:.0f} us, then {(b - a - r) * 1e6:.0f} us to the next send"))
    print(f"{late} send gaps over 1.5 periods")


if __name__ == "__main__":
    main()
