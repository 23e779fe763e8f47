//! Bags recorded by a bench's own tools, read through a channel map.
//!
//! The equality tests take the committed rig bag (bags/rig_40db, the paper's simulated rig at
//! 40 dB), have an independent writer (Python mcap + mcap-ros2-support, `$FORCEMAP_PYTHON`)
//! record the same run with standard message types, or with a custom type known only from
//! the bag's schema, and check that the records and the identified theta are forcemap's own.
//! The bad-input tests write small bags here, with CDR from serde structs.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::path::{Path, PathBuf};

use forcemap_io::bag::{BagWriter, TopicSpec};
use forcemap_io::channel_map::ChannelMap;
use forcemap_io::foreign_bag::read_foreign_bag;
use forcemap_io::rig_bag::read_rig_bag;
use forcemap_math::identify::{FdMultiOptions, Method};
use forcemap_math::phasor::PhasorOptions;
use forcemap_math::pipeline::identify_records;
use forcemap_math::recipe::ModelSpec;
use forcemap_math::recipe::Setup;
use forcemap_math::record::Record;
use serde::Serialize;

fn rig_bag() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../bags/rig_40db")
}

/// Runs io/tests/python/foreign_bag.py; `None` (with a message) without `FORCEMAP_PYTHON`.
fn python_foreign_bag(dir: &Path, mode: &str) -> Option<PathBuf> {
    let Ok(python) = std::env::var("FORCEMAP_PYTHON") else {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI is set but FORCEMAP_PYTHON is not: the independent writer did not run"
        );
        println!("skipped: set FORCEMAP_PYTHON to a python with mcap and mcap-ros2-support");
        return None;
    };
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/foreign_bag.py");
    let out = dir.join(format!("{mode}.mcap"));
    let run = std::process::Command::new(python)
        .arg(&script)
        .arg(rig_bag().join("rig_40db_0.mcap"))
        .arg(&out)
        .arg(mode)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "foreign_bag.py {mode} failed:\n{}\n{}",
        String::from_utf8_lossy(&run.stdout),
        String::from_utf8_lossy(&run.stderr)
    );
    Some(out)
}

fn theta(records: &[Record]) -> Vec<f64> {
    let model = "coulomb".parse::<ModelSpec>().unwrap().build().unwrap();
    identify_records(
        &model,
        &Setup::BaseExcited { mass_kg: 36.0 },
        Method::FdMulti,
        records,
        &PhasorOptions::default(),
        &FdMultiOptions::default(),
    )
    .unwrap()
    .theta()
    .to_vec()
}

/// The records of the foreign bag are the rig bag's (values to rounding of the map's scale),
/// and so is theta (relative difference below 1e-6; in fact a few ulp).
fn assert_same_run(foreign: &Path, map: &ChannelMap) {
    let own = read_rig_bag(&rig_bag()).unwrap().records;
    let got = read_foreign_bag(foreign, map).unwrap();
    assert!(got.left_out.is_none(), "{:?}", got.left_out);
    let got = got.records;
    assert_eq!(own.len(), got.len(), "record count");
    for (a, b) in own.iter().zip(&got) {
        assert_eq!(a.step, b.step);
        assert_eq!(a.len(), b.len(), "step {}", a.step);
        assert_eq!(
            a.channels.len(),
            b.channels.len(),
            "step {}: channels",
            a.step
        );
        assert_eq!(a.sample_rate_hz, b.sample_rate_hz, "step {}", a.step);
        assert_eq!(a.start_time_s, b.start_time_s, "step {}", a.step);
        assert_eq!(a.excitation.frequency_hz(), b.excitation.frequency_hz());
        for (c, v) in &b.channels {
            let w = a.channel(*c).unwrap();
            for (x, y) in v.iter().zip(w) {
                assert!(
                    (x - y).abs() <= 1e-15 * y.abs().max(1e-6),
                    "{c:?}: {x} vs {y}"
                );
            }
        }
    }
    let (t_own, t_got) = (theta(&own), theta(&got));
    println!("theta: rig bag {t_own:?}, foreign bag {t_got:?}");
    for (a, b) in t_own.iter().zip(&t_got) {
        assert!((a - b).abs() <= 1e-6 * a.abs(), "theta {a} vs {b}");
    }
}

