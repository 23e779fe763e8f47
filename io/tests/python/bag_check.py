#!/usr/bin/env python3
"""Independent check of a bag written by forcemap's Rust bag layer.

usage: bag_check.py BAG_DIR EXPECTED_JSON

EXPECTED_JSON is a list of {"topic", "log_time", "fields": {name: value}} in log-time order.
The bag is decoded (a) with rosbags.highlevel.AnyReader and an empty type store, so that the
types come only from the schemas embedded in the bag, and (b) with mcap's make_reader and
mcap_ros2's DecoderFactory on the bag's .mcap file. Exits 1 on any mismatch.

needs: pip install rosbags mcap mcap-ros2-support
"""

import json
import math
import sys
from pathlib import Path

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore


def compare(label, got, expected):
    errors = []
    if len(got) != len(expected):
        errors.append(f"{label}: {len(got)} messages, expected {len(expected)}")
    for i, (g, e) in enumerate(zip(got, expected)):
        topic, log_time, msg = g
        if topic != e["topic"] or log_time != e["log_time"]:
            errors.append(
                f"{label}: message {i}: {topic} at {log_time}, expected "
                f"{e['topic']} at {e['log_time']}"
            )
        for name, value in e["fields"].items():
            v = getattr(msg, name, None)
            if v is None or not math.isclose(v, value, rel_tol=0.0, abs_tol=0.0):
                errors.append(f"{label}: message {i} ({topic}): {name} = {v}, expected {value}")
        if len(errors) > 10:
            break
    return errors


def read_rosbags(bag):
    got = []
    with AnyReader([bag], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        types = sorted({c.msgtype for c in reader.connections})
        for conn, timestamp, raw in reader.messages(connections=reader.connections):
            got.append((conn.topic, timestamp, reader.deserialize(raw, conn.msgtype)))
    return got, types


def read_mcap(bag):
    files = sorted(bag.glob("*.mcap")) if bag.is_dir() else [bag]
    got = []
    for f in files:
        with open(f, "rb") as stream:
            reader = make_reader(stream, decoder_factories=[DecoderFactory()])
            header = reader.get_header()
            if header.profile != "ros2":
                raise SystemExit(f"mcap: profile {header.profile!r}, expected 'ros2'")
            for schema, channel, message, decoded in reader.iter_decoded_messages(
                log_time_order=True
            ):
                if schema.encoding != "ros2msg" or channel.message_encoding != "cdr":
                    raise SystemExit(
                        f"mcap: {channel.topic}: encodings {schema.encoding}/"
                        f"{channel.message_encoding}"
                    )
                got.append((channel.topic, message.log_time, decoded))
    return got


def main():
    if len(sys.argv) != 3:
        raise SystemExit(__doc__)
    bag = Path(sys.argv[1])
    expected = json.loads(Path(sys.argv[2]).read_text())

    got_rb, types = read_rosbags(bag)
    got_mcap = read_mcap(bag)
    errors = compare("rosbags", got_rb, expected) + compare("mcap", got_mcap, expected)
    if errors:
        print("\n".join(errors))
        return 1
    print(
        f"ok: {len(expected)} messages decoded identically by rosbags AnyReader "
        f"(types from the bag: {', '.join(types)}) and by mcap + mcap_ros2"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
