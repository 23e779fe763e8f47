//! Helpers of the graph tests: nodes as real processes talking DDS over loopback, each test on
//! its own ROS_DOMAIN_ID so that tests running side by side never hear each other.
#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

pub fn forcemap() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_forcemap"))
}

pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// A node process with its output collected line by line.
pub struct NodeProcess {
    pub name: String,
    child: Child,
    lines: Arc<Mutex<Vec<String>>>,
}

impl NodeProcess {
    /// `forcemap node KIND --ros-args -r __ns:=/rig -p ...` on `domain`.
    pub fn start(kind: &str, domain: u16, params: &[String]) -> NodeProcess {
        Self::start_in(None, kind, domain, params)
    }

    /// [`NodeProcess::start`] inside the network namespace `netns` (`ip netns exec`), as on
    /// another host.
    pub fn start_in(
        netns: Option<&str>,
        kind: &str,
        domain: u16,
        params: &[String],
    ) -> NodeProcess {
        let mut args = vec![
            "node".to_string(),
            kind.to_string(),
            "--ros-args".into(),
            "-r".into(),
            "__ns:=/rig".into(),
        ];
        for p in params {
            if p.starts_with("--params-file=") {
                args.push("--params-file".into());
                args.push(p.trim_start_matches("--params-file=").to_string());
            } else {
                args.push("-p".into());
                args.push(p.clone());
            }
        }
        let mut command = match netns {
            Some(ns) => {
                let mut c = Command::new("ip");
                c.args(["netns", "exec", ns]).arg(forcemap());
                c
            }
            None => Command::new(forcemap()),
        };
        let mut child = command
            .args(&args)
            .env("ROS_DOMAIN_ID", domain.to_string())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .stdin(Stdio::null())
            .spawn()
            .expect("start a node");
        let lines = Arc::new(Mutex::new(Vec::new()));
        for out in [
            Box::new(child.stdout.take().unwrap()) as Box<dyn std::io::Read + Send>,
            Box::new(child.stderr.take().unwrap()),
        ] {
            let l = lines.clone();
            let tag = kind.to_string();
            std::thread::spawn(move || {
                for line in BufReader::new(out).lines().map_while(Result::ok) {
                    eprintln!("[{tag}] {line}");
                    l.lock().unwrap().push(line);
                }
            });
        }
        NodeProcess {
            name: kind.to_string(),
            child,
            lines,
        }
    }

    pub fn lines(&self) -> Vec<String> {
        self.lines.lock().unwrap().clone()
    }

