"""A bench's own topics in the forcemap graph, published by Eclipse Cyclone DDS (PyPI
`cyclonedds`) with standard ROS 2 types: sensor_msgs/JointState (named joints, one per channel)
on rt/bench/joints and geometry_msgs/WrenchStamped (the mass acceleration, halved, in
wrench.force.z) on rt/bench/load, both stamped with the sample's time. forcemap's foreign node
turns them into rig samples; the script then waits for theta on rt/rig/theta (forcemap's
identifier) and prints the last theta as JSON.

usage: cyclone_foreign.py DOMAIN SAMPLES.json EXPECTED_STEPS TIMEOUT_S
SAMPLES.json: {"joints": [names], "load": name or null, "samples": [[sec, nanosec, {name: value}]]}
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
from cyclonedds.idl.types import float64, sequence
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
    theta_r = DataReader(dp, Topic(dp, "rt/rig/theta", IdentifiedParameters_), qos=theta_qos)

    t0 = time.time()
    for w in [joints_w, load_w]:
        while w is not None and not w.get_matched_subscriptions():
            if time.time() - t0 > 30:
                sys.exit("no subscriber (forcemap's foreign node) matched within 30 s")
            time.sleep(0.05)
    time.sleep(0.5)
    names = run["joints"]
    zero = Vector3_(x=0.0, y=0.0, z=0.0)
    for sec, nanosec, values in run["samples"]:
        h = Header_(stamp=Time_(sec=sec, nanosec=nanosec), frame_id="bench")
        joints_w.write(JointState_(header=h, name=names, position=[values[n] for n in names], velocity=[], effort=[]))
        if load_w is not None:
            load_w.write(WrenchStamped_(header=h, wrench=Wrench_(
                force=Vector3_(x=0.0, y=0.0, z=values[run["load"]] / 2.0), torque=zero)))
    joints_w.wait_for_acks(duration(seconds=30))
    if load_w is not None:
        load_w.wait_for_acks(duration(seconds=30))

    print_last_theta(theta_r, expected_steps, timeout_s)


if __name__ == "__main__":
    main()
