#!/usr/bin/env python3
"""Independent check of the CDR bytes and schemas written by forcemap_msgs (tests/python_check.rs).

Reads FORCEMAP_CDR_DIR (or argv[1]) / manifest.json, registers the message types from the .msg
files with rosbags.typesys.get_types_from_msg, and for each case:
  - deserialises the CDR bytes with rosbags and compares every field with the expected JSON
    (null stands for NaN);
  - serialises the decoded message again with rosbags and compares the bytes with Rust's;
  - parses the MCAP ros2msg schema text and compares the field definitions with the .msg files.
Also checks the constants, and that the copies of the upstream std_msgs, builtin_interfaces and
diagnostic_msgs definitions match rosbags' own ROS 2 Humble definitions.
Prints 'N passed, M failed' and exits 1 on any failure.
"""

import json
import math
import os
import struct
import sys
from pathlib import Path

from rosbags.typesys import Stores, get_types_from_msg, get_typestore

failures: list[str] = []
passed = 0


def check(ok: bool, what: str) -> None:
    global passed
    if ok:
        passed += 1
    else:
        failures.append(what)
        print(f"FAIL: {what}", file=sys.stderr)


def to_plain(value, store):
    """rosbags message objects / numpy arrays to plain Python values (fields only, no constants)."""
    msgtype = getattr(value, "__msgtype__", None)
    if msgtype is not None:
        names = [name for name, _ in store.fielddefs[msgtype][1]]
        return {k: to_plain(getattr(value, k), store) for k in names}
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return [to_plain(v, store) for v in value]
    return value


def same(expected, actual, path: str) -> list[str]:
    """Differences between the expected JSON value and the decoded value."""
    if isinstance(expected, dict):
        if not isinstance(actual, dict) or set(expected) != set(actual):
            return [f"{path}: fields {sorted(expected)} != {sorted(actual) if isinstance(actual, dict) else actual!r}"]
        out = []
        for k in expected:
            out += same(expected[k], actual[k], f"{path}.{k}")
        return out
    if isinstance(expected, list):
        if not isinstance(actual, list) or len(expected) != len(actual):
            return [f"{path}: {expected!r} != {actual!r}"]
        out = []
        for i, (e, a) in enumerate(zip(expected, actual)):
            out += same(e, a, f"{path}[{i}]")
        return out
    if expected is None:  # NaN
        ok = isinstance(actual, float) and math.isnan(actual)
        return [] if ok else [f"{path}: expected NaN, got {actual!r}"]
    if isinstance(expected, bool):
        return [] if actual is expected or actual == expected else [f"{path}: {expected!r} != {actual!r}"]
    if isinstance(expected, float):
        # Bit for bit: -0.0 and 0.0 differ, and so does any lost last digit.
        ok = isinstance(actual, float) and struct.pack("<d", actual) == struct.pack("<d", expected)
        return [] if ok else [f"{path}: {expected!r} != {actual!r}"]
    return [] if expected == actual and type(actual) is not float else [f"{path}: {expected!r} != {actual!r}"]


def main() -> int:
    root = Path(sys.argv[1] if len(sys.argv) > 1 else os.environ["FORCEMAP_CDR_DIR"])
    manifest = json.loads((root / "manifest.json").read_text())

    # Types from the .msg files only (an empty store: nothing taken from rosbags' own defs).
    store = get_typestore(Stores.EMPTY)
    types = {}
    for entry in manifest["msg_files"]:
        types.update(get_types_from_msg(Path(entry["path"]).read_text(), entry["type"]))
    store.register(types)

    # The upstream copies agree with rosbags' ROS 2 Humble definitions.
    humble = get_typestore(Stores.ROS2_HUMBLE)
    for entry in manifest["msg_files"]:
        name = entry["type"]
        if not name.startswith("forcemap_msgs/"):
            check(
                store.fielddefs[name] == humble.fielddefs[name],
                f"{name}: definition differs from ROS 2 Humble's: {store.fielddefs[name]} != {humble.fielddefs[name]}",
            )

    for typename, consts in manifest["constants"].items():
        cls = store.types[typename]
        for cname, value in consts.items():
            check(getattr(cls, cname, None) == value, f"{typename}.{cname} == {value}")

    for case in manifest["cases"]:
        typename = case["type"]
        label = f"{case['name']} ({typename})"
        raw = (root / case["cdr"]).read_bytes()
        try:
            msg = store.deserialize_cdr(raw, typename)
        except Exception as e:  # noqa: BLE001
            check(False, f"{label}: rosbags cannot deserialise: {e!r}")
            continue
        diffs = same(case["expected"], to_plain(msg, store), case["name"])
        check(not diffs, f"{label}: " + "; ".join(diffs))
        again = bytes(store.serialize_cdr(msg, typename))
        check(again == raw, f"{label}: rosbags serialises to different bytes:\n  rust   {raw.hex()}\n  rosbags {again.hex()}")

        schema = (root / case["schema"]).read_text()
        parsed = get_types_from_msg(schema, typename)
        for name, fielddef in parsed.items():
            check(
                name in store.fielddefs and store.fielddefs[name] == fielddef,
                f"{label}: schema definition of {name} differs from the .msg file",
            )
        check(typename in parsed, f"{label}: schema does not define {typename}")

    print(f"python check_cdr: {passed} passed, {len(failures)} failed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
