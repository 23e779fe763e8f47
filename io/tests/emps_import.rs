//! Imports the real EMPS benchmark files (../shared/real/emps, not in the repository) into
//! bags, reads them back with BagReader and checks every sample. Skips with a notice where the
//! data is absent.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;
use std::path::{Path, PathBuf};

use forcemap_io::bag::BagReader;
use forcemap_io::emps::{self, AXIS_TOPIC, EPOCH_NS, PARAMETERS_TOPIC};
use forcemap_msgs::RosMessage;
use forcemap_msgs::diagnostic_msgs::DiagnosticStatus;
use forcemap_msgs::msg::AxisSample;

fn data_dir() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/real/emps");
    if dir.join("DATA_EMPS.mat").is_file() {
        Some(dir)
    } else {
        eprintln!("skipped: {} does not exist", dir.display());
        None
    }
}

fn check_file(name: &str, expect_extra: &[&str]) {
    let Some(dir) = data_dir() else { return };
    let mat = dir.join(name);
    let data = emps::read_emps(&mat).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("emps_bag");
    let summary = emps::import_emps(&mat, &out).unwrap();
    assert_eq!(summary.bag, out);
    assert_eq!(summary.samples as usize, data.len());
    assert_eq!(summary.parameter_messages, 1);
    assert_eq!(summary.extra_variables, expect_extra);
    println!("{name}: {summary:?}");

    let n = data.len();
    assert_eq!(n, 24841, "{name}: length of t");
    // t uniform at 1 kHz: every step within 0.05 % of 1 ms, the mean exactly 1 ms.
    assert!(
        (summary.sample_rate_hz - 1000.0).abs() < 1e-6,
        "{summary:?}"
    );
    for w in data.time_s.windows(2) {
        assert!(((w[1] - w[0]) - 1e-3).abs() < 5e-7, "step {}", w[1] - w[0]);
    }
    // Position within the published range (the carriage travels 0 .. about 0.25 m).
    for q in data.position_m.iter().chain(&data.reference_m) {
        assert!((-1e-3..=0.26).contains(q), "{q}");
    }
    let max_q = data.position_m.iter().fold(f64::MIN, |m, v| m.max(*v));
    assert!(max_q > 0.2, "{max_q}");
    assert!((data.gtau - 35.150_651_882_485_47).abs() < 1e-12);
    assert_eq!((data.kp, data.kv), (160.18, 243.45));

    let bag = BagReader::open(&out).unwrap();
    let s = bag.summary();
    assert_eq!(s.message_count as usize, n + 1);
    assert_eq!(bag.topic(AXIS_TOPIC).unwrap().message_count as usize, n);
    assert_eq!(
        bag.topic(AXIS_TOPIC).unwrap().type_name,
        "forcemap_msgs/msg/AxisSample"
    );
    assert_eq!(
        bag.topic(AXIS_TOPIC).unwrap().schema_text,
        AxisSample::schema()
    );
    let ptopic = bag.topic(PARAMETERS_TOPIC).unwrap();
    assert_eq!(ptopic.type_name, "diagnostic_msgs/msg/DiagnosticStatus");
    assert!(
        ptopic.offered_qos_profiles.contains("durability: 1"),
        "latched"
    );
    assert_eq!(s.start_ns, EPOCH_NS);

    let mut params = None;
    let mut i = 0;
    for m in bag.messages().unwrap() {
        let m = m.unwrap();
        if m.topic.name == PARAMETERS_TOPIC {
            params = Some(DiagnosticStatus::from_cdr(&m.data).unwrap());
            continue;
        }
        let a = AxisSample::from_cdr(&m.data).unwrap();
        assert_eq!(a.header.frame_id, "emps");
        assert_eq!(a.header.stamp.as_nanos() as u64, m.log_time);
        let t = (m.log_time - EPOCH_NS) as f64 * 1e-9;
        assert!((t - data.time_s[i]).abs() < 1e-9);
        assert_eq!(a.position_m, data.position_m[i]);
        assert_eq!(a.reference_position_m, data.reference_m[i]);
        assert_eq!(a.drive_input, data.drive_input[i]);
        assert_eq!(a.force_n, data.gtau * a.drive_input, "force = gtau * vir");
        assert!(a.velocity_mps.is_nan() && a.acceleration_mps2.is_nan());
        i += 1;
    }
    assert_eq!(i, n);
    let params = params.expect("a parameters message");
    let get = |k: &str| {
        params
            .values
            .iter()
            .find(|kv| kv.key == k)
            .unwrap_or_else(|| panic!("no key {k}"))
            .value
            .clone()
    };
    assert_eq!(get("gtau").parse::<f64>().unwrap(), data.gtau);
    assert_eq!(get("kp").parse::<f64>().unwrap(), data.kp);
    assert_eq!(get("kv").parse::<f64>().unwrap(), data.kv);
    assert_eq!(get("gtau_unit"), "N/V");
    assert_eq!(get("drive_input_unit"), "V");
    assert_eq!(get("source_file"), name);
    for (k, values) in &data.extra {
        assert_eq!(&emps::parse_run_length(&get(k)).unwrap(), values, "{k}");
    }
}

#[test]
fn imports_data_emps() {
    check_file("DATA_EMPS.mat", &[]);
}

#[test]
fn imports_data_emps_pulses() {
    check_file("DATA_EMPS_PULSES.mat", &["pulses_N"]);
}

#[test]
fn existing_output_is_refused_and_left_alone() {
    let Some(dir) = data_dir() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("bag");
    std::fs::create_dir(&out).unwrap();
    let err = emps::import_emps(&dir.join("DATA_EMPS.mat"), &out).unwrap_err();
    assert!(err.to_string().contains("already exists"), "{err}");
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 0);
}

/// The EMPS bag decodes identically with rosbags (types from the embedded schemas only) and with
/// mcap + mcap-ros2-support (tests/python/bag_check.py).
#[test]
fn python_readers_decode_the_emps_bag() {
    let Some(dir) = data_dir() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("emps_bag");
    emps::import_emps(&dir.join("DATA_EMPS.mat"), &out).unwrap();
    let reader = BagReader::open(&out).unwrap();
    let mut expected = Vec::new();
    for m in reader.messages().unwrap() {
        let m = m.unwrap();
        let mut f = serde_json::Map::new();
        if m.topic.name == AXIS_TOPIC {
            let s = AxisSample::from_cdr(&m.data).unwrap();
            for (k, v) in [
                ("position_m", s.position_m),
                ("reference_position_m", s.reference_position_m),
                ("force_n", s.force_n),
                ("drive_input", s.drive_input),
            ] {
                f.insert(k.into(), v.into());
            }
        } else {
            f.insert(
                "level".into(),
                DiagnosticStatus::from_cdr(&m.data).unwrap().level.into(),
            );
        }
        expected
            .push(serde_json::json!({"topic": m.topic.name, "log_time": m.log_time, "fields": f}));
    }
    common::python_bag_check(&out, &serde_json::Value::Array(expected));
}
