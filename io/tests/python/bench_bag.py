#!/usr/bin/env python3
"""Writes a bench's own bag with Python rosbags, as `ros2 bag record` makes it of a bench's
topics: every log time is when the recorder received the message, not its stamp.

usage: bench_bag.py RUN_CSV OUT_DIR [PAUSE_S]

RUN_CSV is a forcemap CSV export of a rig run with its labels (`forcemap simulate --csv`).
OUT_DIR becomes a rosbag2 bag (metadata.yaml version 8, MCAP storage) with:

  /bench/joints     sensor_msgs/msg/JointState, stamped with the sample's time: joints 'base'
                    (base displacement), 'stroke' (relative displacement), 'body' (mass
                    displacement) [m]
  /bench/actuator   std_msgs/msg/Float64MultiArray, no header: [mass acceleration, base
                    acceleration] [m/s^2]
  /bench/step       std_msgs/msg/UInt32, no header, once per step at its first sample
  /bench/frequency  std_msgs/msg/Float64, no header, once per step at its first sample [Hz]

Log times: the sample's time plus each topic's own delay (joints 1.2 ms, actuator 2.6 ms, step
1.8 ms, frequency 2.1 ms) plus a jitter uniform in +-0.5 ms per message (seeded). With PAUSE_S,
the samples of step k are k * PAUSE_S later (a DAQ that pauses between steps).

needs: pip install rosbags
"""

import csv
import random
import sys
from pathlib import Path

import numpy as np

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

DELAY_NS = {"/bench/joints": 1_200_000, "/bench/actuator": 2_600_000,
            "/bench/step": 1_800_000, "/bench/frequency": 2_100_000}
JITTER_NS = 500_000
T0_NS = 1_767_225_600_000_000_000


def main():
    run, out = sys.argv[1], Path(sys.argv[2])
    pause_s = float(sys.argv[3]) if len(sys.argv) > 3 else 0.0
    rows = list(csv.DictReader(open(run)))
    ts = get_typestore(Stores.ROS2_HUMBLE)
    JointState = ts.types["sensor_msgs/msg/JointState"]
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    MultiArray = ts.types["std_msgs/msg/Float64MultiArray"]
    Layout = ts.types["std_msgs/msg/MultiArrayLayout"]
    Dim = ts.types["std_msgs/msg/MultiArrayDimension"]
    UInt32 = ts.types["std_msgs/msg/UInt32"]
    Float64 = ts.types["std_msgs/msg/Float64"]
    rng = random.Random(7)

    messages = []  # (log time, topic, message, type)

    def add(topic, stamp_ns, msg, msgtype):
        log = stamp_ns + DELAY_NS[topic] + int(rng.uniform(-JITTER_NS, JITTER_NS))
        messages.append((log, topic, msg, msgtype))

    previous_step = None
    for r in rows:
        step = int(r["step"])
        t_ns = T0_NS + round((float(r["time_s"]) + step * pause_s) * 1e9)
        header = Header(stamp=Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000),
                        frame_id="bench")
        add("/bench/joints", t_ns, JointState(
            header=header, name=["base", "stroke", "body"],
            position=np.array([float(r["base_displacement_m"]), float(r["relative_displacement_m"]),
                               float(r["mass_displacement_m"])], dtype=np.float64),
            velocity=np.array([], dtype=np.float64), effort=np.array([], dtype=np.float64)),
            "sensor_msgs/msg/JointState")
        add("/bench/actuator", t_ns, MultiArray(
            layout=Layout(dim=[Dim(label="ch", size=2, stride=2)], data_offset=0),
            data=np.array([float(r["mass_acceleration_mps2"]), float(r["base_acceleration_mps2"])],
                          dtype=np.float64)), "std_msgs/msg/Float64MultiArray")
        if step != previous_step:
            previous_step = step
            add("/bench/step", t_ns, UInt32(data=step), "std_msgs/msg/UInt32")
            f = float(r["frequency_hz"] or 0.0)
            add("/bench/frequency", t_ns, Float64(data=f), "std_msgs/msg/Float64")

    messages.sort(key=lambda m: m[0])
    with Writer(out, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        connections = {}
        for topic, msgtype in [("/bench/joints", "sensor_msgs/msg/JointState"),
                               ("/bench/actuator", "std_msgs/msg/Float64MultiArray"),
                               ("/bench/step", "std_msgs/msg/UInt32"),
                               ("/bench/frequency", "std_msgs/msg/Float64")]:
            connections[topic] = w.add_connection(topic, msgtype, typestore=ts)
        for log, topic, msg, msgtype in messages:
            w.write(connections[topic], log, ts.serialize_cdr(msg, msgtype))


if __name__ == "__main__":
    main()
