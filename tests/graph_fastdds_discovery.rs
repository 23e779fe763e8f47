//! Discovery between forcemap's nodes and ROS 2's default middleware, in both orders: an
//! eProsima Fast DDS 2.9 participant (tests/fastdds/fastdds_peer.cpp, `discover`) started
//! before the six nodes of the main job and another started after them must each discover
//! every endpoint of every node: what ros2-client creates for every node (ros_discovery_info,
//! rt/parameter_events, rt/rosout, rt/clock, the parameter services) and the node's own
//! topics, 126 endpoints in all. FORCEMAP_FASTDDS_DISCOVERY_RUNS runs (default 3; the
//! acceptance figure is 20, docs/graph.md).
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

use std::collections::{BTreeMap, BTreeSet};
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use common::*;

/// A `fastdds_peer discover` process and the lines it printed.
struct Observer {
    child: Child,
    lines: Arc<Mutex<Vec<String>>>,
}

impl Observer {
    fn start(exe: &Path, domain: u16) -> Observer {
        let mut child = Command::new(exe)
            .args(["discover", &domain.to_string()])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .unwrap();
        let lines = Arc::new(Mutex::new(Vec::new()));
        let out = child.stdout.take().unwrap();
        let l = lines.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines().map_while(Result::ok) {
                l.lock().unwrap().push(line);
            }
        });
        let o = Observer { child, lines };
        let t0 = Instant::now();
        while !o.lines.lock().unwrap().iter().any(|l| l == "ready") {
            assert!(t0.elapsed() < Duration::from_secs(30), "observer not ready");
            std::thread::sleep(Duration::from_millis(20));
        }
        o
    }

    /// Endpoints discovered, by participant: ("W"/"R", topic).
    fn endpoints(&self) -> BTreeMap<String, BTreeSet<(String, String)>> {
        let mut by = BTreeMap::<String, BTreeSet<(String, String)>>::new();
        for l in self.lines.lock().unwrap().iter() {
            let mut f = l.split(' ');
            if let (Some(kind @ ("W" | "R")), Some(prefix), Some(topic)) =
                (f.next(), f.next(), f.next())
            {
                by.entry(prefix.to_string())
                    .or_default()
                    .insert((kind.to_string(), topic.to_string()));
            }
        }
        by
    }
}

impl Drop for Observer {
    fn drop(&mut self) {
        drop(self.child.stdin.take());
        let _ = self.child.wait();
    }
}

fn set(list: &[(&str, &str)]) -> BTreeSet<(String, String)> {
    list.iter()
        .map(|(k, t)| ((*k).to_string(), (*t).to_string()))
        .collect()
}

/// What each node creates: what ros2-client gives every node (the `ros_discovery_info` reader
/// and writer, the `rt/parameter_events` and `rt/rosout` writers, the `rt/clock` reader and the
/// six parameter services, a request reader and a reply writer each), then the node's own
/// topics, as `nodes/src/node/*.rs` subscribes and publishes them in namespace /rig.
fn expected_endpoints() -> Vec<(&'static str, BTreeSet<(String, String)>)> {
    let node = |name: &str, own: &[(&str, &str)]| {
        let mut s = set(&[
            ("R", "ros_discovery_info"),
            ("W", "ros_discovery_info"),
            ("W", "rt/parameter_events"),
            ("W", "rt/rosout"),
            ("R", "rt/clock"),
        ]);
        for service in [
            "describe_parameters",
            "get_parameter_types",
            "get_parameters",
            "list_parameters",
            "set_parameters",
            "set_parameters_atomically",
        ] {
            s.insert(("R".into(), format!("rq/rig/{name}/{service}Request")));
            s.insert(("W".into(), format!("rr/rig/{name}/{service}Reply")));
        }
        s.extend(set(own));
        s
    };
    vec![
        (
            "sensor",
            node(
                "sensor",
                &[
                    ("W", "rt/rig/samples"),
                    ("W", "rt/rig/excitation"),
                    ("W", "rt/rig/parameters"),
                ],
            ),
        ),
        (
            "harmonic",
            node(
                "harmonic",
                &[
                    ("R", "rt/rig/samples"),
                    ("R", "rt/rig/excitation"),
                    ("W", "rt/rig/phasors"),
                    ("W", "rt/diagnostics"),
                ],
            ),
        ),
        (
            "identifier",
            node(
                "identifier",
                &[
                    ("R", "rt/rig/phasors"),
                    ("R", "rt/rig/phasors/provisional"),
                    ("R", "rt/rig/parameters"),
                    ("R", "rt/rig/excitation"),
                    ("W", "rt/rig/theta"),
                    ("W", "rt/diagnostics"),
                ],
            ),
        ),
        (
            "diagnoser",
            node(
                "diagnoser",
                &[
                    ("R", "rt/rig/phasors"),
                    ("R", "rt/rig/parameters"),
                    ("R", "rt/rig/excitation"),
                    ("W", "rt/rig/diagnosis"),
                    ("W", "rt/diagnostics"),
                ],
            ),
        ),
        (
            "recorder",
            node(
                "recorder",
                &[
                    ("R", "rt/rig/samples"),
                    ("R", "rt/rig/excitation"),
                    ("R", "rt/rig/parameters"),
                    ("R", "rt/rig/phasors"),
                    ("R", "rt/rig/theta"),
                    ("R", "rt/diagnostics"),
                ],
            ),
        ),
        (
            "monitor",
            node(
                "monitor",
                &[
                    ("R", "rt/rig/theta"),
                    ("R", "rt/rig/excitation"),
                    ("R", "rt/rig/parameters"),
                ],
            ),
        ),
    ]
}

