//! Helpers shared by the integration tests. Each test crate uses some of them.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

/// Runs the `forcemap` binary of this build.
pub fn forcemap(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_forcemap"))
        .args(args)
        .output()
        .expect("forcemap runs")
}

/// `forcemap identify DATA ARGS... --json`: the identified parameter values, in model order.
pub fn identified_values(data: &Path, args: &[&str]) -> Vec<f64> {
    let mut all = vec!["identify", data.to_str().unwrap(), "--json"];
    all.extend_from_slice(args);
    let o = forcemap(&all);
    assert!(
        o.status.success(),
        "{}: {}",
        data.display(),
        String::from_utf8_lossy(&o.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    v["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["value"].as_f64().unwrap())
        .collect()
}

/// Checks `bag` with the independent readers: runs `tests/python/bag_check.py` (rosbags with an
/// empty type store, and mcap + mcap-ros2-support) with `$FORCEMAP_PYTHON`, against `expected`,
/// a JSON list of `{"topic", "log_time", "fields": {name: number}}` in log-time order. Without
/// `FORCEMAP_PYTHON` it says that it skipped; under CI (which installs the readers) that fails.
pub fn python_bag_check(bag: &Path, expected: &serde_json::Value) {
    let Ok(python) = std::env::var("FORCEMAP_PYTHON") else {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI is set but FORCEMAP_PYTHON is not: the independent readers did not run"
        );
        println!(
            "skipped: set FORCEMAP_PYTHON to a python with rosbags, mcap and mcap-ros2-support"
        );
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let json = tmp.path().join("expected.json");
    std::fs::write(&json, expected.to_string()).unwrap();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/bag_check.py");
    let out = std::process::Command::new(python)
        .arg(&script)
        .arg(bag)
        .arg(&json)
        .output()
        .unwrap();
    println!("{}", String::from_utf8_lossy(&out.stdout));
    assert!(
        out.status.success(),
        "bag_check.py failed on {}:\n{}\n{}",
        bag.display(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}
