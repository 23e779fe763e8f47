//! The live source of foreign topics without ROS: payloads in, aligned samples out. The
//! samples equal the values written (through the map's scale), timed by the header stamps;
//! the map's mistakes are named with topic and field; any bytes give a report, never a panic.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use forcemap_io::channel_map::ChannelMap;
use forcemap_io::foreign_topics::{ForeignTopics, LEARN_MESSAGES, Output};
use forcemap_math::record::Channel;
use serde::Serialize;

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
struct WrenchStamped {
    header: Header,
    force: Vector3,
    torque: Vector3,
}

const T0: i64 = 1_767_225_600_000_000_000;
const DT: i64 = 10_000_000;

fn header(ns: i64) -> Header {
    Header {
        stamp: Time {
            sec: (ns / 1_000_000_000) as i32,
            nanosec: (ns % 1_000_000_000) as u32,
        },
        frame_id: "bench".into(),
    }
}

fn joints(i: i64, shift: i64) -> Vec<u8> {
    forcemap_msgs::encode(&JointState {
        header: header(T0 + i * DT + shift),
        name: vec!["stroke".into(), "base".into()],
        position: vec![(i as f64 * 0.3).sin(), i as f64],
        velocity: vec![],
        effort: vec![],
    })
}

fn load(i: i64) -> Vec<u8> {
    let zero = || Vector3 {
        x: 0.0,
        y: 0.0,
        z: 0.0,
    };
    forcemap_msgs::encode(&WrenchStamped {
        header: header(T0 + i * DT),
        force: Vector3 {
            x: 0.0,
            y: 0.0,
            z: 0.25 * i as f64,
        },
        torque: zero(),
    })
}

const MAP: &str = "channels:
  relative_displacement_m: {topic: /bench/joints, type: sensor_msgs/msg/JointState, field: 'position[stroke]', scale: 0.001}
  base_displacement_m: {topic: /bench/joints, field: 'position[base]'}
  mass_acceleration_mps2: {topic: /bench/load, type: geometry_msgs/WrenchStamped, field: wrench.force.z, scale: 4.0}
";

fn topics(text: &str) -> Result<ForeignTopics, String> {
    let map = ChannelMap::from_yaml_str(text, "map.yaml").map_err(|e| e.to_string())?;
    ForeignTopics::new(&map).map_err(|e| e.to_string())
}

/// Feeds messages 0..n of both topics, the load topic one message behind (as two publishers
/// interleave), `joints_shift` added to the joints' stamps and message `lost` of the joints
/// left out.
fn feed(n: i64, joints_shift: i64, lost: Option<i64>) -> Vec<Output> {
    let mut f = topics(MAP).unwrap();
    let mut out = Vec::new();
    for i in 0..n {
        if Some(i) != lost {
            f.push(0, &joints(i, joints_shift), 0, &mut out);
        }
        if i > 0 {
            f.push(1, &load(i - 1), 0, &mut out);
        }
    }
    out
}

#[test]
fn samples_are_the_values_written_at_their_stamps() {
    let out = feed(40, 0, None);
    let samples: Vec<(i64, Vec<(Channel, f64)>)> = out
        .into_iter()
        .map(|o| match o {
            Output::Sample { t_ns, values, .. } => (t_ns, values),
            other => panic!("{other:?}"),
        })
        .collect();
    // Every message pair but the last (its load message is not sent).
    assert_eq!(samples.len(), 39);
    for (i, (t, values)) in samples.iter().enumerate() {
        let i = i as i64;
        assert_eq!(*t, T0 + i * DT);
        let mut values = values.clone();
        values.sort_by_key(|(c, _)| c.name());
        assert_eq!(
            values,
            vec![
                (Channel::BaseDisplacementM, i as f64),
                (Channel::MassAccelerationMps2, i as f64),
                (
                    Channel::RelativeDisplacementM,
                    (i as f64 * 0.3).sin() * 0.001
                ),
            ]
        );
    }
}

#[test]
fn misaligned_messages_are_reported_with_topic_and_field() {
    // A lost joints message after the interval is learnt.
    let lost = LEARN_MESSAGES as i64 + 5;
    let out = feed(40, 0, Some(lost));
    let reports: Vec<&String> = out
        .iter()
        .filter_map(|o| match o {
            Output::Misaligned(m) => Some(m),
            _ => None,
        })
        .collect();
    assert_eq!(reports.len(), 1, "{out:?}");
    assert!(
        reports[0].contains("/bench/load (wrench.force.z) message at")
            && reports[0].contains("matches no /bench/joints (position["),
        "{}",
        reports[0]
    );
    // A clock 1 ms off on the joints: nothing aligns, every sample is reported.
    let out = feed(40, 1_000_000, None);
    assert!(!out.iter().any(|o| matches!(o, Output::Sample { .. })));
    let first = out
        .iter()
        .find_map(|o| match o {
            Output::Misaligned(m) => Some(m.clone()),
            _ => None,
        })
        .unwrap();
    assert!(
        first.contains("the nearest /bench/load (wrench.force.z) message is -0.001000000 s away"),
        "{first}"
    );
}

