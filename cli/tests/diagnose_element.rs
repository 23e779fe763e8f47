//! `forcemap diagnose` on an element test (a mount tester's export): no record to simulate
//! held-out, so the phasor diagnosis decides on the sine steps, cross-validated. A planted
//! effect is named, the true model is adequate, and a preload (invisible on the rig) is found;
//! a held-out sweep is predicted better with the top effect; held-out sine steps and rig data
//! are refused.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use std::path::{Path, PathBuf};

use forcemap_io::csv_export::write_csv;
use forcemap_math::phasor::SweepKind;
use forcemap_math::recipe::SetupKind;
use forcemap_math::sim::bench_runs::sine_grid;
use forcemap_math::sim::{ElementDrive, RunSpec, StepSpec, TruthElement};

/// An elastomer mount on a displacement-driven tester at 40 dB: 2e5 N/m, 300 N s/m, a 0.5 kg
/// fixture; 2-20 Hz at 0.5, 1 and 2 mm.
fn mount_csv(dir: &Path, name: &str, element: TruthElement) -> PathBuf {
    let run = RunSpec {
        snr_db: Some(40.0),
        seed: 4,
        ..RunSpec::element_test(
            ElementDrive::Displacement,
            0.5,
            element,
            sine_grid(&[2.0, 5.0, 10.0, 20.0], &[0.0005, 0.001, 0.002]),
            2000.0,
            4000,
        )
    };
    let path = dir.join(name);
    write_csv(&path, &run.simulate().unwrap(), SetupKind::Element).unwrap();
    path
}

fn diagnose(csv: &Path, model: &str) -> serde_json::Value {
    let o = common::forcemap(&[
        "diagnose",
        csv.to_str().unwrap(),
        "--model",
        model,
        "--mass-kg",
        "0.5",
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

fn mount() -> TruthElement {
    TruthElement::linear(2.0e5, 300.0)
}

#[test]
fn a_hardening_mount_is_explained_by_cubic_stiffness_and_adequate_with_it() {
    let dir = tempfile::tempdir().unwrap();
    let csv = mount_csv(
        dir.path(),
        "cubic.csv",
        TruthElement {
            cubic_stiffness_n_per_m3: 1.5e10,
            ..mount()
        },
    );
    let v = diagnose(&csv, "linear");
    assert_eq!(v["verdict"], "explained", "{v}");
    assert_eq!(v["top_effect"], "cubic_stiffness", "{v}");
    assert_eq!(v["evidence"], "cross_validated_force_error");
    assert_eq!(v["setup"], "element");
    let v = diagnose(&csv, "cubic");
    assert_eq!(v["verdict"], "adequate", "{v}");
}

#[test]
fn a_static_load_is_explained_by_preload() {
    let dir = tempfile::tempdir().unwrap();
    let csv = mount_csv(
        dir.path(),
        "preload.csv",
        TruthElement {
            preload_n: 80.0,
            ..mount()
        },
    );
    let v = diagnose(&csv, "linear");
    assert_eq!(v["verdict"], "explained", "{v}");
    assert_eq!(v["top_effect"], "preload", "{v}");
    let added = &v["ranked_effects"][0]["added_parameters"][0];
    let f0 = added["value"].as_f64().unwrap();
    assert!((f0 / 80.0 - 1.0).abs() < 0.02, "{added}");
}

/// A sweep of the mount, 2-20 Hz at 1 mm (40 dB, another seed): held-out data.
fn mount_sweep_csv(dir: &Path, element: TruthElement) -> PathBuf {
    let run = RunSpec {
        snr_db: Some(40.0),
        seed: 5,
        ..RunSpec::element_test(
            ElementDrive::Displacement,
            0.5,
            element,
            vec![StepSpec::Sweep {
                sweep: SweepKind::Linear,
                start_frequency_hz: 2.0,
                end_frequency_hz: 20.0,
                amplitude: 0.001,
            }],
            2000.0,
            16_000,
        )
    };
    let path = dir.join("sweep.csv");
    write_csv(&path, &run.simulate().unwrap(), SetupKind::Element).unwrap();
    path
}

#[test]
fn a_held_out_sweep_is_predicted_better_with_the_top_effect() {
    let dir = tempfile::tempdir().unwrap();
    let hardening = TruthElement {
        cubic_stiffness_n_per_m3: 1.5e10,
        ..mount()
    };
    let csv = mount_csv(dir.path(), "cubic.csv", hardening.clone());
    let sweep = mount_sweep_csv(dir.path(), hardening);
    let o = common::forcemap(&[
        "diagnose",
        csv.to_str().unwrap(),
        "--model",
        "linear",
        "--mass-kg",
        "0.5",
        "--validate",
        sweep.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["top_effect"], "cubic_stiffness", "{v}");
    let h = &v["heldout"][0];
    assert_eq!(h["excitation"], "sweep", "{v}");
    assert_eq!(h["effect"], "cubic_stiffness");
    let before = h["baseline_nmse_percent"].as_f64().unwrap();
    let after = h["effect_nmse_percent"].as_f64().unwrap();
    assert!(after < before / 3.0, "{before} % -> {after} %");
}

#[test]
fn held_out_sine_steps_are_predicted_and_rig_data_refused_for_an_element_test() {
    let dir = tempfile::tempdir().unwrap();
    let csv = mount_csv(dir.path(), "plain.csv", mount());
    let diagnose = |validate: &Path| {
        common::forcemap(&[
            "diagnose",
            csv.to_str().unwrap(),
            "--model",
            "linear",
            "--mass-kg",
            "0.5",
            "--validate",
            validate.to_str().unwrap(),
            "--json",
        ])
    };
    // Sine steps held out are predicted along their measured motion, one result per step.
    let o = diagnose(&csv);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let held = v["heldout"].as_array().expect("heldout");
    assert!(!held.is_empty(), "{v}");
    assert!(held.iter().all(|h| h["excitation"] == "sine"), "{v}");
    let rig = dir.path().join("rig.csv");
    let records = RunSpec::paper_rig(Some(40.0), 1).simulate().unwrap();
    write_csv(&rig, &records, SetupKind::BaseExcited).unwrap();
    let o = diagnose(&rig);
    assert_eq!(o.status.code(), Some(1));
    let e = common::stderr(&o);
    assert!(
        e.contains("validation data must hold the channels of the data's element setup"),
        "{e}"
    );
}
