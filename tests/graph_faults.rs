//! Faults in the real node graph: an identifier killed with SIGKILL in the middle of a run and
//! restarted ends with the theta of an undisturbed run; a recorder killed with SIGKILL leaves a
//! bag that `forcemap bag recover` restores with every message the recorder had put on disk; every
//! idle node stops cleanly on SIGTERM; a monitor and an identifier that join after a flooded
//! run was published still end it with its theta.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use std::process::Command;
use std::time::Duration;

use common::*;

#[test]
fn identifier_killed_mid_run_resumes_and_ends_with_the_undisturbed_theta() {
    let d = domain(2);
    let dir = tempfile::tempdir().unwrap();
    let state = dir.path().join("identifier_state.json");
    let summary = dir.path().join("summary.json");
    let bag = repo().join("bags/rig_40db");
    let id_params = vec![
        "model:=coulomb".to_string(),
        format!("state_file:={}", state.display()),
    ];
    let mut monitor = NodeProcess::start(
        "monitor",
        d,
        &[
            format!("summary_json:={}", summary.display()),
            "quiet_s:=3.0".into(),
            "timeout_s:=180.0".into(),
        ],
    );
    let _harmonic = NodeProcess::start("harmonic", d, &[]);
    let identifier = NodeProcess::start("identifier", d, &id_params);
    // 10x real time: a 13 s step every 1.3 s.
    let mut sensor = play_bag(d, &bag, 10.0);
    identifier.wait_for("step 2:", Duration::from_secs(60));
    identifier.signal("KILL");
    drop(identifier);
    // Steps go by while it is down; their phasors wait in the harmonic node's history.
    sensor.wait_for("step 6:", Duration::from_secs(60));
    let restarted = NodeProcess::start("identifier", d, &id_params);
    restarted.wait_for("resuming from", Duration::from_secs(30));
    assert!(sensor.wait_exit(Duration::from_secs(120)).success());
    assert!(monitor.wait_exit(Duration::from_secs(60)).success());

    let lines = restarted.lines();
    assert!(
        lines
            .iter()
            .any(|l| l.contains("already in the accumulated equations")),
        "the restarted identifier should have skipped the steps it had:\n{}",
        lines.join("\n")
    );
    let live = summary_theta(&summary);
    let undisturbed = offline_theta(&bag, &["--model", "coulomb"]);
    assert_same_theta(&live, &undisturbed, 1e-9);
}

#[test]
fn recorder_killed_leaves_a_bag_that_recover_restores() {
    let d = domain(3);
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("rec");
    let source = repo().join("bags/rig_40db");
    let recorder = NodeProcess::start(
        "recorder",
        d,
        &[
            format!("bag:={}", bag.display()),
            "log_flushes:=true".into(),
            "topics:=[samples, excitation, parameters]".into(),
        ],
    );
    recorder.wait_for("recording 3 topics", Duration::from_secs(30));
    let mut sensor = play_bag(d, &source, 10.0);
    sensor.wait_for("step 3:", Duration::from_secs(60));
    // Wait for a flush after step 3 began, then kill without warning.
    let n0 = recorder
        .lines()
        .iter()
        .filter(|l| l.contains("on disk:"))
        .count();
    let t0 = std::time::Instant::now();
    while recorder
        .lines()
        .iter()
        .filter(|l| l.contains("on disk:"))
        .count()
        < n0 + 2
    {
        assert!(t0.elapsed() < Duration::from_secs(10), "no flush logged");
        std::thread::sleep(Duration::from_millis(20));
    }
    recorder.signal("KILL");
    let on_disk: u64 = recorder
        .lines()
        .iter()
        .rev()
        .find_map(|l| l.strip_prefix("on disk: "))
        .and_then(|s| s.trim_end_matches(" messages").parse().ok())
        .expect("a flush count");
    drop(recorder);
    let _ = sensor.wait_exit(Duration::from_secs(60));

    // The bag never finished: only the partial directory exists.
    assert!(!bag.exists());
    let partial = dir.path().join(".rec.partial");
    assert!(
        partial.exists(),
        "the recorder's partial bag should be left behind"
    );
    let restored = dir.path().join("restored");
    let out = Command::new(forcemap())
        .args(["bag", "recover"])
        .arg(&partial)
        .arg(&restored)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "recover failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let info = Command::new(forcemap())
        .args(["bag", "info", "--json"])
        .arg(&restored)
        .output()
        .unwrap();
    assert!(info.status.success());
    let v: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    let total = v["messages"].as_u64().expect("messages");
    assert!(
        total >= on_disk,
        "recovered {total} messages, the recorder had {on_disk} on disk"
    );

    // Every recovered sample is the one the source bag holds at the same place.
    let orig = forcemap_io::rig_bag::read_rig_bag(&source).unwrap();
    let got = forcemap_io::bag::BagReader::open(&restored).unwrap();
    let mut n = 0usize;
    let samples: Vec<f64> = orig
        .records
        .iter()
        .flat_map(|r| {
            r.channel(forcemap_math::record::Channel::MassAccelerationMps2)
                .unwrap()
                .to_vec()
        })
        .collect();
    for m in got.messages_on(&["/rig/samples"]).unwrap() {
        let m = m.unwrap();
        use forcemap_msgs::RosMessage;
        let s = forcemap_msgs::msg::RigSample::from_cdr(&m.data).unwrap();
        assert_eq!(
            s.mass_acceleration_mps2.to_bits(),
            samples[n].to_bits(),
            "sample {n}"
        );
        n += 1;
    }
    assert!(n > 3 * 1300, "only {n} samples recovered");
}

