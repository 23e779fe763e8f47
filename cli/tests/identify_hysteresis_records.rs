//! `forcemap identify --model NAME+hysteresis` on records with no steps whose motion the bench
//! did not impose, through CSV exports: a force-driven single-DOF system with a hysteresis loop
//! measured with one-period multisines, and the paper's rig with a loop on band-random records.
//! The fit along the measured motion is refined by output error without being told; held-out
//! records are predicted by simulation.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use forcemap_io::csv_export::write_csv;
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::pipeline::validate_forced_element;
use forcemap_math::recipe::SetupKind;
use forcemap_math::record::Record;
use forcemap_math::signal::bouc_wen::HysteresisLaw;
use forcemap_math::sim::{ElementDrive, MultisineDesign, RunSpec, StepSpec, TruthElement};

/// The force-driven loop of `math/tests/output_error_hysteresis.rs`: 2 kg on k 40 000 N/m and
/// c 60 N s/m with a Bouc-Wen loop of alpha 20 000 N/m, yield 0.4 mm, shape n 2, r 0.7; six
/// one-period multisines of 40 N RMS (5-60 Hz every 0.5 Hz, 1 kHz) back to back, 30 dB.
fn truth_law() -> HysteresisLaw {
    HysteresisLaw {
        yield_m: 4.0e-4,
        n: 2.0,
        r: 0.7,
    }
}

fn forced_loop_records(seed: u64) -> Vec<Record> {
    let law = truth_law();
    let element = TruthElement {
        bouc_wen: Some(law.bouc_wen(2.0e4)),
        ..TruthElement::linear(4.0e4, 60.0)
    };
    let step = StepSpec::Multisine {
        base_frequency_hz: 0.5,
        low_hz: 5.0,
        high_hz: 60.0,
        rms: 40.0,
        design: MultisineDesign::Full,
    };
    RunSpec {
        snr_db: Some(30.0),
        seed,
        ..RunSpec::element_test(
            ElementDrive::Force,
            2.0,
            element,
            vec![step; 6],
            1000.0,
            2000,
        )
    }
    .simulate()
    .unwrap()
}

fn value(v: &serde_json::Value, name: &str) -> f64 {
    v["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == name)
        .unwrap_or_else(|| panic!("no {name} in {v}"))["value"]
        .as_f64()
        .unwrap()
}

#[test]
fn a_force_driven_loop_is_refined_by_output_error_and_simulated_on_a_held_out_record() {
    let dir = tempfile::tempdir().unwrap();
    let mut records = forced_loop_records(1);
    let held_out = records.split_off(5);
    let fitted = dir.path().join("fitted.csv");
    let validation = dir.path().join("held_out.csv");
    write_csv(&fitted, &records, SetupKind::Element).unwrap();
    write_csv(&validation, &held_out, SetupKind::Element).unwrap();
    let args = [
        "identify",
        fitted.to_str().unwrap(),
        "--model",
        "linear+hysteresis",
        "--mass-kg",
        "2",
        "--validate",
        validation.to_str().unwrap(),
    ];
    let o = common::forcemap(&[&args[..], &["--json"]].concat());
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["method"], "hysteresis-output-error", "{v:#}");
    let misfit = v["output_error"]["residual_rms_noise_std"]
        .as_f64()
        .unwrap();
    let (k, c) = (value(&v, "k"), value(&v, "c"));
    let held_rms_m = v["held_out"][0]["rms_error_m"].as_f64().unwrap();
    // The truth's own misfit on the held-out record (its noise floor), simulated from the
    // initial state that fits it best.
    let model = Model::by_name("linear", &ModelOptions::default()).unwrap();
    let law = truth_law();
    let floor = validate_forced_element(
        &model,
        Some(2.0),
        Some(law),
        &[4.0e4, 60.0, 2.0e4, law.yield_m],
        &held_out[0],
    )
    .unwrap();
    // The model without the loop, by the default (output error) on the same records.
    let plain = common::forcemap(&[
        "identify",
        fitted.to_str().unwrap(),
        "--model",
        "linear",
        "--mass-kg",
        "2",
        "--validate",
        validation.to_str().unwrap(),
        "--json",
    ]);
    assert!(plain.status.success());
    let p: serde_json::Value = serde_json::from_slice(&plain.stdout).unwrap();
    let plain_rms_m = p["held_out"][0]["simulated"]["rms_error_m"]
        .as_f64()
        .unwrap_or(f64::NAN);
    eprintln!(
        "k {k:.1} ({:+.3} %), c {c:.3} ({:+.3} %), alpha {:.0}, yield {:.3e} m, n {}, r {}; misfit {misfit:.3} noise std; held out {held_rms_m:.4e} m RMS, the truth's own {:.4e} m ({:.3}x), linear alone {plain_rms_m:.4e} m",
        100.0 * (k / 4.0e4 - 1.0),
        100.0 * (c / 60.0 - 1.0),
        value(&v, "alpha"),
        value(&v, "yield_m"),
        value(&v, "n"),
        value(&v, "r"),
        floor.rms_error_m,
        held_rms_m / floor.rms_error_m
    );
    assert!((k / 4.0e4 - 1.0).abs() < 0.005 && (c / 60.0 - 1.0).abs() < 0.005);
    assert!(misfit < 1.2, "{v:#}");
    assert!(held_rms_m < 1.2 * floor.rms_error_m);
    assert!(plain_rms_m > 2.5 * held_rms_m, "{p:#}");
    let text = common::forcemap(&args);
    let out = String::from_utf8_lossy(&text.stdout);
    assert!(out.contains("refined by output error"), "{out}");
    assert!(
        out.contains("displacement (the mass simulated under its measured force)"),
        "{out}"
    );
}
