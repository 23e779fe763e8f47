//! Foreign topics, live: a Python Cyclone DDS participant publishes the committed rig run on a
//! bench's own standard topics (sensor_msgs/JointState with one joint per channel, and
//! geometry_msgs/WrenchStamped carrying the mass acceleration, halved, undone by the map's
//! scale), stamped with the samples' times, with no forcemap message and no excitation state.
//! forcemap's foreign node (through a channel map), the harmonic node finding the steps itself
//! and the identifier run as processes; the theta the Python participant receives equals
//! `forcemap identify` on the same run's bag.
//!
//! The same with an eProsima Fast DDS participant (ROS 2's default middleware; the C++ peer of
//! graph_fastdds in its `bench` mode).
//!
//! A bench as it publishes in real time: the Python participant stamps each sample with the
//! wall clock as it publishes it, the accelerations on a topic without a header (timed by when
//! the foreign node receives it), and the step and frequency labels once per step, without
//! headers either; the foreign node reads the labels (no `find_steps`) and the theta is the
//! run's CSV's.
//!
//! Runs when FORCEMAP_PYTHON names a Python with `cyclonedds`, and Fast DDS is installed
//! (each skipped with a message otherwise, failed under CI).
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;
#[path = "fastdds/peer.rs"]
mod peer;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use common::*;
use forcemap_math::record::Channel;
use forcemap_msgs::RosMessage;
use forcemap_msgs::msg::RigSample;

/// The committed rig run as a bench would publish it: per sample its stamp and the values of
/// the joints (every channel but the mass acceleration) and of the load (the mass acceleration).
struct BenchRun {
    joints: Vec<&'static str>,
    load: Channel,
    /// (sec, nanosec, joint values in `joints` order, load value).
    samples: Vec<(i32, u32, Vec<f64>, f64)>,
}

fn bench_run() -> BenchRun {
    let bag = repo().join("bags/rig_40db");
    let reader = forcemap_io::bag::BagReader::open(&bag).unwrap();
    let load = Channel::MassAccelerationMps2;
    let mut joints: Vec<Channel> = Vec::new();
    let mut samples = Vec::new();
    for m in reader.messages_on(&["/rig/samples"]).unwrap() {
        let s = RigSample::from_cdr(&m.unwrap().data).unwrap();
        if joints.is_empty() {
            assert!(s.present().contains(&load), "{:?}", s.present());
            joints = s.present().into_iter().filter(|c| *c != load).collect();
        }
        let values = joints.iter().map(|c| s.channel(*c).unwrap()).collect();
        let stamp = &s.header.stamp;
        samples.push((stamp.sec, stamp.nanosec, values, s.channel(load).unwrap()));
    }
    BenchRun {
        joints: joints.iter().map(|c| c.name()).collect(),
        load,
        samples,
    }
}

/// The channel map of the bench: each joint by name, the load cell's z force scaled back.
fn write_map(dir: &Path, run: &BenchRun) -> PathBuf {
    let mut map = String::from("channels:\n");
    for j in &run.joints {
        map.push_str(&format!(
            "  {j}: {{topic: /bench/joints, type: sensor_msgs/msg/JointState, field: 'position[{j}]'}}\n"
        ));
    }
    map.push_str(&format!(
        "  {}: {{topic: /bench/load, type: geometry_msgs/msg/WrenchStamped, field: wrench.force.z, scale: 2.0}}\n",
        run.load.name()
    ));
    let path = dir.join("bench.channels.yaml");
    std::fs::write(&path, map).unwrap();
    path
}

/// The harmonic node (with `harmonic_args`), the identifier and the foreign node on `domain`,
/// ready for the bench's messages.
fn start_graph(domain: u16, map: &Path, harmonic_args: &[String]) -> Vec<NodeProcess> {
    let harmonic = NodeProcess::start("harmonic", domain, harmonic_args);
    let identifier = NodeProcess::start(
        "identifier",
        domain,
        &["model:=coulomb".into(), "mass_kg:=36.0".into()],
    );
    let foreign = NodeProcess::start("foreign", domain, &[format!("channels:={}", map.display())]);
    harmonic.wait_for("waiting for samples", Duration::from_secs(30));
    foreign.wait_for("publishing aligned samples", Duration::from_secs(30));
    vec![harmonic, identifier, foreign]
}

