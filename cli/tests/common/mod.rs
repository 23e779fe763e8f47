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

/// A command's stderr as text (for assertion messages and error checks).
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
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

/// The value of parameter `name` in a `--json` list of named parameters (`identify`'s
/// `parameters`, a diagnosis candidate's `refitted_baseline` or `added_parameters`).
pub fn parameter_value(list: &serde_json::Value, name: &str) -> f64 {
    list.as_array()
        .unwrap_or_else(|| panic!("not a list of parameters: {list}"))
        .iter()
        .find(|p| p["name"] == name)
        .unwrap_or_else(|| panic!("no {name}: {list}"))["value"]
        .as_f64()
        .unwrap()
}

/// The check of a bag by the independent Python readers, shared with forcemap_io's tests.
#[path = "../../../io/tests/common/python.rs"]
mod python;
#[allow(unused_imports)]
pub use python::python_bag_check;
