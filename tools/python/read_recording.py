#!/usr/bin/env python3
"""Decodes a contract recording (docs/recording-format.md) with mcap +
mcap-ros2-support only (nothing of exo's) and prints JSON:

  {"topics": {TOPIC: {"schema": NAME, "count": N, "first": {...}, "last": {...},
                      "messages": [{...}, ...]}},
   "metadata": {NAME: {KEY: VALUE}}, "attachments": {NAME: SIZE}}

Each message lists its fields by name (floats as repr strings, which
round-trip exactly; fixed arrays as lists) plus "_log_time" and
"_publish_time" (ns). "messages" holds every message, or the first N with
--max N. Used by exo's cross-check tests.

Usage: read_recording.py RECORDING.mcap [--max N]
"""
import argparse
import json
import sys

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


def value(v):
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, (list, tuple)) or type(v).__name__ == "ndarray":
        return [value(x) for x in v]
    return v


def fields(ros, message):
    out = {name: value(getattr(ros, name)) for name in ros.__slots__}
    out["_log_time"] = message.log_time
    out["_publish_time"] = message.publish_time
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recording")
    ap.add_argument("--max", type=int, default=None, help="messages listed per topic")
    a = ap.parse_args()
    topics = {}
    with open(a.recording, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, ros in reader.iter_decoded_messages(log_time_order=False):
            t = topics.setdefault(channel.topic, {"schema": schema.name, "count": 0, "messages": []})
            m = fields(ros, message)
            t["count"] += 1
            t.setdefault("first", m)
            t["last"] = m
            if a.max is None or len(t["messages"]) < a.max:
                t["messages"].append(m)
        meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        attachments = {x.name: len(x.data) for x in reader.iter_attachments()}
    json.dump({"topics": topics, "metadata": meta, "attachments": attachments}, sys.stdout)


if __name__ == "__main__":
    main()
