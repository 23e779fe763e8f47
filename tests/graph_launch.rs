//! `forcemap launch` with the shipped launch files: the simulated rig end to end (the README's
//! main command), a clean stop of every node on Ctrl-C, and four rigs in one graph (the
//! four-poster launch).
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use common::*;

/// The launch's stdout lines as they arrive: a thread reads them (echoing each to stderr).
struct Lines {
    lines: Arc<Mutex<Vec<String>>>,
    reader: std::thread::JoinHandle<()>,
}

impl Lines {
    /// The lines read so far.
    fn so_far(&self) -> std::sync::MutexGuard<'_, Vec<String>> {
        self.lines.lock().unwrap()
    }

    /// Every line, read to the end of the output: call it once the launch has ended (when
    /// `wait` returns, the reader can still be behind by the last lines). A process that
    /// still held the output open would keep the reader waiting: after 10 s the lines so far.
    fn all(self) -> Vec<String> {
        let t0 = Instant::now();
        while !self.reader.is_finished() && t0.elapsed() < Duration::from_secs(10) {
            std::thread::sleep(Duration::from_millis(20));
        }
        if self.reader.is_finished() {
            self.reader.join().unwrap();
        }
        self.lines.lock().unwrap().clone()
    }
}

fn launch(domain_id: u16, args: &[String]) -> (std::process::Child, Lines) {
    launch_file("rig_sim.launch.yaml", domain_id, args)
}

fn launch_file(file: &str, domain_id: u16, args: &[String]) -> (std::process::Child, Lines) {
    let mut child = Command::new(forcemap())
        .arg("launch")
        .arg(repo().join("launch_configs").join(file))
        .args(args)
        .env("ROS_DOMAIN_ID", domain_id.to_string())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let lines = Arc::new(Mutex::new(Vec::new()));
    let l = lines.clone();
    let out = child.stdout.take().unwrap();
    let reader = std::thread::spawn(move || {
        for line in BufReader::new(out).lines().map_while(Result::ok) {
            eprintln!("{line}");
            l.lock().unwrap().push(line);
        }
    });
    (child, Lines { lines, reader })
}

#[test]
fn simulated_rig_runs_end_to_end_through_the_graph() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let (mut child, lines) = launch(
        domain(5),
        &[format!("out:={}", out.display()), "rate_factor:=0.0".into()],
    );
    let t0 = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(120),
            "launch did not end"
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(status.success());
    let lines = lines.all();
    for prefix in [
        "[sensor] ",
        "[harmonic] ",
        "[identifier] ",
        "[diagnoser] ",
        "[monitor] ",
        "[recorder] ",
    ] {
        assert!(
            lines.iter().any(|l| l.starts_with(prefix)),
            "no output from {prefix}"
        );
    }
    // The summary: theta within 1 % of the simulator's truth, all ten sine steps used.
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["steps_used"].as_array().unwrap().len(), 10);
    for p in summary["parameters"].as_array().unwrap() {
        let err = p["error_percent"].as_f64().unwrap();
        assert!(err.abs() < 1.0, "{p}");
    }
    // The recorded bag holds the run: 12 records (10 sine, 2 random) and the live theta, and
    // identifying it offline gives the live theta.
    let bag = out.join("bag");
    let run = forcemap_io::rig_bag::read_rig_bag(&bag).unwrap();
    assert_eq!(run.records.len(), 12);
    let info = forcemap_io::bag::BagReader::open(&bag).unwrap();
    assert_eq!(info.topic("/rig/theta").unwrap().message_count, 10);
    let live = summary_theta(&out.join("summary.json"));
    assert_same_theta(&live, &offline_theta(&bag, &["--model", "coulomb"]), 1e-9);
}