/// The last theta a peer received equals the offline theta of the committed run, and the
/// foreign node skipped no message.
fn assert_offline_theta(last: &serde_json::Value, foreign: &NodeProcess) {
    let offline = offline_theta(&repo().join("bags/rig_40db"), &["--model", "coulomb"]);
    assert_theta(last, foreign, &offline, 10);
}

/// The last theta a peer received, of `steps` steps, equals `offline`, and the foreign node
/// skipped no message.
fn assert_theta(
    last: &serde_json::Value,
    foreign: &NodeProcess,
    offline: &[(String, f64)],
    steps: usize,
) {
    assert_eq!(
        last["steps_used"].as_array().unwrap().len(),
        steps,
        "{last}"
    );
    let live: Vec<(String, f64)> = last["names"]
        .as_array()
        .unwrap()
        .iter()
        .zip(last["values"].as_array().unwrap())
        .map(|(n, x)| (n.as_str().unwrap().to_string(), x.as_f64().unwrap()))
        .collect();
    let worst = live
        .iter()
        .zip(offline)
        .map(|((_, a), (_, b))| (a - b).abs() / b.abs())
        .fold(0.0f64, f64::max);
    eprintln!("live {live:?}\noffline {offline:?}\nlargest relative difference {worst:e}");
    assert_same_theta(&live, offline, 1e-6);
    let lines = foreign.lines();
    assert!(
        !lines.iter().any(|l| l.contains("warning")),
        "{}",
        lines.join("\n")
    );
}

#[test]
fn cyclone_dds_on_standard_topics_gives_the_offline_theta() {
    let Some(py) = python_with_cyclonedds() else {
        return;
    };
    let d = domain(41);
    let dir = tempfile::tempdir().unwrap();
    let run = bench_run();
    let samples: Vec<serde_json::Value> = run
        .samples
        .iter()
        .map(|(sec, nanosec, joints, load)| {
            let mut values: serde_json::Map<String, serde_json::Value> = run
                .joints
                .iter()
                .zip(joints)
                .map(|(j, v)| (j.to_string(), (*v).into()))
                .collect();
            values.insert(run.load.name().to_string(), (*load).into());
            serde_json::json!([sec, nanosec, values])
        })
        .collect();
    let json = dir.path().join("samples.json");
    std::fs::write(
        &json,
        serde_json::json!({"joints": run.joints, "load": run.load.name(), "samples": samples})
            .to_string(),
    )
    .unwrap();
    let graph = start_graph(
        d,
        &write_map(dir.path(), &run),
        &["find_steps:=true".into()],
    );
    let out = Command::new(&py)
        .arg(repo().join("tests/python/cyclone_foreign.py"))
        .arg(d.to_string())
        .arg(&json)
        .arg("10")
        .arg("120")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "cyclone_foreign.py failed: {}\n{}",
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_offline_theta(&v, &graph[2]);
}

