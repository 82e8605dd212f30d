#!/usr/bin/env python3
"""Decode an rbprops MCAP file with the reference `mcap` reader (PyPI) alone.

Checks every channel is json-encoded with a jsonschema schema, decodes every message,
validates FRF payloads against the axis, and prints `<topic> <count>` per topic.
Exit status is non-zero on any problem.
"""
import base64
import json
import struct
import sys

from mcap.reader import make_reader


def main(path: str) -> int:
    counts: dict[str, int] = {}
    axis = None
    frfs = []
    with open(path, "rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages():
            assert channel.message_encoding == "json", channel
            assert schema is not None and schema.encoding == "jsonschema", channel.topic
            json.loads(schema.data)
            payload = json.loads(message.data)
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.topic == "/rbprops/frf_axis":
                axis = payload
            elif channel.topic == "/rbprops/frf":
                frfs.append(payload)
    if frfs:
        assert axis is not None, "FRF messages without an axis"
        n = len(axis["channels"]) * len(axis["frequency_hz"]) * 2
        for m in frfs:
            raw = base64.b64decode(m["values_f64le"])
            values = struct.unpack("<%dd" % n, raw)
            assert all(v == v for v in values), "NaN in FRF values"
    for topic, count in counts.items():
        print(topic, count)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
