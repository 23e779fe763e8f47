#!/usr/bin/env python3
"""Writes a bench's own bag from a forcemap rig bag, with an independent writer.

usage: foreign_bag.py RIG_MCAP OUT_MCAP MODE

Reads forcemap's /rig/samples and /rig/excitation with mcap + mcap_ros2's decoder (types from
the schemas in the bag) and writes the same run with mcap_ros2's writer as a bench that never
heard of forcemap would record it:

- MODE standard: standard message types on separate topics:
  /dyno/actuator   std_msgs/Float64MultiArray, no header (log time 2 us off the sample time,
                   alternating sign), data = [999, base displacement in mm, base acceleration]
  /dyno/joints     sensor_msgs/JointState, names [shock_right, shock_left, body], positions
                   [0.5, relative displacement, mass displacement] [m]
  /dyno/load_cell  geometry_msgs/WrenchStamped, force.z = 2 * mass acceleration
  /dyno/step       std_msgs/UInt32 and /dyno/frequency std_msgs/Float64, once per step at its
                   start (log time)
- MODE custom: one topic /bench/frame of a type known only from the bag's schema,
  bench_msgs/msg/RigFrame (nested types, a fixed array, a bounded array, a constant, a
  default, padding between a float32 and a float64).

needs: pip install mcap mcap-ros2-support
"""

import sys

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from mcap_ros2.writer import Writer

SEP = "=" * 80 + "\n"
HEADER = "builtin_interfaces/Time stamp\nstring frame_id\n"
TIME = "int32 sec\nuint32 nanosec\n"


def deps(*pairs):
    return "".join(f"{SEP}MSG: {name}\n{text}" for name, text in pairs)


FLOAT64_MULTI_ARRAY = (
    "MultiArrayLayout layout\nfloat64[] data\n"
    + deps(
        ("std_msgs/MultiArrayLayout", "MultiArrayDimension[] dim\nuint32 data_offset\n"),
        ("std_msgs/MultiArrayDimension", "string label\nuint32 size\nuint32 stride\n"),
    )
)
JOINT_STATE = (
    "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\n"
    "float64[] effort\n" + deps(("std_msgs/Header", HEADER), ("builtin_interfaces/Time", TIME))
)
WRENCH_STAMPED = (
    "std_msgs/Header header\nWrench wrench\n"
    + deps(
        ("std_msgs/Header", HEADER),
        ("builtin_interfaces/Time", TIME),
        ("geometry_msgs/Wrench", "Vector3 force\nVector3 torque\n"),
        ("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z\n"),
    )
)
RIG_FRAME = (
    "# A bench's own frame: one per sample.\n"
    "uint8 VERSION=2\n"
    "std_msgs/Header header\n"
    "StepInfo info   # the step\n"
    "float64[3] displacement_mm  # base, relative, mass\n"
    "Accel accel\n"
    "string note \"bench # 7\"\n"
    "int16[<=4] spare\n"
    + deps(
        ("std_msgs/Header", HEADER),
        ("builtin_interfaces/Time", TIME),
        ("bench_msgs/StepInfo", "uint32 step\nfloat32 gain\nfloat64 frequency_hz\n"),
        ("bench_msgs/Accel", "bool valid\nfloat64 z_mps2\nfloat64 base_z_mps2\n"),
    )
)


def ns(t):
    return t.sec * 1_000_000_000 + t.nanosec


def read_rig(path):
    samples, steps = [], []
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _schema, channel, message, msg in reader.iter_decoded_messages():
            if channel.topic.endswith("/samples"):
                samples.append(msg)
            elif channel.topic.endswith("/excitation") and msg.kind != 2:
                steps.append(msg)
    return samples, steps


def main():
    rig, out, mode = sys.argv[1], sys.argv[2], sys.argv[3]
    samples, steps = read_rig(rig)
    with open(out, "wb") as f:
        w = Writer(f)
        if mode == "standard":
            actuator = w.register_msgdef("std_msgs/msg/Float64MultiArray", FLOAT64_MULTI_ARRAY)
            joints = w.register_msgdef("sensor_msgs/msg/JointState", JOINT_STATE)
            load = w.register_msgdef("geometry_msgs/msg/WrenchStamped", WRENCH_STAMPED)
            step = w.register_msgdef("std_msgs/msg/UInt32", "uint32 data\n")
            freq = w.register_msgdef("std_msgs/msg/Float64", "float64 data\n")
            for s in steps:
                t = ns(s.start_time)
                w.write_message("/dyno/step", step, {"data": s.step}, log_time=t, publish_time=t)
                w.write_message(
                    "/dyno/frequency", freq, {"data": s.frequency_hz}, log_time=t, publish_time=t
                )
            for i, s in enumerate(samples):
                t = ns(s.header.stamp)
                header = {"stamp": {"sec": s.header.stamp.sec, "nanosec": s.header.stamp.nanosec},
                          "frame_id": "dyno"}
                jitter = 2000 if i % 2 else -2000
                layout = {"dim": [{"label": "ch", "size": 3, "stride": 3}], "data_offset": 0}
                w.write_message(
                    "/dyno/actuator", actuator,
                    {"layout": layout,
                     "data": [999.0, s.base_displacement_m * 1000.0, s.base_acceleration_mps2]},
                    log_time=t + jitter, publish_time=t + jitter,
                )
                w.write_message(
                    "/dyno/joints", joints,
                    {"header": header, "name": ["shock_right", "shock_left", "body"],
                     "position": [0.5, s.relative_displacement_m, s.mass_displacement_m],
                     "velocity": [], "effort": []},
                    log_time=t + 50_000, publish_time=t + 50_000,
                )
                w.write_message(
                    "/dyno/load_cell", load,
                    {"header": header,
                     "wrench": {"force": {"x": 0.0, "y": 0.0, "z": 2.0 * s.mass_acceleration_mps2},
                                "torque": {"x": 0.0, "y": 0.0, "z": 0.0}}},
                    log_time=t + 70_000, publish_time=t + 70_000,
                )
        elif mode == "custom":
            frame = w.register_msgdef("bench_msgs/msg/RigFrame", RIG_FRAME)
            plans = {s.step: s.frequency_hz for s in steps}
            for i, s in enumerate(samples):
                t = ns(s.header.stamp)
                w.write_message(
                    "/bench/frame", frame,
                    {"header": {"stamp": {"sec": s.header.stamp.sec,
                                          "nanosec": s.header.stamp.nanosec},
                                "frame_id": "bench"},
                     "info": {"step": s.step, "gain": 1.5, "frequency_hz": plans[s.step]},
                     "displacement_mm": [s.base_displacement_m * 1000.0,
                                         s.relative_displacement_m * 1000.0,
                                         s.mass_displacement_m * 1000.0],
                     "accel": {"valid": True, "z_mps2": s.mass_acceleration_mps2,
                               "base_z_mps2": s.base_acceleration_mps2},
                     "note": "bench # 7",
                     "spare": list(range(i % 5))},
                    # Log times out of step with the stamps: the header decides.
                    log_time=t + 300_000, publish_time=t + 300_000,
                )
        else:
            sys.exit(f"unknown mode {mode}")
        w.finish()


if __name__ == "__main__":
    main()
