//! A third-party DDS: Python Cyclone DDS (PyPI `cyclonedds`, final types, XCDR1) feeds the rig
//! samples of a bag into forcemap's harmonic node and receives theta from forcemap's identifier.
//! The theta Cyclone receives equals `forcemap identify` on the same bag.
//!
//! Runs when FORCEMAP_PYTHON names a Python with `cyclonedds` (.ci/run installs it); under CI
//! without it the test fails rather than skip.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use std::process::Command;
use std::time::Duration;

use common::*;
use forcemap_msgs::RosMessage;
use forcemap_msgs::msg::{ExcitationState, RigSample};

#[test]
fn cyclone_dds_publishes_samples_and_receives_the_offline_theta() {
    let Some(py) = python_with_cyclonedds() else {
        return;
    };
    let d = domain(4);
    let bag = repo().join("bags/rig_40db");
    let dir = tempfile::tempdir().unwrap();
    // The bag's excitation states and samples, in order, for the Cyclone publisher.
    let reader = forcemap_io::bag::BagReader::open(&bag).unwrap();
    let mut list = Vec::new();
    for m in reader
        .messages_on(&["/rig/excitation", "/rig/samples"])
        .unwrap()
    {
        let m = m.unwrap();
        let (topic, msg) = if m.topic.name == "/rig/samples" {
            (
                "samples",
                serde_json::to_value(RigSample::from_cdr(&m.data).unwrap()),
            )
        } else {
            (
                "excitation",
                serde_json::to_value(ExcitationState::from_cdr(&m.data).unwrap()),
            )
        };
        list.push(serde_json::json!({"topic": topic, "msg": msg.unwrap()}));
    }
    let messages = dir.path().join("messages.json");
    std::fs::write(&messages, serde_json::to_string(&list).unwrap()).unwrap();

    let harmonic = NodeProcess::start("harmonic", d, &[]);
    let _identifier = NodeProcess::start(
        "identifier",
        d,
        &["model:=coulomb".into(), "mass_kg:=36.0".into()],
    );
    harmonic.wait_for("waiting for samples", Duration::from_secs(30));
    let out = Command::new(&py)
        .arg(repo().join("tests/python/cyclone_interop.py"))
        .arg(d.to_string())
        .arg(&messages)
        .arg("10")
        .arg("90")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "cyclone_interop.py failed: {}\n{}",
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
    assert_same_theta(&live, &offline, 1e-9);
}