#[test]
fn map_mistakes_are_named_with_topic_and_field() {
    let e = topics(&MAP.replace(", type: geometry_msgs/WrenchStamped", "")).unwrap_err();
    assert!(
        e.contains("topic /bench/load: the channel map names no message type"),
        "{e}"
    );
    let e = topics(&MAP.replace("geometry_msgs/WrenchStamped", "bench_msgs/Secret")).unwrap_err();
    assert!(
        e.contains("topic /bench/load: cannot decode message type bench_msgs/msg/Secret"),
        "{e}"
    );
    let e = topics(&MAP.replace("wrench.force.z", "wrench.force.w")).unwrap_err();
    assert!(
        e.contains("topic /bench/load, field wrench.force.w (for mass_acceleration_mps2)")
            && e.contains("no field 'w'"),
        "{e}"
    );
    let e = topics(&MAP.replace("wrench.force.z", "header.frame_id")).unwrap_err();
    assert!(
        e.contains("field header.frame_id") && e.contains("not a number"),
        "{e}"
    );
    let e = topics(&MAP.replace(
        "field: 'position[base]'",
        "type: std_msgs/msg/Float64, field: 'position[base]'",
    ))
    .unwrap_err();
    assert!(
        e.contains("topic /bench/joints has type")
            && e.contains("std_msgs/msg/Float64")
            && e.contains("sensor_msgs/msg/JointState"),
        "{e}"
    );
}

#[test]
fn malformed_payloads_are_reported_and_skipped() {
    let mut f = topics(MAP).unwrap();
    let mut out = Vec::new();
    let good = joints(0, 0);
    // Truncations, garbage and a joint missing from the names.
    for cut in 0..good.len() - 3 {
        f.push(0, &good[..cut], 0, &mut out);
    }
    let mut state = 7u64;
    for _ in 0..2000 {
        let len = (state % 97) as usize;
        let bytes: Vec<u8> = (0..len)
            .map(|_| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (state >> 56) as u8
            })
            .collect();
        f.push((state % 2) as usize, &bytes, 0, &mut out);
    }
    let unnamed = forcemap_msgs::encode(&JointState {
        header: header(T0),
        name: vec!["base".into()],
        position: vec![1.0],
        velocity: vec![],
        effort: vec![],
    });
    out.clear();
    f.push(0, &unnamed, 0, &mut out);
    assert!(
        matches!(&out[..], [Output::Malformed { topic, problem }] if topic == "/bench/joints" && problem.contains("position[stroke]")),
        "{out:?}"
    );
    // The good messages still align afterwards.
    out.clear();
    for i in 0..30 {
        f.push(0, &joints(i, 0), 0, &mut out);
        f.push(1, &load(i), 0, &mut out);
    }
    assert_eq!(
        out.iter()
            .filter(|o| matches!(o, Output::Sample { .. }))
            .count(),
        30,
        "{out:?}"
    );
}

#[derive(Serialize)]
struct Float64 {
    data: f64,
}

/// The load as a `std_msgs/Float64` (no header): timed by when it is received.
const HEADERLESS_MAP: &str = "channels:
  relative_displacement_m: {topic: /bench/joints, type: sensor_msgs/msg/JointState, field: 'position[stroke]', scale: 0.001}
  base_displacement_m: {topic: /bench/joints, field: 'position[base]'}
  mass_acceleration_mps2: {topic: /bench/load, type: std_msgs/msg/Float64, field: data, scale: 4.0}
";

/// Messages 0..n of both topics, each received `delay_ns` plus a jitter uniform in
/// +-`jitter_ns` after its sample time (a live graph: the publisher stamps the joints when it
/// samples, the network and the scheduler delay every message), fed in the order received.
fn feed_received(n: i64, delay_ns: i64, jitter_ns: i64) -> Vec<Output> {
    let mut state = 11u64;
    let mut jitter = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) * jitter_ns as f64
    };
    let mut messages: Vec<(i64, usize, Vec<u8>)> = Vec::new();
    for i in 0..n {
        let sampled = T0 + i * DT;
        messages.push((sampled + delay_ns + jitter() as i64, 0, joints(i, 0)));
        let load = forcemap_msgs::encode(&Float64 {
            data: 0.25 * i as f64,
        });
        messages.push((sampled + delay_ns + jitter() as i64, 1, load));
    }
    messages.sort_by_key(|m| m.0);
    let mut f = topics(HEADERLESS_MAP).unwrap();
    let mut out = Vec::new();
    for (receive_ns, k, payload) in messages {
        f.push(k, &payload, receive_ns, &mut out);
    }
    out
}