/// Every node of the main job, idle (the sensor waits for more subscribers than there are),
/// stops by itself on SIGTERM, as the launcher and a process supervisor stop it: exit status 0,
/// not death by the signal and not the run_node grace period's error.
#[test]
fn every_idle_node_stops_cleanly_on_sigterm() {
    let d = domain(11);
    let dir = tempfile::tempdir().unwrap();
    let bag = repo().join("bags/rig_40db");
    let nodes = [
        (
            "sensor",
            vec![
                "source:=bag".to_string(),
                format!("bag:={}", bag.display()),
                "min_subscribers:=99".into(),
            ],
            "waiting for 99 subscriber(s)",
        ),
        ("harmonic", vec![], "waiting for samples"),
        (
            "identifier",
            vec!["model:=coulomb".into()],
            "identifying model",
        ),
        (
            "diagnoser",
            vec!["baseline:=linear".into()],
            "diagnosing the gap",
        ),
        (
            "recorder",
            vec![format!("bag:={}", dir.path().join("bag").display())],
            "recording",
        ),
        (
            "monitor",
            vec![format!(
                "summary_json:={}",
                dir.path().join("summary.json").display()
            )],
            "watching",
        ),
    ];
    let mut running: Vec<NodeProcess> = nodes
        .iter()
        .map(|(kind, params, _)| NodeProcess::start(kind, d, params))
        .collect();
    for (node, (_, _, ready)) in running.iter().zip(&nodes) {
        node.wait_for(ready, Duration::from_secs(60));
    }
    for node in &running {
        node.signal("TERM");
    }
    for node in &mut running {
        let status = node.wait_exit(Duration::from_secs(15));
        assert!(
            status.success(),
            "{} on SIGTERM: {status}; output:\n{}",
            node.name,
            node.lines().join("\n")
        );
    }
}

/// A run published as fast as the graph keeps up is over in a fraction of a second, which on a
/// loaded host is less than discovery takes. The sensor waits for every node that must see the
/// run end (`min_excitation_subscribers`), and a monitor that sees the run end before any
/// identifier is matched on theta waits for one rather than report no theta. CI's four-poster
/// lost a corner this way: its summary was never written.
#[test]
fn a_late_monitor_and_a_late_identifier_still_end_the_run_with_its_theta() {
    let d = domain(14);
    let dir = tempfile::tempdir().unwrap();
    let summary = dir.path().join("summary.json");
    let _harmonic = NodeProcess::start("harmonic", d, &[]);
    let mut sensor = NodeProcess::start(
        "sensor",
        d,
        &[
            "rate_factor:=0.0".into(),
            "min_excitation_subscribers:=2".into(),
            "startup_timeout_s:=120.0".into(),
        ],
    );
    sensor.wait_for(
        "waiting for 2 subscriber(s) on /rig/excitation",
        Duration::from_secs(60),
    );
    // The harmonic node alone is not enough: nothing is published without the monitor.
    std::thread::sleep(Duration::from_secs(2));
    let early = sensor.lines();
    assert!(
        !early.iter().any(|l| l.contains("publishing")),
        "the sensor published before the monitor listened:\n{}",
        early.join("\n")
    );
    let mut monitor = NodeProcess::start(
        "monitor",
        d,
        &[
            format!("summary_json:={}", summary.display()),
            "quiet_s:=2.0".into(),
            "timeout_s:=180.0".into(),
        ],
    );
    assert!(sensor.wait_exit(Duration::from_secs(60)).success());
    // The run is over and no identifier exists yet: the monitor waits for one.
    monitor.wait_for("no identifier is matched", Duration::from_secs(30));
    let params = format!(
        "--params-file={}",
        repo().join("launch_configs/rig.params.yaml").display()
    );
    let _identifier = NodeProcess::start("identifier", d, &[params, "model:=coulomb".into()]);
    assert!(monitor.wait_exit(Duration::from_secs(90)).success());
    let s = summary_json(&summary);
    assert_eq!(s["steps_used"].as_array().unwrap().len(), 10, "{s}");
    for p in s["parameters"].as_array().unwrap() {
        let err = p["error_percent"].as_f64().unwrap();
        assert!(err.abs() < 1.0, "{p}");
    }
}
