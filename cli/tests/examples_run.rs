//! The worked examples of `examples/` run as a new user runs them: each script by bash from the
//! repository's root, with this build's `forcemap` as `$FORCEMAP` and a scratch directory as its
//! argument, must exit 0. Each script checks its own key output (the parameters, the held-out
//! lines, the verdict, the tracked table) and exits non-zero when a line is missing, so this test
//! fails with the script's output when an example does not show what its README says.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .canonicalize()
        .unwrap()
}

/// Runs `examples/NAME` and asserts that it exits 0, printing its output either way.
fn run_example(name: &str) {
    let script = repo().join("examples").join(name);
    assert!(script.is_file(), "no example {}", script.display());
    let scratch = tempfile::tempdir().unwrap();
    let start = Instant::now();
    let o = Command::new("bash")
        .arg(&script)
        .arg(scratch.path())
        .current_dir(repo())
        .env("FORCEMAP", env!("CARGO_BIN_EXE_forcemap"))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    let stderr = String::from_utf8_lossy(&o.stderr);
    println!(
        "examples/{name}: {} in {:.1} s",
        o.status,
        start.elapsed().as_secs_f64()
    );
    assert!(
        o.status.success(),
        "examples/{name} failed ({})\n--- stdout\n{stdout}\n--- stderr\n{stderr}",
        o.status
    );
    let last = stdout.lines().last().unwrap_or_default();
    assert!(
        last.ends_with("all checks passed"),
        "examples/{name} ended without its checks: {last}\n--- stdout\n{stdout}"
    );
}

#[test]
fn simulated_rig() {
    run_example("simulated_rig.sh");
}

#[test]
fn damper_dyno_map() {
    run_example("damper_dyno_map.sh");
}

#[test]
fn real_damper() {
    run_example("real_damper.sh");
}

#[test]
fn tracking() {
    run_example("tracking.sh");
}

#[test]
fn friction_damper() {
    run_example("friction_damper.sh");
}

/// Every script of `examples/` is one of the tests above and is named in its README.
#[test]
fn every_example_is_run_and_described() {
    let tested = [
        "simulated_rig.sh",
        "damper_dyno_map.sh",
        "real_damper.sh",
        "tracking.sh",
        "friction_damper.sh",
    ];
    let readme = std::fs::read_to_string(repo().join("examples/README.md")).unwrap();
    for entry in std::fs::read_dir(repo().join("examples")).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        if name.ends_with(".sh") {
            assert!(
                tested.contains(&name.as_str()),
                "examples/{name} is not run by cli/tests/examples_run.rs"
            );
            assert!(
                readme.contains(&name),
                "examples/{name} is not described in examples/README.md"
            );
        }
    }
}
