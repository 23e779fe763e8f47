//! `forcemap identify` on element-test records with no steps to take phasors from: the
//! force-driven Duffing oscillator's one-period multisines (`RunSpec::shaker_duffing_one_period`)
//! through a CSV export, identified by output error without being told, and a held-out record
//! predicted with `--validate`.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use forcemap_io::csv_export::write_csv;
use forcemap_math::recipe::SetupKind;
use forcemap_math::sim::RunSpec;

#[test]
fn one_period_multisines_of_a_force_driven_system_are_identified_by_output_error() {
    let dir = tempfile::tempdir().unwrap();
    let mut records = RunSpec::shaker_duffing_one_period(Some(30.0), 1)
        .simulate()
        .unwrap();
    let held_out = records.split_off(5);
    let fitted = dir.path().join("fitted.csv");
    let validation = dir.path().join("held_out.csv");
    write_csv(&fitted, &records, SetupKind::Element).unwrap();
    write_csv(&validation, &held_out, SetupKind::Element).unwrap();
    let o = common::forcemap(&[
        "identify",
        fitted.to_str().unwrap(),
        "--model",
        "cubic",
        "--mass-kg",
        "2",
        "--validate",
        validation.to_str().unwrap(),
        "--json",
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let id = &v;
    assert_eq!(id["method"], "output-error", "{v}");
    for (name, truth) in RunSpec::SHAKER_DUFFING_THETA {
        let p = id["parameters"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["name"] == name)
            .unwrap();
        let value = p["value"].as_f64().unwrap();
        assert!((value / truth - 1.0).abs() < 0.01, "{name} {value}");
    }
    let warnings = id["warnings"].to_string();
    assert!(
        warnings.contains("output error chosen: the records have no steps"),
        "{warnings}"
    );
    // The held-out record: its displacement simulated under its measured force misses by
    // about the noise (the truth's own misfit is 5.1e-5 m on this record).
    let held = &v["held_out"][0];
    println!("{}", serde_json::to_string_pretty(held).unwrap());
    let rms_m = held["simulated"]["rms_error_m"].as_f64().unwrap();
    assert!(rms_m < 1.2 * 5.1e-5, "{held}");
}
