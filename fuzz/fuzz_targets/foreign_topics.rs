//! Messages from a foreign participant into the live source of foreign topics
//! (`forcemap_io::foreign_topics::ForeignTopics`, the `foreign` node's pure core), under the
//! channel map the graph tests use (`launch_configs/bench.channels.yaml`: a JointState topic
//! with four joints and a WrenchStamped topic). The decoder itself has its own target
//! (`ros_msg_decode`); this one drives the alignment by stamps: any order, loss, duplicates,
//! jitter, stamps far apart, joints missing or renamed, non-finite values, or raw bytes.
//! It must never panic, every sample must carry one value per mapped channel, and the samples'
//! times must strictly increase.
//!
//! Input: byte 0 chooses the mode. Raw (odd): records of `topic (1 byte), length (1 byte),
//! payload`, each payload pushed as it is. Built (even): records of 12 bytes, each a valid
//! message built from them (see `built`).
#![no_main]

use forcemap_io::channel_map::ChannelMap;
use forcemap_io::foreign_topics::{ForeignTopics, Output};
use libfuzzer_sys::fuzz_target;
use serde::Serialize;

const MAP: &str = include_str!("../../launch_configs/bench.channels.yaml");
const JOINTS: [&str; 4] = [
    "base_displacement_m",
    "relative_displacement_m",
    "mass_displacement_m",
    "base_acceleration_mps2",
];
/// 2026-01-01 in ns, and the bench's 10 ms sample interval.
const T0_NS: i64 = 1_767_225_600_000_000_000;
const DT_NS: i64 = 10_000_000;

#[derive(Serialize)]
struct Time {
    sec: i32,
    nanosec: u32,
}

#[derive(Serialize)]
struct Header {
    stamp: Time,
    frame_id: String,
}

#[derive(Serialize)]
struct JointState {
    header: Header,
    name: Vec<String>,
    position: Vec<f64>,
    velocity: Vec<f64>,
    effort: Vec<f64>,
}

#[derive(Serialize)]
struct Vector3 {
    x: f64,
    y: f64,
    z: f64,
}

#[derive(Serialize)]
struct Wrench {
    force: Vector3,
    torque: Vector3,
}

#[derive(Serialize)]
struct WrenchStamped {
    header: Header,
    wrench: Wrench,
}

fn header(ns: i64) -> Header {
    Header {
        stamp: Time {
            sec: ns.div_euclid(1_000_000_000) as i32,
            nanosec: ns.rem_euclid(1_000_000_000) as u32,
        },
        frame_id: "bench".into(),
    }
}

/// A valid message from 12 bytes: `b0` bit 0 the topic (joints or load), bits 1-2 the step in
/// that topic's sample counter (+1, +0 = duplicate, -1 = back, +2 = one lost), bit 3 a joint
/// left out, bit 4 a joint renamed; `b1..3` a signed jitter in ns (i16, times 16 when bit 5);
/// `b3` unused; `b4..12` the value (any f64 bits).
fn built(rec: &[u8], counters: &mut [i64; 2]) -> (usize, Vec<u8>) {
    let topic = usize::from(rec[0] & 1);
    counters[topic] += match (rec[0] >> 1) & 3 {
        0 => 1,
        1 => 0,
        2 => -1,
        _ => 2,
    };
    let mut jitter = i64::from(i16::from_le_bytes([rec[1], rec[2]]));
    if rec[0] & 0x20 != 0 {
        jitter *= 16;
    }
    let ns = T0_NS + counters[topic] * DT_NS + jitter;
    let value = f64::from_le_bytes(rec[4..12].try_into().unwrap_or([0; 8]));
    let payload = if topic == 0 {
        let mut name: Vec<String> = JOINTS.iter().map(|j| j.to_string()).collect();
        let mut position: Vec<f64> = (0..name.len()).map(|i| value + i as f64).collect();
        if rec[0] & 0x08 != 0 {
            name.pop();
            position.pop();
        }
        if rec[0] & 0x10 != 0 {
            name[0] = "stroke".into();
        }
        forcemap_msgs::encode(&JointState {
            header: header(ns),
            name,
            position,
            velocity: vec![],
            effort: vec![],
        })
    } else {
        let zero = || Vector3 {
            x: 0.0,
            y: 0.0,
            z: 0.0,
        };
        forcemap_msgs::encode(&WrenchStamped {
            header: header(ns),
            wrench: Wrench {
                force: Vector3 {
                    x: 0.0,
                    y: 0.0,
                    z: value,
                },
                torque: zero(),
            },
        })
    };
    (topic, payload)
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    let map = ChannelMap::from_yaml_str(MAP, "bench.channels.yaml").expect("the committed map");
    let mut topics = ForeignTopics::new(&map).expect("the committed map resolves");
    let n_channels = topics.channels().len();
    let n_topics = topics.topics().len();
    let mut out = Vec::new();
    let mut receive_ns = T0_NS;
    if mode & 1 == 1 {
        let mut rest = rest;
        while let [topic, len, tail @ ..] = rest {
            let n = usize::from(*len).min(tail.len());
            let (payload, next) = tail.split_at(n);
            topics.push(usize::from(*topic) % (n_topics + 1), payload, receive_ns, &mut out);
            receive_ns += DT_NS;
            rest = next;
        }
    } else {
        let mut counters = [0i64; 2];
        for rec in rest.chunks_exact(12) {
            let (topic, payload) = built(rec, &mut counters);
            topics.push(topic, &payload, receive_ns, &mut out);
            receive_ns += DT_NS;
        }
    }
    topics.flush(&mut out);
    let mut last_ns: Option<i64> = None;
    for o in &out {
        if let Output::Sample { t_ns, values, .. } = o {
            assert_eq!(values.len(), n_channels, "a sample without every mapped channel");
            if let Some(last) = last_ns {
                assert!(*t_ns > last, "sample times not increasing: {last} then {t_ns}");
            }
            last_ns = Some(*t_ns);
        }
    }
});
