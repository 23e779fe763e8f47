//! ROS 2's default middleware in the forcemap graph: an eProsima Fast DDS 2.9 participant
//! (tests/fastdds/fastdds_peer.cpp, set up as rmw_fastrtps_cpp sets up a node's entities)
//! publishes a bag's rig samples and excitation states into forcemap's harmonic node and
//! identifier and receives theta; the theta equals `forcemap identify` on the same bag. Then a
//! late joiner (reliable, transient local, keep last 1, as a control node subscribes) receives
//! exactly one theta, the latest, and so does one with keep last 100 (which would keep any
//! older theta the identifier's writer still offered).
//!
//! Runs when Fast DDS, fastddsgen and g++ are installed (.ci/run installs them); under CI
//! without them the test fails rather than skip.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;
#[path = "fastdds/peer.rs"]
mod peer;

use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;
use std::time::Duration;

use common::*;
use forcemap_msgs::RosMessage;
use forcemap_msgs::msg::{ExcitationState, RigSample};

/// The bag's excitation states and samples in order, one tab-separated line each, as the peer
/// reads them (floats in Rust's shortest round-trip form, so the peer sends the same bits).
fn messages_tsv(bag: &Path) -> String {
    let reader = forcemap_io::bag::BagReader::open(bag).unwrap();
    let mut out = String::new();
    for m in reader
        .messages_on(&["/rig/excitation", "/rig/samples"])
        .unwrap()
    {
        let m = m.unwrap();
        if m.topic.name == "/rig/samples" {
            let s = RigSample::from_cdr(&m.data).unwrap();
            let h = &s.header;
            writeln!(
                out,
                "S\t{}\t{}\t{}\t{}\t{}\t{:?}\t{:?}\t{:?}\t{:?}\t{:?}\t{:?}\t{:?}",
                h.stamp.sec,
                h.stamp.nanosec,
                h.frame_id,
                s.step,
                s.present_channels,
                s.base_displacement_m,
                s.relative_displacement_m,
                s.mass_acceleration_mps2,
                s.mass_displacement_m,
                s.base_acceleration_mps2,
                s.force_n,
                s.drive_point_displacement_m
            )
            .unwrap();
        } else {
            let e = ExcitationState::from_cdr(&m.data).unwrap();
            let h = &e.header;
            writeln!(
                out,
                "E\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{:?}\t{:?}\t{:?}\t{:?}\t{}",
                h.stamp.sec,
                h.stamp.nanosec,
                h.frame_id,
                e.step,
                e.start_time.sec,
                e.start_time.nanosec,
                e.kind,
                e.driven_channel,
                e.frequency_hz,
                e.amplitude,
                e.band_low_hz,
                e.band_high_hz,
                e.sample_count
            )
            .unwrap();
        }
    }
    out
}

/// The peer's JSON lines (one per theta received).
fn theta_lines(stdout: &[u8]) -> Vec<serde_json::Value> {
    String::from_utf8_lossy(stdout)
        .lines()
        .filter(|l| l.starts_with('{'))
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

fn steps_used(v: &serde_json::Value) -> Vec<u64> {
    v["steps_used"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s.as_u64().unwrap())
        .collect()
}

/// What Fast DDS 2.9 prints when its own statistics bookkeeping aborts the peer: a send to a
/// remote locator its transport has not registered yet (a race with discovery, assertions on in
/// Debian's build; eProsima/Fast-DDS#3285, the race #3169 fixed upstream). Seen in 2 of 3 CI
/// runs on a machine loaded by three other builds (once in both tries of one run, each within
/// 0.2 s of the peer's start), never in 8 runs of the test alone. Such a run says nothing about
/// forcemap: the scenario runs again, up to five tries.
const FASTDDS_STATISTICS_ABORT: &str = "OutputTrafficManager::set_statistics_message_data";

/// The peer's output; `None` when Fast DDS aborted itself as [`FASTDDS_STATISTICS_ABORT`]
/// says; any other failure fails the test.
fn run_peer(exe: &Path, args: &[String]) -> Option<std::process::Output> {
    let out = Command::new(exe).args(args).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    if !out.status.success() && stderr.contains(FASTDDS_STATISTICS_ABORT) {
        eprintln!("fastdds_peer {args:?}: Fast DDS aborted in its statistics module: {stderr}");
        return None;
    }
    assert!(
        out.status.success(),
        "fastdds_peer {args:?} failed: {stderr}\n{}",
        String::from_utf8_lossy(&out.stdout)
    );
    Some(out)
}

#[test]
fn fast_dds_publishes_samples_receives_the_offline_theta_and_a_late_joiner_only_the_latest() {
    let Some(exe) = peer::fastdds_peer() else {
        return;
    };
    // Another try on a domain of its own, after a pause, only when Fast DDS aborted itself.
    let tries = [domain(20), domain(22), domain(23), domain(24), domain(25)];
    let completed = tries.iter().enumerate().any(|(i, &d)| {
        if i > 0 {
            std::thread::sleep(Duration::from_secs(2));
        }
        offline_theta_live_and_only_the_latest_to_a_late_joiner(&exe, d).is_some()
    });
    assert!(
        completed,
        "Fast DDS aborted itself in all {} tries",
        tries.len()
    );
}

/// The scenario of the test on domain `d`; `None` when the Fast DDS peer aborted itself.
fn offline_theta_live_and_only_the_latest_to_a_late_joiner(exe: &Path, d: u16) -> Option<()> {
    let bag = repo().join("bags/rig_40db");
    let dir = tempfile::tempdir().unwrap();
    let messages = dir.path().join("messages.tsv");
    std::fs::write(&messages, messages_tsv(&bag)).unwrap();

    let harmonic = NodeProcess::start("harmonic", d, &[]);
    let _identifier = NodeProcess::start(
        "identifier",
        d,
        &["model:=coulomb".into(), "mass_kg:=36.0".into()],
    );
    harmonic.wait_for("waiting for samples", Duration::from_secs(30));
    let out = run_peer(
        exe,
        &[
            "publish".into(),
            d.to_string(),
            messages.display().to_string(),
            "10".into(),
            "90".into(),
        ],
    )?;
    let thetas = theta_lines(&out.stdout);
    let last = thetas.last().expect("no theta received");
    assert_eq!(steps_used(last).len(), 10, "{last}");
    let live: Theta = last["names"]
        .as_array()
        .unwrap()
        .iter()
        .zip(last["values"].as_array().unwrap())
        .map(|(n, x)| (n.as_str().unwrap().to_string(), x.as_f64().unwrap()))
        .collect();
    let offline = offline_theta(&bag, &["--model", "coulomb"]);
    assert_same_theta(&live, &offline, 1e-9);

    // The identifier has published ten thetas (one per step); a control node joining now must
    // get only the tenth, whatever its reader's depth: the writer's history is one deep.
    let out = run_peer(exe, &["late".into(), d.to_string(), "3".into()])?;
    let late = theta_lines(&out.stdout);
    for reader in ["keep_last_1", "keep_last_100"] {
        let got: Vec<(Vec<u64>, &serde_json::Value)> = late
            .iter()
            .filter(|v| v["reader"] == reader)
            .map(|v| (steps_used(v), &v["values"]))
            .collect();
        assert_eq!(
            got,
            vec![(steps_used(last), &last["values"])],
            "{reader}: the late joiner must receive exactly one theta, the latest (steps used and values of each theta received)"
        );
    }
    Some(())
}
