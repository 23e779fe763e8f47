//! `forcemap identify/diagnose BAG --channels MAP`: a bag read through a channel map gives
//! the theta of forcemap's own reading of the same run; bad maps fail with the topic and field
//! named and a non-zero exit. The bag is the committed rig bag read through a map of its own
//! fields (no Python needed); io/tests/foreign_bag.rs covers bags written by an independent
//! writer with standard and custom message types.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use common::{forcemap, identified_values};

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
