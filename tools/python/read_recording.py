#!/usr/bin/env python3
"""Decodes a contract recording with mcap + mcap-ros2-support only (nothing
of exo's) and prints JSON: per topic the schema name, the message count and
every decoded message's fields (floats as repr strings, so they round-trip
exactly), plus the metadata records. Used by exo's cross-check tests.

Usage: read_recording.py RECORDING.mcap [--max N]
"""
import json
import sys

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


def fields(ros):
    out = {}
    for name in ros.__slots__:
        v = getattr(ros, name)
        if isinstance(v, float):
            out[name] = repr(v)
        elif isinstance(v, (list, tuple)):
            out[name] = [repr(x) if isinstance(x, float) else x for x in v]
        else:
            out[name] = v
    return out


def main():
    path = sys.argv[1]
    limit = int(sys.argv[3]) if len(sys.argv) > 3 and sys.argv[2] == "--max" else None
    topics = {}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, ros in reader.iter_decoded_messages():
            t = topics.setdefault(channel.topic, {"schema": schema.name, "count": 0, "messages": []})
            t["count"] += 1
            if limit is None or len(t["messages"]) < limit:
                m = fields(ros)
                m["_log_time"] = message.log_time
                t["messages"].append(m)
        meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
    json.dump({"topics": topics, "metadata": meta}, sys.stdout)


if __name__ == "__main__":
    main()
