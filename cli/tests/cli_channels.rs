//! `forcemap identify/diagnose BAG --channels MAP`: a bag read through a channel map gives
//! the theta of forcemap's own reading of the same run; bad maps fail with the topic and field
//! named and a non-zero exit. The bag is the committed rig bag read through a map of its own
//! fields (no Python needed); io/tests/foreign_bag.rs covers bags written by an independent
//! writer with standard and custom message types. A bench's bag as `ros2 bag record` makes it
//! (every log time a receive time; a topic without a header; labels once per step; pauses
//! between steps) is written by Python rosbags (`$FORCEMAP_PYTHON`) from the same run's CSV.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use common::{forcemap, identified_values, stderr};

use std::path::{Path, PathBuf};

fn rig_bag() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../bags/rig_40db")
}

const MAP: &str = "channels:
  base_displacement_m: {topic: /rig/samples, field: base_displacement_m}
  relative_displacement_m: {topic: /rig/samples, field: relative_displacement_m}
  mass_acceleration_mps2: {topic: /rig/samples, field: mass_acceleration_mps2}
  mass_displacement_m: {topic: /rig/samples, field: mass_displacement_m}
  base_acceleration_mps2: {topic: /rig/samples, field: base_acceleration_mps2}
  step: {topic: /rig/samples, field: step}
  frequency_hz: {topic: /rig/excitation, field: frequency_hz}
";

