"""A bench's own topics in the forcemap graph, published by Eclipse Cyclone DDS (PyPI
`cyclonedds`) with standard ROS 2 types: sensor_msgs/JointState (named joints, one per channel)
on rt/bench/joints and geometry_msgs/WrenchStamped (the mass acceleration, halved, in
wrench.force.z) on rt/bench/load, both stamped with the sample's time. forcemap's foreign node
turns them into rig samples; the script then waits for theta on rt/rig/theta (forcemap's
identifier) and prints the last theta as JSON.

As a bench publishes in real time ("paced_hz"): sample k stamped and published at the start
time plus k / paced_hz of the wall clock (the sample times of the file are not used), the
channels named in "actuator" on rt/bench/actuator as a std_msgs/Float64MultiArray without a
header (timed by when it is received), and the step and frequency labels of "steps" (one
[step, frequency_hz] per sample) on rt/bench/step (std_msgs/UInt32) and rt/bench/frequency
(std_msgs/Float64), once per step at its first sample, no header either.

usage: cyclone_foreign.py DOMAIN SAMPLES.json EXPECTED_STEPS TIMEOUT_S
SAMPLES.json: {"joints": [names], "load": name or null, "samples": [[sec, nanosec, {name: value}]],
               optional "paced_hz": rate, "actuator": [names], "steps": [[step, frequency_hz]]}
"""
import json
import os
import sys
import time
from dataclasses import dataclass

from cyclonedds.core import Qos, Policy
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.annotations import final
from cyclonedds.idl.types import float64, sequence, uint32
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cyclone_interop import Header_, IdentifiedParameters_, Time_, print_last_theta  # noqa: E402


@final
@dataclass
class JointState_(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
    header: Header_
    name: sequence[str]
    position: sequence[float64]
    velocity: sequence[float64]
    effort: sequence[float64]


@final
@dataclass
class Vector3_(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64
    y: float64
    z: float64


@final
@dataclass
class Wrench_(IdlStruct, typename="geometry_msgs::msg::dds_::Wrench_"):
    force: Vector3_
    torque: Vector3_


@final
@dataclass
class WrenchStamped_(IdlStruct, typename="geometry_msgs::msg::dds_::WrenchStamped_"):
    header: Header_
    wrench: Wrench_


@final
@dataclass
class MultiArrayDimension_(IdlStruct, typename="std_msgs::msg::dds_::MultiArrayDimension_"):
    label: str
    size: uint32
    stride: uint32


@final
@dataclass
class MultiArrayLayout_(IdlStruct, typename="std_msgs::msg::dds_::MultiArrayLayout_"):
    dim: sequence[MultiArrayDimension_]
    data_offset: uint32


@final
@dataclass
class Float64MultiArray_(IdlStruct, typename="std_msgs::msg::dds_::Float64MultiArray_"):
    layout: MultiArrayLayout_
    data: sequence[float64]


@final
@dataclass
class UInt32_(IdlStruct, typename="std_msgs::msg::dds_::UInt32_"):
    data: uint32


@final
@dataclass
class Float64_(IdlStruct, typename="std_msgs::msg::dds_::Float64_"):
    data: float64


def main():
    domain, path, expected_steps, timeout_s = int(sys.argv[1]), sys.argv[2], int(sys.argv[3]), float(sys.argv[4])
    run = json.load(open(path))
    dp = DomainParticipant(domain)
    xcdr1 = Policy.DataRepresentation(use_cdrv0_representation=True)
    data_qos = Qos(Policy.Reliability.Reliable(duration(seconds=10)), Policy.History.KeepAll, xcdr1)
    theta_qos = Qos(
        Policy.Reliability.Reliable(duration(seconds=1)),
        Policy.Durability.TransientLocal,
        Policy.History.KeepLast(1),
        xcdr1,
    )
    joints_w = DataWriter(dp, Topic(dp, "rt/bench/joints", JointState_), qos=data_qos)
    load_w = DataWriter(dp, Topic(dp, "rt/bench/load", WrenchStamped_), qos=data_qos) if run["load"] else None
    actuator = run.get("actuator", [])
    actuator_w = DataWriter(dp, Topic(dp, "rt/bench/actuator", Float64MultiArray_), qos=data_qos) if actuator else None
    steps = run.get("steps")
    step_w = DataWriter(dp, Topic(dp, "rt/bench/step", UInt32_), qos=data_qos) if steps else None
    freq_w = DataWriter(dp, Topic(dp, "rt/bench/frequency", Float64_), qos=data_qos) if steps else None
    theta_r = DataReader(dp, Topic(dp, "rt/rig/theta", IdentifiedParameters_), qos=theta_qos)
    writers = [w for w in [joints_w, load_w, actuator_w, step_w, freq_w] if w is not None]

    t0 = time.time()
    for w in writers:
        while w is not None and not w.get_matched_subscriptions():
            if time.time() - t0 > 30:
                sys.exit("no subscriber (forcemap's foreign node) matched within 30 s")
            time.sleep(0.05)
    time.sleep(0.5)
    names = run["joints"]
    zero = Vector3_(x=0.0, y=0.0, z=0.0)
    paced_hz = run.get("paced_hz")
    start_ns = time.time_ns() + 500_000_000
    layout = MultiArrayLayout_(dim=[MultiArrayDimension_(label="ch", size=len(actuator), stride=len(actuator))],
                               data_offset=0)
    previous_step = None
    for k, (sec, nanosec, values) in enumerate(run["samples"]):
        if paced_hz:
            t_ns = start_ns + round(k * 1e9 / paced_hz)
            wait = (t_ns - time.time_ns()) * 1e-9
            if wait > 0:
                time.sleep(wait)
            sec, nanosec = divmod(t_ns, 1_000_000_000)
        h = Header_(stamp=Time_(sec=sec, nanosec=nanosec), frame_id="bench")
        joints_w.write(JointState_(header=h, name=names, position=[values[n] for n in names], velocity=[], effort=[]))
        if load_w is not None:
            load_w.write(WrenchStamped_(header=h, wrench=Wrench_(
                force=Vector3_(x=0.0, y=0.0, z=values[run["load"]] / 2.0), torque=zero)))
        if actuator_w is not None:
            actuator_w.write(Float64MultiArray_(layout=layout, data=[values[n] for n in actuator]))
        if steps and steps[k][0] != previous_step:
            previous_step = steps[k][0]
            step_w.write(UInt32_(data=steps[k][0]))
            freq_w.write(Float64_(data=steps[k][1]))
    for w in writers:
        w.wait_for_acks(duration(seconds=30))

    print_last_theta(theta_r, expected_steps, timeout_s)


if __name__ == "__main__":
    main()
