#!/usr/bin/env python3
"""An independent client of exo's live view (the Foxglove WebSocket protocol,
subprotocol `foxglove.sdk.v1`), written from the protocol's public
description with nothing of exo's code: it connects, reads the channel
advertisements, decodes every message with the advertised ros2msg schema
(CDR, little endian, each field aligned to its size after the 4-byte
encapsulation header), and writes what it received as JSON.

Usage: live_client.py URL OUT.json [--bad-input]

It prints `subscribed` on standard output once it has subscribed to every
advertised channel. It then reads one JSON line on standard input, the
number of messages expected per topic, and stops when it has them all or
when no message arrived for `--idle` seconds after that line.

With --bad-input it first sends what a broken client would (text that is
not JSON, an unknown binary opcode, a subscription to a channel id that
was never advertised) and records the server's status messages; then it
goes on as a good client, to show the server still serves it.
"""

import argparse
import asyncio
import json
import struct
import sys
import time

import websockets

SUBPROTOCOL = "foxglove.sdk.v1"

# ros2msg primitive types: (struct format, size).
PRIMITIVES = {
    "bool": ("?", 1),
    "byte": ("B", 1),
    "char": ("b", 1),
    "int8": ("b", 1),
    "uint8": ("B", 1),
    "int16": ("h", 2),
    "uint16": ("H", 2),
    "int32": ("i", 4),
    "uint32": ("I", 4),
    "int64": ("q", 8),
    "uint64": ("Q", 8),
    "float32": ("f", 4),
    "float64": ("d", 8),
}


def parse_schema(text):
    """[(name, type, array length or None)] of a flat ros2msg schema."""
    fields = []
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith("==="):
            break
        parts = line.split()
        ty, name = parts[0], parts[1]
        if "=" in name:  # a constant
            continue
        n = None
        if ty.endswith("]"):
            ty, n = ty[:-1].split("[")
            n = int(n)
        if ty not in PRIMITIVES:
            raise ValueError(f"type {ty} is not a primitive")
        fields.append((name, ty, n))
    return fields


def decode_cdr(fields, data, args_float_bits=False):
    """{name: value} of one CDR payload (header checked); float64 values as
    their bit patterns with `args_float_bits`."""
    if data[0:2] != b"\x00\x01":
        raise ValueError(f"not little-endian CDR: header {data[:4].hex()}")
    body = data[4:]
    pos = 0
    out = {}
    for name, ty, n in fields:
        fmt, size = PRIMITIVES[ty]
        values = []
        for _ in range(n or 1):
            pos += (-pos) % size
            (v,) = struct.unpack_from("<" + fmt, body, pos)
            if args_float_bits and fmt == "d":
                # The IEEE 754 bit pattern, so the comparison is exact.
                (v,) = struct.unpack_from("<Q", body, pos)
            pos += size
            values.append(v)
        out[name] = values if n is not None else values[0]
    return out


async def run(args):
    statuses = []
    channels = {}
    received = {}
    log_times = {}
    errors = []
    async with websockets.connect(
        args.url, subprotocols=[SUBPROTOCOL], max_size=None, max_queue=None
    ) as ws:
        # Until every channel is advertised (the server sends them on connect).
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            msg = await asyncio.wait_for(ws.recv(), timeout=30)
            if isinstance(msg, str):
                m = json.loads(msg)
                if m.get("op") == "advertise":
                    for c in m["channels"]:
                        channels[c["id"]] = c
                elif m.get("op") == "status":
                    statuses.append(m)
                if channels and m.get("op") == "advertise":
                    break
        if args.bad_input:
            await ws.send("this is not JSON {")
            await ws.send(b"\xff\x00\x01")
            unknown = max(channels) + 1000
            await ws.send(
                json.dumps(
                    {"op": "subscribe", "subscriptions": [{"id": 4242, "channelId": unknown}]}
                )
            )
            # The server answers each with a status message.
            t = time.monotonic() + 10
            while len(statuses) < 3 and time.monotonic() < t:
                try:
                    msg = await asyncio.wait_for(ws.recv(), timeout=1)
                except asyncio.TimeoutError:
                    continue
                if isinstance(msg, str):
                    m = json.loads(msg)
                    if m.get("op") == "status":
                        statuses.append(m)
        schemas = {}
        for cid, c in channels.items():
            if c["encoding"] != "cdr" or c["schemaEncoding"] != "ros2msg":
                errors.append(f"{c['topic']}: {c['encoding']}/{c['schemaEncoding']}")
                continue
            schemas[cid] = parse_schema(c["schema"])
            received[c["topic"]] = []
            log_times[c["topic"]] = []
        await ws.send(
            json.dumps(
                {
                    "op": "subscribe",
                    "subscriptions": [{"id": cid, "channelId": cid} for cid in schemas],
                }
            )
        )
        print("subscribed", flush=True)
        if args.stall:
            # A client that stops reading: the server's queue for it fills.
            sys.stdin.readline()
            return

        expected = None
        loop = asyncio.get_running_loop()
        stdin_line = loop.run_in_executor(None, sys.stdin.readline)
        last_message = time.monotonic()
        while True:
            if expected is None and stdin_line.done():
                expected = json.loads(stdin_line.result())
                last_message = time.monotonic()
            if expected is not None:
                if all(len(received.get(t, [])) >= n for t, n in expected.items()):
                    break
                if time.monotonic() - last_message > args.idle:
                    break
            try:
                msg = await asyncio.wait_for(ws.recv(), timeout=0.2)
            except asyncio.TimeoutError:
                continue
            if isinstance(msg, str):
                m = json.loads(msg)
                if m.get("op") == "status":
                    statuses.append(m)
                continue
            last_message = time.monotonic()
            if msg[0] != 1:
                errors.append(f"binary opcode {msg[0]}")
                continue
            sub_id, log_time = struct.unpack_from("<IQ", msg, 1)
            c = channels[sub_id]
            received[c["topic"]].append(decode_cdr(schemas[sub_id], msg[13:], args.float_bits))
            log_times[c["topic"]].append(log_time)
    out = {
        "channels": {
            c["topic"]: {"schemaName": c["schemaName"], "fields": [f[0] for f in schemas.get(cid, [])]}
            for cid, c in channels.items()
        },
        "messages": received,
        "log_times": log_times,
        "statuses": statuses,
        "errors": errors,
    }
    with open(args.out, "w") as f:
        json.dump(out, f)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("url")
    p.add_argument("out")
    p.add_argument("--bad-input", action="store_true")
    p.add_argument("--idle", type=float, default=30.0)
    p.add_argument("--float-bits", action="store_true", help="write float64 fields as their IEEE 754 bits")
    p.add_argument("--stall", action="store_true", help="subscribe, then never read (a slow client)")
    args = p.parse_args()
    asyncio.run(run(args))


if __name__ == "__main__":
    main()