fn write_map(dir: &Path, text: &str) -> String {
    let p = dir.join("map.yaml");
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

#[test]
fn identify_through_a_channel_map_gives_the_bags_own_theta() {
    let dir = tempfile::tempdir().unwrap();
    let map = write_map(dir.path(), MAP);
    let own = identified_values(&rig_bag(), &["--model", "coulomb"]);
    // A foreign bag carries no constants: the mass comes from the flag.
    let mapped = identified_values(
        &rig_bag(),
        &["--model", "coulomb", "--mass-kg", "36", "--channels", &map],
    );
    assert_eq!(own.len(), 3);
    for (a, b) in own.iter().zip(&mapped) {
        assert!((a - b).abs() <= 1e-6 * a.abs(), "{own:?} vs {mapped:?}");
    }
}

#[test]
fn diagnose_through_a_channel_map_runs() {
    let dir = tempfile::tempdir().unwrap();
    let map = write_map(dir.path(), MAP);
    let bag = rig_bag().display().to_string();
    let o = forcemap(&[
        "diagnose",
        &bag,
        "--model",
        "linear",
        "--mass-kg",
        "36",
        "--channels",
        &map,
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v.is_object(), "{v}");
}

#[test]
fn bad_maps_name_topic_and_field_and_fail() {
    let dir = tempfile::tempdir().unwrap();
    let bag = rig_bag().display().to_string();
    for (text, expected) in [
        (
            MAP.replace(
                "{topic: /rig/samples, field: step}",
                "{topic: /rig/steps, field: step}",
            ),
            "topic /rig/steps (for step) is not in the bag",
        ),
        (
            MAP.replace("field: mass_acceleration_mps2}", "field: mass_accel}"),
            "topic /rig/samples, field mass_accel (for mass_acceleration_mps2): forcemap_msgs/msg/RigSample has no field 'mass_accel'",
        ),
        (
            MAP.replace("field: base_displacement_m}", "field: header.frame_id}"),
            "field header.frame_id (for base_displacement_m): field 'header.frame_id' is a string, not a number",
        ),
        (
            MAP.replace("  step: {topic: /rig/samples, field: step}\n", ""),
            "the channel map gives no step (map both step and frequency_hz",
        ),
    ] {
        let map = write_map(dir.path(), &text);
        let o = forcemap(&[
            "identify",
            &bag,
            "--model",
            "coulomb",
            "--mass-kg",
            "36",
            "--channels",
            &map,
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && err.contains(expected),
            "{text}\n-> {err}"
        );
    }
}

/// `forcemap simulate --system rig --snr-db 40 --seed 1 --csv` (and `extra` flags) into `dir`.
fn rig_csv(dir: &Path, extra: &[&str]) -> PathBuf {
    let csv = dir.join("run.csv");
    let mut args = vec![
        "simulate",
        "--system",
        "rig",
        "--snr-db",
        "40",
        "--seed",
        "1",
        "--csv",
        csv.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = forcemap(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    csv
}

/// io/tests/python/bench_bag.py: the run of `csv` as a bench's bag recorded by `ros2 bag
/// record` (rosbags), its steps `pause_s` apart; `None` (with a message) without
/// `FORCEMAP_PYTHON`.
fn bench_bag(dir: &Path, csv: &Path, pause_s: f64) -> Option<PathBuf> {
    let Ok(python) = std::env::var("FORCEMAP_PYTHON") else {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI is set but FORCEMAP_PYTHON is not: the rosbags writer did not run"
        );
        println!("skipped: set FORCEMAP_PYTHON to a python with rosbags");
        return None;
    };
    let bag = dir.join(format!("bench_{pause_s}"));
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../io/tests/python/bench_bag.py");
    let o = std::process::Command::new(python)
        .arg(&script)
        .arg(csv)
        .arg(&bag)
        .arg(pause_s.to_string())
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "bench_bag.py failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    Some(bag)
}

/// The bench's map: joints by name (stamped), the accelerations from a headerless
/// `Float64MultiArray`, the labels from headerless `UInt32` / `Float64` topics.
const BENCH_MAP: &str = "channels:
  base_displacement_m: {topic: /bench/joints, field: 'position[base]'}
  relative_displacement_m: {topic: /bench/joints, field: 'position[stroke]'}
  mass_displacement_m: {topic: /bench/joints, field: 'position[body]'}
  mass_acceleration_mps2: {topic: /bench/actuator, field: 'data[0]'}
  base_acceleration_mps2: {topic: /bench/actuator, field: 'data[1]'}
  step: {topic: /bench/step, field: data}
  frequency_hz: {topic: /bench/frequency, field: data}
";

const COULOMB_36: [&str; 4] = ["--model", "coulomb", "--mass-kg", "36"];

fn largest_relative_difference(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| ((x - y) / y).abs())
        .fold(0.0, f64::max)
}

/// Every log time a receive time (1.2-2.6 ms after the stamp by topic, +-0.5 ms), the
/// accelerations on a topic without a header, the labels once per step: the theta of the
/// run's CSV (the headerless messages and the labels each on their own sample).
#[test]
fn a_bench_bag_of_receive_times_gives_its_csvs_theta() {
    let dir = tempfile::tempdir().unwrap();
    let csv = rig_csv(dir.path(), &[]);
    let Some(bag) = bench_bag(dir.path(), &csv, 0.0) else {
        return;
    };
    let map = write_map(dir.path(), BENCH_MAP);
    let own = identified_values(&csv, &COULOMB_36);
    let mut args = COULOMB_36.to_vec();
    args.extend(["--channels", &map]);
    let mapped = identified_values(&bag, &args);
    let d = largest_relative_difference(&mapped, &own);
    println!("csv {own:?}\nbag {mapped:?}\nlargest relative difference {d:e}");
    assert!(d <= 1e-6, "{d}");
}

/// The bench pauses 0.5 s between steps (identification steps only): labelled, the theta of
/// the CSV without pauses; without the labels (a run cut at its pauses, each part cut where its
/// drive changes), every parameter within 1 % of the truth (k 6380 N/m, c 184 N s/m, fd 12.3 N).
#[test]
fn a_bench_bag_pausing_between_steps_reads_labelled_or_not() {
    let dir = tempfile::tempdir().unwrap();
    let csv = rig_csv(dir.path(), &["--no-random"]);
    let Some(bag) = bench_bag(dir.path(), &csv, 0.5) else {
        return;
    };
    let own = identified_values(&csv, &COULOMB_36);
    let labelled = write_map(dir.path(), BENCH_MAP);
    let mut args = COULOMB_36.to_vec();
    args.extend(["--channels", &labelled]);
    let mapped = identified_values(&bag, &args);
    let d = largest_relative_difference(&mapped, &own);
    println!("csv {own:?}\nbag with pauses {mapped:?}\nlargest relative difference {d:e}");
    assert!(d <= 1e-6, "{d}");

    let unlabelled = dir.path().join("unlabelled.yaml");
    let text: String = BENCH_MAP
        .lines()
        .filter(|l| !l.contains("step:") && !l.contains("frequency_hz:"))
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(&unlabelled, text).unwrap();
    let mut args = COULOMB_36.to_vec();
    args.extend(["--channels", unlabelled.to_str().unwrap()]);
    let found = identified_values(&bag, &args);
    let truth = [6380.0, 184.0, 12.3];
    let d = largest_relative_difference(&found, &truth);
    println!(
        "unlabelled bag with pauses {found:?}: largest relative difference {d:e} from the truth"
    );
    assert!(d < 0.01, "{d}");
}