/// The six nodes of the main job, idle: the sensor (playing the rig bag) waits for more
/// subscribers than there are. Returns once each has logged that its endpoints are up.
fn start_nodes(d: u16, out: &Path) -> Vec<NodeProcess> {
    let bag = repo().join("bags/rig_40db");
    let nodes = vec![
        NodeProcess::start(
            "sensor",
            d,
            &[
                "source:=bag".into(),
                format!("bag:={}", bag.display()),
                "min_subscribers:=99".into(),
                "startup_timeout_s:=600.0".into(),
            ],
        ),
        NodeProcess::start("harmonic", d, &[]),
        NodeProcess::start("identifier", d, &["model:=coulomb".into()]),
        NodeProcess::start("diagnoser", d, &["baseline:=linear".into()]),
        NodeProcess::start(
            "recorder",
            d,
            &[format!("bag:={}", out.join("bag").display())],
        ),
        NodeProcess::start(
            "monitor",
            d,
            &[format!(
                "summary_json:={}",
                out.join("summary.json").display()
            )],
        ),
    ];
    // The line each node logs after creating its subscriptions and publishers.
    let ready = [
        "waiting for 99 subscriber(s)",
        "waiting for samples",
        "identifying model",
        "diagnosing the gap",
        "recording",
        "watching",
    ];
    for (node, line) in nodes.iter().zip(ready) {
        node.wait_for(line, Duration::from_secs(60));
    }
    nodes
}

#[test]
fn fast_dds_started_before_or_after_the_nodes_discovers_every_endpoint() {
    let Some(exe) = peer::fastdds_peer() else {
        return;
    };
    let runs: usize = std::env::var("FORCEMAP_FASTDDS_DISCOVERY_RUNS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let d = domain(21);
    let nodes_expected = expected_endpoints();
    let expected: BTreeSet<Vec<(String, String)>> = nodes_expected
        .iter()
        .map(|(_, s)| s.iter().cloned().collect())
        .collect();
    let mut complete = [0usize; 2];
    for run in 0..runs {
        let dir = tempfile::tempdir().unwrap();
        let before = Observer::start(&exe, d);
        let nodes = start_nodes(d, dir.path());
        let after = Observer::start(&exe, d);
        // Wait until both observers see every endpoint, or 20 s: an endpoint Fast DDS missed
        // is not reported later, so the bound only ends a failing run.
        let t0 = Instant::now();
        let views = loop {
            let views = [before.endpoints(), after.endpoints()];
            let done = views.iter().all(|v| {
                let got: BTreeSet<Vec<(String, String)>> =
                    v.values().map(|s| s.iter().cloned().collect()).collect();
                v.len() >= 6 && expected.iter().all(|e| got.contains(e))
            });
            if done || t0.elapsed() > Duration::from_secs(20) {
                break views;
            }
            std::thread::sleep(Duration::from_millis(100));
        };
        for (i, v) in views.iter().enumerate() {
            let got: BTreeSet<&BTreeSet<(String, String)>> = v.values().collect();
            let missing: Vec<&str> = nodes_expected
                .iter()
                .filter(|(_, e)| !got.contains(e))
                .map(|(n, _)| *n)
                .collect();
            eprintln!(
                "run {run}: observer started {} the nodes: {} participants, {} endpoints; nodes not seen complete: {missing:?}",
                ["before", "after"][i],
                v.len(),
                v.values().map(BTreeSet::len).sum::<usize>(),
            );
        }
        drop(nodes);
        for (i, v) in views.iter().enumerate() {
            let got: BTreeSet<Vec<(String, String)>> =
                v.values().map(|s| s.iter().cloned().collect()).collect();
            if expected.iter().all(|e| got.contains(e)) {
                complete[i] += 1;
            }
        }
    }
    eprintln!(
        "every endpoint of every node discovered: started before the nodes {}/{runs} runs, after {}/{runs}",
        complete[0], complete[1]
    );
    assert_eq!(complete, [runs, runs], "runs complete (before, after)");
}