#[test]
fn standard_message_types_give_the_rig_bags_theta() {
    let dir = tempfile::tempdir().unwrap();
    let Some(bag) = python_foreign_bag(dir.path(), "standard") else {
        return;
    };
    let map = ChannelMap::from_yaml_str(
        "channels:
  base_displacement_m: {topic: /dyno/actuator, field: 'data[1]', scale: 0.001}
  relative_displacement_m: {topic: /dyno/joints, field: 'position[shock_left]'}
  mass_acceleration_mps2: {topic: /dyno/load_cell, field: wrench.force.z, scale: 0.5}
  mass_displacement_m: {topic: /dyno/joints, field: 'position[body]'}
  base_acceleration_mps2: {topic: /dyno/actuator, field: 'data[2]'}
  step: {topic: /dyno/step, field: data}
  frequency_hz: {topic: /dyno/frequency, field: data}
",
        "map.yaml",
    )
    .unwrap();
    assert_same_run(&bag, &map);
}

#[test]
fn a_custom_type_known_only_from_the_bags_schema_gives_the_rig_bags_theta() {
    let dir = tempfile::tempdir().unwrap();
    let Some(bag) = python_foreign_bag(dir.path(), "custom") else {
        return;
    };
    // The map as a section of a ROS 2 params file.
    let map = ChannelMap::from_yaml_str(
        "/**:
  ros__parameters:
    channels:
      base_displacement_m: {topic: /bench/frame, field: 'displacement_mm[0]', scale: 0.001}
      relative_displacement_m: {topic: /bench/frame, field: 'displacement_mm[1]', scale: 0.001}
      mass_acceleration_mps2: {topic: /bench/frame, field: accel.z_mps2}
      mass_displacement_m: {topic: /bench/frame, field: 'displacement_mm[2]', scale: 0.001}
      base_acceleration_mps2: {topic: /bench/frame, field: accel.base_z_mps2}
      step: {topic: /bench/frame, field: info.step}
      frequency_hz: {topic: /bench/frame, field: info.frequency_hz}
",
        "rig.params.yaml",
    )
    .unwrap();
    assert_same_run(&bag, &map);
}

/// The rig bag's five measured channels by their RigSample field names (a channel map without
/// step or frequency labels).
const RIG_SAMPLE_CHANNELS: &str = "channels:
  base_displacement_m: {topic: /rig/samples, field: base_displacement_m}
  relative_displacement_m: {topic: /rig/samples, field: relative_displacement_m}
  mass_acceleration_mps2: {topic: /rig/samples, field: mass_acceleration_mps2}
  mass_displacement_m: {topic: /rig/samples, field: mass_displacement_m}
  base_acceleration_mps2: {topic: /rig/samples, field: base_acceleration_mps2}
";

/// forcemap's own bag read as a foreign one: its RigSample fields by name, the step from the
/// samples, the frequency from the ExcitationState topic (once per step). Needs no Python.
#[test]
fn the_rig_bag_through_a_map_of_its_own_fields_gives_its_theta() {
    let map = ChannelMap::from_yaml_str(
        &format!(
            "{RIG_SAMPLE_CHANNELS}  step: {{topic: /rig/samples, field: step}}
  frequency_hz: {{topic: /rig/excitation, field: frequency_hz}}
"
        ),
        "map.yaml",
    )
    .unwrap();
    assert_same_run(&rig_bag(), &map);
}

/// Without step and frequency labels (a bench that records no excitation state) the steps are
/// found in the driven channel: the sine steps are the labelled bag's (same samples, start
/// and frequency) and so is theta; the random records are cut where the drive changes.
#[test]
fn the_rig_bag_without_labels_gives_its_sine_steps_and_theta() {
    let map = ChannelMap::from_yaml_str(RIG_SAMPLE_CHANNELS, "map.yaml").unwrap();
    let sines = |records: &[Record]| -> Vec<Record> {
        records
            .iter()
            .filter(|r| r.excitation.frequency_hz().is_some())
            .cloned()
            .collect()
    };
    let own = read_rig_bag(&rig_bag()).unwrap().records;
    let got = read_foreign_bag(&rig_bag(), &map).unwrap().records;
    let (own_sines, got_sines) = (sines(&own), sines(&got));
    assert_eq!(own_sines.len(), 10);
    assert_eq!(got_sines.len(), own_sines.len());
    for (a, b) in own_sines.iter().zip(&got_sines) {
        assert_eq!(
            (a.len(), a.start_time_s, a.sample_rate_hz),
            (b.len(), b.start_time_s, b.sample_rate_hz),
            "step {}",
            a.step
        );
        assert_eq!(a.excitation.frequency_hz(), b.excitation.frequency_hz());
        for (c, v) in &b.channels {
            assert_eq!(Some(v.as_slice()), a.channel(*c), "step {}: {c:?}", a.step);
        }
    }
    let random = |records: &[Record]| -> usize {
        records
            .iter()
            .filter(|r| r.excitation.frequency_hz().is_none())
            .map(Record::len)
            .sum()
    };
    assert_eq!(random(&got), random(&own));
    let (t_own, t_got) = (theta(&own), theta(&got));
    for (a, b) in t_own.iter().zip(&t_got) {
        assert!((a - b).abs() <= 1e-6 * a.abs(), "theta {a} vs {b}");
    }
}

