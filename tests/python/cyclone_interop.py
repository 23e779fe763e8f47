"""A third-party DDS in the forcemap graph: Eclipse Cyclone DDS (PyPI `cyclonedds`).

Publishes the excitation states and rig samples listed in a JSON file (as forcemap's sensor
would) on rt/rig/excitation and rt/rig/samples, then waits for theta on rt/rig/theta from
forcemap's identifier and prints the last theta as JSON. Types are final (XCDR1), written from
the .msg files, so a mismatch in forcemap's encoding fails here.

usage: cyclone_interop.py DOMAIN MESSAGES.json EXPECTED_STEPS TIMEOUT_S
"""
import json
import math
import sys
import time
from dataclasses import dataclass

from cyclonedds.core import Qos, Policy
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.annotations import final
from cyclonedds.idl.types import float64, sequence, uint8, uint32, int32
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration


@final
@dataclass
class Time_(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32
    nanosec: uint32


@final
@dataclass
class Header_(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time_
    frame_id: str


@final
@dataclass
class RigSample_(IdlStruct, typename="forcemap_msgs::msg::dds_::RigSample_"):
    header: Header_
    step: uint32
    present_channels: uint32
    base_displacement_m: float64
    relative_displacement_m: float64
    mass_acceleration_mps2: float64
    mass_displacement_m: float64
    base_acceleration_mps2: float64
    force_n: float64
    drive_point_displacement_m: float64


@final
@dataclass
class ExcitationState_(IdlStruct, typename="forcemap_msgs::msg::dds_::ExcitationState_"):
    header: Header_
    step: uint32
    start_time: Time_
    kind: uint8
    driven_channel: str
    frequency_hz: float64
    amplitude: float64
    band_low_hz: float64
    band_high_hz: float64
    sample_count: uint32


@final
@dataclass
class IdentifiedParameters_(IdlStruct, typename="forcemap_msgs::msg::dds_::IdentifiedParameters_"):
    header: Header_
    model: str
    method: str
    parameter_names: sequence[str]
    values: sequence[float64]
    standard_deviations: sequence[float64]
    covariance: sequence[float64]
    r_percent: sequence[float64]
    equations: uint32
    condition_number: float64
    residual_rms: float64
    steps_used: sequence[uint32]
    warnings: sequence[str]


def f(v):
    return math.nan if v is None else float(v)


def header(h):
    return Header_(stamp=Time_(sec=h["stamp"]["sec"], nanosec=h["stamp"]["nanosec"]), frame_id=h["frame_id"])


def print_last_theta(theta_r, expected_steps, timeout_s):
    """Takes thetas until one uses `expected_steps` steps (or `timeout_s` passes) and prints the
    last as one JSON line, as the Rust tests read it."""
    last = None
    t0 = time.time()
    while time.time() - t0 < timeout_s:
        for t in theta_r.take(N=16):
            last = t
        if last is not None and len(last.steps_used) >= expected_steps:
            break
        time.sleep(0.05)
    if last is None:
        sys.exit("no theta received on rt/rig/theta")
    print(json.dumps({
        "model": last.model, "method": last.method, "names": list(last.parameter_names),
        "values": list(last.values), "steps_used": list(last.steps_used),
        "equations": last.equations,
    }))


def main():
    domain, path, expected_steps, timeout_s = int(sys.argv[1]), sys.argv[2], int(sys.argv[3]), float(sys.argv[4])
    messages = json.load(open(path))
    dp = DomainParticipant(domain)
    xcdr1 = Policy.DataRepresentation(use_cdrv0_representation=True)
    latched = Qos(
        Policy.Reliability.Reliable(duration(seconds=1)),
        Policy.Durability.TransientLocal,
        Policy.History.KeepLast(64),
        xcdr1,
    )
    samples_qos = Qos(Policy.Reliability.Reliable(duration(seconds=10)), Policy.History.KeepAll, xcdr1)
    theta_qos = Qos(
        Policy.Reliability.Reliable(duration(seconds=1)),
        Policy.Durability.TransientLocal,
        Policy.History.KeepLast(1),
        xcdr1,
    )
    ex_w = DataWriter(dp, Topic(dp, "rt/rig/excitation", ExcitationState_), qos=latched)
    s_w = DataWriter(dp, Topic(dp, "rt/rig/samples", RigSample_), qos=samples_qos)
    theta_r = DataReader(dp, Topic(dp, "rt/rig/theta", IdentifiedParameters_), qos=theta_qos)

    t0 = time.time()
    while not s_w.get_matched_subscriptions():
        if time.time() - t0 > 30:
            sys.exit("no subscriber (forcemap's harmonic node) matched rt/rig/samples within 30 s")
        time.sleep(0.05)
    time.sleep(0.5)
    for m in messages:
        if m["topic"] == "excitation":
            e = m["msg"]
            ex_w.write(ExcitationState_(
                header=header(e["header"]), step=e["step"],
                start_time=Time_(sec=e["start_time"]["sec"], nanosec=e["start_time"]["nanosec"]),
                kind=e["kind"], driven_channel=e["driven_channel"],
                frequency_hz=f(e["frequency_hz"]), amplitude=f(e["amplitude"]),
                band_low_hz=f(e["band_low_hz"]), band_high_hz=f(e["band_high_hz"]),
                sample_count=e["sample_count"]))
        else:
            s = m["msg"]
            s_w.write(RigSample_(
                header=header(s["header"]), step=s["step"], present_channels=s["present_channels"],
                base_displacement_m=f(s["base_displacement_m"]),
                relative_displacement_m=f(s["relative_displacement_m"]),
                mass_acceleration_mps2=f(s["mass_acceleration_mps2"]),
                mass_displacement_m=f(s["mass_displacement_m"]),
                base_acceleration_mps2=f(s["base_acceleration_mps2"]),
                force_n=f(s["force_n"]),
                drive_point_displacement_m=f(s["drive_point_displacement_m"])))
    s_w.wait_for_acks(duration(seconds=30))
    ex_w.wait_for_acks(duration(seconds=30))

    print_last_theta(theta_r, expected_steps, timeout_s)


if __name__ == "__main__":
    main()