/// A headerless topic beside a stamped one, live: receive times 4 ms behind the stamps with
/// +-3 ms of jitter (at 100 Hz: 40 % and 30 % of the interval, 400 and 300 times the
/// stamps' 1 % tolerance) still give every sample, each load value with the joints of its own
/// sample. Delays that spread over half an interval give a report naming the topics and no
/// sample.
#[test]
fn a_headerless_topic_received_late_aligns_with_the_stamped_one() {
    let out = feed_received(200, 4_000_000, 3_000_000);
    let mut samples = 0;
    for o in &out {
        let Output::Sample { t_ns, values, .. } = o else {
            panic!("{o:?}");
        };
        let i = (t_ns - T0) / DT;
        assert_eq!(*t_ns, T0 + i * DT);
        let value = |c: Channel| values.iter().find(|(d, _)| *d == c).unwrap().1;
        assert_eq!(value(Channel::BaseDisplacementM), i as f64);
        assert_eq!(value(Channel::MassAccelerationMps2), i as f64);
        samples += 1;
    }
    // Every sample (the first and last may fall outside the span both topics cover).
    assert!(samples >= 198, "{samples} of 200");
    // Jitter of +-8 ms: the delays' interquartile range is about 8 ms, over half the 10 ms
    // interval.
    let out = feed_received(40, 4_000_000, 8_000_000);
    assert!(!out.iter().any(|o| matches!(o, Output::Sample { .. })));
    let Some(Output::Misaligned(m)) = out.first() else {
        panic!("{out:?}");
    };
    assert!(
        m.contains("/bench/joints: its receive times lag its stamps")
            && m.contains("no consistent offset to time the topics without a header (/bench/load)"),
        "{m}"
    );
}

#[derive(Serialize)]
struct UInt32 {
    data: u32,
}

/// The headerless map with the step and frequency labels, each a headerless topic of its own.
fn labelled_map() -> String {
    format!(
        "{HEADERLESS_MAP}  step: {{topic: /bench/step, type: std_msgs/msg/UInt32, field: data}}
  frequency_hz: {{topic: /bench/frequency, type: std_msgs/msg/Float64, field: data}}
"
    )
}

/// A bench as `ros2 bag record` or the live node sees it: samples every 10 ms, the joints
/// stamped, the load without a header, and the step and frequency labels published once per
/// step (30 samples) at its first sample; each message received its topic's delay (joints
/// 1.2 ms, load 2.6 ms, labels 1.8 ms) plus a jitter uniform in +-0.5 ms after its sample.
/// Every sample carries its own step's labels, the first of each step too (its label is
/// received after it), and the values of its own sample.
#[test]
fn labels_received_after_a_steps_first_sample_start_the_step_there() {
    let mut f = topics(&labelled_map()).unwrap();
    let index = |name: &str| f.topics().iter().position(|t| t.name == name).unwrap();
    let (joints_k, load_k, step_k, freq_k) = (
        index("/bench/joints"),
        index("/bench/load"),
        index("/bench/step"),
        index("/bench/frequency"),
    );
    let mut state = 5u64;
    let mut jitter = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) * 500_000.0
    };
    let n = 300;
    let frequency = |step: i64| 1.5 + step as f64;
    let mut messages: Vec<(i64, usize, Vec<u8>)> = Vec::new();
    for i in 0..n {
        let sampled = T0 + i * DT;
        let mut at = |delay: i64| sampled + delay + jitter() as i64;
        messages.push((at(1_200_000), joints_k, joints(i, 0)));
        let load = forcemap_msgs::encode(&Float64 {
            data: 0.25 * i as f64,
        });
        messages.push((at(2_600_000), load_k, load));
        if i % 30 == 0 {
            let step = forcemap_msgs::encode(&UInt32 {
                data: (i / 30) as u32,
            });
            messages.push((at(1_800_000), step_k, step));
            let f = forcemap_msgs::encode(&Float64 {
                data: frequency(i / 30),
            });
            messages.push((at(1_800_000), freq_k, f));
        }
    }
    messages.sort_by_key(|m| m.0);
    let mut out = Vec::new();
    for (receive_ns, k, payload) in messages {
        f.push(k, &payload, receive_ns, &mut out);
    }
    // The samples wait for their labels at most half a second of the stream.
    let before_flush = out.len();
    f.flush(&mut out);
    assert!(
        before_flush >= (n - 52) as usize && before_flush < n as usize,
        "{before_flush} samples before the stream ended"
    );
    let mut samples = 0;
    for o in &out {
        let Output::Sample {
            t_ns,
            values,
            labels,
        } = o
        else {
            panic!("{o:?}");
        };
        let i = (t_ns - T0) / DT;
        assert_eq!(*t_ns, T0 + i * DT);
        let value = |c: Channel| values.iter().find(|(d, _)| *d == c).unwrap().1;
        assert_eq!(value(Channel::BaseDisplacementM), i as f64);
        assert_eq!(value(Channel::MassAccelerationMps2), i as f64);
        let step = i / 30;
        assert_eq!(
            *labels,
            Some([Some(step as f64), Some(frequency(step))]),
            "sample {i}"
        );
        samples += 1;
    }
    assert!(samples >= n - 2, "{samples} of {n}");
}