// ---- bad input: bags written here ----

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
struct Float64Stamped {
    header: Header,
    value: f64,
    label: String,
}

#[derive(Serialize)]
struct Float64 {
    data: f64,
}

const STAMPED: &str = "std_msgs/Header header\nfloat64 value\nstring label\n================================================================================\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n================================================================================\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n";

fn header(ns: i64) -> Header {
    Header {
        stamp: Time {
            sec: (ns / 1_000_000_000) as i32,
            nanosec: (ns % 1_000_000_000) as u32,
        },
        frame_id: "bench".into(),
    }
}

/// A bag with `/a` and `/b` (a stamped custom type, samples every 10 ms from t0, `/b`'s
/// stamps shifted by `b_shift_ns` and every `b_every`-th message only), `/f` (std_msgs/Float64,
/// no header, one message at t0 with 5.0) and `/s` (Float64, step 0 at t0); `/b` loses
/// message `b_lost`.
fn small_bag(dir: &Path, b_every: usize, b_shift_ns: i64, b_lost: Option<i64>) -> PathBuf {
    let path = dir.join("small");
    let mut w = BagWriter::create(&path).unwrap();
    let a = w
        .add_topic(&TopicSpec::new("/a", "bench_msgs/msg/Stamped", STAMPED))
        .unwrap();
    let b = w
        .add_topic(&TopicSpec::new("/b", "bench_msgs/msg/Stamped", STAMPED))
        .unwrap();
    let f = w
        .add_topic(&TopicSpec::new(
            "/f",
            "std_msgs/msg/Float64",
            "float64 data\n",
        ))
        .unwrap();
    let s = w
        .add_topic(&TopicSpec::new(
            "/s",
            "std_msgs/msg/Float64",
            "float64 data\n",
        ))
        .unwrap();
    let t0: i64 = 1_767_225_600_000_000_000;
    let label = |x: f64| forcemap_msgs::encode(&Float64 { data: x });
    w.write(f, t0 as u64, t0 as u64, &label(5.0)).unwrap();
    w.write(s, t0 as u64, t0 as u64, &label(0.0)).unwrap();
    for i in 0..200i64 {
        let t = t0 + i * 10_000_000;
        let m = |shift: i64| {
            forcemap_msgs::encode(&Float64Stamped {
                header: header(t + shift),
                value: (i as f64 * 0.3).sin(),
                label: "x".into(),
            })
        };
        w.write(a, t as u64, t as u64, &m(0)).unwrap();
        if (i as usize).is_multiple_of(b_every) && Some(i) != b_lost {
            w.write(b, t as u64, t as u64, &m(b_shift_ns)).unwrap();
        }
    }
    w.finish().unwrap()
}

fn map(text: &str) -> ChannelMap {
    ChannelMap::from_yaml_str(text, "map.yaml").unwrap()
}

const GOOD: &str = "channels:
  base_displacement_m: {topic: /a, field: value}
  relative_displacement_m: {topic: /b, field: value}
  mass_acceleration_mps2: {topic: /a, field: value}
  step: {topic: /s, field: data}
  frequency_hz: {topic: /f, field: data}
";

fn error(bag: &Path, text: &str) -> String {
    read_foreign_bag(bag, &map(text)).unwrap_err().to_string()
}

#[test]
fn the_small_bag_reads_with_the_good_map() {
    let dir = tempfile::tempdir().unwrap();
    let bag = small_bag(dir.path(), 1, 0, None);
    let run = read_foreign_bag(&bag, &map(GOOD)).unwrap();
    assert_eq!(run.records.len(), 1);
    let r = &run.records[0];
    assert_eq!((r.len(), r.sample_rate_hz), (200, 100.0));
    assert_eq!(r.excitation.frequency_hz(), Some(5.0));
    let x = r
        .channel(forcemap_math::record::Channel::RelativeDisplacementM)
        .unwrap();
    assert_eq!(x[7], (7.0f64 * 0.3).sin());
}

#[test]
fn a_missing_topic_is_named_with_the_bags_topics() {
    let dir = tempfile::tempdir().unwrap();
    let bag = small_bag(dir.path(), 1, 0, None);
    let e = error(&bag, &GOOD.replace("{topic: /b,", "{topic: /dyno/none,"));
    assert!(
        e.contains("topic /dyno/none (for relative_displacement_m) is not in the bag")
            && e.contains("/a, /b"),
        "{e}"
    );
}