    /// Waits for an output line containing `needle`; panics with the output after `timeout`.
    pub fn wait_for(&self, needle: &str, timeout: Duration) -> String {
        let t0 = Instant::now();
        loop {
            if let Some(l) = self.lines().into_iter().find(|l| l.contains(needle)) {
                return l;
            }
            assert!(
                t0.elapsed() < timeout,
                "{}: no line with '{needle}' within {timeout:?}; output:\n{}",
                self.name,
                self.lines().join("\n")
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Waits for the process to end by itself.
    pub fn wait_exit(&mut self, timeout: Duration) -> std::process::ExitStatus {
        let t0 = Instant::now();
        loop {
            if let Some(s) = self.child.try_wait().unwrap() {
                return s;
            }
            assert!(
                t0.elapsed() < timeout,
                "{} did not end within {timeout:?}; output:\n{}",
                self.name,
                self.lines().join("\n")
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    pub fn signal(&self, sig: &str) {
        let ok = Command::new("kill")
            .arg(format!("-{sig}"))
            .arg(self.child.id().to_string())
            .status()
            .unwrap()
            .success();
        assert!(ok, "kill -{sig} {}", self.name);
    }

    /// SIGINT and wait: the clean stop.
    pub fn stop(&mut self) -> std::process::ExitStatus {
        self.signal("INT");
        self.wait_exit(Duration::from_secs(15))
    }
}

impl Drop for NodeProcess {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A sensor node playing `bag` at `rate_factor` (0: as fast as the subscribers acknowledge),
/// the source of most graph tests; one place for the parameters it needs.
pub fn play_bag(domain: u16, bag: &Path, rate_factor: f64) -> NodeProcess {
    NodeProcess::start(
        "sensor",
        domain,
        &[
            "source:=bag".into(),
            format!("bag:={}", bag.display()),
            format!("rate_factor:={rate_factor:?}"),
        ],
    )
}

/// Parameter names and values.
pub type Theta = Vec<(String, f64)>;

/// Theta of `forcemap identify BAG --json` as (name, value).
pub fn offline_theta(bag: &Path, extra: &[&str]) -> Theta {
    theta_of_json(&offline_json(bag, extra))
}

/// What `forcemap identify BAG --json` prints.
pub fn offline_json(bag: &Path, extra: &[&str]) -> serde_json::Value {
    let out = Command::new(forcemap())
        .arg("identify")
        .arg(bag)
        .args(extra)
        .arg("--json")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "identify failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// `parameters: [{name, value}, ...]`, as `forcemap identify --json` and the monitor's summary
/// both write it.
pub fn theta_of_json(v: &serde_json::Value) -> Theta {
    parameter_field_of_json(v, "value")
}

/// Each parameter's standard deviation, `parameters: [{name, std}, ...]`, as `forcemap identify
/// --json` and the monitor's summary both write it.
pub fn stds_of_json(v: &serde_json::Value) -> Theta {
    parameter_field_of_json(v, "std")
}

/// One numeric field of each entry of `parameters: [{name, ...}, ...]`, by parameter name.
fn parameter_field_of_json(v: &serde_json::Value, field: &str) -> Theta {
    v["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            (
                p["name"].as_str().unwrap().to_string(),
                p[field].as_f64().unwrap(),
            )
        })
        .collect()
}

/// Theta from a monitor's summary JSON.
pub fn summary_theta(path: &Path) -> Theta {
    theta_of_json(&summary_json(path))
}

/// A monitor's summary JSON.
pub fn summary_json(path: &Path) -> serde_json::Value {
    let text =
        std::fs::read_to_string(path).unwrap_or_else(|e| panic!("reading {}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

/// Asserts that two thetas name the same parameters and agree to `rel` relative difference.
pub fn assert_same_theta(live: &[(String, f64)], offline: &[(String, f64)], rel: f64) {
    assert_eq!(
        live.iter().map(|p| &p.0).collect::<Vec<_>>(),
        offline.iter().map(|p| &p.0).collect::<Vec<_>>()
    );
    for ((n, a), (_, b)) in live.iter().zip(offline) {
        let d = (a - b).abs() / b.abs().max(f64::MIN_POSITIVE);
        assert!(
            d < rel,
            "{n}: live {a} vs offline {b} (relative difference {d:e})"
        );
    }
}

/// A domain id per test, away from 0 (the default a developer's other ROS graph may use).
pub fn domain(offset: u16) -> u16 {
    let base: u16 = std::env::var("FORCEMAP_TEST_DOMAIN_BASE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(140);
    base + offset
}

/// The Python of FORCEMAP_PYTHON if it has `cyclonedds`; `None` (the test skips, saying so)
/// otherwise, except under CI, where .ci/run must provide it.
pub fn python_with_cyclonedds() -> Option<String> {
    let py = std::env::var("FORCEMAP_PYTHON").ok();
    let usable = py.as_ref().is_some_and(|p| {
        Command::new(p)
            .args(["-c", "import cyclonedds.domain"])
            .status()
            .is_ok_and(|s| s.success())
    });
    if !usable {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI is set but FORCEMAP_PYTHON ({py:?}) has no cyclonedds: .ci/run must install it"
        );
        eprintln!("skipped: set FORCEMAP_PYTHON to a Python with cyclonedds to run this test");
        return None;
    }
    py
}