/// The same with ROS 2's default middleware: an eProsima Fast DDS participant (the peer of
/// graph_fastdds, mode `bench`) publishes the bench's topics.
#[test]
fn fast_dds_on_standard_topics_gives_the_offline_theta() {
    let Some(exe) = peer::fastdds_peer() else {
        return;
    };
    let d = domain(42);
    let dir = tempfile::tempdir().unwrap();
    let run = bench_run();
    // Floats in Rust's shortest round-trip form, so the peer sends the same bits.
    let mut tsv = String::new();
    let names = run.joints.join(",");
    for (sec, nanosec, joints, load) in &run.samples {
        let values: Vec<String> = joints.iter().map(|v| format!("{v:?}")).collect();
        writeln!(
            tsv,
            "J\t{sec}\t{nanosec}\tbench\t{names}\t{}",
            values.join("\t")
        )
        .unwrap();
        writeln!(tsv, "W\t{sec}\t{nanosec}\tbench\t{:?}", load / 2.0).unwrap();
    }
    let path = dir.path().join("bench.tsv");
    std::fs::write(&path, tsv).unwrap();
    // A Fast DDS writer repairing a lost sample under load has held the stream for over the
    // default 5 s of silence that ends a run found in the samples, cutting a step in two.
    let graph = start_graph(
        d,
        &write_map(dir.path(), &run),
        &["find_steps:=true".into(), "run_end_silence_s:=12.0".into()],
    );
    let out = Command::new(&exe)
        .args([
            "bench",
            &d.to_string(),
            &path.display().to_string(),
            "10",
            "120",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "fastdds_peer bench failed: {}\n{}",
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
    let last = String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter(|l| l.starts_with('{'))
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .next_back()
        .expect("no theta received");
    assert_offline_theta(&last, &graph[2]);
}

/// A short rig run as a bench publishes it in real time: 20 Hz (half an interval, 25 ms, for a
/// headerless message's delay to stray from the reference's: a publisher or a test host under
/// load delays a message by more than the 10 ms of 50 Hz now and then), five sine steps of 6 s
/// at 40 dB.
fn real_time_run() -> forcemap_math::sim::RunSpec {
    use forcemap_math::sim::{RunSpec, StepSpec};
    let steps = [2.0, 2.4, 2.8, 3.2, 3.4]
        .map(|frequency_hz| StepSpec::Sine {
            frequency_hz,
            amplitude: 0.006,
        })
        .to_vec();
    RunSpec {
        sample_rate_hz: 20.0,
        samples_per_record: 120,
        snr_db: Some(40.0),
        seed: 1,
        ..RunSpec::rig(steps)
    }
}

/// The bench publishes in real time (stamps from its wall clock), the accelerations on a
/// `Float64MultiArray` without a header and the labels once per step on `UInt32` / `Float64`
/// topics without headers; the foreign node times them by their receive times less the
/// joints' delay and reads the labels (each step's `ExcitationState`, IDLE after the run's
/// silence), the harmonic node takes the steps as labelled: the theta of the run's CSV.
#[test]
fn cyclone_dds_bench_in_real_time_with_receive_times_and_labels_gives_the_csvs_theta() {
    let Some(py) = python_with_cyclonedds() else {
        return;
    };
    let d = domain(43);
    let dir = tempfile::tempdir().unwrap();
    let spec = real_time_run();
    let records = spec.simulate().unwrap();
    let csv = dir.path().join("run.csv");
    forcemap_io::csv_export::write_csv(&csv, &records, spec.setup_kind()).unwrap();
    let offline = offline_theta(&csv, &["--model", "coulomb", "--mass-kg", "36"]);

    let actuator = [Channel::MassAccelerationMps2, Channel::BaseAccelerationMps2];
    let joints: Vec<Channel> = records[0]
        .channels
        .iter()
        .map(|(c, _)| *c)
        .filter(|c| !actuator.contains(c))
        .collect();
    let mut samples = Vec::new();
    let mut steps = Vec::new();
    for r in &records {
        for i in 0..r.len() {
            let values: serde_json::Map<String, serde_json::Value> = r
                .channels
                .iter()
                .map(|(c, x)| (c.name().to_string(), x[i].into()))
                .collect();
            samples.push(serde_json::json!([0, 0, values]));
            steps.push(serde_json::json!([
                r.step,
                r.excitation.frequency_hz().unwrap_or(0.0)
            ]));
        }
    }
    let names = |c: &[Channel]| c.iter().map(|c| c.name()).collect::<Vec<_>>();
    let json = dir.path().join("samples.json");
    std::fs::write(
        &json,
        serde_json::json!({
            "joints": names(&joints), "load": null, "actuator": names(&actuator),
            "samples": samples, "steps": steps, "paced_hz": spec.sample_rate_hz,
        })
        .to_string(),
    )
    .unwrap();
    let mut map = String::from("channels:\n");
    for j in names(&joints) {
        map.push_str(&format!(
            "  {j}: {{topic: /bench/joints, type: sensor_msgs/msg/JointState, field: 'position[{j}]'}}\n"
        ));
    }
    for (k, a) in names(&actuator).iter().enumerate() {
        map.push_str(&format!(
            "  {a}: {{topic: /bench/actuator, type: std_msgs/msg/Float64MultiArray, field: 'data[{k}]'}}\n"
        ));
    }
    map.push_str("  step: {topic: /bench/step, type: std_msgs/msg/UInt32, field: data}\n");
    map.push_str(
        "  frequency_hz: {topic: /bench/frequency, type: std_msgs/msg/Float64, field: data}\n",
    );
    let map_path = dir.path().join("bench.channels.yaml");
    std::fs::write(&map_path, map).unwrap();

    let graph = start_graph(d, &map_path, &[]);
    let out = Command::new(&py)
        .arg(repo().join("tests/python/cyclone_foreign.py"))
        .arg(d.to_string())
        .arg(&json)
        .arg(records.len().to_string())
        .arg("120")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "cyclone_foreign.py failed: {}\n{}",
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_theta(&v, &graph[2], &offline, records.len());
}
