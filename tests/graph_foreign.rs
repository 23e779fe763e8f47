//! Foreign topics, live: a Python Cyclone DDS participant publishes the committed rig run on a
//! bench's own standard topics (sensor_msgs/JointState with one joint per channel, and
//! geometry_msgs/WrenchStamped carrying the mass acceleration, halved, undone by the map's
//! scale), stamped with the samples' times, with no forcemap message and no excitation state.
//! forcemap's foreign node (through a channel map), the harmonic node finding the steps itself
//! and the identifier run as processes; the theta the Python participant receives equals
//! `forcemap identify` on the same run's bag.
//!
//! Runs when FORCEMAP_PYTHON names a Python with `cyclonedds` (skipped with a message
//! otherwise, failed under CI).
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use std::process::Command;
use std::time::Duration;

use common::*;
use forcemap_math::record::Channel;
use forcemap_msgs::RosMessage;
use forcemap_msgs::msg::RigSample;

#[test]
fn cyclone_dds_on_standard_topics_gives_the_offline_theta() {
    let Some(py) = python_with_cyclonedds() else {
        return;
    };
    let d = domain(41);
    let bag = repo().join("bags/rig_40db");
    let dir = tempfile::tempdir().unwrap();
    // The bag's samples as the bench would have them: time and a value per channel.
    let reader = forcemap_io::bag::BagReader::open(&bag).unwrap();
    let mut samples = Vec::new();
    let mut present: Vec<Channel> = Vec::new();
    for m in reader.messages_on(&["/rig/samples"]).unwrap() {
        let s = RigSample::from_cdr(&m.unwrap().data).unwrap();
        if present.is_empty() {
            present = s.present();
        }
        let values: serde_json::Map<String, serde_json::Value> = present
            .iter()
            .map(|c| (c.name().to_string(), s.channel(*c).unwrap().into()))
            .collect();
        samples.push(serde_json::json!([
            s.header.stamp.sec,
            s.header.stamp.nanosec,
            values
        ]));
    }
    let load = Channel::MassAccelerationMps2;
    assert!(present.contains(&load), "{present:?}");
    let joints: Vec<&str> = present
        .iter()
        .filter(|c| **c != load)
        .map(|c| c.name())
        .collect();
    let run = dir.path().join("samples.json");
    std::fs::write(
        &run,
        serde_json::json!({"joints": joints, "load": load.name(), "samples": samples}).to_string(),
    )
    .unwrap();
    // The channel map: each joint by name, the load cell's z force scaled back.
    let mut map = String::from("channels:\n");
    for j in &joints {
        map.push_str(&format!(
            "  {j}: {{topic: /bench/joints, type: sensor_msgs/msg/JointState, field: 'position[{j}]'}}\n"
        ));
    }
    map.push_str(&format!(
        "  {}: {{topic: /bench/load, type: geometry_msgs/msg/WrenchStamped, field: wrench.force.z, scale: 2.0}}\n",
        load.name()
    ));
    let map_file = dir.path().join("bench.channels.yaml");
    std::fs::write(&map_file, map).unwrap();

    let harmonic = NodeProcess::start("harmonic", d, &["find_steps:=true".into()]);
    let _identifier = NodeProcess::start(
        "identifier",
        d,
        &["model:=coulomb".into(), "mass_kg:=36.0".into()],
    );
    let foreign = NodeProcess::start("foreign", d, &[format!("channels:={}", map_file.display())]);
    harmonic.wait_for("waiting for samples", Duration::from_secs(30));
    foreign.wait_for("publishing aligned samples", Duration::from_secs(30));
    let out = Command::new(&py)
        .arg(repo().join("tests/python/cyclone_foreign.py"))
        .arg(d.to_string())
        .arg(&run)
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
    assert_eq!(v["steps_used"].as_array().unwrap().len(), 10, "{v}");
    let live: Vec<(String, f64)> = v["names"]
        .as_array()
        .unwrap()
        .iter()
        .zip(v["values"].as_array().unwrap())
        .map(|(n, x)| (n.as_str().unwrap().to_string(), x.as_f64().unwrap()))
        .collect();
    let offline = offline_theta(&bag, &["--model", "coulomb"]);
    let worst = live
        .iter()
        .zip(&offline)
        .map(|((_, a), (_, b))| (a - b).abs() / b.abs())
        .fold(0.0f64, f64::max);
    eprintln!("live {live:?}\noffline {offline:?}\nlargest relative difference {worst:e}");
    assert_same_theta(&live, &offline, 1e-6);
    // Nothing was skipped on the way.
    let lines = foreign.lines();
    assert!(
        !lines.iter().any(|l| l.contains("warning")),
        "{}",
        lines.join("\n")
    );
}
