//! The independent Python readers' check of a bag (rosbags, mcap + mcap-ros2-support).

use std::path::Path;

/// Checks `bag` with the independent readers: runs `io/tests/python/bag_check.py` (rosbags with an
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
    // io/tests/python, whichever crate's tests include this file.
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../io/tests/python/bag_check.py");
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