#[test]
fn ctrl_c_stops_every_node_cleanly_and_the_bag_is_finished() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    // Real time: the run would last over two minutes.
    let (mut child, lines) = launch(
        domain(6),
        &[format!("out:={}", out.display()), "rate_factor:=1.0".into()],
    );
    let t0 = Instant::now();
    while !lines
        .so_far()
        .iter()
        .any(|l| l.starts_with("[sensor] step 1:"))
    {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "the run did not start"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(
        Command::new("kill")
            .args(["-INT", &child.id().to_string()])
            .status()
            .unwrap()
            .success()
    );
    let t1 = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(
            t1.elapsed() < Duration::from_secs(20),
            "launch did not stop"
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(status.success(), "{status}");
    let lines = lines.all();
    assert!(
        lines
            .iter()
            .any(|l| l.contains("[launch] interrupted: stopping"))
    );
    for node in [
        "sensor",
        "harmonic",
        "identifier",
        "diagnoser",
        "monitor",
        "recorder",
    ] {
        assert!(
            lines
                .iter()
                .any(|l| l.starts_with(&format!("[launch] {node} exited (exit status: 0)"))),
            "{node} did not exit cleanly:\n{}",
            lines.join("\n")
        );
    }
    // The recorder finished its bag (renamed into place with its metadata).
    let bag = out.join("bag");
    assert!(bag.join("metadata.yaml").exists());
    // The step cut by Ctrl-C is left out with the reason; the complete ones are kept.
    let run = forcemap_io::rig_bag::read_rig_bag(&bag).unwrap();
    assert!(!run.records.is_empty());
    assert!(run.records.iter().all(|r| r.len() == 1300));
    if let Some(why) = &run.left_out {
        assert!(why.contains("the recording stopped"), "{why}");
    }
}

/// Bad settings stop a node before it joins the graph, with the parameter named.
#[test]
fn bad_node_settings_fail_fast_and_name_the_parameter() {
    let cases: [(&[&str], &str); 5] = [
        (
            &["identifier", "--ros-args", "-p", "method:=td"],
            "method = td",
        ),
        (&["identifier", "--ros-args", "-p", "model:=nope"], "nope"),
        (
            &["sensor", "--ros-args", "-p", "source:=bag"],
            "parameter bag",
        ),
        (
            &["sensor", "--ros-args", "-p", "rate_factor:=-1.0"],
            "rate_factor",
        ),
        (
            &["recorder", "--model", "x"],
            "unexpected argument '--model'",
        ),
    ];
    for (args, needle) in cases {
        let out = std::process::Command::new(forcemap())
            .arg("node")
            .args(args)
            .env("ROS_DOMAIN_ID", domain(7).to_string())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} should fail");
        assert!(err.contains(needle), "{args:?}: {err}");
    }
    let out = std::process::Command::new(forcemap())
        .args(["node", "sensor"])
        .env("ROS_DOMAIN_ID", "999")
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("ROS_DOMAIN_ID='999'"));
}

/// The four-poster: four corners in one graph, each identified from its own rig's samples
/// (each corner's own noise seed), none disturbed by the others; Ctrl-C then stops all 16
/// nodes cleanly.
#[test]
fn four_corners_in_one_graph_are_each_identified() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let (mut child, lines) = launch_file(
        "four_poster.launch.yaml",
        domain(13),
        &[format!("out:={}", out.display()), "rate_factor:=0.0".into()],
    );
    let corners = ["front_left", "front_right", "rear_left", "rear_right"];
    let t0 = Instant::now();
    while !corners
        .iter()
        .all(|c| out.join(c).join("summary.json").exists())
    {
        assert!(
            t0.elapsed() < Duration::from_secs(180),
            "not every corner's summary was written"
        );
        assert!(child.try_wait().unwrap().is_none(), "launch ended early");
        std::thread::sleep(Duration::from_millis(100));
    }
    let mut thetas = Vec::new();
    for c in corners {
        let summary: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(out.join(c).join("summary.json")).unwrap(),
        )
        .unwrap();
        assert_eq!(summary["steps_used"].as_array().unwrap().len(), 10, "{c}");
        for p in summary["parameters"].as_array().unwrap() {
            let err = p["error_percent"].as_f64().unwrap();
            assert!(err.abs() < 1.0, "{c}: {p}");
        }
        thetas.push(summary_theta(&out.join(c).join("summary.json")));
    }
    // Each corner saw its own noise: four different thetas, not one rig's four times.
    for i in 0..thetas.len() {
        for j in i + 1..thetas.len() {
            assert_ne!(thetas[i], thetas[j], "{} and {}", corners[i], corners[j]);
        }
    }
    assert!(
        Command::new("kill")
            .args(["-INT", &child.id().to_string()])
            .status()
            .unwrap()
            .success()
    );
    let status = child.wait().unwrap();
    assert!(status.success(), "{status}");
    let lines = lines.all();
    for c in corners {
        for kind in ["sensor", "harmonic", "identifier", "monitor"] {
            let label = format!("{c}/{kind}");
            assert!(
                lines
                    .iter()
                    .any(|l| l.starts_with(&format!("[launch] {label} exited (exit status: 0)"))),
                "{label} did not exit cleanly:\n{}",
                lines.join("\n")
            );
        }
    }
}