#[test]
fn a_missing_field_is_named_with_the_types_fields() {
    let dir = tempfile::tempdir().unwrap();
    let bag = small_bag(dir.path(), 1, 0, None);
    let e = error(
        &bag,
        &GOOD.replace("{topic: /b, field: value}", "{topic: /b, field: valu}"),
    );
    assert!(
        e.contains("topic /b, field valu (for relative_displacement_m)")
            && e.contains("has no field 'valu' (its fields: header, value, label)"),
        "{e}"
    );
    let e = error(
        &bag,
        &GOOD.replace(
            "{topic: /b, field: value}",
            "{topic: /b, field: 'value[0]'}",
        ),
    );
    assert!(
        e.contains("field value[0]") && e.contains("not an array"),
        "{e}"
    );
}

#[test]
fn a_non_numeric_field_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let bag = small_bag(dir.path(), 1, 0, None);
    for (field, found) in [
        ("label", "string"),
        ("header", "a message"),
        ("header.frame_id", "string"),
    ] {
        let e = error(
            &bag,
            &GOOD.replace(
                "{topic: /b, field: value}",
                &format!("{{topic: /b, field: {field}}}"),
            ),
        );
        assert!(
            e.contains(&format!("topic /b, field {field}"))
                && e.contains(found)
                && e.contains("not a number"),
            "{e}"
        );
    }
}

#[test]
fn an_unknown_message_type_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("unknown");
    let mut w = BagWriter::create(&path).unwrap();
    // A schema record with no text: neither the bag nor the built-ins define the type.
    let id = w
        .add_topic(&TopicSpec::new("/x", "bench_msgs/msg/Secret", ""))
        .unwrap();
    w.write(id, 1, 1, &forcemap_msgs::encode(&Float64 { data: 1.0 }))
        .unwrap();
    let bag = w.finish().unwrap();
    let e = error(&bag, "channels:\n  force_n: {topic: /x, field: data}\n");
    assert!(
        e.contains("topic /x: unknown message type bench_msgs/msg/Secret"),
        "{e}"
    );
}

#[test]
fn stamps_that_do_not_align_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    // /b at half the rate.
    let e = error(&small_bag(dir.path(), 2, 0, None), GOOD);
    assert!(
        e.contains("cannot align")
            && e.contains("/b has a sample rate of 50.000000 Hz where /a has 100.000000 Hz"),
        "{e}"
    );
    // /b's clock 1 ms off (a tenth of the interval).
    let dir = tempfile::tempdir().unwrap();
    let e = error(&small_bag(dir.path(), 1, 1_000_000, None), GOOD);
    assert!(
        e.contains("cannot align")
            && e.contains(
                "the nearest /b (value) message is 0.001000000 s away; stamps must agree within 1.000e-4 s"
            ),
        "{e}"
    );
    // /b lost a message.
    let dir = tempfile::tempdir().unwrap();
    let e = error(&small_bag(dir.path(), 1, 0, Some(50)), GOOD);
    assert!(
        e.contains("sample 50 (/a (value, value) at 1767225600500000000 ns): the nearest /b (value) message is -0.010000000 s away"),
        "{e}"
    );
    // Within the tolerance (1 % of the interval), /b aligns.
    let dir = tempfile::tempdir().unwrap();
    assert!(read_foreign_bag(&small_bag(dir.path(), 1, 50_000, None), &map(GOOD)).is_ok());
}

#[test]
fn a_map_with_one_label_only_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let bag = small_bag(dir.path(), 1, 0, None);
    let text = GOOD.replace("  step: {topic: /s, field: data}\n", "");
    let e = error(&bag, &text);
    assert!(
        e.contains("the channel map gives no step (map both step and frequency_hz"),
        "{e}"
    );
}

#[test]
fn a_type_the_bag_contradicts_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let bag = small_bag(dir.path(), 1, 0, None);
    let e = error(
        &bag,
        &GOOD.replace("{topic: /b,", "{topic: /b, type: bench_msgs/msg/Other,"),
    );
    assert!(
        e.contains("topic /b: definition of bench_msgs/msg/Stamped: the channel map names the type bench_msgs/msg/Other (for relative_displacement_m), the bag records bench_msgs/msg/Stamped"),
        "{e}"
    );
    // Naming the type the bag records is fine.
    let text = GOOD.replace("{topic: /b,", "{topic: /b, type: bench_msgs/Stamped,");
    assert!(read_foreign_bag(&bag, &map(&text)).is_ok());
}
